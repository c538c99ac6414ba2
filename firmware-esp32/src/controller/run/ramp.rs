//! Engaging through the hole play and the torque ramp to the jam, with the winding estimate
//! taken at the ramp's settles.

use kerfmeter_protocol::spiral::{kerf_step, torque_for_force_nm};
use kerfmeter_protocol::{QualityFlags, REFERENCE_SUPPLY_V};

use super::{ApproachStart, FirstSettle};
use crate::controller::winding::{ESTIMATE_TICK, MAX_STEP, MIN_DUTY, SKIP_TICKS};
use crate::controller::{
    APPROACH_FRACTION, Controller, ENGAGE_MAX_TORQUE_NM, ENGAGE_SPEED_DEG_PER_S, JAM_MIN_INSET_DEG,
    JAM_SETTLE_TICKS, JAM_SLIP_DEG, JAM_STILL_LSB, JAM_WINDOW_TICKS, MAX_TURN_SPEED_DEG_PER_S,
    PRESSING_SPEED_DEG_PER_S, State,
};

impl Controller {
    /// Fitted angle change over the regression window within the stillness band.
    pub(super) fn is_still(&self) -> bool {
        let change_over_window_deg = self.motion.slope_deg_per_tick * (JAM_WINDOW_TICKS - 1) as f32;
        self.motion.slope.is_full()
            && change_over_window_deg.abs() <= JAM_STILL_LSB * self.lsb_deg()
    }

    /// Engaging: turn slowly through the hole play.
    pub(in crate::controller) fn engage(&mut self) {
        self.torque_nm = self
            .speed_loop(ENGAGE_SPEED_DEG_PER_S, ENGAGE_MAX_TORQUE_NM, self.dt_s())
            .max(0.0);
        // No kerf has less play than a zero kerf: the prongs cannot drag the inset before this.
        if self.angle_deg >= self.run.zero_kerf_play_deg - JAM_SLIP_DEG {
            self.state = State::Ramping;
        }
    }

    /// The ramp's ceiling at the current angle, and the flag to raise if the jam is reached
    /// under it: `TORQUE_LIMITED` when `max_torque_nm` capped it, `SUPPLY_LIMITED` when full duty
    /// at the measured supply did (a supply sagging under load, `supply.rs`). The
    /// inset angle comes from one step of the kerf solve a tick, from the last tick's kerf: a
    /// full solve is four or five `asinf`s, and the hub moves at most 0.09° a tick, which the
    /// step follows to within 0.002° of the solved inset (an error of 2e-5 in the target torque).
    fn ramp_target_nm(&mut self) -> (f32, QualityFlags) {
        let step = kerf_step(
            &self.run.params.gauge,
            self.angle_deg,
            self.run.ramp_kerf_um,
        );
        self.run.ramp_kerf_um = step.kerf_um;
        let params = &self.run.params;
        let inset = step.inset_deg.max(0.0);
        let target = torque_for_force_nm(params, params.target_force_n, inset);
        let full_duty_nm = self.supply.full_duty_torque_nm(&self.config);
        if target.min(params.max_torque_nm) > full_duty_nm {
            (full_duty_nm.max(0.0), QualityFlags::SUPPLY_LIMITED)
        } else if target > params.max_torque_nm {
            (params.max_torque_nm, QualityFlags::TORQUE_LIMITED)
        } else {
            (target, QualityFlags::empty())
        }
    }

    /// Ramping: raise the torque towards the target while watching for the jam. `current_a` is
    /// this tick's motor current, for the winding's resistance while the hub settles at the jam.
    pub(in crate::controller) fn ramp(&mut self, current_a: Option<f32>) {
        let (target, limited) = self.ramp_target_nm();
        // The torque rises at the ramp rate, never above the speed loop's (so the inset turns at
        // most at the speed limit) nor above the target for the current angle.
        let dt_s = self.dt_s();
        let speed_capped = self.speed_loop(MAX_TURN_SPEED_DEG_PER_S, target, dt_s);
        let ramped = self.torque_nm + self.run.params.ramp_rate_nm_per_s * dt_s;
        self.torque_nm = ramped.min(speed_capped).clamp(0.0, target);
        if self.torque_nm <= APPROACH_FRACTION * target {
            self.run.approach = Some(ApproachStart {
                torque_nm: self.torque_nm,
                angle_deg: self.angle_deg,
                target_nm: target,
            });
        }
        if self.speed_deg_per_s() < PRESSING_SPEED_DEG_PER_S {
            let drive_v = self.drive_v();
            self.run.max_pressing_drive_v = self.run.max_pressing_drive_v.max(drive_v);
        }
        let at_target = self.torque_nm >= target * 0.999 && target > self.breakaway_torque_nm();
        let inset = self.angle_deg - self.run.zero_kerf_play_deg;
        if at_target && self.is_still() && inset >= JAM_MIN_INSET_DEG {
            self.run.still_ticks += 1;
            let drive_v = self.note_still_drive();
            if self.run.first_settle.is_none() {
                self.run.first_settle = Some(FirstSettle {
                    angle_deg: self.angle_deg,
                    drive_v,
                    torque_nm: self.torque_nm,
                });
            }
            if self.run.still_ticks == ESTIMATE_TICK {
                self.apply_winding_estimate();
            } else {
                self.winding_reading(current_a);
            }
        } else {
            self.run.still_ticks = 0;
            self.winding.clear();
        }
        if self.run.still_ticks >= JAM_SETTLE_TICKS {
            self.run.flags.insert(limited);
            self.run.hold.clear();
            self.state = State::Jammed {
                torque_nm: self.torque_nm,
                entry_deg: self.angle_deg,
            };
        }
    }

    /// [`ESTIMATE_TICK`] ticks into the jam's settle: the winding's factor from the readings so
    /// far applies from the next output on (flagging a mismatch).
    ///
    /// A factor that rose by more than [`MAX_STEP`] (the first run on a warm winding) must not
    /// step the torque up at the jam: the inset would overshoot into the self-locking spiral and
    /// stay there. The commanded torque is then lowered to what the duty already drove at the
    /// new factor, and the ramp takes it up again at its rate, through a new settle (which
    /// estimates again). A smaller rise (a run's warming, the estimate's noise) or a fall is
    /// applied as it is: the settle's remaining ticks let the hub take it before the hold, and
    /// should it move, the settle starts again. Should full duty no longer give the target torque
    /// at the new factor, the ramp's ceiling holds the torque to what it gives, and the result is
    /// flagged `SUPPLY_LIMITED`, as for a sag.
    fn apply_winding_estimate(&mut self) {
        let old = self.winding.factor();
        let concluded = self.winding.conclude(&self.config);
        self.run.winding_measured |= concluded.is_some();
        if concluded == Some(true) {
            self.run.flags.insert(QualityFlags::TORQUE_MISMATCH);
        }
        let new = self.winding.factor();
        self.supply.set_winding_factor(new);
        if new > old * (1.0 + MAX_STEP) {
            let (breakaway, per_duty) =
                (self.config.breakaway_duty, self.config.torque_per_duty_nm);
            let duty = (breakaway + self.torque_nm / per_duty) * (old / new);
            self.torque_nm = ((duty - breakaway) * per_duty).max(0.0);
        }
    }

    /// The drive voltage the last output applied, V (the reference where the supply is not
    /// measured), kept in [`Run::max_still_drive_v`](super::Run::max_still_drive_v): this tick the
    /// hub stands still at its target torque.
    pub(super) fn note_still_drive(&mut self) -> f32 {
        let drive_v = self.drive_v();
        self.run.max_still_drive_v = self.run.max_still_drive_v.max(drive_v);
        drive_v
    }

    /// The drive voltage the last output applied, V: the measured supply times its duty.
    fn drive_v(&self) -> f32 {
        self.supply.supply_v().unwrap_or(REFERENCE_SUPPLY_V) * self.applied_duty
    }

    /// A tick of the jam's settle, the hub still: past the first [`SKIP_TICKS`] and at a duty of
    /// at least [`MIN_DUTY`], the drive voltage the last output applied and the current it drew
    /// are a reading of the winding's resistance (`winding.rs`).
    pub(super) fn winding_reading(&mut self, current_a: Option<f32>) {
        if let Some(current_a) = current_a
            && self.run.still_ticks > SKIP_TICKS
            && self.applied_duty >= MIN_DUTY
        {
            let supply_v = self.supply.supply_v().unwrap_or(REFERENCE_SUPPLY_V);
            self.winding.push(supply_v * self.applied_duty, current_a);
        }
    }
}
