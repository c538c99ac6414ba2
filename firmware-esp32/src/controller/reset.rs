//! Reset: drive the hub back to its zero position (prongs aligned for the next gauge), clearing
//! the last result and any latched fault; `ResetFailed` when the hub does not get there in time.

use kerfmeter_protocol::{ErrorCode, Fault};

use super::{
    Controller, Motion, RESET_MAX_SPEED_DEG_PER_S, RESET_MAX_TORQUE_NM, RESET_SETTLE_TICKS,
    RESET_SPEED_PER_DEG, RESET_TIMEOUT_TICKS, RESET_TOLERANCE_DEG, State,
};

impl Controller {
    /// Start driving the hub back to zero (`Reset`): clears the last result and leaves a latched
    /// fault. Refused (`Busy`) while a run, reset or self-test is in progress.
    pub fn start_reset(&mut self) -> Result<(), ErrorCode> {
        match self.state {
            State::Idle | State::Done | State::Fault(_) => {
                self.result = None;
                self.consecutive_encoder_errors = 0;
                self.torque_nm = 0.0;
                self.motion = Motion::new();
                self.state = State::Resetting {
                    ticks: 0,
                    settled: 0,
                };
                Ok(())
            }
            _ => Err(ErrorCode::Busy),
        }
    }

    /// One tick of the reset, `ticks` into it, the hub within tolerance for the last `settled`.
    pub(super) fn reset_step(&mut self, ticks: u32, settled: u32) {
        if ticks >= RESET_TIMEOUT_TICKS {
            self.latch(Fault::ResetFailed);
            return;
        }
        // Within tolerance: brake and check that the hub stays there; outside, drive towards
        // zero at a speed that falls with the distance left.
        let settled = if self.angle_deg.abs() <= RESET_TOLERANCE_DEG {
            self.torque_nm = 0.0;
            self.motion.speed_integral_nm = 0.0;
            settled + 1
        } else {
            let target = (-RESET_SPEED_PER_DEG * self.angle_deg)
                .clamp(-RESET_MAX_SPEED_DEG_PER_S, RESET_MAX_SPEED_DEG_PER_S);
            self.torque_nm = self.speed_loop(target, RESET_MAX_TORQUE_NM);
            0
        };
        if settled >= RESET_SETTLE_TICKS {
            self.torque_nm = 0.0;
            self.state = State::Idle;
        } else {
            self.state = State::Resetting {
                ticks: ticks + 1,
                settled,
            };
        }
    }
}
