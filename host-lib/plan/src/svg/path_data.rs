//! The `d` of a plan's `<path>` elements (and the `points` of its polygons and polylines), and
//! the numbers of every element's geometry, checked as the source writes them, before usvg
//! reads them.
//!
//! usvg reads path data as SVG viewers draw it: up to its first error, silently. A cut whose data
//! breaks off part way (`L NaN 80`, a stray letter) would be dilated, and written back, without
//! its tail: it is refused (another path with such data passes through, in a note). And an
//! element with a number that single precision cannot hold, or nearly (`1e38`: a coordinate, an
//! arc radius, a shape's `x` or `r`, a `transform`'s offset or scale), is dropped by usvg whole,
//! which left "nothing drawn", or a plan with fewer contours, as the only clue: it is refused
//! here, by name, whether or not it is a cut. This is the one rule for such numbers
//! ([`FARTHEST_COORDINATE`]); the numbers usvg combines past it (a large `x` in a large scale)
//! are found in what usvg draws (see `super::lost`).

use std::str::FromStr;

use rayon::prelude::*;
use roxmltree::Node;
use svgtypes::{NumberListParser, PathParser, PathSegment as S};

/// Coordinates beyond this (in the element's own units), and transforms that scale or move by
/// more, are refused: far past anything drawable (a drawing beyond 170 m is refused anyway, see
/// the reach check), and near the single precision's limit (3.4e38), where usvg drops the whole
/// element.
pub(super) const FARTHEST_COORDINATE: f64 = 1e30;

/// Whether `v` is beyond what [`FARTHEST_COORDINATE`] allows (not a number included).
fn too_far(v: f64) -> bool {
    !v.is_finite() || v.abs() > FARTHEST_COORDINATE
}

/// The geometry attributes whose numbers are checked, by shape (`points` and `d` have their
/// own readers).
fn geometry_attributes(shape: &str) -> &'static [&'static str] {
    match shape {
        "rect" => &["x", "y", "width", "height", "rx", "ry"],
        "circle" => &["cx", "cy", "r"],
        "ellipse" => &["cx", "cy", "rx", "ry"],
        "line" => &["x1", "y1", "x2", "y2"],
        // A clone's offset.
        "use" => &["x", "y"],
        _ => &[],
    }
}

/// What is wrong with a path's data.
#[derive(Debug, PartialEq)]
pub(super) enum Flaw {
    /// The data breaks off: svgtypes' words, and where.
    BreaksOff(String),
    /// A coordinate beyond [`FARTHEST_COORDINATE`].
    TooFar(f64),
}

/// The first flaw of the path data `d`, if any.
pub(super) fn flaw(d: &str) -> Option<Flaw> {
    // The current point and the subpath's start, to make relative coordinates absolute.
    let (mut at, mut start) = ([0.0, 0.0], [0.0, 0.0]);
    for segment in PathParser::from(d) {
        let segment = match segment {
            Ok(s) => s,
            Err(e) => return Some(Flaw::BreaksOff(e.to_string())),
        };
        let (points, end) = absolute(&segment, at, start);
        let far = (points.iter().flatten().flatten()).find(|v| too_far(**v));
        if let Some(&v) = far {
            return Some(Flaw::TooFar(v));
        }
        if matches!(segment, S::MoveTo { .. }) {
            start = end;
        }
        at = end;
    }
    None
}

/// The points a segment names (control points and end, an arc's radii as a point; a closing
/// segment none), made absolute
/// from the current point `at` (the subpath's `start` is where a closing segment ends), and its
/// end point.
fn absolute(s: &S, at: [f64; 2], start: [f64; 2]) -> ([Option<[f64; 2]>; 3], [f64; 2]) {
    let from = |abs: bool, x: f64, y: f64| if abs { [x, y] } else { [at[0] + x, at[1] + y] };
    let (controls, end) = match *s {
        S::MoveTo { abs, x, y } | S::LineTo { abs, x, y } | S::SmoothQuadratic { abs, x, y } => {
            ([None, None], from(abs, x, y))
        }
        // The radii too: a huge one puts the arc's curves as far out.
        S::EllipticalArc {
            abs, rx, ry, x, y, ..
        } => ([Some([rx, ry]), None], from(abs, x, y)),
        S::HorizontalLineTo { abs, x } => ([None, None], [if abs { x } else { at[0] + x }, at[1]]),
        S::VerticalLineTo { abs, y } => ([None, None], [at[0], if abs { y } else { at[1] + y }]),
        S::Quadratic { abs, x1, y1, x, y }
        | S::SmoothCurveTo {
            abs,
            x2: x1,
            y2: y1,
            x,
            y,
        } => ([Some(from(abs, x1, y1)), None], from(abs, x, y)),
        S::CurveTo {
            abs,
            x1,
            y1,
            x2,
            y2,
            x,
            y,
        } => (
            [Some(from(abs, x1, y1)), Some(from(abs, x2, y2))],
            from(abs, x, y),
        ),
        S::ClosePath { .. } => return ([None; 3], start),
    };
    ([controls[0], controls[1], Some(end)], end)
}

/// A `<path>`, `<polygon>` or `<polyline>` whose geometry has a flaw: its index among the
/// shapes, which geometry it is for a message (`path data` or `points`), and its flaw.
pub(super) struct Flawed {
    pub shape: usize,
    pub data: &'static str,
    pub flaw: Flaw,
}

/// The elements among `shapes` whose path data or points have a flaw (in document order).
pub(super) fn flawed(shapes: &[Node]) -> Vec<Flawed> {
    (shapes.par_iter().enumerate())
        .filter_map(|(shape, n)| {
            let (data, flaw) = match n.tag_name().name() {
                "path" => ("path data", flaw(n.attribute("d")?)),
                "polygon" | "polyline" => ("points", points_flaw(n.attribute("points")?)),
                _ => return None,
            };
            Some(Flawed {
                shape,
                data,
                flaw: flaw?,
            })
        })
        .collect()
}

/// The first of the `elements` (any element, in document order) with a number beyond
/// [`FARTHEST_COORDINATE`] in its `transform` or in a geometry attribute of its shape (a
/// rectangle's `x`, a circle's `r`, a clone's `x`): the element, the attribute, the number.
/// Numbers that are not numbers (`x="abc"`) are usvg's to ignore, as viewers do.
pub(super) fn far_attribute<'d, 'a>(
    elements: impl Iterator<Item = Node<'d, 'a>>,
) -> Option<(Node<'d, 'a>, &'static str, f64)> {
    elements.filter(Node::is_element).find_map(|n| {
        let attribute = |name: &str| {
            (n.attributes())
                .find(|a| a.name() == name && a.namespace().is_none())
                .map(|a| a.value())
        };
        let transform = attribute("transform")
            .and_then(|t| svgtypes::Transform::from_str(t).ok())
            .and_then(|t| {
                [t.a, t.b, t.c, t.d, t.e, t.f]
                    .into_iter()
                    .find(|v| too_far(*v))
            });
        if let Some(v) = transform {
            return Some((n, "transform", v));
        }
        geometry_attributes(n.tag_name().name())
            .iter()
            .find_map(|&name| {
                let length = svgtypes::Length::from_str(attribute(name)?).ok()?;
                too_far(length.number).then_some((n, name, length.number))
            })
    })
}

/// The first flaw of a `<polygon>`'s or `<polyline>`'s `points`, if any: usvg reads them up to
/// the first that is not a number, and drops an odd one at the end.
pub(super) fn points_flaw(points: &str) -> Option<Flaw> {
    let mut count = 0;
    for number in NumberListParser::from(points) {
        match number {
            Ok(v) if too_far(v) => {
                return Some(Flaw::TooFar(v));
            }
            Ok(_) => count += 1,
            Err(e) => return Some(Flaw::BreaksOff(e.to_string())),
        }
    }
    (count % 2 == 1).then(|| Flaw::BreaksOff(format!("{count} numbers: the last has no pair")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn good_data_has_no_flaw() {
        assert_eq!(
            flaw("M10 10 H30 V30 H10 Z m 5 5 l 1 0 a 2 2 0 0 1 2 2 z"),
            None
        );
        assert_eq!(flaw(""), None);
        assert_eq!(flaw("M1e29 0 L0 0"), None);
    }

    #[test]
    fn data_that_breaks_off_says_where() {
        let Some(Flaw::BreaksOff(why)) = flaw("M10 10 H30 V30 Z M70 70 L NaN 80 H90 Z") else {
            panic!("a flaw expected");
        };
        assert!(why.contains("position"), "{why}");
        assert!(matches!(flaw("M10 10 L"), Some(Flaw::BreaksOff(_))));
    }

    #[test]
    fn points_that_break_off_or_lack_a_pair_are_flaws() {
        assert_eq!(points_flaw("10,10 30,10 30 30"), None);
        assert!(matches!(
            points_flaw("10,10 30,10 x 30"),
            Some(Flaw::BreaksOff(_))
        ));
        assert!(matches!(
            points_flaw("10,10 30,10 30"),
            Some(Flaw::BreaksOff(_))
        ));
        assert_eq!(points_flaw("10,10 1e39,10 30,30"), Some(Flaw::TooFar(1e39)));
    }

    #[test]
    fn coordinates_single_precision_cannot_hold_are_too_far() {
        assert_eq!(flaw("M70 70 L80 70 L1e39 80 Z"), Some(Flaw::TooFar(1e39)));
        // Relative steps add up to the absolute coordinate that is too far.
        assert_eq!(flaw("M0 0 l 8e29 0 l 8e29 0"), Some(Flaw::TooFar(1.6e30)));
        assert_eq!(
            flaw("M0 0 A 1e39 1e39 0 1 1 10 10"),
            Some(Flaw::TooFar(1e39))
        );
    }
}
