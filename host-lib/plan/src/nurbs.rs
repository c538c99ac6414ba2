//! Non-uniform rational B-splines (the curves of DXF's `SPLINE`), checked and evaluated, so that
//! the DXF reader can turn them into biarcs (within [`CURVE_TOLERANCE_MM`](crate::geom::CURVE_TOLERANCE_MM),
//! like every other free-form curve).
//!
//! A spline of degree p with control points P₀…Pₙ, weights w₀…wₙ (all 1 when the file gives none)
//! and knots u₀…u_{n+p+1} (non-decreasing) is evaluated by de Boor's algorithm on the weighted
//! points (x·w, y·w, w), one polynomial piece (knot span) at a time. Each non-empty span is a
//! smooth curve; the pieces meet at the knots, where the curve may have a corner (repeated knots),
//! so the pieces are fitted one by one.

use crate::geom::{V2, v2};

/// The highest degree accepted (CAD programs write 2 or 3; a high degree is a damaged file).
const MAX_DEGREE: usize = 25;

/// The range of weights accepted (CAD programs write weights near 1; a weight near 0 or huge
/// makes a curve that no cutter follows, and numbers that lose their precision).
const MIN_WEIGHT: f64 = 1e-9;
const MAX_WEIGHT: f64 = 1e9;

/// A checked spline in drawing coordinates.
#[derive(Debug, Clone)]
pub(crate) struct Nurbs {
    degree: usize,
    /// (x·w, y·w, w) for each control point.
    weighted: Vec<[f64; 3]>,
    knots: Vec<f64>,
}

impl Nurbs {
    /// A spline from its degree, control points (x, y), weights (empty: all 1) and knots; why not
    /// when the data cannot describe one.
    pub(crate) fn new(
        degree: i32,
        points: &[(f64, f64)],
        weights: &[f64],
        knots: &[f64],
    ) -> Result<Nurbs, String> {
        let p = usize::try_from(degree)
            .ok()
            .filter(|&p| (1..=MAX_DEGREE).contains(&p))
            .ok_or_else(|| format!("its degree {degree} is not between 1 and {MAX_DEGREE}"))?;
        if points.len() < p + 1 {
            return Err(format!(
                "it has {} control points, fewer than degree + 1 = {}",
                points.len(),
                p + 1
            ));
        }
        if knots.len() != points.len() + p + 1 {
            return Err(format!(
                "it has {} knots where {} control points of degree {p} need {}",
                knots.len(),
                points.len(),
                points.len() + p + 1
            ));
        }
        if !weights.is_empty() && weights.len() != points.len() {
            return Err(format!(
                "it has {} weights for {} control points",
                weights.len(),
                points.len()
            ));
        }
        let finite = points.iter().all(|&(x, y)| x.is_finite() && y.is_finite())
            && knots.iter().all(|k| k.is_finite());
        if !finite
            || weights
                .iter()
                .any(|w| !(MIN_WEIGHT..=MAX_WEIGHT).contains(w))
        {
            return Err(format!(
                "a control point, weight or knot is not a finite number, or a weight is not between {MIN_WEIGHT:e} and {MAX_WEIGHT:e}"
            ));
        }
        if knots.windows(2).any(|w| w[1] < w[0]) {
            return Err("its knots are not in increasing order".into());
        }
        let weighted = points
            .iter()
            .enumerate()
            .map(|(i, &(x, y))| {
                let w = weights.get(i).copied().unwrap_or(1.0);
                [x * w, y * w, w]
            })
            .collect();
        let spline = Nurbs {
            degree: p,
            weighted,
            knots: knots.to_vec(),
        };
        if spline.spans().next().is_none() {
            return Err("its knots leave no curve (all equal)".into());
        }
        Ok(spline)
    }

    /// The knot spans that carry curve: indexes k with u_k < u_{k+1}, p ≤ k ≤ n.
    pub(crate) fn spans(&self) -> impl Iterator<Item = usize> + '_ {
        (self.degree..self.weighted.len()).filter(|&k| self.knots[k] < self.knots[k + 1])
    }

    /// Span `k` as a curve on [0, 1]: position and tangent (in the sense of increasing
    /// parameter).
    pub(crate) fn span_curve(&self, k: usize) -> impl Fn(f64) -> (V2, V2) + '_ {
        let (u0, u1) = (self.knots[k], self.knots[k + 1]);
        let len = u1 - u0;
        move |t: f64| {
            let u = u0 + len * t;
            // The piece is one polynomial (rational): a central difference may look past the
            // span's ends, on the same piece.
            let h = len * 1e-6;
            let (a, b) = (self.point_on_piece(k, u - h), self.point_on_piece(k, u + h));
            (self.point_on_piece(k, u), (b - a).scale(1.0 / (2.0 * h)))
        }
    }

    /// The spline's first point.
    pub(crate) fn start(&self) -> V2 {
        let k = self.spans().next().expect("checked in new");
        self.point_on_piece(k, self.knots[k])
    }

    /// The point at parameter `u` of the polynomial piece of span `k` (de Boor).
    fn point_on_piece(&self, k: usize, u: f64) -> V2 {
        let p = self.degree;
        let mut d: Vec<[f64; 3]> = (0..=p).map(|j| self.weighted[j + k - p]).collect();
        for r in 1..=p {
            for j in (r..=p).rev() {
                let (lo, hi) = (self.knots[j + k - p], self.knots[j + 1 + k - r]);
                let alpha = if hi > lo { (u - lo) / (hi - lo) } else { 0.0 };
                let prev = d[j - 1];
                for (v, q) in d[j].iter_mut().zip(prev) {
                    *v = (1.0 - alpha) * q + alpha * *v;
                }
            }
        }
        let [x, y, w] = d[p];
        v2(x / w, y / w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rational_quadratic_draws_an_exact_quarter_circle() {
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let s = Nurbs::new(
            2,
            &[(1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
            &[1.0, w, 1.0],
            &[0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
        )
        .unwrap();
        let spans: Vec<usize> = s.spans().collect();
        assert_eq!(spans, vec![2]);
        let f = s.span_curve(2);
        for i in 0..=20 {
            let (q, d) = f(f64::from(i) / 20.0);
            assert!((q.length() - 1.0).abs() < 1e-12, "{q:?}");
            // The tangent is perpendicular to the radius.
            assert!(q.dot(d).abs() < 1e-6 * d.length(), "{q:?} {d:?}");
        }
        assert!((s.start() - v2(1.0, 0.0)).length() < 1e-15);
    }

    #[test]
    fn bad_data_is_refused_with_the_reason() {
        let pts = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)];
        let e = Nurbs::new(2, &pts, &[], &[0.0, 0.0, 1.0]).unwrap_err();
        assert!(e.contains("knots"), "{e}");
        let e = Nurbs::new(0, &pts, &[], &[]).unwrap_err();
        assert!(e.contains("degree"), "{e}");
        let e =
            Nurbs::new(2, &pts, &[1.0, -1.0, 1.0], &[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).unwrap_err();
        assert!(e.contains("weight"), "{e}");
        let e = Nurbs::new(2, &pts, &[], &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert!(e.contains("no curve"), "{e}");
        let e = Nurbs::new(2, &pts, &[], &[0.0, 0.0, 1.0, 0.5, 1.0, 1.0]).unwrap_err();
        assert!(e.contains("increasing"), "{e}");
    }
}
