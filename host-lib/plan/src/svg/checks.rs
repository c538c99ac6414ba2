//! What a source is refused for, or noted, before usvg reads it: entities that would expand it
//! many times over, numbers single precision cannot hold, path data or points that break off,
//! and a root `viewBox` that draws nothing or maps the page absurdly.

use std::collections::HashSet;

use roxmltree::{Document, Node};

use super::elements::{LineIndex, describe};
use super::path_data::{self, Flaw};
use super::{Instance, SVG_NS, bad};
use crate::entities;
use crate::error::{PlanError, Result};
use crate::outcome::PlanSummary;

/// A `<path>`, `<polygon>` or `<polyline>` whose path data or points break off (see
/// [`path_data`]): its index among the shapes, its name and svgtypes' words for where.
pub(super) struct BrokenPath {
    shape: usize,
    name: String,
    /// `path data` or `points`.
    data: &'static str,
    why: String,
}

/// The elements among `shapes` (of the source `text`) whose path data or points break off,
/// named; one with a coordinate too far for single precision is refused.
pub(super) fn broken_paths(text: &str, shapes: &[Node]) -> Result<Vec<BrokenPath>> {
    let flawed = path_data::flawed(shapes);
    if flawed.is_empty() {
        return Ok(Vec::new());
    }
    let lines = LineIndex::new(text);
    let mut broken = Vec::new();
    for f in flawed {
        let (name, data) = (describe(&lines, shapes[f.shape]), f.data);
        match f.flaw {
            Flaw::TooFar(v) => return Err(too_far(&name, v, data)),
            Flaw::BreaksOff(why) => broken.push(BrokenPath {
                shape: f.shape,
                name,
                data,
                why,
            }),
        }
    }
    Ok(broken)
}

/// An element with the number `v` in its `what` (`path data`, `transform`, `x attribute`) beyond
/// what single precision holds (see [`path_data::FARTHEST_COORDINATE`]), named `name`.
fn too_far(name: &str, v: f64, what: &str) -> PlanError {
    bad(format!(
        "{name} has the number {v:e} in its {what}, more than an SVG's single-precision coordinates can hold (a damaged file or a unit mistake); fix its {what}"
    ))
}

/// Refuse an element of the source `doc` (of `text`) whose `transform` or shape geometry (`x`,
/// `r`, …) has a number single precision cannot hold (see [`path_data::far_attribute`]): usvg
/// would drop it, and with it the cuts it draws.
pub(super) fn check_far_attributes(text: &str, doc: &Document) -> Result<()> {
    let svg_elements = doc
        .descendants()
        .filter(|n| matches!(n.tag_name().namespace(), None | Some(SVG_NS)));
    let Some((n, attribute, v)) = path_data::far_attribute(svg_elements) else {
        return Ok(());
    };
    let what = match attribute {
        "transform" => "transform".to_string(),
        a => format!("{a} attribute"),
    };
    Err(too_far(&describe(&LineIndex::new(text), n), v, &what))
}

/// A cut among the `broken` paths is refused: SVG viewers draw it only up to its error, and its
/// dilation would be written without the rest. The others pass through unchanged, in a note
/// naming the first three: not drawn as cuts, or (a cut's colour) drawing nothing before the
/// error, which usvg then drops.
pub(super) fn check_broken(
    broken: &[BrokenPath],
    instances: &[Instance],
    summary: &mut PlanSummary,
) -> Result<()> {
    if broken.is_empty() {
        return Ok(());
    }
    let cuts: HashSet<usize> = instances.iter().map(|i| i.element).collect();
    if let Some(b) = broken.iter().find(|b| cuts.contains(&b.shape)) {
        return Err(bad(format!(
            "the cut {} has an error in its {} ({}): SVG viewers draw it only up to there, and its dilation would be written without the rest; fix its {}",
            b.name, b.data, b.why, b.data
        )));
    }
    let mut listed: Vec<String> = (broken.iter().take(3))
        .map(|b| format!("{} ({}: {})", b.name, b.data, b.why))
        .collect();
    if broken.len() > 3 {
        listed.push(format!("and {} more", broken.len() - 3));
    }
    summary.notes.push(format!(
        "{} path(s) not read as cuts (not drawn as cuts, or drawing nothing before the error) have an error in their path data or points (SVG viewers draw them only up to it); passed through unchanged: {}",
        broken.len(),
        listed.join("; ")
    ));
    Ok(())
}

/// Refuse a source whose document type declaration's entities would expand it many times over,
/// before any parse (see [`entities`]).
pub(super) fn check_entities(text: &str) -> Result<()> {
    let Err(added) = entities::check(text) else {
        return Ok(());
    };
    let mb = |bytes: u64| bytes as f64 / 1e6;
    Err(bad(format!(
        "not a usable SVG file: the entities of its document type declaration would add {:.0} MB to its {:.1} MB (at most {:.0} MB); remove the DTD's entities, or write them out",
        mb(added),
        mb(text.len() as u64),
        mb(entities::limit_bytes(text.len()))
    )))
}

/// Refuse a root `viewBox` that draws nothing or maps the page absurdly: renderers take a zero or
/// negative one to switch rendering off, and usvg drops one it cannot use and takes a user unit
/// for a pixel, so the output would be dilated in other units than the file's readers see.
pub(super) fn check_view_box(root: Node) -> Result<()> {
    let Some(text) = root.attribute("viewBox") else {
        return Ok(());
    };
    let numbers: Vec<f64> = text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().unwrap_or(f64::NAN))
        .collect();
    let usable = match numbers[..] {
        [x, y, w, h] => {
            [x, y, w, h].iter().all(|v| v.is_finite() && v.abs() < 1e9)
                && w > 0.0
                && h > 0.0
                && w.min(h) > 1e-9 * w.max(h).max(1.0)
        }
        _ => false,
    };
    if usable {
        return Ok(());
    }
    Err(bad(format!(
        "its root viewBox=\"{text}\" is not a usable box (four finite numbers, width and height above zero and within reason): a zero one draws nothing, and programs read such a file differently; fix or remove the viewBox"
    )))
}
