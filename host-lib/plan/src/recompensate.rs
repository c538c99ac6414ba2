//! The geometry of undoing a compensation: boxes.py's corner loops and retraces, and moving a
//! compensated contour by kerf/2 − burn with its corners as drawn.
//!
//! **What a burnt contour keeps, corner by corner.** A contour compensated by a burn b is the
//! boundary of the part's Minkowski sum with a disk of radius b (round joins). At a convex
//! corner of the part it is an arc of radius b around the corner: nothing is lost, the corner is
//! the arc's centre, and moving the contour by d only changes the arc's radius to b + d. At an
//! inner (reflex) corner it is sharp, where the two offset edges meet: nothing is lost either,
//! but moving *into* the material by an offset with round joins would round that corner (a
//! morphological closing, up to 0.41·d off at a right angle), so the edges are extended to meet
//! again ([`sharpen`]); moving away from the material keeps it sharp by itself. What *is* lost:
//! an edge of the part that the burn swallowed whole (a notch or slot narrower than 2·b, or the
//! flat bottom of a notch whose sides the burn made meet): the contour carries nothing of it,
//! and recompensating to a smaller burn cannot bring it back (its sides are extended to a point
//! instead). So recompensating is exact (the same cut as compensating the uncompensated part by
//! the new kerf) at any corner angle, acute or reflex, as long as no edge was swallowed.
//!
//! **boxes.py's construction.** boxes.py traces each part with a turtle, `burn` outside it: at a
//! convex corner it turns along an arc of radius `burn` around the part's corner (a turn past
//! 100° in steps); at an inner corner it runs on past the point where the two offset edges
//! cross, turns back along a small arc (or a small closed Bézier, its default `--inner_corners
//! loop`) and crosses its own path there. The cut is right (the loop lies inside the cut
//! region), but the contour crosses itself. [`remove_corner_loops`] cuts every such loop off at
//! the crossing, which leaves exactly the offset contour with a sharp inner corner. Where boxes.py
//! turns twice at one point (a finger joint's last inner quarter turn, then the part's own
//! corner: Platonic's parts, with no edge between them), the first turn draws the corner's arc
//! backwards and the second draws it forwards again: the two passes lie on one circle and need
//! not cross (boxes.py's 1 µm rounding), leaving a crack into the part that an offset into the
//! material widens into a slot. Such a *retrace* (the contour reverses within 5° of straight
//! back and runs back over a vertex of the way it came, within 3 µm) is cut back to where the
//! passes part: the corner's arc as a round join draws it. A turn on past a corner and part of
//! the way back (CoinDisplay's 60° corners, turned 90° and back 30° before the edge leaves with a
//! second reversal) is cut where that edge leaves the arc, once no whole retrace is left. A notch
//! sharper than 5° whose tip is a single vertex runs back over none and is kept.
//!
//! **Moving a compensated contour.** Eroding the compensated region by burn − kerf/2 (a plain
//! offset inwards with round joins) rounds every inner corner: that is a morphological closing,
//! off by up to 0.41·(burn − kerf/2) at a right angle. The exact result moves each drawn segment
//! and arc along its normal and extends its neighbours until they meet. A compensated contour
//! has only two kinds of corner: tangent joins (its arcs around convex corners, which just change
//! radius) and sharp inner corners. So [`sharpen`] takes `cavalier_contours`' offset (exact
//! everywhere else, including where features vanish) and replaces each round join it made at a
//! drawn corner by the two neighbours extended to where they meet. Moving outwards (kerf/2 >
//! burn) needs no change: the neighbours at an inner corner already meet there.
//!
//! **Offsets in µm.** A plan compensated elsewhere as polygons draws its round joins as chords a
//! few µm long, which `cavalier_contours` takes for parallel in mm: see [`offset_in_um`].
//!
//! **Tested** (`tests/plan_recompensation.rs`): random star polygons with acute spikes and
//! reflex notches, drawn by boxes.py's construction or buffered by GEOS at one burn,
//! recompensated to another, against this tool's dilation of the polygon itself: within 1 µm
//! (GEOS's: and its chords' own error); and boxes.py's own plans
//! (`tests/plan_recompensation_boxes.rs`).

use cavalier_contours::core::math::{
    CircleCircleIntr, LineCircleIntr, LineLineIntr, circle_circle_intr, line_circle_intr,
    line_line_intr,
};
use cavalier_contours::polyline::internal::pline_intersects::all_self_intersects_as_basic;
use cavalier_contours::polyline::{
    PlineSource, PlineSourceMut, PlineVertex, seg_arc_radius_and_center, seg_closest_point,
    seg_length, seg_split_at_point, seg_tangent_vector,
};
use cavalier_contours::static_aabb2d_index::{StaticAABB2DIndex, StaticAABB2DIndexBuilder};

use crate::geom::{Pline, V2, v2};

/// Positions closer than this are the same, mm.
const POS_EPS: f64 = 1e-9;
/// A step between a retrace's two passes shorter than this is left out, mm.
const STEP_MIN_MM: f64 = 3e-4;
/// A loop reaches at least this far from its crossing, mm (less is the rounding of a joint).
const LOOP_MIN_MM: f64 = 1e-5;

/// One loop to cut off: the contour keeps the start of segment `p` up to `x`, then goes on from
/// `y` along the end of segment `q` (a straight step from `x` to `y` when they differ: a
/// retrace's two passes); the vertices after `p` up to `q` (cyclically) go.
#[derive(Debug, Clone, Copy)]
struct LoopCut {
    p: usize,
    q: usize,
    x: V2,
    y: V2,
}

/// Remove the small loops (each no larger than `max_loop_mm` across) a contour makes where it
/// crosses itself, keeping the rest: the contour and how many loops went. Larger crossings stay
/// (the dilation reports them).
pub fn remove_corner_loops(p: &Pline, max_loop_mm: f64) -> (Pline, usize) {
    let (looped, crossings) = remove_crossing_loops(p, max_loop_mm);
    let (retraced, retraces) = remove_retraces(&looped, max_loop_mm);
    (retraced, crossings + retraces)
}

/// The loops that cross the contour (see [`remove_corner_loops`]).
fn remove_crossing_loops(p: &Pline, max_loop_mm: f64) -> (Pline, usize) {
    let mut cur = p.clone();
    let mut removed = 0;
    // Loops found together rarely overlap (several crossings at one point); a few rounds catch
    // any that were set aside.
    for _ in 0..8 {
        if cur.vertex_count() < 3 {
            break;
        }
        let index = cur.create_approx_aabb_index();
        let cuts: Vec<LoopCut> = all_self_intersects_as_basic(&cur, &index, false, POS_EPS)
            .into_iter()
            .filter_map(|i| small_loop(&cur, i.start_index1, i.start_index2, i.point, max_loop_mm))
            .collect();
        let found = cuts.len();
        let chosen = disjoint(cuts, cur.vertex_count());
        if chosen.is_empty() {
            break;
        }
        removed += chosen.len();
        cur = cut_loops(&cur, &chosen);
        // Cutting a loop off makes no new crossing: look again only for loops set aside.
        if chosen.len() == found {
            break;
        }
    }
    (cur, removed)
}

fn pos(p: &Pline, i: usize) -> V2 {
    let v = p.at(i);
    v2(v.x, v.y)
}

/// Whether the vertices `from..=to` (cyclically) and `x` fit in a box `max` across.
fn small(p: &Pline, from: usize, to: usize, x: V2, max: f64) -> bool {
    let n = p.vertex_count();
    let (mut lo, mut hi) = (x, x);
    let mut i = from % n;
    loop {
        let q = pos(p, i);
        lo = v2(lo.x.min(q.x), lo.y.min(q.y));
        hi = v2(hi.x.max(q.x), hi.y.max(q.y));
        if (hi - lo).length() > max {
            return false;
        }
        if i == to % n {
            return true;
        }
        i = (i + 1) % n;
    }
}

/// The loop cut for a crossing of segments `a` and `b` at `x`, when one side of it is small.
fn small_loop(p: &Pline, a: usize, b: usize, x: V2, max: f64) -> Option<LoopCut> {
    let (a, b) = (a.min(b), a.max(b));
    if a == b {
        return None;
    }
    let n = p.vertex_count();
    // Neighbouring segments that meet where they join (within rounding) make no loop.
    let reaches =
        |from: usize, to: usize| (from..=to).any(|i| (pos(p, i % n) - x).length() > LOOP_MIN_MM);
    if small(p, a + 1, b, x, max) && reaches(a + 1, b) {
        Some(LoopCut {
            p: a,
            q: b,
            x,
            y: x,
        })
    } else if small(p, b + 1, a + n, x, max) && reaches(b + 1, a + n) {
        Some(LoopCut {
            p: b,
            q: a,
            x,
            y: x,
        })
    } else {
        None
    }
}

/// Cyclic vertex indexes `p..=q`.
fn span(c: &LoopCut, n: usize) -> impl Iterator<Item = usize> {
    let len = (c.q + n - c.p) % n;
    (0..=len).map(move |k| (c.p + k) % n)
}

/// Loop cuts that share no vertex, smallest first.
fn disjoint(mut cuts: Vec<LoopCut>, n: usize) -> Vec<LoopCut> {
    cuts.sort_by_key(|c| (c.q + n - c.p) % n);
    let mut claimed = vec![false; n];
    let mut chosen = Vec::new();
    for c in cuts {
        if span(&c, n).any(|i| claimed[i]) {
            continue;
        }
        span(&c, n).for_each(|i| claimed[i] = true);
        chosen.push(c);
    }
    chosen
}

/// Where a loop is cut off at a vertex: the vertex's new bulge (up to the cut), the step's
/// start when the two passes are apart, and the vertex the contour goes on from.
type Splice = (f64, Option<V2>, PlineVertex<f64>);

/// The contour with the loops cut off.
fn cut_loops(p: &Pline, cuts: &[LoopCut]) -> Pline {
    let n = p.vertex_count();
    let mut gone = vec![false; n];
    let mut at: Vec<Option<Splice>> = vec![None; n];
    for c in cuts {
        span(c, n).skip(1).for_each(|i| gone[i] = true);
        let first = seg_split_at_point(p.at(c.p), p.at((c.p + 1) % n), c.x, POS_EPS);
        let second = seg_split_at_point(p.at(c.q), p.at((c.q + 1) % n), c.y, POS_EPS);
        // A step too short to matter (the passes meet within reading's error) is none: the
        // segment runs on to `y` instead of doubling back on itself.
        let step = ((c.x - c.y).length() > STEP_MIN_MM).then_some(c.x);
        at[c.p] = Some((first.updated_start.bulge, step, second.split_vertex));
    }
    let mut out = Pline::new_closed();
    for i in 0..n {
        if gone[i] {
            continue;
        }
        let mut v = p.at(i);
        match at[i] {
            Some((bulge, step, y)) => {
                v.bulge = bulge;
                out.add_vertex(v);
                if let Some(x) = step {
                    out.add(x.x, x.y, 0.0);
                }
                out.add_vertex(y);
            }
            None => out.add_vertex(v),
        }
    }
    out.remove_repeat_pos(POS_EPS).unwrap_or(out)
}

/// A reversal at a vertex is a cusp when its two directions are closer than 5° to opposite.
const CUSP_COS: f64 = -0.996_19;
/// The two passes of a retrace lie within this of each other, mm: boxes.py's 1 µm rounding of
/// both, and the biarcs its Béziers are read as.
const RETRACE_MM: f64 = 0.003;

/// Cut off every retrace no longer than `max_mm`: where the contour reverses at a cusp and runs
/// back along itself (within [`RETRACE_MM`]), it is joined straight from where the first pass
/// leaves the second. The contour, and how many went.
fn remove_retraces(p: &Pline, max_mm: f64) -> (Pline, usize) {
    let mut cur = p.clone();
    let mut removed = 0;
    while removed < p.vertex_count() && cur.vertex_count() >= 3 {
        // Whole retraces first: a corner drawn back and over again (Platonic) also reverses
        // where its first pass leaves the edge, and that reversal, cut as a partial retrace,
        // would cut the edge short instead of removing the spike.
        let find =
            |partial| (0..cur.vertex_count()).find_map(|k| retrace_at(&cur, k, max_mm, partial));
        let Some(cut) = find(false).or_else(|| find(true)) else {
            break;
        };
        cur = cut_loops(&cur, &[cut]);
        removed += 1;
    }
    (cur, removed)
}

/// The retrace that reverses at vertex `k`, if the contour reverses there and runs back along
/// itself over at least one vertex of the way it came (the tip of a sharp notch runs back over
/// none: its edges part at once); with `partial`, one that runs back over part of a segment only
/// and reverses again where it leaves it.
fn retrace_at(p: &Pline, k: usize, max_mm: f64, partial: bool) -> Option<LoopCut> {
    let n = p.vertex_count();
    if !is_cusp(p, k) {
        return None;
    }
    // The first pass (the segments before `k`, walked back) and the second (from `k` on). The
    // retrace ends where the passes part: at the farthest vertex of the first pass that the
    // second runs back over (where boxes.py's arc around a corner began), or at the farthest
    // vertex of the second pass that lies on the first and reverses again (where a second turn
    // that runs back over only part of the first leaves it: CoinDisplay turns 90° around a 60°
    // corner, then 30° back, then along the edge; a pass that runs on tangentially past the
    // first's start does not end there). A tangent that merely leaves the cusp has neither.
    let first = walk(p, k, max_mm, false);
    let second = walk(p, k, max_mm, true);
    let mut over_first = None;
    for &s in &first {
        let (q, d) = nearest(p, &second, p.at(s).pos());
        if d > RETRACE_MM {
            break;
        }
        let x = p.at(s).pos();
        // Keep the segment that ends at `x`, then go on from `y`.
        over_first = Some(LoopCut {
            p: (s + n - 1) % n,
            q,
            x,
            y: nearest_point(p, q, x),
        });
    }
    let mut over_second = None;
    for &v in second.iter().skip(1) {
        let y = p.at(v).pos();
        let (f, d) = nearest(p, &first, y);
        if d > RETRACE_MM {
            break;
        }
        // A reversal back within reading's error of the cusp is the step a cut retrace leaves
        // between its passes, not a pass of its own.
        if !is_cusp(p, v) || (y - p.at(k).pos()).length() <= RETRACE_MM {
            continue;
        }
        // Keep segment `f` up to the point nearest `y`, then go on from `y` along segment `v`.
        over_second = Some(LoopCut {
            p: f,
            q: v,
            x: nearest_point(p, f, y),
            y,
        });
    }
    if partial { over_second } else { over_first }
}

/// Whether the contour reverses at vertex `k`: its directions in and out are within 5° of
/// opposite.
fn is_cusp(p: &Pline, k: usize) -> bool {
    let n = p.vertex_count();
    let (a, b, c) = (p.at((k + n - 1) % n), p.at(k), p.at((k + 1) % n));
    let (t_in, t_out) = (
        seg_tangent_vector(a, b, b.pos()),
        seg_tangent_vector(b, c, b.pos()),
    );
    t_in.length() >= POS_EPS
        && t_out.length() >= POS_EPS
        && t_in.normalize().dot(t_out.normalize()) <= CUSP_COS
}

/// Segments from vertex `k` on (`forward`), or before it walked back, up to `max_mm` of length.
fn walk(p: &Pline, k: usize, max_mm: f64, forward: bool) -> Vec<usize> {
    let n = p.vertex_count();
    let mut out = Vec::new();
    let mut length = 0.0;
    for i in 0..n - 1 {
        let s = if forward {
            (k + i) % n
        } else {
            (k + n - 1 - i) % n
        };
        out.push(s);
        length += seg_length(p.at(s), p.at((s + 1) % n));
        if length > max_mm {
            break;
        }
    }
    out
}

/// The segment among `segs` nearest to `x`, and its distance.
fn nearest(p: &Pline, segs: &[usize], x: V2) -> (usize, f64) {
    segs.iter()
        .map(|&s| (s, (nearest_point(p, s, x) - x).length()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, f64::INFINITY))
}

/// The point of segment `s` nearest to `x`.
fn nearest_point(p: &Pline, s: usize, x: V2) -> V2 {
    let n = p.vertex_count();
    seg_closest_point(p.at(s), p.at((s + 1) % n), x, POS_EPS)
}

/// `offset` (a `cavalier_contours` offset of `source` by `r` mm into its material) with every
/// round join it made at a drawn corner of `source` replaced by the two neighbouring segments
/// extended to where they meet. Where that would make the contour cross itself, the error is
/// the corner's position.
pub fn sharpen(offset: &Pline, source: &Pline, r: f64) -> Result<Pline, V2> {
    let corners = corner_index(source);
    let n = offset.vertex_count();
    if n < 4 {
        return Ok(offset.clone());
    }
    let joins: Vec<bool> = (0..n)
        .map(|i| is_join(offset, i, &corners, source, r))
        .collect();
    // Where each join (not next to another) is replaced by a corner.
    let meets: Vec<Option<V2>> = (0..n)
        .map(|i| {
            let (prev, next) = ((i + n - 1) % n, (i + 1) % n);
            if !joins[i] || joins[prev] || joins[next] {
                return None;
            }
            let at = |k: usize| offset.at(k % n);
            meet(at(prev), at(i), at(next), at(i + 2))
        })
        .collect();
    if meets.iter().all(Option::is_none) {
        return Ok(offset.clone());
    }
    let mut out = Pline::new_closed();
    for k in (0..n).filter(|&k| meets[k].is_none()) {
        let (a, b) = (offset.at(k), offset.at((k + 1) % n));
        let start = meets[(k + n - 1) % n].unwrap_or(a.pos());
        let end = meets[(k + 1) % n].unwrap_or(b.pos());
        let bulge = if a.bulge_is_zero() {
            0.0
        } else {
            sweep_bulge(seg_arc_radius_and_center(a, b).1, start, end, a.bulge > 0.0)
        };
        out.add(start.x, start.y, bulge);
    }
    if crosses_itself_in_um(&out) || out.area() * offset.area() <= 0.0 {
        return Err(meets
            .iter()
            .flatten()
            .next()
            .copied()
            .unwrap_or(pos(offset, 0)));
    }
    Ok(out)
}

/// How many of `cavalier_contours`' units a millimetre is in [`offset_in_um`]: it works in µm.
const UM_PER_MM: f64 = 1000.0;

/// `p.parallel_offset(offset_mm)` (positive: to the left), worked out in micrometres.
///
/// A plan compensated elsewhere as polygons draws each round join as chords, as short as a few
/// µm (GEOS's buffer by 50 µm: 9.5 µm, and less where a join turns less than a quarter). The
/// offset tells whether two neighbouring segments are parallel from the cross product of their
/// vectors against an absolute 1e-5 (`pos_equal_eps`), in the plan's units: in mm, two chords of
/// 7.8 µm meeting at 8.9° (a cross product of 9e-6 mm²) count as parallel, then as overlapping,
/// and the offset comes back as a sliver of no area (GEOS's buffer of a hexagon moved 30 µm
/// into the part: 24 vertices around one spike, the rest lost). In µm the same test takes
/// only lines within 1e-5 µm² of parallel, and the positions it equates are 1e-5 µm apart,
/// still thousands of times what double precision resolves a metre from the origin.
pub fn offset_in_um(p: &Pline, offset_mm: f64) -> Vec<Pline> {
    let mut scaled = p.clone();
    scaled.scale_mut(UM_PER_MM);
    let mut out: Vec<Pline> = scaled.parallel_offset(offset_mm * UM_PER_MM);
    for r in &mut out {
        r.scale_mut(1.0 / UM_PER_MM);
    }
    out
}

/// Whether `p` crosses itself, asked in micrometres: in mm, `cavalier_contours` takes two short
/// segments at an angle for parallel, and overlapping (see [`offset_in_um`]), so a chord polygon
/// moved into its part (chords of 3.6 µm) would be found crossing itself where it does not.
fn crosses_itself_in_um(p: &Pline) -> bool {
    let mut scaled = p.clone();
    scaled.scale_mut(UM_PER_MM);
    scaled.scan_for_self_intersect()
}

/// A closed outline grown outwards by `d` mm (round corners), drawn in the same direction; `None`
/// when the offset is not one outline.
pub fn grow_outline(p: &Pline, d: f64) -> Option<Pline> {
    let ccw = p.area() > 0.0;
    // A positive offset goes left: inwards for a counter-clockwise outline.
    let mut out: Vec<Pline> = p.parallel_offset(if ccw { -d } else { d });
    (out.len() == 1).then(|| out.remove(0))
}

/// A spatial index of a contour's vertices.
fn corner_index(p: &Pline) -> Option<StaticAABB2DIndex<f64>> {
    let mut b = StaticAABB2DIndexBuilder::new(p.vertex_count());
    for v in p.iter_vertexes() {
        b.add(v.x, v.y, v.x, v.y);
    }
    b.build().ok()
}

/// Whether segment `i` of `offset` is a round join: an arc of radius `r` around a vertex of
/// `source`.
fn is_join(
    offset: &Pline,
    i: usize,
    corners: &Option<StaticAABB2DIndex<f64>>,
    source: &Pline,
    r: f64,
) -> bool {
    let (a, b) = (offset.at(i), offset.at((i + 1) % offset.vertex_count()));
    if a.bulge_is_zero() {
        return false;
    }
    let (radius, c) = seg_arc_radius_and_center(a, b);
    // 0.01 µm: a join's centre found again from its ends lands 0.1–0.3 µm off its corner on a
    // large page (AirPurifier's parts at y = 1.3 m, read in single precision), and a join missed
    // stays round (21 µm at a right angle moved 50 µm).
    let tol = 1e-5 * r.max(1.0);
    if (radius - r).abs() > tol {
        return false;
    }
    corners.as_ref().is_some_and(|index| {
        index
            .query(c.x - tol, c.y - tol, c.x + tol, c.y + tol)
            .into_iter()
            .any(|k| (pos(source, k) - c).length() <= tol)
    })
}

/// Where the segment `s0 → s1` and the segment `e0 → e1`, both extended along their own line or
/// circle, meet nearest to the gap `s1`–`e0` between them.
fn meet(
    s0: PlineVertex<f64>,
    s1: PlineVertex<f64>,
    e0: PlineVertex<f64>,
    e1: PlineVertex<f64>,
) -> Option<V2> {
    let gap_mid = (s1.pos() + e0.pos()).scale(0.5);
    let gap = (s1.pos() - e0.pos()).length();
    let candidates: Vec<V2> = match (s0.bulge_is_zero(), e0.bulge_is_zero()) {
        (true, true) => match line_line_intr(s0.pos(), s1.pos(), e0.pos(), e1.pos(), POS_EPS) {
            LineLineIntr::TrueIntersect { seg1_t, .. }
            | LineLineIntr::FalseIntersect { seg1_t, .. } => {
                vec![s0.pos() + (s1.pos() - s0.pos()).scale(seg1_t)]
            }
            _ => Vec::new(),
        },
        (true, false) => line_circle(s0.pos(), s1.pos(), seg_arc_radius_and_center(e0, e1)),
        (false, true) => line_circle(e0.pos(), e1.pos(), seg_arc_radius_and_center(s0, s1)),
        (false, false) => {
            let (r1, c1) = seg_arc_radius_and_center(s0, s1);
            let (r2, c2) = seg_arc_radius_and_center(e0, e1);
            match circle_circle_intr(r1, c1, r2, c2, POS_EPS) {
                CircleCircleIntr::TangentIntersect { point } => vec![point],
                CircleCircleIntr::TwoIntersects { point1, point2 } => vec![point1, point2],
                _ => Vec::new(),
            }
        }
    };
    candidates
        .into_iter()
        .min_by(|p, q| (*p - gap_mid).length().total_cmp(&(*q - gap_mid).length()))
        // A corner far from its gap is a reversal, not a corner: leave it round.
        .filter(|m| (*m - gap_mid).length() <= 50.0 * gap.max(POS_EPS))
}

/// Where the line through `p0`, `p1` meets the circle `(radius, center)`.
fn line_circle(p0: V2, p1: V2, (radius, center): (f64, V2)) -> Vec<V2> {
    let at = |t: f64| p0 + (p1 - p0).scale(t);
    match line_circle_intr(p0, p1, radius, center, POS_EPS) {
        LineCircleIntr::TangentIntersect { t0 } => vec![at(t0)],
        LineCircleIntr::TwoIntersects { t0, t1 } => vec![at(t0), at(t1)],
        LineCircleIntr::NoIntersect => Vec::new(),
    }
}

/// The bulge of the arc around `c` from `s` to `e`, counter-clockwise when `ccw`.
fn sweep_bulge(c: V2, s: V2, e: V2, ccw: bool) -> f64 {
    let (u, w) = (s - c, e - c);
    let mut sweep = u.perp_dot(w).atan2(u.dot(w));
    if ccw && sweep < 0.0 {
        sweep += std::f64::consts::TAU;
    } else if !ccw && sweep > 0.0 {
        sweep -= std::f64::consts::TAU;
    }
    (sweep / 4.0).tan()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An L-shaped part (inner corner at (10, 10)), counter-clockwise.
    fn ell() -> Pline {
        let mut p = Pline::new_closed();
        for (x, y) in [
            (0.0, 0.0),
            (20.0, 0.0),
            (20.0, 10.0),
            (10.0, 10.0),
            (10.0, 20.0),
            (0.0, 20.0),
        ] {
            p.add(x, y, 0.0);
        }
        p
    }

    #[test]
    fn shrinking_keeps_the_inner_corner_sharp_where_a_plain_offset_rounds_it() {
        let d = 0.025;
        let src = ell();
        let plain: Vec<Pline> = src.parallel_offset(d);
        assert_eq!(plain.len(), 1);
        let sharp = sharpen(&plain[0], &src, d).unwrap();
        let corner = v2(10.0 - d, 10.0 - d);
        let has = |p: &Pline| {
            p.iter_vertexes()
                .any(|v| (v.pos() - corner).length() < 1e-9)
        };
        assert!(has(&sharp) && !has(&plain[0]));
        // Everything else is the plain offset: one join arc fewer, one vertex fewer.
        assert_eq!(sharp.vertex_count() + 1, plain[0].vertex_count());
        assert!(sharp.iter_vertexes().all(|v| v.bulge == 0.0));
    }

    /// How the corner (10, 0) of [`square`] is drawn.
    #[derive(Clone, Copy)]
    enum Corner {
        /// As the offset: a quarter arc.
        Clean,
        /// boxes.py's two turns at one point: back 90° around the corner, then on 180° (over
        /// the same arc again), as a finger's last inner turn followed by the polygon's corner
        /// draws it.
        Retraced,
        /// A turn past the corner's own, then part of the way back (CoinDisplay's 60° corners,
        /// turned 90° and back 30°): the second pass runs back over part of one segment.
        Overrun,
    }

    /// The square [0, 10]² offset by `b`, counter-clockwise, turned by 30° and written to 1 µm as
    /// boxes.py writes; its corner (10, 0) drawn as `corner` says.
    fn square(b: f64, corner: Corner) -> Pline {
        let quarter = (std::f64::consts::FRAC_PI_2 / 4.0).tan();
        let mut p = Pline::new_closed();
        p.add(0.0, -b, 0.0);
        match corner {
            Corner::Clean => p.add(10.0, -b, quarter),
            Corner::Retraced => {
                p.add(10.0, -b, -quarter);
                p.add(10.0 - b, 0.0, 1.0);
            }
            Corner::Overrun => {
                // 120° on around the corner, then 30° back to where the edge leaves.
                let (sin, cos) = (std::f64::consts::FRAC_PI_6).sin_cos();
                p.add(10.0, -b, (120f64.to_radians() / 4.0).tan());
                p.add(10.0 + b * cos, b * sin, -(30f64.to_radians() / 4.0).tan());
            }
        }
        for (x, y, bulge) in [
            (10.0 + b, 0.0, 0.0),
            (10.0 + b, 10.0, quarter),
            (10.0, 10.0 + b, 0.0),
            (0.0, 10.0 + b, quarter),
            (-b, 10.0, 0.0),
            (-b, 0.0, quarter),
        ] {
            p.add(x, y, bulge);
        }
        let (sin, cos) = (std::f64::consts::FRAC_PI_6).sin_cos();
        let um = |v: f64| (v * 1000.0).round() / 1000.0;
        let mut turned = Pline::new_closed();
        for v in p.iter_vertexes() {
            turned.add(
                um(cos * v.x - sin * v.y),
                um(sin * v.x + cos * v.y),
                v.bulge,
            );
        }
        turned
    }

    #[test]
    fn an_arc_drawn_back_and_over_again_at_one_corner_is_cut_back_to_the_corner_arc() {
        let b = 0.1;
        let (drawn, clean) = (square(b, Corner::Retraced), square(b, Corner::Clean));
        // It does not cross itself: no loop is found, but a crack runs into the part.
        assert_eq!(remove_crossing_loops(&drawn, 0.5).1, 0);
        let (cut, n) = remove_corner_loops(&drawn, 0.5);
        assert_eq!(n, 1);
        // The corner arc's start as read on each pass, a rounding apart: the line runs on to it.
        assert_eq!(cut.vertex_count(), clean.vertex_count());
        // The clean outline, within boxes.py's rounding.
        for (got, want) in cut.iter_vertexes().zip(clean.iter_vertexes()) {
            assert!((got.pos() - want.pos()).length() < 1e-3, "{got:?} {want:?}");
            assert!((got.bulge - want.bulge).abs() < 0.01, "{got:?} {want:?}");
        }
        let m = square(b, Corner::Retraced).at(2).pos();
        assert!(cut.iter_vertexes().all(|v| (v.pos() - m).length() > 0.05));
        // A tangent leaving a cusp is no retrace: the clean contour and a loop's cusp stay.
        assert_eq!(remove_retraces(&clean, 0.5).1, 0);
    }

    #[test]
    fn a_corner_turned_on_and_part_of_the_way_back_is_cut_where_the_passes_part() {
        let b = 0.1;
        let (drawn, clean) = (square(b, Corner::Overrun), square(b, Corner::Clean));
        assert_eq!(remove_crossing_loops(&drawn, 0.5).1, 0);
        let (cut, n) = remove_corner_loops(&drawn, 0.5);
        assert_eq!(n, 1);
        // The arc runs on to where the edge leaves (boxes.py's rounding apart), and no further:
        // its last point is the clean arc's end, the edge's start.
        let end = clean.at(2).pos();
        assert!(cut.iter_vertexes().any(|v| (v.pos() - end).length() < 2e-3));
        let tip = drawn.at(2).pos();
        assert!(cut.iter_vertexes().all(|v| (v.pos() - tip).length() > 0.01));
        // Every point of the cut contour lies on the clean one, within the rounding.
        for v in cut.iter_vertexes() {
            let d = clean.closest_point(v.pos(), 1e-9).unwrap().distance;
            assert!(d < 2e-3, "{v:?} is {d} mm off");
        }
        assert!((cut.area() - clean.area()).abs() < 1e-3);
    }

    #[test]
    fn a_loop_at_an_inner_corner_is_cut_off_at_its_crossing() {
        // The L offset outwards by 0.1 with boxes.py's back-arc at the inner corner: the edge runs
        // on to (10.1, 10.1)… drawn as x = 10.1 past y = 10.1 and back along an arc.
        let b = 0.1;
        let mut p = Pline::new_closed();
        p.add(-b, -b, 0.0);
        p.add(20.0 + b, -b, 0.0);
        p.add(20.0 + b, 10.0 + b, 0.0);
        // Along y = 10.1 to x = 10, past the crossing at x = 10.1, then back around (10, 10).
        p.add(10.0, 10.0 + b, (-std::f64::consts::FRAC_PI_2 / 4.0).tan());
        p.add(10.0 + b, 10.0, 0.0);
        p.add(10.0 + b, 20.0 + b, 0.0);
        p.add(-b, 20.0 + b, 0.0);
        assert!(p.scan_for_self_intersect());
        let (clean, n) = remove_corner_loops(&p, 0.5);
        assert_eq!(n, 1);
        assert!(!clean.scan_for_self_intersect());
        let x = v2(10.0 + b, 10.0 + b);
        assert!(clean.iter_vertexes().any(|v| (v.pos() - x).length() < 1e-9));
        assert_eq!(clean.vertex_count(), 6);
    }
}
