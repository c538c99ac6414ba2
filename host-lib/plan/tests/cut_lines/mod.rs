//! Cut lines compared as curves: read back from an SVG by usvg (an independent parser), flattened
//! far finer than what is measured, and the symmetric Hausdorff distance between two sets of them
//! computed without a sampling step.
//!
//! **Flattening.** Lines are kept as they are; every Bézier is split until its control points lie
//! within [`FLAT_MM`] (0.01 µm) of its chord, so the polyline is within that of the curve (a
//! Bézier lies in the hull of its control points). usvg itself turns SVG arcs into cubics
//! (kurbo, four to a circle at these sizes): 2.7·10⁻⁴ of the radius at most, 0.014 µm for a
//! 50 µm round join.
//!
//! **Distance.** The directed distance from A to B is the largest distance from a point of A's
//! polylines to B's segments (found with a uniform grid). Along a segment of A the distance to any
//! one segment of B is convex, so an interval of A whose two ends have the same nearest segment of
//! B is no farther from B than its farther end; only where the nearest segment changes is the
//! interval halved, until its bound is within [`BOUND_MM`] (0.001 µm) of the largest distance
//! found. The result is the distance between the flattened lines within that bound; no point
//! between samples is missed.

// Each test file uses its own subset.
#![allow(dead_code)]

use std::collections::HashMap;

/// A point, mm.
pub type P = (f64, f64);

/// A polyline, mm: closed ones repeat their first point at the end.
pub type Line = Vec<P>;

/// Flattened Béziers lie within this of their curves, mm.
pub const FLAT_MM: f64 = 1e-5;
/// The directed distance is exact within this, mm.
const BOUND_MM: f64 = 1e-6;
/// Millimetres per CSS pixel: usvg works in px at 96 per inch.
const MM_PER_PX: f64 = 25.4 / 96.0;

/// A stroked line of an SVG, with the id of the group it is drawn in (the nearest one that has
/// an id; empty for none).
#[derive(Debug, Clone)]
pub struct Drawn {
    pub group: String,
    /// The stroke's colour, RGB.
    pub rgb: [u8; 3],
    pub line: Line,
}

/// The stroked lines of an SVG in document mm (y down), each subpath one line, curves flattened
/// within [`FLAT_MM`].
pub fn read(svg: &str) -> Vec<Drawn> {
    let tree = usvg::Tree::from_str(svg, &usvg::Options::default()).expect("usvg reads the SVG");
    let mut lines = Vec::new();
    collect(tree.root(), "", &mut lines);
    lines
}

/// Whether a line ends where it starts.
pub fn is_closed(l: &[P]) -> bool {
    l.len() > 2 && dist(l[0], l[l.len() - 1]) < 1e-6
}

fn collect(g: &usvg::Group, group: &str, out: &mut Vec<Drawn>) {
    let group = if g.id().is_empty() { group } else { g.id() };
    for n in g.children() {
        match n {
            usvg::Node::Path(p) => {
                let Some(usvg::Paint::Color(c)) = p.stroke().map(usvg::Stroke::paint) else {
                    continue;
                };
                out.extend(flatten(p).into_iter().map(|line| Drawn {
                    group: group.to_string(),
                    rgb: [c.red, c.green, c.blue],
                    line,
                }));
            }
            usvg::Node::Group(c) => collect(c, group, out),
            _ => {}
        }
    }
}

/// A usvg path's subpaths in document mm, curves flattened.
fn flatten(path: &usvg::Path) -> Vec<Line> {
    use usvg::tiny_skia_path::PathSegment;
    let t = path.abs_transform();
    let map = |p: usvg::tiny_skia_path::Point| {
        let (x, y) = (f64::from(p.x), f64::from(p.y));
        (
            (f64::from(t.sx) * x + f64::from(t.kx) * y + f64::from(t.tx)) * MM_PER_PX,
            (f64::from(t.ky) * x + f64::from(t.sy) * y + f64::from(t.ty)) * MM_PER_PX,
        )
    };
    let mut out: Vec<Line> = Vec::new();
    for seg in path.data().segments() {
        match seg {
            PathSegment::MoveTo(p) => out.push(vec![map(p)]),
            PathSegment::LineTo(p) => push(&mut out, map(p)),
            PathSegment::QuadTo(a, b) => {
                let s = last(&out);
                let (a, b) = (map(a), map(b));
                // The same curve as a cubic.
                let c1 = lerp(s, a, 2.0 / 3.0);
                let c2 = lerp(b, a, 2.0 / 3.0);
                cubic(&mut out, [s, c1, c2, b]);
            }
            PathSegment::CubicTo(a, b, c) => {
                let s = last(&out);
                cubic(&mut out, [s, map(a), map(b), map(c)]);
            }
            PathSegment::Close => {
                let first = out.last().expect("a subpath")[0];
                push(&mut out, first);
            }
        }
    }
    out
}

fn last(out: &[Line]) -> P {
    *out.last().and_then(|l| l.last()).expect("a current point")
}

fn push(out: &mut [Line], p: P) {
    let line = out.last_mut().expect("a subpath");
    if line.last() != Some(&p) {
        line.push(p);
    }
}

fn lerp(a: P, b: P, t: f64) -> P {
    (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t)
}

/// Append a cubic Bézier, split until flat within [`FLAT_MM`].
fn cubic(out: &mut [Line], c: [P; 4]) {
    let flat = seg_dist(c[1], c[0], c[3]).max(seg_dist(c[2], c[0], c[3])) <= FLAT_MM;
    if flat || dist(c[0], c[3]) + dist(c[0], c[1]) < 1e-9 {
        push(out, c[3]);
        return;
    }
    let (ab, bc, cd) = (
        lerp(c[0], c[1], 0.5),
        lerp(c[1], c[2], 0.5),
        lerp(c[2], c[3], 0.5),
    );
    let (abc, bcd) = (lerp(ab, bc, 0.5), lerp(bc, cd, 0.5));
    let mid = lerp(abc, bcd, 0.5);
    cubic(out, [c[0], ab, abc, mid]);
    cubic(out, [mid, bcd, cd, c[3]]);
}

pub fn dist(a: P, b: P) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

/// Distance from `p` to the segment `a`–`b`.
pub fn seg_dist(p: P, a: P, b: P) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let t = if l2 == 0.0 {
        0.0
    } else {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0)
    };
    (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
}

/// The lines moved by `d`.
pub fn shifted(lines: &[Line], d: P) -> Vec<Line> {
    lines
        .iter()
        .map(|l| l.iter().map(|p| (p.0 + d.0, p.1 + d.1)).collect())
        .collect()
}

/// The area centroid of a closed line (its signed area must not be 0).
pub fn centroid(l: &[P]) -> P {
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for w in l.windows(2) {
        let c = w[0].0 * w[1].1 - w[1].0 * w[0].1;
        a += c;
        cx += (w[0].0 + w[1].0) * c;
        cy += (w[0].1 + w[1].1) * c;
    }
    (cx / (3.0 * a), cy / (3.0 * a))
}

/// A uniform grid of segments.
struct Grid {
    segs: Vec<(P, P)>,
    cells: HashMap<(i64, i64), Vec<usize>>,
    cell_mm: f64,
}

/// How far a query looks before it gives up, mm (a farther point reports this).
const SEARCH_MM: f64 = 2.0;

impl Grid {
    fn new(lines: &[Line], cell_mm: f64) -> Self {
        let mut segs = Vec::new();
        let mut cells: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        for l in lines {
            for w in l.windows(2) {
                let id = segs.len();
                segs.push((w[0], w[1]));
                let (x0, x1) = (w[0].0.min(w[1].0), w[0].0.max(w[1].0));
                let (y0, y1) = (w[0].1.min(w[1].1), w[0].1.max(w[1].1));
                let cell = |v: f64| (v / cell_mm).floor() as i64;
                for i in cell(x0)..=cell(x1) {
                    for j in cell(y0)..=cell(y1) {
                        cells.entry((i, j)).or_default().push(id);
                    }
                }
            }
        }
        Grid {
            segs,
            cells,
            cell_mm,
        }
    }

    /// The distance from `p` to the nearest segment and that segment (`usize::MAX` and
    /// [`SEARCH_MM`] when none is that near).
    fn nearest(&self, p: P) -> (f64, usize) {
        let (ci, cj) = (
            (p.0 / self.cell_mm).floor() as i64,
            (p.1 / self.cell_mm).floor() as i64,
        );
        let mut best = (SEARCH_MM, usize::MAX);
        let rings = (SEARCH_MM / self.cell_mm).ceil() as i64 + 1;
        for k in 0..=rings {
            for (i, j) in ring(ci, cj, k) {
                for &s in self.cells.get(&(i, j)).into_iter().flatten() {
                    let d = seg_dist(p, self.segs[s].0, self.segs[s].1);
                    if d < best.0 || (d == best.0 && s < best.1) {
                        best = (d, s);
                    }
                }
            }
            // Every cell within k rings is searched: nothing farther out is nearer than k cells.
            if best.0 <= k as f64 * self.cell_mm {
                break;
            }
        }
        best
    }

    fn to_seg(&self, p: P, s: usize) -> f64 {
        if s == usize::MAX {
            return SEARCH_MM;
        }
        seg_dist(p, self.segs[s].0, self.segs[s].1)
    }
}

/// The cells at Chebyshev distance `k` from `(i, j)`.
fn ring(i: i64, j: i64, k: i64) -> Vec<(i64, i64)> {
    if k == 0 {
        return vec![(i, j)];
    }
    let mut v = Vec::with_capacity(8 * k as usize);
    for d in -k..=k {
        v.extend([(i + d, j - k), (i + d, j + k)]);
    }
    for d in (-k + 1)..k {
        v.extend([(i - k, j + d), (i + k, j + d)]);
    }
    v
}

/// The largest distance from a point of `a` to `b`, and where on `a` it is.
#[derive(Debug, Clone, Copy)]
pub struct Deviation {
    /// mm.
    pub mm: f64,
    /// Where, mm.
    pub at: P,
}

/// The directed Hausdorff distance from the lines `a` to the lines `b` (see the module doc).
pub fn directed(a: &[Line], b: &[Line]) -> Deviation {
    let grid = Grid::new(b, 0.5);
    let mut worst = Deviation {
        mm: 0.0,
        at: (0.0, 0.0),
    };
    let note = |d: f64, p: P, worst: &mut Deviation| {
        if d > worst.mm {
            *worst = Deviation { mm: d, at: p };
        }
    };
    // Every vertex first: a good bound prunes most intervals.
    let mut ends: Vec<Vec<(f64, usize)>> = Vec::with_capacity(a.len());
    for l in a {
        let e: Vec<(f64, usize)> = l.iter().map(|&p| grid.nearest(p)).collect();
        for (p, (d, _)) in l.iter().zip(&e) {
            note(*d, *p, &mut worst);
        }
        ends.push(e);
    }
    for (l, e) in a.iter().zip(&ends) {
        for k in 1..l.len() {
            let mut stack = vec![((l[k - 1], e[k - 1]), (l[k], e[k]))];
            while let Some(((p, (dp, sp)), (q, (dq, sq)))) = stack.pop() {
                if sp == sq {
                    continue;
                }
                // Convex along the interval: each end's nearest segment bounds the other half.
                let bound = (dp.max(grid.to_seg(q, sp)))
                    .min(dq.max(grid.to_seg(p, sq)))
                    .min(dp.max(dq) + dist(p, q) / 2.0);
                if bound <= worst.mm + BOUND_MM || dist(p, q) < BOUND_MM {
                    continue;
                }
                let m = lerp(p, q, 0.5);
                let em = grid.nearest(m);
                note(em.0, m, &mut worst);
                stack.push(((p, (dp, sp)), (m, em)));
                stack.push(((m, em), (q, (dq, sq))));
            }
        }
    }
    worst
}

/// The symmetric Hausdorff distance between the lines `a` and `b`: the larger directed one.
pub fn hausdorff(a: &[Line], b: &[Line]) -> Deviation {
    let (ab, ba) = (directed(a, b), directed(b, a));
    if ab.mm >= ba.mm { ab } else { ba }
}
