//! The cutting order ([`cut_order`]): a contour is cut only after every contour inside it, and
//! among those that may be cut next the one with a vertex nearest the head goes first, starting
//! at that vertex; the candidates' boxes in an R-tree (see the [`gcode`](super) module doc).

use cavalier_contours::polyline::{PlineCreation, PlineSource, PlineSourceMut};
use rstar::RTree;
use rstar::primitives::{GeomWithData, Rectangle};

use super::Job;
use crate::dilate::{self, Contour};
use crate::error::{PlanError, Result};
use crate::geom::{Pline, V2, area_and_centroid, v2};

/// The order to cut `jobs` in (see the module doc), each closed contour starting at its chosen
/// vertex; the head starts at the machine origin.
pub fn cut_order(jobs: Vec<Job>) -> Result<Vec<Job>> {
    if let Some(empty) = jobs.iter().find(|j| j.pline.extents().is_none()) {
        return Err(PlanError::InvalidArgument(format!(
            "{} has no extent: it cannot be cut",
            empty.label
        )));
    }
    let parent = parents(&jobs)?;
    let mut waiting = vec![0usize; jobs.len()];
    for p in parent.iter().flatten() {
        waiting[*p] += 1;
    }
    let mut tree: RTree<Boxed> = RTree::bulk_load(
        (0..jobs.len())
            .filter(|&i| waiting[i] == 0)
            .filter_map(|i| boxed(i, &jobs[i].pline))
            .collect(),
    );
    let mut head = v2(0.0, 0.0);
    let mut order = Vec::with_capacity(jobs.len());
    while let Some((i, k)) = next_cut(&tree, &jobs, head) {
        if let Some(entry) = boxed(i, &jobs[i].pline) {
            tree.remove(&entry);
        }
        let v = jobs[i].pline.at(k);
        head = v2(v.x, v.y);
        order.push((i, k));
        if let Some(p) = parent[i] {
            waiting[p] -= 1;
            if waiting[p] == 0
                && let Some(entry) = boxed(p, &jobs[p].pline)
            {
                tree.insert(entry);
            }
        }
    }
    if order.len() != jobs.len() {
        let left: Vec<&str> = (0..jobs.len())
            .filter(|i| !order.iter().any(|(j, _)| j == i))
            .map(|i| jobs[i].label.as_str())
            .collect();
        return Err(PlanError::InvalidArgument(format!(
            "{} contour{} could not be placed in the cutting order (empty or degenerate): {}",
            left.len(),
            if left.len() == 1 { "" } else { "s" },
            left.join(", ")
        )));
    }
    let mut slots: Vec<Option<Job>> = jobs.into_iter().map(Some).collect();
    Ok(order
        .into_iter()
        .filter_map(|(i, k)| {
            slots[i].take().map(|job| Job {
                pline: starting_at(&job.pline, k),
                ..job
            })
        })
        .collect())
}

/// A contour that may be cut next, by its bounding box.
type Boxed = GeomWithData<Rectangle<[f64; 2]>, usize>;

fn boxed(i: usize, p: &Pline) -> Option<Boxed> {
    let e = p.extents()?;
    Some(GeomWithData::new(
        Rectangle::from_corners([e.min_x, e.min_y], [e.max_x, e.max_y]),
        i,
    ))
}

/// The contour in `tree` with the vertex nearest `head`, and that vertex. Boxes come in order of
/// their distance, a lower bound of their vertices' distance: the search stops at the first box
/// farther than the best vertex found.
fn next_cut(tree: &RTree<Boxed>, jobs: &[Job], head: V2) -> Option<(usize, usize)> {
    let mut best: Option<(f64, usize, usize)> = None;
    for (entry, box_d2) in tree.nearest_neighbor_iter_with_distance_2(&[head.x, head.y]) {
        if best.is_some_and(|(d2, _, _)| box_d2 > d2) {
            break;
        }
        let i = entry.data;
        for (k, v) in jobs[i].pline.iter_vertexes().enumerate() {
            let d2 = (v2(v.x, v.y) - head).length_squared();
            if best.is_none_or(|(b, _, _)| d2 < b) {
                best = Some((d2, i, k));
            }
        }
    }
    best.map(|(_, i, k)| (i, k))
}

/// The smallest contour enclosing each contour, if any (the plan's own nesting rules).
fn parents(jobs: &[Job]) -> Result<Vec<Option<usize>>> {
    let contours: Vec<Contour> = jobs
        .iter()
        .map(|j| Contour {
            pline: j.pline.clone(),
            label: j.label.clone(),
        })
        .collect();
    let areas: Vec<f64> = contours
        .iter()
        .map(|c| area_and_centroid(&c.pline).0)
        .collect();
    Ok(dilate::nest(&contours, &areas)?.1)
}

/// The closed contour `p` drawn from its vertex `k` (each bulge stays with its segment).
fn starting_at(p: &Pline, k: usize) -> Pline {
    let n = p.vertex_count();
    let mut out = Pline::with_capacity(n, true);
    for j in 0..n {
        out.add_vertex(p.at((k + j) % n));
    }
    out
}
