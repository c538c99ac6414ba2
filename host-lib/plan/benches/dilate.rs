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

mod common;

use common::finger_part::{HOLE, SLOT, WINDOW, outline};

/// A closed polyline through `points` (x, y, bulge) moved by (`x`, `y`).
fn closed(x: f64, y: f64, points: impl IntoIterator<Item = (f64, f64, f64)>) -> Polyline<f64> {
    let mut p = Polyline::new_closed();
    for (px, py, bulge) in points {
        p.add(x + px, y + py, bulge);
    }
    p
}

/// One part at (`x`, `y`) (see `common::finger_part`): its outline and three holes.
fn part(x: f64, y: f64, contours: &mut Vec<Contour>) {
    let ((cx, cy), r) = HOLE;
    let ((wx, wy), (ww, wh), wr) = WINDOW;
    // A quarter turn.
    let b = (FRAC_PI_4 / 2.0).tan();
    let shapes = [
        (
            format!("part at ({x}, {y})"),
            closed(x, y, outline().into_iter().map(|(px, py)| (px, py, 0.0))),
        ),
        (
            "slot".into(),
            closed(x, y, SLOT.map(|(px, py)| (px, py, 0.0))),
        ),
        (
            "hole".into(),
            closed(x, y, [(cx + r, cy, 1.0), (cx - r, cy, 1.0)]),
        ),
        (
            "rounded window".into(),
            closed(
                x,
                y,
                [
                    (wx + wr, wy, 0.0),
                    (wx + ww - wr, wy, b),
                    (wx + ww, wy + wr, 0.0),
                    (wx + ww, wy + wh - wr, b),
                    (wx + ww - wr, wy + wh, 0.0),
                    (wx + wr, wy + wh, b),
                    (wx, wy + wh - wr, 0.0),
                    (wx, wy + wr, b),
                ],
            ),
        ),
    ];
    for (label, pline) in shapes {
        contours.push(Contour { pline, label });
    }
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
