//! The bring-up on the twin, fault by fault: the healthy twin passes every step, and each fault
//! the twin can be given fails the step that should catch it. Then the judges alone, for what
//! the twin cannot be made to show (a watchdog reset).

use std::ops::ControlFlow;

use kerfmeter::Options;
use kerfmeter::protocol::{
    AdcCalibration, BrownOutDetector, Diagnostics, G2Variant, ResetReason, SelfTestItem,
    TestOutcome,
};
use kerfmeter::sim::{PlantParams, SimDevice, SimFault, SimOptions};

use super::*;

/// The bring-up of a twin started with `options`, the twin answering (unless `request` does).
fn bring_up_twin(options: SimOptions, request: &BringupRequest) -> BringupReport {
    let truth = TwinTruth::of(&options);
    let (_sim, mut meter) = SimDevice::connect(options, Options::default()).unwrap();
    bring_up(&mut meter, request, Some(truth), &mut NoWitness, |_| {
        ControlFlow::Continue(())
    })
    .unwrap()
}

fn with_plant(name: &str, value: f64) -> SimOptions {
    let mut plant = PlantParams::default();
    plant.set(name, value).unwrap();
    SimOptions {
        plant,
        ..SimOptions::default()
    }
}

fn outcome(r: &BringupReport, id: StepId) -> Outcome {
    r.step(id)
        .unwrap_or_else(|| panic!("no {id:?} in\n{r}"))
        .outcome
}

/// `report` failed at `id` (and the text says so).
fn assert_fails_at(r: &BringupReport, id: StepId) {
    assert!(!r.passed, "{r}");
    assert!(r.failed.contains(&id), "{id:?} did not fail:\n{r}");
    assert!(
        r.to_string().contains(&format!("{:<16} FAIL", id.title())),
        "{r}"
    );
}

#[test]
fn the_healthy_twin_passes_every_step_and_says_the_twin_answered() {
    let r = bring_up_twin(SimOptions::default(), &BringupRequest::default());
    assert!(r.passed, "{r}");
    assert!(r.not_checked.is_empty(), "{r}");
    assert!(r.steps.iter().all(|s| s.outcome == Outcome::Pass), "{r}");
    assert_eq!(r.steps.len(), 11, "{r}");
    let meter = r.step(StepId::SupplyMeter).unwrap();
    assert_eq!(meter.answered_by, Some(AnsweredBy::Twin));
    assert!(
        r.to_string()
            .contains("the twin answered: no person looked")
    );
    assert!(r.to_string().ends_with("bring-up passed"), "{r}");
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["kerfmeter_bringup"], 1);
    assert_eq!(json["steps"][3]["step"], "supply-meter");
    assert_eq!(json["steps"][3]["answered_by"], "twin");
}

#[test]
fn a_supply_too_low_or_too_high_fails_the_supply_and_skips_the_motion() {
    for supply_v in [6.0, 28.0] {
        let r = bring_up_twin(with_plant("supply_v", supply_v), &BringupRequest::default());
        assert_fails_at(&r, StepId::Supply);
        assert_eq!(outcome(&r, StepId::SelfTest), Outcome::Skipped, "{r}");
        assert_eq!(outcome(&r, StepId::GaugeRun), Outcome::Skipped, "{r}");
    }
}

#[test]
fn a_24_v_supply_on_an_18v17_is_within_the_senses_tolerance_of_its_limit() {
    let r = bring_up_twin(with_plant("supply_v", 24.0), &BringupRequest::default());
    assert_fails_at(&r, StepId::Supply);
    let ok = bring_up_twin(
        SimOptions {
            driver: G2Variant::V24v13,
            ..with_plant("supply_v", 24.0)
        },
        &BringupRequest::default(),
    );
    assert_eq!(outcome(&ok, StepId::Supply), Outcome::Pass, "{ok}");
}

#[test]
fn a_meter_reading_far_from_the_devices_fails_the_meter_step() {
    let request = BringupRequest {
        meter_v: Some(10.5),
        ..BringupRequest::default()
    };
    let r = bring_up_twin(SimOptions::default(), &request);
    assert_fails_at(&r, StepId::SupplyMeter);
    let step = r.step(StepId::SupplyMeter).unwrap();
    assert_eq!(step.answered_by, Some(AnsweredBy::Flag));
}

#[test]
fn a_weak_magnet_fails_the_encoder_and_skips_the_self_test() {
    let r = bring_up_twin(with_plant("magnet_agc", 230.0), &BringupRequest::default());
    assert_fails_at(&r, StepId::Encoder);
    assert_eq!(outcome(&r, StepId::SelfTest), Outcome::Skipped, "{r}");
    assert!(r.to_string().contains("field is weak"), "{r}");
}

#[test]
fn an_uncalibrated_adc_fails_the_calibration_step() {
    let r = bring_up_twin(
        SimOptions {
            adc_uncalibrated: true,
            ..SimOptions::default()
        },
        &BringupRequest::default(),
    );
    assert_fails_at(&r, StepId::AdcCalibration);
    assert_eq!(r.failed, vec![StepId::AdcCalibration], "{r}");
}

#[test]
fn swapped_motor_leads_fail_the_direction() {
    let r = bring_up_twin(
        SimOptions {
            motor_leads_swapped: true,
            ..SimOptions::default()
        },
        &BringupRequest::default(),
    );
    assert_fails_at(&r, StepId::Direction);
    assert!(r.to_string().contains("leads are"), "{r}");
}

#[test]
fn a_person_who_saw_the_hub_turn_ccw_on_a_consistent_device_fails_the_direction() {
    let request = BringupRequest {
        hub_turned: Some(HubTurn::Ccw),
        ..BringupRequest::default()
    };
    let r = bring_up_twin(SimOptions::default(), &request);
    assert_fails_at(&r, StepId::Direction);
    assert!(r.to_string().contains("both reversed"), "{r}");
}

#[test]
fn slow_ticks_fail_the_timing() {
    let mut options = with_plant("late_tick_ms", 5.0);
    options.plant.set("late_ticks_per_s", 5.0).unwrap();
    let r = bring_up_twin(options, &BringupRequest::default());
    assert_fails_at(&r, StepId::Timing);
}

/// Each injected fault, and the step that must catch it.
const FAULTS: [(SimFault, StepId); 9] = [
    (SimFault::Parity, StepId::SelfTest),
    (SimFault::MotorDisconnected, StepId::Direction),
    (SimFault::MagnetLost, StepId::GaugeRun),
    (SimFault::MisoStuck, StepId::GaugeRun),
    (SimFault::NoInset, StepId::GaugeRun),
    (SimFault::DriverFault, StepId::GaugeRun),
    (SimFault::OverCurrent, StepId::GaugeRun),
    (SimFault::HostSilent, StepId::GaugeRun),
    (SimFault::ProngSlip, StepId::GaugeRun),
];

#[test]
fn every_injected_fault_fails_the_step_that_should_catch_it() {
    assert_eq!(FAULTS.len(), SimFault::ALL.len());
    for (fault, step) in FAULTS {
        let r = bring_up_twin(
            SimOptions {
                fault: Some(fault),
                ..SimOptions::default()
            },
            &BringupRequest::default(),
        );
        assert!(
            r.failed.contains(&step),
            "{} did not fail {step:?}:\n{r}",
            fault.name()
        );
    }
}

#[test]
fn without_an_answer_on_hardware_the_persons_steps_are_not_checked() {
    let (_sim, mut meter) = SimDevice::connect(SimOptions::default(), Options::default()).unwrap();
    let r = bring_up(
        &mut meter,
        &BringupRequest::default(),
        None,
        &mut NoWitness,
        |_| ControlFlow::Continue(()),
    )
    .unwrap();
    assert!(r.passed, "{r}");
    assert_eq!(
        r.not_checked,
        vec![StepId::SupplyMeter, StepId::Direction, StepId::GaugeRun],
        "{r}"
    );
    assert!(
        r.to_string().contains("not checked: supply vs meter"),
        "{r}"
    );
}

#[test]
fn a_stop_during_the_self_test_ends_the_bring_up_cancelled() {
    let (_sim, mut meter) = SimDevice::connect(SimOptions::default(), Options::default()).unwrap();
    let e = bring_up(
        &mut meter,
        &BringupRequest::default(),
        None,
        &mut NoWitness,
        |_| ControlFlow::Break(()),
    )
    .unwrap_err();
    assert!(matches!(e, kerfmeter::Error::Cancelled), "{e}");
    let status = meter.status().unwrap();
    assert_eq!(status.torque_nm, 0.0);
}

fn healthy() -> Diagnostics {
    Diagnostics {
        reset_reason: ResetReason::PowerOn,
        chip_revision: None,
        adc_calibration: AdcCalibration::Efuse { version: 1 },
        brown_out: BrownOutDetector::Resets,
        cs_asleep_mv: Some(60),
        cs_offset_mv: 50.0,
        cs_offset_learnt: true,
        encoder: None,
        longest_step_us: 0,
        longest_gap_us: 1000,
        adc_restarts: 0,
        driver: G2Variant::V18v17,
    }
}

#[test]
fn a_watchdog_brown_out_or_panic_reset_fails_the_reset_step() {
    assert_eq!(
        judge::reset_reason(&healthy()).outcome,
        Outcome::Pass,
        "power-on"
    );
    for reason in [
        ResetReason::Watchdog,
        ResetReason::BrownOut,
        ResetReason::Panic,
    ] {
        let d = Diagnostics {
            reset_reason: reason,
            ..healthy()
        };
        assert_eq!(judge::reset_reason(&d).outcome, Outcome::Fail, "{reason:?}");
    }
}

#[test]
fn an_adc_conversion_given_up_fails_the_calibration_step() {
    // A stalled conversion is the in-process twin's (`Twin::stall_next_adc_conversion`), not
    // an option of a `--sim` twin: its report is judged alone.
    assert_eq!(judge::adc_calibration(&healthy()).outcome, Outcome::Pass);
    let restarted = Diagnostics {
        adc_restarts: 1,
        ..healthy()
    };
    let step = judge::adc_calibration(&restarted);
    assert_eq!(step.outcome, Outcome::Fail);
    assert!(
        step.seen.contains("1 conversion(s) given up"),
        "{}",
        step.seen
    );
}

#[test]
fn a_cs_offset_not_learnt_or_a_high_sleep_level_fails_its_step() {
    assert_eq!(judge::cs_braking(&healthy()).outcome, Outcome::Pass);
    let unlearnt = Diagnostics {
        cs_offset_learnt: false,
        ..healthy()
    };
    assert_eq!(judge::cs_braking(&unlearnt).outcome, Outcome::Fail);
    let high = Diagnostics {
        cs_asleep_mv: Some(400),
        ..healthy()
    };
    assert_eq!(judge::cs_asleep(&high).outcome, Outcome::Fail);
}

#[test]
fn the_direction_tells_a_swapped_motor_from_an_inverted_encoder() {
    let back = SelfTestItem {
        outcome: TestOutcome::Fail,
        value: -12.0,
    };
    let cw = Some((HubTurn::Cw, AnsweredBy::Person));
    let ccw = Some((HubTurn::Ccw, AnsweredBy::Person));
    let encoder = judge::direction(back, cw);
    assert!(
        encoder
            .means
            .unwrap()
            .contains("configuration: encoder_inverted true")
    );
    let motor = judge::direction(back, ccw);
    assert!(
        motor
            .means
            .unwrap()
            .contains("configuration: motor_inverted true")
    );
}

#[test]
fn a_request_refuses_unknown_fields_and_reads_its_answers() {
    let r: BringupRequest =
        serde_json::from_str(r#"{"meter_v": 12.05, "hub_turned": "cw"}"#).unwrap();
    assert_eq!(r.meter_v, Some(12.05));
    assert_eq!(r.hub_turned, Some(HubTurn::Cw));
    assert!(serde_json::from_str::<BringupRequest>(r#"{"meter": 12}"#).is_err());
    for v in [f32::NAN, -1.0, f32::INFINITY] {
        let r = BringupRequest {
            meter_v: Some(v),
            ..BringupRequest::default()
        };
        assert!(r.check().is_err(), "{v}");
    }
    assert_eq!("CCW".parse::<HubTurn>(), Ok(HubTurn::Ccw));
}
