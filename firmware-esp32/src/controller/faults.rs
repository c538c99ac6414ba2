//! Every fault check, and latching: the first fault found in a tick is latched as
//! `Fault(reason)` and that very tick's output is the motor's safe state.
//!
//! Two checks per tick: [`Controller::check_faults`] before the state advances (the inputs
//! themselves: driver FLT, current, encoder errors and diagnostics, a late step, host silence),
//! and [`Controller::check_run_limits`] after it (the run's motion: time, overtravel, reverse
//! motion, no motion).
//!
//! Before both, [`Controller::update_conditions`] keeps the idle conditions: driver FLT, an
//! unreadable encoder and failing encoder diagnostics are conditions in every state, and only
//! while the motor may be driven does `check_faults` latch them as faults. At rest they latch
//! nothing (see the controller's docs, "Idle conditions"). A supply outside the rated range is a
//! condition judged at rest only, and never a fault (`supply.rs`).

use kerfmeter_protocol::{Conditions, Fault, QualityFlags};

use super::wake::Woken;
use super::{
    Controller, DEFAULT_HOST_TIMEOUT_MS, Inputs, MAX_CONSECUTIVE_ENCODER_ERRORS, NO_MOTION_DEG,
    NO_MOTION_TICKS, OVER_CURRENT_MEAN_TICKS, OVER_CURRENT_PEAK_FACTOR, REVERSE_TOLERANCE_DEG,
    State,
};
use crate::as5048a::DiagnosticFault;
use crate::build::CONTROL_RATE_HZ;

impl Controller {
    /// The idle conditions from this tick's inputs. FLT and the encoder's readability are known
    /// every tick; the diagnostics only on the ticks they are read, so their conditions stand
    /// until the next reading.
    pub(super) fn update_conditions(&mut self, inputs: &Inputs) {
        let at_rest = !self.is_active();
        let c = &mut self.conditions;
        c.set(Conditions::DRIVER_FAULT, inputs.driver_fault);
        c.set(
            Conditions::ENCODER_UNREADABLE,
            self.consecutive_encoder_errors >= MAX_CONSECUTIVE_ENCODER_ERRORS,
        );
        if let Some(diagnostics) = inputs.diagnostics {
            let chip = matches!(diagnostics, Err(DiagnosticFault::Chip));
            let magnet = matches!(diagnostics, Err(DiagnosticFault::Magnet));
            c.set(Conditions::ENCODER_DIAGNOSTICS, chip);
            c.set(Conditions::NO_MAGNET, magnet);
        }
        // Judged on the unloaded supply only: under load the bus sags by design (`supply.rs`).
        if at_rest {
            c.set(Conditions::SUPPLY_OUT_OF_RANGE, self.supply.out_of_range());
        }
    }

    /// Faults that stand regardless of what the controller does this tick. The idle conditions
    /// latch only while the motor may be driven.
    pub(super) fn check_faults(
        &mut self,
        now_us: u64,
        inputs: &Inputs,
        overrun: bool,
    ) -> Option<Fault> {
        if let State::Fault(_) = self.state {
            return None;
        }
        let active = self.is_active();
        if active && inputs.driver_fault {
            return Some(Fault::DriverFault);
        }
        if self.over_current(inputs.current_a) {
            return Some(Fault::OverCurrent);
        }
        if active && self.consecutive_encoder_errors >= MAX_CONSECUTIVE_ENCODER_ERRORS {
            return Some(Fault::EncoderErrors);
        }
        match inputs.diagnostics {
            Some(Err(DiagnosticFault::Chip)) if active => return Some(Fault::EncoderDiagnostics),
            Some(Err(DiagnosticFault::Magnet)) if active => return Some(Fault::Magnet),
            Some(Ok(d)) => {
                self.last_diagnostics = Some(d);
                if d.marginal && active {
                    self.run.flags.insert(QualityFlags::WEAK_MAGNET);
                }
            }
            _ => {}
        }
        if !self.is_active() {
            return None;
        }
        if overrun {
            return Some(Fault::StepOverrun);
        }
        let timeout_ms = match self.state {
            State::Resetting { .. }
            | State::SelfTest(_)
            | State::Waking {
                then: Woken::Reset, ..
            } => DEFAULT_HOST_TIMEOUT_MS,
            _ => self.run.params.host_timeout_ms,
        };
        if now_us.saturating_sub(self.last_host_us) > u64::from(timeout_ms) * 1000 {
            return Some(Fault::HostSilent);
        }
        None
    }

    /// This tick's current is over the limit: unknown (it cannot be shown to be within it), its
    /// mean over the last [`OVER_CURRENT_MEAN_TICKS`] ticks above `max_current_a`, or this one
    /// reading above [`OVER_CURRENT_PEAK_FACTOR`] times it.
    fn over_current(&mut self, current_a: Option<f32>) -> bool {
        let Some(current_a) = current_a else {
            return true;
        };
        let max_a = self.config.max_current_a;
        self.current_mean.push_over(current_a, max_a)
            || current_a > OVER_CURRENT_PEAK_FACTOR * max_a
    }

    /// Faults of the run's motion, checked after the state advanced.
    pub(super) fn check_run_limits(&mut self) -> Option<Fault> {
        if !self.state.is_run() {
            return None;
        }
        let breakaway_nm = self.breakaway_torque_nm();
        let run = &mut self.run;
        let elapsed_ms = (run.ticks + 1) * 1000 / u32::from(CONTROL_RATE_HZ);
        if elapsed_ms > run.params.max_time_ms {
            return Some(Fault::MaxRunTime);
        }
        if self.angle_deg > run.overtravel_limit_deg {
            return Some(Fault::Overtravel);
        }
        run.max_deg = run.max_deg.max(self.angle_deg);
        let backing_off = matches!(self.state, State::BackingOff { .. });
        if !backing_off && self.angle_deg < run.max_deg - REVERSE_TOLERANCE_DEG {
            return Some(Fault::ReverseMotion);
        }
        if matches!(self.state, State::Engaging | State::Ramping) {
            let moved = self.angle_deg - run.start_deg;
            if moved < NO_MOTION_DEG && self.torque_nm > breakaway_nm {
                run.no_motion_ticks += 1;
                if run.no_motion_ticks >= NO_MOTION_TICKS {
                    return Some(Fault::NoMotion);
                }
            } else {
                run.no_motion_ticks = 0;
            }
        }
        None
    }

    /// Latch `fault`: the motor is safe from this tick on, until `ClearFault` or `Reset`.
    pub(super) fn latch(&mut self, fault: Fault) {
        self.state = State::Fault(fault);
        self.torque_nm = 0.0;
    }
}

/// The last [`OVER_CURRENT_MEAN_TICKS`] motor currents, for the over-current check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct CurrentMean {
    last_a: [f32; OVER_CURRENT_MEAN_TICKS],
    next: usize,
    /// Readings since the last one above the limit: their mean cannot be above it when none
    /// of them is, so it is summed only within [`OVER_CURRENT_MEAN_TICKS`] of one (cheap on a
    /// core without an FPU, where each addition is a call).
    since_above: usize,
}

impl CurrentMean {
    /// No current yet (zeros).
    pub(super) const fn new() -> Self {
        Self {
            last_a: [0.0; OVER_CURRENT_MEAN_TICKS],
            next: 0,
            since_above: OVER_CURRENT_MEAN_TICKS,
        }
    }

    /// Add this tick's current, A: true when the mean of the last [`OVER_CURRENT_MEAN_TICKS`]
    /// is above `max_a` (their sum against N times it: no division).
    fn push_over(&mut self, current_a: f32, max_a: f32) -> bool {
        self.last_a[self.next] = current_a;
        self.next = (self.next + 1) % OVER_CURRENT_MEAN_TICKS;
        self.since_above = if current_a > max_a {
            0
        } else {
            (self.since_above + 1).min(OVER_CURRENT_MEAN_TICKS)
        };
        self.since_above < OVER_CURRENT_MEAN_TICKS
            && self.last_a.iter().sum::<f32>() > OVER_CURRENT_MEAN_TICKS as f32 * max_a
    }
}
