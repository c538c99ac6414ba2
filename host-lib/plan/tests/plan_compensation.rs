//! Never compensating twice: boxes.py plans (drawn here by boxes.py's own construction: every edge
//! `burn` outside the part, an arc of radius `burn` around each convex corner, a loop at each
//! inner corner) and this tool's own SVG and DXF outputs are recognised and refused, and
//! `--recompensate` gives the part as drawn directly at the target burn, inner corners sharp.

mod common;

use std::io::Cursor;

use common::{MM_PER_CSS_PX, Poly, Sampling, path_by_id, seg_dist, subpaths};
use kerfmeter_plan::PlanError;
use kerfmeter_plan::compensation::{CompensatedBy, IfCompensated};
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::dxf_plan::{DxfOptions, dilate_dxf};
use kerfmeter_plan::outcome::PlanSummary;
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};
use kerfmeter_protocol::advice::Advice;

type P = (f64, f64);

/// How boxes.py draws an inner corner (`--inner_corners`).
#[derive(Clone, Copy, PartialEq)]
enum Inner {
    /// Its default: a small closed Bézier from the crossing back to it.
    Loop,
    /// Running on past the crossing and back along an arc around the part's corner.
    Backarc,
    /// Sharp, at the crossing (the clean offset: what a plan at the target burn must equal).
    Corner,
}

/// A part with fingers on top, notches below: counter-clockwise in the page (y down), mm.
fn finger_part() -> Vec<P> {
    let mut v = vec![(10.0, 20.0)];
    for k in 0..3 {
        let x = 16.0 + 12.0 * f64::from(k);
        v.extend([(x, 20.0), (x, 17.0), (x + 6.0, 17.0), (x + 6.0, 20.0)]);
    }
    v.extend([(70.0, 20.0), (70.0, 60.0)]);
    for k in (0..2).rev() {
        let x = 28.0 + 18.0 * f64::from(k);
        v.extend([(x + 6.0, 60.0), (x + 6.0, 57.0), (x, 57.0), (x, 60.0)]);
    }
    v.push((10.0, 60.0));
    v
}

/// A finger slot (a hole) in the part.
fn slot() -> Vec<P> {
    vec![(37.0, 35.0), (43.0, 35.0), (43.0, 45.0), (37.0, 45.0)]
}

fn sub(a: P, b: P) -> P {
    (a.0 - b.0, a.1 - b.1)
}

fn add(a: P, b: P, s: f64) -> P {
    (a.0 + b.0 * s, a.1 + b.1 * s)
}

fn cross(a: P, b: P) -> f64 {
    a.0 * b.1 - a.1 * b.0
}

fn unit(a: P) -> P {
    let l = a.0.hypot(a.1);
    (a.0 / l, a.1 / l)
}

/// The path boxes.py draws around `poly` at `burn` (away from the material: outwards for a part,
/// into a hole), coordinates with `digits` decimals.
fn boxes_path(poly: &[P], hole: bool, burn: f64, inner: Inner, digits: usize) -> String {
    let n = poly.len();
    let area: f64 = (0..n).map(|i| cross(poly[i], poly[(i + 1) % n])).sum();
    let away = |d: P| {
        if (area > 0.0) != hole {
            (d.1, -d.0)
        } else {
            (-d.1, d.0)
        }
    };
    let f = |p: P| format!("{:.digits$} {:.digits$}", p.0, p.1);
    let mut d = String::new();
    for k in 0..=n {
        let c = poly[k % n];
        let (d_in, d_out) = (
            unit(sub(c, poly[(k + n - 1) % n])),
            unit(sub(poly[(k + 1) % n], c)),
        );
        let (o_in, o_out) = (away(d_in), away(d_out));
        let (a, b) = (add(c, o_in, burn), add(c, o_out, burn));
        // Where the two offset edges cross: before `a` on the incoming edge at an inner corner.
        let t = cross(sub(b, a), d_out) / cross(d_in, d_out);
        let x = add(a, d_in, t);
        let inner_corner = t < 0.0;
        if k == 0 {
            d.push_str(&format!(
                "M {}",
                f(if inner_corner && inner != Inner::Backarc {
                    x
                } else {
                    b
                })
            ));
            continue;
        }
        match (inner_corner, inner) {
            (true, Inner::Loop) => d.push_str(&format!(" L {} C {} {} {}", f(x), f(a), f(b), f(x))),
            (true, Inner::Corner) => d.push_str(&format!(" L {}", f(x))),
            // No burn: no arc.
            _ if burn == 0.0 => d.push_str(&format!(" L {}", f(a))),
            _ => d.push_str(&format!(
                " L {} C {} {} {}",
                f(a),
                f(arc_c1(c, a, b)),
                f(arc_c2(c, a, b)),
                f(b)
            )),
        }
    }
    d.push_str(" Z");
    d
}

/// boxes.py's cubic for the arc around `c` from `a` to `b` (its `Context._arc`): control points.
fn arc_k2(c: P, a: P, b: P) -> (P, P, f64) {
    let (u, w) = (sub(a, c), sub(b, c));
    let q1 = u.0 * u.0 + u.1 * u.1;
    let q2 = q1 + u.0 * w.0 + u.1 * w.1;
    (
        u,
        w,
        4.0 / 3.0 * ((2.0 * q1 * q2).sqrt() - q2) / cross(u, w),
    )
}

fn arc_c1(c: P, a: P, b: P) -> P {
    let (u, _, k2) = arc_k2(c, a, b);
    (c.0 + u.0 - k2 * u.1, c.1 + u.1 + k2 * u.0)
}

fn arc_c2(c: P, a: P, b: P) -> P {
    let (_, w, k2) = arc_k2(c, a, b);
    (c.0 + w.0 + k2 * w.1, c.1 + w.1 - k2 * w.0)
}

/// A boxes.py SVG: its comment and metadata (`comment`, `metadata` lines), the part and the slot.
fn boxes_svg(comment: &str, metadata: &str, burn: f64, inner: Inner, digits: usize) -> String {
    format!(
        r#"<?xml version='1.0' encoding='utf-8'?>
<svg height="80.00mm" viewBox="0.0 0.0 80.00 80.00" width="80.00mm" xmlns="http://www.w3.org/2000/svg" xmlns:dc="http://purl.org/dc/elements/1.1/" xmlns:cc="http://creativecommons.org/ns#" xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">
<!--
FingerPart - a part with finger joints

Created with Boxes.py (https://boxes.hackerspace-bamberg.de/)
{comment}
-->
<title>FingerPart</title>
<metadata>
<rdf:RDF><cc:Work>
<dc:title>Part - FingerPart</dc:title>
<dc:description>A part with finger joints

Created with Boxes.py (https://boxes.hackerspace-bamberg.de/)
{metadata}
</dc:description>
</cc:Work></rdf:RDF></metadata>
<g id="p-0" style="fill:none;stroke-linecap:round;stroke-linejoin:round;">
  <path id="outer" d="{}" stroke="rgb(0,0,0)" stroke-width="0.20" />
  <path id="slot" d="{}" stroke="rgb(0,0,0)" stroke-width="0.20" />
</g>
</svg>
"#,
        boxes_path(&finger_part(), false, burn, inner, digits),
        boxes_path(&slot(), true, burn, inner, digits),
    )
}

/// The plan boxes.py writes for `boxes FingerPart --burn 0.1` (command line in both places).
fn burnt(burn: f64, inner: Inner, digits: usize) -> String {
    boxes_svg(
        &format!("Command line (remove spaces between dashes): boxes FingerPart - -burn={burn}"),
        &format!(
            "Command line: boxes FingerPart --burn={burn}\nCommand line short: boxes FingerPart --burn={burn}"
        ),
        burn,
        inner,
        digits,
    )
}

fn run(svg: &str, kerf_um: f64, policy: IfCompensated) -> Result<(String, PlanSummary), PlanError> {
    let opts = SvgOptions {
        if_compensated: policy,
        ..SvgOptions::default()
    };
    dilate_svg(svg, &KerfSource::Uniform(kerf_um), &opts)
}

/// The sampled closed outlines of the elements `ids` of an SVG.
fn outlines(svg: &str, ids: &[&str]) -> Vec<Poly> {
    let tree = usvg::Tree::from_str(svg, &usvg::Options::default()).unwrap();
    let sampling = Sampling {
        mm_per_px: MM_PER_CSS_PX,
        points_per_curve: 64,
        close_rings: true,
    };
    ids.iter()
        .map(|id| subpaths(path_by_id(tree.root(), id), &sampling).remove(0))
        .collect()
}

fn dist_to(p: P, poly: &Poly) -> f64 {
    poly.windows(2)
        .map(|w| seg_dist(p, w[0], w[1]))
        .fold(f64::INFINITY, f64::min)
}

/// Symmetric Hausdorff distance of two sampled outlines, mm.
fn hausdorff(a: &Poly, b: &Poly) -> f64 {
    let one = |x: &Poly, y: &Poly| x.iter().map(|&p| dist_to(p, y)).fold(0.0, f64::max);
    one(a, b).max(one(b, a))
}

#[test]
fn boxes_py_plans_are_refused_naming_the_burn_and_both_ways_on() {
    for inner in [Inner::Loop, Inner::Backarc] {
        let e = run(&burnt(0.1, inner, 3), 150.0, IfCompensated::Refuse).unwrap_err();
        let msg = e.to_string();
        let PlanError::AlreadyCompensated { found, .. } = &e else {
            panic!("{msg}");
        };
        assert_eq!(
            (found.by, found.offset_um.0),
            (CompensatedBy::BoxesPy, [100.0, 100.0])
        );
        for needle in [
            "boxes.py compensated this plan with --burn 0.1 (mm",
            "100 µm outside the parts",
            "kerf/2 − burn = 75 − 100 = -25 µm",
            "nothing was written",
        ] {
            assert!(msg.contains(needle), "{needle:?} not in: {msg}");
        }
        assert_eq!(
            e.advice(),
            [Advice::Recompensate, Advice::AlreadyCompensatedOk]
        );
    }
}

#[test]
fn without_the_record_the_same_plan_crosses_itself_so_the_check_must_come_first() {
    // The loops are what the old message complained about.
    let anonymous = burnt(0.1, Inner::Loop, 3)
        .replace("Boxes.py", "a generator")
        .replace("burn=0.1", "x=1")
        .replace("boxes FingerPart", "gen FingerPart");
    let e = run(&anonymous, 150.0, IfCompensated::Refuse)
        .unwrap_err()
        .to_string();
    assert!(e.contains("crosses itself"), "{e}");
}

#[test]
fn every_form_of_boxes_py_record_is_recognised() {
    let found = |comment: &str, metadata: &str, label: &str| {
        let svg = boxes_svg(comment, metadata, 0.1, Inner::Corner, 3)
            .replace("</g>", &format!("<text>{label}</text></g>"));
        run(&svg, 150.0, IfCompensated::DilateAnyway)
            .unwrap()
            .1
            .compensation_found
    };
    let burn_um = |f: Option<kerfmeter_plan::compensation::FoundCompensation>| {
        let f = f.expect("found");
        assert_eq!(f.by, CompensatedBy::BoxesPy);
        (f.offset_um.0[0], f.default_burn)
    };
    // The comment's short command line, dashes spaced.
    assert_eq!(
        burn_um(found(
            "Command line (remove spaces between dashes): boxes A - -burn=0.2",
            "",
            ""
        )),
        (200.0, false)
    );
    // The metadata's full command line, value after a space.
    assert_eq!(
        burn_um(found(
            "",
            "Command line: boxes A --x=3 --burn 0.15 --y=2",
            ""
        )),
        (150.0, false)
    );
    // The web generator's URL.
    assert_eq!(
        burn_um(found(
            "Url: https://boxes.example/A?x=3&burn=0.05&render=1",
            "",
            ""
        )),
        (50.0, false)
    );
    // The reference label, then boxes.py's default when nothing names it.
    assert_eq!(
        burn_um(found("Command line: boxes A", "", "100.0mm, burn:0.12mm")),
        (120.0, false)
    );
    assert_eq!(
        burn_um(found("Command line: boxes A", "", "")),
        (100.0, true)
    );
    // A burn of 0 is no compensation: the plan is dilated as usual.
    let svg = boxes_svg("", "Command line: boxes A --burn=0", 0.0, Inner::Corner, 3);
    let (_, s) = run(&svg, 150.0, IfCompensated::Refuse).unwrap();
    assert_eq!(s.compensation_applied.unwrap().action, "dilate");
    // Not boxes.py at all.
    let svg = boxes_svg("", "", 0.1, Inner::Corner, 3).replace("Boxes.py", "a generator");
    assert!(
        run(&svg, 150.0, IfCompensated::Refuse)
            .unwrap()
            .1
            .compensation_found
            .is_none()
    );
    // Asking to recompensate it says there was nothing to undo.
    let (_, s) = run(&svg, 150.0, IfCompensated::Recompensate).unwrap();
    assert_eq!(
        s.compensation_applied.unwrap().net_offset_um.0,
        [75.0, 75.0]
    );
    assert!(
        s.notes
            .iter()
            .any(|n| n.contains("records no compensation")),
        "{:?}",
        s.notes
    );
}

/// Recompensating boxes.py's plan at 0.1 mm for `kerf_um` against the same part drawn directly
/// at burn kerf/2 (its clean offset): the largest distance, mm, per outline.
fn recompensated_vs_direct(kerf_um: f64, inner: Inner, digits: usize) -> Vec<f64> {
    let (out, s) = run(
        &burnt(0.1, inner, digits),
        kerf_um,
        IfCompensated::Recompensate,
    )
    .unwrap();
    let applied = s.compensation_applied.unwrap();
    assert_eq!(applied.action, "recompensate");
    assert_eq!(applied.net_offset_um.0, [kerf_um / 2.0 - 100.0; 2]);
    let expected_loops = if inner == Inner::Corner { 0 } else { 10 + 4 };
    assert_eq!(applied.corner_loops_removed, expected_loops);
    let direct = burnt(kerf_um / 2000.0, Inner::Corner, digits);
    let got = outlines(&out, &["outer", "slot"]);
    let want = outlines(&direct, &["outer", "slot"]);
    got.iter()
        .zip(&want)
        .map(|(g, w)| hausdorff(g, w))
        .collect()
}

#[test]
fn recompensation_matches_the_part_drawn_at_the_target_burn() {
    // Exact coordinates: within 0.1 µm (0.041 µm measured: boxes.py's Bézier arcs), shrinking
    // (kerf/2 < burn) and growing.
    for inner in [Inner::Loop, Inner::Backarc, Inner::Corner] {
        for kerf_um in [150.0, 120.0, 260.0] {
            let d = recompensated_vs_direct(kerf_um, inner, 6);
            assert!(d.iter().all(|&x| x < 1e-4), "kerf {kerf_um}: {d:?} mm");
        }
    }
    // boxes.py's own 1 µm rounding of coordinates: within 0.5 µm (0.23 µm measured).
    for inner in [Inner::Loop, Inner::Backarc] {
        let d = recompensated_vs_direct(150.0, inner, 3);
        assert!(d.iter().all(|&x| x < 5e-4), "{d:?} mm");
    }
}

/// The finger part `(dx, dy)` mm from the origin, as boxes.py draws it at `burn`, on a page
/// large enough.
fn far_part(burn: f64, inner: Inner, (dx, dy): P) -> String {
    let poly: Vec<P> = finger_part()
        .iter()
        .map(|&(x, y)| (x + dx, y + dy))
        .collect();
    format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="2500mm" height="400mm" viewBox="0 0 2500 400"><!-- Command line (remove spaces between dashes): boxes FingerPart - -burn={burn} --><path id="outer" d="{}" stroke="rgb(0,0,0)" stroke-width="0.20" fill="none"/></svg>"#,
        boxes_path(&poly, false, burn, inner, 6)
    )
}

#[test]
fn recompensation_holds_metres_from_the_origin() {
    // boxes.py's OrganPipe lays its parts out up to 2.4 m from the origin, where usvg's single
    // precision holds a coordinate to 0.14 µm. There, a loop's last fitted piece was shorter
    // than the tolerance within which ends meet (18 µm) and was left out: the loop ended short of
    // its corner, its tail stayed on the contour and tilted the next edge (1.1 µm at the far
    // corner, 1.55 µm in OrganPipe against its uncompensated plan dilated).
    for at in [(0.0, 0.0), (1000.0, 200.0), (2300.0, 300.0)] {
        let (out, s) = run(
            &far_part(0.1, Inner::Loop, at),
            150.0,
            IfCompensated::Recompensate,
        )
        .unwrap();
        assert_eq!(s.compensation_applied.unwrap().corner_loops_removed, 10);
        let got = outlines(&out, &["outer"]).remove(0);
        let want = outlines(&far_part(0.075, Inner::Corner, at), &["outer"]).remove(0);
        // Both read in single precision: up to 0.2 µm apart 2.4 m out.
        let d = hausdorff(&got, &want);
        assert!(d < 3e-4, "{d} mm at {at:?}");
    }
}

#[test]
fn recompensated_inner_corners_stay_sharp() {
    let (out, _) = run(
        &burnt(0.1, Inner::Loop, 6),
        150.0,
        IfCompensated::Recompensate,
    )
    .unwrap();
    let got = outlines(&out, &["outer"]).remove(0);
    // The notch's inner corners at (28, 57) and (34, 57), moved 75 µm out of the material: sharp
    // corners at (28.075, 57.075)… would be rounded 0.41 × 25 µm ≈ 10 µm away by an erosion.
    for corner in [
        (28.075, 57.075),
        (33.925, 57.075),
        (22.075, 19.925),
        (27.925, 19.925),
    ] {
        let nearest = got
            .iter()
            .map(|&p| (p.0 - corner.0).hypot(p.1 - corner.1))
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 1e-4,
            "corner {corner:?}: nearest point {nearest} mm away"
        );
    }
}

#[test]
fn dilating_anyway_adds_the_full_kerf_on_top_without_the_loops() {
    let (out, s) = run(
        &burnt(0.1, Inner::Loop, 6),
        150.0,
        IfCompensated::DilateAnyway,
    )
    .unwrap();
    let applied = s.compensation_applied.unwrap();
    assert_eq!(
        (applied.net_offset_um.0[0], applied.offset_um.0[0]),
        (75.0, 175.0)
    );
    let got = outlines(&out, &["outer", "slot"]);
    let want = outlines(&burnt(0.175, Inner::Corner, 6), &["outer", "slot"]);
    for (g, w) in got.iter().zip(&want) {
        assert!(hausdorff(g, w) < 1e-4);
    }
}

#[test]
fn own_svg_outputs_are_recorded_refused_and_recompensated() {
    let plan = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/box_generator.svg"),
    )
    .unwrap();
    let (once, _) = run(&plan, 150.0, IfCompensated::Refuse).unwrap();
    assert!(once.contains("<metadata><kerfmeter:compensation xmlns:kerfmeter=\"urn:x-kerfmeter:compensation:1\" tool=\"kerfmeter\""));
    assert!(once.contains("<!-- kerfmeter-compensation tool=kerfmeter version="));
    let refused = run(&once, 150.0, IfCompensated::Refuse).unwrap_err();
    assert_eq!(
        refused.advice(),
        [Advice::Recompensate, Advice::AlreadyCompensatedOk]
    );
    let e = refused.to_string();
    assert!(
        e.contains("kerfmeter") && e.contains("kerf 150 µm") && e.contains("75 µm outside"),
        "{e}"
    );
    // On top: one record, the total offset.
    let (twice, s) = run(&once, 150.0, IfCompensated::DilateAnyway).unwrap();
    assert_eq!(s.compensation_applied.unwrap().offset_um.0, [150.0, 150.0]);
    assert_eq!(twice.matches("<kerfmeter:compensation").count(), 1);
    assert_eq!(twice.matches("<!-- kerfmeter-compensation").count(), 1);
    // Recompensated for another kerf = the original dilated by it.
    for kerf_um in [100.0, 220.0] {
        let (re, s) = run(&once, kerf_um, IfCompensated::Recompensate).unwrap();
        assert_eq!(s.compensation_found.unwrap().offset_um.0, [75.0, 75.0]);
        let (direct, _) = run(&plan, kerf_um, IfCompensated::Refuse).unwrap();
        let tree = |svg: &str| usvg::Tree::from_str(svg, &usvg::Options::default()).unwrap();
        let (a, b) = (tree(&re), tree(&direct));
        let sampling = Sampling {
            mm_per_px: MM_PER_CSS_PX,
            points_per_curve: 64,
            close_rings: true,
        };
        let pa: Vec<Poly> = common::all_paths(a.root())
            .iter()
            .flat_map(|p| subpaths(p, &sampling))
            .collect();
        let pb: Vec<Poly> = common::all_paths(b.root())
            .iter()
            .flat_map(|p| subpaths(p, &sampling))
            .collect();
        assert_eq!(pa.len(), pb.len());
        for (x, y) in pa.iter().zip(&pb) {
            assert!(
                hausdorff(x, y) < 1e-4,
                "kerf {kerf_um}: {} mm",
                hausdorff(x, y)
            );
        }
    }
}

#[test]
fn own_dxf_outputs_are_recorded_refused_and_recompensated() {
    use dxf::entities::{Entity, EntityType, LwPolyline};
    let mut d = dxf::Drawing::new();
    d.header.version = dxf::enums::AcadVersion::R2000;
    d.header.default_drawing_units = dxf::enums::Units::Millimeters;
    let mut lw = LwPolyline::default();
    for (x, y) in [
        (0.0, 0.0),
        (20.0, 0.0),
        (20.0, 10.0),
        (10.0, 10.0),
        (10.0, 20.0),
        (0.0, 20.0),
    ] {
        lw.vertices.push(dxf::LwPolylineVertex {
            x,
            y,
            ..Default::default()
        });
    }
    lw.set_is_closed(true);
    let mut e = Entity::new(EntityType::LwPolyline(lw));
    e.common.color = dxf::Color::from_index(1);
    d.add_entity(e);
    let mut bytes = Vec::new();
    d.save(&mut bytes).unwrap();
    let opts = |if_compensated| DxfOptions {
        if_compensated,
        ..DxfOptions::default()
    };
    let kerf = |k| KerfSource::Uniform(k);
    let (once, _) = dilate_dxf(&bytes, &kerf(150.0), &opts(IfCompensated::Refuse)).unwrap();
    assert!(String::from_utf8_lossy(&once).starts_with("999"));
    let e = dilate_dxf(&once, &kerf(150.0), &opts(IfCompensated::Refuse)).unwrap_err();
    let PlanError::AlreadyCompensated { found, .. } = &e else {
        panic!("{e}");
    };
    assert_eq!(found.by, CompensatedBy::Kerfmeter);
    assert_eq!(found.kerf_um.map(|k| k.0), Some([150.0, 150.0]));
    assert!(e.to_string().contains("a DXF 999 comment"), "{e}");
    // Recompensated for 100 µm = the original dilated by 100 µm; the inner corner stays sharp.
    let (re, s) = dilate_dxf(&once, &kerf(100.0), &opts(IfCompensated::Recompensate)).unwrap();
    assert_eq!(
        s.compensation_applied.unwrap().net_offset_um.0,
        [-25.0, -25.0]
    );
    let (direct, _) = dilate_dxf(&bytes, &kerf(100.0), &opts(IfCompensated::Refuse)).unwrap();
    let vertices = |b: &[u8]| -> Vec<(f64, f64, f64)> {
        let d = dxf::Drawing::load(&mut Cursor::new(b)).unwrap();
        d.entities()
            .flat_map(|e| match &e.specific {
                EntityType::LwPolyline(lw) => {
                    lw.vertices.iter().map(|v| (v.x, v.y, v.bulge)).collect()
                }
                _ => Vec::new(),
            })
            .collect()
    };
    let (vr, vd) = (vertices(&re), vertices(&direct));
    assert_eq!(vr.len(), vd.len(), "{vr:?} vs {vd:?}");
    // The same vertices (each with its bulge), wherever each contour starts.
    for a in &vr {
        let same =
            |b: &(f64, f64, f64)| (a.0 - b.0).hypot(a.1 - b.1) < 1e-9 && (a.2 - b.2).abs() < 1e-9;
        assert!(vd.iter().any(same), "{a:?} not in {vd:?}");
    }
    assert!(
        vr.iter()
            .any(|v| (v.0 - 10.05).abs() < 1e-9 && (v.1 - 10.05).abs() < 1e-9)
    );
}

#[test]
fn boxes_py_reference_rectangle_drawn_without_burn_is_only_dilated() {
    // boxes.py's reference: 60 × 5 mm as drawn (no burn), labelled with the burn.
    let rect = [(10.0, 70.0), (70.0, 70.0), (70.0, 75.0), (10.0, 75.0)];
    let reference = format!(
        r#"<g id="p-1" style="fill:none;"><path id="reference" d="{}" stroke="rgb(0,0,0)" stroke-width="0.20"/><text>60.0mm, burn:0.10mm</text></g></svg>"#,
        boxes_path(&rect, false, 0.0, Inner::Corner, 6)
    );
    let svg = burnt(0.1, Inner::Loop, 6).replace("</svg>", &reference);
    let (out, s) = run(&svg, 150.0, IfCompensated::Recompensate).unwrap();
    assert!(
        s.notes.iter().any(|n| n.contains("reference rectangle")),
        "{:?}",
        s.notes
    );
    let want = boxes_svg("", "", 0.0, Inner::Corner, 6).replace(
        "</svg>",
        &format!(
            r#"<path id="reference" d="{}" fill="none" stroke="rgb(0,0,0)" stroke-width="0.20"/></svg>"#,
            boxes_path(&rect, false, 0.075, Inner::Corner, 6)
        ),
    );
    let (got, want) = (
        outlines(&out, &["reference"]),
        outlines(&want, &["reference"]),
    );
    assert!(
        hausdorff(&got[0], &want[0]) < 1e-4,
        "{}",
        hausdorff(&got[0], &want[0])
    );
    // The parts themselves are recompensated as before.
    assert!(
        recompensated_vs_direct(150.0, Inner::Loop, 6)
            .iter()
            .all(|&x| x < 1e-4)
    );
}

#[test]
fn the_gauge_drawing_is_cut_as_drawn_never_dilated() {
    use kerfmeter_plan::gauge::{self, GaugeOptions, TestPieceSpec};
    let geometry = kerfmeter_protocol::GaugeGeometry::PAPER;
    let plain = gauge::build(&geometry, &GaugeOptions::default()).unwrap();
    let with_piece = gauge::build(
        &geometry,
        &GaugeOptions {
            test_piece: Some(TestPieceSpec {
                thickness_mm: 3.0,
                finger_width_mm: 6.0,
                kerf_um: 150.0,
            }),
            ..GaugeOptions::default()
        },
    )
    .unwrap();
    for (drawing, piece) in [(&plain, false), (&with_piece, true)] {
        let svg = gauge::to_svg(drawing);
        let e = run(&svg, 150.0, IfCompensated::Refuse).unwrap_err();
        let found = e.compensation_found().expect("found").clone();
        assert_eq!(found.by, CompensatedBy::KerfmeterGauge, "{e}");
        assert!(e.to_string().contains("cut it as it is"), "{e}");
        assert_eq!(
            e.to_string().contains("compensate the test piece twice"),
            piece,
            "{e}"
        );
        // Nothing to undo: recompensating is refused too; dilating anyway is the user's word.
        let e = run(&svg, 150.0, IfCompensated::Recompensate).unwrap_err();
        assert!(
            e.to_string()
                .contains("does not apply: the spiral carries no"),
            "{e}"
        );
        assert!(e.advice().contains(&Advice::Recompensate), "{e}");
        // At a kerf of 0 (its cuts as drawn, as `gcode` makes them) it passes.
        assert!(run(&svg, 0.0, IfCompensated::Refuse).is_ok());
        // Dilated anyway, the output carries one record, this dilation's, and no gauge words.
        let (out, _) = run(&svg, 150.0, IfCompensated::DilateAnyway).unwrap();
        assert_eq!(out.matches("kerfmeter-compensation").count(), 1, "{out}");
        assert!(!out.contains("drawing=gauge") && !out.contains("cut it as drawn"));
        let dxf = gauge::to_dxf(drawing).unwrap();
        let opts = DxfOptions {
            if_compensated: IfCompensated::Refuse,
            ..DxfOptions::default()
        };
        let e = dilate_dxf(&dxf, &KerfSource::Uniform(150.0), &opts).unwrap_err();
        let found = e.compensation_found().expect("found in the DXF");
        assert_eq!(found.by, CompensatedBy::KerfmeterGauge, "{e}");
        let anyway = DxfOptions {
            if_compensated: IfCompensated::DilateAnyway,
            ..DxfOptions::default()
        };
        let (out, _) = dilate_dxf(&dxf, &KerfSource::Uniform(150.0), &anyway).unwrap();
        let out = String::from_utf8_lossy(&out);
        assert_eq!(out.matches("kerfmeter-compensation").count(), 1);
        assert!(!out.contains("drawing=gauge") && !out.contains("cut it as drawn"));
    }
}
