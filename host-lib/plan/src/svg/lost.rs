//! Elements usvg drops although each of their numbers keeps the rule for them
//! ([`FARTHEST_COORDINATE`]): usvg combines an element's coordinates with every transform above
//! it and the `viewBox`, in single precision, and drops the element whole when the result
//! overflows (a shape at 1e29 in a group scaled by 1e10; two nested scales of 1e20). Nothing of
//! it is left in usvg's tree, so no later check could see it: its cuts would be copied
//! undilated, and the plan dilated without them.
//!
//! What usvg hands back shows where that can have happened: a group whose combined transform is
//! not finite, or scales by more than single precision can take a coordinate the rule allows to
//! ([`overflows`]). Only then is the tagged copy drawn again with the whole drawing scaled down
//! (a `scale` of 2^-22 on the root: exact in single precision, and twice the smallest that usvg
//! draws a transform with), and the elements drawn there but not in the first drawing are the
//! ones usvg lost: they are refused by name ([`lost`], [`refuse`]). Which elements are drawn is
//! all that is read of the second drawing. Should it overflow as well (transforms combined
//! past 2^22 times the limit), the drawing is refused as a whole.
//!
//! Elements are known by the tag their stroke carries (see `super::tagged`), so only stroked
//! elements, and so every cut, can be found lost; a filled shape usvg drops is no cut, and is
//! copied as it is.

use std::collections::HashSet;

use roxmltree::Node;

use super::bad;
use super::edits::tag_name_range;
use super::path_data::FARTHEST_COORDINATE;
use super::tagging::USE_TAG;
use crate::error::{PlanError, Problems, Result};

/// The scale of the drawing made again, on the root: 2^-22 (see the module's docs).
const SMALLER: &str = "scale(2.384185791015625e-7)";

/// The largest combined scale that keeps every coordinate the rule allows (and the sum of two,
/// a rectangle's `x + width`) within single precision.
const LARGEST_SCALE: f64 = f32::MAX as f64 / (2.0 * FARTHEST_COORDINATE);

/// The largest combined offset that leaves room for the coordinates added to it.
const LARGEST_OFFSET: f64 = f32::MAX as f64 / 2.0;

/// Whether a group's combined transform `t` (usvg's `abs_transform`) may have made usvg drop an
/// element it holds: a number not finite, a scale beyond [`LARGEST_SCALE`] or an offset beyond
/// [`LARGEST_OFFSET`].
fn overflows(t: usvg::Transform) -> bool {
    let beyond = |v: f32, limit: f64| !v.is_finite() || f64::from(v).abs() > limit;
    [t.sx, t.kx, t.ky, t.sy]
        .into_iter()
        .any(|v| beyond(v, LARGEST_SCALE))
        || [t.tx, t.ty].into_iter().any(|v| beyond(v, LARGEST_OFFSET))
}

/// A group of usvg's tree whose combined transform [`overflows`]: the first whose transform is
/// not finite, else the first found.
pub(super) struct Overflow {
    /// The group's id (a `<g>`'s or a `<use>`'s; empty for a group usvg made for an element's
    /// own transform).
    id: String,
    finite: bool,
}

impl Overflow {
    /// Note `group` in `found` if it overflows and names the place better.
    pub(super) fn note(found: &mut Option<Overflow>, group: &usvg::Group) {
        let t = group.abs_transform();
        if !overflows(t) || found.as_ref().is_some_and(|f| !f.finite) {
            return;
        }
        let finite = [t.sx, t.kx, t.ky, t.sy, t.tx, t.ty]
            .into_iter()
            .all(f32::is_finite);
        if found.is_none() || !finite {
            *found = Some(Overflow {
                id: group.id().to_string(),
                finite,
            });
        }
    }
}

/// Where the smaller drawing's scale goes in the root's start tag: before its own transform, or
/// as a new `transform`. The offset is the same in the source and in its tagged copy: tags go
/// only into shapes and clones, which come after the root's start tag.
pub(super) struct Probe {
    at: usize,
    text: String,
}

impl Probe {
    /// Where the scale goes in the source `src`, whose root element is `root`.
    pub(super) fn of(src: &str, root: Node) -> Self {
        let own = (root.attributes()).find(|a| a.name() == "transform" && a.namespace().is_none());
        match own {
            Some(t) => Probe {
                at: t.range_value().start,
                text: format!("{SMALLER} "),
            },
            None => Probe {
                at: tag_name_range(src, root).end,
                text: format!(" transform=\"{SMALLER}\""),
            },
        }
    }

    /// The tagged copy `tagged` with the whole drawing scaled down.
    pub(super) fn smaller(&self, tagged: &str) -> String {
        let mut text = String::with_capacity(tagged.len() + self.text.len());
        text.push_str(&tagged[..self.at]);
        text.push_str(&self.text);
        text.push_str(&tagged[self.at..]);
        text
    }
}

/// The elements (shape, outermost `<use>`) drawn in the smaller drawing (`smaller`) but not in
/// the first one (`first`), in document order; an error when none is found and a group of the
/// smaller drawing still overflows (`overflow`).
pub(super) fn lost(
    first: &HashSet<(usize, Option<usize>)>,
    smaller: &HashSet<(usize, Option<usize>)>,
    overflow: Option<Overflow>,
) -> Result<Vec<(usize, Option<usize>)>> {
    let mut lost: Vec<(usize, Option<usize>)> = smaller.difference(first).copied().collect();
    lost.sort_unstable();
    match overflow {
        Some(Overflow { id, .. }) if lost.is_empty() => {
            let group = match id.as_str() {
                "" => "a group or a transformed element (with no id)".to_string(),
                id if id.starts_with(USE_TAG) => "a <use> (with no id)".to_string(),
                id => format!("the element \"{id}\""),
            };
            Err(bad(format!(
                "the transforms around {group} combine to a scale or an offset that an SVG's single-precision coordinates cannot hold, so what it holds cannot be drawn (a damaged file or a unit mistake); fix the transforms of the groups and clones there"
            )))
        }
        _ => Ok(lost),
    }
}

/// Refuse the elements usvg lost, named by `names`.
pub(super) fn refuse(names: impl Iterator<Item = String>) -> Result<()> {
    let mut problems = Problems::default();
    for name in names {
        problems.push(format!(
            "{name} cannot be drawn: with the transforms around it and the viewBox applied, its coordinates go beyond what an SVG's single-precision coordinates can hold (about 3.4e38), and it would be left out; fix its coordinates or those transforms (a damaged file or a unit mistake)"
        ));
    }
    problems.into_error(PlanError::Svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(sx: f32, tx: f32) -> usvg::Transform {
        usvg::Transform::from_row(sx, 0.0, 0.0, sx, tx, 0.0)
    }

    #[test]
    fn only_transforms_that_can_take_an_allowed_coordinate_past_the_limit_overflow() {
        assert!(!overflows(t(3.78, 0.0)));
        assert!(!overflows(t(1e8, 1e37)));
        assert!(overflows(t(1e9, 0.0)));
        assert!(overflows(t(1.0, 2e38)));
        assert!(overflows(t(1.0, f32::INFINITY)));
        assert!(overflows(t(f32::NAN, 0.0)));
    }

    #[test]
    fn the_smaller_drawing_scales_the_root() {
        let src = r#"<svg xmlns="http://www.w3.org/2000/svg" width="1mm"><rect/></svg>"#;
        let doc = roxmltree::Document::parse(src).unwrap();
        let smaller = Probe::of(src, doc.root_element()).smaller(src);
        assert!(
            smaller.starts_with(r#"<svg transform="scale(2.384185791015625e-7)" xmlns="#),
            "{smaller}"
        );
        let src = r#"<svg transform="rotate(90)" xmlns="http://www.w3.org/2000/svg"/>"#;
        let doc = roxmltree::Document::parse(src).unwrap();
        let smaller = Probe::of(src, doc.root_element()).smaller(src);
        assert!(
            smaller.starts_with(r#"<svg transform="scale(2.384185791015625e-7) rotate(90)""#),
            "{smaller}"
        );
    }

    #[test]
    fn what_only_the_smaller_drawing_draws_is_lost() {
        let first = HashSet::from([(0, None), (2, Some(0))]);
        let smaller = HashSet::from([(0, None), (1, None), (2, Some(0)), (2, Some(1))]);
        assert_eq!(
            lost(&first, &smaller, None).unwrap(),
            [(1, None), (2, Some(1))]
        );
        // Nothing found, and still overflowing: refused as a whole.
        let overflow = Overflow {
            id: "g1".to_string(),
            finite: false,
        };
        let e = lost(&first, &first, Some(overflow))
            .unwrap_err()
            .to_string();
        assert!(e.contains("around the element \"g1\""), "{e}");
    }
}
