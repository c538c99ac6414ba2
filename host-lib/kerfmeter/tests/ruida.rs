//! The Ruida driver against the simulated controller over loopback UDP, and the whole loop on
//! the twins: the Ruida twin cuts the product's gauge G-code (read into programs, arcs
//! flattened), the device twin measures the gauge it traced, and the job is cut. Then every way
//! it must fail: a lost program packet, a late acknowledgement, a busy controller, a job
//! refused, a controller that never answers or answers what the protocol does not allow, a
//! program beyond the bed, Ctrl-C mid-stream, and a stop the controller does not confirm (the
//! laser may be on: exit 5).

mod common;

use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use common::fast_options;
use kerfmeter::JointSpec;
use kerfmeter::grbl::CutterError;
use kerfmeter::job::{Devices, JobError, JobRequest, Placement, SimLink, Stage, run_job};
use kerfmeter::protocol::GaugeGeometry;
use kerfmeter::ruida::{ProngAxis, RuidaAddress, RuidaCutter, RuidaFailure, Timing};
use kerfmeter::sim::{SimDevice, SimOptions};
use kerfmeter_plan::gauge::{GaugeOptions, build};
use kerfmeter_plan::gcode::{GcodeOptions, Provenance, gauge_program};
use kerfmeter_plan::profile::CutSettings;
use kerfmeter_ruida::twin::{Faults, RuidaTwin, TwinConfig, TwinLog};

const GAUGE_AT_MM: [f64; 2] = [250.0, 60.0];
const JOB_X0_MM: f64 = 400.0;

fn gauge_gcode(at_mm: [f64; 2]) -> String {
    let drawing = build(&GaugeGeometry::PAPER, &GaugeOptions::default()).unwrap();
    let settings = CutSettings {
        feed_mm_per_min: 300.0,
        power_percent: 100.0,
        passes: 1,
    };
    let options = GcodeOptions {
        origin_mm: at_mm,
        ..GcodeOptions::default()
    };
    let (program, _) =
        gauge_program(&drawing, &settings, &options, &Provenance::default()).unwrap();
    program.to_text()
}

/// `n` squares of 20 mm grown by the kerf, at 600 mm/min and 80 %.
fn job_gcode(kerf_um: f64, n: usize) -> String {
    let half = kerf_um / 2000.0;
    let mut g = String::from("(S_MAX=1000)\nG21 G90\nM5\n");
    for i in 0..n {
        let x0 = JOB_X0_MM + 25.0 * i as f64 - half;
        let y0 = 10.0 - half;
        let (x1, y1) = (x0 + 20.0 + 2.0 * half, y0 + 20.0 + 2.0 * half);
        g += &format!("M5\nG0 X{x0:.4} Y{y0:.4}\nM4\nG1 X{x1:.4} S800 F600\nG1 Y{y1:.4}\n");
        g += &format!("G1 X{x0:.4}\nG1 Y{y0:.4}\n");
    }
    g + "M5\nM2\n"
}

fn cutter() -> RuidaCutter {
    RuidaCutter::sim(TwinConfig::default(), Timing::sim()).unwrap()
}

fn log(cutter: &RuidaCutter) -> TwinLog {
    cutter.twin().unwrap().log()
}

fn stream(cutter: &mut RuidaCutter, program: &str) -> Result<(), CutterError> {
    let cancel = AtomicBool::new(false);
    cutter.stream(program, &cancel, &mut |_| {}).map(|_| ())
}

fn inject(cutter: &RuidaCutter, faults: Faults) {
    cutter.twin().unwrap().inject(faults);
}

/// Every cut of the log lies within `radius_mm` of `at_mm`, and some cut does.
fn cuts_near(log: &TwinLog, at_mm: [f64; 2], radius_mm: f64) -> bool {
    let cuts: Vec<_> = log.strokes.iter().filter(|s| s.laser_on).collect();
    let near = |p: [i32; 2]| {
        (f64::from(p[0]) / 1000.0 - at_mm[0]).hypot(f64::from(p[1]) / 1000.0 - at_mm[1])
            <= radius_mm
    };
    !cuts.is_empty() && cuts.iter().all(|s| near(s.from_um) && near(s.to_um))
}

#[test]
fn the_gauge_is_cut_where_asked_with_the_laser_off_on_every_travel() {
    let mut cutter = cutter();
    stream(&mut cutter, &gauge_gcode(GAUGE_AT_MM)).unwrap();
    let log = log(&cutter);
    assert_eq!(log.programs_run, 1);
    assert!(log.refused.is_empty() && log.naks == 0, "{log:?}");
    assert!(cuts_near(&log, GAUGE_AT_MM, 12.0));
    // Each cut starts where the head stood: the laser goes on only along a path, never on a
    // travel (a travel is a move, 88 or D9, recorded laser off).
    for pair in log.strokes.windows(2) {
        assert_eq!(pair[0].to_um, pair[1].from_um);
    }
    // The gauge's three contours: three travels into it, all at the gauge's speed and 100 %.
    let travels = log.strokes.iter().filter(|s| !s.laser_on).count();
    assert_eq!(travels, 3, "{travels}");
    assert!(
        log.strokes
            .iter()
            .filter(|s| s.laser_on)
            .all(|s| s.speed_um_per_s == 5000 && s.power_steps == [16383, 16383])
    );
}

#[test]
fn the_prongs_go_down_on_z_or_u_and_the_head_over_the_gauge() {
    let placement = Placement {
        gauge_at_mm: GAUGE_AT_MM,
        prong_offset_mm: [35.0, -12.5],
        insert_z_mm: -3.0,
        travel_z_mm: 8.0,
        plunge_feed_mm_per_min: 300.0,
    };
    let mut cutter = cutter();
    stream(&mut cutter, &placement.lower_program()).unwrap();
    let log = log(&cutter);
    assert_eq!(log.zu_um, [-3000, 0]);
    assert_eq!(log.strokes.last().unwrap().to_um, [215_000, 72_500]);
    assert!(log.strokes.iter().all(|s| !s.laser_on));
    let [x, y, z] = cutter.head_mm().unwrap();
    assert_eq!([x, y, z], [215.0, 72.5, -3.0]);
    // On U, the same moves go to the U axis.
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let address = RuidaAddress {
        host: "127.0.0.1".into(),
        port: twin.addr().port(),
        z_travel_mm: [-20.0, 20.0],
        bed_mm: None,
        fallback_bed_mm: None,
        prong_axis: ProngAxis::U,
        local_port: 0,
    };
    let mut on_u = RuidaCutter::open(&address, Timing::sim()).unwrap();
    stream(&mut on_u, &placement.lift_program()).unwrap();
    assert_eq!(twin.log().zu_um, [0, 8000]);
}

/// The device twin (its own cutter far off: the reading must be the Ruida twin's kerf), and a
/// Ruida twin made unkind by `faults` before the loop.
fn rig(faults: Faults) -> (SimDevice, kerfmeter::Kerfmeter, RuidaCutter) {
    let device = SimOptions {
        kerf_um: 120.0,
        ..SimOptions::default()
    };
    let (device, meter) = SimDevice::connect(device, fast_options(300)).unwrap();
    let config = TwinConfig {
        busy_reads: 3,
        ..TwinConfig::default()
    };
    let cutter = RuidaCutter::sim(config, Timing::sim()).unwrap();
    inject(&cutter, faults);
    (device, meter, cutter)
}

/// Run the loop on `rig` with the gauge at [`GAUGE_AT_MM`] and a job of three squares.
fn run_loop(
    (device, meter, cutter): &mut (SimDevice, kerfmeter::Kerfmeter, RuidaCutter),
) -> Result<kerfmeter::job::JobReport, JobError> {
    let kerf = kerfmeter_twin::plant::CutterKerf {
        kerf_um: 210.0,
        kerf_sd_um: 0.0,
        repeatability_um: 5.0,
    };
    let gauge = gauge_gcode(GAUGE_AT_MM);
    let request = JobRequest {
        gauge_gcode: &gauge,
        placement: Placement {
            gauge_at_mm: GAUGE_AT_MM,
            prong_offset_mm: [35.0, -12.5],
            insert_z_mm: -3.0,
            travel_z_mm: 8.0,
            plunge_feed_mm_per_min: 300.0,
        },
        params: JointSpec::default()
            .run_params(GaugeGeometry::PAPER)
            .unwrap(),
        plan_box_mm: None,
    };
    let devices = Devices {
        cutter,
        meter,
        sim: Some(SimLink {
            device,
            kerf: Some(kerf),
        }),
    };
    let cancel = AtomicBool::new(false);
    let mut dilate = |kerf_um: f64| Ok(job_gcode(kerf_um, 3));
    run_job(devices, &request, &mut dilate, &cancel, &mut |_| {})
}

#[test]
fn the_whole_loop_runs_on_the_twins_and_cuts_the_job_dilated_by_the_kerf_measured() {
    let mut rig = rig(Faults::default());
    let report = run_loop(&mut rig).unwrap();
    let stages: Vec<Stage> = report.stages.iter().map(|s| s.stage).collect();
    assert_eq!(stages, Stage::ALL);
    let truth = rig.0.truth_um(report.kerf.run_id).unwrap();
    eprintln!(
        "ruida loop: kerf {:.1} µm, truth {truth:.1} µm, stages {:?}",
        report.kerf.kerf_um, report.stages
    );
    assert!((f64::from(report.kerf.kerf_um) - truth).abs() < 3.0);
    assert!(truth > 205.0 && truth < 230.0, "{truth}");
    let log = log(&rig.2);
    assert_eq!(log.programs_run, 2, "the gauge and the job");
    // Back at the height the head stood at (0) before the job was cut.
    assert_eq!(log.zu_um[0], 0);
    let job_cuts = log
        .strokes
        .iter()
        .filter(|s| s.laser_on && s.from_um[0] >= 399_000)
        .count();
    assert_eq!(job_cuts, 12);
}

#[test]
fn a_job_refused_after_the_measurement_stops_the_loop_with_the_cutter_stopped() {
    let mut rig = rig(Faults {
        refuse_program: Some(1),
        ..Faults::default()
    });
    let e = run_loop(&mut rig).unwrap_err();
    let JobError::Cutter { stage, source } = &e else {
        panic!("{e}");
    };
    assert_eq!(*stage, Stage::StreamJob);
    assert!(matches!(source, CutterError::Stopped { .. }), "{e}");
    assert!(!e.laser_may_be_on(), "{e}");
    let log = log(&rig.2);
    assert_eq!((log.programs_run, log.refused.len(), log.stops), (1, 1, 1));
    assert!(
        !log.strokes
            .iter()
            .any(|s| s.laser_on && s.from_um[0] >= 399_000)
    );
}

#[test]
fn a_lost_program_packet_is_not_sent_again_the_cutter_is_stopped_and_nothing_cut() {
    let mut cutter = cutter();
    inject(
        &cutter,
        Faults {
            drop_program_packets: 1,
            ..Faults::default()
        },
    );
    let e = stream(&mut cutter, &gauge_gcode(GAUGE_AT_MM)).unwrap_err();
    assert!(matches!(e, CutterError::Stopped { .. }), "{e}");
    assert!(!e.laser_may_be_on());
    assert!(e.to_string().contains("did not answer"), "{e}");
    let log = log(&cutter);
    assert_eq!((log.programs_run, log.stops, log.dropped), (0, 1, 1));
    assert!(log.strokes.iter().all(|s| !s.laser_on));
}

#[test]
fn a_late_acknowledgement_stops_and_when_the_stop_cannot_be_confirmed_says_the_laser_may_be_on() {
    let mut cutter = cutter();
    inject(
        &cutter,
        Faults {
            late_from_program: Some(Duration::from_millis(700)),
            ..Faults::default()
        },
    );
    let e = stream(&mut cutter, &gauge_gcode(GAUGE_AT_MM)).unwrap_err();
    assert!(e.laser_may_be_on(), "{e}");
    assert!(
        e.to_string().starts_with("THE LASER MAY STILL BE ON"),
        "{e}"
    );
    assert_eq!(log(&cutter).programs_run, 0);
}

#[test]
fn a_busy_controller_is_refused_with_nothing_sent_and_not_stopped() {
    // Busy at connect: another job runs.
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    twin.inject(Faults {
        busy_reads: 1000,
        ..Faults::default()
    });
    let Err(e) = RuidaCutter::on_twin(twin, Timing::sim()) else {
        panic!("connected to a busy controller");
    };
    assert!(
        matches!(&e, CutterError::Ruida(f) if matches!(**f, RuidaFailure::Busy { .. })),
        "{e}"
    );
    assert!(e.to_string().contains("Nothing was sent"), "{e}");
    // Busy when the program is to go: refused, nothing sent, no stop of another's job.
    let mut cutter = cutter();
    inject(
        &cutter,
        Faults {
            busy_reads: 1000,
            ..Faults::default()
        },
    );
    let e = stream(&mut cutter, &gauge_gcode(GAUGE_AT_MM)).unwrap_err();
    assert!(!e.stop_was_tried(), "{e}");
    let log = log(&cutter);
    assert_eq!((log.programs_run, log.stops), (0, 0));
}

#[test]
fn a_job_refused_stops_the_cutter_and_nothing_is_cut() {
    let mut cutter = cutter();
    inject(
        &cutter,
        Faults {
            refuse_program: Some(0),
            ..Faults::default()
        },
    );
    let e = stream(&mut cutter, &gauge_gcode(GAUGE_AT_MM)).unwrap_err();
    assert!(matches!(e, CutterError::Stopped { .. }), "{e}");
    assert!(
        e.to_string()
            .contains("answered ERR while sending a cut program: it refused the job"),
        "{e}"
    );
    let log = log(&cutter);
    assert_eq!((log.programs_run, log.refused.len()), (0, 1));
    assert!(log.strokes.is_empty());
}

#[test]
fn a_program_acked_and_not_run_is_a_clear_error_and_the_cutter_is_stopped() {
    let mut cutter = cutter();
    inject(
        &cutter,
        Faults {
            skip_next_program: true,
            ..Faults::default()
        },
    );
    let e = stream(&mut cutter, &gauge_gcode(GAUGE_AT_MM)).unwrap_err();
    assert!(matches!(e, CutterError::Stopped { .. }), "{e}");
    assert!(e.to_string().contains("did not run it"), "{e}");
    let log = log(&cutter);
    assert_eq!((log.programs_run, log.stops), (0, 1));
}

#[test]
fn a_program_beyond_the_bed_is_refused_before_anything_is_sent() {
    let mut cutter = cutter();
    let e = stream(&mut cutter, &gauge_gcode([595.0, 60.0])).unwrap_err();
    assert!(matches!(e, CutterError::BeyondTravel { .. }), "{e}");
    let said = e.to_string();
    assert!(said.contains("Nothing was sent"), "{said}");
    // In a Ruida's words: its bed, not GRBL's settings.
    assert!(
        said.contains("set the controller's bed size") && !said.contains('$'),
        "{said}"
    );
    let e = stream(&mut cutter, "G21 G90\nM5 S0\nG0 Z80\n").unwrap_err();
    assert!(matches!(e, CutterError::BeyondTravel { .. }), "{e}");
    assert!(e.to_string().contains("z-mm=MIN,MAX"), "{e}");
    let log = log(&cutter);
    assert!(log.strokes.is_empty() && log.zu_um == [0, 0] && log.stops == 0);
    // A program in a dialect the driver does not read: refused, nothing sent.
    let e = stream(&mut cutter, "G91\nG0 X10\n").unwrap_err();
    assert!(matches!(e, CutterError::BadProgram { .. }), "{e}");
}

#[test]
fn ctrl_c_mid_stream_stops_the_cutter_and_an_unconfirmed_stop_is_exit_5() {
    for ignore_stops in [false, true] {
        let config = TwinConfig {
            busy_reads: 10_000,
            ..TwinConfig::default()
        };
        let mut cutter = RuidaCutter::sim(config, Timing::sim()).unwrap();
        inject(
            &cutter,
            Faults {
                ignore_stops,
                ..Faults::default()
            },
        );
        let cancel = AtomicBool::new(false);
        let e = std::thread::scope(|s| {
            s.spawn(|| {
                std::thread::sleep(Duration::from_millis(100));
                cancel.store(true, Ordering::Relaxed);
            });
            cutter.stream(&gauge_gcode(GAUGE_AT_MM), &cancel, &mut |_| {})
        })
        .unwrap_err();
        assert!(matches!(e.cause(), CutterError::Cancelled { .. }), "{e}");
        assert_eq!(e.laser_may_be_on(), ignore_stops, "{e}");
        assert_eq!(log(&cutter).stops, 1);
    }
}

/// A socket that answers every datagram with `answer` (`None`: never answers).
fn fake_controller(answer: Option<Vec<u8>>) -> (UdpSocket, std::thread::JoinHandle<()>) {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let server = socket.try_clone().unwrap();
    server
        .set_read_timeout(Some(Duration::from_millis(1500)))
        .unwrap();
    let thread = std::thread::spawn(move || {
        let mut buf = [0u8; 2048];
        while let Ok((_, from)) = server.recv_from(&mut buf) {
            if let Some(a) = &answer {
                let _ = server.send_to(a, from);
            }
        }
    });
    (socket, thread)
}

fn open(port: u16) -> Result<RuidaCutter, CutterError> {
    let address = RuidaAddress {
        host: "127.0.0.1".into(),
        port,
        z_travel_mm: [-20.0, 20.0],
        bed_mm: None,
        fallback_bed_mm: None,
        prong_axis: ProngAxis::Z,
        local_port: 0,
    };
    RuidaCutter::open(&address, Timing::sim())
}

#[test]
fn a_controller_that_never_answers_or_breaks_the_protocol_gets_a_clear_error() {
    let (silent, _t) = fake_controller(None);
    let Err(e) = open(silent.local_addr().unwrap().port()) else {
        panic!("connected to nothing");
    };
    assert!(
        e.to_string().contains("did not answer while connecting"),
        "{e}"
    );
    // Three bytes where a one-byte reply is due.
    let (garbage, _t) = fake_controller(Some(vec![1, 2, 3]));
    let Err(e) = open(garbage.local_addr().unwrap().port()) else {
        panic!("connected to a broken controller");
    };
    assert!(e.to_string().contains("protocol does not allow"), "{e}");
}

#[test]
fn a_gauge_beyond_the_controller_bed_stops_the_loop_before_anything_moves() {
    let (device, mut meter) = SimDevice::connect(SimOptions::default(), fast_options(300)).unwrap();
    let mut cutter = cutter();
    let gauge = gauge_gcode([590.0, 60.0]);
    let request = JobRequest {
        gauge_gcode: &gauge,
        placement: Placement {
            gauge_at_mm: [590.0, 60.0],
            prong_offset_mm: [0.0, 0.0],
            insert_z_mm: -3.0,
            travel_z_mm: 8.0,
            plunge_feed_mm_per_min: 300.0,
        },
        params: JointSpec::default()
            .run_params(GaugeGeometry::PAPER)
            .unwrap(),
        plan_box_mm: None,
    };
    let devices = Devices {
        cutter: &mut cutter,
        meter: &mut meter,
        sim: Some(SimLink {
            device: &device,
            kerf: None,
        }),
    };
    let cancel = AtomicBool::new(false);
    let e = run_job(
        devices,
        &request,
        &mut |_| Ok(String::new()),
        &cancel,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(matches!(e, JobError::Travel(_)), "{e}");
    assert!(log(&cutter).strokes.is_empty());
}

/// An address of the twin `twin` with the bed `bed_mm` (and `fallback_bed_mm`) given.
fn twin_address(
    twin: &RuidaTwin,
    bed_mm: Option<[f64; 2]>,
    fallback_bed_mm: Option<[f64; 2]>,
) -> RuidaAddress {
    RuidaAddress {
        host: "127.0.0.1".into(),
        port: twin.addr().port(),
        z_travel_mm: [-20.0, 20.0],
        bed_mm,
        fallback_bed_mm,
        prong_axis: ProngAxis::Z,
        local_port: 0,
    }
}

#[test]
fn the_bed_is_read_from_the_controller_and_otherwise_required() {
    let failure = |e: CutterError| match e {
        CutterError::Ruida(f) => *f,
        e => panic!("{e}"),
    };
    // Registers that read nothing: the address's bed, else the job's, else refused.
    let blank = RuidaTwin::start(TwinConfig {
        bed_um: [0, 0],
        ..TwinConfig::default()
    })
    .unwrap();
    let Err(e) = RuidaCutter::open(&twin_address(&blank, None, None), Timing::sim()) else {
        panic!("no bed, yet connected");
    };
    assert!(e.to_string().contains("--bed-mm W,H"), "{e}");
    assert!(matches!(failure(e), RuidaFailure::NoBed { .. }));
    let given = twin_address(&blank, Some([900.0, 600.0]), None);
    let travel = RuidaCutter::open(&given, Timing::sim()).unwrap().travel();
    assert_eq!(travel.bed_mm(), [900.0, 600.0]);
    let job = twin_address(&blank, None, Some([700.0, 500.0]));
    let travel = RuidaCutter::open(&job, Timing::sim()).unwrap().travel();
    assert_eq!(travel.bed_mm(), [700.0, 500.0]);
    // Registers that read: they win; an address that disagrees is refused, the job's is not used.
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let Err(e) = RuidaCutter::open(
        &twin_address(&twin, Some([900.0, 600.0]), None),
        Timing::sim(),
    ) else {
        panic!("a bed that disagrees, yet connected");
    };
    assert!(matches!(failure(e), RuidaFailure::BedMismatch { .. }));
    let job = twin_address(&twin, None, Some([300.0, 200.0]));
    let travel = RuidaCutter::open(&job, Timing::sim()).unwrap().travel();
    assert_eq!(travel.bed_mm(), [600.0, 400.0]);
}
