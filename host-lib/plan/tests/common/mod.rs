//! What the plan tests share: reading an SVG back through usvg (an independent parser) into
//! sampled polylines in millimetres, finding its elements by id, and point-to-segment distance.

// Each test file uses its own subset.
#![allow(dead_code)]

/// A sampled polyline, mm.
pub type Poly = Vec<(f64, f64)>;

/// Millimetres per CSS pixel: usvg works in px at 96 per inch.
pub const MM_PER_CSS_PX: f64 = 25.4 / 96.0;

/// How to sample a usvg path.
pub struct Sampling {
    /// Document mm per usvg unit.
    pub mm_per_px: f64,
    /// Points per quadratic or cubic Bézier segment.
    pub points_per_curve: u32,
    /// Whether a `Close` repeats the subpath's first point (a closed ring) or adds nothing.
    pub close_rings: bool,
}

/// The subpaths of a usvg path in document mm (y down), curves sampled per `sampling`.
pub fn subpaths(path: &usvg::Path, sampling: &Sampling) -> Vec<Poly> {
    use usvg::tiny_skia_path::PathSegment;
    let t = path.abs_transform();
    let mm = sampling.mm_per_px;
    let map = |p: usvg::tiny_skia_path::Point| {
        let (x, y) = (f64::from(p.x), f64::from(p.y));
        (
            (f64::from(t.sx) * x + f64::from(t.kx) * y + f64::from(t.tx)) * mm,
            (f64::from(t.ky) * x + f64::from(t.sy) * y + f64::from(t.ty)) * mm,
        )
    };
    let mut out: Vec<Poly> = Vec::new();
    let mut last = (0.0, 0.0);
    for seg in path.data().segments() {
        let points = match seg {
            PathSegment::MoveTo(p) => {
                out.push(Vec::new());
                vec![map(p)]
            }
            PathSegment::LineTo(p) => vec![map(p)],
            PathSegment::QuadTo(a, b) => bezier(&[last, map(a), map(b)], sampling.points_per_curve),
            PathSegment::CubicTo(a, b, c) => {
                bezier(&[last, map(a), map(b), map(c)], sampling.points_per_curve)
            }
            PathSegment::Close if sampling.close_rings => vec![out.last().unwrap()[0]],
            PathSegment::Close => Vec::new(),
        };
        if let Some(&end) = points.last() {
            last = end;
        }
        out.last_mut().unwrap().extend(points);
    }
    out
}

/// `n` points along a quadratic or cubic Bézier (control points `c`), excluding its start.
fn bezier(c: &[(f64, f64)], n: u32) -> Poly {
    (1..=n)
        .map(|i| {
            let s = f64::from(i) / f64::from(n);
            let u = 1.0 - s;
            let w: &[f64] = if c.len() == 3 {
                &[u * u, 2.0 * u * s, s * s]
            } else {
                &[u * u * u, 3.0 * u * u * s, 3.0 * u * s * s, s * s * s]
            };
            let x = w.iter().zip(c).map(|(w, p)| w * p.0).sum();
            let y = w.iter().zip(c).map(|(w, p)| w * p.1).sum();
            (x, y)
        })
        .collect()
}

/// Every path below `g`, in document order.
pub fn all_paths(g: &usvg::Group) -> Vec<&usvg::Path> {
    let mut v = Vec::new();
    for n in g.children() {
        match n {
            usvg::Node::Path(p) => v.push(p.as_ref()),
            usvg::Node::Group(c) => v.extend(all_paths(c)),
            _ => {}
        }
    }
    v
}

/// The path with this id below `g`.
pub fn path_by_id<'a>(g: &'a usvg::Group, id: &str) -> &'a usvg::Path {
    all_paths(g)
        .into_iter()
        .find(|p| p.id() == id)
        .unwrap_or_else(|| panic!("no path {id}"))
}

/// Distance from `p` to the segment `a`–`b`.
pub fn seg_dist(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let t = if l2 == 0.0 {
        0.0
    } else {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0)
    };
    (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
}
