//! What the device tells about its own health (protocol 2.6, issue 34), on the twin: the reset's
//! reason, the chip, the ADC's calibration (an uncalibrated chip's current sense reads 35 %
//! high, and the device says so in `Status` and next to its self-test), the current sense's
//! levels and the encoder's diagnostics; and the G2 variant's current-sense gain and supply
//! limit.

use kerfmeter_protocol::{
    AdcCalibration, BrownOutDetector, ChipRevision, Conditions, Diagnostics, ErrorCode, G2Variant,
    Request, ResetReason, Response, RunParams, RunState, SelfTestReport, Status,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

fn twin(options: TwinOptions) -> Twin {
    let mut t = Twin::new(TwinOptions {
        kerf_um: 150.0,
        seed: 21,
        ..options
    });
    // The supply filter settles and the encoder's diagnostics are read.
    t.advance_ticks(100);
    t
}

fn diagnostics(t: &mut Twin) -> Diagnostics {
    match t.request(&Request::GetDiagnostics) {
        Response::Diagnostics(d) => d,
        other => panic!("{other:?}"),
    }
}

fn status(t: &mut Twin) -> Status {
    match t.request(&Request::GetStatus) {
        Response::Status(s) => s,
        other => panic!("{other:?}"),
    }
}

/// Start a self-test and poll it like a host until its report comes, at most 2 s.
fn self_test(t: &mut Twin) -> SelfTestReport {
    assert_eq!(t.request(&Request::SelfTest), Response::Ok);
    for _ in 0..200 {
        t.advance_ticks(10);
        if let Response::SelfTest(Some(r)) = t.request(&Request::GetSelfTest) {
            return r;
        }
    }
    panic!("no self-test report in 2 s");
}

#[test]
fn a_healthy_twin_reports_its_boot_its_sensors_and_its_timing() {
    let mut t = twin(TwinOptions::default());
    let d = diagnostics(&mut t);
    assert_eq!(d.reset_reason, ResetReason::PowerOn);
    assert_eq!(d.chip_revision, Some(ChipRevision { major: 0, minor: 4 }));
    assert_eq!(d.adc_calibration, AdcCalibration::Efuse { version: 1 });
    assert_eq!(d.brown_out, BrownOutDetector::Resets);
    assert_eq!(d.driver, G2Variant::V18v17);
    assert_eq!(d.adc_restarts, 0);
    let encoder = d.encoder.expect("the encoder's diagnostics were read");
    assert!(encoder.ocf && !encoder.cof && !encoder.comp_low && !encoder.comp_high);
    assert!(encoder.magnitude > 1000, "{encoder:?}");
    // The CS pin asleep: the G2's offset and its sleep level (50 + 10 mV by default).
    let p = *t.plant().params();
    let asleep_mv = f64::from(d.cs_asleep_mv.expect("read asleep"));
    assert!(
        (asleep_mv - (p.cs_offset_mv + p.cs_sleep_delta_mv)).abs() <= 3.0,
        "{asleep_mv}"
    );
    assert!(!d.cs_offset_learnt, "nothing braked yet: {d:?}");
    assert!(d.longest_gap_us >= 1000, "{d:?}");
    assert!(
        !status(&mut t)
            .conditions
            .contains(Conditions::ADC_UNCALIBRATED)
    );

    // A self-test brakes awake first: the offset is learnt, the awake one.
    self_test(&mut t);
    let d = diagnostics(&mut t);
    assert!(d.cs_offset_learnt);
    assert!(
        (f64::from(d.cs_offset_mv) - p.cs_offset_mv).abs() <= 1.0,
        "{d:?}"
    );
}

#[test]
fn a_reset_reads_as_its_reason_and_the_boot_facts_are_settable() {
    let mut t = twin(TwinOptions::default());
    t.set_boot_facts(kerfmeter_firmware::health::BootFacts {
        reset_reason: ResetReason::BrownOut,
        brown_out: BrownOutDetector::Off,
        ..kerfmeter_firmware::health::BootFacts::UNKNOWN
    });
    let d = diagnostics(&mut t);
    assert_eq!(d.reset_reason, ResetReason::BrownOut);
    assert_eq!(d.brown_out, BrownOutDetector::Off);
    assert_eq!(d.chip_revision, None);
    // A power cycle keeps the chip's facts and reads as a power-on; a watchdog reset as one.
    t.reboot();
    assert_eq!(diagnostics(&mut t).reset_reason, ResetReason::PowerOn);
    assert_eq!(diagnostics(&mut t).brown_out, BrownOutDetector::Off);
    t.reset_by(ResetReason::Watchdog);
    assert_eq!(diagnostics(&mut t).reset_reason, ResetReason::Watchdog);
}

#[test]
fn an_uncalibrated_adc_is_reported_and_its_self_test_reads_the_current_high() {
    let calibrated = self_test(&mut twin(TwinOptions::default()));
    let mut t = twin(TwinOptions {
        adc_uncalibrated: true,
        ..TwinOptions::default()
    });
    assert_eq!(
        diagnostics(&mut t).adc_calibration,
        AdcCalibration::Uncalibrated
    );
    let conditions = status(&mut t).conditions;
    assert!(
        conditions.contains(Conditions::ADC_UNCALIBRATED),
        "{conditions:?}"
    );
    // It blocks nothing: a self-test runs, and the condition stands beside its report.
    let uncalibrated = self_test(&mut t);
    assert!(
        status(&mut t)
            .conditions
            .contains(Conditions::ADC_UNCALIBRATED)
    );
    // The current sense reads 35 % high (its offset too, which the brake learns): the torque
    // constant comes out some 35 % high, still inside the self-test's window, which is why the
    // condition must say it.
    let ratio = uncalibrated.torque_per_duty_nm.value / calibrated.torque_per_duty_nm.value;
    assert!((1.25..=1.45).contains(&ratio), "{ratio}: {uncalibrated:?}");
}

#[test]
fn a_24v13_current_is_read_at_its_own_gain() {
    // Its CS gives 40 mV/A: read at the 18v17's 20 mV/A, every current would be doubled, and
    // the self-test's torque constant with it.
    let reference = self_test(&mut twin(TwinOptions::default()));
    let mut t = twin(TwinOptions {
        driver: G2Variant::V24v13,
        ..TwinOptions::default()
    });
    assert_eq!(diagnostics(&mut t).driver, G2Variant::V24v13);
    let report = self_test(&mut t);
    let ratio = report.torque_per_duty_nm.value / reference.torque_per_duty_nm.value;
    assert!((0.9..=1.1).contains(&ratio), "{ratio}: {report:?}");
}

/// A twin on a `supply_v` supply with the G2 `driver`.
fn on_supply(supply_v: f64, driver: G2Variant) -> Twin {
    twin(TwinOptions {
        plant: PlantParams {
            supply_v,
            ..PlantParams::default()
        },
        driver,
        ..TwinOptions::default()
    })
}

#[test]
fn a_25_v_supply_is_refused_on_an_18v17_and_accepted_on_a_24v13() {
    // Pololu gives the 18v17 a safe maximum of about 24 V; the device accepted up to 26 V.
    let mut t = on_supply(25.0, G2Variant::V18v17);
    let conditions = status(&mut t).conditions;
    assert!(
        conditions.contains(Conditions::SUPPLY_OUT_OF_RANGE),
        "{conditions:?}"
    );
    assert_eq!(
        t.request(&Request::Run(RunParams::DEFAULT)),
        Response::Error(ErrorCode::Blocked(conditions))
    );
    // 24 V, an 18v17's safe maximum, is accepted.
    let mut t = on_supply(24.0, G2Variant::V18v17);
    assert!(status(&mut t).conditions.is_empty());
    // The 24v13 is safe to about 34 V, and the device to 26 V.
    let mut t = on_supply(25.0, G2Variant::V24v13);
    assert!(status(&mut t).conditions.is_empty());
    assert_eq!(t.request(&Request::Run(RunParams::DEFAULT)), Response::Ok);
    let mut t = on_supply(28.0, G2Variant::V24v13);
    assert!(
        status(&mut t)
            .conditions
            .contains(Conditions::SUPPLY_OUT_OF_RANGE)
    );
}

#[test]
fn an_adc_conversion_that_never_finishes_mid_run_is_given_up_and_the_run_goes_on() {
    // The twin's ADC follows the board's schedule (the supply one tick in ten), and a stalled
    // conversion waits for ever until the firmware opens the ADC again: without that restart
    // the current would be unknown from the tenth tick on, and the run would fault OverCurrent.
    let mut t = twin(TwinOptions::default());
    assert_eq!(t.request(&Request::Run(RunParams::DEFAULT)), Response::Ok);
    t.advance_ticks(300);
    assert!(t.motor_driven(), "mid-run, the bridge driven");
    t.stall_next_adc_conversion();
    for _ in 0..3000 {
        t.advance_ticks(10);
        match status(&mut t).state {
            RunState::Done => break,
            RunState::Fault(f) => panic!("faulted {f:?}"),
            _ => {}
        }
    }
    assert_eq!(t.adc_stalls(), 1);
    let Response::Kerf(Some(k)) = t.request(&Request::GetKerf) else {
        panic!("a result")
    };
    let truth_um = t.plant().truth_um(&RunParams::DEFAULT);
    assert!(
        (f64::from(k.kerf_um) - truth_um).abs() < 2.0,
        "{k:?} against {truth_um}"
    );
    assert_eq!(diagnostics(&mut t).adc_restarts, 1);
    assert!(t.motor_safe());
}
