//! Dilating closed cut contours by half the kerf: the core, independent of file formats.
//!
//! The laser removes a strip of width k centred on the line it follows, so a part cut along its
//! nominal outline comes out k/2 too small all round. Cutting instead along the boundary of the
//! part's **Minkowski sum with a disk of radius k/2** (the beam is round) gives back the nominal
//! part exactly: every closed contour is offset by k/2 with *round joins* — outer contours grow,
//! holes shrink, and a part lying inside another part's hole (an island) grows again.
//!
//! * **Nesting** decides the sign: a contour's *depth* is the number of contours enclosing it.
//!   Even depth = the outer contour of a part, odd depth = a hole of the part it lies in directly.
//!   The direction each contour is drawn in does not matter (it is normalised for the offset and
//!   restored afterwards, so fill rules and cut order keep working).
//! * **Offsets** come from `cavalier_contours` (`parallel_offset`): lines stay lines, arcs stay
//!   arcs, convex corners get round joins (arcs of radius k/2), concave corners stay sharp. For a
//!   part with holes the contours can be offset one by one: outer contours move outwards and holes
//!   move into the hole, away from each other, so they never interact — provided they do not
//!   meet as drawn, which is checked (two holes of a part however close, even closer than the
//!   kerf, shrink apart).
//! * **Kerf per part**: each part (an outer contour with its holes) uses one kerf, the one given
//!   at the part's area centroid (with a kerf map, interpolated there).
//! * **Recompensation** ([`Offsetting::Recompensate`], [`dilate_with`]): a plan already offset by
//!   a burn moves by kerf/2 − burn instead, with its drawn corners kept sharp (see
//!   [`crate::recompensate`]). With a burn above kerf/2 that moves into the part's material —
//!   holes grow, outlines shrink — so a part's loops are checked again once offset: where its
//!   material is narrower than twice the move, they would overlap.
//!
//! * **Memory**: [`dilate_releasing_drawn`] (what the plan pipeline uses) frees each drawn contour
//!   as soon as it is offset, so a large plan's drawn and dilated geometry are not held at once.
//!
//! Problems are collected, not stopped at, and reported together (each with the contours' labels
//! and a position in mm): contours that cross themselves or each other (holes of one part
//! included: two holes side by side are compared with a spatial index of the holes, nesting only
//! compares a contour with the larger ones around it), a loop drawn twice, a hole narrower than the
//! kerf (it would vanish or split), a part whose outline would close around a void, loops of a
//! part that a recompensation would move into each other, and two parts
//! that would *merge* — closer than the kerf, so their dilated regions overlap (or share a cut
//! line). A notch open to the outside and narrower than the kerf simply fills in: no kerf
//! compensation can cut it.

use cavalier_contours::polyline::{PlineSource, PlineSourceMut};
use cavalier_contours::static_aabb2d_index::{StaticAABB2DIndex, StaticAABB2DIndexBuilder};
use kerfmeter_protocol::advice::{Advice, Advised};
use rayon::prelude::*;
use serde::Serialize;

use std::fmt;
use std::sync::Arc;

use super::geom::{Pline, V2, area_and_centroid, v2};
use crate::error::{PlanError, Problems, Result};
use crate::progress::{Progress, Stage};
use crate::recompensate;

/// Largest kerf accepted, µm (a sanity bound: real kerfs are 50–500 µm).
pub const MAX_KERF_UM: f64 = 5000.0;

/// A closed cut contour in document space, mm.
#[derive(Debug, Clone)]
pub struct Contour {
    /// The contour (closed; either direction).
    pub pline: Pline,
    /// How to name it in messages, e.g. `path "side-a"` or `LWPOLYLINE 2F`.
    pub label: String,
}

/// The kerf (µm) at a point of the bed (x, y in mm).
pub type KerfField = dyn Fn(f64, f64) -> f64 + Send + Sync;

/// Where the kerf comes from.
#[derive(Clone)]
pub enum KerfSource {
    /// The same kerf everywhere, µm.
    Uniform(f64),
    /// A kerf that varies over the bed, e.g. a bed map's: each part uses the kerf at its
    /// centroid.
    Map(Arc<KerfField>),
}

impl fmt::Debug for KerfSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KerfSource::Uniform(k) => f.debug_tuple("Uniform").field(k).finish(),
            KerfSource::Map(_) => f.write_str("Map(..)"),
        }
    }
}

impl KerfSource {
    /// The kerf at (`x_mm`, `y_mm`), µm.
    pub fn kerf_at_um(&self, x_mm: f64, y_mm: f64) -> f64 {
        match self {
            KerfSource::Uniform(k) => *k,
            KerfSource::Map(field) => field(x_mm, y_mm),
        }
    }

    /// Check a kerf value given by the user, µm.
    pub fn check_kerf_um(kerf_um: f64) -> Result<f64> {
        if kerf_um == 0.0 {
            // −0 is 0: a report says "by 0 µm".
            Ok(0.0)
        } else if kerf_um.is_finite() && (0.0..=MAX_KERF_UM).contains(&kerf_um) {
            Ok(kerf_um)
        } else {
            Err(PlanError::InvalidArgument(format!(
                "the kerf must be between 0 and {MAX_KERF_UM} µm, got {} µm",
                kerfmeter_protocol::Shown(kerf_um)
            )))
        }
    }
}

/// What a contour is within its part.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// The outline of a part (even nesting depth): grows.
    Outer,
    /// A hole of a part (odd nesting depth): shrinks.
    Hole,
}

/// A part: an outer contour and its holes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Part {
    /// Index of the outer contour.
    pub outer: usize,
    /// Indexes of its holes.
    pub holes: Vec<usize>,
    /// Nesting depth of the outer contour (0 = top level; 2, 4, … = an island in a hole).
    pub depth: usize,
    /// Area centroid of the part (outer minus holes), mm.
    pub centroid_mm: [f64; 2],
    /// Area of the part, mm².
    pub area_mm2: f64,
    /// The kerf used for this part, µm.
    pub kerf_um: f64,
}

/// The result of [`dilate`].
#[derive(Debug, Clone)]
pub struct Dilation {
    /// The dilated contours, one per input contour, drawn in the same direction as the input.
    pub contours: Vec<Pline>,
    /// Role of each input contour.
    pub roles: Vec<Role>,
    /// Part of each input contour (index into `parts`).
    pub part_of: Vec<usize>,
    /// The parts.
    pub parts: Vec<Part>,
}

fn at(p: V2) -> String {
    format!("({:.3}, {:.3}) mm", p.x, p.y)
}

fn first_point(p: &Pline) -> V2 {
    let v = p.at(0);
    v2(v.x, v.y)
}

/// A point where two polylines cross or touch, if they do.
fn crossing(a: &Pline, b: &Pline) -> Option<V2> {
    let found = a.find_intersects(b);
    if let Some(i) = found.basic_intersects.first() {
        return Some(i.point);
    }
    found.overlapping_intersects.first().map(|o| o.point1)
}

fn inside(p: &Pline, q: V2) -> bool {
    p.winding_number(q) != 0
}

#[derive(Clone, Copy)]
struct Bbox {
    min: V2,
    max: V2,
}

impl Bbox {
    fn of(p: &Pline) -> Bbox {
        let e = p.extents().expect("a contour has vertices");
        Bbox {
            min: v2(e.min_x, e.min_y),
            max: v2(e.max_x, e.max_y),
        }
    }

    fn contains(&self, o: &Bbox, eps: f64) -> bool {
        self.min.x <= o.min.x + eps
            && self.min.y <= o.min.y + eps
            && self.max.x >= o.max.x - eps
            && self.max.y >= o.max.y - eps
    }
}

fn index_of(boxes: &[Bbox]) -> Option<StaticAABB2DIndex<f64>> {
    if boxes.is_empty() {
        return None;
    }
    let mut b = StaticAABB2DIndexBuilder::new(boxes.len());
    for x in boxes {
        b.add(x.min.x, x.min.y, x.max.x, x.max.y);
    }
    b.build().ok()
}

/// How each contour is moved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Offsetting {
    /// By half the kerf, with round joins: the Minkowski sum with the beam's disk.
    Dilate,
    /// The plan is already offset by `burn_mm` (boxes.py's burn, or an earlier dilation): move
    /// every contour by half the kerf minus that, keeping the drawn corners sharp
    /// (see [`crate::recompensate`]).
    Recompensate {
        /// The offset already drawn, mm.
        burn_mm: f64,
    },
}

/// Dilate closed contours (document space, mm) by half the kerf, with nesting, per-part kerf and
/// the checks described in the module doc.
pub fn dilate(contours: &[Contour], kerf: &KerfSource) -> Result<Dilation> {
    dilate_with_progress(contours, kerf, Offsetting::Dilate, &Progress::default())
}

/// [`dilate`], with the contours moved as `how` says.
pub fn dilate_with(contours: &[Contour], kerf: &KerfSource, how: Offsetting) -> Result<Dilation> {
    dilate_with_progress(contours, kerf, how, &Progress::default())
}

/// [`dilate_with`], telling `progress` how many contours are offset.
///
/// The contours are independent, so the work on them (the checks of each, nesting, offsets, the
/// merge check) is spread over the cores with rayon; the results are put together in the input's
/// order, so they do not depend on the number of threads.
pub fn dilate_with_progress(
    contours: &[Contour],
    kerf: &KerfSource,
    how: Offsetting,
    progress: &Progress,
) -> Result<Dilation> {
    dilate_drawn(Drawn::Lent(contours), kerf, how, progress)
}

/// [`dilate_with_progress`], freeing each contour's drawn geometry (its polyline is left empty)
/// as soon as it is offset; the labels stay, for messages. Nothing after the offsets needs the
/// drawn geometry, and a large plan's drawn and dilated contours held at once were most of its
/// memory: this way the drawn ones go while the dilated ones are made. After an error the
/// contours may be partly emptied (those offset before it): the plan is not to be used again.
pub fn dilate_releasing_drawn(
    contours: &mut [Contour],
    kerf: &KerfSource,
    how: Offsetting,
    progress: &Progress,
) -> Result<Dilation> {
    dilate_drawn(Drawn::Given(contours), kerf, how, progress)
}

/// The drawn contours the kernel works on: lent (left as they are), or given (each one's
/// polyline freed once it is offset).
enum Drawn<'c> {
    Lent(&'c [Contour]),
    Given(&'c mut [Contour]),
}

impl Drawn<'_> {
    fn get(&self) -> &[Contour] {
        match self {
            Drawn::Lent(c) => c,
            Drawn::Given(c) => c,
        }
    }
}

fn dilate_drawn(
    mut drawn: Drawn,
    kerf: &KerfSource,
    how: Offsetting,
    progress: &Progress,
) -> Result<Dilation> {
    let contours = drawn.get();
    progress.start(Stage::Dilating, contours.len());
    let (areas, centroids) = check_each(contours)?;
    let (depth, parent) = nest(contours, &areas)?;
    let roles: Vec<Role> = depth
        .iter()
        .map(|d| if d % 2 == 0 { Role::Outer } else { Role::Hole })
        .collect();
    let (mut parts, part_index) = group_parts(&roles, &depth, &parent);
    check_holes(contours, &parts)?;
    kerf_per_part(&mut parts, contours, &areas, &centroids, kerf)?;
    let dilated = offset_all(&mut drawn, &roles, &parts, &part_index, how, progress)?;
    check_offset_loops(drawn.get(), &parts, &dilated, how)?;
    check_merges(drawn.get(), &parts, &dilated)?;
    Ok(Dilation {
        contours: dilated,
        roles,
        part_of: part_index,
        parts,
    })
}

/// Each contour on its own: closed, with an area, not crossing itself. Its signed area and
/// centroid.
fn check_each(contours: &[Contour]) -> Result<(Vec<f64>, Vec<V2>)> {
    let checked: Vec<(f64, V2, Option<String>)> = contours
        .par_iter()
        .map(|c| {
            let (a, cen) = area_and_centroid(&c.pline);
            let problem = if !c.pline.is_closed() || c.pline.vertex_count() < 2 || a.abs() < 1e-12
            {
                Some(format!(
                    "{} at {} encloses no area; remove it or draw it as an open line",
                    c.label,
                    at(first_point(&c.pline))
                ))
            } else if c.pline.scan_for_self_intersect() {
                Some(format!(
                    "{} at {} crosses itself; fix the drawing (each cut must be a simple closed line)",
                    c.label,
                    at(first_point(&c.pline))
                ))
            } else {
                None
            };
            (a, cen, problem)
        })
        .collect();
    let mut problems = Problems::default();
    let mut areas = Vec::with_capacity(checked.len());
    let mut centroids = Vec::with_capacity(checked.len());
    for (a, cen, problem) in checked {
        areas.push(a);
        centroids.push(cen);
        if let Some(p) = problem {
            problems.push(p);
        }
    }
    problems.cannot_dilate()?;
    Ok((areas, centroids))
}

/// Nesting: who encloses whom. Each contour's depth (how many contours enclose it) and parent
/// (the smallest one that does); contours that cross are problems.
pub(crate) fn nest(
    contours: &[Contour],
    areas: &[f64],
) -> Result<(Vec<usize>, Vec<Option<usize>>)> {
    let n = contours.len();
    let boxes: Vec<Bbox> = contours.par_iter().map(|c| Bbox::of(&c.pline)).collect();
    let Some(index) = &index_of(&boxes) else {
        return Ok((vec![0; n], vec![None; n]));
    };
    let found: Vec<Enclosers> = (0..n)
        .into_par_iter()
        .map(|i| enclosers(i, contours, areas, &boxes, index))
        .collect();
    let mut problems = Problems::default();
    let mut depth = Vec::with_capacity(n);
    let mut parent = Vec::with_capacity(n);
    for e in found {
        depth.push(e.depth);
        parent.push(e.parent);
        for p in e.problems {
            problems.push(p);
        }
    }
    problems.cannot_dilate()?;
    Ok((depth, parent))
}

/// What encloses one contour: how many contours, the smallest of them, and the contours it
/// crosses (as problems).
struct Enclosers {
    depth: usize,
    parent: Option<usize>,
    problems: Vec<String>,
}

/// The contours enclosing contour `i`, found among those whose boxes hold its first point.
fn enclosers(
    i: usize,
    contours: &[Contour],
    areas: &[f64],
    boxes: &[Bbox],
    index: &StaticAABB2DIndex<f64>,
) -> Enclosers {
    let p = first_point(&contours[i].pline);
    let mut found = Enclosers {
        depth: 0,
        parent: None,
        problems: Vec::new(),
    };
    for j in index.query(p.x, p.y, p.x, p.y) {
        if j == i || !boxes[j].contains(&boxes[i], 1e-9) || areas[j].abs() <= areas[i].abs() {
            continue;
        }
        // Each pair is looked at once: only the larger contour can enclose.
        if let Some(x) = crossing(&contours[i].pline, &contours[j].pline) {
            found.problems.push(format!(
                "{} and {} cross or touch at {}; cut lines must not meet",
                contours[i].label,
                contours[j].label,
                at(x)
            ));
            continue;
        }
        if inside(&contours[j].pline, p) {
            found.depth += 1;
            if found.parent.is_none_or(|b| areas[j].abs() < areas[b].abs()) {
                found.parent = Some(j);
            }
        }
    }
    found
}

/// Two loops that meet: the same loop drawn twice, or crossing or touching at a point.
enum Meeting {
    Twice(V2),
    At(V2),
}

/// Whether and how loops `a` and `b` meet.
fn meeting(a: &Pline, b: &Pline) -> Option<Meeting> {
    let x = crossing(a, b)?;
    Some(if same_loop(a, b) {
        Meeting::Twice(x)
    } else {
        Meeting::At(x)
    })
}

/// Whether two loops are one loop drawn twice: the same vertices and arcs, from any start and in
/// either direction. (A loop redrawn with other vertices, e.g. a circle split at another point,
/// is not recognised: it still meets the first one.)
fn same_loop(a: &Pline, b: &Pline) -> bool {
    const EPS_MM: f64 = 1e-9;
    let n = a.vertex_count();
    if n != b.vertex_count() {
        return false;
    }
    let mut b = b.clone();
    if (a.area() > 0.0) != (b.area() > 0.0) {
        b.invert_direction_mut();
    }
    let close = |i: usize, j: usize| {
        let (u, v) = (a.at(i), b.at(j));
        (u.x - v.x).abs() <= EPS_MM
            && (u.y - v.y).abs() <= EPS_MM
            && (u.bulge - v.bulge).abs() <= EPS_MM
    };
    (0..n).any(|k| (0..n).all(|i| close(i, (i + k) % n)))
}

/// Loops of one part that meet, as `loop_of` gives them (drawn or offset): every two of its holes,
/// and its outline with each hole where `with_outer` says so. Each pair once, as (part, contour,
/// contour, where), in the input's order. Nesting compares a contour only with the larger ones
/// whose boxes hold it, and the merge check only parts, so holes side by side are compared here:
/// those whose boxes overlap, found with a spatial index.
fn meeting_loops<'p>(
    parts: &[Part],
    with_outer: impl Fn(&Part) -> bool,
    loop_of: impl Fn(usize) -> &'p Pline + Sync,
) -> Vec<(usize, usize, usize, Meeting)> {
    let loops: Vec<(usize, usize)> = parts
        .iter()
        .enumerate()
        .flat_map(|(p, part)| {
            let outer = with_outer(part).then_some(part.outer);
            outer
                .into_iter()
                .chain(part.holes.iter().copied())
                .map(move |c| (p, c))
        })
        .collect();
    let boxes: Vec<Bbox> = loops
        .par_iter()
        .map(|&(_, c)| Bbox::of(loop_of(c)))
        .collect();
    let Some(index) = index_of(&boxes) else {
        return Vec::new();
    };
    let found: Vec<Vec<(usize, usize, usize, Meeting)>> = (0..loops.len())
        .into_par_iter()
        .map(|a| {
            let (part, ca) = loops[a];
            let ba = boxes[a];
            let mut met = Vec::new();
            for b in index.query(ba.min.x, ba.min.y, ba.max.x, ba.max.y) {
                let cb = loops[b].1;
                if b > a
                    && loops[b].0 == part
                    && let Some(m) = meeting(loop_of(ca), loop_of(cb))
                {
                    met.push((part, ca, cb, m));
                }
            }
            met.sort_by_key(|&(_, _, cb, _)| cb);
            met
        })
        .collect();
    found.into_iter().flatten().collect()
}

/// Holes of one part that cross, touch or coincide as drawn: cut lines that meet, like any two
/// contours that cross (see [`enclosers`]).
fn check_holes(contours: &[Contour], parts: &[Part]) -> Result<()> {
    let mut problems = Problems::default();
    // A part's outline and its holes were compared when nesting.
    for (p, a, b, m) in meeting_loops(parts, |_| false, |h| &contours[h].pline) {
        let (la, lb) = (&contours[a].label, &contours[b].label);
        problems.push(match m {
            Meeting::Twice(x) => {
                format!("{la} and {lb} are the same loop drawn twice (at {}); delete one", at(x))
            }
            Meeting::At(x) => format!(
                "the holes {la} and {lb} of the part {} cross or touch at {}; cut lines must not meet: draw them as one hole, or move them apart",
                contours[parts[p].outer].label,
                at(x)
            ),
        });
    }
    problems.cannot_dilate()
}

/// Loops of one part that would overlap once offset. Dilating, they cannot (holes shrink into
/// themselves, outlines grow away from them) unless they meet as drawn, which is refused first;
/// but undoing a compensation larger than half the kerf grows the holes and shrinks the outline,
/// into the part's material: where it is narrower than twice that, they would overlap.
fn check_offset_loops(
    contours: &[Contour],
    parts: &[Part],
    dilated: &[Pline],
    how: Offsetting,
) -> Result<()> {
    let into_material_mm = |part: &Part| match how {
        Offsetting::Dilate => -part.kerf_um / 2000.0,
        Offsetting::Recompensate { burn_mm } => burn_mm - part.kerf_um / 2000.0,
    };
    let with_outer = |part: &Part| into_material_mm(part) > 0.0;
    let mut problems = Problems::default();
    for (p, a, b, m) in meeting_loops(parts, with_outer, |c| &dilated[c]) {
        let (Meeting::Twice(x) | Meeting::At(x)) = m;
        let part = &parts[p];
        let named = |c: usize| {
            let what = if c == part.outer { "outline" } else { "hole" };
            format!("the {what} {}", contours[c].label)
        };
        let moved_um = into_material_mm(part) * 1000.0;
        let why = if moved_um > 0.0 {
            format!(
                ": undoing the compensation moves them {moved_um:.1} µm into the part, and the material between them is narrower than {:.1} µm; move them apart, or recompensate the original drawing",
                2.0 * moved_um
            )
        } else {
            // Not expected: they moved apart. Still never written overlapping.
            " once offset; move them apart".to_string()
        };
        problems.push(format!(
            "{} and {} of the part {} would overlap near {}{why}",
            named(a),
            named(b),
            contours[part.outer].label,
            at(x),
        ));
    }
    problems.cannot_dilate()
}

/// Parts: one per outer contour, with the holes directly inside it. The parts, and each
/// contour's part.
fn group_parts(
    roles: &[Role],
    depth: &[usize],
    parent: &[Option<usize>],
) -> (Vec<Part>, Vec<usize>) {
    let n = roles.len();
    let mut part_index = vec![usize::MAX; n];
    let mut parts: Vec<Part> = Vec::new();
    for i in 0..n {
        if roles[i] == Role::Outer {
            part_index[i] = parts.len();
            parts.push(Part {
                outer: i,
                holes: Vec::new(),
                depth: depth[i],
                centroid_mm: [0.0; 2],
                area_mm2: 0.0,
                kerf_um: 0.0,
            });
        }
    }
    for i in 0..n {
        if roles[i] == Role::Hole {
            match enclosing_part(i, parent, &part_index) {
                Some(p) => {
                    part_index[i] = p;
                    parts[p].holes.push(i);
                }
                // No outer contour encloses it (degenerate input the checks let through): it
                // is cut as a part of its own rather than trusted to one.
                None => {
                    part_index[i] = parts.len();
                    parts.push(Part {
                        outer: i,
                        holes: Vec::new(),
                        depth: depth[i],
                        centroid_mm: [0.0; 2],
                        area_mm2: 0.0,
                        kerf_um: 0.0,
                    });
                }
            }
        }
    }
    (parts, part_index)
}

/// The part of the nearest enclosing outer contour of hole `i`, walking up its parents (each
/// strictly larger, so the walk ends).
fn enclosing_part(i: usize, parent: &[Option<usize>], part_index: &[usize]) -> Option<usize> {
    let mut at = parent[i];
    while let Some(j) = at {
        if part_index[j] != usize::MAX {
            return Some(part_index[j]);
        }
        at = parent[j];
    }
    None
}

/// Each part's area, centroid and kerf (the kerf at its centroid), which must be ≥ 0.
fn kerf_per_part(
    parts: &mut [Part],
    contours: &[Contour],
    areas: &[f64],
    centroids: &[V2],
    kerf: &KerfSource,
) -> Result<()> {
    let mut problems = Problems::default();
    for part in parts {
        let mut area = areas[part.outer].abs();
        let mut moment = centroids[part.outer].scale(area);
        for &h in &part.holes {
            area -= areas[h].abs();
            moment = moment - centroids[h].scale(areas[h].abs());
        }
        let c = if area > 0.0 {
            moment.scale(1.0 / area)
        } else {
            centroids[part.outer]
        };
        part.centroid_mm = [c.x, c.y];
        part.area_mm2 = area;
        part.kerf_um = kerf.kerf_at_um(c.x, c.y);
        if !(part.kerf_um.is_finite() && part.kerf_um >= 0.0) {
            problems.push(format!(
                "the kerf map gives {:.1} µm for the part {} (centroid {}); a kerf must be ≥ 0",
                part.kerf_um,
                contours[part.outer].label,
                at(c)
            ));
        }
    }
    problems.cannot_dilate()
}

/// Offset every contour by half its part's kerf, spread over the available cores (a given
/// contour's drawn polyline is freed as soon as it is offset).
fn offset_all(
    drawn: &mut Drawn,
    roles: &[Role],
    parts: &[Part],
    part_index: &[usize],
    how: Offsetting,
    progress: &Progress,
) -> Result<Vec<Pline>> {
    let already_mm = match how {
        Offsetting::Dilate => 0.0,
        Offsetting::Recompensate { burn_mm } => burn_mm,
    };
    let counter = progress.counter(Stage::Dilating, drawn.get().len());
    let one = |i: usize, label: &str, pline: Pline| {
        let grow = parts[part_index[i]].kerf_um / 2000.0 - already_mm;
        let offset = offset_one(label, pline, roles[i], grow, how);
        counter.step();
        offset
    };
    let outcomes: Vec<Result<Pline, Advised>> = match drawn {
        Drawn::Lent(contours) => contours
            .par_iter()
            .enumerate()
            .map(|(i, c)| one(i, &c.label, c.pline.clone()))
            .collect(),
        Drawn::Given(contours) => contours
            .par_iter_mut()
            .enumerate()
            .map(|(i, c)| {
                one(
                    i,
                    &c.label,
                    std::mem::replace(&mut c.pline, Pline::new_closed()),
                )
            })
            .collect(),
    };
    let mut problems = Problems::default();
    let mut dilated = Vec::with_capacity(outcomes.len());
    for o in outcomes {
        match o {
            Ok(p) => dilated.push(p),
            Err(e) => {
                problems.push(e);
                dilated.push(Pline::new_closed());
            }
        }
    }
    problems.cannot_dilate()?;
    Ok(dilated)
}

/// Parts that would merge: their dilated outlines overlap.
fn check_merges(contours: &[Contour], parts: &[Part], dilated: &[Pline]) -> Result<()> {
    let part_boxes: Vec<Bbox> = parts
        .par_iter()
        .map(|p| Bbox::of(&dilated[p.outer]))
        .collect();
    let Some(index) = index_of(&part_boxes) else {
        return Ok(());
    };
    let found: Vec<Vec<String>> = (0..parts.len())
        .into_par_iter()
        .map(|a| {
            let b0 = part_boxes[a];
            let mut merges = Vec::new();
            for b in index.query(b0.min.x, b0.min.y, b0.max.x, b0.max.y) {
                if b > a
                    && let Some(x) = parts_overlap(&parts[a], &parts[b], dilated)
                {
                    merges.push(merge_problem(contours, &parts[a], &parts[b], x));
                }
            }
            merges
        })
        .collect();
    let mut problems = Problems::default();
    for p in found.into_iter().flatten() {
        problems.push(p);
    }
    problems.cannot_dilate()
}

/// The message for parts `pa` and `pb` that would merge near `x`.
fn merge_problem(contours: &[Contour], pa: &Part, pb: &Part, x: V2) -> String {
    let need = if (pa.kerf_um - pb.kerf_um).abs() < 1e-9 {
        format!("{:.1} µm", pa.kerf_um)
    } else {
        format!("{:.1} µm", (pa.kerf_um + pb.kerf_um) / 2.0)
    };
    format!(
        "the parts {} and {} would merge near {}: dilated they overlap; parts must be more than the kerf ({need}) apart and must not share cut lines",
        contours[pa.outer].label,
        contours[pb.outer].label,
        at(x)
    )
}

/// Offset one contour: `grow` > 0 moves it away from the part's material by that many mm
/// (outwards for an outer contour, into the hole for a hole).
/// With [`Offsetting::Recompensate`] the drawn corners stay sharp where the contour moves into
/// the material (`grow` < 0). `label` names the drawn contour `p` in messages.
fn offset_one(
    label: &str,
    mut p: Pline,
    role: Role,
    grow: f64,
    how: Offsetting,
) -> Result<Pline, Advised> {
    if grow == 0.0 {
        return Ok(p);
    }
    // Where the contour starts as drawn, for messages.
    let first = first_point(&p);
    let ccw = p.area() > 0.0;
    if !ccw {
        p.invert_direction_mut();
    }
    // For a counter-clockwise contour a positive offset goes left = inwards.
    let offset = match role {
        Role::Outer => -grow,
        Role::Hole => grow,
    };
    let mut results = match how {
        Offsetting::Dilate => p.parallel_offset(offset),
        // A compensated plan may draw its round joins as chords a few µm long.
        Offsetting::Recompensate { .. } => recompensate::offset_in_um(&p, offset),
    };
    if matches!(how, Offsetting::Recompensate { .. }) && grow < 0.0 {
        results = results
            .iter()
            .map(|r| recompensate::sharpen(r, &p, grow.abs()))
            .collect::<Result<_, V2>>()
            .map_err(|x| {
                Advised::text(format!(
                    "{} at {}: its inner corner near {} cannot be kept sharp when its compensation is undone (a feature there is narrower than the change, {:.1} µm); recompensate the original drawing or use ",
                    label,
                    at(first),
                    at(x),
                    grow.abs() * 1000.0
                ))
                .advise(Advice::AlreadyCompensatedOk)
            })?;
    }
    let kerf_um = grow.abs() * 2000.0;
    let total = results.len();
    let mut keep: Vec<Pline> = results.into_iter().filter(|r| r.area() > 0.0).collect();
    match (role, keep.len(), total) {
        (_, 1, 1) => {
            let mut r = keep.pop().expect("one result");
            if !ccw {
                r.invert_direction_mut();
            }
            // Built vertex by vertex, it holds up to twice the room it needs until the plan is
            // written.
            r.vertex_data.shrink_to_fit();
            Ok(r)
        }
        (Role::Hole, 0, _) => Err(format!(
            "the hole {} at {} is narrower than the kerf ({kerf_um:.1} µm) and would vanish: it could not be cut at its size",
            label,
            at(first)
        )
        .into()),
        (Role::Hole, _, _) => Err(format!(
            "the hole {} at {} has a neck narrower than the kerf ({kerf_um:.1} µm): shrunk, it would split in two",
            label,
            at(first)
        )
        .into()),
        (Role::Outer, _, _) => Err(format!(
            "the part {} at {} has a gap narrower than the kerf ({kerf_um:.1} µm) that would close around a void",
            label,
            at(first)
        )
        .into()),
    }
}

/// Whether two dilated parts overlap, and where.
fn parts_overlap(a: &Part, b: &Part, dilated: &[Pline]) -> Option<V2> {
    let (oa, ob) = (&dilated[a.outer], &dilated[b.outer]);
    if let Some(x) = crossing(oa, ob) {
        return Some(x);
    }
    for &h in &a.holes {
        if let Some(x) = crossing(&dilated[h], ob) {
            return Some(x);
        }
    }
    for &h in &b.holes {
        if let Some(x) = crossing(oa, &dilated[h]) {
            return Some(x);
        }
    }
    // No crossings: one part may still lie on the other's material.
    let on_material = |p: &Part, q: V2| {
        inside(&dilated[p.outer], q) && !p.holes.iter().any(|&h| inside(&dilated[h], q))
    };
    let qb = first_point(ob);
    if on_material(a, qb) {
        return Some(qb);
    }
    let qa = first_point(oa);
    if on_material(b, qa) {
        return Some(qa);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use cavalier_contours::polyline::PlineSource;

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64, ccw: bool) -> Pline {
        let mut p = Pline::new_closed();
        let pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
        if ccw {
            for (x, y) in pts {
                p.add(x, y, 0.0);
            }
        } else {
            for (x, y) in pts.iter().rev() {
                p.add(*x, *y, 0.0);
            }
        }
        p
    }

    fn c(p: Pline, label: &str) -> Contour {
        Contour {
            pline: p,
            label: label.into(),
        }
    }

    /// A circle as two half-circle arcs, counter-clockwise.
    fn circle(cx: f64, cy: f64, r: f64) -> Pline {
        let mut p = Pline::new_closed();
        p.add(cx - r, cy, 1.0);
        p.add(cx + r, cy, 1.0);
        p
    }

    /// A 60 mm square part with the two circle holes (x, y, r) given, named "a" and "b".
    fn square_with_holes(a: (f64, f64, f64), b: (f64, f64, f64)) -> Vec<Contour> {
        vec![
            c(rect(0.0, 0.0, 60.0, 60.0, true), "square"),
            c(circle(a.0, a.1, a.2), "a"),
            c(circle(b.0, b.1, b.2), "b"),
        ]
    }

    #[test]
    fn a_hole_drawn_twice_is_an_error() {
        let contours = square_with_holes((30.0, 30.0, 5.0), (30.0, 30.0, 5.0));
        let e = dilate(&contours, &KerfSource::Uniform(150.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a and b are the same loop drawn twice"), "{e}");
        assert!(e.contains("delete one"), "{e}");
        // Drawn the other way round, it is still the same loop.
        let mut contours = contours;
        contours[2].pline.invert_direction_mut();
        let e = dilate(&contours, &KerfSource::Uniform(150.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a and b are the same loop drawn twice"), "{e}");
    }

    #[test]
    fn holes_of_a_part_that_cross_are_an_error() {
        // Equal areas: nesting compares neither with the other.
        let nearly_twice = square_with_holes((30.0, 30.0, 5.0), (30.0, 30.05, 5.0));
        // A smaller hole sticking out of the larger one's box.
        let overlapping = square_with_holes((30.0, 30.0, 5.0), (33.0, 30.0, 4.0));
        for contours in [nearly_twice, overlapping] {
            let e = dilate(&contours, &KerfSource::Uniform(150.0))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("the holes a and b of the part square cross or touch at"),
                "{e}"
            );
            assert!(e.contains("move them apart"), "{e}");
        }
    }

    #[test]
    fn holes_closer_than_the_kerf_shrink_apart_and_dilate() {
        // 50 µm apart with a 150 µm kerf: each hole shrinks into itself, away from the other.
        let contours = square_with_holes((30.0, 30.0, 5.0), (40.05, 30.0, 5.0));
        let d = dilate(&contours, &KerfSource::Uniform(150.0)).unwrap();
        assert_eq!(d.parts[0].holes, vec![1, 2]);
        let r = 5.0 - 0.075;
        for h in [1, 2] {
            assert!((d.contours[h].area() - std::f64::consts::PI * r * r).abs() < 1e-9);
        }
    }

    #[test]
    fn holes_that_grow_into_each_other_when_a_compensation_is_undone_are_an_error() {
        // Drawn 200 µm outside their parts (a burn of 0.2 mm), recompensated for a 100 µm kerf:
        // every hole grows by 150 µm, so two holes 200 µm apart would overlap.
        let contours = square_with_holes((30.0, 30.0, 5.0), (40.2, 30.0, 5.0));
        let how = Offsetting::Recompensate { burn_mm: 0.2 };
        let e = dilate_with(&contours, &KerfSource::Uniform(100.0), how)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the hole a and the hole b of the part square would overlap near"),
            "{e}"
        );
        // 400 µm apart they still fit.
        let contours = square_with_holes((30.0, 30.0, 5.0), (40.4, 30.0, 5.0));
        assert!(dilate_with(&contours, &KerfSource::Uniform(100.0), how).is_ok());
        // The outline shrinks as much: 200 µm from a hole, they would overlap too.
        let contours = square_with_holes((5.2, 30.0, 5.0), (30.0, 30.0, 5.0));
        let e = dilate_with(&contours, &KerfSource::Uniform(100.0), how)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the outline square and the hole a of the part square would overlap"),
            "{e}"
        );
        // Dilating instead, the same part is fine: both move away from the web.
        assert!(dilate(&contours, &KerfSource::Uniform(100.0)).is_ok());
    }

    #[test]
    fn outer_grows_hole_shrinks_island_grows_with_orientation_kept() {
        let contours = vec![
            c(rect(0.0, 0.0, 100.0, 100.0, false), "outer"),
            c(rect(10.0, 10.0, 90.0, 90.0, true), "hole"),
            c(rect(40.0, 40.0, 60.0, 60.0, false), "island"),
        ];
        let d = dilate(&contours, &KerfSource::Uniform(200.0)).unwrap();
        assert_eq!(d.roles, vec![Role::Outer, Role::Hole, Role::Outer]);
        assert_eq!(d.parts.len(), 2);
        assert_eq!(d.parts[0].holes, vec![1]);
        // Outer: 100.2 × 100.2 with four quarter-round corners of radius 0.1.
        let r: f64 = 0.1;
        let expected_outer = 100.0 * 100.0 + 4.0 * 100.0 * r + std::f64::consts::PI * r * r;
        assert!((d.contours[0].area().abs() - expected_outer).abs() < 1e-9);
        // Hole: 79.8 × 79.8, sharp corners.
        assert!((d.contours[1].area().abs() - 79.8 * 79.8).abs() < 1e-9);
        // Orientation kept.
        assert!(
            d.contours[0].area() < 0.0 && d.contours[1].area() > 0.0 && d.contours[2].area() < 0.0
        );
        // The part's centroid: the middle.
        assert!((d.parts[0].centroid_mm[0] - 50.0).abs() < 1e-9);
    }

    #[test]
    fn parts_closer_than_the_kerf_merge_and_are_reported() {
        let contours = vec![
            c(rect(0.0, 0.0, 10.0, 10.0, true), "a"),
            c(rect(10.15, 0.0, 20.0, 10.0, true), "b"),
        ];
        let e = dilate(&contours, &KerfSource::Uniform(200.0))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("would merge") && e.contains("a") && e.contains("b"),
            "{e}"
        );
        assert!(dilate(&contours, &KerfSource::Uniform(100.0)).is_ok());
    }

    #[test]
    fn a_hole_narrower_than_the_kerf_is_an_error() {
        let contours = vec![
            c(rect(0.0, 0.0, 10.0, 10.0, true), "part"),
            c(rect(2.0, 2.0, 2.15, 8.0, true), "slit"),
        ];
        let e = dilate(&contours, &KerfSource::Uniform(200.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("slit") && e.contains("vanish"), "{e}");
    }

    #[test]
    fn crossing_contours_are_an_error() {
        let contours = vec![
            c(rect(0.0, 0.0, 10.0, 10.0, true), "big"),
            c(rect(5.0, 5.0, 10.0, 12.0, true), "sticks-out"),
        ];
        let e = dilate(&contours, &KerfSource::Uniform(100.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("would merge"), "{e}");
        // A square inside an L's bounding box, crossing the L.
        let mut l = Pline::new_closed();
        for (x, y) in [
            (0.0, 0.0),
            (10.0, 0.0),
            (10.0, 5.0),
            (5.0, 5.0),
            (5.0, 10.0),
            (0.0, 10.0),
        ] {
            l.add(x, y, 0.0);
        }
        let contours = vec![c(l, "L"), c(rect(3.0, 3.0, 7.0, 7.0, true), "square")];
        let e = dilate(&contours, &KerfSource::Uniform(100.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("square and L cross"), "{e}");
    }

    #[test]
    fn releasing_the_drawn_contours_frees_them_and_dilates_the_same() {
        let drawn = vec![
            c(rect(0.0, 0.0, 100.0, 100.0, false), "outer"),
            c(rect(10.0, 10.0, 90.0, 90.0, true), "hole"),
        ];
        let lent = dilate(&drawn, &KerfSource::Uniform(200.0)).unwrap();
        let mut given = drawn.clone();
        let released = dilate_releasing_drawn(
            &mut given,
            &KerfSource::Uniform(200.0),
            Offsetting::Dilate,
            &Progress::default(),
        )
        .unwrap();
        assert_eq!(released.contours.len(), lent.contours.len());
        for (a, b) in released.contours.iter().zip(&lent.contours) {
            assert_eq!(a.vertex_data, b.vertex_data);
        }
        assert_eq!(released.parts, lent.parts);
        // The drawn geometry is gone; the labels stay for messages.
        assert!(given.iter().all(|c| c.pline.vertex_count() == 0));
        let labels: Vec<&str> = given.iter().map(|c| c.label.as_str()).collect();
        assert_eq!(labels, ["outer", "hole"]);
    }

    #[test]
    fn a_map_gives_each_part_the_kerf_at_its_centroid() {
        // 120 µm left of x = 100 mm, 160 µm right of it.
        let field = |x_mm: f64, _y_mm: f64| if x_mm < 100.0 { 120.0 } else { 160.0 };
        let contours = vec![
            c(rect(40.0, 40.0, 60.0, 60.0, true), "left"),
            c(rect(140.0, 40.0, 160.0, 60.0, true), "right"),
        ];
        let d = dilate(&contours, &KerfSource::Map(Arc::new(field))).unwrap();
        assert!((d.parts[0].kerf_um - 120.0).abs() < 1e-9);
        assert!((d.parts[1].kerf_um - 160.0).abs() < 1e-9);
    }
}
