//! Judging the hold and the kerf result: the jam's angle solved for the kerf, and the quality
//! flags that say how far to trust it (force sensitivity from the probe, the approach and the
//! first settle; overshoot; the torque's uncertainty).

use kerfmeter_protocol::spiral::{force_for_torque_n, kerf_from_angle};
use kerfmeter_protocol::{KerfResult, QualityFlags};

use super::HeldJam;
use crate::controller::{
    Controller, FORCE_SENSITIVITY_LIMIT_UM, HOLD_CREEP_LSB, MIN_APPROACH_FRACTION,
    MIN_PROBE_FRACTION, NEAR_DISENGAGE_FRACTION, OVERSHOOT_LIMIT, PRESSED_OVER_LIMIT,
    PRESSED_PROBE_STILL_LSB, SETTLE_MIN_FORCE_RISE, State, TORQUE_UNCERTAINTY,
    TORQUE_UNCERTAINTY_UNMEASURED,
};

impl Controller {
    /// Whether an inset at `inset_deg` is past [`NEAR_DISENGAGE_FRACTION`] of the gauge's
    /// disengage angle (`NEAR_DISENGAGE`: the spiral lets go soon after).
    pub(super) fn near_disengage(&self, inset_deg: f32) -> bool {
        inset_deg > NEAR_DISENGAGE_FRACTION * self.run.params.gauge.disengage_deg
    }

    /// The hold's flags from the probe's figures ([`Controller::judge_hold`]), then `Releasing`.
    pub(super) fn judge_and_release(&mut self) {
        if let (Some(held), Some(probe)) = (self.run.held, self.run.probe) {
            self.judge_hold(&held, probe);
        }
        self.state = State::Releasing;
    }

    /// The hold's flags, on the probe's last tick or the winding check's (light ones: the first
    /// releasing tick has the kerf solve): `NOISY_HOLD` for a hold that drifted past
    /// [`HOLD_CREEP_LSB`]: one still creeping after it was taken again for a creep, or that
    /// could not be taken again (no retries or run time left), is read short of where the hub
    /// comes to rest. `FORCE_SENSITIVE` for a reading that the probe's `(rise_deg, fraction)`,
    /// the approach, the turn since the first settle or an overshoot says a torque error could
    /// move too far, or whose contact bore more on the way in than at the hold.
    fn judge_hold(&mut self, held: &HeldJam, probe: (f32, f32)) {
        let drift_lsb = held.drift_deg.abs() / self.lsb_deg();
        // A hold is judged only once it may not be taken again: a creep left is a creep read.
        if drift_lsb > HOLD_CREEP_LSB {
            self.run.flags.insert(QualityFlags::NOISY_HOLD);
        }
        let sensitivity_um = self
            .force_sensitivity_um(probe, held.overshoot)
            .max(self.approach_sensitivity_um(held))
            .max(self.settle_sensitivity_um(held));
        if held.overshoot > OVERSHOOT_LIMIT
            || self.pressed_harder_than_held(held)
            || sensitivity_um > FORCE_SENSITIVITY_LIMIT_UM
        {
            self.run.flags.insert(QualityFlags::FORCE_SENSITIVE);
        }
    }

    /// Whether the contact bore more on the way in than at the hold: the hub pressed into it,
    /// turning slowly, at a drive over [`PRESSED_OVER_LIMIT`] above the hold's, and the probe
    /// then could not move the hub (by [`PRESSED_PROBE_STILL_LSB`]): a contact that crushed under
    /// the ramp while the falling target followed the inset down, which the self-locking spiral
    /// keeps. A sound contact the probe moves, or the hold's drive is its highest.
    fn pressed_harder_than_held(&self, held: &HeldJam) -> bool {
        held.pressed_over > PRESSED_OVER_LIMIT && self.probe_was_still()
    }

    /// The result from the held jam's median angle at its torque (the hold's flags are in the
    /// run's already: [`Controller::judge_hold`]).
    pub(super) fn finish(&mut self, held: HeldJam) {
        let HeldJam { angle_deg, .. } = held;
        // Where the winding check found the torque the hold really drove, that is the reading's.
        let torque_nm = held.torque_nm * (1.0 + self.run.hold_torque_error.unwrap_or(0.0));
        let params = &self.run.params;
        let gauge = &params.gauge;
        let solution = kerf_from_angle(gauge, angle_deg);
        let mut flags = self.run.flags;
        if self.near_disengage(solution.inset_deg) {
            flags.insert(QualityFlags::NEAR_DISENGAGE);
        }
        if !solution.converged {
            flags.insert(QualityFlags::PLAY_NOT_CONVERGED);
        }
        if self.log.ticks_per_sample() > 1 {
            flags.insert(QualityFlags::DECIMATED);
        }
        // Until the back-off measures the play (`apply_measured_play`).
        flags.insert(QualityFlags::PLAY_MODELLED);
        self.result = Some(KerfResult {
            run_id: self.run_id,
            kerf_um: solution.kerf_um,
            angle_deg,
            play_deg: solution.play_deg,
            torque_at_jam_nm: torque_nm,
            force_at_jam_n: force_for_torque_n(params, torque_nm, solution.inset_deg),
            flags,
        });
    }

    /// How far the torque's uncertainty could move the reading, µm, from the probe's `(rise_deg,
    /// fraction)` (a torque `fraction` above the held one turned the hub `rise_deg` on) after an
    /// `overshoot` (the contact had borne that much more before the hold, so the hub only moves
    /// once the probe passes it, and the reading is high by what the overshoot compressed). The
    /// contact's compliance is the rise over the probe's torque beyond the overshoot; the error it
    /// allows is that compliance times the torque's uncertainty
    /// ([`Controller::torque_uncertainty`]) or the overshoot, whichever is larger. Zero where the
    /// probe could not rise far enough to tell (the run's cap or full duty held it:
    /// `TORQUE_LIMITED` and `SUPPLY_LIMITED` flag those).
    fn force_sensitivity_um(&self, (rise_deg, fraction): (f32, f32), overshoot: f32) -> f32 {
        let beyond = fraction - overshoot;
        if beyond < MIN_PROBE_FRACTION {
            return 0.0;
        }
        let rise_um = self.run.params.gauge.pitch_um_per_deg * rise_deg.max(0.0);
        rise_um / beyond * self.torque_uncertainty().max(overshoot)
    }

    /// How far the torque's uncertainty could move the reading, µm, judged from the approach
    /// ([`Run::approach`](super::Run::approach)): the hub turned from the approach's start to the
    /// held median while the torque rose to the held one, so the contact's compliance is at least
    /// that turn over that rise (a slip on the way, stick-slip, counts in full: it is what a torque
    /// error that size does). The probe after the hold cannot see this where the drive train's and
    /// the inset's static friction hold the hub at the jam: a torque 10 % higher does not break it
    /// loose, and the probe reads a stiff contact. Where the torque rose by less than
    /// [`MIN_APPROACH_FRACTION`] of the held one, the force's rise is taken, if the probe could not
    /// move the hub ([`Controller::approach_force_turn`]); zero otherwise.
    fn approach_sensitivity_um(&self, held: &HeldJam) -> f32 {
        let approach = self
            .approach_turn(held)
            .or_else(|| self.approach_force_turn(held));
        let Some((turn_deg, rise_nm)) = approach else {
            return 0.0;
        };
        let turn_um = self.run.params.gauge.pitch_um_per_deg * turn_deg;
        turn_um / rise_nm * held.torque_nm * self.torque_uncertainty()
    }

    /// The approach to `held` ([`Run::approach`](super::Run::approach)): how far the hub turned,
    /// degrees, while the torque rose how much, N·m, from the approach's start to the held jam;
    /// `None` where the torque rose by less than [`MIN_APPROACH_FRACTION`] of the held one (a jam
    /// reached at the approach's start, or one the target followed down along the spiral: see
    /// [`Controller::approach_force_turn`]).
    pub(super) fn approach_turn(&self, held: &HeldJam) -> Option<(f32, f32)> {
        let start = self.run.approach?;
        let rise_nm = held.torque_nm - start.torque_nm;
        (rise_nm >= MIN_APPROACH_FRACTION * held.torque_nm)
            .then(|| (start.turn_to_held_deg(held), rise_nm))
    }

    /// The approach to `held`, for one whose torque hardly rose ([`Controller::approach_turn`] is
    /// `None`: its caller asks that first), where the probe could not move the hub: how far the hub
    /// turned, degrees, while the force rose how much, as a share of the held torque, N·m. The
    /// target for the run's force falls along the spiral, so a contact giving way at that force
    /// (crushing past its yield) lets the hub turn on far with no rise in torque, while the force
    /// rose from at most [`APPROACH_FRACTION`](crate::controller::APPROACH_FRACTION) of the target
    /// to all of it (on the twin a contact yielding at 178 N turned the hub 26° so, read 38 µm high
    /// and was not flagged). Only for the flag: the winding check's allowance keeps the torque's
    /// rise, which such a contact would make unbounded. Where the probe moved the hub it measured
    /// the contact itself, and a free hub crawling to the jam at high torque (a high-ratio build)
    /// turns as far with no contact to give way: `None`.
    fn approach_force_turn(&self, held: &HeldJam) -> Option<(f32, f32)> {
        let start = self.run.approach?;
        if !self.probe_was_still() {
            return None;
        }
        let force_rise_nm =
            held.torque_nm * (1.0 - start.torque_nm / start.target_nm.max(f32::EPSILON));
        Some((
            start.turn_to_held_deg(held),
            force_rise_nm.max(f32::EPSILON),
        ))
    }

    /// Whether the probe after the hold turned the hub by less than
    /// [`PRESSED_PROBE_STILL_LSB`] (static friction held it; also before any probe).
    fn probe_was_still(&self) -> bool {
        self.run
            .probe
            .is_none_or(|(rise_deg, _)| rise_deg.abs() < PRESSED_PROBE_STILL_LSB * self.lsb_deg())
    }

    /// How far a torque error of the run's uncertainty would move the reading, µm, judged from
    /// the run's first settle to the hold ([`HeldJam::since_first_settle`]): the hub stood still
    /// there at its target, then turned on to the hold with the force risen by so much (at least
    /// [`SETTLE_MIN_FORCE_RISE`]). Where the winding's estimate raised the factor at the settle,
    /// this is the contact's compliance, as the approach's; where the contact gave way under the
    /// settle's load (crushing, then running on faster than the pressing test sees, or with the
    /// approach's start taken again by a dip of the speed loop), the hub turned tens of degrees
    /// for a force some 50 % higher, and the reading is as uncertain as that compliance says.
    ///
    /// The rise is the commanded one; the drive train's friction at the settle may have borne
    /// up to its breakaway torque of the load, so the contact's own rise may be larger by that
    /// share of the held torque, and the compliance is taken over the larger rise (a lower
    /// bound). A force that did not rise (a jam creeping in at the target's force, the settle's
    /// still tick a pause of a hub still short of the contact) measures nothing.
    fn settle_sensitivity_um(&self, held: &HeldJam) -> f32 {
        match held.since_first_settle {
            Some((turn_deg, rise)) if rise >= SETTLE_MIN_FORCE_RISE => {
                let turn_um = self.run.params.gauge.pitch_um_per_deg * turn_deg.max(0.0);
                let friction_share = self.breakaway_torque_nm() / held.torque_nm.max(f32::EPSILON);
                turn_um / (rise + friction_share) * self.torque_uncertainty()
            }
            _ => 0.0,
        }
    }

    /// The torque's relative uncertainty at this run's jam: [`TORQUE_UNCERTAINTY`] where a
    /// settle of the run measured the winding; where only the check after the probe did, the
    /// held torque's error it found on top; [`TORQUE_UNCERTAINTY_UNMEASURED`] where nothing did.
    fn torque_uncertainty(&self) -> f32 {
        match (self.run.winding_measured, self.run.hold_torque_error) {
            (true, _) => TORQUE_UNCERTAINTY,
            (false, Some(error)) => TORQUE_UNCERTAINTY + error.abs(),
            (false, None) => TORQUE_UNCERTAINTY_UNMEASURED,
        }
    }
}
