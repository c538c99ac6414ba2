//! The offset itself: each part's kerf, and each contour offset by half of it (outer contours
//! out, holes in) on every core, with the problems an offset finds (a hole that would vanish or
//! split, a gap that would close).

use cavalier_contours::polyline::{PlineSource, PlineSourceMut};
use kerfmeter_protocol::advice::{Advice, Advised};
use rayon::prelude::*;

use super::geometry::{at, first_point};
use super::{Contour, Drawn, KerfSource, Offsetting, Part, Role};
use crate::error::{Problems, Result};
use crate::geom::{Pline, V2};
use crate::progress::{Progress, Stage};
use crate::recompensate;

/// Each part's area, centroid and kerf (the kerf at its centroid), which must be ≥ 0.
pub(super) fn kerf_per_part(
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
pub(super) fn offset_all(
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
