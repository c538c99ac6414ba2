//! The gauge the cutter twin cut is the gauge the device twin measures: the plan crate's gauge
//! drawing, written as G-code here (G0 travels with the beam off, G1 lines and G2/G3 arcs at
//! 1 µm, laser mode),
//! streamed into the GRBL cutter twin, and the trace it records put under the device twin's
//! prongs. Drawn right, it reads like any gauge of the twin's cutter; with its pitch wrong it
//! reads wrong by c/c′; mirrored, or with a hole missing or too small, it is refused with the
//! reason.

use kerfmeter::grbl::twin::{CutterLog, CutterOptions, Grbl, Segment};
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_plan::gauge::{GaugeDrawing, GaugeOptions, build};
use kerfmeter_plan::gcode::{GcodeOptions, Provenance, gauge_program};
use kerfmeter_plan::profile::CutSettings;
use kerfmeter_protocol::spiral::kerf_from_angle;
use kerfmeter_protocol::{
    Fault, GaugeGeometry, KerfResult, Request, Response, RunParams, RunState,
};
use kerfmeter_twin::gauge_trace::{GaugeTraceError, TracedGaugeSlot};
use kerfmeter_twin::plant::{CutterKerf, PlantParams};
use kerfmeter_twin::{Twin, TwinOptions};

/// Where on the bed the gauge is cut, and where the prongs then come down, mm.
const AT_MM: [f64; 2] = [212.5, 87.25];

/// How the G-code places the drawing: each point's offset from the gauge's centre is scaled by
/// these before it is put at [`AT_MM`] (−1 in y mirrors it).
#[derive(Clone, Copy)]
struct Placement {
    scale: [f64; 2],
}

const AS_DRAWN: Placement = Placement { scale: [1.0, 1.0] };

/// G-code for the drawing's spiral and holes (holes listed in `holes`), placed as `placement`.
fn gcode(drawing: &GaugeDrawing, holes: &[usize], placement: Placement) -> Vec<String> {
    let c = drawing.center;
    let at = |x: f64, y: f64| {
        let (sx, sy) = (placement.scale[0], placement.scale[1]);
        [AT_MM[0] + sx * (x - c.x), AT_MM[1] + sy * (y - c.y)]
    };
    let mirrored = placement.scale[0] * placement.scale[1] < 0.0;
    let mut lines = vec!["G21 G90 G94".to_owned(), "M4 S0".to_owned()];
    let v = &drawing.spiral.vertex_data;
    let [x0, y0] = at(v[0].x, v[0].y);
    lines.push(format!("G0 X{x0:.3} Y{y0:.3}"));
    for i in 0..v.len() {
        let (p, q) = (&v[i], &v[(i + 1) % v.len()]);
        let [x, y] = at(q.x, q.y);
        if p.bulge == 0.0 {
            lines.push(format!("G1 X{x:.3} Y{y:.3} S1000 F600"));
            continue;
        }
        // The arc's centre from its bulge (tan of a quarter of its signed sweep).
        let (dx, dy) = (q.x - p.x, q.y - p.y);
        let h = (1.0 - p.bulge * p.bulge) / (4.0 * p.bulge);
        let centre = at((p.x + q.x) / 2.0 - dy * h, (p.y + q.y) / 2.0 + dx * h);
        let [px, py] = at(p.x, p.y);
        let ccw = (p.bulge > 0.0) != mirrored;
        let (i_mm, j_mm) = (centre[0] - px, centre[1] - py);
        let g = if ccw { "G3" } else { "G2" };
        lines.push(format!(
            "{g} X{x:.3} Y{y:.3} I{i_mm:.3} J{j_mm:.3} S1000 F600"
        ));
    }
    for &i in holes {
        let (centre, r) = drawing.holes[i];
        let [cx, cy] = at(centre.x, centre.y);
        let r = r * placement.scale[0].abs();
        // The beam off for the travel, as the plan crate's programs do (laser mode would keep
        // it dark, but a program should not rely on that: the twin records it if it does).
        lines.push("M5".to_owned());
        lines.push(format!("G0 X{:.3} Y{cy:.3}", cx + r));
        lines.push("M4".to_owned());
        lines.push(format!(
            "G2 X{:.3} Y{cy:.3} I{:.3} J0 S1000 F600",
            cx + r,
            -r
        ));
    }
    lines.push("M5".to_owned());
    lines
}

/// Stream `lines` into a cutter twin one at a time (each waits for its `ok`), let it finish,
/// and return the segments it traced.
fn cut(lines: &[String]) -> Vec<Segment> {
    cut_on(CutterOptions::default(), lines)
}

/// [`cut`] on a cutter twin set up as `options`.
fn cut_on(options: CutterOptions, lines: &[String]) -> Vec<Segment> {
    let log = CutterLog::default();
    let mut grbl = Grbl::new(options, log.clone());
    grbl.take_output();
    for line in lines {
        grbl.receive(format!("{line}\n").as_bytes());
        let mut reply = String::new();
        while !reply.contains("ok") {
            assert!(!reply.contains("error"), "{line}: {reply}");
            grbl.advance_us(10_000);
            reply += &String::from_utf8(grbl.take_output()).unwrap();
        }
    }
    grbl.advance_us(600_000_000);
    let record = log.snapshot();
    assert!(record.travel_firings.is_empty());
    assert!(
        record.blanked_travels.is_empty(),
        "{:?}",
        record.blanked_travels
    );
    record.segments
}

/// The drawing of `geometry`, as the plan crate draws it.
fn drawing(geometry: &GaugeGeometry) -> GaugeDrawing {
    build(geometry, &GaugeOptions::default()).unwrap()
}

fn twin(seed: u64) -> Twin {
    let mut t = Twin::new(TwinOptions {
        seed,
        ..TwinOptions::default()
    });
    t.advance_ticks(5);
    t
}

#[test]
fn the_gauge_cut_as_drawn_reads_like_any_gauge_of_the_twins_cutter() {
    let segments = cut(&gcode(&drawing(&GaugeGeometry::PAPER), &[0, 1], AS_DRAWN));
    for seed in [3, 4] {
        let mut traced = twin(seed);
        let placed = traced.place_traced_gauge(&segments, AT_MM).unwrap();
        let reading = measure(&mut traced, &RunParams::DEFAULT).unwrap();
        assert_eq!(traced.plant().cut(), &placed);
        let geometry = *traced.plant().geometry();
        let pitch_error = geometry.pitch_um_per_deg / GaugeGeometry::PAPER.pitch_um_per_deg - 1.0;
        assert!(pitch_error.abs() < 5e-4, "{geometry:?}");
        assert_eq!(geometry.jam_direction, GaugeGeometry::PAPER.jam_direction);
        let truth = traced.plant().truth_um(&RunParams::DEFAULT);
        // The same seed's twin without the trace draws the same gauge from its cutter.
        let mut plain = twin(seed);
        let usual = measure(&mut plain, &RunParams::DEFAULT).unwrap();
        let error_um = f64::from(reading.kerf_um) - truth;
        eprintln!(
            "seed {seed}: read {:.2} µm, truth {truth:.2} µm, untraced twin {:.2} µm",
            reading.kerf_um, usual.kerf_um
        );
        assert!(error_um.abs() < 3.0, "{error_um}");
        assert!((reading.kerf_um - usual.kerf_um).abs() < 1.0);
    }
}

/// The program `kerfmeter gauge -o gauge.gcode --at-mm X,Y` writes, as its lines.
fn product_gauge_gcode() -> Vec<String> {
    let settings = CutSettings {
        feed_mm_per_min: 300.0,
        power_percent: 100.0,
        passes: 1,
    };
    let options = GcodeOptions {
        origin_mm: AT_MM,
        ..GcodeOptions::default()
    };
    let provenance = Provenance {
        source: "gauge".to_owned(),
        kerf: "none: the gauge measures it".to_owned(),
    };
    let drawing = drawing(&GaugeGeometry::PAPER);
    let (program, _) = gauge_program(&drawing, &settings, &options, &provenance).unwrap();
    program.to_text().lines().map(str::to_owned).collect()
}

/// The product's own gauge G-code, not this file's: cut by the cutter twin, it is recognised
/// and reads the cutter's kerf. A wrong pitch, a missing hole or a mirrored spiral in the gauge
/// writer would fail here.
#[test]
fn the_products_gauge_g_code_cut_by_the_cutter_twin_reads_the_cutters_kerf() {
    let segments = cut(&product_gauge_gcode());
    let mut traced = twin(3);
    traced.place_traced_gauge(&segments, AT_MM).unwrap();
    let geometry = *traced.plant().geometry();
    let pitch_error = geometry.pitch_um_per_deg / GaugeGeometry::PAPER.pitch_um_per_deg - 1.0;
    assert!(pitch_error.abs() < 5e-4, "{geometry:?}");
    assert_eq!(geometry.jam_direction, GaugeGeometry::PAPER.jam_direction);
    let reading = measure(&mut traced, &RunParams::DEFAULT).unwrap();
    let truth = traced.plant().truth_um(&RunParams::DEFAULT);
    let error_um = f64::from(reading.kerf_um) - truth;
    assert!(
        error_um.abs() < 3.0,
        "read {} µm, truth {truth} µm",
        reading.kerf_um
    );
}

#[test]
fn the_kerf_measured_is_the_cutter_twins_not_the_device_twins() {
    let options = CutterOptions {
        kerf: CutterKerf {
            kerf_um: 230.0,
            kerf_sd_um: 0.0,
            repeatability_um: 5.0,
        },
        ..CutterOptions::default()
    };
    let segments = cut_on(
        options,
        &gcode(&drawing(&GaugeGeometry::PAPER), &[0, 1], AS_DRAWN),
    );
    let params = PlantParams {
        kerf_location_sd_um: 0.0,
        ..PlantParams::default()
    };
    let cutter = options.kerf.cutter(params, 11).unwrap();
    let mut t = Twin::new(TwinOptions {
        kerf_um: 150.0,
        seed: 11,
        plant: params,
        ..TwinOptions::default()
    });
    t.advance_ticks(5);
    let placed = t
        .place_traced_gauge_cut_by(&segments, AT_MM, &cutter)
        .unwrap();
    assert_eq!(placed.kerf_um, 230.0);
    let reading = f64::from(measure(&mut t, &RunParams::DEFAULT).unwrap().kerf_um);
    let truth = t.plant().truth_um(&RunParams::DEFAULT);
    eprintln!("cutter kerf 230 µm: read {reading:.2} µm, truth {truth:.2} µm");
    assert!((reading - truth).abs() < 3.0, "{reading} vs {truth}");
    // The truth is the cutter's kerf plus the contact's compression at the run's force.
    assert!(truth > 230.0 && truth < 245.0, "{truth}");
}

#[test]
fn a_pitch_scaled_in_the_g_code_reads_wrong_by_the_pitchs_ratio() {
    // The device takes the jam angle θs = k / c′ of a spiral of pitch c′ for one of pitch c:
    // it reads c·θs = k·c/c′ (the spiral model's gap = k − c·θs).
    for scale in [1.05f32, 0.96] {
        let wrong = GaugeGeometry {
            pitch_um_per_deg: GaugeGeometry::PAPER.pitch_um_per_deg * scale,
            ..GaugeGeometry::PAPER
        };
        let segments = cut(&gcode(&drawing(&wrong), &[0, 1], AS_DRAWN));
        let mut t = twin(5);
        t.place_traced_gauge(&segments, AT_MM).unwrap();
        let reading = f64::from(measure(&mut t, &RunParams::DEFAULT).unwrap().kerf_um);
        let traced = t.plant().geometry().pitch_um_per_deg;
        // Within 0.05 % (G-code's 1 µm rounding): 0.08 µm of a 160 µm reading.
        assert!(
            (traced / wrong.pitch_um_per_deg - 1.0).abs() < 5e-4,
            "{traced} vs {}",
            wrong.pitch_um_per_deg
        );
        let truth = t.plant().truth_um(&RunParams::DEFAULT);
        let expected = truth / f64::from(scale);
        eprintln!("pitch ×{scale}: read {reading:.2} µm, truth {truth:.2}, expected {expected:.2}");
        assert!((reading - expected).abs() < 3.0, "{reading} vs {expected}");
        assert!((reading - truth).abs() > 5.0, "{reading} vs {truth}");
    }
}

#[test]
fn a_gauge_placed_through_a_shared_slot_is_the_one_the_next_run_measures() {
    // As a served twin's caller places it, while the twin runs in its thread.
    let steep = GaugeGeometry {
        pitch_um_per_deg: GaugeGeometry::PAPER.pitch_um_per_deg * 1.05,
        ..GaugeGeometry::PAPER
    };
    let segments = cut(&gcode(&drawing(&steep), &[0, 1], AS_DRAWN));
    let slot = TracedGaugeSlot::default();
    let mut t = twin(12).with_traced_gauges(slot.clone());
    let cutter = CutterKerf::default()
        .cutter(PlantParams::default(), 12)
        .unwrap();
    let placed = slot
        .place(
            &segments,
            &GaugeGeometry::PAPER,
            AT_MM,
            &cutter,
            &mut Rng::new(2),
        )
        .unwrap();
    measure(&mut t, &RunParams::DEFAULT).unwrap();
    assert_eq!(t.plant().cut(), &placed);
    let pitch = t.plant().geometry().pitch_um_per_deg;
    assert!(
        (pitch / steep.pitch_um_per_deg - 1.0).abs() < 5e-4,
        "{pitch}"
    );
    // A refused trace leaves the slot as it was.
    assert!(
        slot.place(&[], &GaugeGeometry::PAPER, AT_MM, &cutter, &mut Rng::new(3))
            .is_err()
    );
    assert_eq!(slot.get().map(|(_, cut)| cut), Some(placed));
}

#[test]
fn a_drawing_scaled_as_a_whole_reads_as_its_pitch_and_holes_say() {
    // G-code scaled 2 % (a units or DPI slip): the pitch, the hole radius and the holes' distance
    // all grow. The device reads θm = θplay′ + k′/c′ (the play of the holes as cut, the jam of
    // the steeper spiral) as c·(θm − θplay(k)) = k, the spiral model's fixed point.
    let scaled = Placement {
        scale: [1.02, 1.02],
    };
    let segments = cut(&gcode(&drawing(&GaugeGeometry::PAPER), &[0, 1], scaled));
    // No repeatability and no location bias: the holes' play is then the same at every angle.
    let plant = PlantParams {
        hole_position_sd_um: 0.0,
        prong_offset_sd_um: 0.0,
        kerf_location_sd_um: 0.0,
        ..PlantParams::default()
    };
    let mut t = Twin::new(TwinOptions {
        seed: 13,
        plant,
        ..TwinOptions::default()
    });
    t.advance_ticks(5);
    let placed = t.place_traced_gauge(&segments, AT_MM).unwrap();
    assert!(
        (placed.hole_offset_um[0][0] - 106.0).abs() < 1.0,
        "{placed:?}"
    );
    let reading = f64::from(measure(&mut t, &RunParams::DEFAULT).unwrap().kerf_um);
    let truth = t.plant().truth_um(&RunParams::DEFAULT);
    let physical = *t.plant().geometry();
    let jam_deg = t.plant().play_deg().0 + truth / f64::from(physical.pitch_um_per_deg);
    let expected = kerf_from_angle(&GaugeGeometry::PAPER, jam_deg as f32).kerf_um;
    let expected = f64::from(expected);
    eprintln!("scaled ×1.02: read {reading:.2} µm, truth {truth:.2}, expected {expected:.2}");
    assert!((reading - expected).abs() < 3.0, "{reading} vs {expected}");
    assert!((reading - truth).abs() > 2.0, "{reading} vs {truth}");
}

#[test]
fn a_mirrored_gauge_is_refused_as_turning_the_wrong_way() {
    let mirrored = Placement { scale: [1.0, -1.0] };
    let segments = cut(&gcode(&drawing(&GaugeGeometry::PAPER), &[0, 1], mirrored));
    let mut t = twin(6);
    let err = t.place_traced_gauge(&segments, AT_MM).unwrap_err();
    assert!(
        matches!(err, GaugeTraceError::SenseReversed { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("mirrored"), "{err}");
}

#[test]
fn a_missing_or_too_small_hole_is_refused_with_which_and_where() {
    let paper = drawing(&GaugeGeometry::PAPER);
    let mut t = twin(7);
    let missing = cut(&gcode(&paper, &[0], AS_DRAWN));
    let err = t.place_traced_gauge(&missing, AT_MM).unwrap_err();
    assert!(
        matches!(err, GaugeTraceError::HoleMissing { hole: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().starts_with("hole 1 is missing"), "{err}");
    // Hole 1 drawn 1.9 mm in radius: with half a 150 µm kerf, still under the 2 mm prong.
    let mut small = paper.clone();
    small.holes[1].1 = 1.9;
    let err = t
        .place_traced_gauge(&cut(&gcode(&small, &[0, 1], AS_DRAWN)), AT_MM)
        .unwrap_err();
    assert!(
        matches!(err, GaugeTraceError::HoleTooSmall { hole: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("too small"), "{err}");
    // Nothing cut there at all.
    let err = t.place_traced_gauge(&missing, [20.0, 20.0]).unwrap_err();
    assert!(matches!(err, GaugeTraceError::NoSpiral { .. }), "{err}");
}

#[test]
fn a_gauge_cut_off_where_the_prongs_come_down_is_refused_beyond_the_holes_play() {
    let segments = cut(&gcode(&drawing(&GaugeGeometry::PAPER), &[0, 1], AS_DRAWN));
    let mut t = twin(8);
    // The prongs come down 0.7 mm off: more than the 0.42 mm + half-kerf clearance.
    let err = t
        .place_traced_gauge(&segments, [AT_MM[0], AT_MM[1] + 0.7])
        .unwrap_err();
    assert!(matches!(err, GaugeTraceError::ProngOffHole { .. }), "{err}");
}

/// Run one measurement with `params`, polling like a host every 10 ms; the run's end or its
/// fault.
fn measure(twin: &mut Twin, params: &RunParams) -> Result<KerfResult, Fault> {
    assert_eq!(twin.request(&Request::Run(*params)), Response::Ok);
    for _ in 0..3000 {
        twin.advance_ticks(10);
        let Response::Status(s) = twin.request(&Request::GetStatus) else {
            panic!("no status");
        };
        match s.state {
            RunState::Done => match twin.request(&Request::GetKerf) {
                Response::Kerf(Some(k)) => return Ok(k),
                other => panic!("no result after Done: {other:?}"),
            },
            RunState::Fault(f) => return Err(f),
            _ => {}
        }
    }
    panic!("the run neither finished nor faulted in 30 s");
}
