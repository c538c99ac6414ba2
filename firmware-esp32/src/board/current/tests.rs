//! The current-sense conversion against an exact RC filter of the G2's pulse train.

use super::*;
use kerfmeter_protocol::DeviceConfig;

/// An output driving at `duty`.
fn driving(duty: f32) -> MotorOutput {
    MotorOutput {
        duty,
        dir_high: true,
        awake: true,
    }
}

/// The analog RC filter on the `CS` pin, fed with the pulse train's mean D·i (mV above the
/// offset), integrated finely: what the ADC reads at any instant.
struct AnalogFilter {
    y_mv: f64,
}

impl AnalogFilter {
    fn run(&mut self, input_mv: f64, us: u64) {
        for _ in 0..us {
            self.y_mv += (input_mv - self.y_mv) / CS_FILTER_TAU_US as f64;
        }
    }
}

#[test]
fn the_constants_are_the_rc_filters() {
    let tau_us = CS_FILTER_OHM * CS_FILTER_NF * 1e-9 * 1e6;
    assert!((tau_us - CS_FILTER_TAU_US as f32).abs() < 1e-3, "{tau_us}");
    let decay = (-(PERIOD_US as f64) / CS_FILTER_TAU_US as f64).exp();
    assert!((f64::from(FILTER_DECAY_PER_TICK) - decay).abs() < 1e-7);
    // The filtered signal at the limit stays far inside the 0 dB range.
    assert!(f32::from(CS_ADC_MAX_MV) > CURRENT_SENSE_OFFSET_MV + 20.0 * 6.5 * 3.0);
}

/// A duty ramp with a steady current, the reading taken one conversion behind as the board
/// takes it: the current reads right from the second tick of driving on, through the ramp.
#[test]
fn the_current_reads_right_while_the_duty_ramps() {
    let current_a = 2.0;
    let mut sense = MotorCurrent::new();
    let mut analog = AnalogFilter { y_mv: 0.0 };
    let mut reading_mv = None;
    let mut duty = 0.0_f32;
    for tick in 0..60_u64 {
        let now_us = tick * PERIOD_US;
        let read = sense.current_a(reading_mv.map(|y: f64| (y + 50.0).round() as u16));
        if sense.duty_filtered() >= DUTY_FLOOR {
            let a = read.unwrap();
            // One 1 mV step of the ADC, over the filtered duty (at least 0.1 here).
            let step_a = 1.0 / 20.0 / sense.duty_filtered().max(DUTY_FLOOR);
            assert!((a - current_a).abs() <= step_a, "tick {tick}: {a} A");
        }
        duty = (duty + 0.02).min(0.9);
        sense.applied(&driving(duty), now_us);
        // The conversion starts just after the output is applied...
        reading_mv = Some(analog.y_mv);
        // ...and the pulse train at the new duty runs until the next tick.
        analog.run(f64::from(duty) * current_a as f64 * 20.0, PERIOD_US);
    }
}

#[test]
fn a_step_of_duty_reads_the_current_from_the_first_reading_after_it() {
    let mut sense = MotorCurrent::new();
    let mut analog = AnalogFilter { y_mv: 0.0 };
    let mut reading_mv = Some(0.0);
    let mut reads = Vec::new();
    for tick in 0..8_u64 {
        let read = sense.current_a(reading_mv.map(|y: f64| (y + 50.0).round() as u16));
        reads.push(read.unwrap());
        let duty = if tick >= 1 { 0.3 } else { 0.0 };
        sense.applied(&driving(duty), tick * PERIOD_US);
        reading_mv = Some(analog.y_mv);
        analog.run(f64::from(duty) * 3.0 * 20.0, PERIOD_US);
    }
    // Ticks 0–2 read what the filter saw before the step reached it: nothing. Tick 3 sees the
    // first millisecond, its filtered duty (0.19) just under the floor: low by 5 %, and an ADC
    // step. From then on, the current within half an ADC step over the filtered duty.
    assert!(reads[..3].iter().all(|&a| a == 0.0), "{reads:?}");
    assert!((reads[3] - 3.0 * 0.19 / DUTY_FLOOR).abs() < 1.0 / 20.0 / DUTY_FLOOR);
    for &a in &reads[4..] {
        assert!((a - 3.0).abs() < 0.5 / 20.0 / 0.26, "{reads:?}");
    }
}

#[test]
fn below_the_floor_the_current_reads_low_by_duty_over_floor() {
    let mut sense = MotorCurrent::new();
    for tick in 0..20 {
        sense.applied(&driving(0.05), tick * PERIOD_US);
    }
    assert!((sense.duty_filtered() - 0.05).abs() < 1e-4);
    // 1 A at 5 % duty: 1 mV above the offset, read as a quarter of it.
    let a = sense.current_a(Some(51)).unwrap();
    assert!((a - 0.25).abs() < 1e-4, "{a}");
    // A short at that duty (30 A in the drive phase) still reads above the default limit.
    let a = sense.current_a(Some(50 + 30)).unwrap();
    assert!(a > DeviceConfig::DEFAULT.max_current_a, "{a}");
}

#[test]
fn the_offset_is_learnt_only_with_the_bridge_idle_and_a_plausible_reading() {
    let mut sense = MotorCurrent::new();
    sense.applied(&MotorOutput::SAFE, 0);
    // From the very first idle reading on, an off-nominal offset reads no current.
    assert_eq!(sense.current_a(Some(65)), Some(0.0));
    for _ in 0..200 {
        sense.current_a(Some(60));
    }
    assert!(
        (sense.offset_mv() - 60.0).abs() < 0.1,
        "{}",
        sense.offset_mv()
    );
    assert!(sense.current_a(Some(60)).unwrap() < 1e-3);
    // A sense that reads 0 V asleep is not an offset.
    for _ in 0..200 {
        sense.current_a(Some(0));
    }
    assert!((sense.offset_mv() - 60.0).abs() < 0.1);
    // Driving, readings are current, not offset (the first reading after the bridge starts
    // driving was taken before: it is still the idle bridge's).
    for tick in 1..20 {
        sense.applied(&driving(0.5), tick * PERIOD_US);
        if tick > 1 {
            sense.current_a(Some(70));
        }
    }
    assert!((sense.offset_mv() - 60.0).abs() < 0.1);
    let a = sense.current_a(Some(70)).unwrap();
    assert!((a - 1.0).abs() < 1e-3, "{a}");
}

#[test]
fn no_reading_or_a_clipped_one_is_an_unknown_current() {
    let mut sense = MotorCurrent::new();
    assert_eq!(sense.current_a(Some(CS_ADC_MAX_MV)), None);
    assert!(sense.current_a(Some(CS_ADC_MAX_MV - 1)).is_some());
}

#[test]
fn asleep_the_duty_filter_decays_to_zero_even_after_a_long_gap() {
    let mut sense = MotorCurrent::new();
    for tick in 0..20 {
        sense.applied(&driving(0.8), tick * PERIOD_US);
    }
    // Asleep from tick 20; the next output comes a second later.
    sense.applied(&MotorOutput::SAFE, 20 * PERIOD_US);
    assert!((sense.duty_filtered() - 0.8).abs() < 1e-3);
    sense.applied(&MotorOutput::SAFE, 1_020 * PERIOD_US);
    assert!(sense.duty_filtered() < 1e-3, "{}", sense.duty_filtered());
    // Braking holds no duty either; one tick decays by e^-1.
    let mut sense = MotorCurrent::new();
    sense.applied(&driving(1.0), 0);
    sense.applied(&MotorOutput::BRAKE, PERIOD_US);
    sense.applied(&MotorOutput::BRAKE, 2 * PERIOD_US);
    let expected = (1.0 - FILTER_DECAY_PER_TICK) * FILTER_DECAY_PER_TICK;
    assert!((sense.duty_filtered() - expected).abs() < 1e-6);
}

#[test]
fn a_missed_reading_keeps_the_last_current_until_it_is_stale() {
    let mut sense = MotorCurrent::new();
    assert_eq!(sense.current_a(Some(150)), Some(1.0 / DUTY_FLOOR * 5.0));
    for tick in 1..=CURRENT_STALE_TICKS {
        assert_eq!(
            sense.current_a(None),
            Some(5.0 / DUTY_FLOOR),
            "missed tick {tick}"
        );
    }
    assert_eq!(sense.current_a(None), None);
    assert_eq!(sense.current_a(None), None);
    // A reading makes it known again.
    assert_eq!(sense.current_a(Some(50)), Some(0.0));
}

#[test]
fn before_any_reading_the_current_reads_zero_then_unknown() {
    let mut sense = MotorCurrent::default();
    for _ in 0..CURRENT_STALE_TICKS {
        assert_eq!(sense.current_a(None), Some(0.0));
    }
    assert_eq!(sense.current_a(None), None);
}
