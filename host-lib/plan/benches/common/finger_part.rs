//! The box-joint part that the plan benchmarks dilate, in one place: the kernel benchmark
//! (`benches/dilate.rs`) and the whole-command benchmark's plan generator
//! (`examples/plan_bench.rs`, run by `cargo xtask bench-plan`) both build their plans from it.
//!
//! A part is 40 × 40 mm with its corner at the origin: an outline with seven 2.5 mm fingers
//! (3 mm long) a side, 116 vertices, and three holes, a slot, a round hole and a rounded window.

/// The outline of a part with its corner at the origin: 16 steps of 2.5 mm a side, every other
/// one (but the first and last) a finger 3 mm out. Counter-clockwise with y up.
pub fn outline() -> Vec<(f64, f64)> {
    let step = 40.0 / 16.0;
    type Side = ((f64, f64), (f64, f64), (f64, f64));
    let sides: [Side; 4] = [
        ((0.0, 0.0), (1.0, 0.0), (0.0, -1.0)),
        ((40.0, 0.0), (0.0, 1.0), (1.0, 0.0)),
        ((40.0, 40.0), (-1.0, 0.0), (0.0, 1.0)),
        ((0.0, 40.0), (0.0, -1.0), (-1.0, 0.0)),
    ];
    let mut pts = Vec::with_capacity(116);
    for (start, dir, out) in sides {
        for k in 0..16 {
            let at = |k: usize| {
                (
                    start.0 + dir.0 * step * k as f64,
                    start.1 + dir.1 * step * k as f64,
                )
            };
            let (p, q) = (at(k), at(k + 1));
            if k == 0 {
                pts.push(p);
            } else if k % 2 == 1 && k < 15 {
                pts.push(p);
                pts.push((p.0 + 3.0 * out.0, p.1 + 3.0 * out.1));
                pts.push((q.0 + 3.0 * out.0, q.1 + 3.0 * out.1));
                pts.push(q);
            }
        }
    }
    pts
}

/// The slot's corners.
pub const SLOT: [(f64, f64); 4] = [(8.0, 8.0), (14.0, 8.0), (14.0, 30.0), (8.0, 30.0)];
/// The round hole: centre and radius.
pub const HOLE: ((f64, f64), f64) = ((28.0, 12.0), 4.0);
/// The rounded window: corner, size, corner radius.
pub const WINDOW: ((f64, f64), (f64, f64), f64) = ((20.0, 22.0), (14.0, 10.0), 2.0);
