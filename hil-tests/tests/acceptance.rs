//! The acceptance cases (issue: hil-tests). Each runs against the twin, or against a board when
//! `KERFMETER_PORT` is set; run them one at a time on a board (`--test-threads=1`), as there is
//! only one device.

use std::io::Write;
use std::time::Duration;

use kerfmeter::protocol::{
    Conditions, Envelope, ErrorCode, Fault, MAX_REQUEST_FRAME_LEN, Request, RunState, encode_frame,
};
use kerfmeter::sim::{SimFault, SimOptions};
use kerfmeter::{Error, Kerfmeter, Progress};
use kerfmeter_hil::{Bench, TWIN_KERF_UM, options};

fn bench(case: &str, seed: u64) -> Bench {
    let b = Bench::connect(seed).unwrap_or_else(|e| panic!("{case}: {e}"));
    b.report(case);
    b
}

#[test]
fn handshake_and_info_fields_are_sane() {
    let mut b = bench("handshake", 11);
    let info = b.meter.info().expect("GetInfo");
    assert!(kerfmeter::protocol::PROTOCOL_VERSION.compatible_with(&info.protocol));
    assert_eq!(
        info.hardware.encoder_bits, 14,
        "AS5048A is a 14-bit encoder"
    );
    assert!(
        info.hardware.control_rate_hz >= 1000,
        "control loop must run at 1 kHz or more"
    );
    assert!((8..=16).contains(&info.hardware.pwm_bits));
    assert!(info.hardware.max_samples >= 256);
    assert!(
        usize::from(info.hardware.max_request_frame_len) >= MAX_REQUEST_FRAME_LEN,
        "the device must accept every request this host can send"
    );
    if b.target.is_twin() {
        assert_eq!(info.hardware.board.as_str(), "twin");
    } else {
        assert!(
            info.hardware.board.starts_with("esp32"),
            "{}",
            info.hardware.board
        );
    }
    // Stable while the device runs.
    assert_eq!(b.meter.info().expect("GetInfo").boot_id, info.boot_id);
    // A healthy bench at rest: no idle condition and a step gap reported; on the twin, the
    // control rate held so far and a measured 12 V supply (a board reports no supply until its
    // ADC is wired, and its gaps include flash writes at rest).
    let status = b.meter.status().expect("GetStatus");
    assert_eq!(status.conditions, Conditions::empty(), "{status:?}");
    // Its health (protocol 2.6): no watchdog, brown-out or panic behind this boot.
    let health = b.meter.diagnostics().expect("GetDiagnostics");
    let health = health.expect("a protocol 2.6 device answers GetDiagnostics");
    assert!(!health.reset_reason.is_abnormal(), "{health:?}");
    assert!(status.longest_gap_us >= 1, "{status:?}");
    if b.target.is_twin() {
        assert!((1_000..=3_000).contains(&status.longest_gap_us));
        assert!(
            status.supply_v.is_some_and(|v| (11.0..13.5).contains(&v)),
            "{status:?}"
        );
    }
}

#[test]
fn the_reference_gauge_reads_its_kerf_and_the_curve_is_physical() {
    let mut b = bench("reference-gauge", 12);
    b.meter.reset_kerfmeter().unwrap();
    let mut progress: Vec<Progress> = Vec::new();
    let result = b
        .meter
        .run_kerfmeter(&b.params, |p| progress.push(*p))
        .unwrap();
    let expected = b.expected_kerf_um(&result);
    let error = f64::from(result.kerf_um) - expected;
    eprintln!(
        "reference gauge: {:.2} µm, expected {expected:.2} µm, error {error:+.2} µm",
        result.kerf_um
    );
    assert!(
        error.abs() <= b.tolerance_um,
        "error {error:+.2} µm > {} µm",
        b.tolerance_um
    );
    assert!(
        (result.force_at_jam_n - b.params.target_force_n).abs() < 0.02 * b.params.target_force_n
    );

    // The curve: time strictly increases; until the jam the hub never turns back by more than
    // encoder noise (8 LSB); the torque never exceeds the run's limit.
    let curve = b.meter.curve().unwrap();
    assert_eq!(curve.run_id, result.run_id);
    let noise_deg = 8.0 * 360.0 / 16384.0;
    let mut furthest = f32::MIN;
    for w in curve.samples.windows(2) {
        assert!(w[1].t_ms > w[0].t_ms);
    }
    for s in &curve.samples {
        assert!(s.torque_nm <= b.params.max_torque_nm + 1e-4);
        if s.angle_deg < result.angle_deg - 1.0 {
            furthest = furthest.max(s.angle_deg);
            assert!(
                s.angle_deg > furthest - noise_deg,
                "{s:?} fell back from {furthest}"
            );
        }
    }
    assert!(progress.iter().any(|p| p.state == RunState::Ramping));
}

#[test]
fn reset_returns_the_hub_to_zero_and_forgets_the_result() {
    let mut b = bench("reset", 13);
    b.meter.reset_kerfmeter().unwrap();
    b.meter.run_kerfmeter(&b.params, |_| {}).unwrap();
    assert!(b.meter.get_kerf_value().unwrap().is_some());
    b.meter.reset_kerfmeter().unwrap();
    let status = b.meter.status().unwrap();
    assert!(
        status.angle_deg.abs() <= 0.5,
        "hub at {}° after reset",
        status.angle_deg
    );
    assert_eq!(status.state, RunState::Idle);
    assert_eq!(b.meter.get_kerf_value().unwrap(), None);
}

#[test]
fn abort_mid_ramp_stops_the_motor_and_the_next_run_works() {
    let mut b = bench("abort", 14);
    b.meter.reset_kerfmeter().unwrap();
    b.meter.call(Request::Run(b.params)).unwrap();
    // Wait for the ramp.
    for _ in 0..500 {
        if b.meter.status().unwrap().state == RunState::Ramping {
            break;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    b.meter.abort().unwrap();
    // The device answers Abort after the tick that applied it: no torque from then on.
    let status = b.meter.status().unwrap();
    assert_eq!(status.state, RunState::Idle);
    assert_eq!(status.torque_nm, 0.0);
    b.meter.reset_kerfmeter().unwrap();
    let result = b.meter.run_kerfmeter(&b.params, |_| {}).unwrap();
    assert!((f64::from(result.kerf_um) - b.expected_kerf_um(&result)).abs() <= b.tolerance_um);
}

#[test]
fn every_injectable_fault_is_typed_safe_and_recoverable() {
    let probe = bench("faults", 15);
    if !probe.target.is_twin() {
        probe.skip(
            "faults",
            "faults other than host silence cannot be injected on a board; see host-silence",
        );
        return;
    }
    drop(probe);
    for fault in SimFault::ALL {
        if fault == SimFault::HostSilent {
            continue; // its own case below, on both targets
        }
        let mut b = Bench::connect_with(SimOptions {
            kerf_um: TWIN_KERF_UM,
            seed: 15,
            fault: Some(fault),
            ..SimOptions::default()
        })
        .unwrap();
        b.meter.reset_kerfmeter().unwrap();
        let outcome = b.meter.run_kerfmeter(&b.params, |_| {});
        match fault.expected() {
            Some(expected) => {
                let err = outcome.expect_err(fault.name());
                assert_eq!(err.fault(), Some(expected), "{fault}: {err}");
                let status = b.meter.status().unwrap();
                assert_eq!(status.state, RunState::Fault(expected), "{fault}");
                assert_eq!(status.torque_nm, 0.0, "{fault}: motor safe");
                // Latched: everything but clearing is refused, with the fault named.
                let refused = b.meter.run_kerfmeter(&b.params, |_| {}).unwrap_err();
                assert!(
                    matches!(refused, Error::Device { code: ErrorCode::Faulted(f), .. } if f == expected),
                    "{fault}: {refused:?}"
                );
                b.meter.clear_fault().unwrap();
            }
            None => {
                let result =
                    outcome.unwrap_or_else(|e| panic!("{fault} must be ridden through: {e}"));
                assert!(
                    !result.flags.is_empty(),
                    "{fault}: the errors ridden through are reported"
                );
            }
        }
        b.meter.reset_kerfmeter().unwrap();
        let result = b
            .meter
            .run_kerfmeter(&b.params, |_| {})
            .unwrap_or_else(|e| panic!("{fault}: no recovery: {e}"));
        assert!((f64::from(result.kerf_um) - b.expected_kerf_um(&result)).abs() <= b.tolerance_um);
        eprintln!("HIL fault-{fault} twin ran");
    }
}

#[test]
fn host_silence_mid_run_stops_the_motor_within_the_watchdog_period() {
    // On the twin, simulated time must pass while the host is silent: real-time pace.
    let mut b = Bench::connect_with(SimOptions {
        kerf_um: 400.0,
        seed: 16,
        realtime: true,
        ..SimOptions::default()
    })
    .unwrap();
    b.report("host-silence");
    b.meter.reset_kerfmeter().unwrap();
    b.meter.call(Request::Run(b.params)).unwrap();
    std::thread::sleep(Duration::from_millis(150));
    assert!(b.meter.status().unwrap().state != RunState::Idle);
    // The host goes quiet for the watchdog period and a margin.
    std::thread::sleep(Duration::from_millis(
        u64::from(b.params.host_timeout_ms) + 300,
    ));
    let status = b.meter.status().unwrap();
    assert_eq!(status.state, RunState::Fault(Fault::HostSilent));
    assert_eq!(status.torque_nm, 0.0);
    b.meter.clear_fault().unwrap();
}

/// A request frame with an arbitrary envelope, for abuse.
fn frame(seq: u16, request: &Request) -> Vec<u8> {
    let mut buf = [0u8; MAX_REQUEST_FRAME_LEN];
    encode_frame(
        &Envelope {
            seq,
            body: request.clone(),
        },
        &mut buf,
    )
    .unwrap()
    .to_vec()
}

#[test]
fn protocol_abuse_never_hangs_the_device_nor_moves_the_motor() {
    let (target, port) = Bench::open(SimOptions {
        seed: 17,
        ..SimOptions::default()
    })
    .unwrap();
    let mut raw = port.try_clone().unwrap();
    let meter = Kerfmeter::from_port(port, options()).unwrap();
    let mut b = Bench::describe(target, meter).unwrap();
    b.report("protocol-abuse");
    b.meter.reset_kerfmeter().unwrap();
    let before = b.meter.status().unwrap();

    let mut abuse = Vec::new();
    // Random bytes (a fixed pseudo-random sequence), with and without delimiters.
    let mut x: u32 = 0x1234_5678;
    for _ in 0..4096 {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        abuse.push(x as u8);
    }
    // An oversized frame: far longer than any request.
    abuse.push(0);
    abuse.extend(std::iter::repeat_n(0x55, 10 * MAX_REQUEST_FRAME_LEN));
    abuse.push(0);
    // A truncated frame and a frame with a bad CRC, both of a Run.
    let run = frame(40_000, &Request::Run(b.params));
    abuse.extend(&run[..run.len() / 2]);
    abuse.push(0);
    let mut bad = frame(40_001, &Request::Run(b.params));
    let n = bad.len();
    bad[n - 3] ^= 0x01;
    abuse.extend(bad);
    raw.write_all(&abuse).unwrap();
    raw.flush().unwrap();
    std::thread::sleep(Duration::from_millis(100));

    // Still answering, nothing moved.
    let after = b.meter.status().unwrap();
    assert_eq!(after.state, RunState::Idle);
    assert_eq!(after.torque_nm, 0.0);
    assert_eq!(after.run_id, before.run_id, "no corrupted Run was executed");
    assert!((after.angle_deg - before.angle_deg).abs() < 0.2);

    // Out of order: Run during a run is Busy; GetKerf during a run has no result yet; a
    // duplicate seq is answered from memory, not executed again.
    b.meter.call(Request::Run(b.params)).unwrap();
    let busy = b.meter.call(Request::Run(b.params)).unwrap_err();
    assert!(
        matches!(
            busy,
            Error::Device {
                code: ErrorCode::Busy,
                ..
            }
        ),
        "{busy:?}"
    );
    assert_eq!(b.meter.get_kerf_value().unwrap(), None);
    let run_id = b.meter.status().unwrap().run_id;
    let dup = frame(50_000, &Request::Abort);
    raw.write_all(&dup).unwrap();
    raw.write_all(&dup).unwrap();
    std::thread::sleep(Duration::from_millis(50));
    let status = b.meter.status().unwrap();
    assert_eq!(status.state, RunState::Idle);
    assert_eq!(status.run_id, run_id);
    b.meter.reset_kerfmeter().unwrap();
}

#[test]
fn soak_runs_do_not_drift() {
    let mut b = bench("soak", 18);
    let runs = b.soak_runs as usize;
    let rss_before = resident_kib();
    let mut errors = Vec::with_capacity(runs);
    for i in 0..runs {
        b.meter.reset_kerfmeter().unwrap();
        let r = b
            .meter
            .run_kerfmeter(&b.params, |_| {})
            .unwrap_or_else(|e| panic!("run {i}: {e}"));
        errors.push(f64::from(r.kerf_um) - b.expected_kerf_um(&r));
    }
    let window = (runs / 10).max(1);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let drift = mean(&errors[runs - window..]) - mean(&errors[..window]);
    let (worst_run, worst) = errors
        .iter()
        .enumerate()
        .fold((0, 0.0f64), |(wi, w), (i, e)| {
            if e.abs() > w { (i, e.abs()) } else { (wi, w) }
        });
    eprintln!(
        "soak: {runs} runs, drift {drift:+.3} µm, worst error {worst:.3} µm (run {worst_run}); \
         mean error of the first {window} runs {:+.3} µm",
        mean(&errors[..window])
    );
    assert!(
        worst <= b.tolerance_um,
        "worst error {worst:.3} µm (run {worst_run})"
    );
    assert!(drift.abs() <= b.tolerance_um / 2.0, "drift {drift:+.3} µm");
    if let (Some(before), Some(after)) = (rss_before, resident_kib()) {
        eprintln!("soak: resident memory {before} KiB → {after} KiB");
        assert!(
            after < before + 8 * 1024,
            "memory grew by {} KiB",
            after - before
        );
    }
}

/// Resident memory of this process (host and in-process twin), KiB; `None` off Linux.
fn resident_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
