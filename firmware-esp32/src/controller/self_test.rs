//! The self-test, with no gauge under the prongs: encoder reads with the motor off (and the
//! magnet's field from the diagnostics), the drive direction, and an estimate of the torque
//! constant from the current drawn by a short pulse from standstill.
//!
//! "Motor off" is the driver awake and braking (duty 0): the encoder phase is also where the
//! current sense learns its offset awake, before the direction check first drives
//! (`board::current`; it lasts longer than the brake before a run,
//! [`OFFSET_WINDOW_TICKS`]).
//!
//! # The torque constant
//!
//! At standstill the winding draws i = D·V/R, so the output torque per duty at the reference
//! supply is `torque_per_amp_nm` · i / D · V_ref / V. The pulse runs at [`SELFTEST_PULSE_DUTY`]
//! from standstill (after [`SELFTEST_SETTLE_TICKS`] of braking, in which the current sense also
//! learns its offset). The motor current comes from the RC-filtered current sense divided by the
//! duty filtered alike (`board::current`), read one conversion behind: the reading of the pulse's
//! tick *j* is the filter's state at tick *j* − 1. So the first reading with the pulse in it is
//! tick 2's, and it is already right: both filters saw the same first millisecond, and the
//! filtered duty is above the conversion's floor by then (0.38 against 0.2). The
//! readings of [`PULSE_AVERAGED`] ticks are averaged, with the supply over the same ticks: enough
//! readings to average the ADC's 1 mV step (0.09 A of motor current at 60 % duty) and its noise,
//! early enough that the free hub's back-EMF has taken little of the current (some 6 % a
//! millisecond on the reference build, the same at any supply: the hub's acceleration and the
//! drive voltage both scale with it). What it took is put back from the hub's mean speed over
//! those ticks (`torque_per_amp_nm` × ω: a lower bound, as the gearbox's efficiency is not
//! known). On the twin's defaults the estimate lands at 0.88–1.04 of the configured value for 50
//! seeds at each of 9, 12 and 24 V (the twin's current sense reads 5 % high, and its ADC adds
//! 1 mV of noise; the `sense_study` example).

use kerfmeter_protocol::{
    Conditions, ErrorCode, REFERENCE_SUPPLY_V, SelfTestItem, SelfTestReport, TestOutcome,
};

use super::winding::PLAUSIBLE_FACTOR;
use super::{
    Controller, Inputs, PERIOD_US, SELFTEST_DIRECTION_MIN_DEG, SELFTEST_DIRECTION_TICKS,
    SELFTEST_DIRECTION_TORQUE_NM, SELFTEST_ENCODER_MIN_OK, SELFTEST_ENCODER_TICKS,
    SELFTEST_PULSE_DUTY, SELFTEST_PULSE_TICKS, SELFTEST_SETTLE_TICKS, SELFTEST_TORQUE_TOLERANCE,
    State,
};
use crate::board::current::OFFSET_WINDOW_TICKS;

// The encoder phase is the self-test's brake before it drives (module docs).
const _: () = assert!(SELFTEST_ENCODER_TICKS as u64 >= OFFSET_WINDOW_TICKS);

/// The phases, in order, with their working data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum SelfTestPhase {
    Encoder { ticks: u32, ok: u32 },
    Direction { ticks: u32, start_deg: f32 },
    Settle { ticks: u32 },
    Pulse { ticks: u32, sums: PulseSums },
}

const SKIPPED: SelfTestItem = SelfTestItem {
    outcome: TestOutcome::Skipped,
    value: 0.0,
};

/// A report with nothing run yet.
pub(super) const NOT_RUN: SelfTestReport = SelfTestReport {
    encoder_ok_fraction: SKIPPED,
    magnet_magnitude: SKIPPED,
    direction_deg: SKIPPED,
    torque_per_duty_nm: SKIPPED,
};

/// Pulse ticks whose current (and supply) readings are averaged: from the first reading with the
/// pulse in it (module docs).
const PULSE_AVERAGED: core::ops::RangeInclusive<u32> = 2..=6;

/// What the pulse phase gathers for the torque-constant estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PulseSums {
    /// The motor current readings of [`PULSE_AVERAGED`], summed, A.
    current_a: f32,
    /// The supply readings of the same ticks, summed, V.
    supply_v: f32,
    /// The hub angle when the pulse started, degrees (jam frame).
    start_deg: f32,
    /// How far the hub turned from the pulse's start to the last averaged tick, degrees.
    moved_deg: f32,
}

fn item(pass: bool, value: f32) -> SelfTestItem {
    SelfTestItem {
        outcome: if pass {
            TestOutcome::Pass
        } else {
            TestOutcome::Fail
        },
        value,
    }
}

impl Controller {
    /// Start the self-test (`SelfTest`); its report replaces the last one when it ends. Refused
    /// while a run, reset or self-test is in progress (`Busy`) and with a fault latched
    /// (`Faulted`).
    pub fn start_self_test(&mut self) -> Result<(), ErrorCode> {
        self.refuse_unless_ready(Conditions::BLOCKING)?;
        self.self_test = None;
        self.self_test_partial = NOT_RUN;
        self.torque_nm = 0.0;
        self.state = State::SelfTest(SelfTestPhase::Encoder { ticks: 0, ok: 0 });
        Ok(())
    }

    /// One tick of the self-test in `phase`.
    pub(super) fn self_test_step(
        &mut self,
        phase: SelfTestPhase,
        inputs: &Inputs,
        fresh: Option<f32>,
    ) {
        let mut report = self.self_test_partial;
        let next = match phase {
            SelfTestPhase::Encoder { ticks, ok } => {
                self.self_test_encoder(&mut report, ticks, ok + u32::from(fresh.is_some()))
            }
            SelfTestPhase::Direction { ticks, start_deg } => {
                self.self_test_direction(&mut report, ticks, start_deg)
            }
            SelfTestPhase::Settle { ticks } => {
                self.torque_nm = 0.0;
                if ticks + 1 < SELFTEST_SETTLE_TICKS {
                    Some(SelfTestPhase::Settle { ticks: ticks + 1 })
                } else {
                    Some(SelfTestPhase::Pulse {
                        ticks: 0,
                        sums: PulseSums {
                            current_a: 0.0,
                            supply_v: 0.0,
                            start_deg: self.angle_deg,
                            moved_deg: 0.0,
                        },
                    })
                }
            }
            SelfTestPhase::Pulse { ticks, sums } => {
                self.self_test_pulse(&mut report, ticks, sums, inputs)
            }
        };
        self.self_test_partial = report;
        match next {
            Some(phase) => self.state = State::SelfTest(phase),
            None => {
                self.self_test = Some(report);
                self.state = State::Idle;
            }
        }
    }

    /// Encoder phase, `ok` good reads in `ticks + 1` ticks; then the encoder and magnet items.
    fn self_test_encoder(
        &mut self,
        report: &mut SelfTestReport,
        ticks: u32,
        ok: u32,
    ) -> Option<SelfTestPhase> {
        self.torque_nm = 0.0;
        if ticks + 1 < SELFTEST_ENCODER_TICKS {
            return Some(SelfTestPhase::Encoder {
                ticks: ticks + 1,
                ok,
            });
        }
        let fraction = ok as f32 / SELFTEST_ENCODER_TICKS as f32;
        report.encoder_ok_fraction = item(fraction >= SELFTEST_ENCODER_MIN_OK, fraction);
        report.magnet_magnitude = match self.last_diagnostics {
            Some(d) => item(!d.marginal, f32::from(d.magnitude)),
            None => item(false, 0.0),
        };
        Some(SelfTestPhase::Direction {
            ticks: 0,
            start_deg: self.angle_deg_cw(),
        })
    }

    /// Direction phase: a clockwise torque, whatever the last gauge's sense (this checks the
    /// wiring); then the direction item.
    fn self_test_direction(
        &mut self,
        report: &mut SelfTestReport,
        ticks: u32,
        start_deg: f32,
    ) -> Option<SelfTestPhase> {
        self.torque_nm = self.jam_frame(SELFTEST_DIRECTION_TORQUE_NM);
        if ticks + 1 < SELFTEST_DIRECTION_TICKS {
            return Some(SelfTestPhase::Direction {
                ticks: ticks + 1,
                start_deg,
            });
        }
        let moved = self.jam_frame(self.angle_deg) - start_deg;
        report.direction_deg = item(moved >= SELFTEST_DIRECTION_MIN_DEG, moved);
        Some(SelfTestPhase::Settle { ticks: 0 })
    }

    /// Pulse phase: counter-clockwise, bringing the hub back, at the pulse duty; the current and
    /// supply readings of [`PULSE_AVERAGED`] summed, and the hub's motion over them; then the
    /// torque-constant item, and the self-test ends (`None`).
    fn self_test_pulse(
        &mut self,
        report: &mut SelfTestReport,
        ticks: u32,
        mut sums: PulseSums,
        inputs: &Inputs,
    ) -> Option<SelfTestPhase> {
        let torque =
            (SELFTEST_PULSE_DUTY - self.config.breakaway_duty) * self.config.torque_per_duty_nm;
        self.torque_nm = -self.jam_frame(torque);
        if PULSE_AVERAGED.contains(&ticks) {
            // The current is known here: an unknown one latched `OverCurrent` before this step
            // advanced the state. An unmeasured supply counts as the reference.
            sums.current_a += inputs.current_a.unwrap_or(0.0);
            sums.supply_v += inputs.supply_v.unwrap_or(REFERENCE_SUPPLY_V);
        }
        if ticks == *PULSE_AVERAGED.end() {
            sums.moved_deg = (self.angle_deg - sums.start_deg).abs();
        }
        if ticks + 1 < SELFTEST_PULSE_TICKS {
            return Some(SelfTestPhase::Pulse {
                ticks: ticks + 1,
                sums,
            });
        }
        let estimate = self.torque_per_duty_estimate_nm(&sums);
        let ratio = estimate / self.config.torque_per_duty_nm;
        report.torque_per_duty_nm = item(plausible_torque_ratio(ratio), estimate);
        self.torque_nm = 0.0;
        None
    }
}

/// Whether the estimate of the torque per duty, as a `ratio` of the configured one, is what a
/// healthy motor gives: the winding draws i = D·V/R, so the estimate is the configured figure
/// over the winding's resistance factor, which its temperature and the current sense's gain
/// may put anywhere in [`PLAUSIBLE_FACTOR`] (a winding at 120 °C after a job: 1.37), widened
/// by the estimate's own error ([`SELFTEST_TORQUE_TOLERANCE`]). A fixed ±30 % around the
/// configured value failed a healthy hot motor whose current sense reads low (1 / 1.37 × 0.9 =
/// 0.66). A disconnected motor (no current) or a torque constant off by half still fails.
fn plausible_torque_ratio(ratio: f32) -> bool {
    let lowest = (1.0 - SELFTEST_TORQUE_TOLERANCE) / PLAUSIBLE_FACTOR.end();
    let highest = (1.0 + SELFTEST_TORQUE_TOLERANCE) / PLAUSIBLE_FACTOR.start();
    (lowest..=highest).contains(&ratio)
}

impl Controller {
    /// The output torque per duty at the reference supply, N·m, from what the pulse gathered, at
    /// the duty the pulse drives at: the current it would draw at standstill (the mean current
    /// scaled up by the drive voltage over what the back-EMF left of it), per duty, times
    /// `torque_per_amp_nm`, scaled from the measured supply to the reference.
    ///
    /// The back-EMF is `torque_per_amp_nm` × the hub's mean speed over the averaged ticks: the
    /// motor's ke·N·ω with the gearbox's efficiency taken as 1, so a lower bound, and capped at
    /// half the drive voltage (a hub that spun that fast was not starting from standstill).
    fn torque_per_duty_estimate_nm(&self, sums: &PulseSums) -> f32 {
        let n = PULSE_AVERAGED.clone().count() as f32;
        let (current_a, supply_v) = (sums.current_a / n, (sums.supply_v / n).max(f32::EPSILON));
        let duty = self.output().duty.max(f32::EPSILON);
        let window_s = *PULSE_AVERAGED.end() as f32 * PERIOD_US as f32 * 1e-6;
        let speed_rad_per_s = sums.moved_deg.to_radians() / window_s;
        let drive_v = duty * supply_v;
        let emf_v = (self.config.torque_per_amp_nm * speed_rad_per_s).min(0.5 * drive_v);
        let standstill_a = current_a * drive_v / (drive_v - emf_v);
        self.config.torque_per_amp_nm * standstill_a / duty * REFERENCE_SUPPLY_V / supply_v
    }
}
