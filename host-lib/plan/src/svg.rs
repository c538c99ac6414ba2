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
//!   element, see [`compensation`](crate::compensation)), replacing an earlier record of this
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
//!
//! **Modules**, one concern each: `reading` parses the source and has usvg draw it, with `checks`
//! (what is refused before usvg reads it), `units`, `tagging` (the copy usvg draws, each element
//! tagged) and `walk` (usvg's tree back to the elements); `plan` is the document in the plan
//! pipeline, with `elements` (found and named) and `trace` (into document mm); `writing` makes the
//! dilated document, with `edits` (of the source text) and `path_writer` (the new path data);
//! `exact`, `lost` and `path_data` keep what single precision would lose; `tests`.

use std::io::Write;

use super::compensation::IfCompensated;
use super::dilate::KerfSource;
use super::geom::{Affine, V2, v2};
use super::outcome::{AssumedUnits, CutPath, PlanSummary};
use super::pipeline;
use super::progress::{Progress, Stage};
use super::rules::{CutRules, Rgb};
use super::source_file::SourceFile;
use crate::error::{PlanError, Result};

mod checks;
mod edits;
mod elements;
mod exact;
mod lost;
mod path_data;
mod path_writer;
mod plan;
mod reading;
mod tagging;
mod trace;
mod units;
mod walk;
mod writing;

#[cfg(test)]
mod tests;

use edits::Slot;
use exact::Exactness;
use plan::SvgPlan;
use reading::render;

pub(crate) use path_writer::write_pline;

const SVG_NS: &str = "http://www.w3.org/2000/svg";
const XLINK_NS: &str = "http://www.w3.org/1999/xlink";
const SODIPODI_NS: &str = "http://sodipodi.sourceforge.net/DTD/sodipodi-0.dtd";
const INKSCAPE_NS: &str = "http://www.inkscape.org/namespaces/inkscape";

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
