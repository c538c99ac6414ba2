//! The sweep's own cases: draws repeatable and within their ranges, classification, the summary.

use kerfmeter_protocol::{DeviceConfig, Fault, KerfResult, QualityFlags};

use super::*;
use crate::plant::{PlantParamError, PlantParams, param};
use crate::study::{Outcome, Phase};

#[test]
fn every_drawn_parameter_is_within_its_range_and_consistent() {
    for index in 0..50 {
        let draw = Draw::new(7, index);
        assert_eq!(draw.plant.validate(), Ok(()));
        assert_eq!(draw.options().validate(), Ok(()));
        assert!((KERF_RANGE_UM.0..=KERF_RANGE_UM.1).contains(&draw.kerf_um));
        assert!((KERF_SD_RANGE_UM.0..=KERF_SD_RANGE_UM.1).contains(&draw.kerf_sd_um));
    }
}

#[test]
fn draws_are_deterministic_for_a_seed_and_differ_between_draws_and_seeds() {
    assert_eq!(Draw::new(3, 4), Draw::new(3, 4));
    assert_ne!(Draw::new(3, 4).plant, Draw::new(3, 5).plant);
    assert_ne!(Draw::new(3, 4).plant, Draw::new(4, 4).plant);
    assert_ne!(Draw::new(3, 4).twin_seed, Draw::new(3, 5).twin_seed);
}

#[test]
fn a_held_parameter_is_the_same_in_every_draw_and_moves_no_other() {
    let mut sweep = Sweep::new(3);
    sweep.fix("supply_v", 24.0).unwrap();
    for index in 0..20 {
        let (held, free) = (sweep.draw(index), Draw::new(3, index));
        assert_eq!(held.plant.supply_v, 24.0);
        assert_eq!(held.kerf_um, free.kerf_um);
        assert_eq!(held.plant.gear_ratio, free.plant.gear_ratio);
        assert_eq!(held.plant.validate(), Ok(()));
    }
    // The last value given wins; a value out of range or an unknown name is refused.
    sweep.fix("supply_v", 9.0).unwrap();
    assert_eq!(sweep.draw(0).plant.supply_v, 9.0);
    assert_eq!(sweep.fixed.len(), 1);
    assert!(matches!(
        sweep.fix("supply_v", 40.0),
        Err(PlantParamError::OutOfRange { .. })
    ));
    assert!(matches!(
        sweep.fix("supply_volts", 12.0),
        Err(PlantParamError::Unknown(_))
    ));
}

#[test]
fn a_held_friction_brings_its_partner_and_a_held_winding_temperature_stays() {
    let mut sweep = Sweep::new(5);
    // Above most static frictions drawn: each is raised to it, none is drawn in vain.
    sweep.fix("gear_kinetic_nm", 0.079).unwrap();
    sweep.fix("inset_static_nm", 0.0011).unwrap();
    sweep.fix("winding_temp_c", 120.0).unwrap();
    for index in 0..30 {
        let plant = sweep.draw(index).plant;
        assert_eq!(plant.validate(), Ok(()));
        assert!(plant.gear_static_nm >= 0.079, "{}", plant.gear_static_nm);
        assert!(
            plant.inset_kinetic_nm <= 0.0011,
            "{}",
            plant.inset_kinetic_nm
        );
        assert_eq!(plant.winding_temp_c, 120.0);
    }
    // A pair that cannot agree is refused, and the earlier holds stand.
    assert!(matches!(
        sweep.fix("gear_static_nm", 0.05),
        Err(PlantParamError::Inconsistent(_))
    ));
    assert!(matches!(
        sweep.fix("inset_kinetic_nm", 0.02),
        Err(PlantParamError::Inconsistent(_))
    ));
    assert_eq!(sweep.fixed.len(), 3);
}

#[test]
fn wide_positive_ranges_are_log_uniform_and_the_rest_uniform() {
    let stiffness = param("contact_stiffness_n_per_um").unwrap();
    assert_eq!(scale(stiffness), Scale::LogUniform);
    assert_eq!(scale(param("supply_v").unwrap()), Scale::Uniform);
    // A range from 0 cannot be log-uniform.
    assert_eq!(scale(param("cs_filter_tau_us").unwrap()), Scale::Uniform);
    // Log-uniform: the geometric middle at the middle of the fraction.
    let middle = value_at(stiffness, 0.5);
    assert!((middle - (1.0f64 * 500.0).sqrt()).abs() < 1e-9, "{middle}");
    assert_eq!(value_at(stiffness, 0.0), 1.0);
    assert!((fraction_of(stiffness, middle) - 0.5).abs() < 1e-12);
    // Over many draws each decade of 1–500 N/µm is about equally likely.
    let below_10 = (0..400)
        .filter(|&i| Draw::new(11, i).plant.contact_stiffness_n_per_um < 10.0)
        .count();
    let expected = 400.0 * 10f64.ln() / 500f64.ln();
    assert!(
        (below_10 as f64 - expected).abs() < 40.0,
        "{below_10} of 400 below 10 N/µm, expected about {expected:.0}"
    );
    let supply_below_17 = (0..400)
        .filter(|&i| Draw::new(11, i).plant.supply_v < 17.0)
        .count();
    assert!(
        (160..=240).contains(&supply_below_17),
        "{supply_below_17} of 400 supplies below the middle of 6–28 V"
    );
}

fn reading(kerf_um: f32, truth_um: f64, flags: QualityFlags) -> Outcome {
    Outcome::Reading {
        result: KerfResult {
            run_id: 1,
            kerf_um,
            angle_deg: 60.0,
            play_deg: 4.5,
            torque_at_jam_nm: 0.5,
            force_at_jam_n: 55.0,
            flags,
        },
        truth_um,
    }
}

#[test]
fn the_boot_temperature_is_held_to_what_the_build_can_reach() {
    // The reference build stalled at 0.8 N·m draws 5 A: hundreds of degrees of rise, so
    // any drawn temperature above the enclosure's stands, and one below it is raised to it.
    let hot = PlantParams {
        winding_temp_c: 110.0,
        ambient_temp_c: 20.0,
        ..PlantParams::default()
    };
    assert_eq!(reachable_winding_temp_c(&hot), 110.0);
    let cold = PlantParams {
        winding_temp_c: 5.0,
        ..hot
    };
    assert_eq!(reachable_winding_temp_c(&cold), 20.0);
    // A 95:1 gearbox draws 1.1 A at the cap, 3.7 W in the hot winding: 11 °C above the
    // enclosure at 3 °C/W.
    let geared = PlantParams {
        gear_ratio: 95.0,
        winding_thermal_res_c_per_w: 3.0,
        ..hot
    };
    let t = reachable_winding_temp_c(&geared);
    assert!((30.0..32.0).contains(&t), "{t}");
    // Every draw is within its range and the rule.
    for index in 0..50 {
        let plant = Draw::new(5, index).plant;
        assert_eq!(reachable_winding_temp_c(&plant), plant.winding_temp_c);
    }
}

#[test]
fn the_default_build_is_configured_as_the_device_defaults() {
    let config = device_config(&PlantParams::default());
    let defaults = DeviceConfig::DEFAULT;
    let close = |a: f32, b: f32| (a - b).abs() <= 0.002 * b.abs().max(1.0);
    assert!(
        close(config.torque_per_duty_nm, defaults.torque_per_duty_nm),
        "{config:?}"
    );
    assert!(
        close(config.breakaway_duty, defaults.breakaway_duty),
        "{config:?}"
    );
    assert!(close(config.gear_ratio, defaults.gear_ratio), "{config:?}");
    assert!(
        close(config.max_current_a, defaults.max_current_a),
        "{config:?}"
    );
    assert!(
        close(config.torque_per_amp_nm, defaults.torque_per_amp_nm),
        "{config:?}"
    );
    for index in 0..50 {
        assert_eq!(device_config(&Draw::new(5, index).plant).validate(), Ok(()));
    }
    let geared = PlantParams {
        gear_ratio: 42.0,
        ..PlantParams::default()
    };
    assert!(close(device_config(&geared).torque_per_duty_nm, 1.76));
}

#[test]
fn endings_are_classified_by_error_flag_and_type() {
    let none = QualityFlags::empty();
    assert_eq!(classify(&reading(152.0, 150.0, none), 5.0), Class::Correct);
    assert_eq!(
        classify(&reading(157.0, 150.0, none), 5.0),
        Class::UnflaggedWrong
    );
    assert_eq!(
        classify(&reading(143.0, 150.0, none), 5.0),
        Class::UnflaggedWrong
    );
    let limited = QualityFlags::TORQUE_LIMITED;
    assert_eq!(
        classify(&reading(170.0, 150.0, limited), 5.0),
        Class::Flagged
    );
    // A decimated curve does not excuse a wrong number.
    assert_eq!(
        classify(&reading(170.0, 150.0, QualityFlags::DECIMATED), 5.0),
        Class::UnflaggedWrong
    );
    let fault = Outcome::Fault {
        phase: Phase::Run,
        fault: Fault::OverCurrent,
    };
    assert_eq!(classify(&fault, 5.0), Class::Fault);
    assert_eq!(
        failure_name(&fault).as_deref(),
        Some("fault OverCurrent (run)")
    );
    assert_eq!(classify(&Outcome::Panic("x".into()), 5.0), Class::Panic);
    assert!(!Class::Panic.ends_properly());
    assert!(Class::UnflaggedWrong.ends_properly());
}

#[test]
fn a_summary_counts_classes_errors_and_the_worst_first() {
    let report = |index, outcome, safe| DrawReport {
        draw: Draw::new(1, index),
        outcome,
        motor_safe: Some(safe),
        sim_ms: 0,
    };
    let none = QualityFlags::empty();
    let reports = [
        report(0, reading(151.0, 150.0, none), true),
        report(1, reading(140.0, 150.0, none), true),
        report(
            2,
            Outcome::Refused {
                phase: Phase::Run,
                code: kerfmeter_protocol::ErrorCode::NotAtZero,
            },
            true,
        ),
        report(3, reading(153.0, 150.0, QualityFlags::NOISY_HOLD), true),
    ];
    let summary = Summary::of(&reports, 5.0);
    assert_eq!(summary.readings(), 3);
    assert_eq!(summary.of_class(Class::UnflaggedWrong), &[1]);
    assert_eq!(summary.of_class(Class::Correct), &[0]);
    assert_eq!(summary.worst, vec![1, 3, 0]);
    assert_eq!(summary.unflagged_readings.n, 2);
    assert_eq!(summary.all_readings.max_abs_um, 10.0);
    assert_eq!(
        summary.failures.keys().collect::<Vec<_>>(),
        ["refused NotAtZero (run)"]
    );
    assert!(summary.all_ended_safely());
    let unsafe_motor = Summary::of(&[report(0, reading(151.0, 150.0, none), false)], 5.0);
    assert!(!unsafe_motor.all_ended_safely());
}

#[test]
fn a_draw_runs_to_an_ending_with_the_motor_safe() {
    let report = run_draw(&Draw::new(1, 0));
    assert!(
        classify(&report.outcome, TOLERANCE_UM).ends_properly(),
        "{report:?}"
    );
    assert_eq!(report.motor_safe, Some(true));
    assert_eq!(report, run_draw(&Draw::new(1, 0)), "deterministic");
}
