//! The contours as drawn: each one checked on its own (closed, with an area, not crossing
//! itself), then nested (who encloses whom, contours that cross refused) and grouped into parts,
//! an outer contour each with the holes directly inside it.

use cavalier_contours::polyline::PlineSource;
use cavalier_contours::static_aabb2d_index::StaticAABB2DIndex;
use rayon::prelude::*;

use super::geometry::{Bbox, at, crossing, first_point, index_of, inside};
use super::{Contour, Part, Role};
use crate::error::{Problems, Result};
use crate::geom::{V2, area_and_centroid};

/// Each contour on its own: closed, with an area, not crossing itself. Its signed area and
/// centroid.
pub(super) fn check_each(contours: &[Contour]) -> Result<(Vec<f64>, Vec<V2>)> {
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

/// Parts: one per outer contour, with the holes directly inside it. The parts, and each
/// contour's part.
pub(super) fn group_parts(
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
