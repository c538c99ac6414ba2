//! An element's geometry read from the source in double precision, built as usvg builds its
//! path (usvg 0.49's `parser/shapes.rs`, svgtypes' `SimplifyingPathParser`, tiny-skia's
//! `PathBuilder`) except that each arc stays the elliptical arc it is:
//!
//! * `<ellipse>` and `<circle>`: a start at (cx + rx, cy) and four quarter arcs, closed.
//! * `<rect>` with rounded corners: four sides and four corner arcs, `rx`/`ry` resolved (one
//!   given stands for both, a negative one is not given) and clamped to half the width and
//!   height as usvg does; one with `rx` 0 has no arc, and is left to usvg.
//! * `<path>`: its data read with svgtypes' `PathParser`, made absolute the way svgtypes'
//!   simplifying parser does (`H`/`V` as lines, `S`/`T` with their reflected control points, a
//!   segment after a close starting at the subpath's start), an `A` in centre parameterisation
//!   by `kurbo::Arc::from_svg_arc` (a straight line where kurbo says it is one), up to the
//!   data's first error, where usvg stops too.
//!
//! Lengths are in user units: a number, or one in `px`, `in`, `cm`, `mm`, `pt` or `pc` at
//! usvg's 96 px per inch. One in `%`, `em` or `ex` (relative to the viewport or the font) is not
//! read here: the element is left to usvg. A value that does not parse is absent, as for usvg.

use std::str::FromStr;

use roxmltree::Node;
use svgtypes::{Length, LengthUnit, PathParser, PathSegment as S};

use super::{ExactPath, Piece, Subpath};
use crate::geom::{V2, v2};

/// usvg's pixels per inch, for absolute units (its default, which this crate keeps).
const PX_PER_IN: f64 = 96.0;

/// The geometry of `node` (a path, ellipse, circle or rect), or `None` when it is none of them,
/// draws nothing, or has a length this module does not read.
pub(super) fn geometry(node: Node) -> Option<ExactPath> {
    match node.tag_name().name() {
        "path" => Some(path(node.attribute("d")?)),
        "ellipse" => {
            let (rx, ry) = radii(node)?;
            ellipse(node, rx, ry)
        }
        "circle" => {
            let r = length(node, "r")?;
            ellipse(node, r, r)
        }
        "rect" => rect(node),
        _ => None,
    }
}

/// A length in user units (see the module doc); `Some(None)` when the attribute is absent (or
/// does not parse), `None` when it is in a unit not read here.
fn attribute(node: Node, name: &str) -> Option<Option<f64>> {
    let Some(l) = node.attribute(name).and_then(|v| Length::from_str(v).ok()) else {
        return Some(None);
    };
    let per_unit = match l.unit {
        LengthUnit::None | LengthUnit::Px => 1.0,
        LengthUnit::In => PX_PER_IN,
        LengthUnit::Cm => PX_PER_IN / 2.54,
        LengthUnit::Mm => PX_PER_IN / 25.4,
        LengthUnit::Pt => PX_PER_IN / 72.0,
        LengthUnit::Pc => PX_PER_IN / 6.0,
        LengthUnit::Percent | LengthUnit::Em | LengthUnit::Ex => return None,
    };
    Some(Some(l.number * per_unit))
}

/// A length that is 0 when absent.
fn length(node: Node, name: &str) -> Option<f64> {
    Some(attribute(node, name)?.unwrap_or(0.0))
}

/// An ellipse's or rect's `rx` and `ry` as usvg resolves them: a negative one is absent, one
/// absent takes the other's value, both absent are 0.
fn radii(node: Node) -> Option<(f64, f64)> {
    let given = |name| -> Option<Option<f64>> {
        Some(attribute(node, name)?.filter(|v: &f64| !v.is_sign_negative()))
    };
    Some(match (given("rx")?, given("ry")?) {
        (None, None) => (0.0, 0.0),
        (Some(r), None) | (None, Some(r)) => (r, r),
        (Some(rx), Some(ry)) => (rx, ry),
    })
}

/// Whether usvg takes `v` for a length that can be drawn.
fn drawable(v: f64) -> bool {
    v > 0.0 && v.is_finite()
}

/// An ellipse (a circle when `rx == ry`) centred at the node's `cx`, `cy`.
fn ellipse(node: Node, rx: f64, ry: f64) -> Option<ExactPath> {
    let (cx, cy) = (length(node, "cx")?, length(node, "cy")?);
    if !(drawable(rx) && drawable(ry)) {
        return None;
    }
    let mut b = Builder::default();
    b.move_to(v2(cx + rx, cy));
    for end in [(cx, cy + ry), (cx - rx, cy), (cx, cy - ry), (cx + rx, cy)] {
        b.arc_to(rx, ry, v2(end.0, end.1));
    }
    b.close();
    Some(b.finish())
}

/// A rect with rounded corners (one without has no arc: `None`, left to usvg).
fn rect(node: Node) -> Option<ExactPath> {
    let (w, h) = (length(node, "width")?, length(node, "height")?);
    let (x, y) = (length(node, "x")?, length(node, "y")?);
    let (rx, ry) = radii(node)?;
    let (rx, ry) = (rx.min(w / 2.0), ry.min(h / 2.0));
    if !(drawable(w) && drawable(h)) || rx == 0.0 {
        return None;
    }
    let mut b = Builder::default();
    b.move_to(v2(x + rx, y));
    let corners = [
        ((x + w - rx, y), (x + w, y + ry)),
        ((x + w, y + h - ry), (x + w - rx, y + h)),
        ((x + rx, y + h), (x, y + h - ry)),
        ((x, y + ry), (x + rx, y)),
    ];
    for (side_end, corner_end) in corners {
        b.line_to(v2(side_end.0, side_end.1));
        b.arc_to(rx, ry, v2(corner_end.0, corner_end.1));
    }
    b.close();
    Some(b.finish())
}

/// Path data `d`, up to its first error.
fn path(d: &str) -> ExactPath {
    let mut r = Resolver::default();
    for segment in PathParser::from(d) {
        let Ok(segment) = segment else { break };
        r.segment(segment);
    }
    r.out.finish()
}

/// The state of svgtypes' simplifying parser: what makes the next segment absolute.
#[derive(Default)]
struct Resolver {
    /// The current point.
    at: V2,
    /// The last move's point (where a close returns).
    move_at: V2,
    /// The previous segment, absolute where svgtypes keeps it so (curves), for `S` and `T`.
    prev: Option<S>,
    /// The control point of the previous `T`.
    smooth_quad_control: V2,
    /// Whether the last segment made was a close.
    closed: bool,
    out: Builder,
}

impl Resolver {
    fn segment(&mut self, s: S) {
        let is_move_or_close = matches!(s, S::MoveTo { .. } | S::ClosePath { .. });
        if self.closed && !is_move_or_close {
            // A segment after a close starts at the closed subpath's start.
            self.move_to(self.move_at);
        }
        let abs = |abs: bool, at: V2, x: f64, y: f64| if abs { v2(x, y) } else { at + v2(x, y) };
        let at = self.at;
        let mut remembered = s;
        match s {
            S::MoveTo { abs: a, x, y } => self.move_to(abs(a, at, x, y)),
            S::LineTo { abs: a, x, y } => self.line_to(abs(a, at, x, y)),
            S::HorizontalLineTo { abs: a, x } => {
                self.line_to(v2(if a { x } else { at.x + x }, at.y))
            }
            S::VerticalLineTo { abs: a, y } => self.line_to(v2(at.x, if a { y } else { at.y + y })),
            S::CurveTo {
                abs: a,
                x1,
                y1,
                x2,
                y2,
                x,
                y,
            } => {
                let (c1, c2, end) = (abs(a, at, x1, y1), abs(a, at, x2, y2), abs(a, at, x, y));
                remembered = curve_to(c2, end);
                self.piece(Piece::Cubic(c1, c2, end));
            }
            S::SmoothCurveTo {
                abs: a,
                x2,
                y2,
                x,
                y,
            } => {
                let c1 = match self.prev {
                    Some(
                        S::CurveTo { x2, y2, x, y, .. } | S::SmoothCurveTo { x2, y2, x, y, .. },
                    ) => v2(2.0 * x - x2, 2.0 * y - y2),
                    _ => at,
                };
                let (c2, end) = (abs(a, at, x2, y2), abs(a, at, x, y));
                remembered = curve_to(c2, end);
                self.piece(Piece::Cubic(c1, c2, end));
            }
            S::Quadratic {
                abs: a,
                x1,
                y1,
                x,
                y,
            } => {
                let (c, end) = (abs(a, at, x1, y1), abs(a, at, x, y));
                remembered = S::Quadratic {
                    abs: true,
                    x1: c.x,
                    y1: c.y,
                    x: end.x,
                    y: end.y,
                };
                self.piece(Piece::Quad(c, end));
            }
            S::SmoothQuadratic { abs: a, x, y } => {
                let c = match self.prev {
                    Some(S::Quadratic { x1, y1, x, y, .. }) => v2(2.0 * x - x1, 2.0 * y - y1),
                    Some(S::SmoothQuadratic { x, y, .. }) => {
                        v2(2.0 * x, 2.0 * y) - self.smooth_quad_control
                    }
                    _ => at,
                };
                self.smooth_quad_control = c;
                let end = abs(a, at, x, y);
                remembered = S::SmoothQuadratic {
                    abs: true,
                    x: end.x,
                    y: end.y,
                };
                self.piece(Piece::Quad(c, end));
            }
            S::EllipticalArc {
                abs: a,
                rx,
                ry,
                x_axis_rotation,
                large_arc,
                sweep,
                x,
                y,
            } => {
                let end = abs(a, at, x, y);
                let arc = kurbo::SvgArc {
                    from: kurbo::Point::new(at.x, at.y),
                    to: kurbo::Point::new(end.x, end.y),
                    radii: kurbo::Vec2::new(rx, ry),
                    x_rotation: x_axis_rotation.to_radians(),
                    large_arc,
                    sweep,
                };
                match kurbo::Arc::from_svg_arc(&arc) {
                    Some(arc) => self.piece(Piece::Arc(arc, end)),
                    None => self.line_to(end),
                }
            }
            S::ClosePath { .. } => {
                if !self.closed {
                    self.out.close();
                    self.closed = true;
                }
                self.at = self.move_at;
            }
        }
        self.prev = Some(remembered);
    }

    fn move_to(&mut self, p: V2) {
        self.out.move_to(p);
        (self.at, self.move_at, self.closed) = (p, p, false);
    }

    fn line_to(&mut self, p: V2) {
        self.piece(Piece::Line(p));
    }

    fn piece(&mut self, piece: Piece) {
        self.at = piece.end();
        self.closed = false;
        self.out.push(piece);
    }
}

/// A cubic as svgtypes remembers it for a following `S`: absolute, its second control point and
/// end.
fn curve_to(c2: V2, end: V2) -> S {
    S::CurveTo {
        abs: true,
        x1: 0.0,
        y1: 0.0,
        x2: c2.x,
        y2: c2.y,
        x: end.x,
        y: end.y,
    }
}

/// Subpaths made as tiny-skia's path builder makes them: a move right after a move replaces
/// it, a close after a close does nothing, and a segment after a close (or first of all) starts
/// a subpath at the last move's point (the origin at first).
#[derive(Default)]
struct Builder {
    subpaths: Vec<Subpath>,
    /// Whether the next segment needs a move first (after a close).
    closed: bool,
}

impl Builder {
    fn move_to(&mut self, p: V2) {
        match self.subpaths.last_mut() {
            Some(s) if s.pieces.is_empty() && !s.closed => s.start = p,
            _ => self.subpaths.push(Subpath {
                start: p,
                pieces: Vec::new(),
                closed: false,
            }),
        }
        self.closed = false;
    }

    fn push(&mut self, piece: Piece) {
        if self.closed || self.subpaths.is_empty() {
            let start = self.subpaths.last().map_or(v2(0.0, 0.0), |s| s.start);
            self.move_to(start);
        }
        if let Some(s) = self.subpaths.last_mut() {
            s.pieces.push(piece);
        }
    }

    /// Where the last piece ends (the subpath's start when it has none).
    fn last_point(&self) -> V2 {
        let last = self.subpaths.last();
        last.map_or(v2(0.0, 0.0), |s| {
            s.pieces.last().map_or(s.start, Piece::end)
        })
    }

    fn line_to(&mut self, p: V2) {
        self.push(Piece::Line(p));
    }

    /// A shape's arc (no rotation, the small one, positive sweep) from the last point to `end`.
    fn arc_to(&mut self, rx: f64, ry: f64, end: V2) {
        let from = self.last_point();
        let arc = kurbo::SvgArc {
            from: kurbo::Point::new(from.x, from.y),
            to: kurbo::Point::new(end.x, end.y),
            radii: kurbo::Vec2::new(rx, ry),
            x_rotation: 0.0,
            large_arc: false,
            sweep: true,
        };
        match kurbo::Arc::from_svg_arc(&arc) {
            Some(arc) => self.push(Piece::Arc(arc, end)),
            None => self.line_to(end),
        }
    }

    fn close(&mut self) {
        if let Some(s) = self.subpaths.last_mut() {
            s.closed = true;
        }
        self.closed = true;
    }

    fn finish(self) -> ExactPath {
        ExactPath {
            subpaths: self.subpaths,
        }
    }
}
