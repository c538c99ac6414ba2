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

/// One tick as the board runs it: this tick's reading (taken as the last output was applied),
/// then this tick's output applied.
fn tick(sense: &mut MotorCurrent, reading_mv: u16, out: MotorOutput, tick: u64) -> Option<f32> {
    let a = sense.current_a(Some(reading_mv));
    sense.applied(&out, tick * PERIOD_US);
    a
}

#[test]
fn the_offset_is_learnt_only_from_a_settled_brake_and_a_plausible_reading() {
    let mut sense = MotorCurrent::new();
    // Asleep, no reading is a current or an offset, whatever its level.
    for (t, mv) in [0, 65, 120, 700].into_iter().enumerate() {
        assert_eq!(tick(&mut sense, mv, MotorOutput::SAFE, t as u64), Some(0.0));
    }
    assert_eq!(sense.offset_mv(), CURRENT_SENSE_OFFSET_MV);
    // Woken to brake at tick 10: the readings of its first OFFSET_SETTLE_TICKS are the filter
    // forgetting the sleep level (no current, no offset); then the offset, the first replacing
    // the nominal one; an implausible one ignored.
    let settled = 10 + 1 + OFFSET_SETTLE_TICKS;
    for t in 10..settled {
        assert_eq!(tick(&mut sense, 75, MotorOutput::BRAKE, t), Some(0.0));
    }
    assert_eq!(sense.offset_mv(), CURRENT_SENSE_OFFSET_MV);
    for t in settled..settled + 30 {
        let mv = if t % 3 == 0 { 0 } else { 60 };
        assert_eq!(tick(&mut sense, mv, MotorOutput::BRAKE, t), Some(0.0));
    }
    assert_eq!(sense.offset_mv(), 60.0);
    // Driving, readings are current, not offset (the first reading after the bridge starts
    // driving was taken before: it is still the braking bridge's).
    for t in 100..120 {
        tick(&mut sense, if t > 100 { 70 } else { 60 }, driving(0.5), t);
    }
    assert_eq!(sense.offset_mv(), 60.0);
    let a = sense.current_a(Some(70)).unwrap();
    assert!((a - 1.0).abs() < 1e-3, "{a}");
    // Asleep, then woken again: a fresh offset, from the new brake's readings alone.
    for t in 120..200 {
        tick(&mut sense, 66, MotorOutput::SAFE, t);
    }
    for t in 200..200 + OFFSET_WINDOW_TICKS {
        tick(&mut sense, 55, MotorOutput::BRAKE, t);
    }
    assert_eq!(sense.offset_mv(), 55.0);
}

/// An offset error divides like the reading: 10 mV is 0.5 A of D·|i| at 20 mV/A, 2.5 A at the
/// 0.2 floor (the module docs' figure), 1 A at half duty.
#[test]
fn an_offset_error_of_10_mv_reads_2_5_a_at_the_duty_floor() {
    assert_eq!(offset_error_a(10.0, 0.0), 2.5);
    assert_eq!(offset_error_a(10.0, DUTY_FLOOR), 2.5);
    assert_eq!(offset_error_a(10.0, 0.5), 1.0);
    // As the conversion reads it: the offset learnt 10 mV low, the bridge at the floor.
    let mut sense = MotorCurrent::new();
    for t in 0..OFFSET_WINDOW_TICKS {
        tick(&mut sense, 50, MotorOutput::BRAKE, t);
    }
    // (The first driving tick's reading was taken braking.)
    tick(&mut sense, 50, driving(DUTY_FLOOR), OFFSET_WINDOW_TICKS);
    for t in OFFSET_WINDOW_TICKS + 1..OFFSET_WINDOW_TICKS + 20 {
        tick(&mut sense, 60, driving(DUTY_FLOOR), t);
    }
    let a = sense.current_a(Some(60)).unwrap();
    assert!((a - 2.5).abs() < 1e-3, "{a}");
}

/// A G2 and its filtered `CS` pin: the offset `awake_mv` awake, `asleep_mv` asleep, and
/// `current_a` in the drive phase; each tick's reading taken as the output is applied, as the
/// board takes it.
struct G2Pin {
    awake_mv: f64,
    asleep_mv: f64,
    current_a: f64,
    filter: AnalogFilter,
}

impl G2Pin {
    /// The pin settled at the sleep level.
    fn asleep(awake_mv: f64, asleep_mv: f64, current_a: f64) -> Self {
        Self {
            awake_mv,
            asleep_mv,
            current_a,
            filter: AnalogFilter { y_mv: asleep_mv },
        }
    }

    /// `ticks` ticks of `out` from tick `from`: the conversion's reading at each, the output
    /// applied, the pin filtered until the next tick.
    fn hold(&mut self, sense: &mut MotorCurrent, out: MotorOutput, from: u64, ticks: u64) {
        for tick in from..from + ticks {
            sense.current_a(Some(self.filter.y_mv.round() as u16));
            sense.applied(&out, tick * PERIOD_US);
            let level_mv = if out.awake {
                self.awake_mv + f64::from(out.duty) * self.current_a * 20.0
            } else {
                self.asleep_mv
            };
            self.filter.run(level_mv, PERIOD_US);
        }
    }
}

/// The rule of issue 34: the offset is what `CS` reads awake and braking, never what it reads
/// asleep. A G2 whose sleep level sits 10 mV above its awake offset (both inside the band a
/// plausible offset may take) sleeps for a second, brakes for [`OFFSET_WINDOW_TICKS`], then
/// drives 1 A at half duty: the offset is the awake one and the current reads 1 A. (Taking every
/// idle reading for the offset, it learnt 66 mV asleep and read 0.5 A.)
#[test]
fn the_offset_is_learnt_awake_and_braking_never_asleep() {
    let mut sense = MotorCurrent::new();
    let mut pin = G2Pin::asleep(56.0, 66.0, 1.0);
    pin.hold(&mut sense, MotorOutput::SAFE, 0, 1000);
    assert_eq!(sense.offset_mv(), CURRENT_SENSE_OFFSET_MV, "asleep");
    pin.hold(&mut sense, MotorOutput::BRAKE, 1000, OFFSET_WINDOW_TICKS);
    assert!(
        (sense.offset_mv() - 56.0).abs() < 0.3,
        "{}",
        sense.offset_mv()
    );
    pin.hold(&mut sense, driving(0.5), 1000 + OFFSET_WINDOW_TICKS, 20);
    let a = sense
        .current_a(Some(pin.filter.y_mv.round() as u16))
        .unwrap();
    assert!((a - 1.0).abs() < 0.05, "{a} A");
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
    for t in 0..20 {
        sense.applied(&driving(0.1), t * PERIOD_US);
    }
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
