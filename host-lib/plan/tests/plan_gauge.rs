//! The spiral gauge, parsed back from the files the gauge drawer writes (as `kerfmeter gauge`
//! does) — SVG with `usvg`, DXF with the `dxf` crate — and checked against r(φ) = a + c·φ, the radial step, the holes and the
//! sense of the spiral, to within 1 µm. The geometry is evaluated here independently of the
//! library (Bézier and bulge formulas written out).

mod common;

use std::f64::consts::{PI, TAU};
use std::path::Path;

use common::{Sampling, path_by_id, subpaths};
use kerfmeter_plan::gauge::{self, GaugeDrawing, GaugeOptions, TestPieceSpec};
use kerfmeter_plan::{PlanError, PlanFormat};
use kerfmeter_protocol::{GaugeGeometry, JamDirection};

const UM: f64 = 1e-3;

/// Draw the gauge and write it to `out`, SVG or DXF by the extension.
fn write_gauge(
    geometry: &GaugeGeometry,
    options: &GaugeOptions,
    out: &Path,
) -> Result<GaugeDrawing, PlanError> {
    let format = PlanFormat::of(out)?;
    let drawing = gauge::build(geometry, options)?;
    let bytes = match format {
        PlanFormat::Svg => gauge::to_svg(&drawing).into_bytes(),
        PlanFormat::Dxf => gauge::to_dxf(&drawing)?,
    };
    std::fs::write(out, bytes).unwrap();
    Ok(drawing)
}

fn pitch_mm_per_rad(pitch_um_per_deg: f64) -> f64 {
    pitch_um_per_deg * 1e-3 * 180.0 / PI
}

/// Points along an SVG path (y down, mm), per subpath, from usvg's data.
fn usvg_points(path: &usvg::Path, mm_per_px: f64) -> Vec<Vec<(f64, f64)>> {
    let sampling = Sampling {
        mm_per_px,
        points_per_curve: 24,
        close_rings: false,
    };
    subpaths(path, &sampling)
}

/// Centre and radius of a sampled circle, and the largest radial deviation.
fn circle_fit(points: &[(f64, f64)]) -> ((f64, f64), f64, f64) {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let cy = points.iter().map(|p| p.1).sum::<f64>() / n;
    let radii: Vec<f64> = points.iter().map(|p| (p.0 - cx).hypot(p.1 - cy)).collect();
    let r = radii.iter().sum::<f64>() / n;
    let dev = radii.iter().map(|x| (x - r).abs()).fold(0.0, f64::max);
    ((cx, cy), r, dev)
}

/// Check a spiral given as points in a y-up top view around `centre`: r(φ) along it, the sense
/// (φ grows counter-clockwise for `sense` = 1, clockwise for −1), the step, and one full turn.
fn check_spiral(points: &[(f64, f64)], centre: (f64, f64), a: f64, c: f64, sense: f64) {
    let mut phi_prev: Option<f64> = None;
    let mut max_err: f64 = 0.0;
    let mut phis = Vec::new();
    for &(x, y) in points {
        let (dx, dy) = (x - centre.0, y - centre.1);
        let psi = sense * dy.atan2(dx);
        // Unwrap onto a continuous φ, starting at 0.
        let phi = match phi_prev {
            None => psi,
            Some(prev) => prev + (psi - prev + PI).rem_euclid(TAU) - PI,
        };
        phi_prev = Some(phi);
        phis.push(phi);
        let err = (dx.hypot(dy) - (a + c * phi)).abs();
        max_err = max_err.max(err);
    }
    assert!(max_err < 1.0 * UM, "r(φ) deviates by {} µm", max_err / UM);
    // Sense: φ grows along the drawn line (never goes back), over one full turn.
    for w in phis.windows(2) {
        assert!(w[1] >= w[0] - 1e-9, "φ goes back: {} → {}", w[0], w[1]);
    }
    assert!(phis[0].abs() < 1e-6, "starts at φ = {}", phis[0]);
    assert!(
        (phis[phis.len() - 1] - TAU).abs() < 1e-6,
        "ends at φ = {}",
        phis[phis.len() - 1]
    );
    // The step: the path starts at r = a and ends at r = a + 2πc, both on φ = 0; the closing
    // segment between them is radial.
    let r = |p: (f64, f64)| (p.0 - centre.0).hypot(p.1 - centre.1);
    let (first, last) = (points[0], points[points.len() - 1]);
    assert!((r(first) - a).abs() < 1.0 * UM);
    assert!((r(last) - (a + TAU * c)).abs() < 1.0 * UM);
    assert!((first.1 - centre.1).abs() < 1.0 * UM && (last.1 - centre.1).abs() < 1.0 * UM);
    assert!(first.0 > centre.0 && last.0 > centre.0);
}

fn svg_gauge_checks(jam: JamDirection) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gauge.svg");
    let geometry = GaugeGeometry {
        jam_direction: jam,
        ..GaugeGeometry::PAPER
    };
    let drawing = write_gauge(&geometry, &GaugeOptions::default(), &out).unwrap();
    let max_deviation_um = drawing.max_deviation_mm * 1e3;
    assert!(max_deviation_um < 0.1, "{max_deviation_um}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains(r#"width=""#) && text.contains("mm\""));
    assert!(text.contains("stroke=\"#FF0000\"") && text.contains("stroke-width=\"0.01\""));
    assert!(text.contains(" A"), "the spiral is made of arcs");

    let tree = usvg::Tree::from_str(&text, &usvg::Options::default()).unwrap();
    let mm_per_px = 25.4 / 96.0;
    let page_h = f64::from(tree.size().height()) * mm_per_px;
    assert!((page_h - drawing.page_mm[1]).abs() < 1e-3);
    // To the y-up top view.
    let up = |pts: Vec<(f64, f64)>| {
        pts.into_iter()
            .map(|(x, y)| (x, page_h - y))
            .collect::<Vec<_>>()
    };
    let hole0 = up(usvg_points(path_by_id(tree.root(), "hole-0"), mm_per_px).remove(0));
    let hole1 = up(usvg_points(path_by_id(tree.root(), "hole-pi"), mm_per_px).remove(0));
    let g = GaugeGeometry::PAPER;
    let (c0, r0, d0) = circle_fit(&hole0[1..]);
    let (c1, r1, d1) = circle_fit(&hole1[1..]);
    // usvg draws circles as four cubics (≈ 0.03 % of the radius off a true circle).
    for (r, d) in [(r0, d0), (r1, d1)] {
        assert!(
            (r - f64::from(g.hole_radius_mm)).abs() < 1.0 * UM,
            "hole radius {r}"
        );
        assert!(d < 1.0 * UM, "hole roundness {d}");
    }
    let centre = ((c0.0 + c1.0) / 2.0, (c0.1 + c1.1) / 2.0);
    // Holes at φ = 0 (+x) and φ = π, R from the centre.
    assert!((c0.0 - centre.0 - f64::from(g.hole_distance_mm)).abs() < 1.0 * UM);
    assert!((c0.1 - centre.1).abs() < 1.0 * UM && (c1.1 - centre.1).abs() < 1.0 * UM);
    assert!(c1.0 < centre.0);

    let spiral = up(usvg_points(path_by_id(tree.root(), "spiral"), mm_per_px).remove(0));
    let c = pitch_mm_per_rad(f64::from(g.pitch_um_per_deg));
    let a = f64::from(g.radius_mm) - PI * c;
    let sense = match jam {
        JamDirection::Clockwise => 1.0,
        JamDirection::CounterClockwise => -1.0,
    };
    check_spiral(&spiral, centre, a, c, sense);
    // The wrong sense must fail the same check (the check can tell the senses apart).
    let wrong = std::panic::catch_unwind(|| check_spiral(&spiral, centre, a, c, -sense));
    assert!(wrong.is_err());
}

#[test]
fn svg_gauge_clockwise_parses_back_within_a_micron() {
    svg_gauge_checks(JamDirection::Clockwise);
}

#[test]
fn svg_gauge_counter_clockwise_is_mirrored() {
    svg_gauge_checks(JamDirection::CounterClockwise);
}

/// Points along a bulge polyline (closed), y-up.
fn bulge_points(v: &[(f64, f64, f64)]) -> Vec<(f64, f64)> {
    let mut out = vec![(v[0].0, v[0].1)];
    for i in 0..v.len() - 1 {
        let (x0, y0, b) = v[i];
        let (x1, y1, _) = v[i + 1];
        for k in 1..=24 {
            let t = k as f64 / 24.0;
            if b == 0.0 {
                out.push((x0 + (x1 - x0) * t, y0 + (y1 - y0) * t));
                continue;
            }
            // Arc through chord with sweep θ = 4·atan(b).
            let theta = 4.0 * b.atan();
            let chord = (x1 - x0).hypot(y1 - y0);
            let radius = chord / (2.0 * (theta / 2.0).sin());
            let (mx, my) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            // Centre: from the midpoint, perpendicular to the chord (left of it for b > 0).
            let h = radius * (theta / 2.0).cos();
            let (ux, uy) = ((x1 - x0) / chord, (y1 - y0) / chord);
            let (cx, cy) = (mx - uy * h, my + ux * h);
            let start = (y0 - cy).atan2(x0 - cx);
            let ang = start + theta * t;
            let rr = radius.abs();
            out.push((cx + rr * ang.cos(), cy + rr * ang.sin()));
        }
    }
    out
}

#[test]
fn dxf_gauge_parses_back_within_a_micron() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gauge.dxf");
    let options = GaugeOptions {
        label: true,
        ..GaugeOptions::default()
    };
    write_gauge(&GaugeGeometry::PAPER, &options, &out).unwrap();
    let drawing = dxf::Drawing::load_file(&out).unwrap();
    assert_eq!(
        drawing.header.default_drawing_units,
        dxf::enums::Units::Millimeters
    );
    let g = GaugeGeometry::PAPER;
    let mut circles = Vec::new();
    let mut polylines = Vec::new();
    let mut texts = 0;
    for e in drawing.entities() {
        match &e.specific {
            dxf::entities::EntityType::Circle(c) => {
                assert_eq!(e.common.layer, "CUT");
                circles.push(((c.center.x, c.center.y), c.radius));
            }
            dxf::entities::EntityType::LwPolyline(p) => {
                assert_eq!(e.common.layer, "CUT");
                assert!(p.is_closed());
                polylines.push(
                    p.vertices
                        .iter()
                        .map(|v| (v.x, v.y, v.bulge))
                        .collect::<Vec<_>>(),
                );
            }
            dxf::entities::EntityType::Text(t) => {
                assert_eq!(e.common.layer, "ENGRAVE");
                texts += usize::from(t.value.contains("jam CW"));
            }
            other => panic!("unexpected entity {other:?}"),
        }
    }
    assert_eq!(
        (circles.len(), polylines.len(), texts),
        (2, 1, 1),
        "two holes, the spiral, a label naming the sense"
    );
    let centre = (
        (circles[0].0.0 + circles[1].0.0) / 2.0,
        (circles[0].0.1 + circles[1].0.1) / 2.0,
    );
    for (c, r) in &circles {
        assert!((r - f64::from(g.hole_radius_mm)).abs() < 1e-9);
        assert!(((c.0 - centre.0).abs() - f64::from(g.hole_distance_mm)).abs() < 1e-9);
        assert!((c.1 - centre.1).abs() < 1e-9);
    }
    let c = pitch_mm_per_rad(f64::from(g.pitch_um_per_deg));
    let a = f64::from(g.radius_mm) - PI * c;
    let pts = bulge_points(&polylines[0]);
    check_spiral(&pts, centre, a, c, 1.0);
}

#[test]
fn the_test_piece_finger_and_slot_are_dilated_by_the_kerf() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gauge.dxf");
    let options = GaugeOptions {
        test_piece: Some(TestPieceSpec {
            thickness_mm: 3.0,
            finger_width_mm: 6.0,
            kerf_um: 200.0,
        }),
        label: false,
    };
    write_gauge(&GaugeGeometry::PAPER, &options, &out).unwrap();
    let drawing = dxf::Drawing::load_file(&out).unwrap();
    let polys: Vec<Vec<(f64, f64)>> = drawing
        .entities()
        .filter_map(|e| match &e.specific {
            dxf::entities::EntityType::LwPolyline(p) => {
                Some(p.vertices.iter().map(|v| (v.x, v.y)).collect())
            }
            _ => None,
        })
        .collect();
    assert_eq!(polys.len(), 3, "spiral, tab, slot");
    let (k, f, l) = (0.2, 6.0, 3.0);
    let bbox = |p: &[(f64, f64)]| {
        p.iter()
            .fold((f64::MAX, f64::MAX, f64::MIN, f64::MIN), |b, q| {
                (b.0.min(q.0), b.1.min(q.1), b.2.max(q.0), b.3.max(q.1))
            })
    };
    let has_x = |p: &[(f64, f64)], x: f64| p.iter().any(|q| (q.0 - x).abs() < 1e-9);
    // Tab part: outline grows by k/2 all round; the finger spans [f − k/2, 2f + k/2].
    let tab = &polys[1];
    let (x0, y0, x1, y1) = bbox(tab);
    assert!((x1 - x0 - (3.0 * f + k)).abs() < 1e-9);
    assert!((y1 - y0 - (2.0 * f + l + k)).abs() < 1e-9);
    let ox = x0 + k / 2.0;
    assert!(has_x(tab, ox + f - k / 2.0) && has_x(tab, ox + 2.0 * f + k / 2.0));
    // Slot part: the slot's walls move in by k/2: [f + k/2, 2f − k/2], its width f − k.
    let slot = &polys[2];
    let (x0, _, x1, _) = bbox(slot);
    assert!((x1 - x0 - (3.0 * f + k)).abs() < 1e-9);
    let ox = x0 + k / 2.0;
    assert!(has_x(slot, ox + f + k / 2.0) && has_x(slot, ox + 2.0 * f - k / 2.0));
}

#[test]
fn bad_gauge_arguments_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let paper = GaugeGeometry::PAPER;
    let none = GaugeOptions::default();
    let out = dir.path().join("gauge.pdf");
    assert!(write_gauge(&paper, &none, &out).is_err());
    let out = dir.path().join("gauge.svg");
    let holes_too_far = GaugeGeometry {
        hole_distance_mm: 9.0,
        ..paper
    };
    let e = write_gauge(&holes_too_far, &none, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("hole"), "{e}");
    let thin_test_piece = GaugeOptions {
        test_piece: Some(TestPieceSpec {
            thickness_mm: 0.1,
            finger_width_mm: 6.3,
            kerf_um: 150.0,
        }),
        label: false,
    };
    let e = write_gauge(&paper, &thin_test_piece, &out)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--thickness-mm"), "{e}");
    assert!(!out.exists());
}
