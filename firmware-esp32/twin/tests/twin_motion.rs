//! The hub's zero on the digital twin, in-process: the encoder's turn counting across
//! configuration changes (output and motor shaft), and `Reset` between gauges when the motor is
//! weaker than its calibration says (a hot winding, a low supply).

mod common;
use common::measure;

use kerfmeter_protocol::{
    Conditions, DeviceConfig, EncoderPlacement, ErrorCode, Fault, KerfResult, Request, Response,
    RunParams, RunState, Status,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

/// Reset, polling every 10 ms; `Ok` in `Idle`, or the fault it ended in.
fn reset(twin: &mut Twin) -> Result<(), Fault> {
    assert_eq!(twin.request(&Request::Reset), Response::Ok);
    for _ in 0..1000 {
        twin.advance_ticks(10);
        match status(twin).state {
            RunState::Idle => return Ok(()),
            RunState::Fault(f) => return Err(f),
            _ => {}
        }
    }
    panic!("reset did not finish in 10 s");
}

fn status(twin: &mut Twin) -> Status {
    match twin.request(&Request::GetStatus) {
        Response::Status(s) => s,
        other => panic!("{other:?}"),
    }
}

fn set_config(twin: &mut Twin, config: DeviceConfig) -> Result<(), ErrorCode> {
    let answer = match twin.request(&Request::SetConfig(config)) {
        Response::Config(report) => {
            assert_eq!(report.config, config);
            Ok(())
        }
        Response::Error(e) => Err(e),
        other => panic!("{other:?}"),
    };
    twin.advance_ticks(20);
    answer
}

fn twin(plant: PlantParams, seed: u64) -> Twin {
    let mut t = Twin::new(TwinOptions {
        kerf_um: 150.0,
        seed,
        plant,
        ..TwinOptions::default()
    });
    t.advance_ticks(5);
    t
}

const MOTOR_SHAFT: DeviceConfig = DeviceConfig {
    encoder_placement: EncoderPlacement::MotorShaft,
    ..DeviceConfig::DEFAULT
};

/// A twin with its magnet on the motor shaft, configured so at boot (the hub at zero).
fn motor_shaft_twin(seed: u64) -> Twin {
    let mut t = twin(PlantParams::default(), seed);
    t.set_magnet_on_motor_shaft(true);
    assert_eq!(set_config(&mut t, MOTOR_SHAFT), Ok(()));
    // The change onto the motor shaft: the user confirms the hub at its mark.
    let s = status(&mut t);
    assert_eq!(s.conditions, Conditions::HUB_TURN_UNKNOWN);
    assert_eq!(t.request(&Request::ConfirmHubAtZero), Response::Ok);
    t.advance_ticks(20);
    let s = status(&mut t);
    assert!(s.conditions.is_empty() && s.angle_deg.abs() < 0.5, "{s:?}");
    t
}

/// Measure and check the reading against the gauge's truth.
fn measure_right(t: &mut Twin) -> KerfResult {
    let k = measure(t, &RunParams::DEFAULT).expect("a result");
    let truth = t.plant().truth_um(&RunParams::DEFAULT);
    assert!(
        (f64::from(k.kerf_um) - truth).abs() < 3.0,
        "measured {} µm, truth {truth} µm",
        k.kerf_um
    );
    k
}

/// Reset, check the hub came to its true zero (the mark), and measure right.
fn reset_to_the_mark_and_measure_right(t: &mut Twin) {
    reset(t).unwrap();
    let hub_deg = t.plant().hub_cw_deg();
    assert!(hub_deg.abs() < 0.5, "{hub_deg}");
    measure_right(t);
}

#[test]
fn a_set_config_in_done_keeps_a_motor_shaft_encoders_zero() {
    let mut t = motor_shaft_twin(31);
    measure_right(&mut t);
    let done_deg = status(&mut t).angle_deg;
    assert!(done_deg > 30.0, "{done_deg}");
    // A field that is not the encoder's: the hub keeps its angle (no re-lock to a false zero)...
    let limits = DeviceConfig {
        max_current_a: 6.0,
        ..MOTOR_SHAFT
    };
    assert_eq!(set_config(&mut t, limits), Ok(()));
    let after_deg = status(&mut t).angle_deg;
    assert!(
        (after_deg - done_deg).abs() < 0.2,
        "{done_deg} → {after_deg}"
    );
    // ...the reset finds the true zero, and the next gauge reads right.
    reset_to_the_mark_and_measure_right(&mut t);
}

#[test]
fn a_motor_shaft_encoders_settings_change_only_at_zero() {
    let mut t = motor_shaft_twin(32);
    measure_right(&mut t);
    // Away from zero a new encoder zero is refused (the restarted turn count would be a motor
    // turn out)...
    let rezeroed = DeviceConfig {
        encoder_zero_raw: 200,
        ..MOTOR_SHAFT
    };
    assert_eq!(set_config(&mut t, rezeroed), Err(ErrorCode::NotAtZero));
    match t.request(&Request::GetConfig) {
        Response::Config(report) => assert_eq!(report.config, MOTOR_SHAFT),
        other => panic!("{other:?}"),
    }
    // ...and taken at zero: the count restarts on the new zero, 200 counts of the motor shaft
    // (200/16384 × 360°/21 of hub angle) away, with the hub where it stands.
    reset(&mut t).unwrap();
    let before_deg = status(&mut t).angle_deg;
    assert_eq!(set_config(&mut t, rezeroed), Ok(()));
    let shift_deg = 200.0 / 16384.0 * 360.0 / 21.0;
    let after_deg = status(&mut t).angle_deg;
    assert!(
        (after_deg - (before_deg - shift_deg)).abs() < 0.05,
        "{before_deg} → {after_deg}, expected a shift of {shift_deg}"
    );
}

#[test]
fn after_power_up_a_motor_shaft_encoder_runs_only_once_the_hub_is_confirmed_at_its_mark() {
    let turn_deg = 360.0 / 21.0;
    let mut t = motor_shaft_twin(33);
    measure_right(&mut t);
    // The power goes with the hub in `Done`, well past half a motor turn from zero: the count
    // comes up a whole number of motor turns out.
    let hub_deg = t.plant().hub_cw_deg();
    assert!(hub_deg > turn_deg, "{hub_deg}");
    t.reboot();
    t.advance_ticks(20);
    let s = status(&mut t);
    assert!(s.conditions.contains(Conditions::HUB_TURN_UNKNOWN), "{s:?}");
    let off_turns = (hub_deg - f64::from(s.angle_deg)) / turn_deg;
    assert!(
        off_turns.round() >= 1.0 && (off_turns - off_turns.round()).abs() < 0.05,
        "reads {}° with the hub at {hub_deg}°",
        s.angle_deg
    );
    // A run is refused as such...
    assert_eq!(
        t.request(&Request::Run(RunParams::DEFAULT)),
        Response::Error(ErrorCode::Blocked(Conditions::HUB_TURN_UNKNOWN))
    );
    // ...while a reset is not, and shows what a run would have started from: the count's zero,
    // whole motor turns off the mark.
    reset(&mut t).unwrap();
    let false_zero_turns = t.plant().hub_cw_deg() / turn_deg;
    assert!(
        false_zero_turns.round() >= 1.0
            && (false_zero_turns - false_zero_turns.round()).abs() < 0.05,
        "{false_zero_turns}"
    );
    // The user turns the hub to its mark (a little off) and confirms: the count restarts there,
    // the condition goes, and after a reset the next gauge reads right.
    t.turn_hub_by_hand(2.0);
    assert_eq!(t.request(&Request::ConfirmHubAtZero), Response::Ok);
    t.advance_ticks(20);
    let s = status(&mut t);
    assert!(s.conditions.is_empty(), "{s:?}");
    assert!((s.angle_deg - 2.0).abs() < 0.2, "{}", s.angle_deg);
    reset_to_the_mark_and_measure_right(&mut t);
}

#[test]
fn a_twin_made_with_its_encoder_on_the_motor_shaft_comes_up_waiting_for_the_confirmation() {
    let mut t = Twin::new(TwinOptions {
        encoder_on_motor_shaft: true,
        ..TwinOptions::default()
    });
    t.advance_ticks(20);
    assert!(
        status(&mut t)
            .conditions
            .contains(Conditions::HUB_TURN_UNKNOWN)
    );
    match t.request(&Request::GetConfig) {
        Response::Config(report) => {
            assert_eq!(report.config, MOTOR_SHAFT);
            assert!(report.saved && !report.defaults_in_use, "{report:?}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(t.request(&Request::ConfirmHubAtZero), Response::Ok);
    t.advance_ticks(20);
    measure_right(&mut t);
}

#[test]
fn an_output_shaft_encoder_needs_no_confirmation() {
    let mut t = twin(PlantParams::default(), 34);
    measure_right(&mut t);
    t.reboot();
    t.advance_ticks(20);
    assert!(status(&mut t).conditions.is_empty());
    assert_eq!(t.request(&Request::ConfirmHubAtZero), Response::Ok);
    reset(&mut t).unwrap();
    measure_right(&mut t);
}

/// `kerfmeter run --samples 3` on a weak motor: reset, run, three times; every reset must end at
/// zero (not `ResetFailed`) and every run in a result. On 9 V the runs ask for no more torque
/// than 9 V gives (the default's 0.8 N·m cap needs 11.4 V: refused with `SupplyTooLow`).
fn three_gauges(plant: PlantParams, seed: u64) {
    let params = if plant.supply_v < 11.0 {
        RunParams {
            max_torque_nm: 0.6,
            ..RunParams::DEFAULT
        }
    } else {
        RunParams::DEFAULT
    };
    let mut t = twin(plant, seed);
    for gauge in 0..3 {
        reset(&mut t).unwrap_or_else(|f| panic!("reset before gauge {gauge}: {f:?}"));
        measure(&mut t, &params).unwrap_or_else(|f| panic!("gauge {gauge}: {f:?}"));
    }
    reset(&mut t).unwrap_or_else(|f| panic!("last reset: {f:?}"));
}

#[test]
fn resets_between_gauges_succeed_with_a_hot_winding() {
    for seed in 41..44 {
        three_gauges(
            PlantParams {
                winding_temp_c: 102.0,
                ..PlantParams::default()
            },
            seed,
        );
    }
}

#[test]
fn resets_between_gauges_succeed_on_a_9_v_supply() {
    for seed in 51..54 {
        three_gauges(
            PlantParams {
                supply_v: 9.0,
                ..PlantParams::default()
            },
            seed,
        );
    }
}

#[test]
fn resets_between_gauges_succeed_with_a_hot_winding_on_a_9_v_supply() {
    three_gauges(
        PlantParams {
            supply_v: 9.0,
            winding_temp_c: 110.0,
            ..PlantParams::default()
        },
        55,
    );
}
