//! The measuring controller: a pure state machine stepped at a fixed rate (1 kHz).
//!
//! ```text
//!            Run                       θ ≥ θplay(0)          still at τ(θs)          hold done
//!   Idle ───▶ Waking ───▶ Engaging ─────────────▶ Ramping ──────────────▶ Jammed ───(probe, check)──▶ Releasing ──(back off)──▶ Done
//!    ▲  ▲                                     ▲                       │ slipped                          │
//!    │  │ Abort (any state, safe this tick)   └───────────────────────┘                                 │
//!    │  └──────────── Resetting ◀── Reset (Idle, Done, Fault) ◀──────────────────────────────────────────┘
//!    └── ClearFault ── Fault(reason) ◀── any state, the tick a fault is detected (motor safe that tick)
//! ```
//!
//! [`Controller::step`] takes this tick's [`Inputs`] (hub angle from the encoder driver, encoder
//! diagnostics when they were read, motor current or that it is unknown, the driver's FLT line,
//! the motor supply when it is measured)
//! and returns the [`MotorOutput`] to apply. The device's request handler calls the typed
//! methods between steps: [`Controller::start_run`], [`Controller::start_reset`],
//! [`Controller::start_self_test`], [`Controller::abort`], [`Controller::clear_fault`] act;
//! [`Controller::status`], [`Controller::result`], [`Controller::sample_chunk`] and
//! [`Controller::self_test_report`] read. Every request first goes to
//! [`Controller::host_activity`], which feeds the communication watchdog. No I/O, no allocation,
//! no waiting: the board binary and the twin call it the same way.
//!
//! The code is split by concern: `run.rs` (engage, ramp, jam, kerf, and the per-run state, which
//! every run builds afresh), `reset.rs`, `wake.rs` (the brake that starts a run or a reset),
//! `self_test.rs`, `faults.rs` (every fault check),
//! `supply.rs` (the measured supply and what it does to the duty), `winding.rs` (the winding's
//! resistance from the current at the jam, and what it does to the duty) and `tuning.rs` (every tuning
//! constant, with its unit and its reason; re-exported here).
//!
//! # Angles, torque and direction
//!
//! The encoder driver reports the hub angle clockwise-positive seen from above (`encoder_inverted`
//! in the configuration makes it so); `DIR` high turns the hub clockwise (`motor_inverted` makes
//! it so). The controller works in the *jam frame*: θ and τ positive in the gauge's
//! `jam_direction`, sent with every run.
//!
//! # Torque from duty
//!
//! Output torque is linear in duty × supply at standstill: duty = (breakaway + τ /
//! torque_per_duty) × ρ × V_ref / V_supply, where `breakaway_duty` covers the gearbox's friction and
//! both calibration figures are at the reference supply V_ref =
//! [`REFERENCE_SUPPLY_V`](kerfmeter_protocol::REFERENCE_SUPPLY_V) (12 V). V_supply is the measured
//! motor supply, filtered, or V_ref where it is not measured: see `supply.rs` for the filter, the
//! rated range, the refusal of a run whose torque is out of reach (`SupplyTooLow`) and what a
//! supply sagging mid-run does (the torque is held to what full duty delivers, and the result
//! flagged `SUPPLY_LIMITED`). The duty is also scaled by the winding's resistance over its
//! resistance at calibration, ρ, estimated from the measured current where the hub stands still
//! at the jam (`winding.rs`: a warm winding draws less current for the same duty); a ρ that
//! the winding's temperature and the senses' gain errors cannot explain flags the result
//! `TORQUE_MISMATCH`. Back-EMF lowers the torque while the hub turns
//! (by ke·N·ω/Vs of duty); it is deliberately *not* compensated: the kerf is read at a jam, at
//! standstill, where back-EMF is zero and the duty-derived torque is exact; while the inset turns
//! a lower torque only slows the approach, and the ramp's speed limit keeps it slow anyway.
//!
//! # The run
//!
//! A run starts only with the hub within
//! [`START_TOLERANCE_DEG`](kerfmeter_protocol::START_TOLERANCE_DEG) of zero (the protocol's rule,
//! shared with the host).
//!
//! - **Waking** (reported as `Engaging`): the driver woken and braking (duty 0) so that the
//!   current sense learns its offset awake before anything drives (`wake.rs`). A reset starts
//!   the same way (reported as `Resetting`).
//! - **Engaging**: a speed-limited low torque turns the hub through the hole play. No kerf can
//!   have less play than θplay(0), so the hub is driven at least that far before the ramp starts.
//! - **Ramping**: torque rises at `ramp_rate_nm_per_s`, never above τ(θs) = (2π − 2θs)·r²·L·F/A_j
//!   for the inset angle θs of the current hub angle (the torque that presses the inset as hard
//!   as the joint is pressed by F), nor above `max_torque_nm` (the result is then flagged
//!   `TORQUE_LIMITED`), nor above what full duty gives at the measured supply (flagged
//!   `SUPPLY_LIMITED`), and is eased off when the hub turns faster than
//!   [`MAX_TURN_SPEED_DEG_PER_S`] so that the inset never slams into the jam.
//! - **Jam**: the angle's change over a [`JAM_WINDOW_TICKS`]-tick regression stays within
//!   [`JAM_STILL_LSB`] encoder LSB for [`JAM_SETTLE_TICKS`] ticks, with the torque at its target
//!   (above breakaway) and the inset past [`JAM_MIN_INSET_DEG`]. Then the torque is held for
//!   [`HOLD_TICKS`] ticks; θm is the median angle over the hold. If the hub slips by more than
//!   [`JAM_SLIP_DEG`] meanwhile, the ramp resumes.
//! - **Probing** (reported as `Jammed`): the torque rises by [`PROBE_FRACTION`] and how far the
//!   hub turns on says how far a torque error would move the reading (`FORCE_SENSITIVE`); so
//!   do the hub's turns from the approach's start and from the run's first settle to the hold,
//!   each over the rise in torque or force between them (`run.rs`, `judge_hold`).
//! - **Checking the winding** (reported as `Jammed`), only where no settle's duty could measure
//!   the winding: the torque rises to a duty the current sense reads and the winding is measured
//!   there (`winding.rs`, "After the hold").
//! - **Releasing** ramps the torque down, then **backs off** (still reported as `Releasing`):
//!   the hub turns back against the jammed inset until the prongs stall on the holes' far faces,
//!   and the kerf is read with half that turn as the hole play instead of the model's (`run.rs`,
//!   "Measured play"). **Done** holds the result for `GetKerf`.
//!
//! # Cost per tick
//!
//! The ESP32-C3 has no FPU: every `f32` operation is a soft-float call of tens of instructions.
//! So nothing on the hot path loops over a window or calls a transcendental function it can do
//! without (`cargo xtask bench-step` counts the instructions, see the README):
//!
//! - the hub's slope (speed loop and stillness test) is a least-squares fit kept in integer
//!   running sums, O(1) a tick ([`SlopeWindow`]);
//! - the hole plays that are fixed for a run (θplay(0), where engaging ends, and the overtravel
//!   limit) are computed once, when the run starts;
//! - the ramp's inset angle takes one fixed-point step of the kerf solve a tick (one `asinf`,
//!   about 1.6k instructions), from the last tick's kerf, instead of a full solve (8k);
//! - the full solve and the hold's median (a selection, not a sort) run once, on the tick the
//!   hold ends: the worst tick, about 15k instructions;
//! - the sample log halves itself over eight ticks when it fills, not in one (a 1024-sample move
//!   would add some 9.5k instructions to a tick, see [`SampleLog`]).
//!
//! The step is not placed in RAM (esp-hal's `#[ram]`): its code and the soft-float and `libm`
//! routines it calls are some 12 KB, which stay in the C3's 16 KB instruction cache from one tick
//! to the next unless other work evicts them; `#[ram]` on the step alone would leave its callees
//! in flash, and no cache effect can be measured here (qemu has no cache model, and no board is
//! at hand). [`Controller::tick_timing`] keeps the longest step and gap since boot, which is how
//! a board shows whether it pays.
//!
//! # Faults
//!
//! Checked every tick; the first one found is latched as `Fault(reason)` and the output of that
//! very tick is the safe state: max run time, overtravel past the disengage angle, no motion with
//! torque above breakaway, reverse motion (except backing off, whose turn back is the point),
//! [`MAX_CONSECUTIVE_ENCODER_ERRORS`] encoder errors in a row, failed encoder diagnostics (chip or
//! magnet), over-current (the mean of the last [`OVER_CURRENT_MEAN_TICKS`] currents above the
//! limit, one reading above twice it, or a current that is unknown), driver FLT, host silence
//! (communication watchdog) and a late control step: a gap of more than [`MAX_GAP_PERIODS`] since
//! the last step, or late steps too frequent. An isolated late step is ridden through (the
//! tuning's docs, "Late ticks", say when and why).
//!
//! # Idle conditions
//!
//! The encoder's and the driver's faults (no magnet, failing diagnostics, an unreadable encoder,
//! driver FLT low, as when the motor supply is off) latch only while the motor may be driven. At
//! rest they are *conditions* ([`Controller::conditions`], reported in `Status`), updated every
//! tick and cleared when they go away: they latch nothing, so the device stays configurable
//! and `ClearFault` does not re-latch at once, but they refuse `Run`, `Reset` and `SelfTest`
//! with `ErrorCode::Blocked` (a latched fault is reported first, as `Faulted`). A measured supply
//! outside the rated 9–26 V is a condition too, judged at rest only, and latches nothing during
//! a run (see `supply.rs`). One condition comes from no input: `HUB_TURN_UNKNOWN`, a motor-shaft
//! encoder's hub turn not confirmed since power-up (or since the change onto the motor shaft),
//! which refuses a run only and goes when the user confirms the hub at its mark (`reset.rs`).

use kerfmeter_protocol::{
    Conditions, DeviceConfig, EncoderPlacement, ErrorCode, Fault, JamDirection, KerfResult,
    RunParams, RunState, Sample, SampleChunk, SelfTestReport, Status,
};

use crate::as5048a::{COUNTS_PER_TURN, DiagnosticFault};
use crate::build::{CONTROL_RATE_HZ, MAX_SAMPLES};
use crate::jam::SlopeWindow;
use crate::motor::MotorOutput;
use crate::samples::SampleLog;

mod faults;
mod reset;
mod run;
mod self_test;
mod supply;
#[cfg(test)]
mod tests;
mod timing;
mod tuning;
mod wake;
mod winding;

use run::Run;
use self_test::SelfTestPhase;
use supply::SupplyFilter;
pub use supply::{SUPPLY_FILTER_GAIN, SUPPLY_SENSE_ADC_ERROR_V, SUPPLY_SENSE_TOLERANCE};
use timing::Pacing;
pub use timing::TickTiming;
pub use tuning::*;
use wake::Woken;
use winding::WindingEstimate;
pub use winding::{
    CHECK_READINGS as WINDING_CHECK_READINGS, MIN_DUTY as WINDING_MIN_DUTY,
    PLAUSIBLE_FACTOR as WINDING_PLAUSIBLE_FACTOR,
};

/// Why an encoder read failed (the driver's error, without the bus type).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncoderFault {
    /// The SPI transfer failed.
    Bus,
    /// Bad parity on a response.
    Parity,
    /// The chip's error flag.
    ErrorFlag,
    /// An impossible jump.
    Jump,
}

/// The encoder diagnostics, as the controller needs them.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DiagnosticsReading {
    /// CORDIC magnitude.
    pub magnitude: u16,
    /// AGC near the edge of its band.
    pub marginal: bool,
}

/// What the controller reads each tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inputs {
    /// Hub angle from zero, degrees, clockwise-positive seen from above; or why it is missing.
    pub angle_deg: Result<f32, EncoderFault>,
    /// The encoder diagnostics, on the ticks they were read.
    pub diagnostics: Option<Result<DiagnosticsReading, DiagnosticFault>>,
    /// Motor current magnitude, A: the current in the winding (the RC-filtered current sense
    /// divided by the duty filtered alike, `board::current`), not the `CS` pin's pulsed reading;
    /// `None` when it is unknown (no fresh reading, or one clipped at the ADC's range). An
    /// unknown current cannot be shown to be within `max_current_a`, so it faults with
    /// `OverCurrent` like a current above it.
    pub current_a: Option<f32>,
    /// The driver's FLT line is low.
    pub driver_fault: bool,
    /// Motor supply (the G2's `VIN`), volts, as the supply-sense divider and ADC measure it
    /// (`board::supply`); `None` where it is not measured (a board built without the divider;
    /// the board binary and the digital twin both measure it). Filtered, it scales the duty and is
    /// reported in `Status` (see `supply.rs`, and "Torque from duty" above).
    pub supply_v: Option<f32>,
}

/// `us` as a `u32`, saturated (a figure in `Status`).
fn saturate_u32(us: u64) -> u32 {
    u32::try_from(us).unwrap_or(u32::MAX)
}

/// Internal states, with their working data.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Idle,
    /// A run's or a reset's start: the driver awake and braking, `ticks` into it (`wake.rs`).
    Waking {
        ticks: u32,
        then: Woken,
    },
    Engaging,
    Ramping,
    Jammed {
        torque_nm: f32,
        entry_deg: f32,
    },
    /// After the hold, still reported as `Jammed`: the torque raised to `torque_nm` to see how
    /// far the reading would move (`run.rs`, `FORCE_SENSITIVE`).
    Probing {
        torque_nm: f32,
        ticks: u32,
    },
    /// After the probe, still reported as `Jammed`, where no settle could measure the winding:
    /// the torque raised to `torque_nm` to measure it (`run.rs`, `winding.rs`).
    CheckingWinding {
        torque_nm: f32,
        ticks: u32,
    },
    Releasing,
    /// After the release, reported as `Releasing`: the hub turned back through the hole play
    /// against the jammed inset to measure it (`run.rs`, "Measured play").
    BackingOff {
        from_deg: Option<f32>,
        ticks: u32,
        still: u32,
    },
    Done,
    Resetting {
        ticks: u32,
        settled: u32,
    },
    SelfTest(SelfTestPhase),
    Fault(Fault),
}

impl State {
    /// The states of a run, from `Run` to `Done`.
    fn is_run(self) -> bool {
        matches!(
            self,
            State::Engaging
                | State::Ramping
                | State::Jammed { .. }
                | State::Probing { .. }
                | State::CheckingWinding { .. }
                | State::Releasing
                | State::BackingOff { .. }
        )
    }
}

/// The hub's recent motion and the speed loop's memory. A run and a reset each start a fresh one.
struct Motion {
    /// The last angles, for the regression.
    slope: SlopeWindow,
    /// This tick's fitted slope, degrees per tick (fitted only while the motor may be driven).
    slope_deg_per_tick: f32,
    /// The speed loop's integral term, N·m.
    speed_integral_nm: f32,
}

impl Motion {
    const fn new() -> Self {
        Self {
            slope: SlopeWindow::new(),
            slope_deg_per_tick: 0.0,
            speed_integral_nm: 0.0,
        }
    }
}

/// The measuring controller.
pub struct Controller {
    config: DeviceConfig,
    state: State,
    /// The jam frame's sense: the gauge's, from the last valid run request (also one refused as
    /// not at zero). Reset and self-test keep working in it.
    jam_direction: JamDirection,
    /// The current (or last) run's own state.
    run: Run,
    run_id: u32,
    /// The late-tick rules, and this step's integration time.
    pacing: Pacing,
    /// The time this step integrates, µs (see [`Pace`](timing::Pace)).
    dt_us: u32,
    /// The longest step and gap between steps since boot.
    timing: TickTiming,
    last_host_us: u64,
    /// Commanded torque, N·m, jam frame.
    torque_nm: f32,
    /// Last good hub angle, degrees, jam frame.
    angle_deg: f32,
    have_angle: bool,
    motion: Motion,
    /// The farthest from zero a reset may take the hub, degrees (set as it starts).
    reset_limit_deg: f32,
    consecutive_encoder_errors: u16,
    last_diagnostics: Option<DiagnosticsReading>,
    /// The idle conditions as of the last tick (see [`Controller::conditions`]).
    conditions: Conditions,
    /// Moved on by `ConfirmHubAtZero`: the encoder driver restarts its turn count when it
    /// changes ([`Controller::encoder_epoch`]).
    encoder_epoch: u16,
    /// The motor supply, filtered, and the duty scale it gives (the winding's factor included).
    supply: SupplyFilter,
    /// The winding's resistance over the calibration's, from the current at the jams.
    winding: WindingEstimate,
    /// The duty of the last step's output (what this step's current reading was drawn at).
    applied_duty: f32,
    /// The last ticks' motor currents, for the over-current check.
    current_mean: faults::CurrentMean,
    /// The last run's samples (kept outside [`Run`]: 24 KiB are cleared, not rebuilt).
    log: SampleLog<{ MAX_SAMPLES as usize }>,
    result: Option<KerfResult>,
    self_test: Option<SelfTestReport>,
    self_test_partial: SelfTestReport,
}

impl Controller {
    /// A controller in `Idle`, motor safe; with the encoder on the motor shaft, its hub's turn
    /// unknown until confirmed ([`Conditions::HUB_TURN_UNKNOWN`], `reset.rs`).
    pub fn new(config: DeviceConfig) -> Self {
        let motor_shaft = config.encoder_placement == EncoderPlacement::MotorShaft;
        let mut conditions = Conditions::empty();
        conditions.set(Conditions::HUB_TURN_UNKNOWN, motor_shaft);
        Self {
            config,
            state: State::Idle,
            jam_direction: RunParams::DEFAULT.gauge.jam_direction,
            run: Run::new(RunParams::DEFAULT, 0.0),
            run_id: 0,
            pacing: Pacing::new(),
            dt_us: PERIOD_US as u32,
            timing: TickTiming::new(),
            last_host_us: 0,
            torque_nm: 0.0,
            angle_deg: 0.0,
            have_angle: false,
            motion: Motion::new(),
            reset_limit_deg: 0.0,
            consecutive_encoder_errors: 0,
            last_diagnostics: None,
            conditions,
            encoder_epoch: 0,
            supply: SupplyFilter::new(),
            winding: WindingEstimate::new(),
            applied_duty: 0.0,
            current_mean: faults::CurrentMean::new(),
            log: SampleLog::new(),
            result: None,
            self_test: None,
            self_test_partial: self_test::NOT_RUN,
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> &DeviceConfig {
        &self.config
    }

    /// The motor driver is `driver` (the board's, or the twin's): its safe maximum supply bounds
    /// `SUPPLY_OUT_OF_RANGE` (see `supply.rs`).
    pub fn set_driver(&mut self, driver: kerfmeter_protocol::G2Variant) {
        self.supply.set_driver(driver);
    }

    /// Replace the configuration; only while the motor is at rest, and a motor-shaft encoder's
    /// settings only at zero ([`Controller::check_config_change`]).
    pub fn set_config(&mut self, config: DeviceConfig) -> Result<(), ErrorCode> {
        config.validate().map_err(ErrorCode::InvalidParam)?;
        if self.is_active() {
            return Err(ErrorCode::Busy);
        }
        self.check_config_change(&config)?;
        // On the output shaft the encoder is absolute over the hub's turn: nothing to confirm. A
        // change onto the motor shaft was judged "at zero" by the old settings, which cannot
        // tell one motor turn from the next: the user confirms the hub at its mark.
        let motor_shaft = config.encoder_placement == EncoderPlacement::MotorShaft;
        let onto_motor_shaft =
            motor_shaft && self.config.encoder_placement != EncoderPlacement::MotorShaft;
        let unknown = self.conditions.contains(Conditions::HUB_TURN_UNKNOWN) || onto_motor_shaft;
        self.conditions
            .set(Conditions::HUB_TURN_UNKNOWN, motor_shaft && unknown);
        // The winding's factor was measured against the old calibration's reference
        // resistance: after a new one (a mismatch corrected) it would scale every duty by a
        // ratio that no longer holds, until the next settle measured it again.
        let recalibrated = config.torque_per_amp_nm != self.config.torque_per_amp_nm
            || config.torque_per_duty_nm != self.config.torque_per_duty_nm;
        if recalibrated {
            self.winding = WindingEstimate::new();
            self.supply.set_winding_factor(self.winding.factor());
        }
        self.config = config;
        Ok(())
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        match self.state {
            State::Fault(f) => Some(f),
            _ => None,
        }
    }

    /// True while the motor may be driven (a run, a reset or a self-test).
    pub fn is_active(&self) -> bool {
        !matches!(self.state, State::Idle | State::Done | State::Fault(_))
    }

    /// The id of the last run started (0 before the first).
    pub fn run_id(&self) -> u32 {
        self.run_id
    }

    /// The last result (`GetKerf`): `None` before the first run, during a run and after a reset.
    pub fn result(&self) -> Option<&KerfResult> {
        // The result is solved as the release starts and completed by the back-off: not
        // published until the run has ended (or a fault or abort ended it: then with the
        // model's play, flagged `PLAY_MODELLED`).
        if self.state.is_run() {
            return None;
        }
        self.result.as_ref()
    }

    /// The run's sample log: whole from the first step after the run ended (Done, a fault or an
    /// abort; mid-run, while the log halves itself, its first part: see
    /// [`SampleLog::as_slice`]). `GetSamples` ([`Controller::sample_chunk`]) is exact throughout.
    pub fn samples(&self) -> &[Sample] {
        self.log.as_slice()
    }

    /// The run's samples from index `from` (`GetSamples`); `NoSamples` before the first run or
    /// past the end of the log.
    pub fn sample_chunk(&self, from: u16) -> Result<SampleChunk, ErrorCode> {
        match self.log.chunk(self.run_id, from) {
            Some(chunk) if self.run_id > 0 => Ok(chunk),
            _ => Err(ErrorCode::NoSamples),
        }
    }

    /// The last self-test's report (`GetSelfTest`): `None` before the first and while one runs.
    pub fn self_test_report(&self) -> Option<&SelfTestReport> {
        self.self_test.as_ref()
    }

    /// The public state.
    pub fn run_state(&self) -> RunState {
        match self.state {
            State::Idle => RunState::Idle,
            State::Waking {
                then: Woken::Run, ..
            }
            | State::Engaging => RunState::Engaging,
            State::Ramping => RunState::Ramping,
            State::Jammed { .. } | State::Probing { .. } | State::CheckingWinding { .. } => {
                RunState::Jammed
            }
            State::Releasing | State::BackingOff { .. } => RunState::Releasing,
            State::Done => RunState::Done,
            State::Waking {
                then: Woken::Reset, ..
            }
            | State::Resetting { .. } => RunState::Resetting,
            State::SelfTest(_) => RunState::SelfTest,
            State::Fault(f) => RunState::Fault(f),
        }
    }

    /// What `GetStatus` answers.
    pub fn status(&self) -> Status {
        Status {
            state: self.run_state(),
            run_id: self.run_id,
            elapsed_ms: self.run.ticks * 1000 / u32::from(CONTROL_RATE_HZ),
            torque_nm: self.torque_nm,
            angle_deg: self.angle_deg,
            samples: self.log.len() as u16,
            encoder_errors: self.run.encoder_errors,
            supply_v: self.supply.supply_v(),
            longest_step_us: saturate_u32(self.timing.longest_step_us()),
            longest_gap_us: saturate_u32(self.timing.longest_gap_us()),
            conditions: self.conditions,
        }
    }

    /// The idle conditions as of the last tick, in every state: what the inputs say is wrong
    /// (see `faults.rs`), and whether a motor-shaft encoder's hub turn awaits the user's
    /// confirmation. While idle they only block a run, reset or self-test (that one a run only);
    /// during one the inputs latch a fault.
    pub fn conditions(&self) -> Conditions {
        self.conditions
    }

    /// The longest step and the longest gap between steps since boot.
    pub fn tick_timing(&self) -> &TickTiming {
        &self.timing
    }

    /// The step that started last (the `now_us` of the last [`Controller::step`]) ended at
    /// `end_us`: its caller reads the clock once the tick's work is done, so that the longest
    /// step counts the whole tick, drivers included.
    pub fn step_finished(&mut self, end_us: u64) {
        self.timing.finished(end_us);
    }

    /// A request from the host arrived at `now_us`. Every request, whatever it asks, counts as
    /// host activity for the communication watchdog: the device calls this for each one.
    pub fn host_activity(&mut self, now_us: u64) {
        self.last_host_us = now_us;
    }

    /// Stop the motor now (safe from the next step on) and end the run, reset or self-test. A
    /// latched fault stays latched.
    pub fn abort(&mut self) {
        if !matches!(self.state, State::Fault(_)) {
            self.state = State::Idle;
        }
        self.torque_nm = 0.0;
    }

    /// Leave a latched fault (the motor stays safe); nothing happens without one. The idle
    /// conditions stay as the inputs last said: the encoder's clear at its next good read or
    /// diagnostics reading (within the diagnostics period), so a run asked for meanwhile is
    /// refused with the condition rather than started on an encoder that was failing (it drove
    /// up to a diagnostics period blind when they were forgotten here).
    pub fn clear_fault(&mut self) {
        if let State::Fault(_) = self.state {
            self.state = State::Idle;
        }
    }

    /// Refuses with `Faulted` or `Busy` unless the motor is at rest with no fault latched, and
    /// with `Blocked` while one of the `blocking` idle conditions stands.
    fn refuse_unless_ready(&self, blocking: Conditions) -> Result<(), ErrorCode> {
        match self.state {
            State::Fault(f) => Err(ErrorCode::Faulted(f)),
            State::Idle | State::Done => self.refuse_if_blocked(blocking),
            _ => Err(ErrorCode::Busy),
        }
    }

    /// Refuses with `Blocked` while one of the `blocking` idle conditions stands
    /// ([`Conditions::BLOCKING`], or [`Conditions::BLOCKING_RUN`] for a run).
    fn refuse_if_blocked(&self, blocking: Conditions) -> Result<(), ErrorCode> {
        let blocking = self.conditions.intersection(blocking);
        if blocking.is_empty() {
            Ok(())
        } else {
            Err(ErrorCode::Blocked(blocking))
        }
    }

    /// The last known hub angle, clockwise-positive.
    fn angle_deg_cw(&self) -> f32 {
        // `angle_deg` is kept in the jam frame; the jam frame is its own inverse.
        self.jam_frame(self.angle_deg)
    }

    /// Clockwise ↔ jam frame.
    fn jam_frame(&self, deg: f32) -> f32 {
        match self.jam_direction {
            JamDirection::Clockwise => deg,
            JamDirection::CounterClockwise => -deg,
        }
    }

    /// One control step at `now_us`: read the inputs, advance the state, return the motor output.
    pub fn step(&mut self, now_us: u64, inputs: &Inputs) -> MotorOutput {
        let pace = self.pacing.step(now_us, self.is_active());
        self.dt_us = pace.dt_us;
        self.timing.started(now_us);

        let fresh = self.read_angle(inputs);
        self.supply.update(inputs.supply_v);
        self.update_conditions(inputs);
        if let Some(fault) = self.check_faults(now_us, inputs, pace.overrun) {
            self.latch(fault);
            return MotorOutput::SAFE;
        }
        if let Some(angle) = fresh {
            self.motion.slope.push(angle);
        }
        // The least-squares slope, read once per tick from the window's running sums: the speed
        // loop and the stillness test both use it, and only while the motor may be driven; at
        // rest nothing reads it.
        if self.is_active() {
            self.motion.slope_deg_per_tick = self.motion.slope.slope_deg_per_tick();
        }
        self.advance(inputs, fresh);
        if let Some(fault) = self.check_run_limits() {
            self.latch(fault);
            return MotorOutput::SAFE;
        }
        if self.state.is_run() {
            self.record_sample();
        } else {
            // No run (any more): finish a halving of the log under way (nothing otherwise), so
            // that `samples()` is the whole run. Not in the tick a fault latches: that tick only
            // makes the motor safe.
            self.log.settle();
        }
        let out = self.output();
        self.applied_duty = out.duty;
        out
    }

    fn read_angle(&mut self, inputs: &Inputs) -> Option<f32> {
        match inputs.angle_deg {
            Ok(cw) => {
                self.consecutive_encoder_errors = 0;
                self.angle_deg = self.jam_frame(cw);
                self.have_angle = true;
                Some(self.angle_deg)
            }
            Err(_) => {
                self.consecutive_encoder_errors = self.consecutive_encoder_errors.saturating_add(1);
                if self.is_active() {
                    self.run.encoder_error();
                }
                None
            }
        }
    }

    fn advance(&mut self, inputs: &Inputs, fresh: Option<f32>) {
        match self.state {
            State::Idle | State::Done | State::Fault(_) => self.torque_nm = 0.0,
            State::Waking { ticks, then } => self.wake(ticks, then),
            State::Engaging => self.engage(),
            State::Ramping => self.ramp(inputs.current_a),
            State::Jammed {
                torque_nm,
                entry_deg,
            } => self.hold_jam(torque_nm, entry_deg, fresh),
            State::Probing { torque_nm, ticks } => self.probe(torque_nm, ticks),
            State::CheckingWinding { torque_nm, ticks } => {
                self.check_winding(torque_nm, ticks, inputs.current_a)
            }
            State::Releasing => self.release(),
            State::BackingOff {
                from_deg,
                ticks,
                still,
            } => self.back_off(from_deg, ticks, still),
            State::Resetting { ticks, settled } => self.reset_step(ticks, settled),
            State::SelfTest(phase) => self.self_test_step(phase, inputs, fresh),
        }
    }

    fn breakaway_torque_nm(&self) -> f32 {
        self.config.breakaway_duty * self.config.torque_per_duty_nm
    }

    /// One encoder LSB as hub angle, degrees.
    fn lsb_deg(&self) -> f32 {
        let turns_per_hub_turn = match self.config.encoder_placement {
            EncoderPlacement::OutputShaft => 1.0,
            EncoderPlacement::MotorShaft => self.config.gear_ratio,
        };
        360.0 / f32::from(COUNTS_PER_TURN) / turns_per_hub_turn
    }

    /// The time this step integrates, seconds: the gap since the last step, at most
    /// [`MAX_STEP_DT_US`] (see the tuning's docs, "Late ticks").
    fn dt_s(&self) -> f32 {
        self.dt_us as f32 * 1e-6
    }

    fn speed_deg_per_s(&self) -> f32 {
        self.motion.slope_deg_per_tick * f32::from(CONTROL_RATE_HZ)
    }

    /// The speed loop (PI): the torque, within ±`cap_nm`, that holds the hub at `target`
    /// degrees per second. The integrator is clamped to the same bounds (no wind-up).
    /// `dt_s` is this step's [`Controller::dt_s`] (its caller may need it too: one soft-float
    /// conversion a step).
    fn speed_loop(&mut self, target_deg_per_s: f32, cap_nm: f32, dt_s: f32) -> f32 {
        let error = target_deg_per_s - self.speed_deg_per_s();
        let integral = &mut self.motion.speed_integral_nm;
        *integral = (*integral + SPEED_KI * error * dt_s).clamp(-cap_nm, cap_nm);
        (SPEED_KP * error + *integral).clamp(-cap_nm, cap_nm)
    }

    /// The motor output for the current torque (jam frame).
    fn output(&self) -> MotorOutput {
        if !self.is_active() {
            return MotorOutput::SAFE;
        }
        if self.torque_nm == 0.0 {
            // Active but no torque wanted: brake (both low-side switches on) rather than coast.
            return MotorOutput::BRAKE;
        }
        let reference_duty =
            self.config.breakaway_duty + self.torque_nm.abs() / self.config.torque_per_duty_nm;
        let duty = reference_duty * self.supply.duty_scale();
        let clockwise = self.jam_frame(self.torque_nm) > 0.0;
        MotorOutput {
            // Not a number (nothing known makes one) drives nothing rather than full duty.
            duty: if duty.is_nan() { 0.0 } else { duty.min(1.0) },
            dir_high: clockwise != self.config.motor_inverted,
            awake: true,
        }
    }
}
