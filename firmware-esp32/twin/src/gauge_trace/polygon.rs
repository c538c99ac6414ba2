//! Holes traced as polygons: a controller that cuts only straight lines (a Ruida, sent the
//! gauge's arcs flattened into chords) traces each hole as a closed chain of short cuts. A chain
//! that closes on itself after at least [`MIN_SIDES`] cuts, whose vertices all lie within
//! [`super::CIRCLE_MATCH_UM`] of one circle (a least-squares fit), and the middle of every side
//! too, is read as that circle (its chords lie inside it by their sagitta, at most a micrometre
//! for the flattening Kerfmeter's Ruida driver writes; a coarse polygon's flats are no circle).
//! The spiral closes too, but its radius grows by a pitch's turn.

use super::{CIRCLE_MATCH_UM, Circle};
use crate::traced::{Segment, SegmentKind};

/// The fewest cuts a polygon hole has.
pub const MIN_SIDES: usize = 8;
/// Two ends meet within this, mm.
const SAME_POINT_MM: f64 = 1e-6;

/// The circles closed chains of straight cuts among `cuts` trace, and per cut whether it is
/// one of their sides.
pub(super) fn polygon_circles(cuts: &[&Segment]) -> (Vec<Circle>, Vec<bool>) {
    let mut circles = Vec::new();
    let mut on_circle = vec![false; cuts.len()];
    let mut first = 0;
    for k in 0..cuts.len() {
        let s = cuts[k];
        let joins = k > first && meets(cuts[k - 1].end, s.start) && s.kind == SegmentKind::Line;
        if !joins {
            first = k;
        }
        if s.kind != SegmentKind::Line || k + 1 - first < MIN_SIDES {
            continue;
        }
        if meets(s.end, cuts[first].start)
            && let Some(circle) = fit(&cuts[first..=k])
        {
            circles.push(circle);
            on_circle[first..=k].iter_mut().for_each(|c| *c = true);
            first = k + 1;
        }
    }
    (circles, on_circle)
}

fn meets(p: [f64; 3], q: [f64; 3]) -> bool {
    (p[0] - q[0]).hypot(p[1] - q[1]) <= SAME_POINT_MM
}

/// The circle through the chain's corners, if every corner lies within [`CIRCLE_MATCH_UM`] of
/// it (a Kåsa fit: x² + y² + a·x + b·y + c = 0 by least squares).
fn fit(chain: &[&Segment]) -> Option<Circle> {
    let points: Vec<[f64; 2]> = chain.iter().map(|s| [s.start[0], s.start[1]]).collect();
    let n = points.len() as f64;
    let mean = |f: &dyn Fn(&[f64; 2]) -> f64| points.iter().map(f).sum::<f64>() / n;
    let (mx, my) = (mean(&|p| p[0]), mean(&|p| p[1]));
    // Centred coordinates keep the normal equations well conditioned.
    let (mut suu, mut svv, mut suv, mut suuu, mut svvv, mut suvv, mut svuu) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for p in &points {
        let (u, v) = (p[0] - mx, p[1] - my);
        suu += u * u;
        svv += v * v;
        suv += u * v;
        suuu += u * u * u;
        svvv += v * v * v;
        suvv += u * v * v;
        svuu += v * u * u;
    }
    let det = suu * svv - suv * suv;
    if det.abs() < 1e-18 {
        return None;
    }
    let (bu, bv) = ((suuu + suvv) / 2.0, (svvv + svuu) / 2.0);
    let uc = (bu * svv - bv * suv) / det;
    let vc = (bv * suu - bu * suv) / det;
    let center = [mx + uc, my + vc];
    let radii: Vec<f64> = points
        .iter()
        .map(|p| (p[0] - center[0]).hypot(p[1] - center[1]))
        .collect();
    let radius = radii.iter().sum::<f64>() / n;
    let tol_mm = CIRCLE_MATCH_UM * 1e-3;
    let corners_on = radii.iter().all(|r| (r - radius).abs() <= tol_mm);
    // Each side's middle too: a coarse polygon's flats are no circle.
    let sides_on = chain.iter().all(|s| {
        let mid = [(s.start[0] + s.end[0]) / 2.0, (s.start[1] + s.end[1]) / 2.0];
        (radius - (mid[0] - center[0]).hypot(mid[1] - center[1])).abs() <= tol_mm
    });
    (corners_on && sides_on).then_some(Circle {
        center,
        radius,
        sweep: std::f64::consts::TAU,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn chain(points: &[[f64; 2]]) -> Vec<Segment> {
        points
            .windows(2)
            .map(|w| Segment {
                kind: SegmentKind::Line,
                start: [w[0][0], w[0][1], 0.0],
                end: [w[1][0], w[1][1], 0.0],
                power_s: 1000.0,
                feed_mm_per_min: 300.0,
                complete: true,
                line: 1,
            })
            .collect()
    }

    /// `n` corners on a circle of `radius_mm` about (10, 20), closed, the radius growing by
    /// `grow_mm` over the turn.
    fn ring(n: usize, radius_mm: f64, grow_mm: f64) -> Vec<Segment> {
        let points: Vec<[f64; 2]> = (0..=n)
            .map(|k| {
                let f = (k % n) as f64 / n as f64;
                let r = radius_mm + grow_mm * f;
                [10.0 + r * (TAU * f).cos(), 20.0 + r * (TAU * f).sin()]
            })
            .collect();
        chain(&points)
    }

    #[test]
    fn a_fine_polygon_is_its_circle_and_a_coarse_one_or_a_spiral_is_not() {
        let fine = ring(160, 2.4, 0.0);
        let refs: Vec<&Segment> = fine.iter().collect();
        let (circles, on) = polygon_circles(&refs);
        assert_eq!(circles.len(), 1);
        assert!(on.iter().all(|o| *o));
        let c = &circles[0];
        assert!((c.center[0] - 10.0).abs() < 1e-9 && (c.center[1] - 20.0).abs() < 1e-9);
        assert!((c.radius - 2.4).abs() < 1e-9);
        for coarse in [ring(12, 2.4, 0.0), ring(400, 10.0, 1.0)] {
            let refs: Vec<&Segment> = coarse.iter().collect();
            assert!(polygon_circles(&refs).0.is_empty());
        }
    }
}
