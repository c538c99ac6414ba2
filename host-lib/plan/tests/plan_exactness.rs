//! Dilation checked against an independent implementation: `geo`'s buffer (on `i_overlay`) with
//! round joins, on random polygons with holes and islands. The boundaries must agree within 1 µm
//! (symmetric Hausdorff distance; both sides' arcs flattened far finer than that) and the area
//! growth within 0.1 %. (The Hausdorff distance is measured here, exactly point-to-segment on
//! finely sampled lines: `geo`'s own is vertex-to-vertex.)

mod common;

use std::f64::consts::TAU;

use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline};
use common::seg_dist;
use geo::algorithm::buffer::{Buffer, BufferStyle, LineJoin};
use geo::{Area, LineString, MultiPolygon, Polygon};
use kerfmeter_plan::dilate::{Contour, KerfSource, Role, dilate};

/// xorshift64*: a small deterministic generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// A random star-shaped (hence simple) polygon around `c` with radii in [r0, r1].
fn star(rng: &mut Rng, c: (f64, f64), r0: f64, r1: f64, n: usize) -> Vec<(f64, f64)> {
    let mut angles: Vec<f64> = (0..n).map(|_| rng.range(0.0, TAU)).collect();
    angles.sort_by(f64::total_cmp);
    angles.dedup_by(|a, b| (*a - *b).abs() < 0.02);
    angles
        .into_iter()
        .map(|a| {
            let r = rng.range(r0, r1);
            (c.0 + r * a.cos(), c.1 + r * a.sin())
        })
        .collect()
}

fn pline(points: &[(f64, f64)]) -> Polyline<f64> {
    let mut p = Polyline::new_closed();
    for &(x, y) in points {
        p.add(x, y, 0.0);
    }
    p
}

fn ring(points: &[(f64, f64)]) -> LineString<f64> {
    let mut v: Vec<(f64, f64)> = points.to_vec();
    v.push(points[0]);
    LineString::from(v)
}

/// A closed polyline with arcs, flattened so that no chord strays more than `tol` from its arc.
fn flatten(p: &Polyline<f64>, tol: f64) -> Vec<(f64, f64)> {
    let n = p.vertex_count();
    let mut out = Vec::new();
    for i in 0..n {
        let (v, w) = (p.at(i), p.at((i + 1) % n));
        out.push((v.x, v.y));
        if v.bulge == 0.0 {
            continue;
        }
        // Arc from v to w: sweep θ = 4·atan(bulge), radius from the chord.
        let theta = 4.0 * v.bulge.atan();
        let chord = (w.x - v.x).hypot(w.y - v.y);
        let r = chord / (2.0 * (theta / 2.0).sin().abs());
        let (ux, uy) = ((w.x - v.x) / chord, (w.y - v.y) / chord);
        let h = r * (theta / 2.0).cos() * theta.signum();
        let (cx, cy) = ((v.x + w.x) / 2.0 - uy * h, (v.y + w.y) / 2.0 + ux * h);
        let start = (v.y - cy).atan2(v.x - cx);
        let step = 2.0 * (1.0 - tol / r).acos();
        let k = (theta.abs() / step).ceil().max(1.0) as usize;
        for j in 1..k {
            let a = start + theta * j as f64 / k as f64;
            out.push((cx + r * a.cos(), cy + r * a.sin()));
        }
    }
    out
}

/// A segment between two points.
type Segment = ((f64, f64), (f64, f64));

/// Segments of closed rings bucketed on a grid, for nearest-segment distances.
struct SegmentGrid {
    cell: f64,
    cells: std::collections::HashMap<(i64, i64), Vec<Segment>>,
}

impl SegmentGrid {
    fn new(rings: &[Vec<(f64, f64)>], cell: f64) -> Self {
        let mut cells: std::collections::HashMap<(i64, i64), Vec<_>> = Default::default();
        for r in rings {
            for w in r.windows(2) {
                let (a, b) = (w[0], w[1]);
                let (x0, x1) = (a.0.min(b.0), a.0.max(b.0));
                let (y0, y1) = (a.1.min(b.1), a.1.max(b.1));
                for i in (x0 / cell).floor() as i64..=(x1 / cell).floor() as i64 {
                    for j in (y0 / cell).floor() as i64..=(y1 / cell).floor() as i64 {
                        cells.entry((i, j)).or_default().push((a, b));
                    }
                }
            }
        }
        Self { cell, cells }
    }

    /// Distance to the nearest segment (looked for in the neighbouring cells: enough for the
    /// small distances measured here; farther is reported as infinite).
    fn distance(&self, p: (f64, f64)) -> f64 {
        let (i, j) = (
            (p.0 / self.cell).floor() as i64,
            (p.1 / self.cell).floor() as i64,
        );
        let mut best = f64::INFINITY;
        for di in -1..=1 {
            for dj in -1..=1 {
                for &(a, b) in self.cells.get(&(i + di, j + dj)).into_iter().flatten() {
                    best = best.min(seg_dist(p, a, b));
                }
            }
        }
        best
    }
}

/// Directed Hausdorff distance from polylines `a` (sampled every 10 µm along each segment) to
/// polylines `b`.
fn directed_hausdorff(a: &[Vec<(f64, f64)>], b: &SegmentGrid) -> f64 {
    let mut worst: f64 = 0.0;
    for r in a {
        for w in r.windows(2) {
            let (p, q) = (w[0], w[1]);
            let n = ((q.0 - p.0).hypot(q.1 - p.1) / 0.01).ceil().max(1.0) as usize;
            for k in 0..=n {
                let t = k as f64 / n as f64;
                worst = worst.max(b.distance((p.0 + (q.0 - p.0) * t, p.1 + (q.1 - p.1) * t)));
            }
        }
    }
    worst
}

/// Symmetric Hausdorff distance between two sets of closed rings.
fn hausdorff(a: &[Vec<(f64, f64)>], b: &[Vec<(f64, f64)>]) -> f64 {
    let (ga, gb) = (SegmentGrid::new(a, 0.25), SegmentGrid::new(b, 0.25));
    directed_hausdorff(a, &gb).max(directed_hausdorff(b, &ga))
}

#[test]
fn dilation_matches_geo_buffer_on_random_polygons_with_holes_and_islands() {
    let mut rng = Rng(0x5eed_cafe_f00d_beef);
    let mut worst_hausdorff: f64 = 0.0;
    let mut worst_area: f64 = 0.0;
    for case in 0..24 {
        let c = (rng.range(-50.0, 50.0), rng.range(-50.0, 50.0));
        // An outer outline, a big central hole, a few small holes in the rim, an island in the
        // central hole.
        let outer = star(&mut rng, c, 20.0, 30.0, 40);
        let hole = star(&mut rng, c, 8.0, 13.0, 24);
        let island = star(&mut rng, c, 2.0, 4.5, 12);
        let mut small_holes = Vec::new();
        for k in 0..3 {
            let a = TAU * (k as f64 + rng.range(0.1, 0.9)) / 3.0;
            let hc = (c.0 + 16.5 * a.cos(), c.1 + 16.5 * a.sin());
            small_holes.push(star(&mut rng, hc, 0.8, 1.8, 10));
        }
        let kerf_um = rng.range(50.0, 400.0);
        let d = kerf_um / 2000.0;

        // Ours. Directions are deliberately mixed: they must not matter.
        let mut contours = vec![
            Contour {
                pline: pline(&outer),
                label: "outer".into(),
            },
            Contour {
                pline: pline(&hole),
                label: "hole".into(),
            },
            Contour {
                pline: pline(&island),
                label: "island".into(),
            },
        ];
        if case % 2 == 0 {
            contours[1].pline.invert_direction_mut();
        }
        for (k, h) in small_holes.iter().enumerate() {
            contours.push(Contour {
                pline: pline(h),
                label: format!("small hole {k}"),
            });
        }
        let result = dilate(&contours, &KerfSource::Uniform(kerf_um)).unwrap();
        assert_eq!(result.roles[0], Role::Outer);
        assert_eq!(result.roles[1], Role::Hole);
        assert_eq!(result.roles[2], Role::Outer, "an island grows again");
        assert_eq!(result.parts.len(), 2);
        let ours: Vec<Vec<(f64, f64)>> = result.contours.iter().map(|p| flatten(p, 1e-5)).collect();

        // geo: the same region as polygons, buffered with fine round joins.
        let mut interiors = vec![ring(&hole)];
        interiors.extend(small_holes.iter().map(|h| ring(h)));
        let region = MultiPolygon::new(vec![
            Polygon::new(ring(&outer), interiors),
            Polygon::new(ring(&island), vec![]),
        ]);
        let style = BufferStyle::new(d).line_join(LineJoin::Round(0.002));
        let theirs = region.buffer_with_style(style);

        // Boundaries as rings of points.
        let theirs_rings: Vec<Vec<(f64, f64)>> = theirs
            .iter()
            .flat_map(|p| std::iter::once(p.exterior()).chain(p.interiors()))
            .map(|r| r.coords().map(|c| (c.x, c.y)).collect())
            .collect();
        let ours_rings: Vec<Vec<(f64, f64)>> = ours
            .iter()
            .map(|r| r.iter().copied().chain(std::iter::once(r[0])).collect())
            .collect();
        assert_eq!(
            ours_rings.len(),
            theirs_rings.len(),
            "case {case}: same number of boundaries"
        );
        let h = hausdorff(&ours_rings, &theirs_rings);
        worst_hausdorff = worst_hausdorff.max(h);
        assert!(h <= 1e-3, "case {case}: Hausdorff {} µm", h * 1e3);

        // Area growth.
        let area_in = region.unsigned_area();
        let area_ours: f64 = result
            .parts
            .iter()
            .map(|p| {
                result.contours[p.outer].area().abs()
                    - p.holes
                        .iter()
                        .map(|&h| result.contours[h].area().abs())
                        .sum::<f64>()
            })
            .sum();
        let area_theirs = theirs.unsigned_area();
        let growth_ours = area_ours - area_in;
        let growth_theirs = area_theirs - area_in;
        let rel = (growth_ours - growth_theirs).abs() / growth_theirs;
        worst_area = worst_area.max(rel);
        assert!(
            growth_ours > 0.0 && rel <= 1e-3,
            "case {case}: growth {growth_ours} vs {growth_theirs}"
        );
    }
    println!(
        "worst Hausdorff {:.4} µm, worst area-growth difference {:.5} %",
        worst_hausdorff * 1e3,
        worst_area * 100.0
    );
}
