//! Closed loops from a DXF's open cut pieces (LINEs, ARCs, open polylines), the same whatever
//! order the CAD program wrote the entities in.
//!
//! **The rule.**
//! 1. Piece ends within [`JOIN_MM`] of each other are one *node* (every pair within reach is
//!    joined, so the nodes do not depend on which end is looked at first).
//! 2. A piece with an end that no other piece reaches lies on no loop: it is an open path (a
//!    lead line, a slit, a dimension's tick), and so, in turn, is every piece left with such an
//!    end once it is set aside. What remains is the part of the drawing where every node joins at
//!    least two pieces.
//! 3. There, each connected group whose nodes each join exactly two pieces is one closed loop: a
//!    cut contour.
//! 4. A group with a node where three or more pieces still meet is ambiguous (an outline with a
//!    line across it, two outlines sharing an edge, a figure eight): which closed outlines are
//!    meant cannot be told, and dilating every loop would cut parts that share an edge. The plan
//!    is refused, naming each such junction, its position and the pieces that meet there.
//!
//! Steps 1–3 are order-free: a node's pieces, the pieces set aside in step 2 (the complement of
//! the graph's 2-core) and the groups of step 3 are the same for any order of the entities. A
//! loop starts at its piece of the lowest index and runs that piece's way, so the same contours
//! come out, each from the same point, up to the entities' order.

use std::collections::HashMap;

use super::JOIN_MM;
use super::geometry::Piece;
use crate::geom::V2;

/// A node where three or more cut pieces meet after the open ends are set aside.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Junction {
    /// Where, mm (document space).
    pub at_mm: V2,
    /// The pieces that meet there (indexes into the pieces given).
    pub pieces: Vec<usize>,
}

/// The pieces sorted into closed loops and open paths, or the junctions that make it ambiguous.
#[derive(Debug, Default)]
pub(super) struct Sorted {
    /// Each closed loop, its pieces joined end to end (the last vertex back at the first).
    pub loops: Vec<Piece>,
    /// The open paths: the pieces set aside, joined end to end through the nodes only two of them
    /// share.
    pub open: Vec<Piece>,
    /// Where the remaining cut lines branch (empty when none do).
    pub junctions: Vec<Junction>,
}

/// Sort `pieces` by the rule of this module.
pub(super) fn sort(pieces: Vec<Piece>) -> Sorted {
    let ends: Vec<[V2; 2]> = pieces.iter().map(|p| [p.start(), p.end()]).collect();
    let node_of = nodes(&ends);
    let in_core = two_core(&node_of, node_count(&node_of));
    let mut slots: Vec<Option<Piece>> = pieces.into_iter().map(Some).collect();
    let core = Graph::new(&node_of, &in_core);
    let junctions = core.junctions(&ends);
    let mut sorted = Sorted {
        junctions,
        ..Sorted::default()
    };
    if sorted.junctions.is_empty() {
        sorted.loops = core.walk_all(&mut slots, &node_of, true);
    }
    let set_aside: Vec<bool> = in_core.iter().map(|c| !c).collect();
    let open = Graph::new(&node_of, &set_aside);
    sorted.open = open.walk_all(&mut slots, &node_of, false);
    sorted
}

/// Each piece's two end nodes: ends within [`JOIN_MM`] share one (transitively), numbered from
/// 0 in order of first appearance.
fn nodes(ends: &[[V2; 2]]) -> Vec<[usize; 2]> {
    let points: Vec<V2> = ends.iter().flatten().copied().collect();
    let cell = |p: V2| {
        (
            (p.x / JOIN_MM).floor() as i64,
            (p.y / JOIN_MM).floor() as i64,
        )
    };
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (i, &p) in points.iter().enumerate() {
        grid.entry(cell(p)).or_default().push(i);
    }
    let mut sets = UnionFind::new(points.len());
    for (i, &p) in points.iter().enumerate() {
        let (cx, cy) = cell(p);
        for (dx, dy) in (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))) {
            for &j in grid.get(&(cx + dx, cy + dy)).into_iter().flatten() {
                if j > i && (points[j] - p).length() <= JOIN_MM {
                    sets.union(i, j);
                }
            }
        }
    }
    let mut numbers: HashMap<usize, usize> = HashMap::new();
    let mut number = |point: usize, sets: &mut UnionFind| {
        let next = numbers.len();
        *numbers.entry(sets.find(point)).or_insert(next)
    };
    (0..ends.len())
        .map(|k| [number(2 * k, &mut sets), number(2 * k + 1, &mut sets)])
        .collect()
}

fn node_count(node_of: &[[usize; 2]]) -> usize {
    node_of.iter().flatten().max().map_or(0, |&n| n + 1)
}

/// Which pieces lie in the graph's 2-core: pieces are set aside while a node joins one piece
/// only (a piece from a node back to itself counts twice there).
fn two_core(node_of: &[[usize; 2]], nodes: usize) -> Vec<bool> {
    let mut degree = vec![0usize; nodes];
    let mut at: Vec<Vec<usize>> = vec![Vec::new(); nodes];
    for (k, &[a, b]) in node_of.iter().enumerate() {
        degree[a] += 1;
        degree[b] += 1;
        at[a].push(k);
        if b != a {
            at[b].push(k);
        }
    }
    let mut in_core = vec![true; node_of.len()];
    let mut lone: Vec<usize> = (0..nodes).filter(|&n| degree[n] == 1).collect();
    while let Some(n) = lone.pop() {
        let Some(&k) = at[n].iter().find(|&&k| in_core[k]) else {
            continue;
        };
        in_core[k] = false;
        for end in node_of[k] {
            degree[end] -= 1;
            if degree[end] == 1 {
                lone.push(end);
            }
        }
    }
    in_core
}

/// The pieces chosen by `member`, by node.
struct Graph {
    /// At each node, the chosen pieces that end there (a piece from the node to itself twice).
    at: Vec<Vec<usize>>,
    member: Vec<bool>,
}

impl Graph {
    fn new(node_of: &[[usize; 2]], member: &[bool]) -> Self {
        let mut at = vec![Vec::new(); node_count(node_of)];
        for (k, ends) in node_of.iter().enumerate().filter(|(k, _)| member[*k]) {
            for &n in ends {
                at[n].push(k);
            }
        }
        Graph {
            at,
            member: member.to_vec(),
        }
    }

    /// The nodes where three or more pieces meet, with where they are.
    fn junctions(&self, ends: &[[V2; 2]]) -> Vec<Junction> {
        let mut found = Vec::new();
        for pieces in self.at.iter().filter(|p| p.len() >= 3) {
            let k = pieces[0];
            let mut unique = pieces.clone();
            unique.dedup();
            // Any end of the first piece at this node: they are all within reach of it.
            let at_mm = self.end_here(k, pieces, ends);
            found.push(Junction {
                at_mm,
                pieces: unique,
            });
        }
        found.sort_by(|a, b| a.pieces.cmp(&b.pieces));
        found
    }

    /// Where piece `k` ends at the node whose pieces are `here`.
    fn end_here(&self, k: usize, here: &[usize], ends: &[[V2; 2]]) -> V2 {
        // The end shared with another piece of the node, else the start.
        let [s, e] = ends[k];
        let other = here.iter().find(|&&j| j != k).copied();
        match other {
            Some(j) => {
                let [a, b] = ends[j];
                let near = |p: V2| (p - a).length().min((p - b).length());
                if near(s) <= near(e) { s } else { e }
            }
            None => s,
        }
    }

    /// Walk every chain of the chosen pieces, from the lowest piece not yet taken: loops (`closed`,
    /// every node of degree 2) or paths through the nodes of degree 2.
    fn walk_all(
        &self,
        slots: &mut [Option<Piece>],
        node_of: &[[usize; 2]],
        closed: bool,
    ) -> Vec<Piece> {
        let members = (0..slots.len()).filter(|&k| self.member[k]);
        // Paths start at a piece with an end that is not a pass-through node (the pieces set
        // aside form no loop, but any left over are walked after them); loops anywhere.
        let path_end = |k: &usize| node_of[*k].iter().any(|&n| self.at[n].len() != 2);
        let (ends_first, rest): (Vec<usize>, Vec<usize>) =
            members.partition(|k| closed || path_end(k));
        ends_first
            .into_iter()
            .chain(rest)
            .filter_map(|k| self.walk(k, slots, node_of))
            .collect()
    }

    /// The chain that starts with piece `k` (if still free), oriented so that it leaves a node
    /// that is not a pass-through (or its own way, on a loop), through nodes of degree 2.
    fn walk(&self, k: usize, slots: &mut [Option<Piece>], node_of: &[[usize; 2]]) -> Option<Piece> {
        let first = slots[k].take()?;
        let [a, b] = node_of[k];
        let turn = self.at[b].len() != 2 && self.at[a].len() == 2;
        let (mut chain, mut node) = if turn {
            (first.reversed(), a)
        } else {
            (first, b)
        };
        let start = if turn { b } else { a };
        while self.at[node].len() == 2 && !(node == start && chain.vertices.len() > 2) {
            let Some(&j) = self.at[node].iter().find(|&&j| slots[j].is_some()) else {
                break;
            };
            let next = slots[j].take()?;
            let [ja, jb] = node_of[j];
            let (next, far) = if ja == node {
                (next, jb)
            } else {
                (next.reversed(), ja)
            };
            chain.append(next);
            node = far;
        }
        Some(chain)
    }
}

/// Disjoint sets of points, with path halving.
struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n).collect(),
        }
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn union(&mut self, i: usize, j: usize) {
        let (a, b) = (self.find(i), self.find(j));
        // The lower root wins: the sets, and so the nodes, are the same whatever the order.
        if a != b {
            self.parent[a.max(b)] = a.min(b);
        }
    }
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use dxf::entities::{Arc, Entity, EntityType, Line, LwPolyline};
    use dxf::enums::{AcadVersion, Units};
    use dxf::{Drawing, Point};

    use super::super::{DxfOptions, dilate_dxf};
    use crate::dilate::KerfSource;
    use crate::geom::area_and_centroid;
    use crate::outcome::PlanSummary;

    /// A cut line (red, ACI 1) from `a` to `b`.
    fn line(a: (f64, f64), b: (f64, f64)) -> Entity {
        let mut e = Entity::new(EntityType::Line(Line::new(
            Point::new(a.0, a.1, 0.0),
            Point::new(b.0, b.1, 0.0),
        )));
        e.common.color = dxf::Color::from_index(1);
        e
    }

    /// A cut arc about `c`, counter-clockwise from `from_deg` to `to_deg`.
    fn arc(c: (f64, f64), r: f64, from_deg: f64, to_deg: f64) -> Entity {
        let mut e = Entity::new(EntityType::Arc(Arc::new(
            Point::new(c.0, c.1, 0.0),
            r,
            from_deg,
            to_deg,
        )));
        e.common.color = dxf::Color::from_index(1);
        e
    }

    /// The pieces of the shapes, as LibreCAD's symbols draw them: a gate body closed by
    /// two arcs and two lines with a lead line touching one of its corners, an arrowhead (three
    /// lines) with its shaft at a tip, a square of four lines, and a slit. Lines can be drawn
    /// either way (`flip`); arcs only counter-clockwise, as DXF has them.
    fn pieces(flip: &[bool]) -> Vec<Entity> {
        let l = |k: usize, a, b| if flip[k] { line(b, a) } else { line(a, b) };
        vec![
            // Gate body: a half disc of radius 10 about (10, 0), closed by its diameter drawn as
            // two lines: its corners at (0, 0), (10, 0) and (20, 0).
            arc((10.0, 0.0), 10.0, 0.0, 180.0),
            l(0, (0.0, 0.0), (10.0, 0.0)),
            l(1, (10.0, 0.0), (20.0, 0.0)),
            // The lead line touching the corner at (20, 0).
            l(2, (20.0, 0.0), (30.0, 0.0)),
            // The arrowhead and its shaft from the tip at (40, 10).
            l(3, (40.0, 10.0), (45.0, 12.0)),
            l(4, (45.0, 12.0), (45.0, 8.0)),
            l(5, (45.0, 8.0), (40.0, 10.0)),
            l(6, (40.0, 10.0), (30.0, 10.0)),
            // A square.
            l(7, (50.0, 0.0), (60.0, 0.0)),
            l(8, (60.0, 0.0), (60.0, 10.0)),
            l(9, (60.0, 10.0), (50.0, 10.0)),
            l(10, (50.0, 10.0), (50.0, 0.0)),
            // A slit.
            l(11, (70.0, 0.0), (70.0, 10.0)),
        ]
    }

    /// A small deterministic generator (the test's seed is its own).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> u64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            self.0 >> 33
        }
    }

    /// An output contour's area and centroid, in units of 0.1 nm (²).
    type Shape = (i64, i64, i64);

    /// Dilate `entities` in this order: the summary, and each output contour's area and centroid
    /// (sorted, rounded to 0.1 nm).
    fn dilated(entities: Vec<Entity>) -> (PlanSummary, Vec<Shape>) {
        let mut d = Drawing::new();
        d.header.version = AcadVersion::R2000;
        d.header.default_drawing_units = Units::Millimeters;
        for e in entities {
            d.add_entity(e);
        }
        let mut bytes = Vec::new();
        d.save(&mut bytes).unwrap();
        let (out, summary) =
            dilate_dxf(&bytes, &KerfSource::Uniform(150.0), &DxfOptions::default()).unwrap();
        let out = Drawing::load(&mut Cursor::new(out)).unwrap();
        let round = |x: f64| (x * 1e7).round() as i64;
        let mut shapes: Vec<Shape> = out
            .entities()
            .filter_map(|e| match &e.specific {
                EntityType::LwPolyline(p) => Some(contour(p)),
                _ => None,
            })
            .map(|(a, c)| (round(a), round(c.0), round(c.1)))
            .collect();
        shapes.sort_unstable();
        (summary, shapes)
    }

    fn contour(p: &LwPolyline) -> (f64, (f64, f64)) {
        let mut pl = crate::geom::Pline::new_closed();
        for v in &p.vertices {
            cavalier_contours::polyline::PlineSourceMut::add(&mut pl, v.x, v.y, v.bulge);
        }
        let (area, c) = area_and_centroid(&pl);
        (area.abs(), (c.x, c.y))
    }

    #[test]
    fn the_loops_found_are_the_same_in_any_entity_order() {
        // Seed 39 (developed on); the figures below hold for every order it draws.
        let mut rng = Lcg(39);
        let mut first: Option<(usize, usize, Vec<Shape>)> = None;
        for _ in 0..60 {
            let flip: Vec<bool> = (0..12).map(|_| rng.next() % 2 == 1).collect();
            let mut entities = pieces(&flip);
            for i in (1..entities.len()).rev() {
                entities.swap(i, (rng.next() % (i as u64 + 1)) as usize);
            }
            let (summary, shapes) = dilated(entities);
            // The gate body, the arrowhead and the square; the lead, the shaft and the slit.
            assert_eq!(summary.contours_dilated, 3, "{summary:?}");
            assert_eq!(summary.open_paths.len(), 3, "{:?}", summary.open_paths);
            let seen = (summary.contours_dilated, summary.open_paths.len(), shapes);
            match &first {
                None => first = Some(seen),
                Some(expected) => assert_eq!(&seen, expected),
            }
        }
        let (_, _, shapes) = first.unwrap();
        // The square grew by 75 µm each side, round corners: area (10.15)² − (4 − π)·0.075².
        let square = 10.15f64.powi(2) - (4.0 - std::f64::consts::PI) * 0.075f64.powi(2);
        assert!(
            shapes
                .iter()
                .any(|s| (s.0 as f64 * 1e-7 - square).abs() < 1e-6),
            "{shapes:?}"
        );
    }

    #[test]
    fn cut_lines_that_branch_are_refused_naming_where() {
        // A square with a diagonal: two triangles sharing an edge, or one square with a line
        // across it: which is meant cannot be told.
        let mut entities = pieces(&[false; 12])[8..12].to_vec();
        entities.push(line((50.0, 0.0), (60.0, 10.0)));
        let mut d = Drawing::new();
        d.header.version = AcadVersion::R2000;
        d.header.default_drawing_units = Units::Millimeters;
        for e in entities {
            d.add_entity(e);
        }
        let mut bytes = Vec::new();
        d.save(&mut bytes).unwrap();
        let err = dilate_dxf(&bytes, &KerfSource::Uniform(150.0), &DxfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("cut lines branch at (50.000, 0.000) mm"),
            "{err}"
        );
        assert!(
            err.contains("cut lines branch at (60.000, 10.000) mm"),
            "{err}"
        );
        assert!(err.contains("3 cut pieces meet"), "{err}");
        assert!(err.contains("--cut-layer"), "{err}");
    }
}
