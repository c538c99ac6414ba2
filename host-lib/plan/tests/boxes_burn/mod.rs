//! boxes.py's construction of a burnt outline, as its turtle draws it (`Boxes.corner`, `edge`,
//! `Context._arc` and the SVG surface's `faster_edges`, boxes.py at commit 7d1a89d9): every edge
//! drawn `burn` outside the part; every corner an arc of radius `burn` around the part's corner
//! point sweeping the corner's turn (a turn past 100° in equal steps of at most 36°, each one
//! cubic Bézier, `_arc`'s control points); a turn inwards sweeps backwards (the "backarc"), and
//! where that is one Bézier between two lines whose ends lie within the line width (2·burn),
//! `faster_edges` redraws it as a small closed loop at the lines' crossing (`--inner_corners
//! loop`, the default). A corner may be drawn as two turns at one point (an inner quarter turn,
//! then the rest), as boxes.py's finger joints draw a part's corner after their last finger: the
//! arc is drawn back and over again.

// Each test file uses its own subset.
#![allow(dead_code)]

/// A point, mm.
pub type P = (f64, f64);

/// How a corner is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Turn {
    /// One turn.
    Once,
    /// An inner quarter turn, then the rest, at the same point.
    Twice,
}

/// One drawing command: a line to a point, or a cubic Bézier (two controls, end).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Cmd {
    L(P),
    C(P, P, P),
}

/// The SVG path data boxes.py draws around the counter-clockwise polygon `poly` (y up, as its
/// turtle) at `burn`, each corner drawn as `turns` says, coordinates with `digits` decimals.
pub fn path(poly: &[P], burn: f64, turns: &[Turn], digits: usize) -> String {
    let cmds = faster_edges(turtle(poly, burn, turns), burn);
    let f = |p: P| format!("{:.digits$} {:.digits$}", p.0, p.1);
    let mut d = String::new();
    let start = match cmds.last() {
        Some(Cmd::L(p) | Cmd::C(_, _, p)) => *p,
        None => return d,
    };
    d.push_str(&format!("M {}", f(start)));
    for c in &cmds {
        match c {
            Cmd::L(p) => d.push_str(&format!(" L {}", f(*p))),
            Cmd::C(a, b, p) => d.push_str(&format!(" C {} {} {}", f(*a), f(*b), f(*p))),
        }
    }
    d.push_str(" Z");
    d
}

/// The turtle's commands, from where the last corner's arc ends (the path's start) round to it.
fn turtle(poly: &[P], burn: f64, turns: &[Turn]) -> Vec<Cmd> {
    let n = poly.len();
    let mut cmds = Vec::new();
    for k in 0..n {
        let (a, b, c) = (poly[(k + n - 1) % n], poly[k], poly[(k + 1) % n]);
        let (d_in, d_out) = (unit(sub(b, a)), unit(sub(c, b)));
        // The edge into the corner, `burn` to its right (outside a counter-clockwise part).
        cmds.push(Cmd::L(add(b, right(d_in), burn)));
        let turn = cross(d_in, d_out).atan2(dot(d_in, d_out)).to_degrees();
        let mut heading = d_in;
        let parts: Vec<f64> = match turns[k % turns.len()] {
            Turn::Twice if turn > 0.0 => vec![-90.0, turn + 90.0],
            _ => vec![turn],
        };
        for deg in parts {
            corner(&mut cmds, b, &mut heading, deg, burn);
        }
    }
    cmds
}

/// `Boxes.corner(deg)` at the part's corner `at`, the turtle heading `heading`: arcs of radius
/// `burn` around `at`, a turn past 100° in equal steps.
fn corner(cmds: &mut Vec<Cmd>, at: P, heading: &mut P, deg: f64, burn: f64) {
    let steps = if deg.abs() > 100.0 {
        (deg.abs() / 36.0) as usize + 1
    } else {
        1
    };
    for _ in 0..steps {
        let step = (deg / steps as f64).to_radians();
        let next = rotate(*heading, step);
        let (from, to) = (add(at, right(*heading), burn), add(at, right(next), burn));
        let (c1, c2) = arc_controls(at, from, to);
        cmds.push(Cmd::C(c1, c2, to));
        *heading = next;
    }
}

/// `Context._arc`'s control points for the arc around `c` from `a` to `b`.
fn arc_controls(c: P, a: P, b: P) -> (P, P) {
    let (u, w) = (sub(a, c), sub(b, c));
    let q1 = dot(u, u);
    let q2 = q1 + dot(u, w);
    let k2 = 4.0 / 3.0 * ((2.0 * q1 * q2).sqrt() - q2) / cross(u, w);
    (
        (c.0 + u.0 - k2 * u.1, c.1 + u.1 + k2 * u.0),
        (c.0 + w.0 + k2 * w.1, c.1 + w.1 - k2 * w.0),
    )
}

/// The SVG surface's `faster_edges(inner_corners="loop")`: a Bézier between two lines whose ends
/// lie within the line width and whose lines cross becomes a loop at the crossing.
fn faster_edges(mut cmds: Vec<Cmd>, burn: f64) -> Vec<Cmd> {
    let lw = (2.0 * burn).max(0.05);
    let end = |c: &Cmd| match c {
        Cmd::L(p) | Cmd::C(_, _, p) => *p,
    };
    let start = cmds.last().map(end);
    for i in 1..cmds.len().saturating_sub(1) {
        let (Cmd::L(p12), Cmd::C(_, _, p21), Cmd::L(p22)) = (cmds[i - 1], cmds[i], cmds[i + 1])
        else {
            continue;
        };
        let p11 = if i >= 2 {
            end(&cmds[i - 2])
        } else {
            start.expect("a path")
        };
        if dist(p12, p21) > lw {
            continue;
        }
        if let Some(x) = segment_crossing((p11, p12), (p21, p22)) {
            cmds[i - 1] = Cmd::L(x);
            cmds[i] = Cmd::C(p12, p21, x);
        }
    }
    cmds
}

/// Where two segments cross (boxes.py's `line_intersection`, with its 1e-4 slack).
fn segment_crossing(l1: (P, P), l2: (P, P)) -> Option<P> {
    let (r, s) = (sub(l1.1, l1.0), sub(l2.1, l2.0));
    let den = cross(r, s);
    if den == 0.0 {
        return None;
    }
    let t = cross(sub(l2.0, l1.0), s) / den;
    let x = add(l1.0, r, t);
    let within = |a: P, b: P| {
        x.0 + 1e-4 >= a.0.min(b.0)
            && x.0 - 1e-4 <= a.0.max(b.0)
            && x.1 + 1e-4 >= a.1.min(b.1)
            && x.1 - 1e-4 <= a.1.max(b.1)
    };
    (within(l1.0, l1.1) && within(l2.0, l2.1)).then_some(x)
}

fn sub(a: P, b: P) -> P {
    (a.0 - b.0, a.1 - b.1)
}

fn add(a: P, b: P, s: f64) -> P {
    (a.0 + b.0 * s, a.1 + b.1 * s)
}

fn dot(a: P, b: P) -> f64 {
    a.0 * b.0 + a.1 * b.1
}

fn cross(a: P, b: P) -> f64 {
    a.0 * b.1 - a.1 * b.0
}

fn dist(a: P, b: P) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

fn unit(a: P) -> P {
    let l = a.0.hypot(a.1);
    (a.0 / l, a.1 / l)
}

/// The right-hand normal of a heading (outside a counter-clockwise part).
fn right(d: P) -> P {
    (d.1, -d.0)
}

fn rotate(d: P, rad: f64) -> P {
    let (s, c) = rad.sin_cos();
    (c * d.0 - s * d.1, s * d.0 + c * d.1)
}
