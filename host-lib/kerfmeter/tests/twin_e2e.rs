//! The host library against the physics twin through a real pseudo-terminal: every call, and
//! what a serial line does to them — garbage, lost responses, a device that restarts, a host or a
//! port that vanishes mid-run.

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use common::{LineFaults, Server, fast_options};
use kerfmeter::protocol::{DeviceConfig, Fault, GaugeGeometry, RunParams, RunState, TestOutcome};
use kerfmeter::sim::{SimDevice, SimOptions};
use kerfmeter::{Error, JointSpec, Kerfmeter, Options};
use kerfmeter_twin::{Pace, Served, TruthLog, Twin, TwinOptions};
use serialport::{SerialPort, TTYPort};

fn options() -> Options {
    fast_options(150)
}

fn params() -> RunParams {
    JointSpec::default()
        .run_params(GaugeGeometry::PAPER)
        .unwrap()
}

/// Switches a test flips while the twin is served.
#[derive(Default)]
struct Controls {
    line: LineFaults,
    reboot: AtomicBool,
}

/// The twin with the test's faults on the wire (responses dropped or preceded by garbage) and a
/// reboot between reads.
struct FaultyWire<'a> {
    twin: Twin,
    controls: &'a Controls,
}

impl Served for FaultyWire<'_> {
    fn receive(&mut self, bytes: &[u8], transmit: &mut dyn FnMut(&[u8])) {
        let mut out = Vec::new();
        self.twin.receive(bytes, |f| out.extend_from_slice(f));
        if !out.is_empty() {
            transmit(&self.controls.line.deliver(&out));
        }
    }

    fn now_us(&self) -> u64 {
        self.twin.now_us()
    }

    fn lead_ticks(&self) -> u64 {
        self.twin.lead_ticks()
    }

    fn advance_ticks(&mut self, ticks: u64) {
        if self.controls.reboot.swap(false, Ordering::SeqCst) {
            self.twin.reboot();
        }
        self.twin.advance_ticks(ticks);
    }
}

/// Serve `twin` on the master end in lock-step, with the test's faults on the wire, until the
/// client hangs up or `stop` is set; returns the twin.
fn serve(mut master: TTYPort, twin: Twin, controls: &Controls, stop: &AtomicBool) -> Twin {
    master.set_timeout(Duration::from_millis(1)).unwrap();
    let mut wire = FaultyWire { twin, controls };
    // An I/O error ends serving like a hang-up: the client sees the port vanish.
    let _ = kerfmeter_twin::serve(&mut master, &mut wire, stop, Pace::LockStep);
    wire.twin
}

/// The twin served on a pseudo-terminal, with the switches the tests flip.
struct Bench {
    controls: Arc<Controls>,
    server: Server<Twin>,
    truths: TruthLog,
}

impl Bench {
    fn start(twin: TwinOptions) -> (Self, Kerfmeter) {
        let (master, slave) = TTYPort::pair().unwrap();
        let controls = Arc::new(Controls::default());
        let served = controls.clone();
        let twin = Twin::new(twin);
        let truths = twin.truths().clone();
        let server = Server::spawn(move |stop| serve(master, twin, &served, &stop));
        let meter =
            Kerfmeter::from_port(Box::new(slave) as Box<dyn SerialPort>, options()).unwrap();
        (
            Self {
                controls,
                server,
                truths,
            },
            meter,
        )
    }

    /// The truth of run `run_id`, µm.
    fn truth_um(&self, run_id: u32) -> f64 {
        self.truths
            .truth_um(run_id)
            .expect("a run the twin started")
    }

    /// Stop serving and get the twin back.
    fn finish(self) -> Twin {
        self.server.finish()
    }
}

#[test]
fn every_call_works_through_a_pty() {
    let (sim, mut meter) = SimDevice::connect(
        SimOptions {
            kerf_um: 180.0,
            seed: 3,
            ..SimOptions::default()
        },
        options(),
    )
    .unwrap();
    let info = meter.info().unwrap();
    assert_eq!(info.hardware.board.as_str(), "twin");

    meter.reset_kerfmeter().unwrap();
    assert_eq!(meter.get_kerf_value().unwrap(), None);
    let mut states = Vec::new();
    let result = meter
        .run_kerfmeter(&params(), |p| states.push(p.state))
        .unwrap();
    let truth = sim.truth_um(result.run_id).unwrap();
    assert!(
        (f64::from(result.kerf_um) - truth).abs() < 2.0,
        "{result:?} against {truth}"
    );
    assert!(states.contains(&RunState::Ramping), "{states:?}");
    assert_eq!(meter.get_kerf_value().unwrap(), Some(result));

    let curve = meter.curve().unwrap();
    assert_eq!(curve.run_id, result.run_id);
    assert!(curve.samples.len() > 500, "{}", curve.samples.len());

    meter.reset_kerfmeter().unwrap();
    assert_eq!(meter.get_kerf_value().unwrap(), None);
    assert!(meter.status().unwrap().angle_deg.abs() < 0.5);

    let report = meter.self_test(|_| {}).unwrap();
    assert_eq!(
        report.direction_deg.outcome,
        TestOutcome::Pass,
        "{report:?}"
    );

    let config = meter.config().unwrap();
    assert!(config.defaults_in_use);
    let new = DeviceConfig {
        encoder_zero_raw: 42,
        ..config.config
    };
    let stored = meter.set_config(&new).unwrap();
    assert_eq!(stored.config, new);
    assert!(!stored.defaults_in_use);
    assert_eq!(meter.config().unwrap().config.encoder_zero_raw, 42);

    meter.abort().unwrap();
    meter.clear_fault().unwrap();
}

#[test]
fn a_fault_is_a_typed_error_latched_until_cleared_then_the_next_run_works() {
    let (sim, mut meter) = SimDevice::connect(
        SimOptions {
            fault: Some(kerfmeter::sim::SimFault::DriverFault),
            ..SimOptions::default()
        },
        options(),
    )
    .unwrap();
    meter.reset_kerfmeter().unwrap();
    let err = meter.run_kerfmeter(&params(), |_| {}).unwrap_err();
    assert_eq!(err.fault(), Some(Fault::DriverFault), "{err}");
    assert!(err.to_string().contains("driver reported a fault"), "{err}");
    // Refused while latched, with the fault named.
    let err = meter.run_kerfmeter(&params(), |_| {}).unwrap_err();
    assert_eq!(err.fault(), Some(Fault::DriverFault));
    assert!(matches!(err, Error::Device { .. }), "{err:?}");
    // Cleared (the twin takes it that the cause was fixed): the next run measures.
    meter.clear_fault().unwrap();
    meter.reset_kerfmeter().unwrap();
    let result = meter.run_kerfmeter(&params(), |_| {}).unwrap();
    let truth = sim.truth_um(result.run_id).unwrap();
    assert!(
        (f64::from(result.kerf_um) - truth).abs() < 2.0,
        "{result:?} against {truth}"
    );
}

#[test]
fn a_run_stopped_by_its_caller_is_aborted_and_the_motor_left_safe() {
    let (_sim, mut meter) = SimDevice::connect(SimOptions::default(), options()).unwrap();
    meter.reset_kerfmeter().unwrap();
    let stop_when_ramping = |p: &kerfmeter::Progress| {
        if p.state == RunState::Ramping {
            std::ops::ControlFlow::Break(())
        } else {
            std::ops::ControlFlow::Continue(())
        }
    };
    let err = meter
        .run_kerfmeter_until(&params(), stop_when_ramping)
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled), "{err:?}");
    assert_eq!(meter.status().unwrap().state, RunState::Idle);
    assert_eq!(meter.get_kerf_value().unwrap(), None);
}

/// A `progress` that stops the call once the device is in `state`.
fn stop_in(state: RunState) -> impl FnMut(&kerfmeter::Progress) -> std::ops::ControlFlow<()> {
    move |p| {
        if p.state == state {
            std::ops::ControlFlow::Break(())
        } else {
            std::ops::ControlFlow::Continue(())
        }
    }
}

#[test]
fn a_reset_or_self_test_stopped_by_its_caller_is_aborted() {
    let (_sim, mut meter) = SimDevice::connect(SimOptions::default(), options()).unwrap();
    meter.reset_kerfmeter().unwrap();
    meter.run_kerfmeter(&params(), |_| {}).unwrap();
    // The hub is far from zero after a run: the reset takes many polls.
    let err = meter
        .reset_kerfmeter_until(stop_in(RunState::Resetting))
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled), "{err:?}");
    assert_eq!(meter.status().unwrap().state, RunState::Idle);
    let err = meter
        .prepare_for_run_until(stop_in(RunState::Resetting))
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled), "{err:?}");
    meter.reset_kerfmeter().unwrap();
    let err = meter
        .self_test_until(stop_in(RunState::SelfTest))
        .unwrap_err();
    assert!(matches!(err, Error::Cancelled), "{err:?}");
    assert_eq!(meter.status().unwrap().state, RunState::Idle);
}

#[test]
fn garbage_on_the_line_is_skipped() {
    let (bench, mut meter) = Bench::start(TwinOptions::default());
    bench.controls.line.garbage.store(true, Ordering::SeqCst);
    meter.reset_kerfmeter().unwrap();
    let result = meter.run_kerfmeter(&params(), |_| {}).unwrap();
    let truth = bench.truth_um(result.run_id);
    assert!(
        (f64::from(result.kerf_um) - truth).abs() < 2.0,
        "{result:?} against {truth}"
    );
}

#[test]
fn a_retried_run_is_not_executed_twice() {
    let (bench, mut meter) = Bench::start(TwinOptions::default());
    meter.reset_kerfmeter().unwrap();
    // The device's answer to Run is lost twice; the client re-sends the same seq.
    bench
        .controls
        .line
        .drop_responses
        .store(2, Ordering::SeqCst);
    let result = meter.run_kerfmeter(&params(), |_| {}).unwrap();
    assert_eq!(result.run_id, 1, "one run, not three");
    assert_eq!(meter.status().unwrap().run_id, 1);
}

#[test]
fn a_rebooted_device_is_detected() {
    let (bench, mut meter) = Bench::start(TwinOptions::default());
    meter.info().unwrap();
    bench.controls.reboot.store(true, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(20));
    let err = meter.info().unwrap_err();
    assert!(matches!(err, Error::DeviceReset { .. }), "{err:?}");
    assert!(err.is_communication());
}

/// Start a long run and, at the `at_poll`-th status poll, `disturb` the bench; the run's error.
fn run_disturbed(at_poll: u32, disturb: impl Fn(&Bench)) -> Error {
    let (bench, mut meter) = Bench::start(TwinOptions {
        kerf_um: 400.0,
        ..TwinOptions::default()
    });
    meter.reset_kerfmeter().unwrap();
    let mut polls = 0;
    meter
        .run_kerfmeter(&params(), |_| {
            polls += 1;
            if polls == at_poll {
                disturb(&bench);
            }
        })
        .unwrap_err()
}

#[test]
fn a_reboot_mid_run_ends_the_run_with_a_clear_error() {
    let err = run_disturbed(5, |b| b.controls.reboot.store(true, Ordering::SeqCst));
    assert!(matches!(err, Error::DeviceReset { .. }), "{err:?}");
}

#[test]
fn a_host_that_vanishes_mid_run_leaves_the_motor_safe_by_the_watchdog() {
    let (bench, mut meter) = Bench::start(TwinOptions {
        kerf_um: 400.0,
        ..TwinOptions::default()
    });
    meter.reset_kerfmeter().unwrap();
    // Start a run and poll a little, then the host process "dies": its port closes.
    meter
        .call(kerfmeter::protocol::Request::Run(params()))
        .unwrap();
    for _ in 0..3 {
        meter.status().unwrap();
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(matches!(
        meter.status().unwrap().state,
        RunState::Engaging | RunState::Ramping
    ));
    drop(meter);
    let mut twin = bench.finish();
    assert!(
        !twin.motor_safe() || twin.device().controller().is_active(),
        "still running when the host left"
    );
    // Nobody talks to the device any more: within the watchdog period it stops on its own.
    twin.advance_ticks(u64::from(params().host_timeout_ms) + 20);
    assert_eq!(
        twin.device().controller().run_state(),
        RunState::Fault(Fault::HostSilent)
    );
    assert!(twin.motor_safe());
}

#[test]
fn a_port_that_vanishes_mid_run_is_a_clear_error() {
    // The device side goes away (unplugged).
    let err = run_disturbed(3, |b| b.server.stop.store(true, Ordering::SeqCst));
    assert!(err.is_communication(), "{err:?}");
    assert!(
        matches!(err, Error::PortVanished { .. } | Error::Timeout { .. }),
        "{err:?}"
    );
}
