//! Every fault check, and latching: the first fault found in a tick is latched as
//! `Fault(reason)` and that very tick's output is the motor's safe state.
//!
//! Two checks per tick: [`Controller::check_faults`] before the state advances (the inputs
//! themselves: driver FLT, current, encoder errors and diagnostics, a late step, host silence),
//! and [`Controller::check_run_limits`] after it (the run's motion: time, overtravel, reverse
//! motion, no motion).

use kerfmeter_protocol::{Fault, QualityFlags};

use super::{
    Controller, DEFAULT_HOST_TIMEOUT_MS, Inputs, MAX_CONSECUTIVE_ENCODER_ERRORS, NO_MOTION_DEG,
    NO_MOTION_TICKS, REVERSE_TOLERANCE_DEG, State,
};
use crate::as5048a::DiagnosticFault;
use crate::build::CONTROL_RATE_HZ;

impl Controller {
    /// Faults that stand regardless of what the controller does this tick.
    pub(super) fn check_faults(
        &mut self,
        now_us: u64,
        inputs: &Inputs,
        overrun: bool,
    ) -> Option<Fault> {
        if let State::Fault(_) = self.state {
            return None;
        }
        if inputs.driver_fault {
            return Some(Fault::DriverFault);
        }
        // An unknown current cannot be shown to be within the limit.
        if inputs
            .current_a
            .is_none_or(|current_a| current_a > self.config.max_current_a)
        {
            return Some(Fault::OverCurrent);
        }
        if self.consecutive_encoder_errors >= MAX_CONSECUTIVE_ENCODER_ERRORS {
            return Some(Fault::EncoderErrors);
        }
        match inputs.diagnostics {
            Some(Err(DiagnosticFault::Chip)) => return Some(Fault::EncoderDiagnostics),
            Some(Err(DiagnosticFault::Magnet)) => return Some(Fault::Magnet),
            Some(Ok(d)) => {
                self.last_diagnostics = Some(d);
                if d.marginal && self.is_active() {
                    self.run.flags.insert(QualityFlags::WEAK_MAGNET);
                }
            }
            None => {}
        }
        if !self.is_active() {
            return None;
        }
        if overrun {
            return Some(Fault::StepOverrun);
        }
        let timeout_ms = match self.state {
            State::Resetting { .. } | State::SelfTest(_) => DEFAULT_HOST_TIMEOUT_MS,
            _ => self.run.params.host_timeout_ms,
        };
        if now_us.saturating_sub(self.last_host_us) > u64::from(timeout_ms) * 1000 {
            return Some(Fault::HostSilent);
        }
        None
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
        if self.angle_deg < run.max_deg - REVERSE_TOLERANCE_DEG {
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
