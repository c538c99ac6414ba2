//! Path data as written back: a dilated contour in its element's own coordinates (arcs as `A`
//! arcs, elliptical where the transform is not a similarity), the subpaths kept as drawn, and
//! their numbers (the digits written by the crate's `decimal` module, the one place numbers are
//! written).

use std::fmt::Write as _;

use cavalier_contours::polyline::PlineSource;

use super::Seg;
use crate::decimal::{decimals_for_step, pow10, trimmed, write_scaled};
use crate::geom::{Affine, Pline, V2, arc_geom, v2};

/// Decimal places that keep 0.01 µm in the element's coordinates.
pub(super) fn digits_for(to_doc: &Affine) -> usize {
    let local_per_mm = 1.0 / to_doc.mean_scale().max(1e-300);
    decimals_for_step(1e-5 * local_per_mm)
}

/// `v` with at most `digits` decimals, trailing zeros dropped (`-0` is `0`).
pub(super) fn num(v: f64, digits: usize, out: &mut String) {
    // Fast path: round to an integer count of the last decimal, ties to even as float
    // formatting does, and print that. Where the product itself rounds across a tie (rare), the
    // last decimal differs by one: 0.01 µm in mm.
    let scaled = (v * pow10(digits as i32)).round_ties_even();
    if digits <= 12 && scaled.abs() < 1e15 {
        if scaled != 0.0 && scaled < 0.0 {
            out.push('-');
        }
        write_scaled(scaled.abs() as u64, digits, |s| out.push_str(s));
        return;
    }
    out.push_str(&trimmed(v, digits));
}

fn point(p: V2, digits: usize, out: &mut String) {
    num(p.x, digits, out);
    out.push(' ');
    num(p.y, digits, out);
}

/// Write a closed document-space polyline as path data in element coordinates.
pub(crate) fn write_pline(p: &Pline, to_local: &Affine, digits: usize, out: &mut String) {
    let n = p.vertex_count();
    let mirror = to_local.det() < 0.0;
    // The image of a circle of radius 1: every arc's ellipse is this one scaled.
    let (unit_rx, unit_ry, rot) = to_local.circle_image(1.0);
    let rot_deg = rot.to_degrees();
    out.push('M');
    let v0 = p.at(0);
    point(to_local.apply(v2(v0.x, v0.y)), digits, out);
    for i in 0..n {
        let a = p.at(i);
        let b = p.at((i + 1) % n);
        let q = to_local.apply(v2(b.x, b.y));
        match arc_geom(v2(a.x, a.y), v2(b.x, b.y), a.bulge) {
            Some(g) => {
                let large = g.sweep.abs() > std::f64::consts::PI;
                let sweep = (g.sweep > 0.0) != mirror;
                out.push_str(" A");
                num(g.radius * unit_rx, digits, out);
                out.push(' ');
                num(g.radius * unit_ry, digits, out);
                out.push(' ');
                num(rot_deg, 6, out);
                let _ = write!(out, " {} {} ", u8::from(large), u8::from(sweep));
                point(q, digits, out);
            }
            None if i + 1 < n => {
                out.push_str(" L");
                point(q, digits, out);
            }
            None => {}
        }
    }
    out.push_str(" Z");
}

/// Write segments unchanged (element coordinates).
pub(super) fn write_segs(segs: &[Seg], digits: usize, out: &mut String) {
    for (k, s) in segs.iter().enumerate() {
        if k > 0 {
            out.push(' ');
        }
        match *s {
            Seg::M(a) => {
                out.push('M');
                point(a.v2(), digits, out);
            }
            Seg::L(a) => {
                out.push('L');
                point(a.v2(), digits, out);
            }
            Seg::Q(a, b) => {
                out.push('Q');
                point(a.v2(), digits, out);
                out.push(' ');
                point(b.v2(), digits, out);
            }
            Seg::C(a, b, c) => {
                out.push('C');
                point(a.v2(), digits, out);
                out.push(' ');
                point(b.v2(), digits, out);
                out.push(' ');
                point(c.v2(), digits, out);
            }
            Seg::Z => out.push('Z'),
        }
    }
}
