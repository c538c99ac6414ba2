//! The winding check after the probe, where no settle measured the winding: the held torque's
//! error, read from how far the hub turns under a check torque (`winding.rs`, "After the hold").

use kerfmeter_protocol::QualityFlags;

use crate::build::CONTROL_RATE_HZ;
use crate::controller::winding::{
    CHECK_COMPLIANCE_MARGIN, CHECK_DUTY, CHECK_MARGIN_MS, CHECK_MAX_ERROR, CHECK_MAX_TICKS,
    CHECK_MAX_TORQUE_RATIO, CHECK_PROBE_MIN_RISE_LSB, CHECK_READINGS,
};
use crate::controller::{
    Controller, JAM_SLIP_DEG, MAX_TURN_SPEED_DEG_PER_S, MIN_PROBE_FRACTION, RELEASE_RATE_NM_PER_S,
    State,
};

impl Controller {
    /// The torque that drives [`CHECK_DUTY`], where this run's winding is still to be measured (no
    /// settle's duty reached [`MIN_DUTY`](crate::controller::winding::MIN_DUTY)) and the check
    /// fits: within the run's cap and what full duty gives, at most [`CHECK_MAX_TORQUE_RATIO`]
    /// times the held torque, never below the probe's, with the inset clear of the spiral's
    /// disengage, and with the run's time left for the ramp up, [`CHECK_MAX_TICKS`], the release
    /// and [`CHECK_MARGIN_MS`]. `None`: no check, the torque's uncertainty stays
    /// [`TORQUE_UNCERTAINTY_UNMEASURED`](crate::controller::TORQUE_UNCERTAINTY_UNMEASURED).
    pub(super) fn winding_check_torque_nm(&self) -> Option<f32> {
        let held = self.run.held?;
        let flags = self.run.flags;
        if self.run.winding_measured
            || flags.contains(QualityFlags::TORQUE_LIMITED)
            || flags.contains(QualityFlags::SUPPLY_LIMITED)
            || self.past_check_turn_limit()
        {
            return None;
        }
        let config = &self.config;
        let check_nm = (CHECK_DUTY / self.supply.duty_scale() - config.breakaway_duty)
            * config.torque_per_duty_nm;
        let cap_nm = self
            .run
            .params
            .max_torque_nm
            .min(self.supply.full_duty_torque_nm(config))
            .min(CHECK_MAX_TORQUE_RATIO * held.torque_nm);
        if check_nm > cap_nm {
            return None;
        }
        let check_nm = check_nm.max(self.torque_nm);
        let ramp_ms = (check_nm - self.torque_nm) / self.run.params.ramp_rate_nm_per_s * 1000.0;
        let release_ms = check_nm / RELEASE_RATE_NM_PER_S * 1000.0;
        let check_ms = (CHECK_MAX_TICKS * 1000 / u32::from(CONTROL_RATE_HZ)) as f32;
        let needed_ms = ramp_ms + check_ms + release_ms + CHECK_MARGIN_MS as f32;
        let left_ms = self.run.params.max_time_ms as f32 - self.elapsed_ms() as f32;
        (needed_ms < left_ms).then_some(check_nm)
    }

    /// Checking the winding after the probe: the torque rises at the ramp's rate to `check_nm`
    /// (the reading was taken: what it compresses now does not enter it), never turning the hub
    /// faster than the ramp's speed limit, and once the hub stands still there, the winding is
    /// measured over [`CHECK_READINGS`] ticks as at a settle. Its factor applies from then on,
    /// and the held torque's error it reveals ([`Controller::conclude_check`]) sets the torque's
    /// uncertainty the hold is judged with, on the tick after (the estimate's tick is not also
    /// the judgement's). `ticks` counts the ticks at `check_nm`: a hub not still in
    /// [`CHECK_MAX_TICKS`] of them leaves the winding unmeasured. A hub that turns on past what
    /// the contact's measured compliance allows ([`Controller::check_turn_allowance_deg`]: a
    /// contact giving way) or towards the spiral's disengage
    /// ([`Controller::past_check_turn_limit`]) has its torque dropped at once, the reading is
    /// flagged `FORCE_SENSITIVE` (its contact yields under less than twice its force), and the run
    /// releases.
    pub(in crate::controller) fn check_winding(
        &mut self,
        check_nm: f32,
        ticks: u32,
        current_a: Option<f32>,
    ) {
        if self.run.winding_checked || ticks >= CHECK_MAX_TICKS {
            self.winding.clear();
            self.judge_and_release();
            return;
        }
        if self.gives_way_under_check() {
            self.torque_nm = 0.0;
            self.winding.clear();
            self.run.flags.insert(QualityFlags::FORCE_SENSITIVE);
            self.judge_and_release();
            return;
        }
        let dt_s = self.dt_s();
        let ramped = self.torque_nm + self.run.params.ramp_rate_nm_per_s * dt_s;
        let speed_capped = self.speed_loop(MAX_TURN_SPEED_DEG_PER_S, check_nm, dt_s);
        self.torque_nm = ramped.min(speed_capped).min(check_nm).max(0.0);
        let at_check = self.torque_nm >= check_nm;
        if at_check && self.is_still() {
            self.run.still_ticks += 1;
            self.winding_reading(current_a);
        } else {
            self.run.still_ticks = 0;
            self.winding.clear();
        }
        if self.winding.readings() >= CHECK_READINGS {
            self.conclude_check();
        }
        self.state = State::CheckingWinding {
            torque_nm: check_nm,
            ticks: ticks + u32::from(at_check),
        };
    }

    /// The contact's compliance the check's turn is held to, degrees per N·m: the probe's where
    /// it turned the hub at least [`CHECK_PROBE_MIN_RISE_LSB`] (the tangent at the held torque,
    /// which a stiffening contact only departs from downwards), else the larger of the probe's
    /// and the approach's (a probe held by static friction measured nothing).
    pub(super) fn check_compliance_deg_per_nm(&self) -> f32 {
        let Some(held) = self.run.held else {
            return 0.0;
        };
        let (probe_rise_deg, probe_deg_per_nm) = match self.run.probe {
            Some((rise_deg, fraction)) if fraction >= MIN_PROBE_FRACTION => {
                let rise_deg = rise_deg.max(0.0);
                (rise_deg, rise_deg / (fraction * held.torque_nm))
            }
            _ => (0.0, 0.0),
        };
        if probe_rise_deg >= CHECK_PROBE_MIN_RISE_LSB * self.lsb_deg() {
            return probe_deg_per_nm;
        }
        let approach_deg_per_nm = self
            .approach_turn(&held)
            .map_or(0.0, |(turn_deg, rise_nm)| turn_deg / rise_nm);
        probe_deg_per_nm.max(approach_deg_per_nm)
    }

    /// How far the hub may turn on from the held angle under the check with the torque at
    /// `torque_nm`, degrees: [`JAM_SLIP_DEG`] plus [`CHECK_COMPLIANCE_MARGIN`] times what the
    /// contact's compliance gives for the torque's rise over the held one. It follows the torque
    /// as the check ramps, so a contact that starts to crush early in the ramp is caught there,
    /// not once it has turned as far as the whole check's torque would allow (the hub lags the
    /// torque, so a sound contact stays inside it).
    fn check_turn_allowance_deg(&self, torque_nm: f32) -> f32 {
        let held_nm = self.run.held.map_or(torque_nm, |h| h.torque_nm);
        let extra_nm = (torque_nm - held_nm).max(0.0);
        JAM_SLIP_DEG + CHECK_COMPLIANCE_MARGIN * self.run.check_compliance_deg_per_nm * extra_nm
    }

    /// Whether the contact gives way under the check: the hub turned on past its allowance from
    /// the held angle, or towards the spiral's disengage.
    fn gives_way_under_check(&self) -> bool {
        let turned_deg = self.run.held.map_or(0.0, |h| self.angle_deg - h.angle_deg);
        turned_deg > self.check_turn_allowance_deg(self.torque_nm) || self.past_check_turn_limit()
    }

    /// The winding check's readings are in: the factor applies from now on, and the held
    /// torque's error follows from the factor the hold drove with. The hold's duty was
    /// (breakaway + τ/k)·s, s proportional to the factor, so a winding r = ρ_held/ρ_found times as
    /// conductive as the hold assumed gave τ·r + b·k·(r − 1): an error of (r − 1)(1 + b·k/τ)
    /// (the breakaway's share moves with the rest of the drive). An implausible estimate is not
    /// taken (`WindingEstimate::conclude_if_plausible`): the error stays unknown.
    fn conclude_check(&mut self) {
        debug_assert!(self.run.held.is_some(), "a check comes after a hold");
        let held_factor = self.winding.factor();
        self.run.winding_checked = true;
        if !self.winding.conclude_if_plausible(&self.config) {
            return;
        }
        let factor = self.winding.factor();
        self.supply.set_winding_factor(factor);
        if let Some(held) = self.run.held {
            let r = held_factor / factor;
            let breakaway_share = self.breakaway_torque_nm() / held.torque_nm.max(f32::EPSILON);
            let error = (r - 1.0) * (1.0 + breakaway_share);
            // An error past [`CHECK_MAX_ERROR`] is more than a correction should be trusted with
            // (a breakaway share that large is the calibration's own guess): left unknown.
            self.run.hold_torque_error = (error.abs() <= CHECK_MAX_ERROR).then_some(error);
        }
    }

    /// Whether the hub has turned so far that the inset may be near the spiral's disengage: past
    /// [`NEAR_DISENGAGE_FRACTION`](crate::controller::NEAR_DISENGAGE_FRACTION) of it, counting the
    /// inset from the zero kerf's play (no kerf has less, so the true inset is at most this).
    fn past_check_turn_limit(&self) -> bool {
        self.near_disengage(self.angle_deg - self.run.zero_kerf_play_deg)
    }
}
