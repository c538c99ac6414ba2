//! The size of things: mm per usvg pixel from the root's `width` and `height` (or as the caller
//! assumes, where they are not absolute), and the length of the root's user unit that the report
//! gives.

use std::str::FromStr;

use roxmltree::Node;

use crate::error::{PlanError, Result};
use crate::outcome::{AssumedUnits, PlanSummary};

/// The length of the root's user unit, mm, as the report says it: usvg's px (`mm_per_px`) times
/// the px in one user unit, which a `viewBox` sets (the page over the box, the smaller of the two
/// ways as SVG's default `preserveAspectRatio` fits it) and which is otherwise one px.
pub(super) fn user_unit_mm(root: Node, mm_per_px: f64) -> f64 {
    let view_box = root
        .attribute("viewBox")
        .and_then(|v| svgtypes::ViewBox::from_str(v).ok());
    let size_px = |name: &str| {
        root.attribute(name)
            .and_then(|s| svgtypes::Length::from_str(s).ok())
            .and_then(|l| length_px(&l))
    };
    let scale =
        |page: Option<f64>, view: f64| page.filter(|p| *p > 0.0 && view > 0.0).map(|p| p / view);
    let Some(v) = view_box else {
        return mm_per_px;
    };
    match (scale(size_px("width"), v.w), scale(size_px("height"), v.h)) {
        (Some(x), Some(y)) => mm_per_px * x.min(y),
        (Some(s), None) | (None, Some(s)) => mm_per_px * s,
        (None, None) => mm_per_px,
    }
}

/// An absolute (or px) length in px at 96 per inch, as usvg counts them.
pub(super) fn length_px(l: &svgtypes::Length) -> Option<f64> {
    use svgtypes::LengthUnit;
    let per_unit = match l.unit {
        LengthUnit::None | LengthUnit::Px => 1.0,
        LengthUnit::Mm => 96.0 / 25.4,
        LengthUnit::Cm => 96.0 / 2.54,
        LengthUnit::In => 96.0,
        LengthUnit::Pt => 96.0 / 72.0,
        LengthUnit::Pc => 16.0,
        _ => return None,
    };
    Some(l.number * per_unit)
}

/// mm per usvg pixel, from the root's `width`/`height` (absolute units), or as the user says
/// (`--units`) where they are not absolute.
pub(super) fn document_scale(
    root: Node,
    assume: Option<AssumedUnits>,
    summary: &mut PlanSummary,
) -> Result<f64> {
    use svgtypes::{Length, LengthUnit};
    let absolute = |l: &Length| {
        matches!(
            l.unit,
            LengthUnit::Mm | LengthUnit::Cm | LengthUnit::In | LengthUnit::Pt | LengthUnit::Pc
        )
    };
    let w = root.attribute("width");
    let h = root.attribute("height");
    let wl = w.and_then(|s| Length::from_str(s).ok());
    let hl = h.and_then(|s| Length::from_str(s).ok());
    match (wl, hl) {
        (Some(a), Some(b)) if absolute(&a) && absolute(&b) => {
            if assume.is_some() {
                summary
                    .notes
                    .push("--units ignored: the file gives its size in absolute units".into());
            }
            // usvg converts absolute lengths at 96 px per inch.
            Ok(25.4 / 96.0)
        }
        (Some(a), Some(b)) if absolute(&a) != absolute(&b) => Err(PlanError::Units(format!(
            "unknown units: the root <svg> mixes width=\"{}\" and height=\"{}\"; give both in mm (or both in the same absolute unit)",
            w.unwrap_or(""),
            h.unwrap_or("")
        ))),
        _ => match assume {
            Some(u) => {
                summary.notes.push(format!(
                    "the file does not say its units; one unit of its unitless width and height taken as {} ({} mm) as asked (the report gives the user unit this makes)",
                    u.name(),
                    u.mm()
                ));
                Ok(u.mm())
            }
            None => Err(PlanError::Units(format!(
                "unknown units: the root <svg> has width=\"{}\" height=\"{}\", not in absolute units (mm, cm, in, pt), so the size of a user unit is not known (96 or 72 px per inch depends on the program). Save with mm units, or say what one unit is with --units (px96 for Inkscape and browsers, px72 for old Illustrator files, mm)",
                w.unwrap_or("(none)"),
                h.unwrap_or("(none)")
            ))),
        },
    }
}
