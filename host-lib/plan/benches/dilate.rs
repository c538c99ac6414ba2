//! Dilating a large plan: 2,500 box-joint parts on a 50 × 50 grid, each an outline with 28
//! fingers (116 vertices) and three holes (a slot, a round hole, a rounded rectangle) — 10,000
//! closed contours, 325,000 vertices — by 150 µm with `kerfmeter_plan::dilate::dilate`
//! (nesting, per-part kerf, offsets, merge check). Budget: under 1 s.
//!
//! `cargo bench -p kerfmeter --bench dilate`

use std::f64::consts::FRAC_PI_4;
use std::hint::black_box;

use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline};
use criterion::{Criterion, criterion_group, criterion_main};
use kerfmeter_plan::dilate::{Contour, KerfSource, dilate};

/// One part at (`x`, `y`): 40 × 40 mm, seven 2.5 mm fingers (3 mm long) on each side, three
/// holes.
fn part(x: f64, y: f64, contours: &mut Vec<Contour>) {
    let mut outline = Polyline::new_closed();
    // Each side: 16 segments of 2.5 mm, alternating plain edge and finger (3 mm out); the first
    // and last segments are plain, so the corners stay square.
    let step = 40.0 / 16.0;
    // (start corner, direction along the side, outward normal) of each side.
    type Side = ((f64, f64), (f64, f64), (f64, f64));
    let sides: [Side; 4] = [
        ((0.0, 0.0), (1.0, 0.0), (0.0, -1.0)),
        ((40.0, 0.0), (0.0, 1.0), (1.0, 0.0)),
        ((40.0, 40.0), (-1.0, 0.0), (0.0, 1.0)),
        ((0.0, 40.0), (0.0, -1.0), (-1.0, 0.0)),
    ];
    for (start, dir, out) in sides {
        for k in 0..16 {
            let (px, py) = (
                start.0 + dir.0 * step * k as f64,
                start.1 + dir.1 * step * k as f64,
            );
            if k % 2 == 1 && k < 15 {
                // A finger: out, along, back in.
                outline.add(x + px, y + py, 0.0);
                outline.add(x + px + 3.0 * out.0, y + py + 3.0 * out.1, 0.0);
                let (qx, qy) = (px + dir.0 * step, py + dir.1 * step);
                outline.add(x + qx + 3.0 * out.0, y + qy + 3.0 * out.1, 0.0);
                outline.add(x + qx, y + qy, 0.0);
            } else if k == 0 {
                outline.add(x + px, y + py, 0.0);
            }
        }
    }
    contours.push(Contour {
        pline: outline,
        label: format!("part at ({x}, {y})"),
    });
    // A slot.
    let mut slot = Polyline::new_closed();
    for (sx, sy) in [(8.0, 8.0), (14.0, 8.0), (14.0, 30.0), (8.0, 30.0)] {
        slot.add(x + sx, y + sy, 0.0);
    }
    contours.push(Contour {
        pline: slot,
        label: "slot".into(),
    });
    // A round hole (two half circles).
    let mut hole = Polyline::new_closed();
    hole.add(x + 32.0, y + 12.0, 1.0);
    hole.add(x + 24.0, y + 12.0, 1.0);
    contours.push(Contour {
        pline: hole,
        label: "hole".into(),
    });
    // A rounded rectangle (quarter arcs at the corners).
    let b = (FRAC_PI_4 / 2.0).tan();
    let mut rr = Polyline::new_closed();
    for (rx, ry, bulge) in [
        (22.0, 22.0, 0.0),
        (32.0, 22.0, b),
        (34.0, 24.0, 0.0),
        (34.0, 30.0, b),
        (32.0, 32.0, 0.0),
        (22.0, 32.0, b),
        (20.0, 30.0, 0.0),
        (20.0, 24.0, b),
    ] {
        rr.add(x + rx, y + ry, bulge);
    }
    contours.push(Contour {
        pline: rr,
        label: "rounded window".into(),
    });
}

fn plan() -> Vec<Contour> {
    let mut contours = Vec::with_capacity(10_000);
    for i in 0..50 {
        for j in 0..50 {
            part(i as f64 * 50.0, j as f64 * 50.0, &mut contours);
        }
    }
    contours
}

fn bench(c: &mut Criterion) {
    let contours = plan();
    let vertices: usize = contours.iter().map(|c| c.pline.vertex_count()).sum();
    assert_eq!((contours.len(), vertices), (10_000, 325_000));
    let kerf = KerfSource::Uniform(150.0);
    // The plan must dilate cleanly (no merges, every part found).
    let once = dilate(&contours, &kerf).expect("the benchmark plan dilates");
    assert_eq!(once.parts.len(), 2_500);
    eprintln!("plan: {} contours, {vertices} vertices", contours.len());
    let mut group = c.benchmark_group("dilate");
    group.sample_size(10);
    group.bench_function("10k contours, 325k vertices", |b| {
        b.iter(|| dilate(black_box(&contours), black_box(&kerf)).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
