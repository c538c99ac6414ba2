//! The automatic loop on the twins: the cutter twin cuts the product's gauge G-code, the device
//! twin measures the gauge it traced where the prongs came down, and the job is streamed. Also
//! every way it must stop with the laser off: a failed measurement, a cutter alarm mid-job, a
//! cancel mid-job.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use common::fast_options;
use kerfmeter::JointSpec;
use kerfmeter::grbl::twin::CutterRecord;
use kerfmeter::grbl::{ConnectOptions, Cutter, SimCutterOptions};
use kerfmeter::job::{
    Devices, JobError, JobEvent, JobReport, JobRequest, Placement, SimLink, Stage, run_job,
};
use kerfmeter::protocol::{GaugeGeometry, RunParams};
use kerfmeter::sim::{SimDevice, SimFault, SimOptions};
use kerfmeter_plan::gauge::{GaugeOptions, build};
use kerfmeter_plan::gcode::{GcodeOptions, Provenance, gauge_program};
use kerfmeter_plan::profile::CutSettings;

const GAUGE_AT_MM: [f64; 2] = [250.0, 60.0];
/// The job's squares are cut from here on in x: the gauge and the prong moves stay left of it.
const JOB_X0_MM: f64 = 400.0;

fn placement() -> Placement {
    Placement {
        gauge_at_mm: GAUGE_AT_MM,
        prong_offset_mm: [35.0, -12.5],
        insert_z_mm: -3.0,
        travel_z_mm: 8.0,
        plunge_feed_mm_per_min: 300.0,
    }
}

fn gauge_gcode() -> String {
    let drawing = build(&GaugeGeometry::PAPER, &GaugeOptions::default()).unwrap();
    let settings = CutSettings {
        feed_mm_per_min: 300.0,
        power_percent: 100.0,
        passes: 1,
    };
    let options = GcodeOptions {
        origin_mm: GAUGE_AT_MM,
        ..GcodeOptions::default()
    };
    let (program, _) =
        gauge_program(&drawing, &settings, &options, &Provenance::default()).unwrap();
    program.to_text()
}

/// The "dilated job": `n` squares of 20 mm grown by the kerf, at 600 mm/min, the beam off for
/// each travel as the plan crate's programs have it.
fn job_gcode(kerf_um: f64, n: usize) -> String {
    let half = kerf_um / 2000.0;
    let mut g = String::from("G21 G90\nM5\n");
    for i in 0..n {
        let x0 = JOB_X0_MM + 25.0 * (i % 8) as f64 - half;
        let y0 = 10.0 + 25.0 * (i / 8) as f64 - half;
        let (x1, y1) = (x0 + 20.0 + 2.0 * half, y0 + 20.0 + 2.0 * half);
        g += &format!("M5\nG0 X{x0:.4} Y{y0:.4}\nM4\nG1 X{x1:.4} S800 F600\nG1 Y{y1:.4}\n");
        g += &format!("G1 X{x0:.4}\nG1 Y{y0:.4}\n");
    }
    g + "M5\nM2\n"
}

fn params() -> RunParams {
    JointSpec::default()
        .run_params(GaugeGeometry::PAPER)
        .unwrap()
}

struct Rig {
    device: SimDevice,
    meter: kerfmeter::Kerfmeter,
    cutter: Cutter,
    twin: SimCutterOptions,
}

fn rig(device: SimOptions, twin: SimCutterOptions) -> Rig {
    let (device, meter) = SimDevice::connect(device, fast_options(300)).unwrap();
    let connect = ConnectOptions {
        banner_wait: Duration::from_millis(500),
        poll_interval: Duration::from_millis(20),
        ..ConnectOptions::default()
    };
    let cutter = Cutter::sim(twin, connect).unwrap();
    Rig {
        device,
        meter,
        cutter,
        twin,
    }
}

/// Run the loop on `rig` with `jobs` squares; `on_event` may set the cancel flag.
fn run(
    rig: &mut Rig,
    jobs: usize,
    on_event: &mut dyn FnMut(&JobEvent<'_>, &AtomicBool),
) -> (Result<JobReport, JobError>, Vec<Stage>) {
    let gauge = gauge_gcode();
    let request = JobRequest {
        gauge_gcode: &gauge,
        placement: placement(),
        params: params(),
        plan_box_mm: None,
    };
    let devices = Devices {
        cutter: &mut rig.cutter,
        meter: &mut rig.meter,
        sim: Some(SimLink {
            device: &rig.device,
            kerf: Some(rig.twin.kerf),
        }),
    };
    let cancel = AtomicBool::new(false);
    let mut started = Vec::new();
    let mut dilate = |kerf_um: f64| Ok(job_gcode(kerf_um, jobs));
    let result = run_job(devices, &request, &mut dilate, &cancel, &mut |e| {
        if let JobEvent::Started(s) = e {
            started.push(s);
        }
        on_event(&e, &cancel);
    });
    (result, started)
}

fn record(rig: &Rig) -> CutterRecord {
    rig.cutter.sim_log().unwrap().snapshot()
}

/// The laser never fired on a travel, nor was left switched on for one that laser mode kept
/// dark, and is off now; whether any of the job was cut.
fn laser_safe_and_job_cut(record: &CutterRecord) -> bool {
    assert!(
        record.travel_firings.is_empty(),
        "{:?}",
        record.travel_firings
    );
    assert!(
        record.blanked_travels.is_empty(),
        "{:?}",
        record.blanked_travels
    );
    assert_eq!(record.laser_power_s, 0.0);
    record
        .segments
        .iter()
        .any(|s| s.power_s > 0.0 && s.end[0] >= JOB_X0_MM - 1.0)
}

#[test]
fn the_loop_measures_the_gauge_the_cutter_cut_and_cuts_the_job_dilated_by_it() {
    let twin = SimCutterOptions {
        kerf: kerfmeter_twin::plant::CutterKerf {
            kerf_um: 210.0,
            kerf_sd_um: 0.0,
            repeatability_um: 5.0,
        },
        ..SimCutterOptions::default()
    };
    // The device twin's own cutter is far off: the reading must be the cutter twin's kerf.
    let device = SimOptions {
        kerf_um: 120.0,
        ..SimOptions::default()
    };
    let mut rig = rig(device, twin);
    // The head stands at its cutting height (its focus), not at the machine's zero.
    let cancel = AtomicBool::new(false);
    (rig.cutter.stream("G21 G90\nG0 Z2\n", &cancel, &mut |_| {})).unwrap();
    let (result, started) = run(&mut rig, 4, &mut |_, _| {});
    let report = result.unwrap();
    assert_eq!(started, Stage::ALL);
    let stages: Vec<Stage> = report.stages.iter().map(|s| s.stage).collect();
    assert_eq!(stages, Stage::ALL);
    let truth = rig.device.truth_um(report.kerf.run_id).unwrap();
    eprintln!(
        "kerf {:.1} µm, truth {truth:.1} µm, stages {:?}",
        report.kerf.kerf_um, report.stages
    );
    assert!((f64::from(report.kerf.kerf_um) - truth).abs() < 3.0);
    assert!(truth > 205.0 && truth < 230.0, "{truth}");
    // The prongs came down over the gauge's centre: the head at centre − offset.
    let [x, y] = report.landing_mm;
    assert!((x - GAUGE_AT_MM[0]).abs() < 1e-3 && (y - GAUGE_AT_MM[1]).abs() < 1e-3);
    assert_eq!(
        report.job_gcode,
        job_gcode(f64::from(report.kerf.kerf_um), 4)
    );
    let record = record(&rig);
    assert!(laser_safe_and_job_cut(&record));
    // The plunge went to the insert height at the head position over the gauge, laser off.
    let plunge = record
        .segments
        .iter()
        .find(|s| s.end[2] == -3.0)
        .expect("a plunge");
    assert_eq!(plunge.power_s, 0.0);
    assert!((plunge.end[0] - 215.0).abs() < 1e-6 && (plunge.end[1] - 72.5).abs() < 1e-6);
    // The gauge and the job were cut at the height the head stood at, the job after the head came
    // back down from the travel height (it was cut 6 mm higher, out of focus).
    let cuts: Vec<_> = record.segments.iter().filter(|s| s.power_s > 0.0).collect();
    assert!(cuts.iter().any(|s| s.end[0] < JOB_X0_MM - 1.0), "the gauge");
    assert!(cuts.iter().any(|s| s.end[0] >= JOB_X0_MM - 1.0), "the job");
    assert!(
        cuts.iter().all(|s| s.start[2] == 2.0 && s.end[2] == 2.0),
        "{:?}",
        cuts.iter().map(|s| s.end[2]).collect::<Vec<_>>()
    );
}

#[test]
fn a_failed_measurement_stops_before_the_job_with_the_prongs_lifted_and_the_laser_off() {
    let device = SimOptions {
        fault: Some(SimFault::ProngSlip),
        ..SimOptions::default()
    };
    let mut rig = rig(device, SimCutterOptions::default());
    let (result, started) = run(&mut rig, 4, &mut |_, _| {});
    let error = result.unwrap_err();
    assert!(
        matches!(
            error,
            JobError::Device {
                stage: Stage::Measure,
                ..
            }
        ),
        "{error}"
    );
    assert!(error.to_string().contains("laser is off"), "{error}");
    assert!(!started.contains(&Stage::Dilate), "{started:?}");
    let record = record(&rig);
    assert!(!laser_safe_and_job_cut(&record));
    // Lifted to the travel height, then stopped.
    assert_eq!(record.segments.last().unwrap().end[2], 8.0);
    assert!(record.resets >= 1);
}

#[test]
fn a_flagged_measurement_stops_before_the_job_with_the_prongs_lifted_and_the_laser_off() {
    // A magnet a little too far from the encoder: every reading works but is flagged.
    let mut device = SimOptions::default();
    device.plant.magnet_agc = 228.0;
    let mut rig = rig(device, SimCutterOptions::default());
    let (result, started) = run(&mut rig, 4, &mut |_, _| {});
    let error = result.unwrap_err();
    assert!(matches!(error, JobError::Flagged { .. }), "{error}");
    let message = error.to_string();
    assert!(message.contains("weak-magnet"), "{message}");
    assert!(message.contains("laser is off"), "{message}");
    assert!(!started.contains(&Stage::Dilate), "{started:?}");
    let record = record(&rig);
    assert!(!laser_safe_and_job_cut(&record));
    assert_eq!(record.segments.last().unwrap().end[2], 8.0);
}

#[test]
fn a_cutter_alarm_mid_job_stops_the_loop_with_the_laser_off() {
    // The gauge and the prong moves take well under 5 min of motion; the job 60 squares, 27 min.
    // Its 200 squares, in rows of 8, need 640 mm of Y travel.
    let twin = SimCutterOptions {
        hard_limit_after_ms: Some(300_000),
        travel_mm: [600.0, 700.0, 50.0],
        ..SimCutterOptions::default()
    };
    let mut rig = rig(SimOptions::default(), twin);
    let (result, _) = run(&mut rig, 200, &mut |_, _| {});
    let error = result.unwrap_err();
    assert!(
        matches!(
            error,
            JobError::Cutter {
                stage: Stage::StreamJob,
                ..
            }
        ),
        "{error}"
    );
    let record = record(&rig);
    assert_eq!(record.alarms, vec![1]);
    // Some of the job was cut before the alarm.
    assert!(laser_safe_and_job_cut(&record));
}

#[test]
fn cancel_mid_job_stops_the_cutter_with_the_laser_off() {
    let mut rig = rig(SimOptions::default(), SimCutterOptions::default());
    let (result, _) = run(&mut rig, 40, &mut |e, cancel| {
        // Past the check pass ($C), into the cutting.
        if let JobEvent::Cutter(Stage::StreamJob, p) = e
            && !p.checking
            && p.answered > 20
        {
            cancel.store(true, Ordering::Relaxed);
        }
    });
    let error = result.unwrap_err();
    assert!(
        matches!(
            error,
            JobError::Cancelled {
                stage: Stage::StreamJob
            }
        ),
        "{error}"
    );
    let record = record(&rig);
    assert!(laser_safe_and_job_cut(&record));
    // Stopped well before the job's last square.
    let last_x = record.segments.iter().map(|s| s.end[1]).fold(0.0, f64::max);
    assert!(last_x < 25.0 * 4.0, "{last_x}");
}

#[test]
fn cancel_during_the_measurement_aborts_the_run_and_cuts_nothing_more() {
    let mut rig = rig(SimOptions::default(), SimCutterOptions::default());
    let (result, started) = run(&mut rig, 4, &mut |e, cancel| {
        if let JobEvent::Device(p) = e
            && p.elapsed_ms > 200
        {
            cancel.store(true, Ordering::Relaxed);
        }
    });
    let error = result.unwrap_err();
    assert!(
        matches!(
            error,
            JobError::Cancelled {
                stage: Stage::Measure
            }
        ),
        "{error}"
    );
    assert!(!started.contains(&Stage::Lift));
    // Nothing moves after a cancel, not even the prongs: the error says they may be down.
    assert!(
        error.to_string().contains("prongs may still be down"),
        "{error}"
    );
    assert!(!laser_safe_and_job_cut(&record(&rig)));
    let status = rig.meter.status().unwrap();
    assert_ne!(status.state, kerfmeter::protocol::RunState::Ramping);
}

#[test]
fn a_gauge_beyond_the_machines_travel_is_refused_before_anything_moves() {
    // 200 mm of X travel; the gauge at X250.
    let twin = SimCutterOptions {
        travel_mm: [200.0, 200.0, 50.0],
        ..SimCutterOptions::default()
    };
    let mut rig = rig(SimOptions::default(), twin);
    let (result, started) = run(&mut rig, 1, &mut |_, _| {});
    let error = result.unwrap_err();
    assert!(matches!(error, JobError::Travel(_)), "{error}");
    assert_eq!(error.category(), kerfmeter::Category::Device);
    let message = error.to_string();
    for says in [
        "the gauge at (250.0, 60.0) mm",
        "$130=200",
        "--gauge-at-mm",
        "Nothing was sent",
    ] {
        assert!(message.contains(says), "{says}: {message}");
    }
    assert!(started.is_empty(), "{started:?}");
    assert!(record(&rig).gcode_received.is_empty());
}
