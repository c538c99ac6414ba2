//! The run: starting it, engaging through the hole play, the torque ramp, the jam and its hold,
//! the kerf result, the release and the back-off that measures the hole play. The state a run
//! keeps for itself lives in [`Run`], which every run builds afresh: nothing of the previous run
//! can leak into the next.
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

use kerfmeter_protocol::{
    Conditions, EncoderPlacement, ErrorCode, KerfResult, QualityFlags, REFERENCE_SUPPLY_V,
    RunParams, START_TOLERANCE_DEG, Sample,
};

use super::supply::{millivolts, needed_supply_v};
use super::winding::{
    CHECK_COMPLIANCE_MARGIN, CHECK_DUTY, CHECK_MARGIN_MS, CHECK_MAX_ERROR, CHECK_MAX_TICKS,
    CHECK_MAX_TORQUE_RATIO, CHECK_PROBE_MIN_RISE_LSB, CHECK_READINGS, ESTIMATE_TICK, MAX_STEP,
    MIN_DUTY, SKIP_TICKS,
};
use super::{
    APPROACH_FRACTION, BACK_OFF_MAX_LONGER_DEG, BACK_OFF_MAX_SHORTER_DEG, BACK_OFF_MAX_TICKS,
    BACK_OFF_MAX_TORQUE_NM, BACK_OFF_MIN_HELD_RATIO, BACK_OFF_MIN_TURN_DEG, BACK_OFF_RESERVE_MS,
    BACK_OFF_SETTLE_TICKS, BACK_OFF_SPEED_DEG_PER_S, BACK_OFF_STALL_SHARE, BACK_OFF_STILL_TICKS,
    Controller, ENGAGE_MAX_TORQUE_NM, ENGAGE_SPEED_DEG_PER_S, FORCE_SENSITIVITY_LIMIT_UM,
    HOLD_CREEP_LSB, HOLD_RETRY_RESERVE_MS, JAM_MIN_INSET_DEG, JAM_SETTLE_TICKS, JAM_SLIP_DEG,
    JAM_STILL_LSB, JAM_WINDOW_TICKS, MAX_HOLD_RETRIES, MAX_TURN_SPEED_DEG_PER_S,
    MIN_APPROACH_FRACTION, MIN_PROBE_FRACTION, Motion, NEAR_DISENGAGE_FRACTION, OVERSHOOT_LIMIT,
    OVERTRAVEL_MARGIN_DEG, PRESSED_OVER_LIMIT, PRESSED_PROBE_STILL_LSB, PRESSING_SPEED_DEG_PER_S,
    PROBE_AVERAGED_TICKS, PROBE_FRACTION, PROBE_TICKS, RELEASE_RATE_NM_PER_S,
    SETTLE_MIN_FORCE_RISE, State, TORQUE_UNCERTAINTY, TORQUE_UNCERTAINTY_UNMEASURED,
};
use crate::build::CONTROL_RATE_HZ;
use crate::jam::HoldWindow;
use kerfmeter_protocol::spiral::{
    force_for_torque_n, kerf_for_inset_um, kerf_from_angle, kerf_step, play_deg,
    torque_for_force_nm,
};

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
    /// ([`HOLD_CREEP_LSB`]).
    pub(super) hold_retries: u32,
    /// The hole play of a zero kerf, θplay(0), degrees: where engaging ends and the inset
    /// starts to turn. Fixed for the run (an `asinf`: computed here, not every tick).
    pub(super) zero_kerf_play_deg: f32,
    /// The furthest hub angle before `Overtravel`, degrees, jam frame: the disengage angle past
    /// the play of the gauge's largest kerf, plus [`OVERTRAVEL_MARGIN_DEG`]. Fixed for the run.
    pub(super) overtravel_limit_deg: f32,
    /// The ramp's running kerf estimate, µm: one fixed-point step of the kerf solve per ramping
    /// tick, from the last tick's (see [`kerf_step`]), for the inset angle of the torque ceiling.
    pub(super) ramp_kerf_um: f32,
    /// The highest drive voltage (supply × duty applied) on a tick the hub stood still at its
    /// target torque (the jam's settles and hold), V: at a still hub the torque follows it, so
    /// one above the hold's means the contact was pressed harder before the hold than during
    /// it (a winding estimate that lowered the factor), which the self-locking spiral keeps.
    pub(super) max_still_drive_v: f32,
    /// The highest drive voltage on a ramping tick with the hub pressing slowly into the contact
    /// (turning slower than [`PRESSING_SPEED_DEG_PER_S`]), V: far above the hold's, with a
    /// probe that cannot move the hub, the contact bore more than it is held with
    /// ([`PRESSED_OVER_LIMIT`]).
    pub(super) max_pressing_drive_v: f32,
    /// The run's first settle ([`FirstSettle`]), on the first tick the hub stood still at its
    /// target torque (one still tick: it may be a pause short of the contact). A jam held far
    /// past it for a force a few per cent above it is a contact that gave way under a load it
    /// had borne (`FORCE_SENSITIVE`, [`Controller::settle_sensitivity_um`]).
    pub(super) first_settle: Option<FirstSettle>,
    /// The winding was measured at one of this run's settles (`winding.rs`).
    pub(super) winding_measured: bool,
    /// The probe's angles summed over its last [`PROBE_AVERAGED_TICKS`], degrees.
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
    /// The approach's start ([`ApproachStart`]), on the last ramping tick whose torque was at
    /// most [`APPROACH_FRACTION`] of its target. From there to the jam the hub moved into the
    /// contact with the torque, so the two give the contact's compliance where the hub's static
    /// friction hides it from the probe (`FORCE_SENSITIVE`).
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
        self.state = State::Engaging;
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

    /// Fitted angle change over the regression window within the stillness band.
    fn is_still(&self) -> bool {
        let change_over_window_deg = self.motion.slope_deg_per_tick * (JAM_WINDOW_TICKS - 1) as f32;
        self.motion.slope.is_full()
            && change_over_window_deg.abs() <= JAM_STILL_LSB * self.lsb_deg()
    }

    /// Engaging: turn slowly through the hole play.
    pub(super) fn engage(&mut self) {
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
    pub(super) fn ramp(&mut self, current_a: Option<f32>) {
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
    /// measured), kept in [`Run::max_still_drive_v`]: this tick the hub stands still at its
    /// target torque.
    fn note_still_drive(&mut self) -> f32 {
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
    fn winding_reading(&mut self, current_a: Option<f32>) {
        if let Some(current_a) = current_a
            && self.run.still_ticks > SKIP_TICKS
            && self.applied_duty >= MIN_DUTY
        {
            let supply_v = self.supply.supply_v().unwrap_or(REFERENCE_SUPPLY_V);
            self.winding.push(supply_v * self.applied_duty, current_a);
        }
    }

    /// Jammed: hold the torque and collect the angles; back to ramping if the jam slips.
    pub(super) fn hold_jam(&mut self, torque_nm: f32, entry_deg: f32, fresh: Option<f32>) {
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
    fn elapsed_ms(&self) -> u32 {
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
    pub(super) fn probe(&mut self, probe_nm: f32, ticks: u32) {
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

    /// The torque that drives [`CHECK_DUTY`], where this run's winding is still to be measured
    /// (no settle's duty reached [`MIN_DUTY`]) and the check fits: within the run's cap and
    /// what full duty gives, at most [`CHECK_MAX_TORQUE_RATIO`] times the held torque, never
    /// below the probe's, with the inset clear of the spiral's disengage, and with the run's
    /// time left for the ramp up, [`CHECK_MAX_TICKS`], the release and [`CHECK_MARGIN_MS`].
    /// `None`: no check, the torque's uncertainty stays [`TORQUE_UNCERTAINTY_UNMEASURED`].
    fn winding_check_torque_nm(&self) -> Option<f32> {
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
    pub(super) fn check_winding(&mut self, check_nm: f32, ticks: u32, current_a: Option<f32>) {
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
    fn check_compliance_deg_per_nm(&self) -> f32 {
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
    /// [`NEAR_DISENGAGE_FRACTION`] of it, counting the inset from the zero kerf's play (no kerf
    /// has less, so the true inset is at most this).
    fn past_check_turn_limit(&self) -> bool {
        self.near_disengage(self.angle_deg - self.run.zero_kerf_play_deg)
    }

    /// Whether an inset at `inset_deg` is past [`NEAR_DISENGAGE_FRACTION`] of the gauge's
    /// disengage angle (`NEAR_DISENGAGE`: the spiral lets go soon after).
    fn near_disengage(&self, inset_deg: f32) -> bool {
        inset_deg > NEAR_DISENGAGE_FRACTION * self.run.params.gauge.disengage_deg
    }

    /// The hold's flags from the probe's figures ([`Controller::judge_hold`]), then `Releasing`.
    fn judge_and_release(&mut self) {
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
    fn finish(&mut self, held: HeldJam) {
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

    /// How far the torque's uncertainty could move the reading, µm, from the probe's
    /// `(rise_deg, fraction)` (a torque `fraction` above the held one turned the hub `rise_deg`
    /// on) after an `overshoot` (the contact had borne that much more before the hold, so the
    /// hub only moves once the probe passes it, and the reading is high by what the overshoot
    /// compressed). The contact's compliance is the rise over the probe's torque beyond the
    /// overshoot; the error it allows is that compliance times the torque's uncertainty
    /// ([`Controller::torque_uncertainty`]) or the overshoot, whichever is larger. Zero where the probe could
    /// not rise far enough to tell (the run's cap or full duty held it: `TORQUE_LIMITED` and
    /// `SUPPLY_LIMITED` flag those).
    fn force_sensitivity_um(&self, (rise_deg, fraction): (f32, f32), overshoot: f32) -> f32 {
        let beyond = fraction - overshoot;
        if beyond < MIN_PROBE_FRACTION {
            return 0.0;
        }
        let rise_um = self.run.params.gauge.pitch_um_per_deg * rise_deg.max(0.0);
        rise_um / beyond * self.torque_uncertainty().max(overshoot)
    }

    /// How far the torque's uncertainty could move the reading, µm, judged from the approach
    /// ([`Run::approach`]): the hub turned from the approach's start to the held median while the
    /// torque rose to the held one, so the contact's compliance is at least that turn over that
    /// rise (a slip on the way, stick-slip, counts in full: it is what a torque error that size
    /// does). The probe after the hold cannot see this where the drive train's and the inset's
    /// static friction hold the hub at the jam: a torque 10 % higher does not break it loose,
    /// and the probe reads a stiff contact. Where the torque rose by less than
    /// [`MIN_APPROACH_FRACTION`] of the held one, the force's rise is taken, if the probe could
    /// not move the hub ([`Controller::approach_force_turn`]); zero otherwise.
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

    /// The approach to `held` ([`Run::approach`]): how far the hub turned, degrees, while the
    /// torque rose how much, N·m, from the approach's start to the held jam; `None` where the
    /// torque rose by less than [`MIN_APPROACH_FRACTION`] of the held one (a jam reached at the
    /// approach's start, or one the target followed down along the spiral: see
    /// [`Controller::approach_force_turn`]).
    fn approach_turn(&self, held: &HeldJam) -> Option<(f32, f32)> {
        let start = self.run.approach?;
        let rise_nm = held.torque_nm - start.torque_nm;
        (rise_nm >= MIN_APPROACH_FRACTION * held.torque_nm)
            .then(|| (start.turn_to_held_deg(held), rise_nm))
    }

    /// The approach to `held`, for one whose torque hardly rose ([`Controller::approach_turn`]
    /// is `None`: its caller asks that first), where the probe could not move the hub: how far
    /// the hub turned, degrees, while the force rose how much, as a share of the held torque,
    /// N·m. The target for the run's force falls along the spiral, so a contact giving way at
    /// that force (crushing past its yield)
    /// lets the hub turn on far with no rise in torque, while the force rose from at most
    /// [`APPROACH_FRACTION`] of the target to all of it (on the twin a contact yielding at
    /// 178 N turned the hub 26° so, read 38 µm high and was not flagged). Only for the flag: the
    /// winding check's allowance keeps the torque's rise, which such a contact would make
    /// unbounded. Where the probe moved the hub it measured the contact itself, and a free hub
    /// crawling to the jam at high torque (a high-ratio build) turns as far with no contact to
    /// give way: `None`.
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

    /// Releasing: ramp the torque down, then back off to measure the play
    /// ([`Controller::back_off`]) where [`Controller::may_back_off`], else `Done`.
    pub(super) fn release(&mut self) {
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
    pub(super) fn back_off(&mut self, from_deg: Option<f32>, ticks: u32, still: u32) {
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
