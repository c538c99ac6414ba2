//! Analytic references for curved cuts: ellipses (any size, aspect and orientation) and rounded
//! rectangles with elliptical corners, with the exact distance from a point to them (Eberly's
//! robust bisection, "Distance from a Point to an Ellipse, an Ellipsoid, or a Hyperellipsoid",
//! 2013), so that a dilated contour is measured against the exact parallel curve: every point of
//! the boundary of the Minkowski sum with a disk of radius `d` (or of the erosion, for a hole)
//! lies at distance `d` from the curve. That alone would pass a contour covering part of the
//! parallel curve, so its enclosed area is also checked against Steiner's formula (the area of a
//! convex body grown by `d` is A + P·d + π·d², shrunk by `d` A − P·d + π·d² while `d` stays under
//! the least radius of curvature).

// Each test file uses its own subset.
#![allow(dead_code)]

use cavalier_contours::polyline::PlineSource;
use kerfmeter_plan::geom::{Pline, area_and_centroid, segment_point, v2};

/// A point, mm.
pub type P = (f64, f64);

/// A convex closed curve with an exact distance.
pub trait Curve {
    /// Distance from `q` to the curve (not the region), mm.
    fn distance(&self, q: P) -> f64;
    /// Whether `q` is inside the region the curve bounds.
    fn inside(&self, q: P) -> bool;
    /// Area enclosed, mm².
    fn area(&self) -> f64;
    /// Length, mm.
    fn perimeter(&self) -> f64;
    /// The least radius of curvature, mm (the inner parallel curve is smooth below it).
    fn min_radius(&self) -> f64;
}

/// Distance from (y0, y1), both ≥ 0, to the ellipse x0²/e0² + x1²/e1² = 1 (e0 ≥ e1 > 0), and the
/// closest point: Eberly's algorithm (its root found by bisection to the last bit), then Newton's
/// method on the ellipse's angle from there. (Eberly's point alone is off the ellipse by up to
/// 10⁻⁴ of its size for a point a hair off the major axis inside the evolute, as the corner of
/// a narrow ellipse's inner parallel curve is: it gives x1 = y1/(s + 1) with s + 1 tiny.)
pub fn quadrant_distance(e0: f64, e1: f64, y0: f64, y1: f64) -> (f64, P) {
    let (_, (x0, x1)) = eberly(e0, e1, y0, y1);
    let mut t = (x1 / e1).atan2(x0 / e0);
    for _ in 0..6 {
        let (s, c) = t.sin_cos();
        let (dx, dy) = (e0 * c - y0, e1 * s - y1);
        let (tx, ty) = (-e0 * s, e1 * c);
        // d/dt of (E − y)·E′, with E″ = −E.
        let slope = tx * tx + ty * ty - (dx * e0 * c + dy * e1 * s);
        if slope <= 0.0 {
            break;
        }
        t -= (dx * tx + dy * ty) / slope;
    }
    let (s, c) = t.sin_cos();
    let (x0, x1) = (e0 * c, e1 * s);
    ((x0 - y0).hypot(x1 - y1), (x0, x1))
}

/// Eberly's closest point (see [`quadrant_distance`]).
fn eberly(e0: f64, e1: f64, y0: f64, y1: f64) -> (f64, P) {
    if y1 > 0.0 {
        if y0 > 0.0 {
            let (z0, z1) = (y0 / e0, y1 / e1);
            let g = z0 * z0 + z1 * z1 - 1.0;
            if g == 0.0 {
                return (0.0, (y0, y1));
            }
            let r0 = (e0 / e1).powi(2);
            let s = root(r0, z0, z1, g);
            let (x0, x1) = (r0 * y0 / (s + r0), y1 / (s + 1.0));
            ((x0 - y0).hypot(x1 - y1), (x0, x1))
        } else {
            ((y1 - e1).abs(), (0.0, e1))
        }
    } else {
        let (numer, denom) = (e0 * y0, e0 * e0 - e1 * e1);
        if numer < denom {
            let xde0 = numer / denom;
            let (x0, x1) = (e0 * xde0, e1 * (1.0 - xde0 * xde0).sqrt());
            ((x0 - y0).hypot(x1), (x0, x1))
        } else {
            ((y0 - e0).abs(), (e0, 0.0))
        }
    }
}

/// The root of (r0·z0/(s + r0))² + (z1/(s + 1))² = 1 (Eberly's `GetRoot`).
fn root(r0: f64, z0: f64, z1: f64, g: f64) -> f64 {
    let n0 = r0 * z0;
    let (mut s0, mut s1) = (z1 - 1.0, if g < 0.0 { 0.0 } else { n0.hypot(z1) - 1.0 });
    let mut s = s0;
    for _ in 0..2100 {
        s = (s0 + s1) / 2.0;
        if s == s0 || s == s1 {
            break;
        }
        let g = (n0 / (s + r0)).powi(2) + (z1 / (s + 1.0)).powi(2) - 1.0;
        if g > 0.0 {
            s0 = s;
        } else if g < 0.0 {
            s1 = s;
        } else {
            break;
        }
    }
    s
}

/// Length of the ellipse of semi-axes `a`, `b` (the trapezoid rule on a periodic integrand:
/// exact to rounding).
pub fn ellipse_perimeter(a: f64, b: f64) -> f64 {
    let n = 4096;
    let h = std::f64::consts::TAU / n as f64;
    (0..n)
        .map(|k| {
            let t = k as f64 * h;
            (a * t.sin()).hypot(b * t.cos()) * h
        })
        .sum()
}

/// An ellipse: centre, semi-axes (`major ≥ minor`) and the unit direction of the major axis.
#[derive(Debug, Clone, Copy)]
pub struct Ellipse {
    pub center: P,
    pub major: f64,
    pub minor: f64,
    pub axis: P,
}

impl Ellipse {
    /// The image of the unit circle under x ↦ `center` + M·x, M = [[m00, m01], [m10, m11]].
    pub fn from_map(center: P, m: [[f64; 2]; 2]) -> Self {
        // The axes are the eigenvectors of M·Mᵀ, the semi-axes the square roots of its values.
        let p = m[0][0] * m[0][0] + m[0][1] * m[0][1];
        let q = m[1][0] * m[1][0] + m[1][1] * m[1][1];
        let r = m[0][0] * m[1][0] + m[0][1] * m[1][1];
        let mean = (p + q) / 2.0;
        let diff = (((p - q) / 2.0).powi(2) + r * r).sqrt();
        let angle = 0.5 * (2.0 * r).atan2(p - q);
        Ellipse {
            center,
            major: (mean + diff).sqrt(),
            minor: (mean - diff).max(0.0).sqrt(),
            axis: (angle.cos(), angle.sin()),
        }
    }

    /// `q` in the ellipse's frame (along the major axis, along the minor one).
    fn local(&self, q: P) -> P {
        let (dx, dy) = (q.0 - self.center.0, q.1 - self.center.1);
        let (c, s) = self.axis;
        (dx * c + dy * s, -dx * s + dy * c)
    }
}

impl Curve for Ellipse {
    fn distance(&self, q: P) -> f64 {
        let (u, v) = self.local(q);
        quadrant_distance(self.major, self.minor, u.abs(), v.abs()).0
    }

    fn inside(&self, q: P) -> bool {
        let (u, v) = self.local(q);
        (u / self.major).powi(2) + (v / self.minor).powi(2) < 1.0
    }

    fn area(&self) -> f64 {
        std::f64::consts::PI * self.major * self.minor
    }

    fn perimeter(&self) -> f64 {
        ellipse_perimeter(self.major, self.minor)
    }

    fn min_radius(&self) -> f64 {
        self.minor * self.minor / self.major
    }
}

/// A rectangle with elliptical corners (`rx` along its width, `ry` along its height), turned by
/// `angle` (radians) about its centre.
#[derive(Debug, Clone, Copy)]
pub struct RoundedRect {
    pub center: P,
    pub half_width: f64,
    pub half_height: f64,
    pub rx: f64,
    pub ry: f64,
    pub angle: f64,
}

impl RoundedRect {
    /// `q` in the rectangle's frame, folded into the first quadrant (it is symmetric in both
    /// axes, and the nearest boundary point of a point in a quadrant is in that quadrant).
    fn folded(&self, q: P) -> P {
        let (dx, dy) = (q.0 - self.center.0, q.1 - self.center.1);
        let (s, c) = self.angle.sin_cos();
        ((dx * c + dy * s).abs(), (-dx * s + dy * c).abs())
    }

    /// The corner ellipse's centre, first quadrant.
    fn corner(&self) -> P {
        (self.half_width - self.rx, self.half_height - self.ry)
    }
}

/// Distance from `q` to the quarter of the ellipse of semi-axes `a`, `b` (axis-aligned, centred
/// at the origin) in the first quadrant. Where `q` is not in that quadrant, the nearest point of
/// the quarter need not be the nearest of the whole ellipse (a point inside a wide, flat corner
/// is nearest its arc though below the arc's centre): the quarter's distance is minimised over
/// its angle, every local minimum bracketed by 256 samples and narrowed by golden sections.
pub fn quarter_arc_distance(a: f64, b: f64, q: P) -> f64 {
    if q.0 >= 0.0 && q.1 >= 0.0 {
        return if a >= b {
            quadrant_distance(a, b, q.0, q.1).0
        } else {
            quadrant_distance(b, a, q.1, q.0).0
        };
    }
    let squared = |t: f64| (a * t.cos() - q.0).powi(2) + (b * t.sin() - q.1).powi(2);
    let n = 256;
    let step = std::f64::consts::FRAC_PI_2 / n as f64;
    let values: Vec<f64> = (0..=n).map(|k| squared(k as f64 * step)).collect();
    let mut best = values[0].min(values[n]);
    for k in 1..n {
        if values[k] <= values[k - 1] && values[k] <= values[k + 1] {
            best = best.min(golden_minimum(
                &squared,
                (k - 1) as f64 * step,
                (k + 1) as f64 * step,
            ));
        }
    }
    best.sqrt()
}

/// The least value of `f` on `[lo, hi]`, where it has one minimum (golden-section search).
fn golden_minimum(f: &dyn Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..80 {
        if f1 <= f2 {
            (hi, x2, f2) = (x2, x1, f1);
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            (lo, x1, f1) = (x1, x2, f2);
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    f1.min(f2)
}

/// Distance from `q` to the segment `a`–`b`.
fn segment_distance(q: P, a: P, b: P) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let t = (((q.0 - a.0) * dx + (q.1 - a.1) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
    (q.0 - a.0 - t * dx).hypot(q.1 - a.1 - t * dy)
}

impl Curve for RoundedRect {
    fn distance(&self, q: P) -> f64 {
        let (u, v) = self.folded(q);
        let (cx, cy) = self.corner();
        let (w, h) = (self.half_width, self.half_height);
        let top = segment_distance((u, v), (0.0, h), (cx, h));
        let side = segment_distance((u, v), (w, 0.0), (w, cy));
        let arc = quarter_arc_distance(self.rx, self.ry, (u - cx, v - cy));
        top.min(side).min(arc)
    }

    fn inside(&self, q: P) -> bool {
        let (u, v) = self.folded(q);
        let (cx, cy) = self.corner();
        let in_box = u < self.half_width && v < self.half_height;
        let in_corner = u >= cx && v >= cy;
        in_box && (!in_corner || ((u - cx) / self.rx).powi(2) + ((v - cy) / self.ry).powi(2) < 1.0)
    }

    fn area(&self) -> f64 {
        4.0 * self.half_width * self.half_height - (4.0 - std::f64::consts::PI) * self.rx * self.ry
    }

    fn perimeter(&self) -> f64 {
        let (cx, cy) = self.corner();
        4.0 * (cx + cy) + ellipse_perimeter(self.rx, self.ry)
    }

    fn min_radius(&self) -> f64 {
        let (a, b) = (self.rx.max(self.ry), self.rx.min(self.ry));
        b * b / a
    }
}

/// A closed curve given by points so dense that its chords stray from it by less than a
/// nanometre (a spline, a Bézier chain evaluated exactly), found near a point through a grid of
/// its chords. A point farther than a grid cell from it is reported infinitely far.
pub struct Sampled {
    points: Vec<P>,
    cell: f64,
    grid: std::collections::HashMap<(i64, i64), Vec<usize>>,
}

impl Sampled {
    /// The curve through `points` (closed: the last joins the first).
    pub fn new(points: Vec<P>) -> Self {
        let n = points.len();
        let chord = |i: usize| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            (a.0 - b.0).hypot(a.1 - b.1)
        };
        let cell = 4.0 * (0..n).map(chord).fold(0.0, f64::max);
        let key = |p: P| ((p.0 / cell).floor() as i64, (p.1 / cell).floor() as i64);
        let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
        for i in 0..n {
            let (a, b) = (key(points[i]), key(points[(i + 1) % n]));
            for x in a.0.min(b.0)..=a.0.max(b.0) {
                for y in a.1.min(b.1)..=a.1.max(b.1) {
                    grid.entry((x, y)).or_default().push(i);
                }
            }
        }
        Sampled { points, cell, grid }
    }
}

impl Curve for Sampled {
    fn distance(&self, q: P) -> f64 {
        let n = self.points.len();
        let (kx, ky) = (
            (q.0 / self.cell).floor() as i64,
            (q.1 / self.cell).floor() as i64,
        );
        let mut best = f64::INFINITY;
        for x in kx - 1..=kx + 1 {
            for y in ky - 1..=ky + 1 {
                for &i in self.grid.get(&(x, y)).into_iter().flatten() {
                    let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                    best = best.min(segment_distance(q, a, b));
                }
            }
        }
        best
    }

    fn inside(&self, q: P) -> bool {
        // Even-odd crossings of a ray towards +x.
        let n = self.points.len();
        let mut inside = false;
        for i in 0..n {
            let (a, b) = (self.points[i], self.points[(i + 1) % n]);
            if (a.1 > q.1) != (b.1 > q.1) && q.0 < a.0 + (q.1 - a.1) / (b.1 - a.1) * (b.0 - a.0) {
                inside = !inside;
            }
        }
        inside
    }

    fn area(&self) -> f64 {
        let n = self.points.len();
        let twice: f64 = (0..n)
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                a.0 * b.1 - b.0 * a.1
            })
            .sum();
        twice.abs() / 2.0
    }

    fn perimeter(&self) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|i| {
                let (a, b) = (self.points[i], self.points[(i + 1) % n]);
                (a.0 - b.0).hypot(a.1 - b.1)
            })
            .sum()
    }

    fn min_radius(&self) -> f64 {
        // Only its distance and area are used (a fit, at no offset).
        f64::INFINITY
    }
}

/// Points along every segment of a closed contour (`per_segment` of them, its start included).
pub fn samples(p: &Pline, per_segment: usize) -> Vec<P> {
    let n = p.vertex_count();
    let mut out = Vec::with_capacity(n * per_segment);
    for i in 0..n {
        let (a, b) = (p.at(i), p.at((i + 1) % n));
        for k in 0..per_segment {
            let t = k as f64 / per_segment as f64;
            let q = segment_point(v2(a.x, a.y), v2(b.x, b.y), a.bulge, t);
            out.push((q.x, q.y));
        }
    }
    out
}

/// How a dilated contour compares with the exact parallel curve of `curve` at distance `d`
/// (outside it, or inside for a hole).
#[derive(Debug, Clone, Copy)]
pub struct Deviation {
    /// The largest |distance to the curve − d| over the contour's samples, µm.
    pub max_um: f64,
    /// Whether every sample is on the right side of the curve.
    pub right_side: bool,
    /// Enclosed area less Steiner's, mm² (`None` for a hole past the least radius of curvature,
    /// whose inner parallel curve has cusps).
    pub area_error_mm2: Option<f64>,
    /// The area error a band of 0.1 µm around the curve allows, mm².
    pub area_allowed_mm2: f64,
}

impl Deviation {
    /// Whether the contour is the parallel curve within `tol_um`, all the way round.
    pub fn within(&self, tol_um: f64) -> bool {
        let area_ok = self
            .area_error_mm2
            .is_none_or(|e| e.abs() <= self.area_allowed_mm2 * tol_um / 0.1);
        self.max_um <= tol_um && self.right_side && area_ok
    }
}

/// Measure `contour` against the parallel curve of `curve` at distance `d` mm (inside for a
/// hole; at 0, against the curve itself).
pub fn deviation(curve: &dyn Curve, contour: &Pline, d: f64, hole: bool) -> Deviation {
    let mut max_um = 0.0f64;
    let mut right_side = true;
    for q in samples(contour, 16) {
        max_um = max_um.max((curve.distance(q) - d).abs() * 1e3);
        right_side &= d == 0.0 || curve.inside(q) == hole;
    }
    let (area, _) = area_and_centroid(contour);
    let (a, p) = (curve.area(), curve.perimeter());
    let steiner = if hole { a - p * d } else { a + p * d } + std::f64::consts::PI * d * d;
    let smooth = !hole || d < curve.min_radius();
    Deviation {
        max_um,
        right_side,
        area_error_mm2: smooth.then(|| area.abs() - steiner),
        area_allowed_mm2: p * 1e-4,
    }
}

/// The worst deviation by size class, and the cases past a tolerance.
pub struct Report {
    tolerance_um: f64,
    worst_by_size: std::collections::BTreeMap<u64, (f64, String)>,
    failures: Vec<String>,
}

/// The size classes reported, mm: each takes the sizes up to 1.5 times it.
const SIZE_CLASSES_MM: [u64; 5] = [1, 5, 20, 100, 500];

impl Report {
    /// A report checking every case against `tolerance_um`.
    pub fn new(tolerance_um: f64) -> Self {
        Report {
            tolerance_um,
            worst_by_size: Default::default(),
            failures: Vec::new(),
        }
    }

    /// The case `what`, of size `size_mm`, measured as `dev`.
    pub fn add(&mut self, size_mm: f64, what: String, dev: Deviation) {
        let class = (SIZE_CLASSES_MM.into_iter())
            .find(|&c| size_mm <= c as f64 * 1.5)
            .unwrap_or(1000);
        let entry = self.worst_by_size.entry(class).or_default();
        if dev.max_um >= entry.0 {
            *entry = (dev.max_um, what.clone());
        }
        if !dev.within(self.tolerance_um) {
            self.failures.push(format!("{what}: {dev:?}"));
        }
    }

    /// Print the worst by size (seen with `--nocapture`) and fail on any case past the
    /// tolerance.
    pub fn check(self, title: &str) {
        println!("{title}: the worst deviation, by size");
        for (size, (um, what)) in &self.worst_by_size {
            println!("  up to {size:>4} mm: {um:.4} µm ({what})");
        }
        assert!(
            self.failures.is_empty(),
            "{title}: {} case(s) past {} µm:\n{}",
            self.failures.len(),
            self.tolerance_um,
            self.failures.join("\n")
        );
    }
}

/// xorshift64*: a small deterministic generator, seeded by `KERFMETER_CURVE_SEED` when set.
pub struct Rng(u64);

impl Rng {
    /// The generator for `seed`, or for the seed in `KERFMETER_CURVE_SEED`.
    pub fn new(seed: u64) -> Self {
        let seed = std::env::var("KERFMETER_CURVE_SEED")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(seed);
        Rng(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }

    /// Uniform in [0, 1).
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}
