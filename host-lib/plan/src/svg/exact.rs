//! Exact curves for the SVG elements whose arcs usvg approximates: ellipses, elliptical arcs
//! (`A` with `rx ≠ ry`, any rotation), rounded rectangles with `rx ≠ ry`, and any arc (a circle
//! included) under a transform that is not a similarity (a skew, unequal scales).
//!
//! usvg (through svgtypes and kurbo) turns every arc into cubic Béziers of up to 90° each, held
//! in single precision. A circular arc in document space is recognised in those cubics and made
//! an exact arc again (see [`crate::geom::cubic_as_arc`]); an elliptical one cannot be: the
//! cubics stray up to 2.7·10⁻⁴ of the larger semi-axis from the ellipse (9.5 µm for semi-axes
//! of 40 and 20 mm), and offsetting them is not offsetting the ellipse. For an element with such an arc, its subpaths
//! are rebuilt here from the source instead, in double precision ([`read`]: the shape's
//! attributes, or its path data read with svgtypes), each arc in centre parameterisation
//! (`kurbo::Arc::from_svg_arc`, the conversion usvg itself makes), and drawn into document mm as
//! the exact ellipse composed with the element's transform (an affine image of an ellipse is an
//! ellipse), by biarcs within [`CURVE_TOLERANCE_MM`](crate::geom::CURVE_TOLERANCE_MM) of it; an
//! arc whose image is a circle stays an exact arc. Lines and Béziers of such an element are drawn
//! as its source gives them.
//!
//! The rebuilt subpaths mirror how usvg builds its path, so that subpath `k` is usvg's subpath `k`
//! and everything downstream (contours, open paths, names, writing back) is unchanged. They are
//! checked against what usvg drew ([`ExactPath::agrees`]): the same subpaths, each starting
//! where usvg's does, every segment ending (and every control point lying) where usvg's does
//! within the join tolerance, an arc drawn by usvg's cubics ending on it at equal steps of its
//! angle, closed alike. An element whose geometry cannot be read here (a length in `%`, `em` or
//! `ex`, which depend on the viewport or the font) or does not agree with usvg's is traced from
//! usvg's cubics as before, and named in a note ([`note_approximated`]).

mod frame;
mod read;

use roxmltree::Node;

use super::{P32, Seg};
use crate::geom::{Affine, PathSink, V2, v2};
use crate::outcome::PlanSummary;

/// One drawing command of a rebuilt subpath, in the element's own coordinates.
#[derive(Debug, Clone)]
enum Piece {
    /// A straight segment to the point.
    Line(V2),
    /// A quadratic Bézier: control point, end.
    Quad(V2, V2),
    /// A cubic Bézier: control points, end.
    Cubic(V2, V2, V2),
    /// An elliptical arc (centre parameterisation) ending at the point the source names.
    Arc(kurbo::Arc, V2),
}

impl Piece {
    /// Where the piece ends.
    fn end(&self) -> V2 {
        match *self {
            Piece::Line(p) | Piece::Quad(_, p) | Piece::Cubic(_, _, p) | Piece::Arc(_, p) => p,
        }
    }
}

/// One subpath, as usvg's path builder makes it: a start, pieces, and whether it closes.
#[derive(Debug, Clone)]
struct Subpath {
    start: V2,
    pieces: Vec<Piece>,
    closed: bool,
}

/// An element's geometry rebuilt from the source, subpath by subpath as usvg draws it.
#[derive(Debug, Clone, Default)]
pub(super) struct ExactPath {
    subpaths: Vec<Subpath>,
}

/// How an instance's curves are traced.
#[derive(Debug, Default)]
pub(super) enum Exactness {
    /// From usvg's path: it has no arc that is elliptical in document space (circular arcs are
    /// recovered exactly from usvg's cubics).
    #[default]
    Usvg,
    /// From its exact geometry, read from the source.
    Exact(Box<ExactPath>),
    /// From usvg's cubics although it may have elliptical arcs: its exact geometry could not be
    /// read here, or did not agree with what usvg drew.
    Approximated,
}

/// How the element `node`, drawn into document mm by usvg's map `to_doc` (directly, or
/// `cloned` through a `<use>`), is to be traced, and the map to trace and write it by: for an
/// element traced from its exact geometry, the same map in double precision where the source
/// gives it (see [`frame`]; `mm_per_px` is document mm per usvg pixel), else `to_doc`.
pub(super) fn exactness(
    node: Node,
    to_doc: Affine,
    mm_per_px: f64,
    cloned: bool,
) -> (Exactness, Affine) {
    if !may_be_elliptical(node, &to_doc) {
        return (Exactness::Usvg, to_doc);
    }
    match read::geometry(node) {
        Some(path) if path.is_elliptical_in(&to_doc) => {
            let exact_map = (!cloned).then(|| frame::to_doc(node, mm_per_px)).flatten();
            let map = exact_map.filter(|m| frame::agrees(m, &to_doc));
            (Exactness::Exact(Box::new(path)), map.unwrap_or(to_doc))
        }
        Some(_) => (Exactness::Usvg, to_doc),
        None => (Exactness::Approximated, to_doc),
    }
}

/// Whether the element may draw an arc that is elliptical in document space: a path with arcs,
/// an ellipse or a rounded rectangle whose `rx` and `ry` differ, or any of them (a circle too)
/// under a map that is not a similarity. (A cheap look at the source: most paths have no `A`.)
fn may_be_elliptical(node: Node, to_doc: &Affine) -> bool {
    let radii_differ = match (node.attribute("rx"), node.attribute("ry")) {
        (Some(rx), Some(ry)) => rx.trim() != ry.trim(),
        _ => false,
    };
    let rounded = node.has_attribute("rx") || node.has_attribute("ry");
    match node.tag_name().name() {
        "ellipse" => radii_differ || !to_doc.is_similarity(),
        "rect" => rounded && (radii_differ || !to_doc.is_similarity()),
        "circle" => !to_doc.is_similarity(),
        "path" => node
            .attribute("d")
            .is_some_and(|d| d.bytes().any(|b| b == b'a' || b == b'A')),
        _ => false,
    }
}

/// Say which elements with elliptical arcs were traced from usvg's cubics (`names`, by name).
pub(super) fn note_approximated(names: &[&str], summary: &mut PlanSummary) {
    if names.is_empty() {
        return;
    }
    let mut listed: Vec<String> = names.iter().take(3).map(|n| n.to_string()).collect();
    if names.len() > 3 {
        listed.push(format!("and {} more", names.len() - 3));
    }
    summary.notes.push(format!(
        "{} element(s) whose arcs may be elliptical were dilated from usvg's Bézier approximation of them (an elliptical arc's is up to 2.7·10⁻⁴ of its larger radius off), not the exact curve: a length in %, em or ex is not read exactly (give it in user or absolute units), or the geometry read did not agree with usvg's: {}",
        names.len(),
        listed.join("; ")
    ));
}

impl ExactPath {
    /// Whether any arc is elliptical (not a circle, to 10⁻⁹) once drawn into document space by
    /// `to_doc`.
    fn is_elliptical_in(&self, to_doc: &Affine) -> bool {
        let arcs = self.subpaths.iter().flat_map(|s| &s.pieces);
        arcs.filter_map(|p| match p {
            Piece::Arc(arc, _) => Some(arc),
            _ => None,
        })
        .any(|arc| image_radius(arc, to_doc).is_none())
    }

    /// Whether this is the geometry usvg drew as `drawn` (its subpaths, element coordinates):
    /// every point within `join_mm` of usvg's once drawn into document mm by `to_doc`.
    pub(super) fn agrees(&self, drawn: &[Vec<Seg>], to_doc: &Affine, join_mm: f64) -> bool {
        let near = |exact: V2, usvg: P32| {
            (to_doc.apply(exact) - to_doc.apply(usvg.v2())).length() <= join_mm
        };
        self.subpaths.len() == drawn.len()
            && (self.subpaths.iter().zip(drawn)).all(|(s, segs)| s.agrees(segs, &near))
    }

    /// Draw subpath `index` into `sink` in document mm (through `to_doc`). After each curve,
    /// `over_budget` is asked whether the vertices drawn are too many: then drawing stops and
    /// `true` is returned.
    pub(super) fn draw(
        &self,
        index: usize,
        to_doc: &Affine,
        sink: &mut PathSink,
        over_budget: &dyn Fn(&PathSink) -> bool,
    ) -> bool {
        let Some(sub) = self.subpaths.get(index) else {
            return false;
        };
        let doc = |p: V2| to_doc.apply(p);
        sink.move_to(doc(sub.start));
        for piece in &sub.pieces {
            match piece {
                Piece::Line(p) => {
                    sink.line_to(doc(*p));
                    continue;
                }
                Piece::Quad(a, b) => sink.quad_to(doc(*a), doc(*b)),
                Piece::Cubic(a, b, c) => sink.cubic_to(doc(*a), doc(*b), doc(*c)),
                Piece::Arc(arc, end) => draw_arc(arc, *end, to_doc, sink),
            }
            if over_budget(sink) {
                return true;
            }
        }
        if sub.closed {
            sink.close();
        }
        false
    }
}

impl Subpath {
    /// Whether usvg's subpath `segs` draws this one, points compared by `near`.
    fn agrees(&self, segs: &[Seg], near: &dyn Fn(V2, P32) -> bool) -> bool {
        let mut segs = segs.iter().peekable();
        if !matches!(segs.next(), Some(Seg::M(p)) if near(self.start, *p)) {
            return false;
        }
        for piece in &self.pieces {
            let agrees = match (piece, segs.next()) {
                (Piece::Line(p), Some(Seg::L(q))) => near(*p, *q),
                (Piece::Quad(a, b), Some(Seg::Q(qa, qb))) => near(*a, *qa) && near(*b, *qb),
                (Piece::Cubic(a, b, c), Some(Seg::C(qa, qb, qc))) => {
                    near(*a, *qa) && near(*b, *qb) && near(*c, *qc)
                }
                (Piece::Arc(arc, end), Some(&Seg::C(_, _, q))) => {
                    let mut ends = vec![q];
                    while !near(*end, *ends.last().expect("one end")) {
                        match segs.next_if(|s| matches!(s, Seg::C(..))) {
                            Some(&Seg::C(_, _, q)) => ends.push(q),
                            _ => return false,
                        }
                    }
                    arc_agrees(arc, &ends, near)
                }
                _ => false,
            };
            if !agrees {
                return false;
            }
        }
        let closes = segs.next_if(|s| matches!(s, Seg::Z)).is_some();
        closes == self.closed && segs.next().is_none()
    }
}

/// Whether usvg's cubics ending at `ends` draw `arc`: kurbo splits an arc into equal steps of its
/// angle, so the `k`-th cubic ends at the point of angle `start + k·sweep/n`.
fn arc_agrees(arc: &kurbo::Arc, ends: &[P32], near: &dyn Fn(V2, P32) -> bool) -> bool {
    let n = ends.len() as f64;
    (ends.iter().enumerate()).all(|(k, &q)| {
        let angle = arc.start_angle + arc.sweep_angle * (k + 1) as f64 / n;
        near(ellipse_at(arc, angle).0, q)
    })
}

/// The point of `arc`'s ellipse at `angle` (its parameter, radians) and the derivative by the
/// angle, element coordinates.
fn ellipse_at(arc: &kurbo::Arc, angle: f64) -> (V2, V2) {
    let (sin, cos) = angle.sin_cos();
    let (sin_r, cos_r) = arc.x_rotation.sin_cos();
    let (rx, ry) = (arc.radii.x, arc.radii.y);
    let rotate = |x: f64, y: f64| v2(cos_r * x - sin_r * y, sin_r * x + cos_r * y);
    let p = v2(arc.center.x, arc.center.y) + rotate(rx * cos, ry * sin);
    (p, rotate(-rx * sin, ry * cos))
}

/// The linear map taking the unit circle's point at angle θ to `arc`'s ellipse's point at θ,
/// less the centre, then through `to_doc`'s linear part.
fn unit_circle_map(arc: &kurbo::Arc, to_doc: &Affine) -> Affine {
    let (sin_r, cos_r) = arc.x_rotation.sin_cos();
    let x_axis = to_doc.apply_vector(v2(cos_r, sin_r).scale(arc.radii.x));
    let y_axis = to_doc.apply_vector(v2(-sin_r, cos_r).scale(arc.radii.y));
    Affine {
        a: x_axis.x,
        b: x_axis.y,
        c: y_axis.x,
        d: y_axis.y,
        e: 0.0,
        f: 0.0,
    }
}

/// The radius of `arc`'s image through `to_doc` when that image is a circle (its semi-axes
/// within 10⁻⁹ of each other), else `None`.
fn image_radius(arc: &kurbo::Arc, to_doc: &Affine) -> Option<f64> {
    let (major, minor, _) = unit_circle_map(arc, to_doc).circle_image(1.0);
    (major - minor <= 1e-9 * major).then_some((major + minor) / 2.0)
}

/// Draw `arc` (ending at `end`) into `sink` in document mm: exact arcs of at most 90° where its
/// image through `to_doc` is a circle, biarcs of its image otherwise.
fn draw_arc(arc: &kurbo::Arc, end: V2, to_doc: &Affine, sink: &mut PathSink) {
    let (start, sweep) = (arc.start_angle, arc.sweep_angle);
    if image_radius(arc, to_doc).is_some() {
        // The image of the unit circle is a circle: angles map one to one, reversed by a mirror.
        let mirror = unit_circle_map(arc, to_doc).det() < 0.0;
        let pieces = (sweep.abs() / std::f64::consts::FRAC_PI_2).ceil().max(1.0);
        let doc_sweep = if mirror { -sweep } else { sweep } / pieces;
        let bulge = (doc_sweep / 4.0).tan();
        for k in 1..pieces as usize {
            let angle = start + sweep * k as f64 / pieces;
            sink.segment_to(to_doc.apply(ellipse_at(arc, angle).0), bulge);
        }
        sink.segment_to(to_doc.apply(end), bulge);
        return;
    }
    let curve = |u: f64| {
        let (p, d) = ellipse_at(arc, start + sweep * u);
        (to_doc.apply(p), to_doc.apply_vector(d.scale(sweep)))
    };
    sink.curve(&curve, to_doc.apply(end));
}

#[cfg(test)]
mod tests;
