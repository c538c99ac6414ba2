//! DXF plans: read with the `dxf` crate, dilate the cuts, write the drawing back.
//!
//! **Units** come from `$INSUNITS` (mm, cm, m, inches, feet, µm, …). A drawing with `$INSUNITS` 0
//! ("unitless", also every R12 file) is refused as *unknown units* unless the caller says what one
//! unit is ([`AssumedUnits`], `--units`). Document space is the drawing's own frame (y up), in mm;
//! a kerf map is looked up at those coordinates.
//!
//! **Cut geometry** (model space, and blocks through `INSERT`; which entities are cuts:
//! [`super::rules`]):
//!
//! * `LWPOLYLINE` and 2-D `POLYLINE` with bulges (closed by flag, or by ending where they start),
//! * `CIRCLE`, `ARC`, `LINE`, and `ELLIPSE` (full or partial; a circular one exactly, others by
//!   biarcs),
//! * `SPLINE` by its control points, weights and knots (rational or not, any degree up to 25; see
//!   the crate-private `nurbs` module), turned into biarcs within
//!   [`CURVE_TOLERANCE_MM`] (0.05 µm) of the curve at the points checked; a
//!   spline given by fit points alone is refused (convert it to a polyline),
//! * open pieces (`LINE`, `ARC`, open polylines and splines) whose ends meet within 0.1 µm are
//!   joined into closed chains, in either direction,
//! * block references (`INSERT`, and `MINSERT` arrays): the cuts inside the block, read through
//!   the insertion's scale, rotation, mirror and position, nested blocks too (the crate-private
//!   `blocks` submodule).
//!   A block scaled unequally in x and y turns its arcs into elliptical arcs, which become biarcs.
//!
//! Entities drawn with a mirrored extrusion direction (0, 0, −1), as some CAD programs write
//! mirrored arcs, are handled; other non-planar entities are refused, as are points more than
//! 10 km from the origin (a unit mistake or a damaged file), a block that inserts itself, blocks
//! nested more than 16 deep and more than 100,000 block instances. Every refusal names the entity by type, handle and layer (and
//! the block and `INSERT` it is reached through) and says what to do.
//!
//! **Writing.** A closed `LWPOLYLINE` gets its new vertices in place (handle, layer, colour,
//! extended data kept); a `CIRCLE` stays a `CIRCLE` with the new radius; a chain of pieces (and an
//! old-style `POLYLINE`, an `ELLIPSE` or a `SPLINE`) is replaced by one closed `LWPOLYLINE` with
//! bulges that takes over the first piece's layer, colour, linetype and lineweight. Everything
//! else is written back as read: an ASCII file's bytes are copied and only the changed entities
//! are spliced in, found by their handles (the crate-private `splice` submodule), so comments,
//! entities and objects the `dxf` crate does not model and the file's own number formatting come
//! out byte for byte, and writing a large plan costs little more than formatting its new
//! vertices (on the 10,000-contour benchmark plan the `dxf` crate's save took 0.94–1.2 s and most
//! of the peak memory; the splice 0.09–0.12 s, its formatting spread over the cores). Where
//! that cannot be done the changed drawing is written whole by the `dxf` crate: a binary DXF; a
//! drawing older than R2000 (no `LWPOLYLINE` before R14), which is written as R2000; assumed
//! units (`--units`), written into its header; a cut inside a block, which becomes a new
//! model-space `LWPOLYLINE` while its `INSERT` shows a copy of the block without the cuts; a
//! drawing with an entity that has no usable handle; an entity to change whose handle is shared.
//! What was applied is recorded in `999` comments at the top of the file (see
//! [`compensation`]).

use std::cell::Cell;
use std::collections::{HashMap, HashSet};

use cavalier_contours::polyline::{PlineCreation, PlineSource, PlineSourceMut, PlineVertex};
use dxf::entities::{Entity, EntityCommon, EntityType, LwPolyline};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, LwPolylineVertex, Point, Vector};

use super::compensation::{self, FoundCompensation, IfCompensated};
use super::decimal::{decimals_for_step, pow10};
use super::dilate::KerfSource;
use super::geom::{Affine, CURVE_TOLERANCE_MM, PathSink, Pline, V2, arc_geom, fit_biarcs, v2};
use super::nurbs::Nurbs;
use super::outcome::{AssumedUnits, CutGroup, CutPath, PlanSummary};
use super::pipeline::{self, Format, MAX_CUT_VERTICES, Plan};
use super::progress::{Progress, Stage};
use super::rules::{CutRules, Rgb, Verdict};
use crate::error::{PlanError, Problems, Result};

mod blocks;
mod splice;
mod values;

use splice::{Change, Layout, Precision, Splice};

/// Ends closer than this join (mm).
const JOIN_MM: f64 = 1e-4;

/// How to read a DXF plan.
#[derive(Debug, Clone, Default)]
pub struct DxfOptions {
    /// Which entities are cuts.
    pub rules: CutRules,
    /// What one drawing unit is when `$INSUNITS` does not say.
    pub assume_units: Option<AssumedUnits>,
    /// What to do when the drawing is already compensated.
    pub if_compensated: IfCompensated,
    /// Where to tell how far the work has got.
    pub progress: Progress,
}

fn bad(message: impl Into<String>) -> PlanError {
    PlanError::Dxf(message.into())
}

/// What a closed contour came from, and how to write it back.
#[derive(Debug, Clone)]
enum Origin {
    /// One closed `LWPOLYLINE`, edited in place.
    LwPolyline(usize),
    /// One `CIRCLE`, edited in place.
    Circle(usize),
    /// Replaced by a new `LWPOLYLINE` (chains, `POLYLINE`, `ELLIPSE`, `SPLINE`).
    Replace(Vec<usize>),
    /// Drawn inside a block: a new model-space `LWPOLYLINE` with these properties.
    Added(Box<EntityCommon>),
}

/// An open piece of a cut: vertices in mm (the last one's bulge unused), its entity.
#[derive(Debug, Clone)]
struct Piece {
    vertices: Vec<PlineVertex<f64>>,
    entities: Vec<usize>,
}

impl Piece {
    fn start(&self) -> V2 {
        let v = self.vertices[0];
        v2(v.x, v.y)
    }

    fn end(&self) -> V2 {
        let v = self.vertices[self.vertices.len() - 1];
        v2(v.x, v.y)
    }

    fn reversed(mut self) -> Piece {
        let n = self.vertices.len();
        let bulges: Vec<f64> = self.vertices.iter().map(|v| v.bulge).collect();
        self.vertices.reverse();
        for i in 0..n {
            // The segment now leaving vertex i was the one leaving vertex n−2−i, reversed.
            self.vertices[i].bulge = if i + 1 < n { -bulges[n - 2 - i] } else { 0.0 };
        }
        self
    }

    fn append(&mut self, other: Piece) {
        let mut it = other.vertices.into_iter();
        let first = it.next().expect("a piece has vertices");
        if let Some(last) = self.vertices.last_mut() {
            last.bulge = first.bulge;
        }
        self.vertices.extend(it);
        self.entities.extend(other.entities);
    }
}

/// Dilate the cuts of a DXF plan (file bytes, ASCII or binary DXF). Returns the new file.
pub fn dilate_dxf(
    bytes: &[u8],
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    // Where the entities are in the file (for the splice) is found on another core while the
    // `dxf` crate parses it (wasted, a small part of the parse's time, on a file that is written
    // whole or fails to load).
    let (loaded, layout) = rayon::join(|| load(bytes, &opts.progress), || Layout::scan(bytes));
    let (drawing, found) = loaded?;
    let (changes, summary) = dilate_loaded(drawing, kerf, opts, found)?;
    Ok((save(changes, &summary, bytes, layout)?, summary))
}

/// [`dilate_dxf`] on bytes it owns (the file read by the command).
pub(crate) fn dilate_dxf_owned(
    bytes: Vec<u8>,
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    dilate_dxf(&bytes, kerf, opts)
}

/// Load a DXF file's drawing, and the compensation its comments record (the loaded drawing
/// has lost them).
fn load(bytes: &[u8], progress: &Progress) -> Result<(Drawing, Option<FoundCompensation>)> {
    let found = compensation::find_in_dxf(bytes);
    progress.start(Stage::Reading, 0);
    let drawing = values::load(bytes).map_err(bad)?;
    Ok((drawing, found))
}

/// The dilated drawing's file: the record of what was applied first, as `999` comments (the
/// `dxf` crate writes none), then the input's bytes with the changed entities spliced in (see the
/// `splice` submodule; `layout` is the input's); or, where that cannot be done, the changed
/// drawing written whole by the `dxf` crate.
fn save(
    changes: Changes,
    summary: &PlanSummary,
    input: &[u8],
    layout: Option<Layout>,
) -> Result<Vec<u8>> {
    let record = |eol: &str| {
        summary
            .compensation_applied
            .as_ref()
            .map(|applied| applied.dxf_record(eol))
    };
    if let Some(out) = changes.splice(input, layout, record("\n").as_deref()) {
        return Ok(out);
    }
    let drawing = changes.apply();
    let mut out = Vec::with_capacity(input.len() + input.len() / 2);
    // The `dxf` crate ends every line of an ASCII file with CR LF.
    if let Some(record) = record("\r\n") {
        out.extend_from_slice(record.as_bytes());
    }
    drawing
        .save(&mut out)
        .map_err(|e| bad(format!("cannot write the DXF: {e}")))?;
    Ok(out)
}

/// mm per drawing unit, when `$INSUNITS` says.
fn units_known(drawing: &Drawing) -> Option<f64> {
    match drawing.header.default_drawing_units {
        Units::Millimeters => Some(1.0),
        Units::Centimeters => Some(10.0),
        Units::Decimeters => Some(100.0),
        Units::Meters => Some(1000.0),
        Units::Inches => Some(25.4),
        Units::Feet => Some(304.8),
        Units::Mils => Some(0.0254),
        Units::Microinches => Some(25.4e-6),
        Units::Microns => Some(1e-3),
        _ => None,
    }
}

/// mm per drawing unit.
fn units_mm(
    drawing: &Drawing,
    assume: Option<AssumedUnits>,
    summary: &mut PlanSummary,
) -> Result<f64> {
    let known = units_known(drawing);
    match (known, assume) {
        (Some(mm), Some(_)) => {
            summary
                .notes
                .push("--units ignored: the drawing says its units ($INSUNITS)".into());
            Ok(mm)
        }
        (Some(mm), None) => Ok(mm),
        (None, Some(u)) => {
            summary.notes.push(format!(
                "the drawing does not say its units; one unit taken as {} ({} mm) as asked",
                u.name(),
                u.mm()
            ));
            Ok(u.mm())
        }
        (None, None) => {
            // The dxf crate reads a code it does not know as unitless too.
            let said = match drawing.header.default_drawing_units {
                Units::Unitless => "unset, 0 (unitless) or a code that names no unit".to_owned(),
                other => format!("{other:?}"),
            };
            Err(PlanError::Units(format!(
                "unknown units: $INSUNITS is {said} (R12 files and many exports leave it unset); save the drawing in mm, or say what one unit is with --units mm|cm|in"
            )))
        }
    }
}

/// Whether an OCS normal is +z (false), −z (true, mirrored in x), or neither (None).
fn mirrored(n: &Vector) -> Option<bool> {
    if n.x.abs() > 1e-9 || n.y.abs() > 1e-9 {
        return None;
    }
    if n.z > 0.0 {
        Some(false)
    } else if n.z < 0.0 {
        Some(true)
    } else {
        None
    }
}

fn type_name(e: &EntityType) -> String {
    let name = match e {
        EntityType::LwPolyline(_) => "LWPOLYLINE",
        EntityType::Polyline(_) => "POLYLINE",
        EntityType::Line(_) => "LINE",
        EntityType::Arc(_) => "ARC",
        EntityType::Circle(_) => "CIRCLE",
        EntityType::Ellipse(_) => "ELLIPSE",
        EntityType::Spline(_) => "SPLINE",
        EntityType::Text(_) => "TEXT",
        EntityType::MText(_) => "MTEXT",
        EntityType::Insert(_) => "INSERT",
        EntityType::ModelPoint(_) => "POINT",
        EntityType::Image(_) => "IMAGE",
        other => {
            // The variant's name, from its debug form.
            let dbg = format!("{other:?}");
            return dbg
                .split(['(', ' ', '{'])
                .next()
                .unwrap_or("entity")
                .to_uppercase();
        }
    };
    name.into()
}

fn label(e: &Entity) -> String {
    format!(
        "{} {:X} on layer {}",
        type_name(&e.specific),
        e.common.handle.0,
        e.common.layer
    )
}

/// Dilate the cuts of a loaded drawing. (A loaded drawing has lost its comments, so a
/// compensation recorded in them is not seen: [`dilate_dxf`] reads them from the file.)
pub fn dilate_drawing(
    drawing: Drawing,
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Drawing, PlanSummary)> {
    let (changes, summary) = dilate_loaded(drawing, kerf, opts, None)?;
    Ok((changes.apply(), summary))
}

/// Dilate a loaded drawing whose file recorded the compensation `found`.
fn dilate_loaded(
    drawing: Drawing,
    kerf: &KerfSource,
    opts: &DxfOptions,
    found: Option<FoundCompensation>,
) -> Result<(Changes, PlanSummary)> {
    pipeline::dilate_plan(
        DxfPlan::new(drawing, opts, found)?,
        kerf,
        opts.if_compensated,
        &opts.rules,
        &opts.progress,
    )
}

/// Dilate the cuts of a DXF plan and give them back as contours in mm (the drawing's frame, y
/// up), each with its colour and layer: what G-code is made from.
pub(crate) fn dilate_dxf_cuts(
    bytes: &[u8],
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Vec<CutPath>, PlanSummary)> {
    let (drawing, found) = load(bytes, &opts.progress)?;
    let plan = DxfPlan::new(drawing, opts, found)?;
    pipeline::dilate_plan_cuts(plan, kerf, opts.if_compensated, &opts.rules, &opts.progress)
}

/// A DXF drawing in the plan pipeline.
struct DxfPlan<'o> {
    drawing: Drawing,
    opts: &'o DxfOptions,
    /// The cut rules, their `--cut-layer` values resolved against this drawing's layers.
    rules: CutRules,
    /// mm per drawing unit (set by `read`).
    scale: f64,
    /// The compensation the file records (read from its comments before loading).
    found: Option<FoundCompensation>,
    /// Model-space `INSERT`s (by entity index) to point at the copy of their block without its
    /// cuts (set by `read`, see the `blocks` submodule).
    retargets: Vec<(usize, String)>,
    /// Those copies, to add to the drawing (set by `read`).
    rest_blocks: Vec<dxf::Block>,
    /// The units assumed for a drawing that did not say, to write into it (set by `read`).
    assumed: Option<Units>,
    /// Vertices the cut entities read so far came to (curves flattened, blocks expanded), against
    /// [`MAX_CUT_VERTICES`].
    vertices_read: Cell<usize>,
}

impl<'o> DxfPlan<'o> {
    /// The plan of a loaded `drawing` whose file recorded the compensation `found`: a
    /// `--cut-layer` value is a layer's whole name if the drawing has such a layer (in its table
    /// or on an entity), else a comma-separated list of names.
    fn new(
        drawing: Drawing,
        opts: &'o DxfOptions,
        found: Option<FoundCompensation>,
    ) -> Result<Self> {
        let rules = if opts.rules.layers.is_empty() {
            opts.rules.clone()
        } else {
            let mut names: HashSet<String> =
                drawing.layers().map(|l| l.name.to_uppercase()).collect();
            names.extend(drawing.entities().map(|e| e.common.layer.to_uppercase()));
            opts.rules
                .for_layers(|n| names.contains(&n.to_uppercase()))?
        };
        Ok(DxfPlan {
            drawing,
            opts,
            rules,
            scale: 1.0,
            found,
            retargets: Vec::new(),
            rest_blocks: Vec::new(),
            assumed: None,
            vertices_read: Cell::new(0),
        })
    }
}

/// What reading one cut entity gives.
enum Read {
    /// A closed contour.
    Closed(Pline, Origin),
    /// An open piece, to be joined with others.
    Piece(Piece),
    /// Nothing (a degenerate entity).
    Nothing,
}

impl Read {
    /// How many vertices it holds.
    fn vertex_count(&self) -> usize {
        match self {
            Read::Closed(pl, _) => pl.vertex_count(),
            Read::Piece(p) => p.vertices.len(),
            Read::Nothing => 0,
        }
    }

    /// Whether the read geometry is usable: finite coordinates within [`MAX_COORDINATE_MM`] of
    /// the origin, and arcs of finite bulge no larger than that in radius.
    fn is_usable(&self) -> bool {
        let (vertices, closed): (Vec<PlineVertex<f64>>, bool) = match self {
            Read::Closed(pl, _) => (pl.iter_vertexes().collect(), true),
            Read::Piece(p) => (p.vertices.clone(), false),
            Read::Nothing => return true,
        };
        let n = vertices.len();
        let near =
            |v: &PlineVertex<f64>| v.x.abs() <= MAX_COORDINATE_MM && v.y.abs() <= MAX_COORDINATE_MM;
        vertices.iter().enumerate().all(|(k, v)| {
            let next = if k + 1 < n || closed {
                Some(vertices[(k + 1) % n])
            } else {
                None
            };
            let arc = next.and_then(|w| arc_geom(v2(v.x, v.y), v2(w.x, w.y), v.bulge));
            near(v) && v.bulge.is_finite() && arc.is_none_or(|g| g.radius <= MAX_COORDINATE_MM)
        })
    }
}

/// Where a cut entity sits: in model space (index into its entities; edited in place there),
/// or inside a block reached through an `INSERT` (written as a new model-space `LWPOLYLINE`
/// styled by the given properties, the block's own `0`-layer and `BYBLOCK` ones resolved).
#[derive(Clone, Copy)]
enum Place<'t> {
    Model(usize),
    Block(&'t EntityCommon),
}

impl Place<'_> {
    /// The origin of a closed contour read here: `in_model` of the index in model space.
    fn origin(&self, in_model: impl FnOnce(usize) -> Origin) -> Origin {
        match self {
            Place::Model(i) => in_model(*i),
            Place::Block(common) => Origin::Added(Box::new((*common).clone())),
        }
    }
}

impl Format for DxfPlan<'_> {
    type Origin = Origin;
    type Output = Changes;

    fn read(&mut self) -> Result<Plan<Origin>> {
        let mut plan = Plan::new("dxf");
        self.scale = units_mm(&self.drawing, self.opts.assume_units, &mut plan.summary)?;
        plan.summary.mm_per_unit = self.scale;
        plan.summary.compensation_found = self.found.take();
        if units_known(&self.drawing).is_none() {
            self.assumed = self.opts.assume_units.and_then(|u| match u {
                AssumedUnits::Mm => Some(Units::Millimeters),
                AssumedUnits::Cm => Some(Units::Centimeters),
                AssumedUnits::In => Some(Units::Inches),
                _ => None,
            });
        }
        let mut blocks = blocks::Expansion::new(&self.drawing);
        let entities: Vec<&Entity> = self.drawing.entities().collect();
        let pieces = self.read_entities(&entities, &mut blocks, &mut plan)?;
        let name_of = |k: usize| label(entities[k]);
        let origin_of = |list: &[usize]| Origin::Replace(list.to_vec());
        close_chains(pieces, &name_of, &origin_of, &mut plan);
        let (retargets, rest_blocks) = blocks.finish(&mut plan.summary);
        self.retargets = retargets;
        self.rest_blocks = rest_blocks;
        Ok(plan)
    }

    fn groups(&self, plan: &Plan<Origin>) -> Vec<CutGroup> {
        let layer_colors: HashMap<String, dxf::Color> = self
            .drawing
            .layers()
            .map(|l| (l.name.to_uppercase(), l.color.clone()))
            .collect();
        let entities: Vec<&Entity> = self.drawing.entities().collect();
        plan.cuts
            .iter()
            .map(|cut| {
                let common = match &cut.origin {
                    Origin::LwPolyline(i) | Origin::Circle(i) => &entities[*i].common,
                    Origin::Replace(list) => &entities[list[0]].common,
                    Origin::Added(common) => common.as_ref(),
                };
                CutGroup {
                    color: resolve_color(common, &layer_colors),
                    layer: Some(common.layer.clone()),
                }
            })
            .collect()
    }

    fn write(self, plan: &mut Plan<Origin>, dilated: Vec<Pline>) -> Result<Changes> {
        plan.summary.changed_elements += plan.cuts.len();
        let cuts = plan
            .cuts
            .iter_mut()
            .zip(dilated)
            .map(|(cut, d)| {
                (
                    std::mem::replace(&mut cut.origin, Origin::Replace(Vec::new())),
                    d,
                )
            })
            .collect();
        if self.drawing.header.version < AcadVersion::R2000 {
            plan.summary.notes.push(
                "the drawing was older than R2000 (no LWPOLYLINE before R14, no $INSUNITS before R2000); written as R2000"
                    .into(),
            );
        }
        Ok(Changes {
            drawing: self.drawing,
            scale: self.scale,
            cuts,
            retargets: self.retargets,
            rest_blocks: self.rest_blocks,
            assumed: self.assumed,
        })
    }
}

/// A dilated drawing not yet written: the drawing as read, and what changes in it.
struct Changes {
    drawing: Drawing,
    /// mm per drawing unit.
    scale: f64,
    /// Each cut's origin and its dilated contour (mm).
    cuts: Vec<(Origin, Pline)>,
    /// Model-space `INSERT`s to point at the copy of their block without its cuts.
    retargets: Vec<(usize, String)>,
    /// Those copies.
    rest_blocks: Vec<dxf::Block>,
    /// The units assumed for a drawing that did not say, to write into it.
    assumed: Option<Units>,
}

impl Changes {
    /// The drawing with the changes made.
    fn apply(mut self) -> Drawing {
        let mut removed = vec![false; self.drawing.entities().count()];
        let mut added: Vec<Entity> = Vec::new();
        {
            // Each entity by index, found once (not by counting from the first every time).
            let mut slots: Vec<&mut Entity> = self.drawing.entities_mut().collect();
            for (origin, d) in std::mem::take(&mut self.cuts) {
                write_cut(
                    &mut slots,
                    self.scale,
                    &origin,
                    &d,
                    &mut removed,
                    &mut added,
                );
            }
            for (i, name) in std::mem::take(&mut self.retargets) {
                if let EntityType::Insert(ins) = &mut slots[i].specific {
                    ins.name = name;
                }
            }
        }
        remove_entities(&mut self.drawing, &removed);
        for block in std::mem::take(&mut self.rest_blocks) {
            self.drawing.add_block(block);
        }
        for e in added {
            self.drawing.add_entity(e);
        }
        if self.drawing.header.version < AcadVersion::R2000 {
            self.drawing.header.version = AcadVersion::R2000;
        }
        if let Some(units) = self.assumed.take() {
            self.drawing.header.default_drawing_units = units;
        }
        self.drawing
    }

    /// The input `bytes` (laid out as `layout` says) with the changes spliced in (see the
    /// `splice` submodule), `record` first; `None` when that cannot be done and the drawing must
    /// be written whole.
    fn splice(
        &self,
        bytes: &[u8],
        layout: Option<Layout>,
        record: Option<&str>,
    ) -> Option<Vec<u8>> {
        if self.drawing.header.version < AcadVersion::R2000
            || self.assumed.is_some()
            || !self.retargets.is_empty()
            || !self.rest_blocks.is_empty()
        {
            return None;
        }
        let mut splice = Splice::new(layout?);
        let entities: Vec<&Entity> = self.drawing.entities().collect();
        for (origin, d) in &self.cuts {
            if !splice_cut(&mut splice, bytes, &entities, self.scale, origin, d) {
                return None;
            }
        }
        let precision = Precision {
            mm_per_unit: self.scale,
            unit_digits: unit_digits(self.scale),
            bulge_digits: BULGE_DIGITS,
        };
        splice.write(bytes, record, precision)
    }
}

/// Place one dilated contour's change in `splice` (see [`write_cut`] for what each origin
/// becomes); `false` when an entity it changes cannot be found in the file.
fn splice_cut<'p>(
    splice: &mut Splice<'p>,
    bytes: &[u8],
    entities: &[&Entity],
    scale: f64,
    origin: &Origin,
    d: &'p Pline,
) -> bool {
    let handle = |i: usize| {
        let e = entities.get(i)?;
        let h = e.common.handle.0;
        (h != 0).then(|| (h, type_name(&e.specific)))
    };
    match origin {
        Origin::LwPolyline(i) => handle(*i).is_some_and(|(h, kind)| {
            splice.change(bytes, h, kind.as_bytes(), Change::Vertices, Some(d))
        }),
        Origin::Circle(i) => {
            let Some((h, kind)) = handle(*i) else {
                return false;
            };
            match (as_circle(d), &entities[*i].specific) {
                (Some((c, r)), EntityType::Circle(circle)) => {
                    let m = mirrored(&circle.normal).unwrap_or(false);
                    let z = circle.center.z * if m { -1.0 } else { 1.0 };
                    let to_units = |x: f64| units(x, scale);
                    let new = [to_units(c.x), to_units(c.y), z, to_units(r)];
                    splice.change(bytes, h, kind.as_bytes(), Change::Circle(new), None)
                }
                _ => {
                    splice.change(bytes, h, kind.as_bytes(), Change::Drop, None) && splice.add(h, d)
                }
            }
        }
        Origin::Replace(list) => {
            list.iter().all(|&i| {
                handle(i).is_some_and(|(h, kind)| {
                    splice.change(bytes, h, kind.as_bytes(), Change::Drop, None)
                })
            }) && list
                .first()
                .and_then(|&i| handle(i))
                .is_some_and(|(h, _)| splice.add(h, d))
        }
        // Cuts inside blocks change their INSERTs: never spliced.
        Origin::Added(_) => false,
    }
}

impl DxfPlan<'_> {
    /// Classify every entity; read the cuts into `plan` (closed ones) or the returned open pieces;
    /// expand block references (`INSERT`) into `blocks`.
    fn read_entities<'d>(
        &self,
        entities: &[&'d Entity],
        blocks: &mut blocks::Expansion<'d>,
        plan: &mut Plan<Origin>,
    ) -> Result<Vec<Piece>> {
        let mut pieces: Vec<Piece> = Vec::new();
        let mut problems = Problems::default();
        let model = Affine::scale(self.scale);
        for (i, &e) in entities.iter().enumerate() {
            if !self.drawn(&e.common, &mut plan.summary) {
                continue;
            }
            if let EntityType::Insert(ins) = &e.specific {
                let rest = self.expand_insert(
                    &e.common,
                    ins,
                    &model,
                    &label(e),
                    0,
                    blocks,
                    plan,
                    &mut problems,
                );
                if let Some(rest) = rest {
                    blocks.retarget(i, rest);
                }
                continue;
            }
            if !self.is_cut(
                &e.common,
                &e.specific,
                blocks.layer_colors(),
                &mut plan.summary,
            ) {
                continue;
            }
            match self.read_checked(e, Place::Model(i), i, &model, &mut plan.summary) {
                Ok(Read::Closed(pl, origin)) => plan.cut(pl, label(e), origin),
                Ok(Read::Piece(piece)) => pieces.push(piece),
                Ok(Read::Nothing) => {}
                Err(problem) => problems.push(problem),
            }
        }
        problems.into_error(PlanError::Dxf)?;
        Ok(pieces)
    }

    /// Whether an entity is drawn in model space at all; counts it as passed through when not.
    fn drawn(&self, common: &EntityCommon, summary: &mut PlanSummary) -> bool {
        if common.is_in_paper_space {
            summary.pass("paper space");
            return false;
        }
        if !common.is_visible {
            summary.pass("invisible");
            return false;
        }
        true
    }

    /// Whether an entity (its common properties, block inheritance resolved, and its kind) is a
    /// cut by the rules: a cut geometry in a cut colour, layer and width. Counts it as passed
    /// through when not.
    fn is_cut(
        &self,
        common: &EntityCommon,
        specific: &EntityType,
        layer_colors: &HashMap<String, dxf::Color>,
        summary: &mut PlanSummary,
    ) -> bool {
        let color = resolve_color(common, layer_colors);
        let lw = (common.lineweight_enum_value > 0)
            .then(|| f64::from(common.lineweight_enum_value) / 100.0);
        if let Verdict::Keep(reason) = self.rules.classify_dxf(color, &common.layer, lw) {
            summary.pass(format!("{} ({reason})", type_name(specific)));
            return false;
        }
        let geometry = matches!(
            specific,
            EntityType::LwPolyline(_)
                | EntityType::Polyline(_)
                | EntityType::Line(_)
                | EntityType::Arc(_)
                | EntityType::Circle(_)
                | EntityType::Ellipse(_)
                | EntityType::Spline(_)
        );
        if !geometry {
            summary.pass(format!("{} (not a cut geometry)", type_name(specific)));
            return false;
        }
        summary.cut_elements += 1;
        true
    }

    /// Read one cut entity ([`Self::read_cut`]) and check that what it gives is usable: finite
    /// coordinates within 10 km of the origin.
    fn read_checked(
        &self,
        e: &Entity,
        place: Place,
        index: usize,
        frame: &Affine,
        summary: &mut PlanSummary,
    ) -> Result<Read, String> {
        let so_far = self.vertices_read.get();
        if so_far > MAX_CUT_VERTICES {
            // Refused once, when the count went over: the rest is not read.
            return Ok(Read::Nothing);
        }
        let read = self.read_cut(e, place, index, frame, summary)?;
        let now = so_far + read.vertex_count();
        self.vertices_read.set(now);
        if now > MAX_CUT_VERTICES {
            return Err(format!(
                "the drawing's cuts come to more than {MAX_CUT_VERTICES} vertices, its curves flattened and its blocks expanded, by {} (a curve kilometres long, or an array of many copies?); check the drawing and its units, or explode and simplify it in the CAD program",
                label(e)
            ));
        }
        if !read.is_usable() {
            return Err(format!(
                "{} has a point or an arc that is not a number or reaches more than 10 km from the origin; check the drawing and its units",
                label(e)
            ));
        }
        Ok(read)
    }

    /// Read one cut entity at `place` (`index`: its index in model space or in its block),
    /// `frame` mapping the coordinates it is drawn in to document mm; a problem when it cannot be
    /// dilated.
    fn read_cut(
        &self,
        e: &Entity,
        place: Place,
        index: usize,
        frame: &Affine,
        summary: &mut PlanSummary,
    ) -> Result<Read, String> {
        match &e.specific {
            EntityType::LwPolyline(lw) => {
                let verts: Vec<_> = lw.vertices.iter().map(|v| (v.x, v.y, v.bulge)).collect();
                let f = in_plane(e, &lw.extrusion_direction, frame)?;
                let origin = place.origin(Origin::LwPolyline);
                Ok(polyline_entity(&verts, lw.is_closed(), &f, origin, index))
            }
            EntityType::Polyline(pl) => {
                if pl.is_3d_polyline() || pl.is_3d_polygon_mesh() || pl.is_polyface_mesh() {
                    return Err(format!(
                        "{} is a 3-D polyline or mesh; a cut must be a 2-D polyline",
                        label(e)
                    ));
                }
                let verts: Vec<_> = pl
                    .vertices()
                    .map(|v| (v.location.x, v.location.y, v.bulge))
                    .collect();
                let f = in_plane(e, &pl.normal, frame)?;
                let origin = place.origin(|i| Origin::Replace(vec![i]));
                Ok(polyline_entity(&verts, pl.is_closed(), &f, origin, index))
            }
            EntityType::Line(l) => Ok(line(l, frame, index)),
            EntityType::Arc(a) => Ok(arc(a, &in_plane(e, &a.normal, frame)?, place, index)),
            EntityType::Circle(c) => Ok(circle(c, &in_plane(e, &c.normal, frame)?, place)),
            EntityType::Ellipse(el) => {
                if mirrored(&el.normal).is_none() {
                    return Err(format!("{} is not drawn in the XY plane", label(e)));
                }
                Ok(ellipse(el, frame, place, index))
            }
            EntityType::Spline(sp) => {
                let read = spline(sp, frame, place, index)
                    .map_err(|why| format!("{} cannot be read: {why}", label(e)))?;
                note_splines(summary);
                Ok(read)
            }
            _ => Ok(Read::Nothing),
        }
    }
}

/// Say once that splines were approximated.
fn note_splines(summary: &mut PlanSummary) {
    const NOTE: &str = "SPLINEs were approximated by circular arcs";
    if !summary.notes.iter().any(|n| n.starts_with(NOTE)) {
        summary.notes.push(format!(
            "{NOTE} within {} µm of the curve",
            CURVE_TOLERANCE_MM * 1e3
        ));
    }
}

/// A polyline entity's vertices (x, y, bulge, drawn in `frame`) read as a contour or a piece.
fn polyline_entity(
    verts: &[(f64, f64, f64)],
    closed: bool,
    frame: &Affine,
    origin: Origin,
    index: usize,
) -> Read {
    polyline_read(map_vertices(frame, verts, closed), closed, origin, index)
}

/// Points of a curve closer than this (mm) are one point (cavalier_contours takes points within
/// 10⁻⁸ for the same).
const CURVE_JOIN_MM: f64 = 1e-7;

/// Coordinates further from the origin than this (mm) are refused: 10 km is no laser bed, and
/// such numbers are a unit mistake or a damaged file.
const MAX_COORDINATE_MM: f64 = 1e7;

/// The frame of an entity drawn in the plane with OCS normal `n`, inside `frame`: mirrored in x
/// when the normal is −z; a problem when it is neither +z nor −z.
fn in_plane(e: &Entity, n: &Vector, frame: &Affine) -> Result<Affine, String> {
    let m = plane(e, n)?;
    Ok(if m {
        frame.then_after(&Affine {
            a: -1.0,
            ..Affine::IDENTITY
        })
    } else {
        *frame
    })
}

/// Polyline vertices (x, y, bulge in the entity's own coordinates) mapped by `frame` into
/// document mm. Under a similarity an arc stays one arc (its bulge negated by a mirror); under
/// any other map (a block inserted with unequal x and y scales) it becomes an elliptical arc,
/// approximated by biarcs within [`CURVE_TOLERANCE_MM`].
fn map_vertices(frame: &Affine, verts: &[(f64, f64, f64)], closed: bool) -> Vec<PlineVertex<f64>> {
    let n = verts.len();
    let similar = frame.is_similarity();
    let flip = if frame.det() < 0.0 { -1.0 } else { 1.0 };
    let mut out = Vec::with_capacity(n);
    for (i, &(x, y, bulge)) in verts.iter().enumerate() {
        let p = v2(x, y);
        let next = if i + 1 < n {
            Some(verts[i + 1])
        } else if closed {
            verts.first().copied()
        } else {
            None
        };
        let arc = next.and_then(|(nx, ny, _)| arc_geom(p, v2(nx, ny), bulge));
        match arc {
            Some(g) if !similar && g.radius.is_finite() => {
                let f = |t: f64| {
                    let (s, c) = (g.start_angle + g.sweep * t).sin_cos();
                    (
                        frame.apply(g.center + v2(c, s).scale(g.radius)),
                        frame.apply_vector(v2(-s, c).scale(g.radius * g.sweep)),
                    )
                };
                fit_biarcs(&f, 0.0, 1.0, CURVE_TOLERANCE_MM, &mut out);
            }
            _ => {
                let q = frame.apply(p);
                let b = if next.is_some() { bulge * flip } else { 0.0 };
                out.push(PlineVertex::new(q.x, q.y, b));
            }
        }
    }
    out
}

fn line(l: &dxf::entities::Line, frame: &Affine, i: usize) -> Read {
    let (a, b) = (
        frame.apply(v2(l.p1.x, l.p1.y)),
        frame.apply(v2(l.p2.x, l.p2.y)),
    );
    let length = (a - b).length();
    if length.is_nan() || length <= JOIN_MM {
        return Read::Nothing;
    }
    Read::Piece(Piece {
        vertices: vec![
            PlineVertex::new(a.x, a.y, 0.0),
            PlineVertex::new(b.x, b.y, 0.0),
        ],
        entities: vec![i],
    })
}

fn arc(a: &dxf::entities::Arc, frame: &Affine, place: Place, i: usize) -> Read {
    let (s, t) = (a.start_angle.to_radians(), a.end_angle.to_radians());
    let mut sweep = (t - s).rem_euclid(std::f64::consts::TAU);
    if sweep.is_nan() || sweep < 1e-12 {
        sweep = std::f64::consts::TAU;
    }
    let at = |ang: f64| {
        (
            a.center.x + a.radius * ang.cos(),
            a.center.y + a.radius * ang.sin(),
        )
    };
    if a.radius.is_nan() || a.radius <= 0.0 {
        return Read::Nothing;
    }
    if sweep >= std::f64::consts::TAU - 1e-9 {
        // A full-circle arc: a circle.
        let (q0, qm) = (at(s), at(s + sweep / 2.0));
        let verts = [(q0.0, q0.1, 1.0), (qm.0, qm.1, 1.0)];
        let pl = closed_pline(map_vertices(frame, &verts, true));
        Read::Closed(pl, place.origin(|i| Origin::Replace(vec![i])))
    } else {
        let (q0, q1) = (at(s), at(s + sweep));
        let verts = [(q0.0, q0.1, (sweep / 4.0).tan()), (q1.0, q1.1, 0.0)];
        Read::Piece(Piece {
            vertices: map_vertices(frame, &verts, false),
            entities: vec![i],
        })
    }
}

fn circle(c: &dxf::entities::Circle, frame: &Affine, place: Place) -> Read {
    if c.radius.is_nan() || c.radius <= 0.0 {
        return Read::Nothing;
    }
    let verts = [
        (c.center.x + c.radius, c.center.y, 1.0),
        (c.center.x - c.radius, c.center.y, 1.0),
    ];
    let pl = closed_pline(map_vertices(frame, &verts, true));
    Read::Closed(pl, place.origin(Origin::Circle))
}

fn closed_pline(verts: Vec<PlineVertex<f64>>) -> Pline {
    let mut pl = Pline::with_capacity(verts.len(), true);
    for v in verts {
        pl.add_vertex(v);
    }
    pl
}

/// An ellipse's parameters (finite) as a start in [0, 2π) and an end after it, at most a full
/// turn on: the sweep from start to end, counter-clockwise, taken modulo a turn (none is a full
/// one, more than one is one). Reduced, not stepped a turn at a time: a parameter of 1e17 no
/// longer changes when 2π is added to it.
fn ellipse_span(t0: f64, t1: f64) -> (f64, f64) {
    let tau = std::f64::consts::TAU;
    let sweep = t1 - t0;
    let sweep = if sweep > tau {
        tau
    } else {
        match sweep.rem_euclid(tau) {
            s if s > 0.0 && s.is_finite() => s,
            _ => tau,
        }
    };
    let start = t0.rem_euclid(tau);
    (start, start + sweep)
}

/// An `ELLIPSE` (or elliptic arc), by biarcs. Its centre and axis are in the coordinates of its
/// block (or model space), whatever its normal; a −z normal reverses its sense.
fn ellipse(el: &dxf::entities::Ellipse, frame: &Affine, place: Place, i: usize) -> Read {
    let mj = v2(el.major_axis.x, el.major_axis.y);
    // Minor axis = ratio · (normal × major).
    let mn = v2(-mj.y, mj.x).scale(el.minor_axis_ratio * el.normal.z.signum());
    let c = v2(el.center.x, el.center.y);
    let (t0, t1) = (el.start_parameter, el.end_parameter);
    if !(t0.is_finite() && t1.is_finite() && mj.length() > 0.0) {
        return Read::Nothing;
    }
    let (t0, t1) = ellipse_span(t0, t1);
    let full = (t1 - t0 - std::f64::consts::TAU).abs() < 1e-9;
    let f = |u: f64| {
        let t = t0 + (t1 - t0) * u;
        let pos = c + mj.scale(t.cos()) + mn.scale(t.sin());
        let d = (mn.scale(t.cos()) - mj.scale(t.sin())).scale(t1 - t0);
        (frame.apply(pos), frame.apply_vector(d))
    };
    let mut sink = PathSink::new(CURVE_JOIN_MM, 1e-12);
    sink.move_to(f(0.0).0);
    sink.curve(&f, f(1.0).0);
    if full {
        sink.close();
    }
    curve_read(sink, full, place, i)
}

/// A `SPLINE` (its control points, weights and knots; see [`nurbs`]), by biarcs within
/// [`CURVE_TOLERANCE_MM`]. A spline given by fit points alone is refused.
fn spline(
    sp: &dxf::entities::Spline,
    frame: &Affine,
    place: Place,
    i: usize,
) -> Result<Read, String> {
    if sp.control_points.is_empty() && !sp.fit_points.is_empty() {
        return Err(
            "it is given by fit points only (no control points); convert it to a polyline in the CAD program, or save it with control points"
                .into(),
        );
    }
    let points: Vec<(f64, f64)> = sp.control_points.iter().map(|p| (p.x, p.y)).collect();
    let curve = Nurbs::new(
        sp.degree_of_curve,
        &points,
        &sp.weight_values,
        &sp.knot_values,
    )?;
    let mut sink = PathSink::new(CURVE_JOIN_MM, 1e-12);
    sink.move_to(frame.apply(curve.start()));
    for k in curve.spans() {
        let piece = curve.span_curve(k);
        let f = |t: f64| {
            let (p, d) = piece(t);
            (frame.apply(p), frame.apply_vector(d))
        };
        sink.curve(&f, f(1.0).0);
        if sink.vertex_count() > MAX_CUT_VERTICES {
            // Kilometres of wiggles at the curve tolerance: refused before it fills the memory.
            return Err(format!(
                "it comes to more than {MAX_CUT_VERTICES} vertices when flattened (a curve kilometres long?); check the drawing and its units"
            ));
        }
    }
    if sp.is_closed() {
        sink.close();
    }
    Ok(curve_read(sink, sp.is_closed(), place, i))
}

/// A curve drawn into `sink` as a closed contour (when `closed`, or when it ends where it
/// starts) or an open piece.
fn curve_read(sink: PathSink, closed: bool, place: Place, i: usize) -> Read {
    match sink.finish().into_iter().next() {
        Some(sub) => {
            let is_closed = closed || sub.pline.is_closed();
            let verts = sub.pline.iter_vertexes().collect();
            polyline_read(
                verts,
                is_closed,
                place.origin(|i| Origin::Replace(vec![i])),
                i,
            )
        }
        None => Read::Nothing,
    }
}

/// Join the open pieces into chains: the closed ones are cuts (named by `name_of` their first
/// entity, their origin made by `origin_of` their entities), the rest open paths. Returns the
/// entities of the closed chains.
fn close_chains(
    pieces: Vec<Piece>,
    name_of: &dyn Fn(usize) -> String,
    origin_of: &dyn Fn(&[usize]) -> Origin,
    plan: &mut Plan<Origin>,
) -> Vec<usize> {
    let mut closed = Vec::new();
    for chain in join_pieces(pieces) {
        let first = name_of(chain.entities[0]);
        let name = if chain.entities.len() == 1 {
            first
        } else {
            format!("chain of {} entities from {first}", chain.entities.len())
        };
        if (chain.start() - chain.end()).length() <= JOIN_MM && chain.vertices.len() > 2 {
            let n = chain.vertices.len();
            let pl = closed_pline(chain.vertices[..n - 1].to_vec());
            plan.cut(pl, name, origin_of(&chain.entities));
            closed.extend_from_slice(&chain.entities);
        } else {
            plan.open_path(name, chain.start(), chain.end());
        }
    }
    closed
}

/// Put one dilated contour back (`slots`: the drawing's entities by index, `scale`: mm per
/// drawing unit): edit its entity in place, or mark the entities it replaces (`removed`) and add
/// the new `LWPOLYLINE` to `added`.
fn write_cut(
    slots: &mut [&mut Entity],
    scale: f64,
    origin: &Origin,
    d: &Pline,
    removed: &mut [bool],
    added: &mut Vec<Entity>,
) {
    let to_units = |x: f64| units(x, scale);
    match origin {
        Origin::Circle(i) => {
            let entity = &mut *slots[*i];
            match (as_circle(d), &mut entity.specific) {
                (Some((c, r)), EntityType::Circle(circle)) => {
                    let m = mirrored(&circle.normal).unwrap_or(false);
                    let z = circle.center.z * if m { -1.0 } else { 1.0 };
                    circle.center = Point::new(to_units(c.x), to_units(c.y), z);
                    circle.radius = to_units(r);
                    circle.normal = Vector::z_axis();
                }
                _ => {
                    removed[*i] = true;
                    added.push(new_lwpolyline(&entity.common, d, scale));
                }
            }
        }
        Origin::LwPolyline(i) => {
            if let EntityType::LwPolyline(lw) = &mut slots[*i].specific {
                lw.vertices = lw_vertices(d, scale);
                lw.set_is_closed(true);
                lw.extrusion_direction = Vector::z_axis();
            }
        }
        Origin::Replace(list) => {
            for &i in list {
                removed[i] = true;
            }
            added.push(new_lwpolyline(&slots[list[0]].common, d, scale));
        }
        Origin::Added(like) => added.push(new_lwpolyline(like, d, scale)),
    }
}

/// Remove the entities marked in `removed` in one pass, the others keeping their order and
/// handles. (Removing them one at a time from the middle of the list is quadratic.)
fn remove_entities(drawing: &mut Drawing, removed: &[bool]) {
    let (kept, total) = {
        let mut slots: Vec<&mut Entity> = drawing.entities_mut().collect();
        let mut kept = 0;
        for r in 0..slots.len() {
            if !removed.get(r).copied().unwrap_or(false) {
                if kept != r {
                    let (front, back) = slots.split_at_mut(r);
                    std::mem::swap(&mut *front[kept], &mut *back[0]);
                }
                kept += 1;
            }
        }
        (kept, slots.len())
    };
    // The removed ones are now at the end, where removing is cheap.
    for i in (kept..total).rev() {
        drawing.remove_entity(i);
    }
}

/// Whether an entity's OCS normal `n` is mirrored (−z) or not (+z); a problem when it is neither.
fn plane(e: &Entity, n: &Vector) -> Result<bool, String> {
    mirrored(n).ok_or_else(|| {
        format!(
            "{} is not drawn in the XY plane (extrusion direction {:?}); flatten the drawing",
            label(e),
            (n.x, n.y, n.z)
        )
    })
}

fn resolve_color(e: &EntityCommon, layers: &HashMap<String, dxf::Color>) -> Option<Rgb> {
    if e.color_24_bit != 0 {
        let c = e.color_24_bit;
        return Some(Rgb((c >> 16) as u8, (c >> 8) as u8, c as u8));
    }
    let c = if e.color.is_by_layer() || e.color.is_by_block() {
        layers.get(&e.layer.to_uppercase()).cloned()?
    } else {
        e.color.clone()
    };
    Rgb::from_aci(c.index()?)
}

/// A polyline's vertices (mm) as a closed contour (closed by flag, or by ending where it starts)
/// or an open piece.
fn polyline_read(
    mut verts: Vec<PlineVertex<f64>>,
    closed_flag: bool,
    origin: Origin,
    index: usize,
) -> Read {
    // Drop repeated points.
    verts.dedup_by(|b, a| (v2(a.x, a.y) - v2(b.x, b.y)).length() <= JOIN_MM * 1e-3);
    if verts.len() < 2 {
        return Read::Nothing;
    }
    let n = verts.len();
    let ends_meet =
        (v2(verts[0].x, verts[0].y) - v2(verts[n - 1].x, verts[n - 1].y)).length() <= JOIN_MM;
    if closed_flag || (ends_meet && n > 2) {
        if ends_meet {
            verts.pop();
        }
        let mut pl = Pline::new_closed();
        for v in verts {
            pl.add_vertex(v);
        }
        Read::Closed(pl, origin)
    } else {
        if let Some(last) = verts.last_mut() {
            last.bulge = 0.0;
        }
        Read::Piece(Piece {
            vertices: verts,
            entities: vec![index],
        })
    }
}

/// Join pieces end to end (either direction) into maximal chains.
fn join_pieces(pieces: Vec<Piece>) -> Vec<Piece> {
    let key = |p: V2| {
        (
            (p.x / JOIN_MM).round() as i64,
            (p.y / JOIN_MM).round() as i64,
        )
    };
    let ends_of: Vec<(V2, V2)> = pieces.iter().map(|p| (p.start(), p.end())).collect();
    let mut ends: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, &(start, end)) in ends_of.iter().enumerate() {
        ends.entry(key(start)).or_default().push(i);
        ends.entry(key(end)).or_default().push(i);
    }
    // A piece is taken out of its slot as it joins a chain (moved, never copied).
    let mut slots: Vec<Option<Piece>> = pieces.into_iter().map(Some).collect();
    // The free piece with an end at `q`, turned to start there (`forward`) or to end there.
    let take_at = |q: V2, forward: bool, slots: &mut [Option<Piece>]| -> Option<Piece> {
        let (kx, ky) = key(q);
        let j = (-1..=1)
            .flat_map(|dx| (-1..=1).map(move |dy| (kx + dx, ky + dy)))
            .filter_map(|k| ends.get(&k))
            .flatten()
            .copied()
            .find(|&j| {
                let (s, e) = ends_of[j];
                slots[j].is_some() && ((s - q).length() <= JOIN_MM || (e - q).length() <= JOIN_MM)
            })?;
        let piece = slots[j].take()?;
        let (start, end) = ends_of[j];
        let kept = (if forward { start } else { end } - q).length() <= JOIN_MM;
        Some(if kept { piece } else { piece.reversed() })
    };
    let mut chains = Vec::new();
    for i in 0..slots.len() {
        let Some(mut chain) = slots[i].take() else {
            continue;
        };
        // Forward.
        while (chain.end() - chain.start()).length() > JOIN_MM {
            let Some(next) = take_at(chain.end(), true, &mut slots) else {
                break;
            };
            chain.append(next);
        }
        // Backward, for chains that did not close: the pieces before it, nearest first (joined
        // at the end, so that each vertex is copied once).
        let mut before: Vec<Piece> = Vec::new();
        let mut start = chain.start();
        while (chain.end() - start).length() > JOIN_MM {
            let Some(prev) = take_at(start, false, &mut slots) else {
                break;
            };
            start = prev.start();
            before.push(prev);
        }
        if let Some(mut whole) = before.pop() {
            while let Some(next) = before.pop() {
                whole.append(next);
            }
            whole.append(chain);
            chain = whole;
        }
        chains.push(chain);
    }
    chains
}

/// Centre and radius when a closed polyline is one full circle.
fn as_circle(p: &Pline) -> Option<(V2, f64)> {
    let n = p.vertex_count();
    let mut found: Option<(V2, f64)> = None;
    let mut sweep = 0.0;
    for i in 0..n {
        let a = p.at(i);
        let b = p.at((i + 1) % n);
        let g = arc_geom(v2(a.x, a.y), v2(b.x, b.y), a.bulge)?;
        sweep += g.sweep;
        match found {
            None => found = Some((g.center, g.radius)),
            Some((c, r)) => {
                if (c - g.center).length() > 1e-9 || (r - g.radius).abs() > 1e-9 {
                    return None;
                }
            }
        }
    }
    ((sweep.abs() - std::f64::consts::TAU).abs() < 1e-9).then_some(())?;
    found
}

/// Decimal places of the numbers written: a step of at most 0.01 µm (so a coordinate is within
/// 0.005 µm), and bulges to 10⁻¹⁰ (a 10 m chord's arc within 0.001 µm). The `dxf` crate prints
/// 12 decimals and drops trailing zeros, so rounded numbers print short.
const STEP_MM: f64 = 1e-5;
const BULGE_DIGITS: i32 = 10;

/// `v` rounded to `digits` decimals.
fn rounded(v: f64, digits: i32) -> f64 {
    let m = pow10(digits);
    let r = (v * m).round() / m;
    if r.is_finite() { r } else { v }
}

/// The decimals of a coordinate in drawing units (`scale` mm each) that give the step written
/// (see [`STEP_MM`]).
fn unit_digits(scale: f64) -> i32 {
    decimals_for_step(STEP_MM / scale) as i32
}

/// `mm` in drawing units (`scale` mm each), rounded to the step written (see [`STEP_MM`]).
fn units(mm: f64, scale: f64) -> f64 {
    rounded(mm / scale, unit_digits(scale))
}

fn lw_vertices(p: &Pline, scale: f64) -> Vec<LwPolylineVertex> {
    p.iter_vertexes()
        .map(|v| LwPolylineVertex {
            x: units(v.x, scale),
            y: units(v.y, scale),
            bulge: rounded(v.bulge, BULGE_DIGITS),
            ..LwPolylineVertex::default()
        })
        .collect()
}

fn new_lwpolyline(like: &EntityCommon, p: &Pline, scale: f64) -> Entity {
    let mut lw = LwPolyline {
        vertices: lw_vertices(p, scale),
        ..LwPolyline::default()
    };
    lw.set_is_closed(true);
    let mut e = Entity::new(EntityType::LwPolyline(lw));
    e.common.layer = like.layer.clone();
    e.common.color = like.color.clone();
    e.common.color_24_bit = like.color_24_bit;
    e.common.line_type_name = like.line_type_name.clone();
    e.common.lineweight_enum_value = like.lineweight_enum_value;
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_ellipse_span_is_one_turn_at_most_and_huge_parameters_end() {
        let tau = std::f64::consts::TAU;
        let close =
            |(a, b): (f64, f64), (c, d): (f64, f64)| (a - c).abs() < 1e-12 && (b - d).abs() < 1e-12;
        assert!(close(ellipse_span(0.0, tau), (0.0, tau)));
        assert!(close(ellipse_span(1.0, 3.0), (1.0, 3.0)));
        assert!(close(ellipse_span(5.0, 7.0), (5.0, 7.0)));
        assert!(close(ellipse_span(3.0, 1.0), (3.0, 1.0 + tau)));
        assert!(close(ellipse_span(0.0, 3.0 * tau), (0.0, tau)));
        assert!(close(ellipse_span(2.0, 2.0), (2.0, 2.0 + tau)));
        // Stepping a turn at a time never ended here.
        let (start, end) = ellipse_span(1e17, 1e17);
        assert!((0.0..tau).contains(&start) && (end - start - tau).abs() < 1e-9);
        let (start, end) = ellipse_span(1e12, 0.0);
        assert!((0.0..tau).contains(&start) && end > start && end - start <= tau);
    }
    use dxf::entities::{Circle, Insert, Line};

    fn drawing(units: Units) -> Drawing {
        let mut d = Drawing::new();
        d.header.version = AcadVersion::R2000;
        d.header.default_drawing_units = units;
        let mut c = Entity::new(EntityType::Circle(Circle::new(
            Point::new(5.0, 5.0, 0.0),
            1.0,
        )));
        c.common.color = dxf::Color::from_index(1);
        d.add_entity(c);
        d
    }

    #[test]
    fn inches_are_converted_both_ways() {
        // 254 µm of kerf = 0.01 in: the hole-less disc grows by 0.005 in of radius.
        let (out, s) = dilate_drawing(
            drawing(Units::Inches),
            &KerfSource::Uniform(254.0),
            &DxfOptions::default(),
        )
        .unwrap();
        assert_eq!(s.mm_per_unit, 25.4);
        let r = out
            .entities()
            .find_map(|e| match &e.specific {
                EntityType::Circle(c) => Some(c.radius),
                _ => None,
            })
            .unwrap();
        assert!((r - 1.005).abs() < 1e-12, "{r}");
    }

    #[test]
    fn unitless_drawings_need_assumed_units_and_other_colours_pass() {
        let e = dilate_drawing(
            drawing(Units::Unitless),
            &KerfSource::Uniform(100.0),
            &DxfOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("unknown units"), "{e}");
        let mut d = drawing(Units::Unitless);
        let mut l = Entity::new(EntityType::Line(Line::new(
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
        )));
        l.common.color = dxf::Color::from_index(3);
        d.add_entity(l);
        let opts = DxfOptions {
            assume_units: Some(AssumedUnits::Mm),
            ..DxfOptions::default()
        };
        let (_, s) = dilate_drawing(d, &KerfSource::Uniform(100.0), &opts).unwrap();
        assert_eq!(s.contours_dilated, 1);
        assert_eq!(s.passed_through.len(), 1, "{:?}", s.passed_through);
        assert!(s.open_paths.is_empty());
    }

    #[test]
    fn a_spline_that_cannot_be_a_curve_is_refused_with_the_reason() {
        let mut d = drawing(Units::Millimeters);
        let mut sp = Entity::new(EntityType::Spline(dxf::entities::Spline::default()));
        sp.common.color = dxf::Color::from_index(1);
        d.add_entity(sp);
        let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("SPLINE") && e.contains("control points"), "{e}");
    }

    /// A closed rational quadratic spline: the circle of radius 10 about (50, 50), four arcs.
    fn circle_spline() -> dxf::entities::Spline {
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let pts = [
            (60.0, 50.0),
            (60.0, 60.0),
            (50.0, 60.0),
            (40.0, 60.0),
            (40.0, 50.0),
            (40.0, 40.0),
            (50.0, 40.0),
            (60.0, 40.0),
            (60.0, 50.0),
        ];
        let mut sp = dxf::entities::Spline {
            degree_of_curve: 2,
            control_points: pts.iter().map(|&(x, y)| Point::new(x, y, 0.0)).collect(),
            weight_values: (0..9).map(|k| if k % 2 == 1 { w } else { 1.0 }).collect(),
            knot_values: vec![0., 0., 0., 1., 1., 2., 2., 3., 3., 4., 4., 4.],
            ..Default::default()
        };
        sp.set_is_closed(true);
        sp.set_is_rational(true);
        sp
    }

    /// Every vertex's distance from (50, 50), and every arc's radius about it.
    fn radii(p: &LwPolyline) -> Vec<f64> {
        let n = p.vertices.len();
        (0..n)
            .map(|k| {
                let (a, b) = (&p.vertices[k], &p.vertices[(k + 1) % n]);
                let mid = crate::geom::segment_point(v2(a.x, a.y), v2(b.x, b.y), a.bulge, 0.5);
                (mid - v2(50.0, 50.0)).length()
            })
            .collect()
    }

    fn lwpolylines(d: &Drawing) -> Vec<&LwPolyline> {
        d.entities()
            .filter_map(|e| match &e.specific {
                EntityType::LwPolyline(p) => Some(p),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_spline_is_read_as_arcs_and_dilated() {
        let mut d = drawing(Units::Millimeters);
        let mut sp = Entity::new(EntityType::Spline(circle_spline()));
        sp.common.color = dxf::Color::from_index(1);
        d.add_entity(sp);
        let (out, s) =
            dilate_drawing(d, &KerfSource::Uniform(200.0), &DxfOptions::default()).unwrap();
        assert_eq!(s.contours_dilated, 2);
        let pl = lwpolylines(&out);
        assert_eq!(pl.len(), 1);
        // Within 0.01 µm: the numbers are written to 0.01 µm.
        for r in radii(pl[0]) {
            assert!((r - 10.1).abs() < 1e-5, "{r} {:?}", pl[0].vertices);
        }
        assert!(
            s.notes.iter().any(|n| n.contains("SPLINE")),
            "{:?}",
            s.notes
        );
    }

    /// A block `PART` (base point (1, 1)): a red square 0..10 drawn on layer 0 in BYBLOCK colour,
    /// a text, and an open red line; inserted by `insert`.
    fn with_block(insert: Insert) -> Drawing {
        let mut d = Drawing::new();
        d.header.version = AcadVersion::R2000;
        d.header.default_drawing_units = Units::Millimeters;
        let mut square = LwPolyline::default();
        for (x, y) in [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)] {
            square.vertices.push(LwPolylineVertex {
                x,
                y,
                ..Default::default()
            });
        }
        square.set_is_closed(true);
        let mut sq = Entity::new(EntityType::LwPolyline(square));
        sq.common.color = dxf::Color::by_block();
        let text = Entity::new(EntityType::Text(dxf::entities::Text {
            value: "label".into(),
            ..Default::default()
        }));
        let mut slit = Entity::new(EntityType::Line(Line::new(
            Point::new(2.0, 5.0, 0.0),
            Point::new(8.0, 5.0, 0.0),
        )));
        slit.common.color = dxf::Color::from_index(1);
        let block = dxf::Block {
            name: "PART".into(),
            base_point: Point::new(1.0, 1.0, 0.0),
            entities: vec![sq, text, slit],
            ..Default::default()
        };
        d.add_block(block);
        let mut ins = Entity::new(EntityType::Insert(insert));
        ins.common.color = dxf::Color::from_index(1);
        d.add_entity(ins);
        d
    }

    fn bounds(p: &LwPolyline) -> (f64, f64, f64, f64) {
        let xs = p.vertices.iter().map(|v| v.x);
        let ys = p.vertices.iter().map(|v| v.y);
        (
            xs.clone().fold(f64::INFINITY, f64::min),
            ys.clone().fold(f64::INFINITY, f64::min),
            xs.fold(f64::NEG_INFINITY, f64::max),
            ys.fold(f64::NEG_INFINITY, f64::max),
        )
    }

    #[test]
    fn cuts_inside_a_rotated_scaled_block_are_dilated_and_the_rest_is_kept() {
        let insert = Insert {
            name: "PART".into(),
            location: Point::new(100.0, 0.0, 0.0),
            x_scale_factor: 2.0,
            y_scale_factor: 2.0,
            rotation: 90.0,
            ..Default::default()
        };
        let (out, s) = dilate_drawing(
            with_block(insert),
            &KerfSource::Uniform(200.0),
            &DxfOptions::default(),
        )
        .unwrap();
        assert_eq!(s.contours_dilated, 1);
        assert_eq!(s.open_paths.len(), 1, "{:?}", s.open_paths);
        // The square (0..10 about base (1, 1)), doubled and turned a quarter: x 100−18 … 100+2,
        // y −2 … 18; then dilated by 0.1 mm.
        let pl = lwpolylines(&out);
        assert_eq!(pl.len(), 1);
        let (x0, y0, x1, y1) = bounds(pl[0]);
        for (got, want) in [(x0, 81.9), (y0, -2.1), (x1, 102.1), (y1, 18.1)] {
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        // The INSERT now shows a copy of the block with the text and the open line alone.
        let name = out
            .entities()
            .find_map(|e| match &e.specific {
                EntityType::Insert(i) => Some(i.name.clone()),
                _ => None,
            })
            .unwrap();
        assert_eq!(name, "PART_KERF1");
        let copy = out.blocks().find(|b| b.name == name).unwrap();
        assert_eq!(copy.entities.len(), 2);
        let original = out.blocks().find(|b| b.name == "PART").unwrap();
        assert_eq!(original.entities.len(), 3);
    }

    #[test]
    fn unequal_block_scales_make_circles_ellipses_and_nested_blocks_compose() {
        let mut d = with_block(Insert {
            name: "PART".into(),
            ..Default::default()
        });
        // A block OUTER inserting PART stretched 3 × 1, itself inserted mirrored in x.
        let inner = Entity::new(EntityType::Insert(Insert {
            name: "PART".into(),
            location: Point::new(1.0, 1.0, 0.0),
            x_scale_factor: 3.0,
            ..Default::default()
        }));
        let mut circle = Entity::new(EntityType::Circle(Circle::new(
            Point::new(0.0, 20.0, 0.0),
            2.0,
        )));
        circle.common.color = dxf::Color::from_index(5);
        d.add_block(dxf::Block {
            name: "OUTER".into(),
            entities: vec![inner, circle],
            ..Default::default()
        });
        let mut outer = Entity::new(EntityType::Insert(Insert {
            name: "OUTER".into(),
            location: Point::new(50.0, 0.0, 0.0),
            x_scale_factor: -1.0,
            y_scale_factor: 2.0,
            ..Default::default()
        }));
        outer.common.color = dxf::Color::from_index(1);
        d.add_entity(outer);
        let (out, s) =
            dilate_drawing(d, &KerfSource::Uniform(200.0), &DxfOptions::default()).unwrap();
        // The first INSERT's square, the nested one, and the circle (now an ellipse 2 × 4).
        assert_eq!(s.contours_dilated, 3);
        let boxes: Vec<_> = lwpolylines(&out).into_iter().map(bounds).collect();
        let near = |a: (f64, f64, f64, f64), b: (f64, f64, f64, f64)| {
            [(a.0, b.0), (a.1, b.1), (a.2, b.2), (a.3, b.3)]
                .iter()
                .all(|(p, q)| (p - q).abs() < 1e-4)
        };
        // Nested: PART's x, y ∈ 0…10 about its base (1, 1), placed at (1, 1) in OUTER:
        // x ↦ 1 + 3·(x − 1) ∈ −2…28, y ∈ 0…10; OUTER at (50, 0) scaled (−1, 2): x 22…52, y 0…20.
        assert!(
            boxes.iter().any(|b| near(*b, (21.9, -0.1, 52.1, 20.1))),
            "{boxes:?}"
        );
        // The ellipse about (50, 40): semi-axes 2 (x) and 4 (y), dilated by 0.1.
        assert!(
            boxes.iter().any(|b| near(*b, (47.9, 35.9, 52.1, 44.1))),
            "{boxes:?}"
        );
        // OUTER's copy points at PART's copy.
        let outer_copy = out.blocks().find(|b| b.name == "OUTER_KERF1").unwrap();
        assert!(outer_copy.entities.iter().any(|e| matches!(
            &e.specific,
            EntityType::Insert(i) if i.name == "PART_KERF1"
        )));
    }

    #[test]
    fn a_block_that_inserts_itself_or_is_missing_is_refused() {
        let mut d = drawing(Units::Millimeters);
        let me = Entity::new(EntityType::Insert(Insert {
            name: "LOOP".into(),
            ..Default::default()
        }));
        d.add_block(dxf::Block {
            name: "LOOP".into(),
            entities: vec![me],
            ..Default::default()
        });
        d.add_entity(Entity::new(EntityType::Insert(Insert {
            name: "LOOP".into(),
            ..Default::default()
        })));
        d.add_entity(Entity::new(EntityType::Insert(Insert {
            name: "GONE".into(),
            ..Default::default()
        })));
        let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"LOOP\" inside itself"), "{e}");
        assert!(e.contains("\"GONE\", which is not in the file"), "{e}");
    }

    /// A few hundred bytes: an array of 316 × 316 copies of a block of 50 circles (5 million
    /// contours, which ran out of memory) is refused for its size before it is read.
    #[test]
    fn an_array_of_a_large_block_is_refused_for_the_entities_it_comes_to() {
        let mut d = drawing(Units::Millimeters);
        let circles = (0..50)
            .map(|k| {
                let mut c = Entity::new(EntityType::Circle(dxf::entities::Circle::new(
                    Point::new(f64::from(k), 0.0, 0.0),
                    0.4,
                )));
                c.common.color = dxf::Color::from_index(1);
                c
            })
            .collect();
        d.add_block(dxf::Block {
            name: "S".into(),
            entities: circles,
            ..Default::default()
        });
        d.add_entity(Entity::new(EntityType::Insert(Insert {
            name: "S".into(),
            column_count: 316,
            row_count: 316,
            column_spacing: 60.0,
            row_spacing: 2.0,
            ..Default::default()
        })));
        let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("come to more than 1000000 entities"), "{e}");
    }
}
