//! What the firmware's ADC channels read at each control tick: the G2's current-sense (`CS`)
//! output as the chip produces it, and the motor supply through its sense divider. Each reading
//! ends as the board's own conversion would hand it to [`Hardware::tick`]: the `CS` pin's
//! millivolts, quantised to the calibrated ADC's 1 mV, which the firmware's own conversion
//! (`board::current`, inside `Hardware::tick`) turns into the motor current; the supply in volts
//! by the firmware's `board::supply`.
//!
//! The twin samples both pins at the end of each tick, just after the firmware's output was
//! applied; the board's ADC converts one of them then, for the next tick to use
//! ([`TwinAdc`](crate::adc::TwinAdc), on the firmware's own schedule: the supply one tick in
//! ten, the current sense the others).
//!
//! # Current sense
//!
//! The G2's `CS` pin follows the motor current only while the bridge drives; in the brake part
//! of each PWM period (and while the driver chops) it sits at its offset. The ADC samples it
//! once per control tick, at a phase within the PWM period that drifts by `cs_sample_drift`
//! periods per tick (the tick's timer and the PWM's are independent), starting at a phase drawn
//! from the seed. A sample in the drive phase reads |i|, one outside reads about zero. With an RC
//! filter on the pin (`cs_filter_tau_us` > 0; by default the board's 10 kΩ and 100 nF, 1 ms) the
//! sample is the filter's output: its exact
//! first-order response to the pulse train, advanced in closed form from one sample to the next
//! (a few exponentials per tick), which tends to D·|i| for a long time constant. The waveform
//! between two samples is the bridge's state after the plant's last sub-step.
//!
//! On top: the CS gain error (`cs_gain_error`) and the G2's Gaussian noise (`current_noise_a`,
//! independent from one PWM period to the next, so the RC filter averages most of it away:
//! 16 % of it is left at 1 ms), then the pin's millivolts at 20 mV/A plus the G2's offset
//! (`cs_offset_mv`), the ADC's own noise (`adc_noise_mv`, which no filter removes), clipped to
//! the ADC's 0 dB range. An injected
//! short reads [`SHORT_CURRENT_A`] in the drive phase instead of the motor current.
//!
//! While the G2 sleeps its `CS` output sits at a level of its own, `cs_sleep_delta_mv` from the
//! offset awake (Pololu documents the offset awake only). The pin sees that level through the
//! same RC filter: when the driver wakes, the reading moves from the sleep level to the offset
//! with the filter's time constant, and back when it sleeps again. The twin boots with the
//! driver asleep, its filter settled at the sleep level.
//!
//! # Supply sense
//!
//! The bus voltage at the driver (after the supply's sag) times (1 + `supply_sense_gain_error`),
//! plus Gaussian noise of `supply_sense_noise_v`, through the divider of `board::supply` (the
//! divider's capacitor averages the PWM ripple, which the plant's bus voltage already is).
//!
//! [`Hardware::tick`]: kerfmeter_firmware::hardware::Hardware::tick

use kerfmeter_firmware::board::current::{CS_ADC_MAX_MV, CURRENT_SENSE_MV_PER_A};
use kerfmeter_firmware::board::supply::{ADC_MAX_MV, SUPPLY_DIVIDER_RATIO, supply_v};
use kerfmeter_firmware::build::PWM_FREQUENCY_HZ;
use kerfmeter_firmware::controller::PERIOD_US;
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_protocol::G2Variant;

use crate::plant::{Electrical, PlantParams};

/// What the current sense reads in the drive phase while a short is injected, A.
pub const SHORT_CURRENT_A: f64 = 30.0;

/// Mixed into the seed of the sense's own random stream (its starting phase and the supply
/// noise), so that it does not reshuffle the draws of any other effect.
const SENSE_STREAM: u64 = 0x7365_6e73_6500_0000;

/// PWM periods in one control period.
const PERIODS_PER_TICK: f64 = PWM_FREQUENCY_HZ as f64 * PERIOD_US as f64 * 1e-6;

/// One tick's readings, as the board's conversions give them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensed {
    /// The current-sense pin, mV, as the calibrated ADC reads it at 0 dB.
    pub cs_mv: u16,
    /// Motor supply, V.
    pub supply_v: f32,
    /// The supply divider's pin, mV, as the calibrated ADC reads it at 11 dB (`supply_v` is
    /// what the firmware makes of it).
    pub supply_mv: u16,
}

/// The ADC's view of the `CS` pin and the supply divider.
#[derive(Debug, Clone)]
pub struct Sense {
    params: PlantParams,
    rng: Rng,
    /// PWM phase at the last sample, in periods (0..1): 0 is the start of the drive phase.
    phase: f64,
    /// When the last sample was taken, µs.
    last_us: u64,
    /// The RC filter's output at the last sample, A.
    filtered_a: f64,
    /// The part of the filter's output due to the sleep level, mV above the offset (it is
    /// linear: the drive's pulses and the sleep level add).
    sleep_mv: f64,
    /// The G2's current-sense gain, mV/A (its variant's: [`Sense::for_board`]).
    cs_mv_per_a: f64,
    /// What the ADC's calibration multiplies a `CS` reading by: 1, or
    /// [`UNCALIBRATED_ADC_GAIN`] on a chip without calibration eFuses.
    cs_adc_gain: f64,
}

/// How much higher an ESP32-C3 without ADC calibration eFuses reads the current sense: esp-hal
/// then calibrates against an assumed reference, and the reading is some 30–40 % high (issue
/// 34's review of esp-hal 1.2.2's calibration); the twin takes the middle, 35 %. Applied to the
/// 0 dB `CS` channel only: what the 11 dB supply channel does on such a chip is not known here.
pub const UNCALIBRATED_ADC_GAIN: f64 = 1.35;

impl Sense {
    /// The sense of a twin with `params`, its own random stream derived from `seed`; the first
    /// sample is taken at time 0.
    pub fn new(params: &PlantParams, seed: u64) -> Self {
        let mut rng = Rng::new(seed ^ SENSE_STREAM);
        let phase = rng.uniform();
        Self {
            params: *params,
            rng,
            phase,
            last_us: 0,
            filtered_a: 0.0,
            sleep_mv: params.cs_sleep_delta_mv,
            cs_mv_per_a: f64::from(CURRENT_SENSE_MV_PER_A),
            cs_adc_gain: 1.0,
        }
    }

    /// The same, on a board whose G2 is `driver` (its current-sense gain), with an ADC without
    /// calibration eFuses when `adc_uncalibrated` (the `CS` reads [`UNCALIBRATED_ADC_GAIN`]
    /// times what it is).
    pub fn for_board(self, driver: G2Variant, adc_uncalibrated: bool) -> Self {
        Self {
            cs_mv_per_a: f64::from(driver.cs_mv_per_a()),
            cs_adc_gain: if adc_uncalibrated {
                UNCALIBRATED_ADC_GAIN
            } else {
                1.0
            },
            ..self
        }
    }

    /// The same, with the PWM phase of the first sample set to `phase` (periods, 0..1).
    pub fn with_phase(self, phase: f64) -> Self {
        Self {
            phase: phase.rem_euclid(1.0),
            ..self
        }
    }

    /// The PWM phase of the last sample, in periods (0..1).
    pub fn phase(&self) -> f64 {
        self.phase
    }

    /// Sample both channels at `now_us`, with the bridge in state `bridge` since the last
    /// sample; `short` replaces the motor current by [`SHORT_CURRENT_A`]. The current's noise is
    /// drawn from `rng`.
    pub fn sample(
        &mut self,
        bridge: &Electrical,
        now_us: u64,
        short: bool,
        rng: &mut Rng,
    ) -> Sensed {
        let p = self.params;
        let elapsed_us = now_us.saturating_sub(self.last_us) as f64;
        self.last_us = now_us;
        let periods = elapsed_us
            * 1e-6
            * PWM_FREQUENCY_HZ as f64
            * (1.0 + p.cs_sample_drift / PERIODS_PER_TICK);
        let amp_a = if short {
            SHORT_CURRENT_A
        } else {
            bridge.cs_drive_a
        };
        let drive = bridge.drive_fraction;
        let from = self.phase;
        self.phase = (from + periods).rem_euclid(1.0);
        let cs_a = if p.cs_filter_tau_us > 0.0 {
            let tau = p.cs_filter_tau_us * 1e-6 * PWM_FREQUENCY_HZ as f64;
            self.filtered_a = filter_pulses(self.filtered_a, from, periods, amp_a, drive, tau);
            self.filtered_a
        } else if self.phase < drive {
            amp_a
        } else {
            0.0
        };
        self.sleep_mv = settle_towards(
            self.sleep_mv,
            sleep_level_mv(&p, bridge),
            elapsed_us,
            p.cs_filter_tau_us,
        );
        let cs_noise_a = p.current_noise_a * filtered_noise_share(p.cs_filter_tau_us);
        let noisy_a = cs_a * (1.0 + p.cs_gain_error) + f64::from(rng.normal()) * cs_noise_a;
        let pin_mv = p.cs_offset_mv + self.sleep_mv + self.cs_mv_per_a * noisy_a;
        let cs_mv = pin_mv * self.cs_adc_gain + f64::from(self.rng.normal()) * p.adc_noise_mv;
        let bus_v = bridge.bus_v * (1.0 + p.supply_sense_gain_error)
            + f64::from(self.rng.normal()) * p.supply_sense_noise_v;
        let supply_mv = adc_mv(bus_v / SUPPLY_DIVIDER_RATIO as f64 * 1e3, ADC_MAX_MV);
        Sensed {
            cs_mv: adc_mv(cs_mv, CS_ADC_MAX_MV),
            supply_v: supply_v(supply_mv),
            supply_mv,
        }
    }
}

/// The `CS` output's level above its awake offset with no current, mV: `cs_sleep_delta_mv`
/// while the G2 sleeps, 0 awake.
fn sleep_level_mv(p: &PlantParams, bridge: &Electrical) -> f64 {
    if bridge.asleep {
        p.cs_sleep_delta_mv
    } else {
        0.0
    }
}

/// A first-order filter of time constant `tau_us` (0: none) at `y`, fed with the steady `input`
/// for `elapsed_us`: its output then.
fn settle_towards(y: f64, input: f64, elapsed_us: f64, tau_us: f64) -> f64 {
    if tau_us <= 0.0 {
        return input;
    }
    input + (y - input) * (-elapsed_us / tau_us).exp()
}

/// What is left of the G2's current-sense noise (independent from one PWM period to the next)
/// after an RC filter of `tau_us` (0: none): √((1 − a)/(1 + a)), a = e^(−T/τ), T the PWM period.
fn filtered_noise_share(tau_us: f64) -> f64 {
    if tau_us <= 0.0 {
        return 1.0;
    }
    let a = (-1e6 / PWM_FREQUENCY_HZ as f64 / tau_us).exp();
    ((1.0 - a) / (1.0 + a)).sqrt()
}

/// The calibrated ADC's reading of `pin_mv` on its pin: whole millivolts within its range,
/// `max_mv` at the attenuation of that channel.
fn adc_mv(pin_mv: f64, max_mv: u16) -> u16 {
    pin_mv.round().clamp(0.0, f64::from(max_mv)) as u16
}

/// A first-order low-pass filter (time constant `tau`, in PWM periods) fed with the `CS` pulse
/// train (`amp_a` in the drive phase, the first `drive` of each period; 0 in the rest): its
/// output after `periods` periods from phase `from`, starting at `y`. Exact for a train that
/// stays the same meanwhile.
fn filter_pulses(y: f64, from: f64, periods: f64, amp_a: f64, drive: f64, tau: f64) -> f64 {
    let relax = |y: f64, input: f64, dt: f64| input + (y - input) * (-dt / tau).exp();
    // From phase `a` to phase `b` of one period (a ≤ b ≤ 1).
    let within = |y: f64, a: f64, b: f64| {
        let y = if a < drive {
            relax(y, amp_a, b.min(drive) - a)
        } else {
            y
        };
        if b > drive {
            relax(y, 0.0, b - a.max(drive))
        } else {
            y
        }
    };
    let end = from + periods;
    if end <= 1.0 {
        return within(y, from, end);
    }
    let y = within(y, from, 1.0);
    let rest = end - 1.0;
    let whole = rest.floor();
    // One whole period maps y to a·y + b; `whole` of them sum a geometric series.
    let a = (-1.0 / tau).exp();
    let b = amp_a * (1.0 - (-drive / tau).exp()) * (-(1.0 - drive) / tau).exp();
    let an = a.powf(whole);
    let y = an * y + b * (1.0 - an) / (1.0 - a);
    within(y, 0.0, rest - whole)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerfmeter_firmware::board::current::CURRENT_SENSE_OFFSET_MV;

    /// A bridge driving `amp_a` at `drive` duty from a 12 V bus.
    fn bridge(amp_a: f64, drive: f64) -> Electrical {
        Electrical {
            current_a: amp_a,
            bus_v: 12.0,
            drive_fraction: drive,
            cs_drive_a: amp_a,
            chopping: false,
            under_voltage: false,
            winding_temp_c: 25.0,
            asleep: false,
        }
    }

    fn exact() -> PlantParams {
        PlantParams {
            current_noise_a: 0.0,
            adc_noise_mv: 0.0,
            cs_gain_error: 0.0,
            cs_filter_tau_us: 0.0,
            supply_sense_gain_error: 0.0,
            supply_sense_noise_v: 0.0,
            cs_sleep_delta_mv: 0.0,
            ..PlantParams::default()
        }
    }

    /// The `CS` pin's reading as amps at the G2's nominal scaling.
    fn cs_a(s: Sensed) -> f32 {
        ((f32::from(s.cs_mv) - CURRENT_SENSE_OFFSET_MV) / CURRENT_SENSE_MV_PER_A).max(0.0)
    }

    /// The readings of `ticks` ticks with the bridge at `b`.
    fn readings(sense: &mut Sense, b: &Electrical, ticks: u64) -> Vec<f32> {
        let mut rng = Rng::new(1);
        (1..=ticks)
            .map(|t| cs_a(sense.sample(b, t * PERIOD_US, false, &mut rng)))
            .collect()
    }

    #[test]
    fn the_current_shows_only_when_sampled_in_the_drive_phase() {
        let p = PlantParams {
            cs_sample_drift: 0.0,
            ..exact()
        };
        let b = bridge(2.0, 0.3);
        let inside = readings(&mut Sense::new(&p, 1).with_phase(0.1), &b, 50);
        assert!(inside.iter().all(|&a| (a - 2.0).abs() < 0.05), "{inside:?}");
        let outside = readings(&mut Sense::new(&p, 1).with_phase(0.6), &b, 50);
        assert!(outside.iter().all(|&a| a == 0.0), "{outside:?}");
    }

    #[test]
    fn the_drifting_instant_sees_the_current_in_a_duty_share_of_the_ticks() {
        let p = exact();
        let b = bridge(2.0, 0.3);
        let ticks = 10_000;
        let all = readings(&mut Sense::new(&p, 7), &b, ticks);
        let seen = all.iter().filter(|&&a| a > 1.0).count() as f64 / ticks as f64;
        assert!((seen - 0.3).abs() < 0.02, "{seen}");
        assert!(all.iter().all(|&a| a == 0.0 || (a - 2.0).abs() < 0.05));
        // Consecutive samples move by the drift.
        let mut s = Sense::new(&p, 7);
        let mut rng = Rng::new(1);
        let before = s.phase();
        s.sample(&b, PERIOD_US, false, &mut rng);
        let moved = (s.phase() - before).rem_euclid(1.0);
        assert!((moved - p.cs_sample_drift).abs() < 1e-9, "{moved}");
    }

    #[test]
    fn a_long_rc_filter_reads_the_duty_times_the_current_wherever_it_samples() {
        let p = PlantParams {
            cs_filter_tau_us: 5_000.0,
            ..exact()
        };
        let b = bridge(2.0, 0.3);
        let all = readings(&mut Sense::new(&p, 3), &b, 100);
        // Settled after twenty time constants, with a ripple far below the ADC's 50 mA step.
        for &a in &all[40..] {
            assert!((a - 0.6).abs() <= 0.051, "{a}");
        }
        // A short filter follows the pulses instead.
        let p = PlantParams {
            cs_filter_tau_us: 0.5,
            cs_sample_drift: 0.0,
            ..p
        };
        let inside = readings(&mut Sense::new(&p, 3).with_phase(0.25), &b, 10);
        assert!(inside.iter().all(|&a| (a - 2.0).abs() < 0.06), "{inside:?}");
        let outside = readings(&mut Sense::new(&p, 3).with_phase(0.9), &b, 10);
        assert!(outside.iter().all(|&a| a < 0.06), "{outside:?}");
    }

    #[test]
    fn the_filter_steps_agree_with_a_fine_integration() {
        let (amp, drive, tau) = (3.0, 0.4, 2.7);
        // Euler over 10,000 steps per period, across 23.37 periods from phase 0.65.
        let steps = 10_000;
        let (mut y, mut t): (f64, f64) = (0.2, 0.65);
        for _ in 0..(23.37 * steps as f64) as usize {
            let input = if t.rem_euclid(1.0) < drive { amp } else { 0.0 };
            y += (input - y) / tau / steps as f64;
            t += 1.0 / steps as f64;
        }
        let closed = filter_pulses(0.2, 0.65, 23.37, amp, drive, tau);
        assert!((closed - y).abs() < 1e-3, "{closed} vs {y}");
    }

    /// The G2's noise, independent from period to period, is averaged by the RC filter; the
    /// ADC's own noise is not.
    #[test]
    fn the_filter_averages_the_sense_noise_but_not_the_adcs() {
        let sd_mv = |p: &PlantParams| {
            let mut sense = Sense::new(p, 5);
            let mut rng = Rng::new(2);
            let b = bridge(1.0, 0.5);
            let reads: Vec<f64> = (1..=4000)
                .map(|t| f64::from(sense.sample(&b, t * PERIOD_US, false, &mut rng).cs_mv))
                .collect();
            let mean = reads.iter().sum::<f64>() / reads.len() as f64;
            (reads.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / reads.len() as f64).sqrt()
        };
        let g2 = PlantParams {
            current_noise_a: 0.4,
            cs_filter_tau_us: 1000.0,
            cs_sample_drift: 0.0,
            ..exact()
        };
        // 0.4 A is 8 mV at the pin; 16 % of it is left (the 1 mV steps add a little).
        let filtered = sd_mv(&g2);
        assert!(
            (filtered - 8.0 * filtered_noise_share(1000.0)).abs() < 0.2,
            "{filtered}"
        );
        assert!((filtered_noise_share(1000.0) - 0.158).abs() < 1e-3);
        let unfiltered = sd_mv(&PlantParams {
            cs_filter_tau_us: 0.0,
            ..g2
        });
        assert!((unfiltered - 8.0).abs() < 0.4, "{unfiltered}");
        let adc = sd_mv(&PlantParams {
            adc_noise_mv: 2.0,
            cs_filter_tau_us: 1000.0,
            cs_sample_drift: 0.0,
            ..exact()
        });
        assert!((adc - 2.0).abs() < 0.15, "{adc}");
    }

    #[test]
    fn the_supply_reads_through_the_divider_with_its_gain_error() {
        let p = PlantParams {
            supply_sense_noise_v: 0.0,
            ..PlantParams::default()
        };
        let mut s = Sense::new(&p, 1);
        let mut b = bridge(0.0, 0.0);
        b.bus_v = 24.0;
        let v = s.sample(&b, PERIOD_US, false, &mut Rng::new(1)).supply_v;
        let expected = 24.0 * (1.0 + p.supply_sense_gain_error);
        // One ADC step is 13 mV at the bus.
        assert!((f64::from(v) - expected).abs() < 0.01, "{v} vs {expected}");
        // Its noise has the SD asked for.
        let noisy = PlantParams::default();
        let mut s = Sense::new(&noisy, 1);
        let reads: Vec<f64> = (1..=2000)
            .map(|t| {
                f64::from(
                    s.sample(&b, t * PERIOD_US, false, &mut Rng::new(1))
                        .supply_v,
                )
            })
            .collect();
        let mean = reads.iter().sum::<f64>() / reads.len() as f64;
        let sd =
            (reads.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / reads.len() as f64).sqrt();
        assert!((sd - noisy.supply_sense_noise_v).abs() < 0.01, "{sd}");
    }

    /// Asleep, `CS` reads its sleep level; woken (braking: no current to show), it settles to
    /// the offset through the RC filter, by e^−1 a millisecond, and back when it sleeps again.
    #[test]
    fn cs_reads_its_sleep_level_asleep_and_settles_to_the_offset_awake() {
        let p = PlantParams {
            cs_sleep_delta_mv: 20.0,
            cs_filter_tau_us: 1000.0,
            ..exact()
        };
        let mut s = Sense::new(&p, 1);
        let mut rng = Rng::new(1);
        let braking = bridge(0.0, 0.0);
        let asleep = Electrical {
            asleep: true,
            ..braking
        };
        let mut read = |b: &Electrical, tick: u64| s.sample(b, tick * PERIOD_US, false, &mut rng);
        // Booted asleep, the filter settled at the sleep level.
        assert_eq!(read(&asleep, 1).cs_mv, 70);
        let awake: Vec<u16> = (2..=6).map(|t| read(&braking, t).cs_mv).collect();
        // 50 + 20·e^−k, rounded to the ADC's 1 mV.
        assert_eq!(awake, [57, 53, 51, 50, 50]);
        // Asleep again: 50 + 20·(1 − e^−1).
        assert_eq!(read(&asleep, 7).cs_mv, 63);
        // Without the filter the level steps at once: here an output that is off asleep.
        let p = PlantParams {
            cs_sleep_delta_mv: -50.0,
            ..exact()
        };
        let mut s = Sense::new(&p, 1);
        assert_eq!(s.sample(&asleep, PERIOD_US, false, &mut rng).cs_mv, 0);
        assert_eq!(s.sample(&braking, 2 * PERIOD_US, false, &mut rng).cs_mv, 50);
    }

    #[test]
    fn a_short_reads_high_in_the_drive_phase_only() {
        let p = PlantParams {
            cs_sample_drift: 0.0,
            ..exact()
        };
        let b = bridge(0.5, 0.4);
        let mut rng = Rng::new(1);
        let mut inside = Sense::new(&p, 1).with_phase(0.2);
        let a = cs_a(inside.sample(&b, PERIOD_US, true, &mut rng));
        assert!((f64::from(a) - SHORT_CURRENT_A).abs() < 0.1, "{a}");
        let mut outside = Sense::new(&p, 1).with_phase(0.7);
        assert_eq!(cs_a(outside.sample(&b, PERIOD_US, true, &mut rng)), 0.0);
    }
}
