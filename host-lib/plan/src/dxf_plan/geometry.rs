//! The geometry of DXF cut entities, read into contours in document mm: polylines with bulges
//! (mapped through a block's frame: arcs stay arcs under a similarity, become biarcs under unequal
//! scales), `LINE`, `ARC`, `CIRCLE`, `ELLIPSE` and `SPLINE` (biarcs within
//! [`CURVE_TOLERANCE_MM`]), and open pieces sorted into closed loops and open paths
//! ([`super::loops`]).

use cavalier_contours::polyline::{PlineCreation, PlineSource, PlineSourceMut, PlineVertex};
use dxf::Vector;
use dxf::entities::Entity;

use super::{JOIN_MM, Origin, Place, Read, label, loops, mirrored};
use crate::error::Problems;
use crate::geom::{Affine, CURVE_TOLERANCE_MM, PathSink, Pline, V2, arc_geom, fit_biarcs, v2};
use crate::nurbs::Nurbs;
use crate::outcome::PlanSummary;
use crate::pipeline::{MAX_CUT_VERTICES, Plan};

/// An open piece of a cut: vertices in mm (the last one's bulge unused), its entity.
#[derive(Debug, Clone)]
pub(super) struct Piece {
    pub vertices: Vec<PlineVertex<f64>>,
    pub entities: Vec<usize>,
}

impl Piece {
    pub(super) fn start(&self) -> V2 {
        let v = self.vertices[0];
        v2(v.x, v.y)
    }

    pub(super) fn end(&self) -> V2 {
        let v = self.vertices[self.vertices.len() - 1];
        v2(v.x, v.y)
    }

    pub(super) fn reversed(mut self) -> Piece {
        let n = self.vertices.len();
        let bulges: Vec<f64> = self.vertices.iter().map(|v| v.bulge).collect();
        self.vertices.reverse();
        for i in 0..n {
            // The segment now leaving vertex i was the one leaving vertex n−2−i, reversed.
            self.vertices[i].bulge = if i + 1 < n { -bulges[n - 2 - i] } else { 0.0 };
        }
        self
    }

    pub(super) fn append(&mut self, other: Piece) {
        let mut it = other.vertices.into_iter();
        let first = it.next().expect("a piece has vertices");
        if let Some(last) = self.vertices.last_mut() {
            last.bulge = first.bulge;
        }
        self.vertices.extend(it);
        self.entities.extend(other.entities);
    }
}

/// Say once that splines were approximated.
pub(super) fn note_splines(summary: &mut PlanSummary) {
    const NOTE: &str = "SPLINEs were approximated by circular arcs";
    if !summary.notes.iter().any(|n| n.starts_with(NOTE)) {
        summary.notes.push(format!(
            "{NOTE} within {} µm of the curve",
            CURVE_TOLERANCE_MM * 1e3
        ));
    }
}

/// A polyline entity's vertices (x, y, bulge, drawn in `frame`) read as a contour or a piece.
pub(super) fn polyline_entity(
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
pub(super) const CURVE_JOIN_MM: f64 = 1e-7;

/// Coordinates further from the origin than this (mm) are refused: 10 km is no laser bed, and
/// such numbers are a unit mistake or a damaged file.
pub(super) const MAX_COORDINATE_MM: f64 = 1e7;

/// The frame of an entity drawn in the plane with OCS normal `n`, inside `frame`: mirrored in x
/// when the normal is −z; a problem when it is neither +z nor −z.
pub(super) fn in_plane(e: &Entity, n: &Vector, frame: &Affine) -> Result<Affine, String> {
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
pub(super) fn map_vertices(
    frame: &Affine,
    verts: &[(f64, f64, f64)],
    closed: bool,
) -> Vec<PlineVertex<f64>> {
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

pub(super) fn line(l: &dxf::entities::Line, frame: &Affine, i: usize) -> Read {
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

pub(super) fn arc(a: &dxf::entities::Arc, frame: &Affine, place: Place, i: usize) -> Read {
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
        Read::Closed(pl, place.origin(i, |i| Origin::Replace(vec![i])))
    } else {
        let (q0, q1) = (at(s), at(s + sweep));
        let verts = [(q0.0, q0.1, (sweep / 4.0).tan()), (q1.0, q1.1, 0.0)];
        Read::Piece(Piece {
            vertices: map_vertices(frame, &verts, false),
            entities: vec![i],
        })
    }
}

pub(super) fn circle(c: &dxf::entities::Circle, frame: &Affine, place: Place, i: usize) -> Read {
    if c.radius.is_nan() || c.radius <= 0.0 {
        return Read::Nothing;
    }
    let verts = [
        (c.center.x + c.radius, c.center.y, 1.0),
        (c.center.x - c.radius, c.center.y, 1.0),
    ];
    let pl = closed_pline(map_vertices(frame, &verts, true));
    Read::Closed(pl, place.origin(i, Origin::Circle))
}

pub(super) fn closed_pline(verts: Vec<PlineVertex<f64>>) -> Pline {
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
pub(super) fn ellipse_span(t0: f64, t1: f64) -> (f64, f64) {
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
pub(super) fn ellipse(el: &dxf::entities::Ellipse, frame: &Affine, place: Place, i: usize) -> Read {
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

/// A `SPLINE` (its control points, weights and knots; see the `nurbs` module), by biarcs within
/// [`CURVE_TOLERANCE_MM`]. A spline given by fit points alone is refused.
pub(super) fn spline(
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
pub(super) fn curve_read(sink: PathSink, closed: bool, place: Place, i: usize) -> Read {
    match sink.finish().into_iter().next() {
        Some(sub) => {
            let is_closed = closed || sub.pline.is_closed();
            let verts = sub.pline.iter_vertexes().collect();
            polyline_read(
                verts,
                is_closed,
                place.origin(i, |i| Origin::Replace(vec![i])),
                i,
            )
        }
        None => Read::Nothing,
    }
}

/// Sort the open pieces into closed loops, which are cuts (named by `name_of` their first
/// entity, their origin made by `origin_of` their entities), and open paths, by the rule of
/// [`super::loops`]; where cut lines branch, each junction is a problem (the plan is refused).
/// Returns the entities of the closed loops.
pub(super) fn close_chains(
    pieces: Vec<Piece>,
    name_of: &dyn Fn(usize) -> String,
    origin_of: &dyn Fn(&[usize]) -> Origin,
    plan: &mut Plan<Origin>,
    problems: &mut Problems,
) -> Vec<usize> {
    let entities_of: Vec<usize> = pieces.iter().map(|p| p.entities[0]).collect();
    let sorted = loops::sort(pieces);
    for junction in &sorted.junctions {
        let names: Vec<String> = junction
            .pieces
            .iter()
            .map(|&k| name_of(entities_of[k]))
            .collect();
        problems.push(junction_problem(junction.at_mm, &names));
    }
    let chain_name = |chain: &Piece| {
        let first = name_of(chain.entities[0]);
        if chain.entities.len() == 1 {
            first
        } else {
            format!("chain of {} entities from {first}", chain.entities.len())
        }
    };
    let mut closed = Vec::new();
    for chain in sorted.loops {
        let n = chain.vertices.len();
        if (chain.start() - chain.end()).length() <= JOIN_MM && n > 2 {
            let pl = closed_pline(chain.vertices[..n - 1].to_vec());
            plan.cut(pl, chain_name(&chain), origin_of(&chain.entities));
            closed.extend_from_slice(&chain.entities);
        } else {
            plan.open_path(chain_name(&chain), chain.start(), chain.end());
        }
    }
    for chain in sorted.open {
        plan.open_path(chain_name(&chain), chain.start(), chain.end());
    }
    closed
}

/// Why cut lines that branch are refused, and what to do.
fn junction_problem(at_mm: V2, names: &[String]) -> String {
    let shown = names.len().min(4);
    let mut list = names[..shown].join(", ");
    if names.len() > shown {
        list.push_str(&format!(" and {} more", names.len() - shown));
    }
    format!(
        "cut lines branch at ({:.3}, {:.3}) mm, where {} cut pieces meet ({list}): a cut outline \
         must be one closed loop, and which loops are meant here cannot be told (lines across an \
         outline, or outlines sharing an edge); put construction and engraving lines on a layer \
         or colour that is not cut (--cut-layer, --cut-color choose what is), or draw each part's \
         outline as one closed loop",
        at_mm.x,
        at_mm.y,
        names.len()
    )
}

/// Whether an entity's OCS normal `n` is mirrored (−z) or not (+z); a problem when it is neither.
pub(super) fn plane(e: &Entity, n: &Vector) -> Result<bool, String> {
    mirrored(n).ok_or_else(|| {
        format!(
            "{} is not drawn in the XY plane (extrusion direction {:?}); flatten the drawing",
            label(e),
            (n.x, n.y, n.z)
        )
    })
}

/// A polyline's vertices (mm) as a closed contour (closed by flag, or by ending where it starts)
/// or an open piece.
pub(super) fn polyline_read(
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

/// Centre and radius when a closed polyline is one full circle.
pub(super) fn as_circle(p: &Pline) -> Option<(V2, f64)> {
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
