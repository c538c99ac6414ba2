//! The run: starting it, engaging through the hole play, the torque ramp, the jam and its hold,
//! the kerf result, the release and the back-off that measures the hole play. The state a run
//! keeps for itself lives in [`Run`], which every run builds afresh: nothing of the previous run
//! can leak into the next.
//!
//! The run's state and its start are here; its phases are one module each: `ramp` (engaging and
//! the torque ramp), `hold` (the jam held, and the probe), `winding_check`, `judge` (the hold
//! judged, the kerf result) and `back_off` (the release, and the back-off that measures the
//! play, whose module docs explain why).

use kerfmeter_protocol::spiral::{play_deg, torque_for_force_nm};
use kerfmeter_protocol::{
    Conditions, ErrorCode, QualityFlags, RunParams, START_TOLERANCE_DEG, Sample,
};

use super::supply::{millivolts, needed_supply_v};
use super::wake::Woken;
use super::{Controller, Motion, OVERTRAVEL_MARGIN_DEG, State};
use crate::build::CONTROL_RATE_HZ;
use crate::jam::HoldWindow;

mod back_off;
mod hold;
mod judge;
mod ramp;
mod winding_check;

/// One run's own state, from `Run` to the next `Run`.
pub(super) struct Run {
    /// The run's parameters.
    pub(super) params: RunParams,
    /// Quality flags collected so far.
    pub(super) flags: QualityFlags,
    /// Ticks spent in the run's states.
    pub(super) ticks: u32,
    /// Encoder read errors while the motor could be driven (this run and the reset or
    /// self-test after it).
    pub(super) encoder_errors: u16,
    /// Hub angle at the start, degrees, jam frame.
    pub(super) start_deg: f32,
    /// Furthest hub angle reached, degrees, jam frame.
    pub(super) max_deg: f32,
    /// Ticks in a row with torque above breakaway and no motion yet.
    pub(super) no_motion_ticks: u32,
    /// Ticks in a row the hub has been still at the target torque.
    pub(super) still_ticks: u32,
    /// Angles collected while a jam is held.
    pub(super) hold: HoldWindow,
    /// Holds taken again because the hub was still creeping into the contact
    /// ([`HOLD_CREEP_LSB`](super::HOLD_CREEP_LSB)).
    pub(super) hold_retries: u32,
    /// The hole play of a zero kerf, θplay(0), degrees: where engaging ends and the inset
    /// starts to turn. Fixed for the run (an `asinf`: computed here, not every tick).
    pub(super) zero_kerf_play_deg: f32,
    /// The furthest hub angle before `Overtravel`, degrees, jam frame: the disengage angle past
    /// the play of the gauge's largest kerf, plus [`OVERTRAVEL_MARGIN_DEG`]. Fixed for the run.
    pub(super) overtravel_limit_deg: f32,
    /// The ramp's running kerf estimate, µm: one fixed-point step of the kerf solve per ramping
    /// tick, from the last tick's (see [`kerf_step`](kerfmeter_protocol::spiral::kerf_step)), for
    /// the inset angle of the torque ceiling.
    pub(super) ramp_kerf_um: f32,
    /// The highest drive voltage (supply × duty applied) on a tick the hub stood still at its
    /// target torque (the jam's settles and hold), V: at a still hub the torque follows it, so
    /// one above the hold's means the contact was pressed harder before the hold than during
    /// it (a winding estimate that lowered the factor), which the self-locking spiral keeps.
    pub(super) max_still_drive_v: f32,
    /// The highest drive voltage on a ramping tick with the hub pressing slowly into the contact
    /// (turning slower than [`PRESSING_SPEED_DEG_PER_S`](super::PRESSING_SPEED_DEG_PER_S)), V: far
    /// above the hold's, with a probe that cannot move the hub, the contact bore more than it is
    /// held with ([`PRESSED_OVER_LIMIT`](super::PRESSED_OVER_LIMIT)).
    pub(super) max_pressing_drive_v: f32,
    /// The run's first settle ([`FirstSettle`]), on the first tick the hub stood still at its
    /// target torque (one still tick: it may be a pause short of the contact). A jam held far
    /// past it for a force a few per cent above it is a contact that gave way under a load it
    /// had borne (`FORCE_SENSITIVE`, [`Controller::settle_sensitivity_um`]).
    pub(super) first_settle: Option<FirstSettle>,
    /// The winding was measured at one of this run's settles (`winding.rs`).
    pub(super) winding_measured: bool,
    /// The probe's angles summed over its last
    /// [`PROBE_AVERAGED_TICKS`](super::PROBE_AVERAGED_TICKS), degrees.
    pub(super) probe_sum_deg: f32,
    /// The probe's figures for the hold's judgement, (rise_deg, fraction): kept from the probe's
    /// last tick to the judgement where the winding is checked after it.
    pub(super) probe: Option<(f32, f32)>,
    /// The winding check after the probe has taken its readings (`winding.rs`, "After the
    /// hold").
    pub(super) winding_checked: bool,
    /// The contact's compliance the winding check holds the hub's turn to, degrees per N·m
    /// ([`Controller::check_compliance_deg_per_nm`], set as the check starts; zero before).
    pub(super) check_compliance_deg_per_nm: f32,
    /// Where no settle measured the winding: the held torque's error as the winding check after
    /// the probe found it, as a fraction of the commanded torque (`None` also where the check's
    /// estimate was implausible: then it measures nothing).
    pub(super) hold_torque_error: Option<f32>,
    /// The approach's start ([`ApproachStart`]), on the last ramping tick whose torque was at most
    /// [`APPROACH_FRACTION`](super::APPROACH_FRACTION) of its target. From there to the jam the hub
    /// moved into the contact with the torque, so the two give the contact's compliance where the
    /// hub's static friction hides it from the probe (`FORCE_SENSITIVE`).
    pub(super) approach: Option<ApproachStart>,
    /// The held jam waiting for its kerf solve ([`HeldJam`]). The hold's last
    /// tick takes the median and the first releasing tick solves it, so that no tick pays for
    /// both (each is some 5–8k instructions: together over the worst-step budget).
    pub(super) held: Option<HeldJam>,
}

/// Where the hub first stood still at its target torque ([`Run::first_settle`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FirstSettle {
    /// The hub angle, degrees, jam frame.
    pub(super) angle_deg: f32,
    /// The drive voltage (supply × duty), V.
    pub(super) drive_v: f32,
    /// The commanded torque, N·m.
    pub(super) torque_nm: f32,
}

/// Where the approach to the jam started ([`Run::approach`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ApproachStart {
    /// The commanded torque, N·m.
    pub(super) torque_nm: f32,
    /// The hub angle, degrees, jam frame.
    pub(super) angle_deg: f32,
    /// The ramp's target there, N·m.
    pub(super) target_nm: f32,
}

impl ApproachStart {
    /// How far the hub turned from here to `held`, degrees (a turn back counts as none).
    fn turn_to_held_deg(&self, held: &HeldJam) -> f32 {
        (held.angle_deg - self.angle_deg).max(0.0)
    }
}

/// A held jam's figures, from the hold's last tick to the kerf solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct HeldJam {
    /// Median hub angle over the hold, degrees, jam frame.
    pub(super) angle_deg: f32,
    /// Drift of the held angles between the hold's halves, degrees
    /// ([`HoldWindow::drift_deg`]).
    pub(super) drift_deg: f32,
    /// How much harder the contact was pressed before the hold than during it, as a fraction of
    /// the held torque ([`Run::max_still_drive_v`]).
    pub(super) overshoot: f32,
    /// How much harder the hub pressed on the way in, turning slowly, than at the hold, as a
    /// fraction of the hold's drive ([`Run::max_pressing_drive_v`]).
    pub(super) pressed_over: f32,
    /// From the run's first settle to the hold ([`Run::first_settle`]): how far the hub turned,
    /// degrees, and how much the force on the contact rose, as a fraction of the settle's
    /// (negative where it fell); `None` without a settle before the hold. The force's ratio is
    /// the drive's (supply × duty: physical, whatever winding factor each assumed) over the
    /// commanded torques' (each the target for the same force at its own angle: the target
    /// falls along the spiral, so a drive that fell over a long turn can still be more force).
    pub(super) since_first_settle: Option<(f32, f32)>,
    /// The torque held, N·m.
    pub(super) torque_nm: f32,
}

impl Run {
    /// A run with `params`, starting with the hub at `start_deg` (jam frame).
    pub(super) fn new(params: RunParams, start_deg: f32) -> Self {
        let gauge = &params.gauge;
        let zero_kerf_play_deg = play_deg(gauge, 0.0);
        let overtravel_limit_deg =
            play_deg(gauge, gauge.max_kerf_um()) + gauge.disengage_deg + OVERTRAVEL_MARGIN_DEG;
        Self {
            params,
            flags: QualityFlags::empty(),
            ticks: 0,
            encoder_errors: 0,
            start_deg,
            max_deg: start_deg,
            no_motion_ticks: 0,
            still_ticks: 0,
            hold: HoldWindow::new(),
            hold_retries: 0,
            zero_kerf_play_deg,
            overtravel_limit_deg,
            ramp_kerf_um: 0.0,
            max_still_drive_v: 0.0,
            max_pressing_drive_v: 0.0,
            first_settle: None,
            winding_measured: false,
            probe_sum_deg: 0.0,
            probe: None,
            winding_checked: false,
            check_compliance_deg_per_nm: 0.0,
            hold_torque_error: None,
            approach: None,
            held: None,
        }
    }

    /// Count an encoder read error.
    pub(super) fn encoder_error(&mut self) {
        self.encoder_errors = self.encoder_errors.saturating_add(1);
        self.flags.insert(QualityFlags::ENCODER_ERRORS);
    }
}

impl Controller {
    /// Start a measurement with `params` (`Run`). Refused while a run, reset or self-test is in
    /// progress (`Busy`), with a fault latched (`Faulted`), while a blocking idle condition
    /// stands (`Blocked`), with an invalid parameter
    /// (`InvalidParam`), when the measured supply cannot deliver the run's torque
    /// (`SupplyTooLow`, [`Controller::check_supply_for`]), and unless the hub stands within
    /// [`START_TOLERANCE_DEG`] of zero (`NotAtZero`). A refused run leaves the last result and
    /// samples as they were; one refused as not at zero has already switched the jam frame to the
    /// new gauge's sense.
    pub fn start_run(&mut self, params: &RunParams) -> Result<(), ErrorCode> {
        self.refuse_unless_ready(Conditions::BLOCKING_RUN)?;
        params.validate().map_err(ErrorCode::InvalidParam)?;
        self.check_supply_for(params)?;
        // The gauge's sense defines the jam frame: re-express the angle in the new one.
        let cw = self.angle_deg_cw();
        self.jam_direction = params.gauge.jam_direction;
        let angle = self.jam_frame(cw);
        self.angle_deg = angle;
        if !self.have_angle || angle.abs() > START_TOLERANCE_DEG {
            return Err(ErrorCode::NotAtZero);
        }
        self.run_id = self.run_id.wrapping_add(1).max(1);
        self.result = None;
        self.log.clear();
        self.run = Run::new(*params, angle);
        if self.last_diagnostics.is_some_and(|d| d.marginal) {
            self.run.flags.insert(QualityFlags::WEAK_MAGNET);
        }
        self.motion = Motion::new();
        self.torque_nm = 0.0;
        self.state = State::Waking {
            ticks: 0,
            then: Woken::Run,
        };
        Ok(())
    }

    /// Refuses `params` with `SupplyTooLow` when the most torque the run may ask for (its target
    /// at the inset's start, where τ(θs) is largest, at most `max_torque_nm`) needs more than full
    /// duty at the measured supply. Never refused where the supply is not measured (`supply.rs`).
    pub fn check_supply_for(&self, params: &RunParams) -> Result<(), ErrorCode> {
        let Some(supply_v) = self.supply.supply_v() else {
            return Ok(());
        };
        let peak_nm =
            torque_for_force_nm(params, params.target_force_n, 0.0).min(params.max_torque_nm);
        let needed_v = needed_supply_v(&self.config, peak_nm);
        if supply_v >= needed_v {
            Ok(())
        } else {
            Err(ErrorCode::SupplyTooLow {
                supply_mv: millivolts(supply_v),
                needed_mv: millivolts(needed_v),
            })
        }
    }

    /// Log this tick of the run.
    pub(super) fn record_sample(&mut self) {
        self.run.ticks += 1;
        // Backing off is not part of the (torque, angle) sweep: its turn is the play's.
        if matches!(self.state, State::BackingOff { .. }) {
            return;
        }
        self.log.record(Sample {
            t_ms: self.run.ticks * 1000 / u32::from(CONTROL_RATE_HZ),
            torque_nm: self.torque_nm,
            angle_deg: self.angle_deg,
        });
    }
}
