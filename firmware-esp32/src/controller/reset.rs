//! Reset: drive the hub back to its zero position (prongs aligned for the next gauge), clearing
//! the last result and any latched fault; `ResetFailed` when the hub does not get there in time.
//! Also what keeps a motor-shaft encoder's zero true: its settings change only at zero, and
//! after power-up a run waits for the user to confirm the hub's turn.
//!
//! # The hub's turn with the encoder on the motor shaft
//!
//! Such an encoder sees the hub only modulo one motor turn (360°/gear ratio of hub angle: 17° at
//! the reference 21:1), and its turn count starts at power-up on the motor turn nearest the
//! zero. A hub switched off away from zero (mid-run, in `Done`, turned by hand) then comes up a
//! whole number of motor turns out: a reset would align the prongs that far from the gauge's
//! holes, and a run would read the offset as kerf. No sensor on the device can tell which turn
//! it is, so it does not guess: from power-up [`Conditions::HUB_TURN_UNKNOWN`] stands and
//! refuses a run (not a reset or a self-test) until the user has turned the hub to its zero
//! mark, within half a motor turn, and sent `ConfirmHubAtZero`
//! ([`Controller::confirm_hub_at_zero`]), which restarts the count there. An output-shaft
//! encoder is absolute over the hub's turn and needs none of this.

use kerfmeter_protocol::{
    Conditions, DeviceConfig, EncoderPlacement, ErrorCode, Fault, START_TOLERANCE_DEG,
};

use crate::as5048a::EncoderSettings;

use super::wake::Woken;
use super::{
    Controller, Motion, RESET_AWAY_DEG, RESET_MAX_SPEED_DEG_PER_S, RESET_MAX_TORQUE_NM,
    RESET_RELEASE_DEG, RESET_SETTLE_TICKS, RESET_SPEED_PER_DEG, RESET_TIMEOUT_TICKS,
    RESET_TOLERANCE_DEG, State,
};

impl Controller {
    /// Whether `config` may replace the configuration in use with the hub where it stands.
    ///
    /// A change of the encoder's own settings restarts its turn counting (`hardware.rs`). An
    /// output-shaft encoder is absolute over the hub's turn, so that is harmless anywhere. A
    /// motor-shaft encoder sees the hub only modulo one motor turn (360°/gear ratio of hub angle):
    /// the restarted count takes the motor turn nearest the (new) zero, which is the true one
    /// only with the hub at zero. Such a change is therefore refused with `NotAtZero` unless the
    /// hub stands within the run's start tolerance of zero on a good encoder reading (send
    /// `Reset`, then the configuration). Changes that leave the encoder settings alone are never
    /// refused here.
    pub fn check_config_change(&self, config: &DeviceConfig) -> Result<(), ErrorCode> {
        let new = EncoderSettings::from_config(config);
        if new == EncoderSettings::from_config(&self.config)
            || new.placement == EncoderPlacement::OutputShaft
        {
            return Ok(());
        }
        let at_zero = self.have_angle
            && self.consecutive_encoder_errors == 0
            && self.angle_deg.abs() <= START_TOLERANCE_DEG;
        if at_zero {
            Ok(())
        } else {
            Err(ErrorCode::NotAtZero)
        }
    }

    /// The user says the hub stands at its zero mark, within half a motor turn
    /// (`ConfirmHubAtZero`; see the module docs): with the encoder on the motor shaft its turn
    /// count restarts at the next tick on the motor turn nearest the zero
    /// ([`Controller::encoder_epoch`]) and [`Conditions::HUB_TURN_UNKNOWN`] is cleared; until that
    /// tick has read the hub again a run is refused as `NotAtZero`. On the output shaft nothing
    /// changes. Refused (`Busy`) while the motor may be driven.
    pub fn confirm_hub_at_zero(&mut self) -> Result<(), ErrorCode> {
        if self.is_active() {
            return Err(ErrorCode::Busy);
        }
        if self.config.encoder_placement == EncoderPlacement::MotorShaft {
            self.encoder_epoch = self.encoder_epoch.wrapping_add(1);
            self.have_angle = false;
            self.conditions.set(Conditions::HUB_TURN_UNKNOWN, false);
        }
        Ok(())
    }

    /// How many times the user has confirmed the hub's turn since boot (wrapping): the encoder
    /// driver restarts its turn count when this changes, as it does for a change of its settings
    /// (`hardware.rs`).
    pub fn encoder_epoch(&self) -> u16 {
        self.encoder_epoch
    }

    /// Start driving the hub back to zero (`Reset`): clears the last result and leaves a latched
    /// fault. Refused (`Busy`) while a run, reset or self-test is in progress, and (`Blocked`)
    /// while a blocking idle condition stands.
    pub fn start_reset(&mut self) -> Result<(), ErrorCode> {
        match self.state {
            State::Idle | State::Done | State::Fault(_) => {
                self.refuse_if_blocked(Conditions::BLOCKING)?;
                self.result = None;
                self.consecutive_encoder_errors = 0;
                self.torque_nm = 0.0;
                self.motion = Motion::new();
                self.reset_limit_deg = self.angle_deg.abs() + RESET_AWAY_DEG;
                self.state = State::Waking {
                    ticks: 0,
                    then: Woken::Reset,
                };
                Ok(())
            }
            _ => Err(ErrorCode::Busy),
        }
    }

    /// One tick of the reset, `ticks` into it, the hub within the settle band for the last
    /// `settled`.
    ///
    /// The settle test has hysteresis: the hub enters the band within [`RESET_TOLERANCE_DEG`] of
    /// zero and leaves it only beyond [`RESET_RELEASE_DEG`], so that encoder noise around the
    /// tolerance's edge cannot restart the count. Inside the band the motor brakes; outside it
    /// the speed loop drives towards zero. The loop keeps its integral across the band: what it
    /// has learnt beyond `breakaway_duty` (a warm winding or a low supply gives less torque per
    /// duty, and the default calibration leaves little margin over the gearbox's friction) still
    /// holds the next time it must move the hub, instead of being rebuilt from nothing.
    pub(super) fn reset_step(&mut self, ticks: u32, settled: u32) {
        if ticks >= RESET_TIMEOUT_TICKS {
            self.latch(Fault::ResetFailed);
            return;
        }
        if self.angle_deg.abs() > self.reset_limit_deg {
            self.latch(Fault::ReverseMotion);
            return;
        }
        let band_deg = if settled > 0 {
            RESET_RELEASE_DEG
        } else {
            RESET_TOLERANCE_DEG
        };
        let settled = if self.angle_deg.abs() <= band_deg {
            self.torque_nm = 0.0;
            settled + 1
        } else {
            // Towards zero, at a speed that falls with the distance left.
            let target = (-RESET_SPEED_PER_DEG * self.angle_deg)
                .clamp(-RESET_MAX_SPEED_DEG_PER_S, RESET_MAX_SPEED_DEG_PER_S);
            self.torque_nm = self.speed_loop(target, RESET_MAX_TORQUE_NM, self.dt_s());
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
