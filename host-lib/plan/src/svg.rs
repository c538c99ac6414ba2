//! SVG plans: read with `usvg`, dilate the cuts, and write the result by *editing the original
//! text*, so ids, layers, text, styles, comments and every non-cut element survive byte for byte.
//!
//! **Reading.** `usvg` resolves what a laser program would see: CSS and inherited styles,
//! `transform`s, the `viewBox`, `<use>` clones, `<symbol>`s, nested `<svg>`s, shapes turned into
//! paths. Each rendered path is tied back to its source element: before `usvg` parses the text, every
//! shape element gets a private numeric tag (carried through `usvg`, clones included, in a style
//! property that does not matter for cutting), and `<use>` elements without an id get a private
//! id. Nothing of this reaches the output.
//!
//! **Units.** Offsets are in mm in *document space* (the page as printed, x right, y down, origin at
//! the page's top-left corner — which is also where a kerf map is looked up). The root `<svg>`
//! must give `width` and `height` in absolute units (`mm`, `cm`, `in`, `pt`, `pc`); user units
//! follow from the `viewBox`. A file whose size is unitless or in `px` is refused ("unknown units":
//! 96 or 72 px per inch depends on the program that wrote it) unless the caller says what one user
//! unit is ([`AssumedUnits`], `--units`).
//!
//! **Geometry.** Every closed subpath of a cut element is a contour (a subpath closes with `Z` or
//! when it ends within 0.1 µm of its start; on pages over about 200 mm, within a few steps of
//! single precision). `usvg` turns arcs, circles and rounded corners into
//! cubic Béziers; those are recognised and made exact arcs again, other curves become biarcs
//! (see [`super::geom`]). `usvg` stores coordinates in single precision: about 0.01 µm per 100 mm
//! of page. An element with an arc that is elliptical on the page (an `<ellipse>`, an `A` with
//! `rx ≠ ry`, a rounded `<rect>` with `rx ≠ ry`, any arc under a skew or unequal scales), whose
//! cubics cannot be made the arc again, is traced instead from its exact geometry, read from the
//! source in double precision with its map to the page, subpath for subpath as usvg draws it
//! (see the private `svg::exact` module).
//!
//! **Writing.** A dilated contour is transformed back into the element's *own* coordinate system
//! (through the inverse of all its transforms, so a scaled or skewed group stays as it is; an arc
//! becomes an elliptical `A` arc where the transform is not a similarity) and written as the
//! element's new `d`:
//!
//! * `<path>`: only the `d` value changes. Inkscape's shape parameters (`sodipodi:*`,
//!   `inkscape:original-d`, `inkscape:path-effect`) are removed, or Inkscape would redraw the old
//!   shape on the next edit.
//! * `<rect>`, `<circle>`, `<ellipse>`, `<polygon>`, closed `<polyline>`: the element becomes a
//!   `<path>` with the same attributes (id, class, style, transform, …) minus its geometry
//!   attributes.
//! * A cut reached through `<use>`: the referenced element is copied, dilated for that instance
//!   (its position, and so its kerf, and its transform are the instance's), into a `<defs>` right
//!   after the original with ids suffixed `-kerfN`, and the `<use>` is pointed at the copy; the
//!   original stays for other users of it. Clones of clones (a cut reached through two nested
//!   `<use>`) are refused: unlink them first (Inkscape: Edit ▸ Clone ▸ Unlink Clone).
//! * Open subpaths of a cut element are kept as drawn (re-emitted in the element's coordinates)
//!   and reported.
//! * What was applied is recorded right after the root's start tag (a comment and a `<metadata>`
//!   element, see [`compensation`]), replacing an earlier record of this
//!   tool's.
//!
//! **Memory.** The dilated document is several times its source (every rounded corner an arc), so
//! it is written to the caller's writer as it is made ([`dilate_svg_into`]), a batch of elements'
//! path data at a time, the next batch made on the other cores while this one is written, and
//! each batch's dilated contours freed once its path data is made. No step holds more than it
//! needs: the source's XML tree is dropped, and so is the source itself, while usvg parses the
//! tagged copy (the source is made again from the copy, whose insertions are known), and of
//! usvg's tree only the cut paths' data is kept; the source is parsed again to name the cuts and
//! find where their new path data goes (byte ranges, a few per element), and that tree goes
//! before the cuts are traced, each path's data freed as it is traced (writing parses the source
//! once more only to copy the targets of `<use>` clones, and G-code's cut order parses it again
//! for the cuts' Inkscape layers). A plan read from a file ([`crate::file::dilate_file_into`],
//! what the CLI uses) does not hold its text while its cuts are dilated: the file is read again,
//! checked unchanged, as the output is written. The kernel frees each drawn contour as it is
//! offset. The peak is the end of the dilation (the dilated contours, cavalier's 24 bytes a
//! vertex, and what each cut needs to be written back), in a heap left fragmented by the reading
//! before it; usvg's parse (the tagged copy, usvg's XML tree of it and its own tree) is a little
//! lower.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt::Write as _;
use std::io::Write;
use std::ops::Range;
use std::str::FromStr;
use std::sync::atomic::{AtomicUsize, Ordering};

use cavalier_contours::polyline::PlineSource;
use rayon::prelude::*;
use roxmltree::{Document, Node, ParsingOptions};
use usvg::tiny_skia_path::{self, PathSegment};

use super::compensation::{self, CompensatedBy, IfCompensated};
use super::decimal::{decimals_for_step, pow10, write_scaled};
use super::dilate::KerfSource;
use super::entities;
use super::geom::{Affine, PathSink, Pline, V2, arc_geom, v2};
use super::outcome::{AssumedUnits, CutGroup, CutPath, PlanSummary};
use super::pipeline::{self, Cut, Format, MAX_CUT_VERTICES, Plan};
use super::progress::{Progress, Stage};
use super::rules::{CutRules, Rgb, Verdict};
use super::source_file::{Copier, SourceFile};
use crate::error::{PlanError, Problems, Result};

mod exact;
mod lost;
mod path_data;

use exact::{ExactPath, Exactness};
use path_data::Flaw;

const SVG_NS: &str = "http://www.w3.org/2000/svg";
const XLINK_NS: &str = "http://www.w3.org/1999/xlink";
const SODIPODI_NS: &str = "http://sodipodi.sourceforge.net/DTD/sodipodi-0.dtd";
const INKSCAPE_NS: &str = "http://www.inkscape.org/namespaces/inkscape";
const SHAPES: [&str; 7] = [
    "path", "rect", "circle", "ellipse", "line", "polyline", "polygon",
];
const GEOMETRY_ATTRIBUTES: [&str; 14] = [
    "x", "y", "width", "height", "rx", "ry", "cx", "cy", "r", "x1", "y1", "x2", "y2", "points",
];
/// Prefix of the private ids given to `<use>` elements that have none (never written out).
const USE_TAG: &str = "__kerfmeter_use_";
/// Elements whose dilated path data is made at once when the document is written (see
/// `SvgPlan::write_document`).
const WRITE_BATCH: usize = 256;

/// How to read an SVG plan.
#[derive(Debug, Clone, Default)]
pub struct SvgOptions {
    /// Which elements are cuts.
    pub rules: CutRules,
    /// What one user unit is when the root `<svg>` does not give absolute units.
    pub assume_units: Option<AssumedUnits>,
    /// What to do when the plan is already compensated.
    pub if_compensated: IfCompensated,
    /// Where to tell how far the work has got.
    pub progress: Progress,
}

/// A point as `usvg` gives it, single precision: half the memory of a [`V2`] (the segments of a
/// large plan, until traced, are most of the memory it takes).
#[derive(Debug, Clone, Copy)]
struct P32(f32, f32);

impl P32 {
    fn v2(self) -> V2 {
        v2(f64::from(self.0), f64::from(self.1))
    }
}

/// One drawing command of a subpath, in the element's own coordinates.
#[derive(Debug, Clone, Copy)]
enum Seg {
    M(P32),
    L(P32),
    Q(P32, P32),
    C(P32, P32, P32),
    Z,
}

/// One rendered occurrence of a cut element.
struct Instance {
    /// Index into the shape elements.
    element: usize,
    /// Index into the `<use>` elements, when reached through one.
    via_use: Option<usize>,
    /// Element coordinates → document mm.
    to_doc: Affine,
    /// How many subpaths the element has.
    subpath_count: usize,
    /// Its subpaths as `usvg` resolved them, kept only when one of them is not a closed contour
    /// (that one is written back as drawn); empty otherwise, as the closed ones are written back
    /// dilated.
    drawn: Vec<Vec<Seg>>,
    /// Its stroke colour (chooses its G-code cut settings).
    stroke: Option<Rgb>,
    /// Whether its curves are traced from its exact geometry (set by `read`, taken when it is
    /// traced; see [`exact`]).
    exact: Exactness,
    /// Where its element starts in the source, and where its new path data goes there (set by
    /// `read`).
    start: usize,
    slots: Vec<Slot>,
}

/// A place in the source that writing a cut element's new path data changes, found while reading
/// (see [`geometry_slots`]), so that writing needs no XML tree of the source.
#[derive(Debug, Clone)]
struct Slot {
    range: Range<usize>,
    put: Put,
}

/// What goes in a [`Slot`].
#[derive(Debug, Clone, Copy)]
enum Put {
    /// The new path data (the value of the element's `d`).
    D,
    /// A new `d` attribute with the path data.
    NewD,
    /// Nothing: an attribute removed.
    Nothing,
    /// `path`: the element's new name.
    Path,
}

/// A byte-range replacement in the source (an insertion when the range is empty).
#[derive(Debug, Clone)]
struct Edit {
    range: Range<usize>,
    text: String,
}

/// Edits inside the targets of `<use>` elements, by `<use>` (index into the `<use>` elements).
type CloneEdits = BTreeMap<usize, Vec<Edit>>;

/// The dilated contour of each (instance, subpath) that is a cut, with the cut's label. A
/// contour is freed once its instance's new path data is made (see [`Contours::free`]).
struct Contours<'p> {
    plines: Vec<Pline>,
    labels: Vec<&'p str>,
    by_origin: HashMap<(usize, usize), usize>,
}

impl<'p> Contours<'p> {
    /// The dilated contours `dilated` of `cuts` (in the same order).
    fn new(cuts: &'p [Cut<(usize, usize)>], dilated: Vec<Pline>) -> Self {
        Contours {
            by_origin: cuts
                .iter()
                .enumerate()
                .map(|(k, c)| (c.origin, k))
                .collect(),
            labels: cuts.iter().map(|c| c.contour.label.as_str()).collect(),
            plines: dilated,
        }
    }

    /// The dilated contour of subpath `si` of instance `ii`, if it is a cut, and its label.
    fn get(&self, ii: usize, si: usize) -> Option<(&Pline, &'p str)> {
        let &k = self.by_origin.get(&(ii, si))?;
        Some((self.plines.get(k)?, self.labels[k]))
    }

    /// Free the dilated contours of the instances `made` (of `instances`), whose path data is
    /// made: their memory goes to the path data made next, rather than the arena growing by as
    /// much.
    fn free(&mut self, made: &[usize], instances: &[Instance]) {
        for &ii in made {
            for si in 0..instances[ii].subpath_count {
                if let Some(&k) = self.by_origin.get(&(ii, si)) {
                    self.plines[k] = Pline::new_closed();
                }
            }
        }
    }
}

/// A subpath of an instance traced into document mm.
enum Traced {
    /// A closed contour: its subpath's index, the contour, its name.
    Closed(usize, Pline, String),
    /// An open path: its name, first and last points.
    Open(String, V2, V2),
}

fn bad(message: impl Into<String>) -> PlanError {
    PlanError::Svg(message.into())
}

/// Dilate the cuts of an SVG plan. Returns the edited document and what was done.
pub fn dilate_svg(
    text: &str,
    kerf: &KerfSource,
    opts: &SvgOptions,
) -> Result<(String, PlanSummary)> {
    let mut out = Vec::with_capacity(text.len());
    let summary = dilate_svg_into(text.to_owned(), kerf, opts, &mut out)?;
    let out = String::from_utf8(out).map_err(|_| {
        bad("internal error: the edited SVG is not UTF-8 (please report this file)")
    })?;
    Ok((out, summary))
}

/// Dilate the cuts of an SVG plan, writing the edited document to `out` as it is made (it is
/// never held whole: with its arcs written out, it is several times the size of the source).
/// The source `text` is taken, not lent: it is not held while usvg parses its tagged copy (see
/// `render`). On an error, part of the document may have been written. An error writing to
/// `out` is a [`PlanError::Write`] (whose path the caller sets).
pub fn dilate_svg_into(
    text: String,
    kerf: &KerfSource,
    opts: &SvgOptions,
    out: &mut (dyn Write + Sync),
) -> Result<PlanSummary> {
    dilate_svg_file_into(text, None, kerf, opts, out)
}

/// [`dilate_svg_into`] for a source `text` read from `file`, if given: then the text is not held
/// while the cuts are dilated, and the file is read again (checked unchanged) as the dilated
/// document is written.
pub(crate) fn dilate_svg_file_into(
    text: String,
    file: Option<SourceFile>,
    kerf: &KerfSource,
    opts: &SvgOptions,
    out: &mut (dyn Write + Sync),
) -> Result<PlanSummary> {
    opts.progress.start(Stage::Reading, 0);
    let (text, rendered) = render(text, opts)?;
    let ((), summary) = pipeline::dilate_plan(
        SvgPlan::new(text, file, rendered, out),
        kerf,
        opts.if_compensated,
        &opts.rules,
        &opts.progress,
    )?;
    Ok(summary)
}

/// Dilate the cuts of an SVG plan and give them back as contours in document mm (y down), each
/// with its stroke colour and Inkscape layer: what G-code is made from.
pub(crate) fn dilate_svg_cuts(
    text: String,
    kerf: &KerfSource,
    opts: &SvgOptions,
) -> Result<(Vec<CutPath>, PlanSummary)> {
    opts.progress.start(Stage::Reading, 0);
    let (text, rendered) = render(text, opts)?;
    pipeline::dilate_plan_cuts(
        SvgPlan::new(text, None, rendered, &mut std::io::sink()),
        kerf,
        opts.if_compensated,
        &opts.rules,
        &opts.progress,
    )
}

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
fn parse(text: &str) -> Result<Document<'_>> {
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
struct Rendered {
    plan: Plan<(usize, usize)>,
    instances: Vec<Instance>,
    /// `paths[k]` is the path data of `instances[k]`.
    paths: Vec<tiny_skia_path::Path>,
    /// The elements usvg could not draw (see [`lost`]), by (shape, outermost `<use>`): refused
    /// once they can be named.
    lost: Vec<(usize, Option<usize>)>,
    /// Document mm per usvg pixel.
    mm_per_px: f64,
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
/// Numbers single precision cannot hold are refused before usvg reads them (see [`path_data`]);
/// when what usvg drew shows transforms that may have combined past it, the tagged copy is drawn
/// again, scaled down, to find the elements usvg dropped (see [`lost`]).
fn render(text: String, opts: &SvgOptions) -> Result<(String, Rendered)> {
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

/// A `<path>`, `<polygon>` or `<polyline>` whose path data or points break off (see
/// [`path_data`]): its index among the shapes, its name and svgtypes' words for where.
struct BrokenPath {
    shape: usize,
    name: String,
    /// `path data` or `points`.
    data: &'static str,
    why: String,
}

/// The elements among `shapes` (of the source `text`) whose path data or points break off,
/// named; one with a coordinate too far for single precision is refused.
fn broken_paths(text: &str, shapes: &[Node]) -> Result<Vec<BrokenPath>> {
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
fn check_far_attributes(text: &str, doc: &Document) -> Result<()> {
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
fn check_broken(
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
fn check_entities(text: &str) -> Result<()> {
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

/// usvg's options: no image is ever loaded. An `<image>` is not a cut (the source counts them as
/// passed through), and loading one would read any file or device its `href` names (`/dev/zero`,
/// a FIFO: unbounded memory, or a wait for ever; a server's plan naming a local file) or parse an
/// embedded SVG again for every clone of it.
fn usvg_options() -> usvg::Options<'static> {
    usvg::Options {
        image_href_resolver: usvg::ImageHrefResolver {
            resolve_data: Box::new(|_, _, _| None),
            resolve_string: Box::new(|_, _| None),
        },
        ..usvg::Options::default()
    }
}

/// The shape elements and the `<use>` elements of a document, each in document order (an
/// instance's `element` and `via_use` index these).
fn shapes_and_uses<'d, 'a>(doc: &'d Document<'a>) -> (Vec<Node<'d, 'a>>, Vec<Node<'d, 'a>>) {
    let shapes = doc
        .descendants()
        .filter(|n| SHAPES.iter().any(|shape| is_svg(*n, shape)))
        .collect();
    let uses = doc.descendants().filter(|n| is_svg(*n, "use")).collect();
    (shapes, uses)
}

/// Whether `n` is the SVG element `name` as usvg reads them: in SVG's namespace, or in none
/// (under a prefixed root, `<s:svg xmlns:s="…">`, an unprefixed element has no namespace).
fn is_svg(n: Node, name: &str) -> bool {
    n.is_element()
        && matches!(n.tag_name().namespace(), None | Some(SVG_NS))
        && n.tag_name().name() == name
}

/// The elements of a parsed source that cuts are named and written by.
struct Elements<'d, 'a> {
    /// The shape elements, in document order (an instance's `element` indexes this).
    shapes: Vec<Node<'d, 'a>>,
    /// The `<use>` elements, in document order.
    uses: Vec<Node<'d, 'a>>,
    /// Elements by id (the first one with each id).
    ids: HashMap<&'d str, Node<'d, 'a>>,
}

impl<'d, 'a> Elements<'d, 'a> {
    fn of(doc: &'d Document<'a>) -> Self {
        let (shapes, uses) = shapes_and_uses(doc);
        let mut ids: HashMap<&str, Node> = HashMap::new();
        for n in doc.descendants().filter(|n| n.is_element()) {
            if let Some(id) = n.attribute("id") {
                ids.entry(id).or_insert(n);
            }
        }
        Elements { shapes, uses, ids }
    }
}

/// Where this tool's compensation record goes in the source (right after the root's start tag),
/// and its earlier records there, to drop.
#[derive(Default)]
struct Records {
    old: Vec<Range<usize>>,
    at: Option<usize>,
}

/// The source with tags inserted (see [`tagged`]), and where they are, so that the source can be
/// made again from it.
struct Tagged {
    text: String,
    /// The inserted tags' ranges in `text`, in order.
    tags: Vec<Range<usize>>,
}

impl Tagged {
    /// The source `text` with the insertions `edits` (empty source ranges) applied.
    fn new(src: &str, edits: Vec<Edit>) -> Result<Self> {
        let edits = sorted(edits);
        let mut grown = 0;
        let mut tags = Vec::with_capacity(edits.len());
        for e in &edits {
            if !e.range.is_empty() {
                return Err(bad(
                    "internal error: a tag replaces SVG text (please report this file)",
                ));
            }
            let at = e.range.start + grown;
            tags.push(at..at + e.text.len());
            grown += e.text.len();
        }
        Ok(Tagged {
            text: apply_edits(src, edits)?,
            tags,
        })
    }

    /// The source again: the text without the tags.
    fn untagged(self) -> String {
        let tagged_len: usize = self.tags.iter().map(Range::len).sum();
        let mut src = String::with_capacity(self.text.len() - tagged_len);
        let mut pos = 0;
        for tag in &self.tags {
            src.push_str(&self.text[pos..tag.start]);
            pos = tag.end;
        }
        src.push_str(&self.text[pos..]);
        src
    }
}

/// The source `text` with every shape tagged by its number (`stroke-miterlimit`, which usvg
/// keeps) and every `<use>` given an id, so that what usvg renders can be traced back to its
/// element; and the `<use>` elements by id.
fn tagged(text: &str, shapes: &[Node], uses: &[Node]) -> Result<(Tagged, HashMap<String, usize>)> {
    let mut tags: Vec<Edit> = Vec::new();
    for (k, n) in shapes.iter().enumerate() {
        let code = k + 1;
        match n
            .attributes()
            .find(|a| a.name() == "style" && a.namespace().is_none())
        {
            Some(style) => tags.push(Edit {
                range: style.range_value().end..style.range_value().end,
                text: format!(";stroke-miterlimit:{code}"),
            }),
            None => {
                let at = tag_name_range(text, *n).end;
                tags.push(Edit {
                    range: at..at,
                    text: format!(" style=\"stroke-miterlimit:{code}\""),
                });
            }
        }
    }
    let mut use_by_id: HashMap<String, usize> = HashMap::new();
    for (k, u) in uses.iter().enumerate() {
        match u.attribute("id") {
            Some(id) => {
                use_by_id.insert(id.to_string(), k);
            }
            None => {
                let id = format!("{USE_TAG}{k}");
                let at = tag_name_range(text, *u).end;
                tags.push(Edit {
                    range: at..at,
                    text: format!(" id=\"{id}\""),
                });
                use_by_id.insert(id, k);
            }
        }
    }
    Ok((Tagged::new(text, tags)?, use_by_id))
}

/// Write a batch of instances' new geometry (`made`, in document order) and, before each edit of
/// it, the other `edits` that come first.
fn write_batch(
    made: Vec<Option<Result<Vec<Edit>>>>,
    edits: &mut std::iter::Peekable<std::vec::IntoIter<Edit>>,
    out: &mut EditWriter,
    summary: &mut PlanSummary,
) -> Result<()> {
    for geometry in made.into_iter().flatten() {
        summary.changed_elements += 1;
        // On a tie the geometry goes first, as it did when all edits were sorted at once.
        for e in sorted(geometry?) {
            while let Some(x) = edits.next_if(|x| edit_key(x) < edit_key(&e)) {
                out.apply(x)?;
            }
            out.apply(e)?;
        }
    }
    Ok(())
}

/// An SVG document in the plan pipeline: the source text and the cut instances found by
/// rendering it. A contour's origin is (instance, subpath).
///
/// No XML tree of the source is kept between the steps (it was a fifth of the peak memory, held
/// through the dilation): reading parses the source to name the cuts and find where their new
/// path data goes, and drops it; writing parses it again only for cuts reached through `<use>`,
/// whose targets are copied. A plan read from a file does not even hold the source's text while
/// its cuts are dilated: the file is read again as the output is written (see [`SourceFile`]).
struct SvgPlan<'w> {
    /// The source (empty between reading and writing when `file` can give it back).
    text: String,
    /// The file the source was read from, when it is to be read again for writing.
    file: Option<SourceFile>,
    /// The rendered occurrences of cut elements (set by `read`).
    instances: Vec<Instance>,
    /// What rendering found, until `read` takes it.
    rendered: Option<Rendered>,
    /// Where the compensation record goes (set by `read`).
    records: Records,
    /// Where each line of the source starts, to name elements by line and column.
    lines: LineIndex,
    /// Where the dilated document goes (taken when it is written).
    out: Option<&'w mut (dyn Write + Sync)>,
}

impl<'w> SvgPlan<'w> {
    /// The plan of the source `text` (read from `file`, if given) as rendered.
    fn new(
        text: String,
        file: Option<SourceFile>,
        rendered: Rendered,
        out: &'w mut (dyn Write + Sync),
    ) -> Self {
        SvgPlan {
            lines: LineIndex::new(&text),
            text,
            file,
            instances: Vec::new(),
            rendered: Some(rendered),
            records: Records::default(),
            out: Some(out),
        }
    }

    /// Trace the instances' subpaths (by instance; `paths[k]` and `names[k]` are instance `k`'s
    /// path data and name) on any core, freeing each one's path data as it goes (it is kept, as
    /// segments, only for elements with an open subpath, which is written back as drawn). With
    /// them, the farthest reach and the instance that has it.
    fn trace_all(
        &mut self,
        paths: Vec<tiny_skia_path::Path>,
        names: &[String],
    ) -> Result<(Vec<Vec<Traced>>, Reach, usize)> {
        let vertices = AtomicUsize::new(0);
        let (traced, reaches): (Vec<Vec<Traced>>, Vec<Reach>) = self
            .instances
            .par_iter_mut()
            .zip(paths)
            .zip(names)
            .map(|((inst, path), name)| {
                let segs = subpaths_of(&path);
                drop(path);
                let reach = Reach::of(inst, &segs);
                let eps = reach.eps_mm();
                let exact = exact_geometry(inst, &segs, eps);
                let traced = trace(inst, &segs, exact.as_deref(), eps, name, &vertices);
                inst.subpath_count = segs.len();
                let all_closed = traced.len() == segs.len()
                    && traced.iter().all(|t| matches!(t, Traced::Closed(..)));
                if !all_closed {
                    inst.drawn = segs;
                }
                (traced, reach)
            })
            .unzip();
        let farthest = (0..reaches.len())
            .max_by(|&a, &b| reaches[a].held_to_mm().total_cmp(&reaches[b].held_to_mm()))
            .unwrap_or(0);
        let reach = reaches.get(farthest).copied().unwrap_or_default();
        if vertices.load(Ordering::Relaxed) > MAX_CUT_VERTICES {
            return Err(bad(format!(
                "the drawing's cuts come to more than {MAX_CUT_VERTICES} vertices once their curves are flattened (curves metres long and full of turns?); check the drawing and its units"
            )));
        }
        Ok((traced, reach, farthest))
    }

    /// How to name an instance in messages.
    fn label(&self, el: &Elements, inst: &Instance) -> String {
        self.name(el, inst.element, inst.via_use)
    }

    /// How to name shape `element` drawn through the `<use>` `via_use` in messages.
    fn name(&self, el: &Elements, element: usize, via_use: Option<usize>) -> String {
        let mut s = describe(&self.lines, el.shapes[element]);
        if let Some(u) = via_use {
            s.push_str(&format!(" via <use> {}", describe(&self.lines, el.uses[u])));
        }
        s
    }

    /// Refuse cuts reached through nested `<use>` clones (they cannot be copied one by one).
    fn check_uses(&self, el: &Elements) -> Result<()> {
        let mut problems = Problems::default();
        for inst in &self.instances {
            if let Some(u) = inst.via_use {
                // `ancestors()` starts at the node itself: the target may be the shape.
                let target = use_target(el.uses[u], &el.ids);
                let inside =
                    target.is_some_and(|t| el.shapes[inst.element].ancestors().any(|a| a == t));
                if !inside {
                    problems.push(format!(
                        "{} is reached through nested <use> clones; unlink the clones first (Inkscape: Edit ▸ Clone ▸ Unlink Clone)",
                        self.label(el, inst)
                    ));
                }
            }
        }
        problems.into_error(PlanError::Svg)
    }

    /// Each instance's traced subpaths (by instance), in document order: closed ones are cuts,
    /// the rest open paths.
    fn contours(plan: &mut Plan<(usize, usize)>, traced: Vec<Vec<Traced>>) {
        for (ii, subpaths) in traced.into_iter().enumerate() {
            for t in subpaths {
                match t {
                    Traced::Closed(si, pline, name) => plan.cut(pline, name, (ii, si)),
                    Traced::Open(name, first, last) => plan.open_path(name, first, last),
                }
            }
        }
    }

    /// In a boxes.py plan, which instances are of its reference rectangle, which boxes.py draws
    /// without burn (by instance; empty for other plans).
    fn boxes_references(&self, el: &Elements, summary: &PlanSummary) -> Vec<bool> {
        let boxes = summary
            .compensation_found
            .as_ref()
            .is_some_and(|f| f.by == CompensatedBy::BoxesPy);
        if !boxes {
            return Vec::new();
        }
        (self.instances.iter())
            .map(|inst| compensation::is_boxes_reference(el.shapes[inst.element]))
            .collect()
    }

    /// Everything reading needs from the source's XML tree, found in one parse that is dropped
    /// before the cuts are traced (the tree and the traced contours held at once were the peak
    /// of reading): the uses checked, the instances placed, the compensation records found, and
    /// each instance's name and whether it is of boxes.py's reference rectangle (`mm_per_px`:
    /// document mm per usvg pixel).
    fn read_source(
        &mut self,
        summary: &PlanSummary,
        lost: &[(usize, Option<usize>)],
        mm_per_px: f64,
    ) -> Result<(Vec<String>, Vec<bool>)> {
        let doc = parse(&self.text)?;
        let el = Elements::of(&doc);
        let lost = lost.iter().map(|&(e, u)| self.name(&el, e, u));
        lost::refuse(lost)?;
        self.check_uses(&el)?;
        place(&mut self.instances, &self.text, &el, mm_per_px);
        self.records = Records {
            old: compensation::own_svg_records(&doc),
            at: doc.root_element().first_child().map(|n| n.range().start),
        };
        let names = (self.instances.iter())
            .map(|inst| self.label(&el, inst))
            .collect();
        Ok((names, self.boxes_references(&el, summary)))
    }

    /// The new geometry of the instances reached through `<use>`, as edits by `<use>`: their
    /// targets are copied whole (see [`Self::clone_uses`]), so these are made before writing.
    fn clone_geometry_edits(
        &self,
        contours: &Contours,
        summary: &mut PlanSummary,
    ) -> Result<CloneEdits> {
        let made: Vec<(usize, Option<Result<Vec<Edit>>>)> = self
            .instances
            .par_iter()
            .enumerate()
            .filter_map(|(ii, inst)| {
                let u = inst.via_use?;
                Some((u, self.instance_edits(ii, inst, contours)))
            })
            .collect();
        let mut clone_edits: CloneEdits = BTreeMap::new();
        for (u, edits) in made {
            if let Some(edits) = edits {
                clone_edits.entry(u).or_default().extend(edits?);
                summary.changed_elements += 1;
            }
        }
        Ok(clone_edits)
    }

    /// Write the document with `edits` applied and the instances drawn directly (not through
    /// `<use>`) given their dilated geometry. That geometry is made batch by batch as the
    /// document is written (each batch's path data on any core, the next one while this one is
    /// written), so no more than two batches of it are held at once: the path data of a whole
    /// plan is larger than its file.
    fn write_document(
        &self,
        edits: Vec<Edit>,
        contours: &mut Contours,
        summary: &mut PlanSummary,
        sink: &mut (dyn Write + Sync),
    ) -> Result<()> {
        let mut direct: Vec<usize> = (0..self.instances.len())
            .filter(|&ii| self.instances[ii].via_use.is_none())
            .collect();
        direct.sort_by_key(|&ii| self.instances[ii].start);
        let mut edits = sorted(edits).into_iter().peekable();
        let src = match (&self.file, self.text.is_empty()) {
            (Some(file), true) => Src::File(file.copier()?),
            _ => Src::Text(&self.text),
        };
        let mut out = EditWriter::new(src, sink);
        let batches: Vec<&[usize]> = direct.chunks(WRITE_BATCH).collect();
        let make = |batch: &[usize], contours: &Contours| -> Vec<Option<Result<Vec<Edit>>>> {
            batch
                .par_iter()
                .map(|&ii| self.instance_edits(ii, &self.instances[ii], contours))
                .collect()
        };
        let mut made = batches.first().map(|b| make(b, contours));
        for (k, batch) in batches.iter().enumerate() {
            let current = made.take().unwrap_or_default();
            contours.free(batch, &self.instances);
            let contours = &*contours;
            // The next batch is made on the pool while this thread writes this one.
            let written = rayon::in_place_scope(|scope| {
                scope.spawn(|_| made = batches.get(k + 1).map(|b| make(b, contours)));
                write_batch(current, &mut edits, &mut out, summary)
            });
            written?;
        }
        for x in edits {
            out.apply(x)?;
        }
        out.finish()
    }

    /// The compensation record (see [`compensation`]) right after the root's start tag, replacing
    /// any this tool wrote before.
    fn record_edits(&self, summary: &PlanSummary) -> Vec<Edit> {
        let mut edits: Vec<Edit> = (self.records.old.iter())
            .map(|range| Edit {
                range: range.clone(),
                text: String::new(),
            })
            .collect();
        if let (Some(applied), Some(at)) = (&summary.compensation_applied, self.records.at) {
            edits.push(Edit {
                range: at..at,
                text: applied.svg_record(),
            });
        }
        edits
    }

    /// The edits that give instance `ii` its dilated subpaths (the others re-emitted as drawn);
    /// `None` when none of its subpaths was dilated.
    fn instance_edits(
        &self,
        ii: usize,
        inst: &Instance,
        contours: &Contours,
    ) -> Option<Result<Vec<Edit>>> {
        let (_, label) = (0..inst.subpath_count).find_map(|si| contours.get(ii, si))?;
        let Some(to_local) = inst.to_doc.inverse() else {
            return Some(Err(bad(format!(
                "{label} has a degenerate transform (zero scale)"
            ))));
        };
        let digits = digits_for(&inst.to_doc);
        let mut d = String::new();
        for si in 0..inst.subpath_count {
            if !d.is_empty() {
                d.push(' ');
            }
            match (contours.get(ii, si), inst.drawn.get(si)) {
                (Some((pline, _)), _) => write_pline(pline, &to_local, digits, &mut d),
                (None, Some(segs)) => write_segs(segs, digits, &mut d),
                // Not kept: every subpath of this instance is a dilated contour.
                (None, None) => {}
            }
        }
        Some(Ok(filled(&inst.slots, &d)))
    }

    /// Copies of the targets of `<use>` elements whose cuts were dilated (ids suffixed `-kerfN`),
    /// each `<use>` pointed at its copy: edits to `main_edits`, one note per copied target.
    fn clone_uses(
        &self,
        el: &Elements,
        clone_edits: CloneEdits,
        main_edits: &mut Vec<Edit>,
        summary: &mut PlanSummary,
    ) -> Result<()> {
        let mut taken: HashSet<String> = el.ids.keys().map(|s| s.to_string()).collect();
        let mut inserts: BTreeMap<usize, (Node, String)> = BTreeMap::new();
        let mut counter = 0usize;
        for (u, edits) in clone_edits {
            let node = el.uses[u];
            let target = use_target(node, &el.ids).expect("checked above");
            let suffix = loop {
                counter += 1;
                let s = format!("-kerf{counter}");
                let root_id = format!("{}{s}", target.attribute("id").unwrap_or(""));
                if !taken.contains(&root_id) {
                    break s;
                }
            };
            let clone = self.clone_of(target, edits, &suffix, &mut taken)?;
            let new_root = format!("{}{suffix}", target.attribute("id").unwrap_or(""));
            for a in node.attributes() {
                let is_href = a.name() == "href"
                    && (a.namespace().is_none() || a.namespace() == Some(XLINK_NS));
                if is_href {
                    main_edits.push(Edit {
                        range: a.range_value(),
                        text: format!("#{new_root}"),
                    });
                }
            }
            let entry = inserts
                .entry(target.range().end)
                .or_insert_with(|| (target, String::new()));
            entry.1.push('\n');
            entry.1.push_str(&clone);
        }
        for (at, (target, clones)) in inserts {
            let in_defs = target.parent_element().is_some_and(|p| is_svg(p, "defs"));
            let text = if in_defs {
                clones
            } else {
                format!("<defs>{clones}</defs>")
            };
            main_edits.push(Edit {
                range: at..at,
                text,
            });
            summary.notes.push(format!(
                "cuts reached through <use> were dilated in copies of {} (ids suffixed -kerfN)",
                describe(&self.lines, target)
            ));
        }
        Ok(())
    }

    /// The source of `target` with `edits` (source ranges) applied and every id suffixed.
    fn clone_of(
        &self,
        target: Node,
        edits: Vec<Edit>,
        suffix: &str,
        taken: &mut HashSet<String>,
    ) -> Result<String> {
        let tr = target.range();
        let mut local: Vec<Edit> = edits
            .into_iter()
            .map(|e| Edit {
                range: e.range.start - tr.start..e.range.end - tr.start,
                text: e.text,
            })
            .collect();
        for n in target.descendants().filter(|n| n.is_element()) {
            if let Some(a) = n
                .attributes()
                .find(|a| a.name() == "id" && a.namespace().is_none())
            {
                let new_id = format!("{}{suffix}", a.value());
                taken.insert(new_id.clone());
                let r = a.range_value();
                local.push(Edit {
                    range: r.start - tr.start..r.end - tr.start,
                    text: new_id,
                });
            }
        }
        apply_edits(&self.text[tr], local)
    }
}

impl Format for SvgPlan<'_> {
    type Origin = (usize, usize);
    type Output = ();

    fn read(&mut self) -> Result<Plan<(usize, usize)>> {
        let Some(Rendered {
            mut plan,
            instances,
            paths,
            lost,
            mm_per_px,
        }) = self.rendered.take()
        else {
            return Err(bad("internal error: the SVG was read twice"));
        };
        self.instances = instances;
        let (names, boxes_reference) = self.read_source(&plan.summary, &lost, mm_per_px)?;
        let (traced, reach, farthest) = self.trace_all(paths, &names)?;
        if let Some(name) = names.get(farthest) {
            check_reach(reach, name, &mut plan.summary)?;
        }
        let approximated: Vec<&str> = (self.instances.iter().zip(&names))
            .filter(|(inst, _)| matches!(inst.exact, Exactness::Approximated))
            .map(|(_, name)| name.as_str())
            .collect();
        exact::note_approximated(&approximated, &mut plan.summary);
        drop(names);
        plan.summary.cut_elements = self.instances.len();
        Self::contours(&mut plan, traced);
        for (k, cut) in plan.cuts.iter().enumerate() {
            if boxes_reference.get(cut.origin.0) == Some(&true) {
                plan.unburnt.push(k);
            }
        }
        if self.file.is_some() {
            // Read again when the plan is written.
            self.text = String::new();
        }
        Ok(plan)
    }

    fn groups(&self, plan: &Plan<(usize, usize)>) -> Vec<CutGroup> {
        // The layers are read from the source parsed again (only G-code asks for them, and it
        // parsed in `read`: a failure now would be a bug, not bad input). The cuts' path never
        // reads from a file (`dilate_svg_cuts` keeps its text), so the text is here.
        debug_assert!(
            self.file.is_none(),
            "the cuts' groups need the source's text"
        );
        let doc = parse(&self.text).expect("the source parsed when it was read");
        let el = Elements::of(&doc);
        plan.cuts
            .iter()
            .map(|cut| {
                let inst = &self.instances[cut.origin.0];
                // A clone is on the layer of its <use>, not of the element it copies.
                let layer =
                    inkscape_layer(inst.via_use.map_or(el.shapes[inst.element], |u| el.uses[u]));
                CutGroup {
                    color: inst.stroke,
                    layer,
                }
            })
            .collect()
    }

    fn write(mut self, plan: &mut Plan<(usize, usize)>, dilated: Vec<Pline>) -> Result<()> {
        let mut contours = Contours::new(&plan.cuts, dilated);
        let mut edits = Vec::new();
        if self.instances.iter().any(|inst| inst.via_use.is_some()) {
            // The targets of `<use>` are copied from the source's text: it is read again whole.
            if let Some(file) = self.file.as_ref().filter(|_| self.text.is_empty()) {
                self.text = file.read_again()?;
            }
            let doc = parse(&self.text)?;
            let el = Elements::of(&doc);
            let clone_edits = self.clone_geometry_edits(&contours, &mut plan.summary)?;
            self.clone_uses(&el, clone_edits, &mut edits, &mut plan.summary)?;
        }
        edits.extend(self.record_edits(&plan.summary));
        let Some(sink) = self.out.take() else {
            return Err(bad("internal error: the SVG was written twice"));
        };
        self.write_document(edits, &mut contours, &mut plan.summary, sink)
    }
}

/// Refuse a root `viewBox` that draws nothing or maps the page absurdly: renderers take a zero or
/// negative one to switch rendering off, and usvg drops one it cannot use and takes a user unit
/// for a pixel, so the output would be dilated in other units than the file's readers see.
fn check_view_box(root: Node) -> Result<()> {
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

/// The length of the root's user unit, mm, as the report says it: usvg's px (`mm_per_px`) times
/// the px in one user unit, which a `viewBox` sets (the page over the box, the smaller of the two
/// ways as SVG's default `preserveAspectRatio` fits it) and which is otherwise one px.
fn user_unit_mm(root: Node, mm_per_px: f64) -> f64 {
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
fn length_px(l: &svgtypes::Length) -> Option<f64> {
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
fn document_scale(
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

/// The walk over usvg's tree: the cut instances found, and each one's path data (a copy).
struct Walk<'a> {
    rules: &'a CutRules,
    mm_per_px: f64,
    shapes_len: usize,
    use_by_id: &'a HashMap<String, usize>,
    /// Whether cut instances are kept: not when only which elements are drawn is asked (see
    /// [`lost`]).
    keep: bool,
    instances: Vec<Instance>,
    paths: Vec<tiny_skia_path::Path>,
    /// The visible stroked elements drawn, by (shape, outermost `<use>`): every cut instance,
    /// and the other elements drawn with a stroke (only those can be named: see [`tagged`]).
    seen: HashSet<(usize, Option<usize>)>,
    summary: &'a mut PlanSummary,
    unidentified: usize,
    /// A group whose combined transform may have made usvg drop what it holds (see
    /// [`lost::Overflow`]).
    overflow: Option<lost::Overflow>,
}

impl<'a> Walk<'a> {
    /// A walk that keeps the cut instances when `keep`.
    fn new(
        rules: &'a CutRules,
        mm_per_px: f64,
        shapes_len: usize,
        use_by_id: &'a HashMap<String, usize>,
        summary: &'a mut PlanSummary,
        keep: bool,
    ) -> Self {
        // Room for one instance per shape (most plans: the cuts, and a few more) from the start:
        // grown by doubling, these vectors held up to twice their room at the peak of reading.
        let room = if keep { shapes_len } else { 0 };
        Walk {
            rules,
            mm_per_px,
            shapes_len,
            use_by_id,
            keep,
            instances: Vec::with_capacity(room),
            paths: Vec::with_capacity(room),
            seen: HashSet::new(),
            summary,
            unidentified: 0,
            overflow: None,
        }
    }

    fn group(&mut self, g: &usvg::Group, uses: &mut Vec<usize>) {
        for child in g.children() {
            match child {
                usvg::Node::Group(c) => {
                    lost::Overflow::note(&mut self.overflow, c);
                    let u = self.use_by_id.get(c.id()).copied();
                    if let Some(u) = u {
                        uses.push(u);
                    }
                    self.group(c, uses);
                    if u.is_some() {
                        uses.pop();
                    }
                }
                usvg::Node::Path(p) => self.path(p, uses),
                // Never loaded (see `usvg_options`): the source counted them.
                usvg::Node::Image(_) => {}
                #[allow(unreachable_patterns)]
                _ => self.summary.pass("other"),
            }
        }
    }

    /// The shape (its index) whose tag (see [`tagged`]) is the stroke miter limit `code`.
    fn shape_of(&self, code: f32) -> Option<usize> {
        let element = code as usize;
        (code.fract() == 0.0 && element > 0 && element <= self.shapes_len).then(|| element - 1)
    }

    fn path(&mut self, p: &usvg::Path, uses: &[usize]) {
        if !p.is_visible() {
            self.summary.pass("hidden");
            return;
        }
        // usvg drops ids inside clones, so only the outermost <use> is seen; a cut reached
        // through nested clones is caught by the caller (it does not lie in that <use>'s
        // target).
        let via_use = uses.first().copied();
        let shape = p.stroke().and_then(|s| self.shape_of(s.miterlimit().get()));
        if !self.keep {
            self.seen.extend(shape.map(|e| (e, via_use)));
            return;
        }
        let to_doc = Affine::scale(self.mm_per_px).then_after(&affine(p.abs_transform()));
        let stroke = p.stroke().and_then(|s| match s.paint() {
            usvg::Paint::Color(c) if s.opacity().get() > 0.0 => Some((
                Rgb(c.red, c.green, c.blue),
                f64::from(s.width().get()) * to_doc.mean_scale(),
            )),
            _ => None,
        });
        let filled = p.fill().is_some_and(|f| f.opacity().get() > 0.0);
        match self.rules.classify_svg(stroke, filled) {
            Verdict::Keep(reason) => {
                self.summary.pass(reason);
                self.seen.extend(shape.map(|e| (e, via_use)));
            }
            Verdict::Cut => {
                let Some(element) = shape else {
                    self.unidentified += 1;
                    return;
                };
                if !self.seen.insert((element, via_use)) {
                    // The same element drawn twice in one instance (paint-order with markers).
                    return;
                }
                let instance = Instance {
                    element,
                    via_use,
                    to_doc,
                    subpath_count: 0,
                    drawn: Vec::new(),
                    stroke: stroke.map(|s| s.0),
                    exact: Exactness::Usvg,
                    start: 0,
                    slots: Vec::new(),
                };
                self.instances.push(instance);
                self.paths.push(p.data().clone());
            }
        }
    }
}

/// The Inkscape layer (a `<g inkscape:groupmode="layer">`) nearest around `node`: its label, else
/// its id.
fn inkscape_layer(node: Node) -> Option<String> {
    node.ancestors()
        .find(|a| a.attribute((INKSCAPE_NS, "groupmode")) == Some("layer"))
        .and_then(|g| {
            g.attribute((INKSCAPE_NS, "label"))
                .or_else(|| g.attribute("id"))
                .map(str::to_string)
        })
}

fn affine(t: usvg::Transform) -> Affine {
    Affine {
        a: f64::from(t.sx),
        b: f64::from(t.ky),
        c: f64::from(t.kx),
        d: f64::from(t.sy),
        e: f64::from(t.tx),
        f: f64::from(t.ty),
    }
}

/// A path's subpaths as usvg resolved them, each vector no larger than it needs.
fn subpaths_of(p: &tiny_skia_path::Path) -> Vec<Vec<Seg>> {
    let mut subpaths: Vec<Vec<Seg>> = Vec::new();
    let pt = |q: tiny_skia_path::Point| P32(q.x, q.y);
    for seg in p.segments() {
        let s = match seg {
            PathSegment::MoveTo(a) => {
                subpaths.push(Vec::new());
                Seg::M(pt(a))
            }
            PathSegment::LineTo(a) => Seg::L(pt(a)),
            PathSegment::QuadTo(a, b) => Seg::Q(pt(a), pt(b)),
            PathSegment::CubicTo(a, b, c) => Seg::C(pt(a), pt(b), pt(c)),
            PathSegment::Close => Seg::Z,
        };
        if subpaths.is_empty() {
            subpaths.push(Vec::new());
        }
        subpaths.last_mut().expect("pushed").push(s);
    }
    for sub in &mut subpaths {
        sub.shrink_to_fit();
    }
    subpaths.shrink_to_fit();
    subpaths
}

/// Where each instance's element starts in the source `text`, where its new path data goes, and
/// whether its curves are traced from its exact geometry (read from the source here, with its
/// map to the page in double precision where the source gives it; `mm_per_px`: document mm per
/// usvg pixel).
fn place(instances: &mut [Instance], text: &str, el: &Elements, mm_per_px: f64) {
    instances.par_iter_mut().for_each(|inst| {
        let node = el.shapes[inst.element];
        inst.start = node.range().start;
        inst.slots = geometry_slots(text, node);
        let cloned = inst.via_use.is_some();
        (inst.exact, inst.to_doc) = exact::exactness(node, inst.to_doc, mm_per_px, cloned);
    });
}

/// The exact geometry of `inst` (drawn by usvg as `segs`, held to `eps` mm), when it has one that
/// agrees with what usvg drew (see [`exact`]); an instance whose exact geometry does not agree is
/// marked [`Exactness::Approximated`].
fn exact_geometry(inst: &mut Instance, segs: &[Vec<Seg>], eps: f64) -> Option<Box<ExactPath>> {
    match std::mem::take(&mut inst.exact) {
        Exactness::Exact(path) if path.agrees(segs, &inst.to_doc, join_mm(eps)) => Some(path),
        Exactness::Exact(_) | Exactness::Approximated => {
            inst.exact = Exactness::Approximated;
            None
        }
        Exactness::Usvg => None,
    }
}

/// Points of an instance closer than this (mm) are one point, its coordinates held to `eps` mm
/// (see [`Reach::eps_mm`]): 0.1 µm, more on huge pages (a few single-precision steps).
fn join_mm(eps: f64) -> f64 {
    (8.0 * eps).max(1e-4)
}

/// One instance's subpaths (`subpaths`, in its element's coordinates, or `exact`, its exact
/// geometry, when given) in document mm, ends within [`join_mm`] meeting; `name` names the
/// instance.
fn trace(
    inst: &Instance,
    subpaths: &[Vec<Seg>],
    exact: Option<&ExactPath>,
    eps: f64,
    name: &str,
    vertices: &AtomicUsize,
) -> Vec<Traced> {
    let n_sub = subpaths.len();
    let mut traced = Vec::with_capacity(n_sub);
    // A curve may flatten to thousands of vertices (a line or move adds one): the budget is
    // watched after each.
    let over_budget =
        |sink: &PathSink| vertices.load(Ordering::Relaxed) + sink.vertex_count() > MAX_CUT_VERTICES;
    for (si, segs) in subpaths.iter().enumerate() {
        let mut sink = PathSink::new(join_mm(eps), eps);
        let over = match exact {
            Some(exact) => exact.draw(si, &inst.to_doc, &mut sink, &over_budget),
            None => draw_segs(segs, &inst.to_doc, &mut sink, &over_budget),
        };
        if over {
            // Refused by the caller: nothing more is traced.
            vertices.store(usize::MAX, Ordering::Relaxed);
            return traced;
        }
        vertices.fetch_add(sink.vertex_count(), Ordering::Relaxed);
        let Some(sub) = sink.finish().into_iter().next() else {
            continue;
        };
        let mut name = name.to_string();
        if n_sub > 1 {
            name.push_str(&format!(" (subpath {} of {n_sub})", si + 1));
        }
        if sub.pline.is_closed() {
            traced.push(Traced::Closed(si, sub.pline, name));
        } else {
            let first = sub.pline.at(0);
            let last = sub.pline.at(sub.pline.vertex_count() - 1);
            traced.push(Traced::Open(name, v2(first.x, first.y), v2(last.x, last.y)));
        }
    }
    traced
}

/// Draw usvg's subpath `segs` into `sink` in document mm (through `to_doc`). After each curve,
/// `over_budget` is asked whether the vertices drawn are too many: then drawing stops and `true`
/// is returned.
fn draw_segs(
    segs: &[Seg],
    to_doc: &Affine,
    sink: &mut PathSink,
    over_budget: &dyn Fn(&PathSink) -> bool,
) -> bool {
    let doc = |p: P32| to_doc.apply(p.v2());
    for s in segs {
        match *s {
            Seg::M(p) => sink.move_to(doc(p)),
            Seg::L(p) => sink.line_to(doc(p)),
            Seg::Q(a, b) => sink.quad_to(doc(a), doc(b)),
            Seg::C(a, b, c) => sink.cubic_to(doc(a), doc(b), doc(c)),
            Seg::Z => sink.close(),
        }
        if matches!(s, Seg::Q(..) | Seg::C(..)) && over_budget(sink) {
            return true;
        }
    }
    false
}

/// How far an instance's coordinates reach from the origin, in document mm: through its own
/// coordinates (scaled to mm) and in the document. usvg keeps them in `f32`, whose step grows
/// with the distance.
#[derive(Clone, Copy, Default)]
struct Reach {
    local_mm: f64,
    doc_mm: f64,
}

impl Reach {
    /// The reach of `inst`'s `subpaths`.
    fn of(inst: &Instance, subpaths: &[Vec<Seg>]) -> Self {
        let mut local = 0.0f64;
        let mut doc = 0.0f64;
        for s in subpaths.iter().flatten() {
            let pts: &[P32] = match s {
                Seg::M(a) | Seg::L(a) => std::slice::from_ref(a),
                Seg::Q(a, _) => std::slice::from_ref(a),
                Seg::C(a, _, _) => std::slice::from_ref(a),
                Seg::Z => &[],
            };
            for p in pts.iter().map(|p| p.v2()) {
                local = local.max(p.x.abs()).max(p.y.abs());
                let q = inst.to_doc.apply(p);
                doc = doc.max(q.x.abs()).max(q.y.abs());
            }
        }
        Reach {
            local_mm: local * inst.to_doc.mean_scale(),
            doc_mm: doc,
        }
    }

    /// Rounding uncertainty of the coordinates in document mm, with a margin: within it, ends
    /// meet.
    fn eps_mm(self) -> f64 {
        4.0 * f64::from(f32::EPSILON) * (self.local_mm + self.doc_mm + 1e-3)
    }

    /// How finely single precision holds the farthest coordinate, ± mm (half its step).
    fn held_to_mm(self) -> f64 {
        0.5 * f64::from(f32::EPSILON) * self.local_mm.max(self.doc_mm)
    }
}

/// Beyond this (± mm) a drawing is too far from the origin to be dilated: at 10 µm, 170 m out.
const FARTHEST_HELD_TO_MM: f64 = 0.01;

/// A drawing reaching `reach` (its farthest instance's, named `name`) is refused when single
/// precision holds it to worse than [`FARTHEST_HELD_TO_MM`]; noted in `summary` when worse than
/// the 0.1 µm the output keeps (1.7 m out).
fn check_reach(reach: Reach, name: &str, summary: &mut PlanSummary) -> Result<()> {
    let (far_mm, held_um) = (reach.local_mm.max(reach.doc_mm), reach.held_to_mm() * 1e3);
    if reach.held_to_mm() > FARTHEST_HELD_TO_MM {
        return Err(bad(format!(
            "{name} reaches {far_mm:.0} mm from the origin, where an SVG's coordinates are held only to ±{held_um:.0} µm (single precision); move the drawing near the origin"
        )));
    }
    if held_um > 0.1 {
        summary.notes.push(format!(
            "{name} reaches {far_mm:.0} mm from the origin, where an SVG's coordinates are held to ±{held_um:.2} µm (single precision), not 0.1 µm"
        ));
    }
    Ok(())
}

/// Decimal places that keep 0.01 µm in the element's coordinates.
fn digits_for(to_doc: &Affine) -> usize {
    let local_per_mm = 1.0 / to_doc.mean_scale().max(1e-300);
    decimals_for_step(1e-5 * local_per_mm)
}

/// `v` with at most `digits` decimals, trailing zeros dropped (`-0` is `0`).
fn num(v: f64, digits: usize, out: &mut String) {
    // Fast path: round to an integer count of the last decimal, ties to even as float
    // formatting does, and print that. Where the product itself rounds across a tie (rare), the
    // last decimal differs by one: 0.01 µm in mm.
    let scaled = (v * pow10(digits as i32)).round_ties_even();
    if digits <= 12 && scaled.abs() < 1e15 {
        if scaled != 0.0 && scaled < 0.0 {
            out.push('-');
        }
        write_scaled(scaled.abs() as u64, digits, |s| out.push_str(s));
        return;
    }
    let mut s = format!("{v:.digits$}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    if s == "-0" {
        s = "0".into();
    }
    out.push_str(&s);
}

fn point(p: V2, digits: usize, out: &mut String) {
    num(p.x, digits, out);
    out.push(' ');
    num(p.y, digits, out);
}

/// Write a closed document-space polyline as path data in element coordinates.
pub(crate) fn write_pline(p: &Pline, to_local: &Affine, digits: usize, out: &mut String) {
    let n = p.vertex_count();
    let mirror = to_local.det() < 0.0;
    // The image of a circle of radius 1: every arc's ellipse is this one scaled.
    let (unit_rx, unit_ry, rot) = to_local.circle_image(1.0);
    let rot_deg = rot.to_degrees();
    out.push('M');
    let v0 = p.at(0);
    point(to_local.apply(v2(v0.x, v0.y)), digits, out);
    for i in 0..n {
        let a = p.at(i);
        let b = p.at((i + 1) % n);
        let q = to_local.apply(v2(b.x, b.y));
        match arc_geom(v2(a.x, a.y), v2(b.x, b.y), a.bulge) {
            Some(g) => {
                let large = g.sweep.abs() > std::f64::consts::PI;
                let sweep = (g.sweep > 0.0) != mirror;
                out.push_str(" A");
                num(g.radius * unit_rx, digits, out);
                out.push(' ');
                num(g.radius * unit_ry, digits, out);
                out.push(' ');
                num(rot_deg, 6, out);
                let _ = write!(out, " {} {} ", u8::from(large), u8::from(sweep));
                point(q, digits, out);
            }
            None if i + 1 < n => {
                out.push_str(" L");
                point(q, digits, out);
            }
            None => {}
        }
    }
    out.push_str(" Z");
}

/// Write segments unchanged (element coordinates).
fn write_segs(segs: &[Seg], digits: usize, out: &mut String) {
    for (k, s) in segs.iter().enumerate() {
        if k > 0 {
            out.push(' ');
        }
        match *s {
            Seg::M(a) => {
                out.push('M');
                point(a.v2(), digits, out);
            }
            Seg::L(a) => {
                out.push('L');
                point(a.v2(), digits, out);
            }
            Seg::Q(a, b) => {
                out.push('Q');
                point(a.v2(), digits, out);
                out.push(' ');
                point(b.v2(), digits, out);
            }
            Seg::C(a, b, c) => {
                out.push('C');
                point(a.v2(), digits, out);
                out.push(' ');
                point(b.v2(), digits, out);
                out.push(' ');
                point(c.v2(), digits, out);
            }
            Seg::Z => out.push('Z'),
        }
    }
}

/// `<tag` … the byte range of the tag's qualified name in a start tag.
fn tag_name_range(src: &str, n: Node) -> Range<usize> {
    let start = n.range().start + 1;
    let end = src[start..]
        .find(|c: char| c.is_whitespace() || c == '/' || c == '>')
        .map_or(src.len(), |i| start + i);
    start..end
}

/// The range of the local name within a qualified name range.
fn local_name(src: &str, qname: Range<usize>) -> Range<usize> {
    match src[qname.clone()].rfind(':') {
        Some(i) => qname.start + i + 1..qname.end,
        None => qname,
    }
}

/// An attribute's range including the whitespace before it.
fn attribute_with_space(src: &str, a: &roxmltree::Attribute) -> Range<usize> {
    let r = a.range();
    let mut start = r.start;
    while start > 0 && src.as_bytes()[start - 1].is_ascii_whitespace() {
        start -= 1;
    }
    start..r.end
}

/// The edits that give an element with these `slots` the path data `d`.
fn filled(slots: &[Slot], d: &str) -> Vec<Edit> {
    slots
        .iter()
        .map(|slot| Edit {
            range: slot.range.clone(),
            text: match slot.put {
                Put::D => d.to_string(),
                Put::NewD => format!(" d=\"{d}\""),
                Put::Nothing => String::new(),
                Put::Path => "path".into(),
            },
        })
        .collect()
}

/// Where giving `node` new path data changes the source (see the module doc).
fn geometry_slots(src: &str, node: Node) -> Vec<Slot> {
    let mut slots = Vec::new();
    let is_path = node.tag_name().name() == "path";
    let dropped = |a: &roxmltree::Attribute| match a.namespace() {
        Some(SODIPODI_NS) => true,
        Some(INKSCAPE_NS) => matches!(a.name(), "original-d" | "path-effect"),
        None => !is_path && GEOMETRY_ATTRIBUTES.contains(&a.name()),
        _ => false,
    };
    let mut last_end = tag_name_range(src, node).end;
    let mut has_d = false;
    for a in node.attributes() {
        last_end = last_end.max(a.range().end);
        if is_path && a.name() == "d" && a.namespace().is_none() {
            has_d = true;
            slots.push(Slot {
                range: a.range_value(),
                put: Put::D,
            });
        } else if dropped(&a) {
            slots.push(Slot {
                range: attribute_with_space(src, &a),
                put: Put::Nothing,
            });
        }
    }
    if !has_d {
        slots.push(Slot {
            range: last_end..last_end,
            put: Put::NewD,
        });
    }
    if !is_path {
        slots.push(Slot {
            range: local_name(src, tag_name_range(src, node)),
            put: Put::Path,
        });
        let r = node.range();
        if !src[..r.end].ends_with("/>")
            && let Some(i) = src[r.clone()].rfind("</")
        {
            let start = r.start + i + 2;
            let end = src[start..r.end]
                .find(|c: char| c.is_whitespace() || c == '>')
                .map_or(r.end, |k| start + k);
            slots.push(Slot {
                range: local_name(src, start..end),
                put: Put::Path,
            });
        }
    }
    slots
}

/// The order edits are applied in: by where they start, then end (an insertion before a
/// replacement at the same place).
fn edit_key(e: &Edit) -> (usize, usize) {
    (e.range.start, e.range.end)
}

/// `edits` in the order they are applied in (equal ones keep their order).
fn sorted(mut edits: Vec<Edit>) -> Vec<Edit> {
    edits.sort_by_key(edit_key);
    edits
}

/// The source text an [`EditWriter`] copies: in memory, or its file read as it is copied.
enum Src<'s> {
    Text(&'s str),
    File(Copier<'s>),
}

/// A source text being copied to a writer with non-overlapping edits applied, given in order.
struct EditWriter<'s, 'o> {
    src: Src<'s>,
    /// How far the source has been copied.
    pos: usize,
    out: &'o mut dyn Write,
}

impl<'s, 'o> EditWriter<'s, 'o> {
    fn new(src: Src<'s>, out: &'o mut dyn Write) -> Self {
        EditWriter { src, pos: 0, out }
    }

    /// Copy the source up to `e`, then `e`'s text in place of its range.
    fn apply(&mut self, e: Edit) -> Result<()> {
        if e.range.start < self.pos {
            return Err(bad(
                "internal error: overlapping edits of the SVG text (please report this file)",
            ));
        }
        self.put(self.pos..e.range.start)?;
        self.write(&e.text)?;
        if let Src::File(file) = &mut self.src {
            file.copy_to(e.range.end as u64, None)?;
        }
        self.pos = e.range.end;
        Ok(())
    }

    /// Copy the rest of the source.
    fn finish(mut self) -> Result<()> {
        match self.src {
            Src::Text(text) => {
                let rest = self.pos..text.len();
                self.put(rest)?;
            }
            Src::File(file) => file.finish(self.out)?,
        }
        self.out.flush().map_err(write_error)
    }

    fn put(&mut self, range: Range<usize>) -> Result<()> {
        match &mut self.src {
            Src::Text(src) => {
                let text = src.get(range).ok_or_else(|| {
                    bad("internal error: an edit of the SVG text splits a character (please report this file)")
                })?;
                self.out.write_all(text.as_bytes()).map_err(write_error)
            }
            Src::File(file) => file.copy_to(range.end as u64, Some(&mut *self.out)),
        }
    }

    fn write(&mut self, text: &str) -> Result<()> {
        self.out.write_all(text.as_bytes()).map_err(write_error)
    }
}

/// An error writing the output; the caller names the output.
fn write_error(source: std::io::Error) -> PlanError {
    PlanError::Write {
        path: std::path::PathBuf::new(),
        source,
    }
}

/// Apply non-overlapping edits.
fn apply_edits(src: &str, edits: Vec<Edit>) -> Result<String> {
    // The exact size: the tagged copy of a large plan is held while usvg parses it, at the peak.
    let grown: usize = edits.iter().map(|e| e.text.len()).sum();
    let cut: usize = edits.iter().map(|e| e.range.len()).sum();
    let mut out = Vec::with_capacity((src.len() + grown).saturating_sub(cut));
    let mut writer = EditWriter::new(Src::Text(src), &mut out);
    for e in sorted(edits) {
        writer.apply(e)?;
    }
    writer.finish()?;
    String::from_utf8(out)
        .map_err(|_| bad("internal error: the edited SVG is not UTF-8 (please report this file)"))
}

/// The element a `<use>` refers to.
fn use_target<'a, 'i>(u: Node<'a, 'i>, ids: &HashMap<&str, Node<'a, 'i>>) -> Option<Node<'a, 'i>> {
    let href = u
        .attribute("href")
        .or_else(|| u.attribute((XLINK_NS, "href")))?;
    ids.get(href.strip_prefix('#')?).copied()
}

/// `path "id"` or `<rect> at line 12, column 5`.
fn describe(lines: &LineIndex, n: Node) -> String {
    match n.attribute("id") {
        Some(id) => format!("{} \"{id}\"", n.tag_name().name()),
        None => {
            let text = n.document().input_text();
            let (line, column) = lines.line_column(text, n.range().start);
            format!("<{}> at line {line}, column {column}", n.tag_name().name())
        }
    }
}

/// Line and column numbers of byte offsets in a text, each found by a binary search over the
/// lines' starts. (roxmltree's `Document::text_pos_at` counts from the start of the document
/// every time, which made naming every element of a large file quadratic in its size.)
struct LineIndex {
    /// Byte offset of the start of each line.
    starts: Vec<usize>,
}

impl LineIndex {
    fn new(text: &str) -> Self {
        let breaks = text.bytes().enumerate().filter(|&(_, b)| b == b'\n');
        let starts = std::iter::once(0)
            .chain(breaks.map(|(i, _)| i + 1))
            .collect();
        LineIndex { starts }
    }

    /// The line and column (both from 1; the column counts characters, as XML tools do) of the
    /// byte at `offset` of `text` (the text indexed).
    fn line_column(&self, text: &str, offset: usize) -> (usize, usize) {
        let offset = offset.min(text.len());
        let line = self.starts.partition_point(|&s| s <= offset);
        let start = self.starts[line - 1];
        let column = text.get(start..offset).map_or(0, |s| s.chars().count()) + 1;
        (line, column)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEAD: &str = r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="100mm" height="100mm" viewBox="0 0 100 100">"#;

    fn run(body: &str, kerf_um: f64) -> Result<(String, PlanSummary)> {
        dilate_svg(
            &format!("{HEAD}{body}</svg>"),
            &KerfSource::Uniform(kerf_um),
            &SvgOptions::default(),
        )
    }

    #[test]
    fn under_a_prefixed_root_unprefixed_cuts_are_read_as_usvg_draws_them() {
        // Unprefixed elements under `<s:svg xmlns:s=…>` have no namespace; usvg draws them as
        // SVG, so they are cuts like the prefixed ones (not left untagged, and so taken for
        // another element).
        let doc = format!(
            r#"<s:svg xmlns:s="{SVG_NS}" width="100mm" height="100mm" viewBox="0 0 100 100"><s:rect x="1" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><s:rect x="11" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><s:rect x="21" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><s:rect x="31" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><rect id="plain" x="41" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/></s:svg>"#
        );
        let (out, summary) =
            dilate_svg(&doc, &KerfSource::Uniform(200.0), &SvgOptions::default()).expect("dilated");
        assert_eq!(summary.contours_dilated, 5, "{summary:?}");
        assert!(
            out.contains(
                r#"<path id="plain" fill="none" stroke="red" stroke-width="0.1" d="M41 0.9 "#
            ),
            "{out}"
        );
        assert_eq!(out.matches("<s:path").count(), 4, "{out}");
    }

    #[test]
    fn a_rect_becomes_a_dilated_path_with_its_attributes() {
        let (out, s) = run(
            r#"<rect id="r" class="c" x="10" y="10" width="20" height="10" fill="none" stroke="red" stroke-width="0.01"/>"#,
            200.0,
        )
        .unwrap();
        assert_eq!(s.contours_dilated, 1);
        assert!(
            out.contains(
                r#"<path id="r" class="c" fill="none" stroke="red" stroke-width="0.01" d="M"#
            ),
            "{out}"
        );
        assert!(!out.contains("width=\"20\""));
        // Corners are quarter arcs of radius 0.1 mm.
        assert!(out.contains("A0.1 0.1 0 0 "), "{out}");
    }

    #[test]
    fn non_cuts_and_the_rest_of_the_file_are_untouched() {
        let body = r##"<!-- comment --><text x="1" y="5" fill="black">Label</text><path id="g" d="M 0 0 L 5 5" stroke="#00ff00" fill="none"/>"##;
        let cut = r#"<rect id="c" x="10" y="10" width="5" height="5" stroke="red" stroke-width="0.1" fill="none"/>"#;
        let src = format!("{HEAD}{body}{cut}</svg>");
        let (out, s) =
            dilate_svg(&src, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap();
        // All but the record of what was applied, right after the root's start tag, and the cut.
        let record = s.compensation_applied.as_ref().unwrap().svg_record();
        assert!(out.starts_with(&format!("{HEAD}{record}{body}")), "{out}");
        assert!(out.ends_with("</svg>") && !out.contains(cut), "{out}");
        assert_eq!(s.contours_dilated, 1);
        assert_eq!(s.passed_through.get("text"), Some(&1));
    }

    #[test]
    fn path_data_that_breaks_off_is_refused_in_a_cut_and_noted_elsewhere() {
        const CUT: &str = r#"<rect id="c" x="10" y="10" width="5" height="5" stroke="red" stroke-width="0.1" fill="none"/>"#;
        // A cut: usvg would read the first square only; its dilation would lose the second.
        let broken = r#"<path id="b" d="M40 40 H60 V60 H40 Z M70 70 L NaN 80 H90 Z" stroke="red" stroke-width="0.1" fill="none"/>"#;
        let e = run(&format!("{CUT}{broken}"), 150.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the cut path \"b\" has an error in its path data"),
            "{e}"
        );
        // An engraving (green): passed through as it is, with a note.
        let green = broken.replace("red", "#00ff00");
        let (out, s) = run(&format!("{CUT}{green}"), 150.0).unwrap();
        assert!(out.contains(&green), "{out}");
        assert!(
            s.notes
                .iter()
                .any(|n| n.contains("1 path(s) not read as cuts") && n.contains("path \"b\"")),
            "{:?}",
            s.notes
        );
    }

    #[test]
    fn a_cut_polygon_whose_points_break_off_is_refused() {
        let polygon = r#"<polygon id="p" points="10,10 30,10 30,30 10" stroke="red" stroke-width="0.1" fill="none"/>"#;
        let e = run(polygon, 150.0).unwrap_err().to_string();
        assert!(
            e.contains("the cut polygon \"p\" has an error in its points"),
            "{e}"
        );
    }

    #[test]
    fn a_coordinate_single_precision_cannot_hold_is_refused_by_name() {
        // usvg drops such a path whole: the plan would have said "nothing drawn".
        let far = r#"<path d="M10 10 H30 V30 H10 Z M70 70 L80 70 L1e39 80 Z" stroke="red" stroke-width="0.1" fill="none"/>"#;
        let e = run(far, 150.0).unwrap_err().to_string();
        assert!(e.contains("<path> at line 1, column"), "{e}");
        assert!(e.contains("the number 1e39 in its path data"), "{e}");
    }

    #[test]
    fn a_plan_without_a_closed_cut_is_refused_and_says_what_was_found() {
        // Only non-cuts (a label, a green line, a red square drawn 1 mm wide: wider than the
        // rules' 0.3 mm) and an open red line: nothing to dilate, and no output that records
        // a compensation it did not apply.
        let body = r##"<text x="1" y="5" fill="black">Label</text><path d="M 0 0 L 5 5" stroke="#00ff00" fill="none"/><rect x="10" y="10" width="5" height="5" stroke="red" stroke-width="1" fill="none"/><path id="open" d="M 20 20 L 30 30" stroke="red" stroke-width="0.1" fill="none"/>"##;
        let src = format!("{HEAD}{body}</svg>");
        let e = dilate_svg(&src, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap_err();
        assert!(matches!(e, PlanError::NoCuts(_)), "{e:?}");
        let e = e.to_string();
        for said in [
            "no closed cut contour",
            "1 text",
            "1 open cut path",
            "up to 0.3 mm wide",
            "--cut-max-width-mm",
        ] {
            assert!(e.contains(said), "{said:?} in {e}");
        }
    }

    #[test]
    fn the_report_gives_the_root_user_unit() {
        let rect = r##"<rect x="10" y="10" width="20" height="20" fill="none" stroke="#FF0000" stroke-width="0.1"/>"##;
        for (root, unit_mm) in [
            (r#"width="100mm" height="60mm" viewBox="0 0 100 60""#, 1.0),
            (r#"width="100mm" height="60mm" viewBox="0 0 1000 600""#, 0.1),
            (r#"width="10cm" height="6cm" viewBox="0 0 100 60""#, 1.0),
            (r#"width="100mm" height="60mm""#, 25.4 / 96.0),
        ] {
            let svg = format!(r#"<svg xmlns="http://www.w3.org/2000/svg" {root}>{rect}</svg>"#);
            let (_, s) =
                dilate_svg(&svg, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap();
            assert!(
                (s.mm_per_unit - unit_mm).abs() < 1e-9,
                "{root}: {}",
                s.mm_per_unit
            );
        }
    }

    #[test]
    fn unitless_documents_need_assumed_units() {
        let src = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100"><rect x="1" y="1" width="5" height="5" stroke="red" stroke-width="0.1" fill="none"/></svg>"#;
        let e = dilate_svg(src, &KerfSource::Uniform(100.0), &SvgOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown units"), "{e}");
        let opts = SvgOptions {
            assume_units: Some(AssumedUnits::Mm),
            ..SvgOptions::default()
        };
        assert!(dilate_svg(src, &KerfSource::Uniform(100.0), &opts).is_ok());
    }

    #[test]
    fn one_path_with_an_outline_and_a_hole_dilates_both_ways() {
        let (out, s) = run(
            r##"<path id="p" d="M 10 10 H 40 V 40 H 10 Z M 20 20 H 30 V 30 H 20 Z" fill="none" stroke="#000" stroke-width="0.1"/>"##,
            200.0,
        )
        .unwrap();
        assert_eq!((s.contours_dilated, s.parts, s.holes), (2, 1, 1));
        // The hole shrinks to 9.8 × 9.8 with sharp corners.
        assert!(
            out.contains("M20.1 20.1 L29.9 20.1 L29.9 29.9 L20.1 29.9 Z"),
            "{out}"
        );
    }

    #[test]
    fn polygons_and_clones_of_groups_are_dilated() {
        let (out, s) = run(
            r##"<defs><g id="t"><polygon id="tri" points="0,0 10,0 5,8" fill="none" stroke="red" stroke-width="0.05"/></g></defs>
<use id="u" href="#t" x="20" y="20"/>"##,
            100.0,
        )
        .unwrap();
        assert_eq!(s.contours_dilated, 1);
        assert!(
            out.contains(r#"<g id="t-kerf1"><path id="tri-kerf1" fill="none""#),
            "{out}"
        );
        assert!(out.contains(r##"href="#t-kerf1""##), "{out}");
        // The original template is untouched.
        assert!(out.contains(r#"<polygon id="tri" points="0,0 10,0 5,8""#));
    }

    #[test]
    fn cuts_reached_through_nested_clones_are_refused() {
        let e = run(
            r##"<defs><rect id="r" width="5" height="5" fill="none" stroke="red" stroke-width="0.05"/><g id="g"><use href="#r"/></g></defs>
<use id="outer" href="#g" x="10" y="10"/>"##,
            100.0,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("nested <use>"), "{e}");
    }

    #[test]
    fn numbers_are_written_as_exact_float_formatting_would() {
        let exact = |v: f64, digits: usize| {
            let s = format!("{v:.digits$}");
            let s = if s.contains('.') {
                s.trim_end_matches('0').trim_end_matches('.').to_string()
            } else {
                s
            };
            if s == "-0" { "0".to_string() } else { s }
        };
        let values = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            20.1,
            29.9,
            0.1,
            -0.000_004,
            1_234.567_891_23,
            -987.654_321,
            1e-5,
            3.000_01,
            12.5,
            100.0,
            2_550.075_000_1,
        ];
        for v in values {
            for digits in [0, 1, 3, 5, 6] {
                let mut out = String::new();
                num(v, digits, &mut out);
                assert_eq!(out, exact(v, digits), "{v} with {digits} digits");
            }
        }
    }

    #[test]
    fn the_source_is_made_again_from_its_tagged_copy() {
        let src = "<svg>\n  <path d=\"M0 0\"/><use href=\"#a\"/>é<rect/></svg>";
        let at = |needle: &str| src.find(needle).unwrap();
        let insert = |at: usize, text: &str| Edit {
            range: at..at,
            text: text.into(),
        };
        // Given out of order, two at one place.
        let edits = vec![
            insert(at("<rect") + 5, " style=\"b\""),
            insert(at("<path") + 5, " style=\"a\""),
            insert(at("<use") + 4, " id=\"u\""),
            insert(at("<use") + 4, " x=\"1\""),
        ];
        let tagged = Tagged::new(src, edits).unwrap();
        assert_eq!(
            tagged.text,
            "<svg>\n  <path style=\"a\" d=\"M0 0\"/><use id=\"u\" x=\"1\" href=\"#a\"/>é<rect style=\"b\"/></svg>"
        );
        assert_eq!(tagged.untagged(), src);
    }

    /// No image is loaded: an `href` may name any file or device (`/dev/zero`, a FIFO).
    #[test]
    fn images_are_passed_through_and_never_loaded() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("a.png");
        std::fs::write(&png, b"\x89PNG\r\n\x1a\n not really a picture").unwrap();
        let href = png.to_str().unwrap();
        let options = usvg_options();
        assert!((options.image_href_resolver.resolve_string)(href, &options).is_none());
        let defaults = usvg::Options::default();
        assert!(
            (defaults.image_href_resolver.resolve_string)(href, &defaults).is_some(),
            "usvg's own resolver reads the file"
        );
        let body = format!(
            r#"<image href="{href}" width="10" height="10"/>
<rect x="0" y="0" width="10" height="10" fill="none" stroke="red" stroke-width="0.1"/>"#
        );
        let (_, summary) = run(&body, 150.0).unwrap();
        assert_eq!(summary.passed_through.get("image"), Some(&1));
        assert_eq!(summary.contours_dilated, 1);
    }

    /// 250 KB that roxmltree would have grown to 5 GB (one large entity used many times).
    #[test]
    fn entities_that_would_grow_the_file_many_times_over_are_refused_unparsed() {
        let svg = format!(
            "<!DOCTYPE svg [<!ENTITY big \"{}\">]><svg xmlns=\"{SVG_NS}\"><desc>{}</desc></svg>",
            "x".repeat(100_000),
            "&big;".repeat(50_000)
        );
        let error = dilate_svg(&svg, &KerfSource::Uniform(150.0), &SvgOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            error.contains("entities of its document type declaration would add 5000 MB"),
            "{error}"
        );
    }

    #[test]
    fn a_view_box_that_draws_nothing_or_maps_absurdly_is_refused() {
        for view_box in [
            "0 0 0 0",
            "0 0 1e-300 1e-300",
            "0 0 1e300 1e300",
            "0 0 -5 5",
            "a b c d",
        ] {
            let svg = format!(
                r#"<svg xmlns="{SVG_NS}" width="100mm" height="100mm" viewBox="{view_box}"><rect width="10" height="10" fill="none" stroke="red" stroke-width="0.1"/></svg>"#
            );
            let error = dilate_svg(&svg, &KerfSource::Uniform(150.0), &SvgOptions::default())
                .unwrap_err()
                .to_string();
            assert!(error.contains("not a usable box"), "{view_box}: {error}");
        }
    }

    #[test]
    fn broken_xml_is_a_clear_error() {
        let e = dilate_svg(
            "<svg><path",
            &KerfSource::Uniform(100.0),
            &SvgOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("not a readable SVG"), "{e}");
    }
}
