//! The first reading of a source: parsed as XML and checked to be SVG, its size and records
//! read, then its tagged copy (see `tagging`) drawn by usvg, which never loads an image, into the
//! plan begun and the cut instances with their path data (see [`render`]).

use roxmltree::{Document, ParsingOptions};
use usvg::tiny_skia_path;

use super::checks::{
    broken_paths, check_broken, check_entities, check_far_attributes, check_view_box,
};
use super::elements::{is_svg, shapes_and_uses};
use super::tagging::tagged;
use super::units::{document_scale, user_unit_mm};
use super::walk::Walk;
use super::{Instance, SVG_NS, SvgOptions, bad, lost};
use crate::compensation;
use crate::error::Result;
use crate::outcome::PlanSummary;
use crate::pipeline::Plan;

/// Why the XML could not be read, in words; an entity the reader does not know is most often an
/// external one (`<!ENTITY x SYSTEM "file:…">`), which is never read: said so.
fn xml_error_message(e: &roxmltree::Error) -> String {
    let hint = match e {
        roxmltree::Error::UnknownEntityReference(..) => {
            "; external entities (<!ENTITY … SYSTEM …>) are not supported: they are never read, \
             so declare the entity's text in the file or remove it"
        }
        _ => "",
    };
    format!("not a readable SVG file (XML error: {e}){hint}")
}

/// The source as XML, refused unless its root is an SVG `<svg>`. The first parse of a source
/// ([`render`]'s) checks its entities before it (see [`check_entities`]); every later one parses
/// the same text (a file read again is checked against the hash of the first reading).
pub(super) fn parse(text: &str) -> Result<Document<'_>> {
    let doc = Document::parse_with_options(
        text,
        ParsingOptions {
            allow_dtd: true,
            ..ParsingOptions::default()
        },
    )
    .map_err(|e| bad(xml_error_message(&e)))?;
    let root = doc.root_element();
    if root.tag_name().name() == "svg" && root.tag_name().namespace().is_none() {
        return Err(bad(format!(
            "not an SVG document: its root <svg> lacks the SVG namespace; add xmlns=\"{SVG_NS}\" to it"
        )));
    }
    if root.tag_name().name() != "svg" || root.tag_name().namespace() != Some(SVG_NS) {
        return Err(bad(format!(
            "not an SVG document: the root element is <{}>",
            root.tag_name().name()
        )));
    }
    Ok(doc)
}

/// The document as usvg renders it: the plan begun (units, the compensation recorded, what
/// passes through) and each cut instance with its path data (element coordinates).
pub(super) struct Rendered {
    pub(super) plan: Plan<(usize, usize)>,
    pub(super) instances: Vec<Instance>,
    /// `paths[k]` is the path data of `instances[k]`.
    pub(super) paths: Vec<tiny_skia_path::Path>,
    /// The elements usvg could not draw (see [`lost`]), by (shape, outermost `<use>`): refused
    /// once they can be named.
    pub(super) lost: Vec<(usize, Option<usize>)>,
    /// Document mm per usvg pixel.
    pub(super) mm_per_px: f64,
}

/// The source's tagged copy `tagged` as usvg draws it.
fn draw(tagged: &str) -> Result<usvg::Tree> {
    usvg::Tree::from_str(tagged, &usvg_options())
        .map_err(|e| bad(format!("not a usable SVG file: {e}")))
}

/// Render the document with usvg and find its cut instances; the source is given back.
///
/// Memory: this is the largest step of reading, so nothing else large is alive during it. The
/// XML tree of the source (parsed here to check it, read its size and records, and tag its
/// elements, see [`tagged`]) goes before usvg parses the tagged copy, and so does the source
/// itself: it is made again from the tagged copy, whose insertions are known, once usvg's tree
/// is gone. Of usvg's tree only the cut paths' data is kept (a tenth of the tree). Reading parses
/// the source again, to name and place the cuts.
///
/// Numbers single precision cannot hold are refused before usvg reads them (see
/// [`path_data`](super::path_data)); when what usvg drew shows transforms that may have combined
/// past it, the tagged copy is drawn again, scaled down, to find the elements usvg dropped (see
/// [`lost`]).
pub(super) fn render(text: String, opts: &SvgOptions) -> Result<(String, Rendered)> {
    let mut plan = Plan::new("svg");
    check_entities(&text)?;
    let (tagged, use_by_id, shapes_len, mm_per_px, broken, probe) = {
        let doc = parse(&text)?;
        let mm_per_px = document_scale(doc.root_element(), opts.assume_units, &mut plan.summary)?;
        check_view_box(doc.root_element())?;
        plan.summary.mm_per_unit = user_unit_mm(doc.root_element(), mm_per_px);
        plan.summary.compensation_found = compensation::find_in_svg(&doc);
        for n in doc.descendants() {
            if is_svg(n, "text") {
                plan.summary.pass("text");
            } else if is_svg(n, "image") {
                plan.summary.pass("image");
            }
        }
        let (shapes, uses) = shapes_and_uses(&doc);
        let broken = broken_paths(&text, &shapes)?;
        check_far_attributes(&text, &doc)?;
        let (tagged, use_by_id) = tagged(&text, &shapes, &uses)?;
        let probe = lost::Probe::of(&text, doc.root_element());
        (tagged, use_by_id, shapes.len(), mm_per_px, broken, probe)
    };
    drop(text);
    let tree = draw(&tagged.text)?;
    let mut walk = Walk::new(
        &opts.rules,
        mm_per_px,
        shapes_len,
        &use_by_id,
        &mut plan.summary,
        true,
    );
    walk.group(tree.root(), &mut Vec::new());
    let (unidentified, mut instances, mut paths) = (walk.unidentified, walk.instances, walk.paths);
    let (seen, overflow) = (walk.seen, walk.overflow);
    drop(tree);
    if unidentified > 0 {
        return Err(bad(format!(
            "{unidentified} cut path(s) could not be traced back to their element (a stylesheet sets stroke-miterlimit with !important?)"
        )));
    }
    let lost = match overflow {
        // What usvg drew shows no place where it could have dropped an element.
        None => Vec::new(),
        Some(_) => {
            let tree = draw(&probe.smaller(&tagged.text))?;
            let mut summary = PlanSummary::default();
            let mut walk = Walk::new(
                &opts.rules,
                mm_per_px,
                shapes_len,
                &use_by_id,
                &mut summary,
                false,
            );
            walk.group(tree.root(), &mut Vec::new());
            lost::lost(&seen, &walk.seen, walk.overflow)?
        }
    };
    drop(seen);
    check_broken(&broken, &instances, &mut plan.summary)?;
    instances.shrink_to_fit();
    paths.shrink_to_fit();
    let rendered = Rendered {
        plan,
        instances,
        paths,
        lost,
        mm_per_px,
    };
    Ok((tagged.untagged(), rendered))
}

/// usvg's options: no image is ever loaded. An `<image>` is not a cut (the source counts them as
/// passed through), and loading one would read any file or device its `href` names (`/dev/zero`,
/// a FIFO: unbounded memory, or a wait for ever; a server's plan naming a local file) or parse an
/// embedded SVG again for every clone of it.
pub(super) fn usvg_options() -> usvg::Options<'static> {
    usvg::Options {
        image_href_resolver: usvg::ImageHrefResolver {
            resolve_data: Box::new(|_, _, _| None),
            resolve_string: Box::new(|_, _| None),
        },
        ..usvg::Options::default()
    }
}
