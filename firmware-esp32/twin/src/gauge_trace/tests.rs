//! Tests of the `gauge_trace` module.

use super::*;
use crate::plant::{CutterKerf, PlantParams};

const PAPER: GaugeGeometry = GaugeGeometry::PAPER;

/// A cut move from `start` to `end`, mm.
fn cut_move(kind: SegmentKind, start: [f64; 2], end: [f64; 2]) -> Segment {
    Segment {
        kind,
        start: [start[0], start[1], 0.0],
        end: [end[0], end[1], 0.0],
        power_s: 1000.0,
        feed_mm_per_min: 600.0,
        complete: true,
        line: 1,
    }
}

/// The paper's gauge about `centre`, its spiral as 720 lines (φ counter-clockwise, or
/// clockwise when `mirrored`), its holes (centres given) as full circles.
fn trace(centre: [f64; 2], holes: [[f64; 2]; 2], mirrored: bool) -> Vec<Segment> {
    let (a, c) = (start_radius_mm(&PAPER), pitch_mm_per_rad(&PAPER));
    let y_sign = if mirrored { -1.0 } else { 1.0 };
    let at = |phi: f64| {
        let r = a + c * phi;
        [
            centre[0] + r * phi.cos(),
            centre[1] + y_sign * r * phi.sin(),
        ]
    };
    let n = 720;
    let mut segments: Vec<Segment> = (0..n)
        .map(|k| {
            let phi = |k: usize| TAU * k as f64 / n as f64;
            cut_move(SegmentKind::Line, at(phi(k)), at(phi(k + 1)))
        })
        .collect();
    segments.push(cut_move(SegmentKind::Line, at(TAU), at(0.0)));
    for h in holes {
        let r = f64::from(PAPER.hole_radius_mm);
        let start = [h[0] + r, h[1]];
        let kind = SegmentKind::Arc {
            center: h,
            clockwise: true,
        };
        segments.push(cut_move(kind, start, start));
    }
    segments
}

/// A cutter with no spread at all: a gauge's cut is what its trace says.
fn exact_cutter() -> Cutter {
    let params = PlantParams {
        kerf_location_sd_um: 0.0,
        ..PlantParams::default()
    };
    let kerf = CutterKerf {
        repeatability_um: 0.0,
        ..CutterKerf::default()
    };
    kerf.cutter(params, 1).unwrap()
}

fn drawn_holes(centre: [f64; 2]) -> [[f64; 2]; 2] {
    let d = f64::from(PAPER.hole_distance_mm);
    [[centre[0] + d, centre[1]], [centre[0] - d, centre[1]]]
}

#[test]
fn the_spirals_centre_pitch_and_sense_are_recovered() {
    let centre = [100.03, 50.02];
    let segments = trace(centre, drawn_holes(centre), false);
    let traced = TracedGauge::recover(&segments, &PAPER, [100.0, 50.0]).unwrap();
    assert!((traced.center_mm[0] - centre[0]).abs() < 1e-6, "{traced:?}");
    assert!((traced.center_mm[1] - centre[1]).abs() < 1e-6, "{traced:?}");
    let pitch = f64::from(PAPER.pitch_um_per_deg);
    assert!((traced.pitch_um_per_deg / pitch - 1.0).abs() < 1e-5);
    assert!((traced.radius_mm - f64::from(PAPER.radius_mm)).abs() < 1e-4);
    assert_eq!(traced.jam_direction, JamDirection::Clockwise);
    assert!(
        traced.step_rad.min(TAU - traced.step_rad) < 1e-3,
        "{traced:?}"
    );
    let mirrored = trace(centre, drawn_holes(centre), true);
    let traced = TracedGauge::recover(&mirrored, &PAPER, [100.0, 50.0]).unwrap();
    assert_eq!(traced.jam_direction, JamDirection::CounterClockwise);
    assert!((traced.pitch_um_per_deg / pitch - 1.0).abs() < 1e-5);
}

#[test]
fn traced_displacements_land_in_the_plants_frames() {
    let centre = [100.0, 50.0];
    let mut holes = drawn_holes(centre);
    // Hole 0 cut 30 µm towards +Y: on a clockwise gauge, against the jam at hole 0.
    holes[0][1] += 0.030;
    // Hole 1 cut 20 µm further out (−X).
    holes[1][0] -= 0.020;
    let segments = trace(centre, holes, false);
    // The prongs come down 50 µm towards +X of the spiral's centre.
    let at_mm = [100.05, 50.0];
    let traced = TracedGauge::recover(&segments, &PAPER, at_mm).unwrap();
    let (_, cut) = traced
        .gauge_cut(&PAPER, at_mm, &exact_cutter(), &mut Rng::new(1))
        .unwrap();
    let close = |x: f64, y: f64| (x - y).abs() < 1e-3;
    assert!(close(cut.hub_offset_um[0], 50.0), "{cut:?}");
    assert!(close(cut.hub_offset_um[1], 0.0), "{cut:?}");
    assert!(close(cut.hole_offset_um[0][0], 0.0), "{cut:?}");
    assert!(close(cut.hole_offset_um[0][1], -30.0), "{cut:?}");
    assert!(close(cut.hole_offset_um[1][0], 20.0), "{cut:?}");
    assert!(close(cut.hole_offset_um[1][1], 0.0), "{cut:?}");
}

#[test]
fn laser_off_moves_and_far_away_cuts_are_not_the_gauge() {
    let centre = [100.0, 50.0];
    let mut segments = trace(centre, drawn_holes(centre), false);
    for s in &mut segments[..400] {
        s.power_s = 0.0;
    }
    let err = TracedGauge::recover(&segments, &PAPER, centre).unwrap_err();
    assert!(
        err.to_string().contains("% of a turn"),
        "a half-cut spiral: {err}"
    );
    let whole = trace(centre, drawn_holes(centre), false);
    let err = TracedGauge::recover(&whole, &PAPER, [130.0, 50.0]).unwrap_err();
    assert!(matches!(err, GaugeTraceError::NoSpiral { .. }), "{err}");
    // A whole circle of a kilometre's radius through the gauge's area is not sampled.
    let mut huge = whole.clone();
    let kind = SegmentKind::Arc {
        center: [100.0, 50.0 + 1e6],
        clockwise: false,
    };
    huge.push(cut_move(kind, [100.0, 50.0], [100.0, 50.0]));
    assert!(TracedGauge::recover(&huge, &PAPER, centre).is_ok());
    let mut nan = whole;
    nan[3].end = [f64::NAN; 3];
    nan[4].start = [f64::NAN; 3];
    assert!(TracedGauge::recover(&nan, &PAPER, centre).is_ok());
}
