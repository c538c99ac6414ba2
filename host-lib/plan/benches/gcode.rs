//! Ordering and writing a large plan as G-code: 2,500 parts on a 50 × 50 grid, each a 116-vertex
//! toothed outline and three holes (a slot, a round hole, a square) — 10,000 closed contours,
//! about 300,000 vertices — with `kerfmeter_plan::gcode`: the cut order (nesting, then nearest
//! neighbour on an R-tree), and building and writing the program. Budget: under 1 s each.
//!
//! `cargo bench -p kerfmeter-plan --bench gcode`

use std::f64::consts::TAU;
use std::hint::black_box;

use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline};
use criterion::{Criterion, criterion_group, criterion_main};
use kerfmeter_plan::gcode::{DEFAULT_S_MAX, Job, build, cut_order};
use kerfmeter_plan::profile::CutSettings;

const SETTINGS: CutSettings = CutSettings {
    feed_mm_per_min: 600.0,
    power_percent: 80.0,
    passes: 1,
};

fn job(pline: Polyline<f64>, label: &str) -> Job {
    Job {
        pline,
        label: label.into(),
        settings: SETTINGS,
    }
}

/// One part at (`x`, `y`): a 40 mm toothed ring outline (116 vertices) and three holes.
fn part(x: f64, y: f64, jobs: &mut Vec<Job>) {
    let mut outline = Polyline::new_closed();
    for k in 0..116 {
        let r = if k % 2 == 0 { 20.0 } else { 18.5 };
        let a = TAU * k as f64 / 116.0;
        outline.add(x + 20.0 + r * a.cos(), y + 20.0 + r * a.sin(), 0.0);
    }
    jobs.push(job(outline, "outline"));
    let mut slot = Polyline::new_closed();
    for (sx, sy) in [(8.0, 12.0), (14.0, 12.0), (14.0, 28.0), (8.0, 28.0)] {
        slot.add(x + sx, y + sy, 0.0);
    }
    jobs.push(job(slot, "slot"));
    let mut hole = Polyline::new_closed();
    hole.add(x + 24.0, y + 20.0, 1.0);
    hole.add(x + 20.0, y + 20.0, 1.0);
    jobs.push(job(hole, "hole"));
    let mut square = Polyline::new_closed();
    for (sx, sy) in [(27.0, 17.0), (32.0, 17.0), (32.0, 22.0), (27.0, 22.0)] {
        square.add(x + sx, y + sy, 0.0);
    }
    jobs.push(job(square, "square"));
}

fn plan() -> Vec<Job> {
    let mut jobs = Vec::with_capacity(10_000);
    for i in 0..50 {
        for j in 0..50 {
            part(i as f64 * 45.0, j as f64 * 45.0, &mut jobs);
        }
    }
    jobs
}

fn bench(c: &mut Criterion) {
    let jobs = plan();
    let vertices: usize = jobs.iter().map(|j| j.pline.vertex_count()).sum();
    eprintln!("{} contours, {vertices} vertices", jobs.len());
    let mut group = c.benchmark_group("gcode");
    group.sample_size(10);
    group.bench_function("cut_order_10k_contours", |b| {
        b.iter(|| cut_order(black_box(jobs.clone())).unwrap())
    });
    let ordered = cut_order(jobs.clone()).unwrap();
    group.bench_function("build_and_write_10k_contours", |b| {
        b.iter(|| build(black_box(ordered.clone()), Vec::new(), DEFAULT_S_MAX).to_text())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
