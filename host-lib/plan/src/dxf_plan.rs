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
//!   [`CURVE_TOLERANCE_MM`](crate::geom::CURVE_TOLERANCE_MM) (0.05 µm) of the curve at the points checked; a
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
//! **Writing.** The output is the input's text with only the cuts rewritten (the crate-private
//! `splice`, `text` and `write` submodules): a closed `LWPOLYLINE` gets its new vertices in place
//! (handle, layer, colour, extended data kept); a `CIRCLE` stays a `CIRCLE` with the new radius;
//! a chain of pieces (and an old-style `POLYLINE`, an `ELLIPSE` or a `SPLINE`) is replaced by one
//! closed polyline with bulges that takes over the first piece's layer, colour, linetype and
//! lineweight; a cut inside a block is taken out of the block and drawn in model space, once for
//! each insertion. New polylines are `LWPOLYLINE`s from R14 on and `POLYLINE`s before, with new
//! handles (and `$HANDSEED` moved past them) when the drawing has handles. Every other entity,
//! table, object, comment and number comes out byte for byte as it went in, with its handle, in
//! the drawing's own version: no program's structure is rebuilt, so every reader opens the
//! output as it opened the input, and writing a large plan costs little more than formatting its
//! new vertices (on the 10,000-contour benchmark plan the `dxf` crate's save took 0.94–1.2 s and
//! most of the peak memory; the splice 0.09–0.12 s, its formatting spread over the cores). A
//! binary DXF is turned into ASCII DXF text pair for pair first (the `binary` submodule), read
//! by the `dxf` crate from that text, and written as ASCII. Units assumed for a drawing that
//! did not say (`--units`) are written into its `$INSUNITS` from R2000 (R12 and R14 have no such
//! variable). What was applied is recorded in `999` comments at the top of the file (see
//! [`compensation`](crate::compensation)).

use std::cell::Cell;
use std::collections::{HashMap, HashSet};

use cavalier_contours::polyline::{PlineSource, PlineVertex};
use dxf::entities::{Entity, EntityCommon, EntityType};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, Vector};

use super::compensation::{FoundCompensation, IfCompensated};
use super::dilate::KerfSource;
use super::geom::{Affine, Pline, arc_geom, v2};
use super::outcome::{AssumedUnits, CutGroup, CutPath, PlanSummary};
use super::pipeline::{self, Format, MAX_CUT_VERTICES, Plan};
use super::progress::Progress;
use super::rules::{CutRules, Rgb, Verdict};
use crate::error::{PlanError, Problems, Result};

mod binary;
mod blocks;
mod fresh;
mod geometry;
mod layout;
mod loops;
mod placing;
mod source;
mod splice;
mod text;
mod values;
mod write;

pub(crate) use fresh::with_table_handles;

use blocks::{BlockCut, EntityRef, Insertion};
use geometry::{
    MAX_COORDINATE_MM, Piece, arc, circle, close_chains, ellipse, in_plane, line, note_splines,
    polyline_entity, spline,
};
use source::Source;
use write::Changes;

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
    /// One closed `LWPOLYLINE` in model space, edited in place.
    LwPolyline(usize),
    /// One `CIRCLE` in model space, edited in place.
    Circle(usize),
    /// Model-space entities replaced by a new polyline (chains, `POLYLINE`, `ELLIPSE`, `SPLINE`).
    Replace(Vec<usize>),
    /// Drawn inside a block: taken out of it, and drawn as a new model-space polyline.
    Block(Box<BlockCut>),
}

/// Dilate the cuts of a DXF plan (file bytes, ASCII or binary DXF). Returns the new file, ASCII
/// DXF in the drawing's own version.
pub fn dilate_dxf(
    bytes: &[u8],
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    let source = Source::read(bytes, &opts.progress)?;
    let (changes, mut summary) = dilate_loaded(source.drawing, kerf, opts, source.found)?;
    if source.binary {
        summary.notes.push(
            "the binary DXF was written as ASCII DXF (the same entities, group codes and handles; every program that reads DXF reads both)"
                .into(),
        );
    }
    let record = summary
        .compensation_applied
        .as_ref()
        .map(|applied| applied.dxf_record("\n"));
    let out = changes
        .write(&source.text, &source.layout, record.as_deref())
        .map_err(|why| {
            bad(format!(
                "cannot write the dilated DXF: {why}; nothing was written"
            ))
        })?;
    Ok((out, summary))
}

/// [`dilate_dxf`] on bytes it owns (the file read by the command).
pub(crate) fn dilate_dxf_owned(
    bytes: Vec<u8>,
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    dilate_dxf(&bytes, kerf, opts)
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
    let source = Source::read(bytes, &opts.progress)?;
    let plan = DxfPlan::new(source.drawing, opts, source.found)?;
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

/// Where a cut entity sits: in model space (edited in place there), or inside a block (upper-case
/// name) reached through `INSERT`s (`via`, outermost first), with its properties, the block's own
/// `0`-layer and `BYBLOCK` ones resolved.
#[derive(Clone, Copy)]
enum Place<'t> {
    Model,
    Block {
        common: &'t EntityCommon,
        block: &'t str,
        via: &'t [EntityRef],
    },
}

impl Place<'_> {
    /// The origin of a closed contour read here from the entity `index` (in model space or its
    /// block): `in_model` of the index in model space.
    fn origin(&self, index: usize, in_model: impl FnOnce(usize) -> Origin) -> Origin {
        match *self {
            Place::Model => in_model(index),
            Place::Block { common, block, via } => Origin::Block(Box::new(BlockCut {
                common: common.clone(),
                block: block.to_owned(),
                entities: vec![index],
                via: via.to_vec(),
            })),
        }
    }
}

impl DxfPlan<'_> {
    /// The units assumed (`--units`) for a drawing that does not say them, to write into its
    /// `$INSUNITS`; from R2000 only, the first version that has the variable (noted otherwise).
    fn units_to_write(&self, summary: &mut PlanSummary) -> Option<Units> {
        if units_known(&self.drawing).is_some() {
            return None;
        }
        let units = self.opts.assume_units.and_then(|u| match u {
            AssumedUnits::Mm => Some(Units::Millimeters),
            AssumedUnits::Cm => Some(Units::Centimeters),
            AssumedUnits::In => Some(Units::Inches),
            _ => None,
        })?;
        if self.drawing.header.version < AcadVersion::R2000 {
            summary.notes.push(
                "the units assumed are not written into the drawing: $INSUNITS came with R2000, and the drawing keeps its version (give --units again to read the output)"
                    .into(),
            );
            return None;
        }
        Some(units)
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
        self.assumed = self.units_to_write(&mut plan.summary);
        let mut blocks = blocks::Expansion::new(&self.drawing);
        let entities: Vec<&Entity> = self.drawing.entities().collect();
        let mut problems = Problems::default();
        let pieces = self.read_entities(&entities, &mut blocks, &mut plan, &mut problems);
        blocks.finish(&mut plan.summary, &mut problems);
        let name_of = |k: usize| label(entities[k]);
        let origin_of = |list: &[usize]| Origin::Replace(list.to_vec());
        close_chains(pieces, &name_of, &origin_of, &mut plan, &mut problems);
        problems.into_error(PlanError::Dxf)?;
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
                    Origin::Block(cut) => &cut.common,
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
        Ok(Changes {
            drawing: self.drawing,
            scale: self.scale,
            cuts,
            assumed: self.assumed,
        })
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
        problems: &mut Problems,
    ) -> Vec<Piece> {
        let mut pieces: Vec<Piece> = Vec::new();
        let model = Affine::scale(self.scale);
        for (i, &e) in entities.iter().enumerate() {
            if !self.drawn(&e.common, &mut plan.summary) {
                continue;
            }
            if let EntityType::Insert(ins) = &e.specific {
                let insertion = Insertion {
                    by: &e.common,
                    ins,
                    at: EntityRef::model(i),
                    label: &label(e),
                };
                self.expand_insert(insertion, &model, 0, blocks, plan, problems);
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
            match self.read_checked(e, Place::Model, i, &model, &mut plan.summary) {
                Ok(Read::Closed(pl, origin)) => plan.cut(pl, label(e), origin),
                Ok(Read::Piece(piece)) => pieces.push(piece),
                Ok(Read::Nothing) => {}
                Err(problem) => problems.push(problem),
            }
        }
        pieces
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
                let origin = place.origin(index, Origin::LwPolyline);
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
                let origin = place.origin(index, |i| Origin::Replace(vec![i]));
                Ok(polyline_entity(&verts, pl.is_closed(), &f, origin, index))
            }
            EntityType::Line(l) => Ok(line(l, frame, index)),
            EntityType::Arc(a) if a.radius.is_nan() || a.radius <= 0.0 => {
                // Nothing to cut, but said: a drawing's arc of radius 0 is a slip of the CAD.
                summary.notes.push(format!(
                    "{} has radius {}: nothing to cut, left out",
                    label(e),
                    kerfmeter_protocol::Shown(a.radius)
                ));
                Ok(Read::Nothing)
            }
            EntityType::Arc(a) => Ok(arc(a, &in_plane(e, &a.normal, frame)?, place, index)),
            EntityType::Circle(c) => Ok(circle(c, &in_plane(e, &c.normal, frame)?, place, index)),
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

/// The colour an entity is drawn in (its layer's when it says `BYLAYER` or `BYBLOCK`).
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

#[cfg(test)]
mod tests;
