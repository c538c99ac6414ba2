//! Geometry shared by the gauge generator and the dilation: contours as `cavalier_contours`
//! polylines (straight segments and circular arcs, an arc stored as the *bulge* `tan(θ/4)` of the
//! segment that starts at a vertex, positive = turning towards +y from +x), 2-D affine maps, and
//! turning what the file formats draw (lines, circular arcs, Bézier curves) into such polylines.
//!
//! * Circular arcs stay exact arcs.
//! * A cubic Bézier that is the standard approximation of a circular arc (arm length
//!   `4/3·tan(θ/4)·r`, symmetric — what `usvg`/`kurbo` make of every SVG `A` command, `<circle>`
//!   and rounded `<rect>`, and what Illustrator writes for circles) is recognised and turned back
//!   into that exact arc.
//! * Any other curve (a free-form Bézier, an elliptical arc) is approximated by *biarcs* (pairs of
//!   tangent-continuous circular arcs) to within [`CURVE_TOLERANCE_MM`], measured at points of
//!   the curve against the arcs as they are written (a nearly straight one as its chord).

use cavalier_contours::core::math::Vector2;
use cavalier_contours::polyline::{
    PlineCreation, PlineSource, PlineSourceMut, PlineVertex, Polyline, seg_arc_radius_and_center,
    seg_closest_point,
};

/// A contour: straight segments and circular arcs (see the module doc for the bulge convention).
pub type Pline = Polyline<f64>;

/// A point or vector, mm unless said otherwise.
pub type V2 = Vector2<f64>;

/// How far an approximated curve (a free-form Bézier, an elliptical arc, the gauge's spiral) may
/// stray from the true curve, mm (0.05 µm).
pub const CURVE_TOLERANCE_MM: f64 = 5e-5;

/// A fitted arc that strays less than this from its chord, mm, is written as its chord (half
/// the curve tolerance; the fit is checked with its arcs so straightened, so the two together
/// stay within the tolerance).
const FLAT_SAGITTA_MM: f64 = CURVE_TOLERANCE_MM / 2.0;

/// Shorthand for a vector.
pub fn v2(x: f64, y: f64) -> V2 {
    Vector2::new(x, y)
}

/// A 2-D affine map `x' = a·x + c·y + e`, `y' = b·x + d·y + f` (the order of SVG's
/// `matrix(a b c d e f)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// Coefficients, see the type's doc.
    pub a: f64,
    /// Coefficients, see the type's doc.
    pub b: f64,
    /// Coefficients, see the type's doc.
    pub c: f64,
    /// Coefficients, see the type's doc.
    pub d: f64,
    /// Coefficients, see the type's doc.
    pub e: f64,
    /// Coefficients, see the type's doc.
    pub f: f64,
}

impl Affine {
    /// The identity.
    pub const IDENTITY: Self = Self {
        a: 1.0,
        b: 0.0,
        c: 0.0,
        d: 1.0,
        e: 0.0,
        f: 0.0,
    };

    /// A uniform scale about the origin.
    pub fn scale(s: f64) -> Self {
        Self {
            a: s,
            d: s,
            ..Self::IDENTITY
        }
    }

    /// Map a point.
    pub fn apply(&self, p: V2) -> V2 {
        v2(
            self.a * p.x + self.c * p.y + self.e,
            self.b * p.x + self.d * p.y + self.f,
        )
    }

    /// `self` after `first`: `self.then_after(first).apply(p) == self.apply(first.apply(p))`.
    pub fn then_after(&self, first: &Affine) -> Affine {
        Affine {
            a: self.a * first.a + self.c * first.b,
            b: self.b * first.a + self.d * first.b,
            c: self.a * first.c + self.c * first.d,
            d: self.b * first.c + self.d * first.d,
            e: self.a * first.e + self.c * first.f + self.e,
            f: self.b * first.e + self.d * first.f + self.f,
        }
    }

    /// Map a vector (the linear part alone: a direction, a tangent).
    pub fn apply_vector(&self, v: V2) -> V2 {
        v2(self.a * v.x + self.c * v.y, self.b * v.x + self.d * v.y)
    }

    /// Whether the map is a similarity (rotation, uniform scale, translation, perhaps a mirror),
    /// which keeps circles circles, to a relative 10⁻⁹.
    pub fn is_similarity(&self) -> bool {
        let size = self.a.abs() + self.b.abs() + self.c.abs() + self.d.abs();
        let tol = 1e-9 * size;
        let rotation = (self.a - self.d).abs() <= tol && (self.b + self.c).abs() <= tol;
        let mirrored = (self.a + self.d).abs() <= tol && (self.b - self.c).abs() <= tol;
        size > 0.0 && (rotation || mirrored)
    }

    /// Determinant of the linear part (negative: the map mirrors).
    pub fn det(&self) -> f64 {
        self.a * self.d - self.b * self.c
    }

    /// The inverse map, if the map is not degenerate.
    pub fn inverse(&self) -> Option<Affine> {
        let det = self.det();
        if !det.is_finite() || det.abs() < 1e-300 {
            return None;
        }
        let (a, b, c, d) = (self.d / det, -self.b / det, -self.c / det, self.a / det);
        Some(Affine {
            a,
            b,
            c,
            d,
            e: -(a * self.e + c * self.f),
            f: -(b * self.e + d * self.f),
        })
    }

    /// Geometric-mean scale factor of the linear part (`√|det|`): how lengths scale on average.
    pub fn mean_scale(&self) -> f64 {
        self.det().abs().sqrt()
    }

    /// The ellipse that the circle of radius `r` becomes under this map: semi-axes `(rx, ry)`
    /// (`rx ≥ ry`) and the rotation of the `rx` axis, radians.
    pub fn circle_image(&self, r: f64) -> (f64, f64, f64) {
        // The image of the unit circle is {A·u}; its axes are the eigenvectors of A·Aᵀ.
        let m00 = self.a * self.a + self.c * self.c;
        let m11 = self.b * self.b + self.d * self.d;
        let m01 = self.a * self.b + self.c * self.d;
        let mean = (m00 + m11) / 2.0;
        let diff = (((m00 - m11) / 2.0).powi(2) + m01 * m01).sqrt();
        let l1 = mean + diff;
        let l2 = (mean - diff).max(0.0);
        let rotation = 0.5 * (2.0 * m01).atan2(m00 - m11);
        (r * l1.sqrt(), r * l2.sqrt(), rotation)
    }
}

/// Centre, radius and angles of the arc from `p0` to `p1` with `bulge` (≠ 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcGeom {
    /// Centre.
    pub center: V2,
    /// Radius (> 0).
    pub radius: f64,
    /// Angle of `p0` seen from the centre, radians.
    pub start_angle: f64,
    /// Signed sweep, radians (positive: towards +y from +x).
    pub sweep: f64,
}

/// The circle an arc segment lies on, or `None` for a straight segment.
pub fn arc_geom(p0: V2, p1: V2, bulge: f64) -> Option<ArcGeom> {
    // cavalier_contours takes a bulge under 10⁻⁸ for a straight segment (the arc's sagitta is
    // then under 0.005 µm per metre of chord), and asserts so in its arc functions.
    if bulge.abs() < 1e-8 || ((p1.x - p0.x).abs() < 1e-8 && (p1.y - p0.y).abs() < 1e-8) {
        return None;
    }
    let (radius, center) = seg_arc_radius_and_center(
        PlineVertex::new(p0.x, p0.y, bulge),
        PlineVertex::new(p1.x, p1.y, 0.0),
    );
    Some(ArcGeom {
        center,
        radius,
        start_angle: (p0.y - center.y).atan2(p0.x - center.x),
        sweep: 4.0 * bulge.atan(),
    })
}

/// The point at parameter `t ∈ [0, 1]` along the segment from `p0` to `p1` with `bulge`.
pub fn segment_point(p0: V2, p1: V2, bulge: f64, t: f64) -> V2 {
    match arc_geom(p0, p1, bulge) {
        None => p0 + (p1 - p0).scale(t),
        Some(g) => {
            let angle = g.start_angle + g.sweep * t;
            g.center + v2(angle.cos(), angle.sin()).scale(g.radius)
        }
    }
}

/// Distance from `q` to the segment from `p0` to `p1` with `bulge`.
pub fn segment_distance(p0: V2, p1: V2, bulge: f64, q: V2) -> f64 {
    let c = seg_closest_point(
        PlineVertex::new(p0.x, p0.y, bulge),
        PlineVertex::new(p1.x, p1.y, 0.0),
        q,
        1e-12,
    );
    (q - c).length()
}

/// Signed area and area centroid of a closed polyline (counter-clockwise in a y-up frame =
/// positive area), arcs included.
pub fn area_and_centroid(pline: &Pline) -> (f64, V2) {
    let mut area = 0.0;
    let mut moment = v2(0.0, 0.0);
    let n = pline.vertex_count();
    for i in 0..n {
        let v = pline.at(i);
        let w = pline.at((i + 1) % n);
        let (p0, p1) = (v2(v.x, v.y), v2(w.x, w.y));
        // Triangle (origin, p0, p1).
        let tri = p0.perp_dot(p1) / 2.0;
        area += tri;
        moment = moment + (p0 + p1).scale(tri / 3.0);
        // Circular segment between the chord and the arc.
        if let Some(g) = arc_geom(p0, p1, v.bulge) {
            let theta = g.sweep.abs();
            let seg_area = g.radius * g.radius / 2.0 * (theta - theta.sin());
            if seg_area > 0.0 {
                let mid_angle = g.start_angle + g.sweep / 2.0;
                let dist =
                    4.0 * g.radius * (theta / 2.0).sin().powi(3) / (3.0 * (theta - theta.sin()));
                let c = g.center + v2(mid_angle.cos(), mid_angle.sin()).scale(dist);
                let signed = seg_area * g.sweep.signum();
                area += signed;
                moment = moment + c.scale(signed);
            }
        }
    }
    let centroid = if area.abs() > 0.0 {
        moment.scale(1.0 / area)
    } else {
        pline
            .get(0)
            .map(|v| v2(v.x, v.y))
            .unwrap_or_else(|| v2(0.0, 0.0))
    };
    (area, centroid)
}

/// Apply an affine map to a polyline. Arcs must stay circular, so the map must be a similarity
/// (uniform scale, rotation, translation, optionally a mirror); a mirror negates the bulges.
pub fn transform_similarity(pline: &Pline, m: &Affine) -> Pline {
    let mirror = m.det() < 0.0;
    let mut out = Pline::with_capacity(pline.vertex_count(), pline.is_closed());
    for v in pline.iter_vertexes() {
        let p = m.apply(v2(v.x, v.y));
        out.add(p.x, p.y, if mirror { -v.bulge } else { v.bulge });
    }
    out
}

/// Reverse a closed polyline's direction (same curve, opposite orientation).
pub fn reversed(pline: &Pline) -> Pline {
    let mut p = pline.clone();
    p.invert_direction_mut();
    p
}

/// If the cubic Bézier `p0 p1 p2 p3` is the standard approximation of a circular arc (≤ 90°
/// per piece as `kurbo` and Illustrator make them), the bulge of that arc.
///
/// `eps` is the absolute uncertainty of the control points (their rounding), mm.
pub fn cubic_as_arc(p0: V2, p1: V2, p2: V2, p3: V2, eps: f64) -> Option<f64> {
    let arm0 = p1 - p0;
    let arm1 = p3 - p2;
    let chord = p3 - p0;
    let (l0, l1, lc) = (arm0.length(), arm1.length(), chord.length());
    if l0 <= 4.0 * eps || l1 <= 4.0 * eps || lc <= 4.0 * eps {
        return None;
    }
    // Half the sweep: the angle from the start tangent to the chord, and from the chord to the
    // end tangent (equal for a circular arc).
    let half = arm0.perp_dot(chord).atan2(arm0.dot(chord));
    let half_end = chord.perp_dot(arm1).atan2(chord.dot(arm1));
    let angle_tol = 1e-6 + 4.0 * eps / l0.min(l1);
    if half.abs() < 1e-7 || (half - half_end).abs() > angle_tol {
        return None;
    }
    let sweep = 2.0 * half;
    if sweep.abs() > std::f64::consts::FRAC_PI_2 * 1.0001 {
        return None;
    }
    let radius = lc / (2.0 * half.abs().sin());
    let arm = 4.0 / 3.0 * (sweep.abs() / 4.0).tan() * radius;
    let arm_tol = 1e-4 * arm + 4.0 * eps;
    if (l0 - arm).abs() > arm_tol || (l1 - arm).abs() > arm_tol {
        return None;
    }
    Some((sweep / 4.0).tan())
}

/// The bulge of a fitted arc from `a` to `b`, or 0 (a straight segment) when the arc is nearly
/// straight (turning less than 0.0004 rad) and strays less than [`FLAT_SAGITTA_MM`] from its
/// chord: a nearly straight stretch of a curve (a spline whose control points sit a few nm off a
/// line, as 6-decimal rounding leaves them) fits arcs of kilometres' radius, which readers refuse
/// as far beyond any bed. The short, curved arcs of a tight curve are kept.
fn straightened(a: V2, b: V2, bulge: f64) -> f64 {
    // The sagitta is half the chord times the bulge.
    let flat = bulge.abs() < 1e-4 && (b - a).length() / 2.0 * bulge.abs() < FLAT_SAGITTA_MM;
    if flat { 0.0 } else { bulge }
}

/// Bulge of the arc from `p` (leaving along unit tangent `t`) to `q`.
fn bulge_from_start_tangent(p: V2, t: V2, q: V2) -> f64 {
    let chord = q - p;
    let half = t.perp_dot(chord).atan2(t.dot(chord));
    (half / 2.0).tan()
}

/// Bulge of the arc from `p` to `q` arriving along unit tangent `t`.
fn bulge_from_end_tangent(p: V2, q: V2, t: V2) -> f64 {
    let chord = q - p;
    let half = chord.perp_dot(t).atan2(chord.dot(t));
    (half / 2.0).tan()
}

/// The equal-tangent-length biarc from `p0` (unit tangent `t0`) to `p1` (unit tangent `t1`):
/// the joint point and the two bulges.
fn biarc(p0: V2, t0: V2, p1: V2, t1: V2) -> Option<(V2, f64, f64)> {
    let v = p1 - p0;
    let vv = v.dot(v);
    if vv <= 0.0 {
        return None;
    }
    let t = t0 + t1;
    let vt = v.dot(t);
    let denom = 2.0 * (1.0 - t0.dot(t1));
    let d = if denom.abs() < 1e-12 {
        let vt1 = v.dot(t1);
        if vt1.abs() < 1e-300 {
            return None;
        }
        vv / (4.0 * vt1)
    } else {
        (-vt + (vt * vt + denom * vv).sqrt()) / denom
    };
    if !d.is_finite() || d <= 0.0 {
        return None;
    }
    let joint = (p0 + p1 + (t0 - t1).scale(d)).scale(0.5);
    Some((
        joint,
        bulge_from_start_tangent(p0, t0, joint),
        bulge_from_end_tangent(joint, p1, t1),
    ))
}

/// How many times a curve is halved at most while fitting: 65,536 biarc pairs, far more than
/// any drawn curve needs at the tolerances used.
const MAX_FIT_DEPTH: u32 = 16;
/// Beyond this distance from the origin (drawing units, mm for the readers) a curve is not
/// refined: no plan is that large, and f64 cannot hold such a curve to a µm.
const FIT_LIMIT: f64 = 1e7;

/// Approximate the curve `f` (position and tangent at a parameter) between `t0` and `t1` by
/// biarcs within `tol`, appending vertices (each with the bulge of the arc that leaves it) to
/// `out`. The end point `f(t1)` itself is *not* appended. Returns the largest deviation seen.
pub fn fit_biarcs<F>(f: &F, t0: f64, t1: f64, tol: f64, out: &mut Vec<PlineVertex<f64>>) -> f64
where
    F: Fn(f64) -> (V2, V2),
{
    fit_biarcs_rec(f, t0, t1, tol, out, 0)
}

fn fit_biarcs_rec<F>(
    f: &F,
    t0: f64,
    t1: f64,
    tol: f64,
    out: &mut Vec<PlineVertex<f64>>,
    depth: u32,
) -> f64
where
    F: Fn(f64) -> (V2, V2),
{
    // The deviation is measured at this many points of the curve; where it comes near the
    // tolerance (the largest deviation can lie between two of them, a few per cent higher), at
    // four times as many, with 1 % to spare (between those it is a fraction of a per cent
    // higher).
    const SAMPLES: usize = 12;
    const NEAR_TOLERANCE: f64 = 0.8;
    const SPARE: f64 = 1.01;
    let (p0, d0) = f(t0);
    let (p1, d1) = f(t1);
    let unit = |d: V2| {
        let l = d.length();
        (l > 0.0).then(|| d.scale(1.0 / l))
    };
    let fitted = match (unit(d0), unit(d1)) {
        (Some(u0), Some(u1)) => biarc(p0, u0, p1, u1),
        _ => None,
    };
    let err_at = |segments: &[(V2, V2, f64)], samples: usize| {
        (1..=samples)
            .map(|i| {
                let t = t0 + (t1 - t0) * i as f64 / (samples + 1) as f64;
                let q = f(t).0;
                segments
                    .iter()
                    .map(|&(a, b, bulge)| segment_distance(a, b, bulge, q))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max)
    };
    let err = |segments: &[(V2, V2, f64)]| {
        let coarse = err_at(segments, SAMPLES);
        let near = coarse > NEAR_TOLERANCE * tol && coarse <= tol;
        if near {
            coarse.max(SPARE * err_at(segments, 4 * SAMPLES))
        } else {
            coarse
        }
    };
    // Measured as written: nearly straight arcs as their chords.
    let segments = match fitted {
        Some((joint, b0, b1)) => vec![
            (p0, joint, straightened(p0, joint, b0)),
            (joint, p1, straightened(joint, p1, b1)),
        ],
        None => vec![(p0, p1, 0.0)],
    };
    let error = err(&segments);
    // A curve kilometres out (a hostile file's circle of radius 1e25 through a skewing INSERT)
    // never meets the tolerance in f64: it is left coarse, and refused later for its
    // coordinates, instead of being split 2^24 ways (gigabytes and minutes: a fuzz find).
    let far = |p: V2| !(p.x.abs() <= FIT_LIMIT && p.y.abs() <= FIT_LIMIT);
    if error <= tol || depth >= MAX_FIT_DEPTH || far(p0) || far(p1) || (t1 - t0).abs() < 1e-12 {
        for (a, _, bulge) in segments {
            out.push(PlineVertex::new(a.x, a.y, bulge));
        }
        return error;
    }
    let tm = (t0 + t1) / 2.0;
    let e0 = fit_biarcs_rec(f, t0, tm, tol, out, depth + 1);
    let e1 = fit_biarcs_rec(f, tm, t1, tol, out, depth + 1);
    e0.max(e1)
}

/// One subpath of a drawing turned into a polyline.
#[derive(Debug, Clone)]
pub struct Subpath {
    /// The geometry; `is_closed()` tells whether the subpath closes.
    pub pline: Pline,
}

/// The shortest segment a [`PathSink`] keeps, mm, however precise its coordinates.
const EMPTY_MIN_MM: f64 = 1e-5;

/// Builds [`Subpath`]s from drawing commands (move, line, arc, quadratic and cubic Bézier, close)
/// given in mm.
#[derive(Debug)]
pub struct PathSink {
    /// Ends closer than this meet (closing a subpath).
    pub join_eps_mm: f64,
    /// Rounding uncertainty of the incoming coordinates, for recognising arcs in cubics.
    pub coord_eps_mm: f64,
    done: Vec<Subpath>,
    current: Vec<PlineVertex<f64>>,
}

impl PathSink {
    /// A sink; `join_eps_mm` decides when points coincide, `coord_eps_mm` is how precise the
    /// incoming coordinates are.
    pub fn new(join_eps_mm: f64, coord_eps_mm: f64) -> Self {
        Self {
            join_eps_mm,
            coord_eps_mm,
            done: Vec::new(),
            current: Vec::new(),
        }
    }

    fn last(&self) -> Option<V2> {
        self.current.last().map(|v| v2(v.x, v.y))
    }

    /// Start a new subpath at `p`.
    pub fn move_to(&mut self, p: V2) {
        self.flush(false);
        self.current.push(PlineVertex::new(p.x, p.y, 0.0));
    }

    /// A segment (straight for `bulge == 0`) from the current point to `p`.
    pub fn segment_to(&mut self, p: V2, bulge: f64) {
        let Some(last) = self.last() else {
            self.move_to(p);
            return;
        };
        if (p - last).length() <= self.empty_mm() {
            return;
        }
        if let Some(v) = self.current.last_mut() {
            v.bulge = bulge;
        }
        self.current.push(PlineVertex::new(p.x, p.y, 0.0));
    }

    /// A straight segment to `p`.
    pub fn line_to(&mut self, p: V2) {
        self.segment_to(p, 0.0);
    }

    /// A cubic Bézier to `p3`: an exact arc when it is one (see [`cubic_as_arc`]), biarcs
    /// otherwise.
    pub fn cubic_to(&mut self, p1: V2, p2: V2, p3: V2) {
        let Some(p0) = self.last() else {
            self.move_to(p3);
            return;
        };
        if let Some(bulge) = cubic_as_arc(p0, p1, p2, p3, self.coord_eps_mm) {
            self.segment_to(p3, bulge);
            return;
        }
        let curve = |t: f64| {
            let u = 1.0 - t;
            let p = p0.scale(u * u * u)
                + p1.scale(3.0 * u * u * t)
                + p2.scale(3.0 * u * t * t)
                + p3.scale(t * t * t);
            let mut d = (p1 - p0).scale(3.0 * u * u)
                + (p2 - p1).scale(6.0 * u * t)
                + (p3 - p2).scale(3.0 * t * t);
            if d.length() < 1e-12 {
                // A cusp or a zero-length arm: the tangent is the second derivative's direction.
                d = (p2 - p1.scale(2.0) + p0).scale(6.0 * u)
                    + (p3 - p2.scale(2.0) + p1).scale(6.0 * t);
                if t > 0.5 {
                    // Near the end the second derivative points back along the curve.
                    d = d.scale(-1.0);
                }
            }
            (p, d)
        };
        self.curve(&curve, p3);
    }

    /// A quadratic Bézier to `p2`.
    pub fn quad_to(&mut self, p1: V2, p2: V2) {
        let Some(p0) = self.last() else {
            self.move_to(p2);
            return;
        };
        // Degree elevation is exact.
        self.cubic_to(
            p0 + (p1 - p0).scale(2.0 / 3.0),
            p2 + (p1 - p2).scale(2.0 / 3.0),
            p2,
        );
    }

    /// Any smooth curve from the current point to `end` (`f` gives position and tangent on
    /// `[0, 1]`), by biarcs.
    pub fn curve<F: Fn(f64) -> (V2, V2)>(&mut self, f: &F, end: V2) {
        let mut vertices = Vec::new();
        fit_biarcs(f, 0.0, 1.0, CURVE_TOLERANCE_MM, &mut vertices);
        let before = self.current.len();
        for w in 0..vertices.len() {
            let next = vertices.get(w + 1).map(|v| v2(v.x, v.y)).unwrap_or(end);
            self.segment_to(next, vertices[w].bulge);
        }
        // A last piece too short to keep leaves the curve ending at its last fitted vertex: that
        // vertex moves to the curve's end instead, so that the curve ends where it was drawn to
        // (boxes.py's loop at an inner corner ends at the corner: ending a few µm short of it
        // left the loop's tail on the contour, tilting the edge that followed).
        if self.current.len() > before
            && let Some(v) = self.current.last_mut()
        {
            (v.x, v.y) = (end.x, end.y);
        }
    }

    /// Segments no longer than this are left out, mm: the rounding of the incoming coordinates,
    /// at least 10 nm (shorter, `cavalier_contours` takes a segment's ends for one point).
    /// [`join_eps_mm`](Self::join_eps_mm), which may be several times larger, only decides
    /// whether ends meet.
    fn empty_mm(&self) -> f64 {
        self.coord_eps_mm.max(EMPTY_MIN_MM)
    }

    /// The vertices drawn so far.
    pub fn vertex_count(&self) -> usize {
        let done: usize = self.done.iter().map(|s| s.pline.vertex_count()).sum();
        done + self.current.len()
    }

    /// Close the current subpath (back to its start).
    pub fn close(&mut self) {
        self.flush(true);
    }

    fn flush(&mut self, close: bool) {
        let mut vertices = std::mem::take(&mut self.current);
        if vertices.len() < 2 {
            return;
        }
        let first = v2(vertices[0].x, vertices[0].y);
        let last = vertices.last().map(|v| v2(v.x, v.y)).unwrap_or(first);
        let meets = (last - first).length() <= self.join_eps_mm;
        let closed = close || (meets && vertices.len() > 2);
        if closed && meets {
            // The closing segment is the one that arrived at the (duplicate) last vertex.
            vertices.pop();
        }
        if closed && vertices.len() < 2 {
            return;
        }
        let mut pline = Pline::with_capacity(vertices.len(), closed);
        for v in vertices {
            pline.add_vertex(v);
        }
        self.done.push(Subpath { pline });
    }

    /// All subpaths, in drawing order.
    pub fn finish(mut self) -> Vec<Subpath> {
        self.flush(false);
        self.done
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn affine_inverse_and_composition() {
        let m = Affine {
            a: 2.0,
            b: 0.5,
            c: -0.3,
            d: 1.5,
            e: 10.0,
            f: -4.0,
        };
        let inv = m.inverse().unwrap();
        let p = v2(3.0, 7.0);
        let q = inv.apply(m.apply(p));
        assert!((q - p).length() < 1e-12);
        let id = inv.then_after(&m);
        assert!((id.apply(p) - p).length() < 1e-12);
    }

    #[test]
    fn circle_image_axes() {
        // A scale (3, 1) rotated by 30°: semi-axes 3r and r, major axis at 30°.
        let (c, s) = ((PI / 6.0).cos(), (PI / 6.0).sin());
        let m = Affine {
            a: 3.0 * c,
            b: 3.0 * s,
            c: -s,
            d: c,
            e: 0.0,
            f: 0.0,
        };
        let (rx, ry, rot) = m.circle_image(2.0);
        assert!((rx - 6.0).abs() < 1e-12 && (ry - 2.0).abs() < 1e-12);
        assert!((rot - PI / 6.0).abs() < 1e-12, "{rot}");
    }

    #[test]
    fn the_standard_cubic_of_a_quarter_circle_is_an_arc_and_others_are_not() {
        let k = 4.0 / 3.0 * (PI / 8.0).tan();
        let (p0, p1, p2, p3) = (v2(1.0, 0.0), v2(1.0, k), v2(k, 1.0), v2(0.0, 1.0));
        let bulge = cubic_as_arc(p0, p1, p2, p3, 1e-9).unwrap();
        assert!((bulge - (PI / 8.0).tan()).abs() < 1e-12);
        // Clockwise: negative bulge.
        assert!(cubic_as_arc(p3, p2, p1, p0, 1e-9).unwrap() < 0.0);
        // A different arm length is a free-form curve.
        assert!(cubic_as_arc(p0, v2(1.0, 0.7), v2(0.7, 1.0), p3, 1e-9).is_none());
    }

    #[test]
    fn biarcs_follow_a_curve_within_tolerance() {
        // A parabola y = x², x ∈ [0, 2].
        let f = |t: f64| (v2(2.0 * t, 4.0 * t * t), v2(2.0, 8.0 * t));
        let mut out = Vec::new();
        let err = fit_biarcs(&f, 0.0, 1.0, 1e-5, &mut out);
        assert!(err <= 1e-5);
        // Every sample of the curve is within tolerance of the polyline.
        let mut pts: Vec<(V2, f64)> = out.iter().map(|v| (v2(v.x, v.y), v.bulge)).collect();
        pts.push((v2(2.0, 4.0), 0.0));
        for i in 0..=1000 {
            let q = f(i as f64 / 1000.0).0;
            let d = pts
                .windows(2)
                .map(|w| segment_distance(w[0].0, w[1].0, w[0].1, q))
                .fold(f64::INFINITY, f64::min);
            assert!(d < 2e-5, "sample {i}: {d}");
        }
    }

    #[test]
    fn area_and_centroid_of_a_disc_and_a_rectangle() {
        let mut disc = Pline::new_closed();
        disc.add(3.0, 1.0, 1.0);
        disc.add(1.0, 1.0, 1.0);
        let (a, c) = area_and_centroid(&disc);
        assert!((a - PI).abs() < 1e-12, "{a}");
        assert!((c - v2(2.0, 1.0)).length() < 1e-12);
        let mut rect = Pline::new_closed();
        for (x, y) in [(0.0, 0.0), (4.0, 0.0), (4.0, 2.0), (0.0, 2.0)] {
            rect.add(x, y, 0.0);
        }
        let (a, c) = area_and_centroid(&rect);
        assert!((a - 8.0).abs() < 1e-12 && (c - v2(2.0, 1.0)).length() < 1e-12);
        // A half disc: centroid at 4r/3π from the diameter.
        let mut half = Pline::new_closed();
        half.add(1.0, 0.0, 1.0);
        half.add(-1.0, 0.0, 0.0);
        let (a, c) = area_and_centroid(&half);
        assert!((a - PI / 2.0).abs() < 1e-12);
        assert!((c.y - 4.0 / (3.0 * PI)).abs() < 1e-12 && c.x.abs() < 1e-12);
    }

    #[test]
    fn sink_closes_and_recovers_arcs() {
        let k = 4.0 / 3.0 * (PI / 8.0).tan();
        let mut s = PathSink::new(1e-9, 1e-12);
        s.move_to(v2(1.0, 0.0));
        s.cubic_to(v2(1.0, k), v2(k, 1.0), v2(0.0, 1.0));
        s.line_to(v2(0.0, 0.0));
        s.close();
        s.move_to(v2(5.0, 5.0));
        s.line_to(v2(6.0, 5.0));
        let subpaths = s.finish();
        assert_eq!(subpaths.len(), 2);
        assert!(subpaths[0].pline.is_closed());
        assert_eq!(subpaths[0].pline.vertex_count(), 3);
        assert!(subpaths[0].pline.at(0).bulge > 0.0);
        assert!(!subpaths[1].pline.is_closed());
        let (a, _) = area_and_centroid(&subpaths[0].pline);
        assert!((a - PI / 4.0).abs() < 1e-12);
    }
}
