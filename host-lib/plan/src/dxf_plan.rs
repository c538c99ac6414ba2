//! DXF plans: read with the `dxf` crate, dilate the cuts, write the drawing back.
//!
//! **Units** come from `$INSUNITS` (mm, cm, m, inches, feet, µm, …). A drawing with `$INSUNITS` 0
//! ("unitless", also every R12 file) is refused as *unknown units* unless the caller says what one
//! unit is ([`AssumedUnits`], `--units`). Document space is the drawing's own frame (y up), in mm;
//! a kerf map is looked up at those coordinates.
//!
//! **Cut geometry** (model space only; which entities are cuts: [`super::rules`]):
//!
//! * `LWPOLYLINE` and 2-D `POLYLINE` with bulges (closed by flag, or by ending where they start),
//! * `CIRCLE`, `ARC`, `LINE`, and `ELLIPSE` (a circular one exactly, others by biarcs),
//! * open pieces (`LINE`, `ARC`, open polylines) whose ends meet within 0.1 µm are joined into
//!   closed chains, in either direction.
//!
//! Entities drawn with a mirrored extrusion direction (0, 0, −1), as some CAD programs write
//! mirrored arcs, are handled; other non-planar entities are refused. A cut `SPLINE` is refused
//! (convert it to a polyline first); block references (`INSERT`) pass through undilated (explode
//! blocks to dilate their contents).
//!
//! **Writing.** A closed `LWPOLYLINE` gets its new vertices in place (handle, layer, colour,
//! extended data kept); a `CIRCLE` stays a `CIRCLE` with the new radius; a chain of pieces (and an
//! old-style `POLYLINE` or an `ELLIPSE`) is replaced by one closed `LWPOLYLINE` with bulges that
//! takes over the first piece's layer, colour, linetype and lineweight. Everything else is written
//! back as read. A drawing older than R14 (which has no `LWPOLYLINE`) is written as R2000. What was
//! applied is recorded in `999` comments at the top of the file (see
//! [`compensation`]).

use std::collections::HashMap;
use std::io::Cursor;

use cavalier_contours::polyline::{PlineSource, PlineSourceMut, PlineVertex};
use dxf::entities::{Entity, EntityType, LwPolyline};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, LwPolylineVertex, Point, Vector};

use super::compensation::{self, FoundCompensation, IfCompensated};
use super::dilate::KerfSource;
use super::geom::{PathSink, Pline, V2, arc_geom, v2};
use super::outcome::{AssumedUnits, CutGroup, CutPath, PlanSummary};
use super::pipeline::{self, Format, Plan};
use super::progress::{Progress, Stage};
use super::rules::{CutRules, Rgb, Verdict};
use crate::error::{PlanError, Problems, Result};

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
    /// Replaced by a new `LWPOLYLINE` (chains, `POLYLINE`, `ELLIPSE`).
    Replace(Vec<usize>),
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
    let found = compensation::find_in_dxf(bytes);
    opts.progress.start(Stage::Reading, 0);
    let drawing = Drawing::load(&mut Cursor::new(bytes))
        .map_err(|e| bad(format!("not a readable DXF file: {e}")))?;
    let (drawing, summary) = dilate_loaded(drawing, kerf, opts, found)?;
    // The output is about the input's size, a little more: no copying as it grows.
    let mut saved = Vec::with_capacity(bytes.len() + bytes.len() / 2);
    drawing
        .save(&mut saved)
        .map_err(|e| bad(format!("cannot write the DXF: {e}")))?;
    // The record goes first, as `999` comments (the `dxf` crate writes none).
    let mut out = Vec::with_capacity(saved.len() + 512);
    if let Some(applied) = &summary.compensation_applied {
        let eol = if saved.windows(2).take(64).any(|w| w == b"\r\n") {
            "\r\n"
        } else {
            "\n"
        };
        out.extend_from_slice(applied.dxf_record(eol).as_bytes());
    }
    out.extend_from_slice(&saved);
    Ok((out, summary))
}

/// mm per drawing unit.
fn units_mm(
    drawing: &Drawing,
    assume: Option<AssumedUnits>,
    summary: &mut PlanSummary,
) -> Result<f64> {
    let known = match drawing.header.default_drawing_units {
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
    };
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
                "the drawing does not say its units; one unit taken as {:?} ({} mm) as asked",
                u,
                u.mm()
            ));
            Ok(u.mm())
        }
        (None, None) => Err(PlanError::Units(format!(
            "unknown units: $INSUNITS is {:?} (R12 files and many exports leave it unset); save the drawing in mm, or say what one unit is with --units mm|cm|in",
            drawing.header.default_drawing_units
        ))),
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
    dilate_loaded(drawing, kerf, opts, None)
}

/// Dilate a loaded drawing whose file recorded the compensation `found`.
fn dilate_loaded(
    drawing: Drawing,
    kerf: &KerfSource,
    opts: &DxfOptions,
    found: Option<FoundCompensation>,
) -> Result<(Drawing, PlanSummary)> {
    pipeline::dilate_plan(
        DxfPlan {
            drawing,
            opts,
            scale: 1.0,
            found,
        },
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
    let found = compensation::find_in_dxf(bytes);
    opts.progress.start(Stage::Reading, 0);
    let drawing = Drawing::load(&mut Cursor::new(bytes))
        .map_err(|e| bad(format!("not a readable DXF file: {e}")))?;
    let plan = DxfPlan {
        drawing,
        opts,
        scale: 1.0,
        found,
    };
    pipeline::dilate_plan_cuts(plan, kerf, opts.if_compensated, &opts.rules, &opts.progress)
}

/// A DXF drawing in the plan pipeline.
struct DxfPlan<'o> {
    drawing: Drawing,
    opts: &'o DxfOptions,
    /// mm per drawing unit (set by `read`).
    scale: f64,
    /// The compensation the file records (read from its comments before loading).
    found: Option<FoundCompensation>,
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

impl Format for DxfPlan<'_> {
    type Origin = Origin;
    type Output = Drawing;

    fn read(&mut self) -> Result<Plan<Origin>> {
        let mut plan = Plan::new("dxf");
        self.scale = units_mm(&self.drawing, self.opts.assume_units, &mut plan.summary)?;
        plan.summary.mm_per_unit = self.scale;
        plan.summary.compensation_found = self.found.take();
        let entities: Vec<&Entity> = self.drawing.entities().collect();
        let pieces = self.read_entities(&entities, &mut plan)?;
        self.close_chains(&entities, pieces, &mut plan);
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
                let first = match &cut.origin {
                    Origin::LwPolyline(i) | Origin::Circle(i) => *i,
                    Origin::Replace(list) => list[0],
                };
                let e = entities[first];
                CutGroup {
                    color: resolve_color(e, &layer_colors),
                    layer: Some(e.common.layer.clone()),
                }
            })
            .collect()
    }

    fn write(mut self, plan: &mut Plan<Origin>, dilated: Vec<Pline>) -> Result<Drawing> {
        let mut removed = vec![false; self.drawing.entities().count()];
        let mut added: Vec<Entity> = Vec::new();
        {
            // Each entity by index, found once (not by counting from the first every time).
            let mut slots: Vec<&mut Entity> = self.drawing.entities_mut().collect();
            for (cut, d) in plan.cuts.iter().zip(dilated) {
                plan.summary.changed_elements += 1;
                write_cut(
                    &mut slots,
                    self.scale,
                    &cut.origin,
                    &d,
                    &mut removed,
                    &mut added,
                );
            }
        }
        remove_entities(&mut self.drawing, &removed);
        for e in added {
            self.drawing.add_entity(e);
        }
        if self.drawing.header.version < AcadVersion::R14 {
            self.drawing.header.version = AcadVersion::R2000;
            plan.summary
                .notes
                .push("the drawing was older than R14 (no LWPOLYLINE); written as R2000".into());
        }
        Ok(self.drawing)
    }
}

impl DxfPlan<'_> {
    /// Classify every entity; read the cuts into `plan` (closed ones) or the returned open pieces.
    fn read_entities(&self, entities: &[&Entity], plan: &mut Plan<Origin>) -> Result<Vec<Piece>> {
        let layer_colors: HashMap<String, dxf::Color> = self
            .drawing
            .layers()
            .map(|l| (l.name.to_uppercase(), l.color.clone()))
            .collect();
        let mut pieces: Vec<Piece> = Vec::new();
        let mut problems = Problems::default();
        for (i, &e) in entities.iter().enumerate() {
            if !self.is_cut(e, &layer_colors, &mut plan.summary) {
                continue;
            }
            let read = match &e.specific {
                EntityType::Insert(_) => {
                    plan.summary
                        .pass("INSERT (block contents are not dilated: explode blocks first)");
                    continue;
                }
                EntityType::LwPolyline(_)
                | EntityType::Polyline(_)
                | EntityType::Line(_)
                | EntityType::Arc(_)
                | EntityType::Circle(_)
                | EntityType::Ellipse(_)
                | EntityType::Spline(_) => {
                    plan.summary.cut_elements += 1;
                    self.read_cut(i, e)
                }
                other => {
                    plan.summary
                        .pass(format!("{} (not a cut geometry)", type_name(other)));
                    continue;
                }
            };
            match read {
                Ok(Read::Closed(pl, origin)) => plan.cut(pl, label(e), origin),
                Ok(Read::Piece(piece)) => pieces.push(piece),
                Ok(Read::Nothing) => {}
                Err(problem) => problems.push(problem),
            }
        }
        problems.into_error(PlanError::Dxf)?;
        Ok(pieces)
    }

    /// Whether an entity is a cut by the rules; counts it as passed through when not.
    fn is_cut(
        &self,
        e: &Entity,
        layer_colors: &HashMap<String, dxf::Color>,
        summary: &mut PlanSummary,
    ) -> bool {
        if e.common.is_in_paper_space {
            summary.pass("paper space");
            return false;
        }
        if !e.common.is_visible {
            summary.pass("invisible");
            return false;
        }
        let color = resolve_color(e, layer_colors);
        let lw = (e.common.lineweight_enum_value > 0)
            .then(|| f64::from(e.common.lineweight_enum_value) / 100.0);
        if let Verdict::Keep(reason) = self.opts.rules.classify_dxf(color, &e.common.layer, lw) {
            summary.pass(format!("{} ({reason})", type_name(&e.specific)));
            return false;
        }
        true
    }

    /// Read one cut entity (`i` in the entity list); a problem when it cannot be dilated.
    fn read_cut(&self, i: usize, e: &Entity) -> Result<Read, String> {
        match &e.specific {
            EntityType::LwPolyline(lw) => {
                let m = plane(e, &lw.extrusion_direction)?;
                let verts = lw.vertices.iter().map(|v| (v.x, v.y, v.bulge));
                Ok(self.polyline(verts, m, lw.is_closed(), Origin::LwPolyline(i), i))
            }
            EntityType::Polyline(pl) => {
                if pl.is_3d_polyline() || pl.is_3d_polygon_mesh() || pl.is_polyface_mesh() {
                    return Err(format!(
                        "{} is a 3-D polyline or mesh; a cut must be a 2-D polyline",
                        label(e)
                    ));
                }
                let m = plane(e, &pl.normal)?;
                let verts = pl.vertices().map(|v| (v.location.x, v.location.y, v.bulge));
                Ok(self.polyline(verts, m, pl.is_closed(), Origin::Replace(vec![i]), i))
            }
            EntityType::Line(l) => Ok(self.line(l, i)),
            EntityType::Arc(a) => Ok(self.arc(a, plane(e, &a.normal)?, i)),
            EntityType::Circle(c) => Ok(self.circle(c, plane(e, &c.normal)?, i)),
            EntityType::Ellipse(el) => {
                if plane(e, &el.normal).is_err() {
                    return Err(format!("{} is not drawn in the XY plane", label(e)));
                }
                Ok(self.ellipse(el, i))
            }
            EntityType::Spline(_) => Err(format!(
                "{} is a cut, but splines cannot be dilated here: convert it to a polyline in the CAD program, or put it on a layer or colour that is not a cut",
                label(e)
            )),
            _ => Ok(Read::Nothing),
        }
    }

    /// A drawing point in document mm, mirrored in x when the entity's OCS is.
    fn point(&self, x: f64, y: f64, mirrored: bool) -> V2 {
        v2(if mirrored { -x } else { x } * self.scale, y * self.scale)
    }

    /// A `LWPOLYLINE` or 2-D `POLYLINE` from its vertices (x, y, bulge in drawing units).
    fn polyline(
        &self,
        verts: impl Iterator<Item = (f64, f64, f64)>,
        m: bool,
        closed_flag: bool,
        origin: Origin,
        index: usize,
    ) -> Read {
        let verts = verts
            .map(|(x, y, bulge)| {
                let q = self.point(x, y, m);
                PlineVertex::new(q.x, q.y, if m { -bulge } else { bulge })
            })
            .collect();
        polyline_read(verts, closed_flag, origin, index)
    }

    fn line(&self, l: &dxf::entities::Line, i: usize) -> Read {
        let (a, b) = (
            self.point(l.p1.x, l.p1.y, false),
            self.point(l.p2.x, l.p2.y, false),
        );
        if (a - b).length() <= JOIN_MM {
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

    fn arc(&self, a: &dxf::entities::Arc, m: bool, i: usize) -> Read {
        let (s, t) = (a.start_angle.to_radians(), a.end_angle.to_radians());
        let mut sweep = (t - s).rem_euclid(std::f64::consts::TAU);
        if sweep < 1e-12 {
            sweep = std::f64::consts::TAU;
        }
        let at = |ang: f64| {
            self.point(
                a.center.x + a.radius * ang.cos(),
                a.center.y + a.radius * ang.sin(),
                m,
            )
        };
        let (q0, q1) = (at(s), at(s + sweep));
        let bulge = (sweep / 4.0).tan() * if m { -1.0 } else { 1.0 };
        if sweep >= std::f64::consts::TAU - 1e-9 {
            // A full-circle arc: a circle.
            let qm = at(s + sweep / 2.0);
            let mut pl = Pline::new_closed();
            pl.add(q0.x, q0.y, bulge.signum());
            pl.add(qm.x, qm.y, bulge.signum());
            Read::Closed(pl, Origin::Replace(vec![i]))
        } else {
            Read::Piece(Piece {
                vertices: vec![
                    PlineVertex::new(q0.x, q0.y, bulge),
                    PlineVertex::new(q1.x, q1.y, 0.0),
                ],
                entities: vec![i],
            })
        }
    }

    fn circle(&self, c: &dxf::entities::Circle, m: bool, i: usize) -> Read {
        let q0 = self.point(c.center.x + c.radius, c.center.y, m);
        let q1 = self.point(c.center.x - c.radius, c.center.y, m);
        let mut pl = Pline::new_closed();
        pl.add(q0.x, q0.y, 1.0);
        pl.add(q1.x, q1.y, 1.0);
        Read::Closed(pl, Origin::Circle(i))
    }

    /// An `ELLIPSE` (or elliptic arc), by biarcs.
    fn ellipse(&self, el: &dxf::entities::Ellipse, i: usize) -> Read {
        let scale = self.scale;
        let mj = v2(el.major_axis.x, el.major_axis.y);
        // Minor axis = ratio · (normal × major).
        let mn = v2(-mj.y, mj.x).scale(el.minor_axis_ratio * el.normal.z.signum());
        let c = v2(el.center.x, el.center.y);
        let (t0, mut t1) = (el.start_parameter, el.end_parameter);
        if t1 <= t0 {
            t1 += std::f64::consts::TAU;
        }
        let full = (t1 - t0 - std::f64::consts::TAU).abs() < 1e-9;
        let f = |u: f64| {
            let t = t0 + (t1 - t0) * u;
            let pos = c + mj.scale(t.cos()) + mn.scale(t.sin());
            let d = (mn.scale(t.cos()) - mj.scale(t.sin())).scale(t1 - t0);
            (pos.scale(scale), d.scale(scale))
        };
        let mut sink = PathSink::new(1e-9, 1e-12);
        sink.move_to(f(0.0).0);
        sink.curve(&f, f(1.0).0);
        if full {
            sink.close();
        }
        match sink.finish().into_iter().next() {
            Some(sub) if sub.pline.is_closed() => Read::Closed(sub.pline, Origin::Replace(vec![i])),
            Some(sub) => Read::Piece(Piece {
                vertices: sub.pline.iter_vertexes().collect(),
                entities: vec![i],
            }),
            None => Read::Nothing,
        }
    }

    /// Join the open pieces into chains: the closed ones are cuts, the rest open paths.
    fn close_chains(&self, entities: &[&Entity], pieces: Vec<Piece>, plan: &mut Plan<Origin>) {
        for chain in join_pieces(pieces) {
            let first = entities[chain.entities[0]];
            let name = if chain.entities.len() == 1 {
                label(first)
            } else {
                format!(
                    "chain of {} entities from {}",
                    chain.entities.len(),
                    label(first)
                )
            };
            if (chain.start() - chain.end()).length() <= JOIN_MM && chain.vertices.len() > 2 {
                let mut pl = Pline::new_closed();
                let n = chain.vertices.len();
                for v in &chain.vertices[..n - 1] {
                    pl.add_vertex(*v);
                }
                plan.cut(pl, name, Origin::Replace(chain.entities.clone()));
            } else {
                plan.open_path(name, chain.start(), chain.end());
            }
        }
    }
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
    let to_units = |x: f64| x / scale;
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
                    added.push(new_lwpolyline(entity, d, scale));
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
            added.push(new_lwpolyline(slots[list[0]], d, scale));
        }
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

fn resolve_color(e: &Entity, layers: &HashMap<String, dxf::Color>) -> Option<Rgb> {
    if e.common.color_24_bit != 0 {
        let c = e.common.color_24_bit;
        return Some(Rgb((c >> 16) as u8, (c >> 8) as u8, c as u8));
    }
    let c = if e.common.color.is_by_layer() || e.common.color.is_by_block() {
        layers.get(&e.common.layer.to_uppercase()).cloned()?
    } else {
        e.common.color.clone()
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
    let mut ends: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, p) in pieces.iter().enumerate() {
        ends.entry(key(p.start())).or_default().push(i);
        ends.entry(key(p.end())).or_default().push(i);
    }
    let mut used = vec![false; pieces.len()];
    let near = |q: V2, used: &[bool], ends: &HashMap<(i64, i64), Vec<usize>>| -> Option<usize> {
        let (kx, ky) = key(q);
        for dx in -1..=1 {
            for dy in -1..=1 {
                if let Some(list) = ends.get(&(kx + dx, ky + dy)) {
                    for &j in list {
                        if !used[j]
                            && ((pieces[j].start() - q).length() <= JOIN_MM
                                || (pieces[j].end() - q).length() <= JOIN_MM)
                        {
                            return Some(j);
                        }
                    }
                }
            }
        }
        None
    };
    let mut chains = Vec::new();
    for i in 0..pieces.len() {
        if used[i] {
            continue;
        }
        used[i] = true;
        let mut chain = pieces[i].clone();
        // Forward.
        while (chain.end() - chain.start()).length() > JOIN_MM {
            let Some(j) = near(chain.end(), &used, &ends) else {
                break;
            };
            used[j] = true;
            let next = if (pieces[j].start() - chain.end()).length() <= JOIN_MM {
                pieces[j].clone()
            } else {
                pieces[j].clone().reversed()
            };
            chain.append(next);
        }
        // Backward, for chains that did not close: the pieces before it, nearest first (joined
        // at the end, so that each vertex is copied once).
        let mut before: Vec<Piece> = Vec::new();
        let mut start = chain.start();
        while (chain.end() - start).length() > JOIN_MM {
            let Some(j) = near(start, &used, &ends) else {
                break;
            };
            used[j] = true;
            let prev = if (pieces[j].end() - start).length() <= JOIN_MM {
                pieces[j].clone()
            } else {
                pieces[j].clone().reversed()
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

fn lw_vertices(p: &Pline, scale: f64) -> Vec<LwPolylineVertex> {
    p.iter_vertexes()
        .map(|v| LwPolylineVertex {
            x: v.x / scale,
            y: v.y / scale,
            bulge: v.bulge,
            ..LwPolylineVertex::default()
        })
        .collect()
}

fn new_lwpolyline(like: &Entity, p: &Pline, scale: f64) -> Entity {
    let mut lw = LwPolyline {
        vertices: lw_vertices(p, scale),
        ..LwPolyline::default()
    };
    lw.set_is_closed(true);
    let mut e = Entity::new(EntityType::LwPolyline(lw));
    e.common.layer = like.common.layer.clone();
    e.common.color = like.common.color.clone();
    e.common.color_24_bit = like.common.color_24_bit;
    e.common.line_type_name = like.common.line_type_name.clone();
    e.common.lineweight_enum_value = like.common.lineweight_enum_value;
    e
}

#[cfg(test)]
mod tests {
    use super::*;
    use dxf::entities::{Circle, Line};

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
    fn a_cut_spline_is_refused() {
        let mut d = drawing(Units::Millimeters);
        let mut sp = Entity::new(EntityType::Spline(dxf::entities::Spline::default()));
        sp.common.color = dxf::Color::from_index(1);
        d.add_entity(sp);
        let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("SPLINE") && e.contains("polyline"), "{e}");
    }
}
