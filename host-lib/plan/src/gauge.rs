//! The spiral gauge to cut: one turn of the Archimedean spiral r(φ) = a + c·φ closed by its radial
//! step, and the two prong holes, from the same [`GaugeGeometry`] the device receives with every
//! run and the same spiral model the device measures with ([`kerfmeter_protocol::spiral`]: pitch
//! and start radius). Written as SVG or DXF, in mm.
//!
//! ```text
//!   Seen from above (the top face of the sheet, as the drawing is shown), for
//!   JamDirection::Clockwise (the default):
//!
//!                       φ = π/2
//!                   .-~~~~~~~~~~~-.
//!                .'        ↺        '.        φ grows counter-clockwise and r with it:
//!               /   φ increases here  \       r(φ) = a + c·φ, a = r_mean − π·c
//!     φ = π    |   (O)      +      (O) |====  φ = 0 / 2π: the radial step, from r = a (inner)
//!               \      holes at 0, π   /      out to r = a + 2π·c
//!                '.                 .'
//!                   '-.__________.-'          the hub turns the inset ↻ clockwise, towards
//!                       φ = 3π/2              decreasing φ: the gap k − c·θs closes everywhere
//! ```
//!
//! For [`JamDirection::CounterClockwise`] the drawing is mirrored: φ grows clockwise. Either way
//! turning the inset in the jam direction moves every point of its edge towards smaller φ, where the
//! surrounding sheet's edge lies c·θs further in: the gap closes at θs = k / c.
//!
//! * **What is cut**: the spiral line and the two holes (red `#FF0000` hairlines, 0.01 mm). The
//!   inset is the part inside the spiral; the surrounding sheet holds it, so there is no outer cut.
//!   The gauge is *not* kerf-compensated: the kerf is what it measures.
//! * **Arcs**: the spiral is not a circle; it is drawn as biarcs (tangent-continuous circular arcs)
//!   within [`CURVE_TOLERANCE_MM`] (0.05 µm) of the true spiral, as SVG `A` commands and DXF
//!   `LWPOLYLINE` bulges; the holes are `<circle>`s and `CIRCLE`s.
//! * **Frames**: positions are computed in a y-up top view with the page's bottom-left corner at
//!   the origin (DXF's own frame); SVG output flips y (its y axis points down) without mirroring the
//!   picture.
//! * **Extras**: an optional engraved label (SVG `<text>` filled black / DXF `TEXT` on layer
//!   `ENGRAVE`) naming the geometry and the jam direction, and optionally the paper's test piece
//!   beside the gauge: a one-finger box-joint pair (a tab part and a slot part, finger width × sheet
//!   thickness) dilated by a given kerf with the plan-dilation code, to check a fit by hand.
//! * **Record**: a comment saying the drawing is the gauge, to be cut as drawn (with the test
//!   piece's kerf), so that `dilate` refuses it ([`crate::compensation::GaugeRecord`]).

use std::f64::consts::TAU;
use std::fmt::Write as _;

use cavalier_contours::polyline::{PlineSource, PlineSourceMut, PlineVertex};
use kerfmeter_protocol::spiral::{pitch_mm_per_rad, start_radius_mm};
use kerfmeter_protocol::{GaugeGeometry, JamDirection, RunParams};
use serde::Serialize;

use super::compensation::GaugeRecord;
use super::dilate::{self, Contour, KerfSource};
use super::geom::{Affine, CURVE_TOLERANCE_MM, Pline, V2, fit_biarcs, segment_distance, v2};
use super::svg::write_pline;
use crate::error::{PlanError, Result};

/// Margin around the drawing, mm.
const MARGIN_MM: f64 = 5.0;
/// Gap between the gauge and the test piece, and between the two test parts, mm.
const GAP_MM: f64 = 5.0;
/// Label text height, mm.
const LABEL_TEXT_MM: f64 = 2.0;
/// Height reserved for the label's two lines, mm.
const LABEL_MM: f64 = 2.0 * LABEL_TEXT_MM * 1.5;
/// Cut stroke width (a hairline), mm.
const HAIRLINE_MM: f64 = 0.01;

/// The box-joint test piece to add beside the gauge.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TestPieceSpec {
    /// Sheet thickness L: the finger's length and the slot's depth, mm.
    pub thickness_mm: f64,
    /// Finger (and slot) width, mm.
    pub finger_width_mm: f64,
    /// Kerf the test piece is dilated by, µm.
    pub kerf_um: f64,
}

/// What to draw besides the gauge.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct GaugeOptions {
    /// Add the box-joint test piece.
    pub test_piece: Option<TestPieceSpec>,
    /// Add an engraved label.
    pub label: bool,
}

/// The gauge laid out on a page: y-up top view, mm, origin at the page's bottom-left corner.
#[derive(Debug, Clone)]
pub struct GaugeDrawing {
    /// The geometry drawn.
    pub geometry: GaugeGeometry,
    /// Page size (width, height), mm.
    pub page_mm: [f64; 2],
    /// Centre of the spiral.
    pub center: V2,
    /// Spiral pitch c, mm per radian.
    pub pitch_mm_per_rad: f64,
    /// Spiral start radius a, mm.
    pub start_radius_mm: f64,
    /// The closed spiral cut (biarcs, then the radial step).
    pub spiral: Pline,
    /// Largest distance between the drawn spiral and r(φ) = a + c·φ, found by dense sampling, mm.
    pub max_deviation_mm: f64,
    /// Hole centres (at φ = 0 and φ = π) and the drawn hole radius, mm.
    pub holes: [(V2, f64); 2],
    /// Test-piece parts (tab, slot), already dilated, with their names.
    pub test_piece: Vec<(String, Pline)>,
    /// The kerf the test piece is dilated by, µm (`None` without one): recorded in the drawing.
    pub test_piece_kerf_um: Option<f64>,
    /// Label lines, each with its baseline start; and the text height, mm.
    pub label: Option<(Vec<(String, V2)>, f64)>,
}

/// +1 when φ grows counter-clockwise seen from above (clockwise jam), −1 otherwise.
pub fn spiral_sense(jam: JamDirection) -> f64 {
    match jam {
        JamDirection::Clockwise => 1.0,
        JamDirection::CounterClockwise => -1.0,
    }
}

/// Check a gauge geometry (the device's own ranges, and that the holes fit inside the spiral).
pub fn check_geometry(g: &GaugeGeometry) -> Result<()> {
    let params = RunParams {
        gauge: *g,
        ..RunParams::DEFAULT
    };
    if let Err(field) = params.validate() {
        return Err(PlanError::InvalidArgument(format!(
            "gauge: {}",
            params.why_invalid(field)
        )));
    }
    let a = start_radius_mm(g);
    let hole_reach = f64::from(g.hole_distance_mm) + f64::from(g.hole_radius_mm);
    if a <= hole_reach + 0.5 {
        return Err(PlanError::InvalidArgument(format!(
            "the spiral starts at r = {a:.3} mm, too close to the prong holes (they reach {hole_reach:.3} mm from the centre): use a larger radius, a smaller pitch or holes nearer the centre"
        )));
    }
    Ok(())
}

/// One turn of the spiral and its step as a closed polyline centred at the origin, y-up, φ
/// counter-clockwise; returns it with the largest deviation found by dense sampling.
pub fn spiral_canonical(a: f64, c: f64) -> (Pline, f64) {
    let f = |phi: f64| {
        let r = a + c * phi;
        let (s, co) = phi.sin_cos();
        (v2(r * co, r * s), v2(c * co - r * s, c * s + r * co))
    };
    let mut vertices: Vec<PlineVertex<f64>> = Vec::new();
    const PIECES: usize = 8;
    for k in 0..PIECES {
        let t0 = TAU * k as f64 / PIECES as f64;
        let t1 = TAU * (k + 1) as f64 / PIECES as f64;
        fit_biarcs(&f, t0, t1, CURVE_TOLERANCE_MM * 0.5, &mut vertices);
    }
    let end = f(TAU).0;
    vertices.push(PlineVertex::new(end.x, end.y, 0.0));
    let mut p = Pline::new_closed();
    for v in vertices {
        p.add_vertex(v);
    }
    // Independent check of the whole curve: distance of dense samples of r(φ) to the drawing.
    let n = p.vertex_count();
    let mut max_dev: f64 = 0.0;
    let mut seg = 0usize;
    const SAMPLES: usize = 20_000;
    for i in 0..=SAMPLES {
        let q = f(TAU * i as f64 / SAMPLES as f64).0;
        // The spiral's samples advance along the segments in order; look around the current one.
        let mut best = f64::INFINITY;
        let mut best_seg = seg;
        for s in seg.saturating_sub(1)..(seg + 3).min(n - 1) {
            let (v, w) = (p.at(s), p.at(s + 1));
            let d = segment_distance(v2(v.x, v.y), v2(w.x, w.y), v.bulge, q);
            if d < best {
                best = d;
                best_seg = s;
            }
        }
        seg = best_seg;
        max_dev = max_dev.max(best);
    }
    (p, max_dev)
}

/// The two test-piece parts (tab, slot), nominal, y-up, with their lower-left corner at `origin`.
fn test_parts(spec: &TestPieceSpec, origin: V2) -> [(String, Pline); 2] {
    let (f, l) = (spec.finger_width_mm, spec.thickness_mm);
    let w = 3.0 * f;
    let h = 2.0 * f;
    let poly = |pts: &[(f64, f64)], dx: f64| {
        let mut p = Pline::new_closed();
        for &(x, y) in pts {
            p.add(origin.x + dx + x, origin.y + y, 0.0);
        }
        p
    };
    // Tab part: a body w × h with the finger (f × l) on top, centred.
    let tab = poly(
        &[
            (0.0, 0.0),
            (w, 0.0),
            (w, h),
            (2.0 * f, h),
            (2.0 * f, h + l),
            (f, h + l),
            (f, h),
            (0.0, h),
        ],
        0.0,
    );
    // Slot part: w × (h + l) with the slot (f wide, l deep) open at the bottom, centred.
    let slot = poly(
        &[
            (0.0, 0.0),
            (f, 0.0),
            (f, l),
            (2.0 * f, l),
            (2.0 * f, 0.0),
            (w, 0.0),
            (w, h + l),
            (0.0, h + l),
        ],
        w + GAP_MM,
    );
    [
        ("test-piece-tab".into(), tab),
        ("test-piece-slot".into(), slot),
    ]
}

/// The test piece's parts, checked and dilated by its kerf, with their lower-left corner at
/// `origin`.
fn dilated_test_piece(spec: &TestPieceSpec, origin: V2) -> Result<Vec<(String, Pline)>> {
    for (name, v) in [
        ("--thickness-mm", spec.thickness_mm),
        ("--finger-width-mm", spec.finger_width_mm),
    ] {
        if !(v.is_finite() && (0.5..=50.0).contains(&v)) {
            return Err(PlanError::InvalidArgument(format!(
                "{name} must be between 0.5 and 50 mm, got {}",
                kerfmeter_protocol::Shown(v)
            )));
        }
    }
    KerfSource::check_kerf_um(spec.kerf_um)?;
    let parts = test_parts(spec, origin);
    let contours: Vec<Contour> = parts
        .iter()
        .map(|(name, p)| Contour {
            pline: p.clone(),
            label: name.clone(),
        })
        .collect();
    let d = dilate::dilate(&contours, &KerfSource::Uniform(spec.kerf_um))?;
    Ok(parts
        .into_iter()
        .map(|(name, _)| name)
        .zip(d.contours)
        .collect())
}

/// The engraved label's two lines (text, baseline start) and text height; widens the page to fit
/// them.
fn label_lines(
    g: &GaugeGeometry,
    opts: &GaugeOptions,
    width: &mut f64,
) -> (Vec<(String, V2)>, f64) {
    let dir = match g.jam_direction {
        JamDirection::Clockwise => "CW",
        JamDirection::CounterClockwise => "CCW",
    };
    let first = format!(
        "Kerfmeter gauge c={} um/deg r={} mm",
        g.pitch_um_per_deg, g.radius_mm
    );
    let mut second = format!(
        "holes {}@{} mm, jam {dir}, top face up",
        g.hole_radius_mm, g.hole_distance_mm
    );
    if let Some(t) = &opts.test_piece {
        let _ = write!(second, ", test k={} um", t.kerf_um);
    }
    let line = LABEL_TEXT_MM * 1.5;
    // Sans-serif glyphs average about 0.6 of the text height: keep the page wide enough.
    let longest = first.chars().count().max(second.chars().count()) as f64;
    *width = width.max(2.0 * MARGIN_MM + 0.6 * LABEL_TEXT_MM * longest);
    (
        vec![
            (first, v2(MARGIN_MM, MARGIN_MM + line)),
            (second, v2(MARGIN_MM, MARGIN_MM)),
        ],
        LABEL_TEXT_MM,
    )
}

/// Lay the gauge out (see [`GaugeDrawing`]).
pub fn build(g: &GaugeGeometry, opts: &GaugeOptions) -> Result<GaugeDrawing> {
    check_geometry(g)?;
    let c = pitch_mm_per_rad(g);
    let a = start_radius_mm(g);
    let outer = a + TAU * c;
    let label_h = if opts.label { LABEL_MM } else { 0.0 };
    let center = v2(MARGIN_MM + outer, MARGIN_MM + label_h + outer);
    let sense = spiral_sense(g.jam_direction);
    let (canonical, max_dev) = spiral_canonical(a, c);
    // Place: mirror y for the counter-clockwise sense, then translate.
    let place = Affine {
        a: 1.0,
        b: 0.0,
        c: 0.0,
        d: sense,
        e: center.x,
        f: center.y,
    };
    let spiral = super::geom::transform_similarity(&canonical, &place);
    let r_hole = f64::from(g.hole_radius_mm);
    let dist = f64::from(g.hole_distance_mm);
    let holes = [
        (center + v2(dist, 0.0), r_hole),
        (center - v2(dist, 0.0), r_hole),
    ];
    let mut width = 2.0 * (MARGIN_MM + outer);
    let mut height = 2.0 * outer + 2.0 * MARGIN_MM + label_h;
    let mut test_piece = Vec::new();
    if let Some(spec) = &opts.test_piece {
        let origin = v2(width - MARGIN_MM + GAP_MM, MARGIN_MM + label_h);
        test_piece = dilated_test_piece(spec, origin)?;
        let f = spec.finger_width_mm;
        width += GAP_MM + 6.0 * f + GAP_MM;
        height = height.max(2.0 * f + spec.thickness_mm + 2.0 * MARGIN_MM + label_h + 1.0);
    }
    let label = opts.label.then(|| label_lines(g, opts, &mut width));
    Ok(GaugeDrawing {
        geometry: *g,
        page_mm: [width, height],
        center,
        pitch_mm_per_rad: c,
        start_radius_mm: a,
        spiral,
        max_deviation_mm: max_dev,
        holes,
        test_piece,
        test_piece_kerf_um: opts.test_piece.map(|spec| spec.kerf_um),
        label,
    })
}

/// What the drawing records of itself, so that `dilate` refuses it (cut as drawn).
fn record(d: &GaugeDrawing) -> GaugeRecord {
    GaugeRecord {
        test_piece_kerf_um: d.test_piece_kerf_um,
    }
}

fn fmt6(v: f64) -> String {
    crate::decimal::trimmed(v, 6)
}

/// The gauge as an SVG document (mm units, y down).
pub fn to_svg(d: &GaugeDrawing) -> String {
    let [w, h] = d.page_mm;
    // Top view y-up → SVG y-down: same picture, flipped coordinates.
    let flip = Affine {
        a: 1.0,
        b: 0.0,
        c: 0.0,
        d: -1.0,
        e: 0.0,
        f: h,
    };
    let g = &d.geometry;
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}mm" height="{}mm" viewBox="0 0 {} {}">"#,
        fmt6(w),
        fmt6(h),
        fmt6(w),
        fmt6(h)
    );
    let _ = writeln!(s, "  {}", record(d).svg_comment());
    let _ = writeln!(s, "  <title>Kerfmeter spiral gauge</title>");
    let _ = writeln!(
        s,
        "  <desc>Cut the red hairlines (the spiral and the two prong holes; there is no outer cut) with the sheet's top face up. Pitch c = {} um/deg ({:.6} mm/rad), mean radius {} mm, spiral r = {:.6} + {:.6}*phi mm, holes r = {} mm at {} mm, jam direction {:?} seen from above. Spiral drawn as biarcs within {:.3} um.</desc>",
        g.pitch_um_per_deg,
        d.pitch_mm_per_rad,
        g.radius_mm,
        d.start_radius_mm,
        d.pitch_mm_per_rad,
        g.hole_radius_mm,
        g.hole_distance_mm,
        g.jam_direction,
        d.max_deviation_mm * 1e3
    );
    let _ = writeln!(
        s,
        r##"  <g id="cut" fill="none" stroke="#FF0000" stroke-width="{HAIRLINE_MM}">"##
    );
    let mut path = String::new();
    write_pline(&d.spiral, &flip, 6, &mut path);
    let _ = writeln!(s, r#"    <path id="spiral" d="{path}"/>"#);
    for ((c, r), id) in d.holes.iter().zip(["hole-0", "hole-pi"]) {
        let p = flip.apply(*c);
        let _ = writeln!(
            s,
            r#"    <circle id="{id}" cx="{}" cy="{}" r="{}"/>"#,
            fmt6(p.x),
            fmt6(p.y),
            fmt6(*r)
        );
    }
    for (name, p) in &d.test_piece {
        let mut path = String::new();
        write_pline(p, &flip, 6, &mut path);
        let _ = writeln!(s, r#"    <path id="{name}" d="{path}"/>"#);
    }
    let _ = writeln!(s, "  </g>");
    if let Some((lines, size)) = &d.label {
        let _ = writeln!(
            s,
            r##"  <g id="engrave" font-family="sans-serif" font-size="{size}" fill="#000000">"##
        );
        for (text, at) in lines {
            let p = flip.apply(*at);
            let _ = writeln!(
                s,
                r#"    <text x="{}" y="{}">{}</text>"#,
                fmt6(p.x),
                fmt6(p.y),
                crate::xml::escape(text)
            );
        }
        let _ = writeln!(s, "  </g>");
    }
    s.push_str("</svg>\n");
    s
}

/// The gauge as a DXF drawing (R2000, `$INSUNITS` = mm; layers `CUT` red and `ENGRAVE` green).
pub fn to_dxf(d: &GaugeDrawing) -> Result<Vec<u8>> {
    use dxf::entities::{Circle, Entity, EntityType, LwPolyline, Text};
    use dxf::enums::{AcadVersion, Units};
    use dxf::tables::Layer;
    use dxf::{Color, Drawing, LwPolylineVertex, Point};

    let mut drawing = Drawing::new();
    drawing.header.version = AcadVersion::R2000;
    drawing.header.default_drawing_units = Units::Millimeters;
    for (name, color) in [("CUT", 1u8), ("ENGRAVE", 3u8)] {
        drawing.add_layer(Layer {
            name: name.into(),
            color: Color::from_index(color),
            ..Layer::default()
        });
    }
    let on = |mut e: Entity, layer: &str| {
        e.common.layer = layer.into();
        e
    };
    let lw = |p: &Pline| {
        let mut lw = LwPolyline {
            vertices: p
                .iter_vertexes()
                .map(|v| LwPolylineVertex {
                    x: v.x,
                    y: v.y,
                    bulge: v.bulge,
                    ..LwPolylineVertex::default()
                })
                .collect(),
            ..LwPolyline::default()
        };
        lw.set_is_closed(true);
        Entity::new(EntityType::LwPolyline(lw))
    };
    drawing.add_entity(on(lw(&d.spiral), "CUT"));
    for (c, r) in &d.holes {
        drawing.add_entity(on(
            Entity::new(EntityType::Circle(Circle::new(
                Point::new(c.x, c.y, 0.0),
                *r,
            ))),
            "CUT",
        ));
    }
    for (_, p) in &d.test_piece {
        drawing.add_entity(on(lw(p), "CUT"));
    }
    if let Some((lines, size)) = &d.label {
        for (text, at) in lines {
            let t = Text {
                location: Point::new(at.x, at.y, 0.0),
                text_height: *size,
                value: text.clone(),
                ..Text::default()
            };
            drawing.add_entity(on(Entity::new(EntityType::Text(t)), "ENGRAVE"));
        }
    }
    // The `dxf` crate writes no comments, and ends every line with CR LF.
    let mut out = record(d).dxf_comments("\r\n").into_bytes();
    drawing
        .save(&mut out)
        .map_err(|e| PlanError::Dxf(format!("cannot write the DXF: {e}")))?;
    // Its table heads get the handles the crate leaves out.
    crate::dxf_plan::with_table_handles(&out)
        .map_err(|e| PlanError::Dxf(format!("cannot write the DXF: {e}")))
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    #[test]
    fn the_spiral_is_within_tolerance_and_closes_with_the_radial_step() {
        let g = GaugeGeometry::PAPER;
        let c = pitch_mm_per_rad(&g);
        let a = 10.0 - PI * c;
        let (p, dev) = spiral_canonical(a, c);
        assert!(dev < 0.1e-3, "deviation {dev} mm");
        assert!(p.is_closed());
        let first = p.at(0);
        let last = p.at(p.vertex_count() - 1);
        assert!((first.x - a).abs() < 1e-12 && first.y.abs() < 1e-12);
        assert!((last.x - (a + TAU * c)).abs() < 1e-12 && last.y.abs() < 1e-12);
        assert_eq!(last.bulge, 0.0, "the step is straight");
        // Counter-clockwise in the canonical frame: the spiral winds with positive area.
        assert!(p.area() > 0.0);
    }

    #[test]
    fn the_paper_gauge_fits_and_nonsense_is_refused() {
        assert!(check_geometry(&GaugeGeometry::PAPER).is_ok());
        let mut g = GaugeGeometry::PAPER;
        g.hole_distance_mm = 8.0;
        assert!(check_geometry(&g).is_err());
        g = GaugeGeometry::PAPER;
        g.pitch_um_per_deg = f32::NAN;
        assert!(check_geometry(&g).is_err());
    }

    #[test]
    fn the_test_piece_is_dilated_by_the_kerf() {
        let opts = GaugeOptions {
            test_piece: Some(TestPieceSpec {
                thickness_mm: 4.0,
                finger_width_mm: 6.0,
                kerf_um: 200.0,
            }),
            label: true,
        };
        let d = build(&GaugeGeometry::PAPER, &opts).unwrap();
        assert_eq!(d.test_piece.len(), 2);
        // Tab: nominal area 18×12 + 6×4 = 240, plus perimeter·0.1 − 4·(1 − π/4)·0.01 … grows.
        let tab = d.test_piece[0].1.area().abs();
        assert!(tab > 240.0 && tab < 250.0, "{tab}");
        assert!(d.label.is_some());
        assert!(d.page_mm[0] > 60.0);
    }
}
