//! The release, and the back-off after it that measures the hole play.
//!
//! # Measured play
//!
//! The hub angle at the jam includes the prongs' play in their holes, which the spiral's model
//! gives as θplay(k) = 2·asin((r_h − r_p + k/2)/(2R)) for prongs centred in holes cut where they
//! were drawn. A real cut differs: the head comes back over the gauge off its centre by its
//! repeatability, which shortens the play both ways by |d_t|/R; the holes are cut off place; a
//! tapered kerf leaves them narrowest where the prongs bear; a prong is off its nominal radius.
//! On the twin these made the model's play up to 1.5° (4 µm of kerf) too long, and its readings
//! 0.9 µm low on average across the robustness sweep.
//!
//! So after the release the hub is turned back ([`Controller::back_off`]): the self-locking
//! spiral holds the inset where the jam left it, and the hub turns freely through both sides of
//! the play until the prongs stall on the holes' far faces. Half that turn is the forward play
//! to first order whatever the head's offset (it shortens both sides alike); what is left is
//! the holes' common displacement along the spiral, (δ₀ + δ₁)/(2R). The pull is capped at
//! [`BACK_OFF_MAX_TORQUE_NM`] over the gearbox's breakaway (which the duty already covers), so
//! a hub the gearbox alone holds does not stand still at the cap; a stall counts only at the cap
//! and after [`BACK_OFF_MIN_TURN_DEG`], and the turn is counted from where the hub came to rest
//! after the release ([`BACK_OFF_SETTLE_TICKS`]). A play more than [`BACK_OFF_MAX_SHORTER_DEG`]
//! shorter or [`BACK_OFF_MAX_LONGER_DEG`] longer than the model's, a hub that never stalls (an
//! inset that gives way: the reading is already taken), and no back-off at all (a hold under
//! [`BACK_OFF_MIN_HELD_RATIO`] times the pull's cap, an encoder on the motor shaft, a run
//! without the time for it: [`Controller::may_back_off`]) leave the model's play, flagged
//! `PLAY_MODELLED`. The back-off is reported as `Releasing` and is not in the sweep; the result
//! is not published until the run has ended; its `play_deg` is the play it was read with, and
//! the host reads the sweep at other forces with it.

use kerfmeter_protocol::spiral::{force_for_torque_n, kerf_for_inset_um};
use kerfmeter_protocol::{EncoderPlacement, QualityFlags};

use crate::build::CONTROL_RATE_HZ;
use crate::controller::{
    BACK_OFF_MAX_LONGER_DEG, BACK_OFF_MAX_SHORTER_DEG, BACK_OFF_MAX_TICKS, BACK_OFF_MAX_TORQUE_NM,
    BACK_OFF_MIN_HELD_RATIO, BACK_OFF_MIN_TURN_DEG, BACK_OFF_RESERVE_MS, BACK_OFF_SETTLE_TICKS,
    BACK_OFF_SPEED_DEG_PER_S, BACK_OFF_STALL_SHARE, BACK_OFF_STILL_TICKS, Controller,
    RELEASE_RATE_NM_PER_S, State,
};

impl Controller {
    /// Releasing: ramp the torque down, then back off to measure the play
    /// ([`Controller::back_off`]) where [`Controller::may_back_off`], else `Done`.
    pub(in crate::controller) fn release(&mut self) {
        if let Some(held) = self.run.held.take() {
            self.finish(held);
        }
        self.torque_nm = (self.torque_nm - RELEASE_RATE_NM_PER_S * self.dt_s()).max(0.0);
        if self.torque_nm > 0.0 {
            return;
        }
        self.state = if self.may_back_off() {
            State::BackingOff {
                from_deg: None,
                ticks: 0,
                still: 0,
            }
        } else {
            State::Done
        };
    }

    /// Whether the play may be measured by backing off: a result to read with it, a hold at
    /// least [`BACK_OFF_MIN_HELD_RATIO`] times the pull's cap (a lighter one could be pulled out
    /// of the jam), an encoder on the output shaft (on the motor's, the turn would carry the
    /// gearbox's backlash), and the run's time left for the longest back-off.
    fn may_back_off(&self) -> bool {
        let Some(result) = self.result else {
            return false;
        };
        let back_off_ms = BACK_OFF_MAX_TICKS * 1000 / u32::from(CONTROL_RATE_HZ);
        let time_left =
            self.elapsed_ms() + back_off_ms + BACK_OFF_RESERVE_MS <= self.run.params.max_time_ms;
        let firm = result.torque_at_jam_nm >= BACK_OFF_MIN_HELD_RATIO * BACK_OFF_MAX_TORQUE_NM;
        let on_output = self.config.encoder_placement == EncoderPlacement::OutputShaft;
        time_left && firm && on_output
    }

    /// Backing off: once the hub stands still after the release ([`BACK_OFF_SETTLE_TICKS`]),
    /// turn it back through the hole play, the inset held by the self-locking spiral, until the
    /// prongs stall on the holes' far faces; half that turn is the play the reading includes
    /// (module docs, "Measured play"). Ends in `Done`, with the play measured, or left to the
    /// model's where the hub never stalled within [`BACK_OFF_MAX_TICKS`], turned past the
    /// longest play it may find (an inset that gave way), or stalled outside the window.
    pub(in crate::controller) fn back_off(
        &mut self,
        from_deg: Option<f32>,
        ticks: u32,
        still: u32,
    ) {
        let Some(from_deg) = from_deg else {
            self.settle_before_back_off(ticks, still);
            return;
        };
        let dt_s = self.dt_s();
        self.torque_nm = self
            .speed_loop(-BACK_OFF_SPEED_DEG_PER_S, BACK_OFF_MAX_TORQUE_NM, dt_s)
            .min(0.0);
        // The loop's output is held to pulling: so is its memory (no wind-up towards pushing).
        self.motion.speed_integral_nm = self.motion.speed_integral_nm.min(0.0);
        let turned_deg = from_deg - self.angle_deg;
        let stalled = turned_deg > BACK_OFF_MIN_TURN_DEG
            && self.torque_nm <= -BACK_OFF_STALL_SHARE * BACK_OFF_MAX_TORQUE_NM
            && self.is_still();
        let still = if stalled { still + 1 } else { 0 };
        let model_play_deg = self.result.map_or(0.0, |r| r.play_deg);
        let too_far =
            turned_deg > 2.0 * (model_play_deg + BACK_OFF_MAX_LONGER_DEG) + BACK_OFF_MIN_TURN_DEG;
        if still >= BACK_OFF_STILL_TICKS {
            self.apply_measured_play(turned_deg / 2.0);
        }
        self.state = if still >= BACK_OFF_STILL_TICKS || too_far || ticks >= BACK_OFF_MAX_TICKS {
            self.torque_nm = 0.0;
            State::Done
        } else {
            State::BackingOff {
                from_deg: Some(from_deg),
                ticks: ticks + 1,
                still,
            }
        };
    }

    /// Before backing off: no torque until the hub has stood still [`BACK_OFF_SETTLE_TICKS`]
    /// in a row, then the back-off's start is where it stands.
    fn settle_before_back_off(&mut self, ticks: u32, still: u32) {
        self.torque_nm = 0.0;
        let still = if self.is_still() { still + 1 } else { 0 };
        self.state = if ticks >= BACK_OFF_MAX_TICKS {
            State::Done
        } else if still >= BACK_OFF_SETTLE_TICKS {
            self.motion.speed_integral_nm = 0.0;
            State::BackingOff {
                from_deg: Some(self.angle_deg),
                ticks: ticks + 1,
                still: 0,
            }
        } else {
            State::BackingOff {
                from_deg: None,
                ticks: ticks + 1,
                still,
            }
        };
    }

    /// The result read with the hole play measured as `play_deg` instead of the model's, where
    /// it is within [`BACK_OFF_MAX_SHORTER_DEG`] shorter or [`BACK_OFF_MAX_LONGER_DEG`] longer:
    /// kerf, play, force and the near-disengage flag follow the inset angle it gives, and the
    /// result is no longer `PLAY_MODELLED` (nor `PLAY_NOT_CONVERGED`).
    fn apply_measured_play(&mut self, play_deg: f32) {
        let Some(mut result) = self.result else {
            return;
        };
        let longer_deg = play_deg - result.play_deg;
        if !(-BACK_OFF_MAX_SHORTER_DEG..=BACK_OFF_MAX_LONGER_DEG).contains(&longer_deg) {
            return;
        }
        let params = &self.run.params;
        let inset_deg = result.angle_deg - play_deg;
        result.kerf_um = kerf_for_inset_um(&params.gauge, inset_deg);
        result.play_deg = play_deg;
        result.force_at_jam_n = force_for_torque_n(params, result.torque_at_jam_nm, inset_deg);
        result.flags.remove(QualityFlags::NEAR_DISENGAGE);
        result.flags.remove(QualityFlags::PLAY_MODELLED);
        result.flags.remove(QualityFlags::PLAY_NOT_CONVERGED);
        if self.near_disengage(inset_deg) {
            result.flags.insert(QualityFlags::NEAR_DISENGAGE);
        }
        self.result = Some(result);
    }
}
