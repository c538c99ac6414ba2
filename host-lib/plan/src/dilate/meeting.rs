//! Loops that meet or would: holes of a part that cross as drawn, loops of a part that an offset
//! into its material would make overlap, and parts whose dilated outlines would merge.

use super::geometry::{Bbox, at, crossing, first_point, index_of, inside};
use super::{Contour, Offsetting, Part};
use crate::error::{Problems, Result};
use crate::geom::{Pline, V2};
use cavalier_contours::polyline::{PlineSource, PlineSourceMut};
use rayon::prelude::*;

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
/// contours that cross (see `enclosers` in `nesting`).
pub(super) fn check_holes(contours: &[Contour], parts: &[Part]) -> Result<()> {
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
pub(super) fn check_offset_loops(
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

/// Parts that would merge: their dilated outlines overlap.
pub(super) fn check_merges(contours: &[Contour], parts: &[Part], dilated: &[Pline]) -> Result<()> {
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
