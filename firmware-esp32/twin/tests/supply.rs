//! Supply-aware torque on the twin: the firmware scales the duty by the supply it measures (the
//! twin's bus, after its sag, with its sense's gain error and noise), so a run reads the same
//! kerf from 9 to 26 V; a run whose torque the supply cannot give is refused with the figures,
//! and a supply outside the rated 9–26 V (9–24 V on the reference G2 18v17) blocks a run.

mod common;
use common::measure;

use kerfmeter_protocol::{
    Conditions, ErrorCode, G2Variant, KerfResult, Request, Response, RunParams, RunState,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

/// A twin cutting `kerf_um` on a `supply_v` supply, its other parameters at their defaults; above
/// the reference G2 18v17's safe 24 V, with a G2 24v21 (the same 20 mV/A current sense, safe to
/// about 34 V).
fn twin(supply_v: f64, kerf_um: f64, seed: u64) -> Twin {
    let driver = if supply_v > f64::from(G2Variant::V18v17.supply_max_v()) {
        G2Variant::V24v21
    } else {
        G2Variant::V18v17
    };
    let mut t = Twin::new(TwinOptions {
        kerf_um,
        seed,
        plant: PlantParams {
            supply_v,
            ..PlantParams::default()
        },
        driver,
        ..TwinOptions::default()
    });
    // Long enough for the supply filter (32 ms) to settle on the idle supply. With the run's
    // 20 ms brake the engage starts 100 ms in, where it did before the brake: the runs below
    // sit near `force-sensitive`'s threshold at 24–26 V and 250 µm (seed 62 is flagged when the
    // engage starts 120 ms in, not at 100, 140 or 160 ms: noise, its error −0.6 µm either way).
    t.advance_ticks(80);
    t
}

/// The device-added error of a run at `supply_v` on kerf `kerf_um`, µm, and its result.
fn error_um(supply_v: f64, kerf_um: f64, params: &RunParams, seed: u64) -> (f64, KerfResult) {
    let mut t = twin(supply_v, kerf_um, seed);
    let k = measure(&mut t, params)
        .unwrap_or_else(|f| panic!("{supply_v} V, kerf {kerf_um} µm: {f:?}"));
    assert!(t.motor_safe());
    let truth_um = t.plant().truth_um(params);
    (f64::from(k.kerf_um) - truth_um, k)
}

/// What a 9 V supply can drive: the default run asks for up to 0.8 N·m, which needs 11.4 V.
const NINE_VOLT_RUN: RunParams = RunParams {
    max_torque_nm: 0.6,
    ..RunParams::DEFAULT
};

#[test]
fn a_run_reads_the_truth_from_12_to_26_v() {
    // Before supply-aware torque: 24 V faulted `OverCurrent` at 100 µm and read +9 µm at 250.
    for supply_v in [12.0, 24.0, 26.0] {
        for (kerf_um, seed) in [(100.0, 61), (250.0, 62)] {
            let (error, k) = error_um(supply_v, kerf_um, &RunParams::DEFAULT, seed);
            assert!(
                error.abs() < 2.0,
                "{supply_v} V, kerf {kerf_um} µm: error {error:+.2} µm ({k:?})"
            );
            assert!(k.flags.is_empty(), "{supply_v} V: {:?}", k.flags);
            assert!((k.force_at_jam_n - 55.0).abs() < 1.0, "{k:?}");
        }
    }
}

#[test]
fn a_run_the_supply_can_drive_reads_the_truth_at_9_v() {
    // Before: −3.6 µm at 250 µm (the duty took 9 V for 12 V).
    let (error, k) = error_um(9.0, 250.0, &NINE_VOLT_RUN, 63);
    assert!(error.abs() < 2.0, "error {error:+.2} µm ({k:?})");
    assert!(k.flags.is_empty(), "{:?}", k.flags);
}

#[test]
fn a_run_asking_more_torque_than_9_v_gives_is_refused_with_the_figures() {
    let mut t = twin(9.0, 100.0, 64);
    let Response::Error(ErrorCode::SupplyTooLow {
        supply_mv,
        needed_mv,
    }) = t.request(&Request::Run(RunParams::DEFAULT))
    else {
        panic!("refused for its supply")
    };
    // 9 V with the sense's 1 % gain error; 12 V × (0.04 + 0.8 / 0.88).
    assert!((8_950..9_250).contains(&supply_mv), "{supply_mv}");
    assert_eq!(needed_mv, 11_389);
    t.advance_ticks(100);
    assert!(t.motor_safe(), "the motor did not move");
    assert!(t.plant().hub_deg().abs() < 0.1, "{}", t.plant().hub_deg());
    assert_eq!(t.device().controller().run_state(), RunState::Idle);
}

#[test]
fn a_6_v_supply_is_refused_as_out_of_its_rated_range() {
    let mut t = twin(6.0, 150.0, 65);
    let Response::Error(ErrorCode::Blocked(conditions)) =
        t.request(&Request::Run(RunParams::DEFAULT))
    else {
        panic!("blocked")
    };
    assert!(
        conditions.contains(Conditions::SUPPLY_OUT_OF_RANGE),
        "{conditions:?}"
    );
    assert_eq!(
        t.request(&Request::Reset),
        Response::Error(ErrorCode::Blocked(conditions))
    );
    t.advance_ticks(100);
    assert!(t.motor_safe());
    assert_eq!(t.device().controller().run_state(), RunState::Idle);
}

#[test]
fn a_noisy_supply_sense_neither_flickers_the_condition_nor_spoils_the_reading() {
    // The sense's noise at the top of its range (0.5 V SD) on a 9 V supply, 0.36 V inside the
    // rated range as read: unfiltered, a quarter of the readings would fall outside it. The
    // filter takes the noise down to some 0.06 V, so the condition never stands.
    let mut t = Twin::new(TwinOptions {
        kerf_um: 250.0,
        seed: 66,
        plant: PlantParams {
            supply_v: 9.0,
            supply_sense_noise_v: 0.5,
            ..PlantParams::default()
        },
        ..TwinOptions::default()
    });
    t.advance_ticks(100);
    for _ in 0..1000 {
        t.advance_ticks(1);
        let conditions = t.device().controller().conditions();
        assert_eq!(
            conditions,
            Conditions::empty(),
            "{:?}",
            t.device().controller().status()
        );
    }
    let k = measure(&mut t, &NINE_VOLT_RUN).unwrap();
    let error = f64::from(k.kerf_um) - t.plant().truth_um(&NINE_VOLT_RUN);
    assert!(error.abs() < 2.0, "error {error:+.2} µm ({k:?})");
}
