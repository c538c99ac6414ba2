//! The client against the firmware's own link, through a real pseudo-terminal: handshake, lost
//! responses, garbage on the line, a vanished port and a restarted device.

mod common;

use std::io::{self, Read, Write};
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::Duration;

use common::{LineFaults, Server, fast_options};
use kerfmeter::protocol::{ErrorCode, Request, Response, RunParams};
use kerfmeter::{Error, Kerfmeter, Options};
use kerfmeter_firmware::device::Device;
use kerfmeter_firmware::link::Handler;
use serialport::{SerialPort, TTYPort};

/// The device, counting `Run`s, with a boot id that can be changed to simulate a restart.
struct TestDevice {
    boot_id: Arc<AtomicU32>,
    runs: Arc<AtomicU32>,
}

impl Handler for TestDevice {
    fn host_activity(&mut self) {}

    fn handle(&mut self, request: &Request) -> Response {
        match request {
            Request::Run(_) => {
                self.runs.fetch_add(1, Ordering::SeqCst);
                Response::Ok
            }
            other => Device::new("test", self.boot_id.load(Ordering::SeqCst)).handle(other),
        }
    }
}

/// The master end of the terminal, with the line's faults on every write.
struct FaultyPort {
    inner: TTYPort,
    line: Arc<LineFaults>,
}

impl Read for FaultyPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.inner.read(buf)
    }
}

impl Write for FaultyPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.inner.write_all(&self.line.deliver(buf))?;
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// A test device served on a pseudo-terminal, with its counters and the line's faults.
struct Bench {
    boot_id: Arc<AtomicU32>,
    runs: Arc<AtomicU32>,
    line: Arc<LineFaults>,
    _server: Server<()>,
}

fn bench() -> (Bench, Box<dyn SerialPort>) {
    let (mut master, slave) = TTYPort::pair().unwrap();
    master.set_timeout(Duration::from_millis(10)).unwrap();
    let boot_id = Arc::new(AtomicU32::new(0xB007_0001));
    let runs = Arc::new(AtomicU32::new(0));
    let line = Arc::new(LineFaults::default());
    let mut port = FaultyPort {
        inner: master,
        line: line.clone(),
    };
    let device = TestDevice {
        boot_id: boot_id.clone(),
        runs: runs.clone(),
    };
    let server = Server::spawn(move |stop| {
        let mut server = kerfmeter_twin::LinkServer::new(device);
        kerfmeter_twin::serve(
            &mut port,
            &mut server,
            &stop,
            kerfmeter_twin::Pace::LockStep,
        )
        .unwrap();
    });
    let bench = Bench {
        boot_id,
        runs,
        line,
        _server: server,
    };
    (bench, Box::new(slave))
}

fn fast() -> Options {
    fast_options(100)
}

#[test]
fn handshake_reads_the_device_info() {
    let (_bench, port) = bench();
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    let info = meter.info().unwrap();
    assert_eq!(info.boot_id, 0xB007_0001);
    assert_eq!(info.hardware.board.as_str(), "test");
}

#[test]
fn a_lost_response_is_retried_and_the_run_is_not_executed_twice() {
    let (bench, port) = bench();
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    bench.line.drop_responses.store(2, Ordering::SeqCst);
    let response = meter.call(Request::Run(RunParams::DEFAULT)).unwrap();
    assert_eq!(response, Response::Ok);
    assert_eq!(
        bench.runs.load(Ordering::SeqCst),
        1,
        "the retried Run must not run again"
    );
    // And a new request is executed.
    meter.call(Request::Run(RunParams::DEFAULT)).unwrap();
    assert_eq!(bench.runs.load(Ordering::SeqCst), 2);
}

#[test]
fn too_many_lost_responses_time_out_with_a_clear_error() {
    let (bench, port) = bench();
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    bench.line.drop_responses.store(100, Ordering::SeqCst);
    let err = meter.call(Request::GetStatus).unwrap_err();
    assert!(matches!(err, Error::Timeout { attempts: 4, .. }), "{err:?}");
    assert!(err.to_string().contains("no answer"), "{err}");
}

#[test]
fn garbage_on_the_line_is_skipped() {
    let (bench, port) = bench();
    bench.line.garbage.store(true, Ordering::SeqCst);
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    let boot_id = bench.boot_id.load(Ordering::SeqCst);
    for i in 0..20 {
        // Each answer is the device's own, read past the noise in front of it.
        let info = meter.info().unwrap_or_else(|e| panic!("call {i}: {e}"));
        assert_eq!(info.boot_id, boot_id, "call {i}");
    }
    let noisy = bench.line.noisy_responses.load(Ordering::SeqCst);
    assert!(
        noisy >= 21,
        "the noise reached the host before {noisy} responses only"
    );
    // And the link still carries a call that answers something else.
    assert!(matches!(
        meter.call(Request::GetKerf).unwrap(),
        Response::Kerf(None)
    ));
}

#[test]
fn device_refusals_are_typed() {
    let (_bench, port) = bench();
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    // No run yet: there are no samples to read.
    let err = meter.call(Request::GetSamples { from: 0 }).unwrap_err();
    assert!(
        matches!(
            err,
            Error::Device {
                code: ErrorCode::NoSamples,
                ..
            }
        ),
        "{err:?}"
    );
    assert!(!err.is_communication());
}

#[test]
fn a_restarted_device_is_detected() {
    let (bench, port) = bench();
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    bench.boot_id.store(0xB007_0002, Ordering::SeqCst);
    let err = meter.info().unwrap_err();
    assert!(
        matches!(
            err,
            Error::DeviceReset {
                old: 0xB007_0001,
                new: 0xB007_0002
            }
        ),
        "{err:?}"
    );
    // Reported once; the client then carries on with the new boot.
    meter.info().unwrap();
}

#[test]
fn a_vanished_port_is_a_clear_error() {
    let (bench, port) = bench();
    let mut meter = Kerfmeter::from_port(port, fast()).unwrap();
    drop(bench); // closes the master end: the device is gone
    let err = meter.info().unwrap_err();
    assert!(err.is_communication());
    assert!(
        matches!(err, Error::PortVanished { .. } | Error::Timeout { .. }),
        "{err:?}"
    );
}

#[test]
fn the_sim_device_answers_through_a_pty() {
    let (sim, mut meter) = kerfmeter::sim::SimDevice::connect(
        kerfmeter::sim::SimOptions {
            seed: 7,
            ..Default::default()
        },
        fast(),
    )
    .unwrap();
    assert!(sim.path().starts_with("/dev/"), "{}", sim.path());
    let info = meter.info().unwrap();
    assert_eq!(info.hardware.board.as_str(), "twin");
    // The seed makes the boot id reproducible.
    let (_sim2, mut meter2) = kerfmeter::sim::SimDevice::connect(
        kerfmeter::sim::SimOptions {
            seed: 7,
            ..Default::default()
        },
        fast(),
    )
    .unwrap();
    assert_eq!(meter2.info().unwrap().boot_id, info.boot_id);
}
