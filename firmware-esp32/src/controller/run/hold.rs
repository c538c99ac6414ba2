//! The jam held: its hold window (taken again while the hub still creeps into the contact), then
//! the probe that presses a little harder to see whether the hub moves.

use super::HeldJam;
use crate::build::CONTROL_RATE_HZ;
use crate::controller::{
    Controller, HOLD_CREEP_LSB, HOLD_RETRY_RESERVE_MS, JAM_SLIP_DEG, MAX_HOLD_RETRIES,
    PROBE_AVERAGED_TICKS, PROBE_FRACTION, PROBE_TICKS, State,
};

impl Controller {
    /// Jammed: hold the torque and collect the angles; back to ramping if the jam slips.
    pub(in crate::controller) fn hold_jam(
        &mut self,
        torque_nm: f32,
        entry_deg: f32,
        fresh: Option<f32>,
    ) {
        self.torque_nm = torque_nm;
        if (self.angle_deg - entry_deg).abs() > JAM_SLIP_DEG {
            // The jam gave way (stick-slip): keep ramping from here.
            self.run.still_ticks = 0;
            self.state = State::Ramping;
            return;
        }
        if let Some(angle) = fresh {
            self.run.hold.push(angle);
        }
        let drive_v = self.note_still_drive();
        if !self.run.hold.is_full() {
            return;
        }
        let drift_deg = self.run.hold.drift_deg();
        if drift_deg.abs() > HOLD_CREEP_LSB * self.lsb_deg() && self.may_hold_again() {
            // Still creeping into the contact: the reading would be short of where the hub comes
            // to rest. Hold again; a creep that carries the hub past the slip limit resumes the
            // ramp.
            self.run.hold_retries += 1;
            self.run.hold.clear();
            return;
        }
        // The contact was pressed this much harder before the hold than it is held.
        let overshoot = (self.run.max_still_drive_v / drive_v.max(f32::EPSILON) - 1.0).max(0.0);
        let pressed_over =
            (self.run.max_pressing_drive_v / drive_v.max(f32::EPSILON) - 1.0).max(0.0);
        let (median, _) = self
            .run
            .hold
            .median_and_spread()
            .unwrap_or((entry_deg, 0.0));
        let since_first_settle = self.run.first_settle.map(|settle| {
            let drive_ratio = drive_v / settle.drive_v.max(f32::EPSILON);
            (
                median - settle.angle_deg,
                drive_ratio * settle.torque_nm / torque_nm.max(f32::EPSILON) - 1.0,
            )
        });
        self.run.held = Some(HeldJam {
            angle_deg: median,
            drift_deg,
            overshoot,
            pressed_over,
            since_first_settle,
            torque_nm,
        });
        self.run.probe_sum_deg = 0.0;
        self.state = State::Probing {
            torque_nm: self.probe_torque_nm(torque_nm, overshoot),
            ticks: 0,
        };
    }

    /// Whether a creeping hold may be taken again: at most [`MAX_HOLD_RETRIES`] times, and only
    /// with [`HOLD_RETRY_RESERVE_MS`] of the run's time left (a slow run is read, not faulted
    /// with `MaxRunTime`, for waiting on its creep).
    fn may_hold_again(&self) -> bool {
        self.run.hold_retries < MAX_HOLD_RETRIES
            && self.elapsed_ms() + HOLD_RETRY_RESERVE_MS < self.run.params.max_time_ms
    }

    /// The run's time so far, ms.
    pub(super) fn elapsed_ms(&self) -> u32 {
        self.run.ticks * 1000 / u32::from(CONTROL_RATE_HZ)
    }

    /// The probe's torque for a jam held at `held_nm` after an `overshoot`: [`PROBE_FRACTION`]
    /// above the most the contact has borne, within the run's cap and what full duty gives at
    /// the measured supply.
    fn probe_torque_nm(&self, held_nm: f32, overshoot: f32) -> f32 {
        let cap_nm = self
            .run
            .params
            .max_torque_nm
            .min(self.supply.full_duty_torque_nm(&self.config));
        (held_nm * (1.0 + overshoot + PROBE_FRACTION))
            .min(cap_nm)
            .max(held_nm)
    }

    /// Probing, after the hold: the torque rises at the ramp's rate to `probe_nm` and stays
    /// there; over the last [`PROBE_AVERAGED_TICKS`] of [`PROBE_TICKS`] the angles are summed.
    /// How far the hub moved on from the held median is how far a torque error that large
    /// moves the reading (`FORCE_SENSITIVE`, [`Controller::force_sensitivity_um`]). The probe
    /// comes after the reading's angles: whatever it compresses does not enter the reading.
    pub(in crate::controller) fn probe(&mut self, probe_nm: f32, ticks: u32) {
        let ramped = self.torque_nm + self.run.params.ramp_rate_nm_per_s * self.dt_s();
        self.torque_nm = ramped.min(probe_nm);
        if ticks + PROBE_AVERAGED_TICKS >= PROBE_TICKS {
            self.run.probe_sum_deg += self.angle_deg;
        }
        if ticks + 1 < PROBE_TICKS {
            self.state = State::Probing {
                torque_nm: probe_nm,
                ticks: ticks + 1,
            };
            return;
        }
        if let Some(held) = self.run.held {
            let mean_deg = self.run.probe_sum_deg / PROBE_AVERAGED_TICKS as f32;
            self.run.probe = Some((mean_deg - held.angle_deg, probe_nm / held.torque_nm - 1.0));
        }
        match self.winding_check_torque_nm() {
            Some(check_nm) => {
                self.run.still_ticks = 0;
                self.winding.clear();
                self.run.check_compliance_deg_per_nm = self.check_compliance_deg_per_nm();
                self.state = State::CheckingWinding {
                    torque_nm: check_nm,
                    ticks: 0,
                };
            }
            None => self.judge_and_release(),
        }
    }
}
