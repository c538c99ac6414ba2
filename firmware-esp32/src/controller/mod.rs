//! The measuring controller: a pure state machine stepped at a fixed rate (1 kHz).
//!
//! ```text
//!            Run                 θ ≥ θplay(0)          still at τ(θs)          hold done
//!   Idle ─────────▶ Engaging ─────────────▶ Ramping ──────────────▶ Jammed ─────────────▶ Releasing ──▶ Done
//!    ▲  ▲                                     ▲                       │ slipped                          │
//!    │  │ Abort (any state, safe this tick)   └───────────────────────┘                                 │
//!    │  └──────────── Resetting ◀── Reset (Idle, Done, Fault) ◀──────────────────────────────────────────┘
//!    └── ClearFault ── Fault(reason) ◀── any state, the tick a fault is detected (motor safe that tick)
//! ```
//!
//! [`Controller::step`] takes this tick's [`Inputs`] (hub angle from the encoder driver, encoder
//! diagnostics when they were read, motor current, the driver's FLT line) and returns the
//! [`MotorOutput`] to apply. [`Controller::request`] carries out the protocol's run requests.
//! No I/O, no allocation, no waiting: the board binary and the twin call it the same way.
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
//! Output torque is linear in duty at standstill: duty = breakaway + τ / torque_per_duty, where
//! `breakaway_duty` covers the gearbox's friction. Back-EMF lowers the torque while the hub turns
//! (by ke·N·ω/Vs of duty); it is deliberately *not* compensated: the kerf is read at a jam, at
//! standstill, where back-EMF is zero and the duty-derived torque is exact; while the inset turns
//! a lower torque only slows the approach, and the ramp's speed limit keeps it slow anyway.
//!
//! # The run
//!
//! - **Engaging**: a speed-limited low torque turns the hub through the hole play. No kerf can
//!   have less play than θplay(0), so the hub is driven at least that far before the ramp starts.
//! - **Ramping**: torque rises at `ramp_rate_nm_per_s`, never above τ(θs) = (2π − 2θs)·r²·L·F/A_j
//!   for the inset angle θs of the current hub angle (the torque that presses the inset as hard
//!   as the joint is pressed by F), nor above `max_torque_nm` (the result is then flagged
//!   `TORQUE_LIMITED`), and is eased off when the hub turns faster than [`MAX_TURN_SPEED_DEG_PER_S`]
//!   so that the inset never slams into the jam.
//! - **Jam**: the angle's change over a [`JAM_WINDOW_TICKS`]-tick regression stays within
//!   [`JAM_STILL_LSB`] encoder LSB for [`JAM_SETTLE_TICKS`] ticks, with the torque at its target
//!   (above breakaway) and the inset past [`JAM_MIN_INSET_DEG`]. Then the torque is held for
//!   [`HOLD_TICKS`] ticks; θm is the median angle over the hold. If the hub slips by more than
//!   [`JAM_SLIP_DEG`] meanwhile, the ramp resumes.
//! - **Releasing** ramps the torque down; **Done** holds the result for `GetKerf`.
//!
//! # Faults
//!
//! Checked every tick; the first one found is latched as `Fault(reason)` and the output of that
//! very tick is the safe state: max run time, overtravel past the disengage angle, no motion with
//! torque above breakaway, reverse motion, [`MAX_CONSECUTIVE_ENCODER_ERRORS`] encoder errors in a
//! row, failed encoder diagnostics (chip or magnet), over-current, driver FLT, host silence
//! (communication watchdog) and a late control step.

use kerfmeter_protocol::{
    DeviceConfig, ErrorCode, Fault, KerfResult, QualityFlags, Request, Response, RunParams,
    RunState, Sample, SelfTestItem, SelfTestReport, Status, TestOutcome,
};

use crate::as5048a::{COUNTS_PER_TURN, DiagnosticFault};
use crate::build::{CONTROL_RATE_HZ, MAX_SAMPLES};
pub use crate::jam::{HOLD_TICKS, JAM_WINDOW_TICKS};
use crate::jam::{HoldWindow, SlopeWindow};
use crate::kerf::{force_for_torque_n, kerf_from_angle, play_deg, torque_for_force_nm};
use crate::motor::MotorOutput;
use crate::samples::SampleLog;

/// Control period, µs.
pub const PERIOD_US: u64 = 1_000_000 / CONTROL_RATE_HZ as u64;
const DT_S: f32 = 1.0 / CONTROL_RATE_HZ as f32;

/// Hub still: fitted angle change over the regression window within this many encoder LSB.
pub const JAM_STILL_LSB: f32 = 4.0;
/// Ticks the hub must stay still, at target torque, before the hold starts.
pub const JAM_SETTLE_TICKS: u32 = 20;
/// A jam only counts with the inset turned at least this far (less is no inset motion at all).
pub const JAM_MIN_INSET_DEG: f32 = 1.0;
/// Movement during the hold that means the jam slipped: back to ramping.
pub const JAM_SLIP_DEG: f32 = 0.3;
/// A hold whose angles spread more than this many LSB is flagged `NOISY_HOLD`.
pub const NOISY_HOLD_LSB: f32 = 8.0;
/// Flag `NEAR_DISENGAGE` when the inset turned past this fraction of the disengage angle.
pub const NEAR_DISENGAGE_FRACTION: f32 = 0.9;

/// Engaging speed target, degrees per second.
pub const ENGAGE_SPEED_DEG_PER_S: f32 = 60.0;
/// Engaging torque ceiling, N·m (well above breakaway, far below any measuring torque).
pub const ENGAGE_MAX_TORQUE_NM: f32 = 0.12;
/// While ramping, the hub never turns faster than this, degrees per second, so that the inset
/// does not slam into the jam (the impact would compress the contact beyond the static value).
pub const MAX_TURN_SPEED_DEG_PER_S: f32 = 90.0;
/// Speed loop (engage, ramp ceiling, reset): proportional gain, N·m per (degree per second).
pub const SPEED_KP: f32 = 0.0005;
/// Speed loop: integral gain, N·m per second per (degree per second).
pub const SPEED_KI: f32 = 0.01;
/// Torque ramp-down rate when releasing, N·m per second.
pub const RELEASE_RATE_NM_PER_S: f32 = 4.0;

/// No motion: the hub moved less than this since the run started...
pub const NO_MOTION_DEG: f32 = 0.5;
/// ...for this long with torque above breakaway.
pub const NO_MOTION_TICKS: u32 = 500;
/// Overtravel: the inset may turn this far past the gauge's nominal disengage angle (the spiral
/// of the paper's gauge lets go between 155° and 180°; a jam at the largest kerf plus the
/// contact's compression lands just past 155°).
pub const OVERTRAVEL_MARGIN_DEG: f32 = 10.0;
/// Reverse motion: the hub fell back this far from the furthest angle it reached.
pub const REVERSE_TOLERANCE_DEG: f32 = 2.0;
/// Encoder errors in a row that fault the device.
pub const MAX_CONSECUTIVE_ENCODER_ERRORS: u16 = 5;
/// A step later than this many periods after the previous one is an overrun.
pub const OVERRUN_PERIODS: u64 = 3;
/// A run starts only within this angle of zero.
pub const START_TOLERANCE_DEG: f32 = 1.0;

/// Reset: hub speed target per degree from zero, (degrees per second) per degree.
pub const RESET_SPEED_PER_DEG: f32 = 4.0;
/// Reset: fastest return, degrees per second.
pub const RESET_MAX_SPEED_DEG_PER_S: f32 = 90.0;
/// Reset: torque ceiling, N·m.
pub const RESET_MAX_TORQUE_NM: f32 = 0.15;
/// Reset is done within this angle of zero...
pub const RESET_TOLERANCE_DEG: f32 = 0.3;
/// ...held for this many ticks.
pub const RESET_SETTLE_TICKS: u32 = 50;
/// Reset gives up (`ResetFailed`) after this many ticks.
pub const RESET_TIMEOUT_TICKS: u32 = 5_000;
/// Watchdog for reset and self-test (no run parameters to take it from), ms.
pub const DEFAULT_HOST_TIMEOUT_MS: u32 = 1_000;

/// Self-test: ticks of encoder reads with the motor off.
pub const SELFTEST_ENCODER_TICKS: u32 = 100;
/// Self-test: direction-check torque, N·m, and its duration in ticks.
pub const SELFTEST_DIRECTION_TORQUE_NM: f32 = 0.08;
/// Self-test: direction-check duration, ticks.
pub const SELFTEST_DIRECTION_TICKS: u32 = 150;
/// Self-test: minimum motion that passes the direction check, degrees.
pub const SELFTEST_DIRECTION_MIN_DEG: f32 = 1.0;
/// Self-test: settling time before the torque-constant pulse, ticks.
pub const SELFTEST_SETTLE_TICKS: u32 = 150;
/// Self-test: duty of the torque-constant pulse (from standstill), and its length in ticks.
pub const SELFTEST_PULSE_DUTY: f32 = 0.3;
/// Self-test: torque-constant pulse length, ticks (current is averaged over the first ones, before
/// the hub has built up speed and back-EMF).
pub const SELFTEST_PULSE_TICKS: u32 = 20;
/// Self-test: the estimate passes within this fraction of the configured torque constant.
pub const SELFTEST_TORQUE_TOLERANCE: f32 = 0.3;
/// Self-test: fraction of good encoder reads that passes.
pub const SELFTEST_ENCODER_MIN_OK: f32 = 0.99;

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
    /// Motor current magnitude, A.
    pub current_a: f32,
    /// The driver's FLT line is low.
    pub driver_fault: bool,
}

/// Internal states, with their working data.
#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Idle,
    Engaging,
    Ramping,
    Jammed { torque_nm: f32, entry_deg: f32 },
    Releasing,
    Done,
    Resetting { ticks: u32, settled: u32 },
    SelfTest(SelfTestPhase),
    Fault(Fault),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum SelfTestPhase {
    Encoder { ticks: u32, ok: u32 },
    Direction { ticks: u32, start_deg: f32 },
    Settle { ticks: u32 },
    Pulse { ticks: u32, current_sum_a: f32 },
}

/// The measuring controller.
pub struct Controller {
    config: DeviceConfig,
    params: RunParams,
    state: State,
    run_id: u32,
    run_ticks: u32,
    last_step_us: Option<u64>,
    last_host_us: u64,
    torque_nm: f32,
    angle_deg: f32,
    have_angle: bool,
    start_deg: f32,
    max_deg: f32,
    no_motion_ticks: u32,
    still_ticks: u32,
    speed_integral_nm: f32,
    slope_deg_per_tick: f32,
    consecutive_encoder_errors: u16,
    run_encoder_errors: u16,
    flags: QualityFlags,
    last_diagnostics: Option<DiagnosticsReading>,
    slope: SlopeWindow,
    hold: HoldWindow,
    log: SampleLog<{ MAX_SAMPLES as usize }>,
    result: Option<KerfResult>,
    self_test: Option<SelfTestReport>,
    self_test_partial: SelfTestReport,
}

const NOT_RUN: SelfTestItem = SelfTestItem {
    outcome: TestOutcome::Skipped,
    value: 0.0,
};

impl Controller {
    /// A controller in `Idle`, motor safe.
    pub fn new(config: DeviceConfig) -> Self {
        Self {
            config,
            params: RunParams::DEFAULT,
            state: State::Idle,
            run_id: 0,
            run_ticks: 0,
            last_step_us: None,
            last_host_us: 0,
            torque_nm: 0.0,
            angle_deg: 0.0,
            have_angle: false,
            start_deg: 0.0,
            max_deg: 0.0,
            no_motion_ticks: 0,
            still_ticks: 0,
            speed_integral_nm: 0.0,
            slope_deg_per_tick: 0.0,
            consecutive_encoder_errors: 0,
            run_encoder_errors: 0,
            flags: QualityFlags::empty(),
            last_diagnostics: None,
            slope: SlopeWindow::new(),
            hold: HoldWindow::new(),
            log: SampleLog::new(),
            result: None,
            self_test: None,
            self_test_partial: SelfTestReport {
                encoder_ok_fraction: NOT_RUN,
                magnet_magnitude: NOT_RUN,
                direction_deg: NOT_RUN,
                torque_per_duty_nm: NOT_RUN,
            },
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> &DeviceConfig {
        &self.config
    }

    /// Replace the configuration; only while the motor is at rest.
    pub fn set_config(&mut self, config: DeviceConfig) -> Result<(), ErrorCode> {
        config.validate().map_err(ErrorCode::InvalidParam)?;
        if self.is_active() {
            return Err(ErrorCode::Busy);
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

    /// The last result.
    pub fn result(&self) -> Option<&KerfResult> {
        self.result.as_ref()
    }

    /// The run's sample log.
    pub fn samples(&self) -> &[Sample] {
        self.log.as_slice()
    }

    /// The public state.
    pub fn run_state(&self) -> RunState {
        match self.state {
            State::Idle => RunState::Idle,
            State::Engaging => RunState::Engaging,
            State::Ramping => RunState::Ramping,
            State::Jammed { .. } => RunState::Jammed,
            State::Releasing => RunState::Releasing,
            State::Done => RunState::Done,
            State::Resetting { .. } => RunState::Resetting,
            State::SelfTest(_) => RunState::SelfTest,
            State::Fault(f) => RunState::Fault(f),
        }
    }

    /// What `GetStatus` answers.
    pub fn status(&self) -> Status {
        Status {
            state: self.run_state(),
            run_id: self.run_id,
            elapsed_ms: self.run_ticks * 1000 / u32::from(CONTROL_RATE_HZ),
            torque_nm: self.torque_nm,
            angle_deg: self.angle_deg,
            samples: self.log.len() as u16,
            encoder_errors: self.run_encoder_errors,
        }
    }

    /// Carry out a run request received at `now_us`. Every request counts as host activity for
    /// the communication watchdog. Returns `None` for requests that are not the controller's
    /// (`GetInfo`, configuration).
    pub fn request(&mut self, now_us: u64, request: &Request) -> Option<Response> {
        self.last_host_us = now_us;
        let response = match request {
            Request::GetStatus => Response::Status(self.status()),
            Request::Run(params) => self.start_run(now_us, params),
            Request::GetSamples { from } => match self.log.chunk(self.run_id, *from) {
                Some(chunk) if self.run_id > 0 => Response::Samples(chunk),
                _ => Response::Error(ErrorCode::NoSamples),
            },
            Request::GetKerf => Response::Kerf(self.result),
            Request::Reset => self.start_reset(),
            Request::Abort => {
                if !matches!(self.state, State::Fault(_)) {
                    self.state = State::Idle;
                }
                self.torque_nm = 0.0;
                Response::Ok
            }
            Request::ClearFault => {
                if let State::Fault(_) = self.state {
                    self.state = State::Idle;
                    self.consecutive_encoder_errors = 0;
                }
                Response::Ok
            }
            Request::SelfTest => self.start_self_test(),
            Request::GetSelfTest => Response::SelfTest(self.self_test),
            Request::GetInfo | Request::GetConfig | Request::SetConfig(_) => return None,
        };
        Some(response)
    }

    fn refuse_unless_ready(&self) -> Result<(), ErrorCode> {
        match self.state {
            State::Fault(f) => Err(ErrorCode::Faulted(f)),
            State::Idle | State::Done => Ok(()),
            _ => Err(ErrorCode::Busy),
        }
    }

    fn start_run(&mut self, now_us: u64, params: &RunParams) -> Response {
        if let Err(e) = self.refuse_unless_ready() {
            return Response::Error(e);
        }
        if let Err(field) = params.validate() {
            return Response::Error(ErrorCode::InvalidParam(field));
        }
        // The gauge's sense defines the jam frame: re-express the angle in the new one.
        let cw = self.angle_deg_cw();
        self.params = *params;
        let angle = self.jam_frame(cw);
        self.angle_deg = angle;
        if !self.have_angle || angle.abs() > START_TOLERANCE_DEG {
            return Response::Error(ErrorCode::NotAtZero);
        }
        self.run_id = self.run_id.wrapping_add(1).max(1);
        self.result = None;
        self.log.clear();
        self.slope.clear();
        self.hold.clear();
        self.flags = QualityFlags::empty();
        if self.last_diagnostics.is_some_and(|d| d.marginal) {
            self.flags.insert(QualityFlags::WEAK_MAGNET);
        }
        self.run_ticks = 0;
        self.run_encoder_errors = 0;
        self.torque_nm = 0.0;
        self.angle_deg = angle;
        self.start_deg = angle;
        self.max_deg = angle;
        self.no_motion_ticks = 0;
        self.still_ticks = 0;
        self.speed_integral_nm = 0.0;
        self.last_host_us = now_us;
        self.state = State::Engaging;
        Response::Ok
    }

    fn start_reset(&mut self) -> Response {
        match self.state {
            State::Idle | State::Done | State::Fault(_) => {
                self.result = None;
                self.consecutive_encoder_errors = 0;
                self.torque_nm = 0.0;
                self.speed_integral_nm = 0.0;
                self.slope.clear();
                self.state = State::Resetting {
                    ticks: 0,
                    settled: 0,
                };
                Response::Ok
            }
            _ => Response::Error(ErrorCode::Busy),
        }
    }

    fn start_self_test(&mut self) -> Response {
        if let Err(e) = self.refuse_unless_ready() {
            return Response::Error(e);
        }
        self.self_test = None;
        self.self_test_partial = SelfTestReport {
            encoder_ok_fraction: NOT_RUN,
            magnet_magnitude: NOT_RUN,
            direction_deg: NOT_RUN,
            torque_per_duty_nm: NOT_RUN,
        };
        self.torque_nm = 0.0;
        self.state = State::SelfTest(SelfTestPhase::Encoder { ticks: 0, ok: 0 });
        Response::Ok
    }

    /// The last known hub angle, clockwise-positive.
    fn angle_deg_cw(&self) -> f32 {
        // `angle_deg` is kept in the jam frame; the jam frame is its own inverse.
        self.jam_frame(self.angle_deg)
    }

    /// Clockwise ↔ jam frame.
    fn jam_frame(&self, deg: f32) -> f32 {
        match self.params.gauge.jam_direction {
            kerfmeter_protocol::JamDirection::Clockwise => deg,
            kerfmeter_protocol::JamDirection::CounterClockwise => -deg,
        }
    }

    /// One control step at `now_us`: read the inputs, advance the state, return the motor output.
    pub fn step(&mut self, now_us: u64, inputs: &Inputs) -> MotorOutput {
        let overrun = self
            .last_step_us
            .is_some_and(|last| now_us.saturating_sub(last) > OVERRUN_PERIODS * PERIOD_US);
        self.last_step_us = Some(now_us);

        let fresh = self.read_angle(inputs);
        if let Some(fault) = self.check_faults(now_us, inputs, overrun) {
            self.latch(fault);
            return MotorOutput::SAFE;
        }
        if let Some(angle) = fresh {
            self.slope.push(angle);
        }
        // One least-squares fit per tick (it is the step's most expensive part in soft float):
        // the speed loop and the stillness test both use it, and only while the motor may be
        // driven; at rest nothing reads it.
        if self.is_active() {
            self.slope_deg_per_tick = self.slope.slope_deg_per_tick();
        }
        self.advance(inputs, fresh);
        if let Some(fault) = self.check_run_limits() {
            self.latch(fault);
            return MotorOutput::SAFE;
        }
        if matches!(
            self.state,
            State::Engaging | State::Ramping | State::Jammed { .. } | State::Releasing
        ) {
            self.run_ticks += 1;
            self.log.record(Sample {
                t_ms: self.run_ticks * 1000 / u32::from(CONTROL_RATE_HZ),
                torque_nm: self.torque_nm,
                angle_deg: self.angle_deg,
            });
        }
        self.output()
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
                    self.run_encoder_errors = self.run_encoder_errors.saturating_add(1);
                    self.flags.insert(QualityFlags::ENCODER_ERRORS);
                }
                None
            }
        }
    }

    /// Faults that stand regardless of what the controller does this tick.
    fn check_faults(&mut self, now_us: u64, inputs: &Inputs, overrun: bool) -> Option<Fault> {
        if let State::Fault(_) = self.state {
            return None;
        }
        if inputs.driver_fault {
            return Some(Fault::DriverFault);
        }
        if inputs.current_a > self.config.max_current_a {
            return Some(Fault::OverCurrent);
        }
        if self.consecutive_encoder_errors >= MAX_CONSECUTIVE_ENCODER_ERRORS {
            return Some(Fault::EncoderErrors);
        }
        match inputs.diagnostics {
            Some(Err(DiagnosticFault::Chip)) => return Some(Fault::EncoderDiagnostics),
            Some(Err(DiagnosticFault::Magnet)) => return Some(Fault::Magnet),
            Some(Ok(d)) => {
                self.last_diagnostics = Some(d);
                if d.marginal && self.is_active() {
                    self.flags.insert(QualityFlags::WEAK_MAGNET);
                }
            }
            None => {}
        }
        if !self.is_active() {
            return None;
        }
        if overrun {
            return Some(Fault::StepOverrun);
        }
        let timeout_ms = match self.state {
            State::Resetting { .. } | State::SelfTest(_) => DEFAULT_HOST_TIMEOUT_MS,
            _ => self.params.host_timeout_ms,
        };
        if now_us.saturating_sub(self.last_host_us) > u64::from(timeout_ms) * 1000 {
            return Some(Fault::HostSilent);
        }
        None
    }

    /// Faults of the run's motion, checked after the state advanced.
    fn check_run_limits(&mut self) -> Option<Fault> {
        if !matches!(
            self.state,
            State::Engaging | State::Ramping | State::Jammed { .. } | State::Releasing
        ) {
            return None;
        }
        let elapsed_ms = (self.run_ticks + 1) * 1000 / u32::from(CONTROL_RATE_HZ);
        if elapsed_ms > self.params.max_time_ms {
            return Some(Fault::MaxRunTime);
        }
        let gauge = &self.params.gauge;
        if self.angle_deg - play_deg(gauge, gauge.max_kerf_um())
            > gauge.disengage_deg + OVERTRAVEL_MARGIN_DEG
        {
            return Some(Fault::Overtravel);
        }
        self.max_deg = self.max_deg.max(self.angle_deg);
        if self.angle_deg < self.max_deg - REVERSE_TOLERANCE_DEG {
            return Some(Fault::ReverseMotion);
        }
        if matches!(self.state, State::Engaging | State::Ramping) {
            let moved = self.angle_deg - self.start_deg;
            if moved < NO_MOTION_DEG && self.torque_nm > self.breakaway_torque_nm() {
                self.no_motion_ticks += 1;
                if self.no_motion_ticks >= NO_MOTION_TICKS {
                    return Some(Fault::NoMotion);
                }
            } else {
                self.no_motion_ticks = 0;
            }
        }
        None
    }

    fn latch(&mut self, fault: Fault) {
        self.state = State::Fault(fault);
        self.torque_nm = 0.0;
    }

    fn breakaway_torque_nm(&self) -> f32 {
        self.config.breakaway_duty * self.config.torque_per_duty_nm
    }

    fn lsb_deg(&self) -> f32 {
        let turns_per_hub_turn = match self.config.encoder_placement {
            kerfmeter_protocol::EncoderPlacement::OutputShaft => 1.0,
            kerfmeter_protocol::EncoderPlacement::MotorShaft => self.config.gear_ratio,
        };
        360.0 / f32::from(COUNTS_PER_TURN) / turns_per_hub_turn
    }

    fn speed_deg_per_s(&self) -> f32 {
        self.slope_deg_per_tick * f32::from(CONTROL_RATE_HZ)
    }

    fn is_still(&self) -> bool {
        let change_over_window_deg = self.slope_deg_per_tick * (JAM_WINDOW_TICKS - 1) as f32;
        self.slope.is_full() && change_over_window_deg.abs() <= JAM_STILL_LSB * self.lsb_deg()
    }

    fn advance(&mut self, inputs: &Inputs, fresh: Option<f32>) {
        match self.state {
            State::Idle | State::Done | State::Fault(_) => self.torque_nm = 0.0,
            State::Engaging => self.engage(),
            State::Ramping => self.ramp(),
            State::Jammed {
                torque_nm,
                entry_deg,
            } => self.hold_jam(torque_nm, entry_deg, fresh),
            State::Releasing => {
                self.torque_nm = (self.torque_nm - RELEASE_RATE_NM_PER_S * DT_S).max(0.0);
                if self.torque_nm == 0.0 {
                    self.state = State::Done;
                }
            }
            State::Resetting { ticks, settled } => self.reset_step(ticks, settled),
            State::SelfTest(phase) => self.self_test_step(phase, inputs, fresh),
        }
    }

    /// The speed loop (PI): the torque, within ±`cap_nm`, that holds the hub at `target`
    /// degrees per second. The integrator is clamped to the same bounds (no wind-up).
    fn speed_loop(&mut self, target_deg_per_s: f32, cap_nm: f32) -> f32 {
        let error = target_deg_per_s - self.speed_deg_per_s();
        self.speed_integral_nm =
            (self.speed_integral_nm + SPEED_KI * error * DT_S).clamp(-cap_nm, cap_nm);
        (SPEED_KP * error + self.speed_integral_nm).clamp(-cap_nm, cap_nm)
    }

    fn engage(&mut self) {
        self.torque_nm = self
            .speed_loop(ENGAGE_SPEED_DEG_PER_S, ENGAGE_MAX_TORQUE_NM)
            .max(0.0);
        let gauge = &self.params.gauge;
        // No kerf has less play than a zero kerf: the prongs cannot drag the inset before this.
        if self.angle_deg >= play_deg(gauge, 0.0) - JAM_SLIP_DEG {
            self.state = State::Ramping;
        }
    }

    /// The ramp's ceiling at the current angle, and whether `max_torque_nm` capped it.
    fn ramp_target_nm(&self) -> (f32, bool) {
        let inset = kerf_from_angle(&self.params.gauge, self.angle_deg)
            .inset_deg
            .max(0.0);
        let target = torque_for_force_nm(&self.params, self.params.target_force_n, inset);
        if target > self.params.max_torque_nm {
            (self.params.max_torque_nm, true)
        } else {
            (target, false)
        }
    }

    fn ramp(&mut self) {
        let (target, limited) = self.ramp_target_nm();
        // The torque rises at the ramp rate, never above the speed loop's (so the inset turns at
        // most at the speed limit) nor above the target for the current angle.
        let speed_capped = self.speed_loop(MAX_TURN_SPEED_DEG_PER_S, target);
        let ramped = self.torque_nm + self.params.ramp_rate_nm_per_s * DT_S;
        self.torque_nm = ramped.min(speed_capped).clamp(0.0, target);
        let at_target = self.torque_nm >= target * 0.999 && target > self.breakaway_torque_nm();
        let inset = self.angle_deg - play_deg(&self.params.gauge, 0.0);
        if at_target && self.is_still() && inset >= JAM_MIN_INSET_DEG {
            self.still_ticks += 1;
        } else {
            self.still_ticks = 0;
        }
        if self.still_ticks >= JAM_SETTLE_TICKS {
            if limited {
                self.flags.insert(QualityFlags::TORQUE_LIMITED);
            }
            self.hold.clear();
            self.state = State::Jammed {
                torque_nm: self.torque_nm,
                entry_deg: self.angle_deg,
            };
        }
    }

    fn hold_jam(&mut self, torque_nm: f32, entry_deg: f32, fresh: Option<f32>) {
        self.torque_nm = torque_nm;
        if (self.angle_deg - entry_deg).abs() > JAM_SLIP_DEG {
            // The jam gave way (stick-slip): keep ramping from here.
            self.still_ticks = 0;
            self.state = State::Ramping;
            return;
        }
        if let Some(angle) = fresh {
            self.hold.push(angle);
        }
        if !self.hold.is_full() {
            return;
        }
        let (median, spread) = self.hold.median_and_spread().unwrap_or((entry_deg, 0.0));
        self.finish(median, spread, torque_nm);
        self.state = State::Releasing;
    }

    fn finish(&mut self, angle_deg: f32, spread_deg: f32, torque_nm: f32) {
        let gauge = &self.params.gauge;
        let solution = kerf_from_angle(gauge, angle_deg);
        let mut flags = self.flags;
        if spread_deg > NOISY_HOLD_LSB * self.lsb_deg() {
            flags.insert(QualityFlags::NOISY_HOLD);
        }
        if solution.inset_deg > NEAR_DISENGAGE_FRACTION * gauge.disengage_deg {
            flags.insert(QualityFlags::NEAR_DISENGAGE);
        }
        if !solution.converged {
            flags.insert(QualityFlags::PLAY_NOT_CONVERGED);
        }
        if self.log.ticks_per_sample() > 1 {
            flags.insert(QualityFlags::DECIMATED);
        }
        self.result = Some(KerfResult {
            run_id: self.run_id,
            kerf_um: solution.kerf_um,
            angle_deg,
            play_deg: solution.play_deg,
            torque_at_jam_nm: torque_nm,
            force_at_jam_n: force_for_torque_n(&self.params, torque_nm, solution.inset_deg),
            flags,
        });
    }

    fn reset_step(&mut self, ticks: u32, settled: u32) {
        if ticks >= RESET_TIMEOUT_TICKS {
            self.latch(Fault::ResetFailed);
            return;
        }
        // Within tolerance: brake and check that the hub stays there; outside, drive towards
        // zero at a speed that falls with the distance left.
        let settled = if self.angle_deg.abs() <= RESET_TOLERANCE_DEG {
            self.torque_nm = 0.0;
            self.speed_integral_nm = 0.0;
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

    fn self_test_step(&mut self, phase: SelfTestPhase, inputs: &Inputs, fresh: Option<f32>) {
        let mut report = self.self_test_partial;
        let next = match phase {
            SelfTestPhase::Encoder { ticks, ok } => {
                self.torque_nm = 0.0;
                let ok = ok + u32::from(fresh.is_some());
                if ticks + 1 < SELFTEST_ENCODER_TICKS {
                    SelfTestPhase::Encoder {
                        ticks: ticks + 1,
                        ok,
                    }
                } else {
                    let fraction = ok as f32 / SELFTEST_ENCODER_TICKS as f32;
                    report.encoder_ok_fraction =
                        item(fraction >= SELFTEST_ENCODER_MIN_OK, fraction);
                    report.magnet_magnitude = match self.last_diagnostics {
                        Some(d) => item(!d.marginal, f32::from(d.magnitude)),
                        None => item(false, 0.0),
                    };
                    SelfTestPhase::Direction {
                        ticks: 0,
                        start_deg: self.angle_deg_cw(),
                    }
                }
            }
            SelfTestPhase::Direction { ticks, start_deg } => {
                // Clockwise, whatever the last gauge's sense: this checks the wiring.
                self.torque_nm = self.jam_frame(SELFTEST_DIRECTION_TORQUE_NM);
                if ticks + 1 < SELFTEST_DIRECTION_TICKS {
                    SelfTestPhase::Direction {
                        ticks: ticks + 1,
                        start_deg,
                    }
                } else {
                    let moved = self.jam_frame(self.angle_deg) - start_deg;
                    report.direction_deg = item(moved >= SELFTEST_DIRECTION_MIN_DEG, moved);
                    SelfTestPhase::Settle { ticks: 0 }
                }
            }
            SelfTestPhase::Settle { ticks } => {
                self.torque_nm = 0.0;
                if ticks + 1 < SELFTEST_SETTLE_TICKS {
                    SelfTestPhase::Settle { ticks: ticks + 1 }
                } else {
                    SelfTestPhase::Pulse {
                        ticks: 0,
                        current_sum_a: 0.0,
                    }
                }
            }
            SelfTestPhase::Pulse {
                ticks,
                current_sum_a,
            } => {
                // Counter-clockwise, bringing the hub back; torque chosen so that the duty is
                // exactly the pulse duty.
                let torque = (SELFTEST_PULSE_DUTY - self.config.breakaway_duty)
                    * self.config.torque_per_duty_nm;
                self.torque_nm = -self.jam_frame(torque);
                const AVERAGED: u32 = 3;
                // The first tick's current is from before the pulse was applied.
                let current_sum_a = if (1..=AVERAGED).contains(&ticks) {
                    current_sum_a + inputs.current_a
                } else {
                    current_sum_a
                };
                if ticks + 1 < SELFTEST_PULSE_TICKS {
                    SelfTestPhase::Pulse {
                        ticks: ticks + 1,
                        current_sum_a,
                    }
                } else {
                    let current_a = current_sum_a / AVERAGED as f32;
                    let estimate = self.config.torque_per_amp_nm * current_a / SELFTEST_PULSE_DUTY;
                    let relative = (estimate / self.config.torque_per_duty_nm - 1.0).abs();
                    report.torque_per_duty_nm =
                        item(relative <= SELFTEST_TORQUE_TOLERANCE, estimate);
                    self.torque_nm = 0.0;
                    self.self_test_partial = report;
                    self.self_test = Some(report);
                    self.state = State::Idle;
                    return;
                }
            }
        };
        self.self_test_partial = report;
        self.state = State::SelfTest(next);
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
        let duty =
            self.config.breakaway_duty + self.torque_nm.abs() / self.config.torque_per_duty_nm;
        let clockwise = self.jam_frame(self.torque_nm) > 0.0;
        MotorOutput {
            duty: duty.min(1.0),
            dir_high: clockwise != self.config.motor_inverted,
            awake: true,
        }
    }
}

fn item(pass: bool, value: f32) -> SelfTestItem {
    SelfTestItem {
        outcome: if pass {
            TestOutcome::Pass
        } else {
            TestOutcome::Fail
        },
        value,
    }
}

#[cfg(test)]
mod tests {
    //! Every state transition and every fault, with scripted inputs (the twin covers them with
    //! physics in `tests/twin_runs.rs`).

    use super::*;

    /// A controller and a clock, fed scripted hub angles.
    struct Script {
        c: Controller,
        now_us: u64,
        angle_deg: f32,
    }

    impl Script {
        fn new() -> Self {
            let mut s = Self {
                c: Controller::new(DeviceConfig::DEFAULT),
                now_us: 0,
                angle_deg: 0.0,
            };
            s.tick();
            s
        }

        fn inputs(&self) -> Inputs {
            Inputs {
                angle_deg: Ok(self.angle_deg),
                diagnostics: None,
                current_a: 0.5,
                driver_fault: false,
            }
        }

        fn tick(&mut self) -> MotorOutput {
            let inputs = self.inputs();
            self.tick_with(&inputs)
        }

        fn tick_with(&mut self, inputs: &Inputs) -> MotorOutput {
            self.now_us += PERIOD_US;
            let out = self.c.step(self.now_us, inputs);
            // A host that polls every 10 ms.
            if (self.now_us / PERIOD_US).is_multiple_of(10) {
                self.c.request(self.now_us, &Request::GetStatus);
            }
            out
        }

        fn request(&mut self, r: Request) -> Response {
            self.c.request(self.now_us, &r).unwrap()
        }

        fn state(&self) -> RunState {
            self.c.run_state()
        }

        fn start(&mut self, params: RunParams) {
            assert_eq!(self.request(Request::Run(params)), Response::Ok);
        }
    }

    #[test]
    fn a_scripted_run_goes_through_every_run_state_to_a_result() {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        let mut seen = [RunState::Idle; 0].to_vec();
        // The hub turns 0.06°/tick until the "gap" closes at 60°, then stands still.
        for _ in 0..5000 {
            if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
                s.angle_deg += 0.06;
            }
            let out = s.tick();
            let st = s.state();
            if seen.last() != Some(&st) {
                seen.push(st);
            }
            if st == RunState::Done {
                assert!(out.is_safe());
                break;
            }
        }
        assert_eq!(
            seen,
            [
                RunState::Engaging,
                RunState::Ramping,
                RunState::Jammed,
                RunState::Releasing,
                RunState::Done
            ]
        );
        let r = s.c.result().unwrap();
        let expected = kerf_from_angle(&kerfmeter_protocol::GaugeGeometry::PAPER, 60.0).kerf_um;
        assert!((r.kerf_um - expected).abs() < 0.01);
        assert!((r.force_at_jam_n - 55.0).abs() < 0.5);
        // Reset: to Resetting, back to zero, then Idle with the result gone.
        assert_eq!(s.request(Request::Reset), Response::Ok);
        assert_eq!(s.state(), RunState::Resetting);
        for _ in 0..3000 {
            let out = s.tick();
            if out.awake && out.duty > 0.0 {
                // The scripted hub follows the drive back.
                s.angle_deg = (s.angle_deg - 0.09).max(0.0);
            }
            if s.state() == RunState::Idle {
                break;
            }
        }
        assert_eq!(s.state(), RunState::Idle);
        assert_eq!(s.request(Request::GetKerf), Response::Kerf(None));
    }

    #[test]
    fn a_slipping_jam_goes_back_to_ramping() {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        for _ in 0..5000 {
            if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
                s.angle_deg += 0.06;
            }
            s.tick();
            if s.state() == RunState::Jammed {
                break;
            }
        }
        assert_eq!(s.state(), RunState::Jammed);
        s.angle_deg += 2.0 * JAM_SLIP_DEG;
        s.tick();
        assert_eq!(s.state(), RunState::Ramping);
    }

    fn run_until_fault(
        s: &mut Script,
        mut script: impl FnMut(&mut Script, u32) -> Inputs,
    ) -> Fault {
        for i in 0..20_000 {
            let inputs = script(s, i);
            let out = s.tick_with(&inputs);
            if let RunState::Fault(f) = s.state() {
                assert!(
                    out.is_safe() && !out.awake,
                    "motor safe in the fault's own tick"
                );
                return f;
            }
        }
        panic!("no fault");
    }

    #[test]
    fn max_run_time() {
        let mut s = Script::new();
        s.start(RunParams {
            max_time_ms: 100,
            ..RunParams::DEFAULT
        });
        // The hub creeps on and never jams.
        let f = run_until_fault(&mut s, |s, _| {
            s.angle_deg += 0.01;
            s.inputs()
        });
        assert_eq!(f, Fault::MaxRunTime);
    }

    #[test]
    fn overtravel() {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        let f = run_until_fault(&mut s, |s, _| {
            s.angle_deg += 0.09;
            s.inputs()
        });
        assert_eq!(f, Fault::Overtravel);
        assert!(s.angle_deg > 160.0);
    }

    #[test]
    fn no_motion() {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        assert_eq!(run_until_fault(&mut s, |s, _| s.inputs()), Fault::NoMotion);
    }

    #[test]
    fn reverse_motion() {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        let f = run_until_fault(&mut s, |s, i| {
            s.angle_deg = if i < 300 { i as f32 * 0.06 } else { 18.0 - 3.0 };
            s.inputs()
        });
        assert_eq!(f, Fault::ReverseMotion);
    }

    #[test]
    fn consecutive_encoder_errors_fault_but_a_few_are_ridden_through() {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        let f = run_until_fault(&mut s, |s, i| {
            s.angle_deg += 0.06;
            let mut inputs = s.inputs();
            // Isolated errors first (ridden through), then a burst.
            if i.is_multiple_of(7) || i >= 200 {
                inputs.angle_deg = Err(EncoderFault::Parity);
            }
            inputs
        });
        assert_eq!(f, Fault::EncoderErrors);
        assert!(s.c.status().encoder_errors >= MAX_CONSECUTIVE_ENCODER_ERRORS + 20);
    }

    #[test]
    fn diagnostics_faults_are_typed() {
        for (diag, fault) in [
            (DiagnosticFault::Chip, Fault::EncoderDiagnostics),
            (DiagnosticFault::Magnet, Fault::Magnet),
        ] {
            let mut s = Script::new();
            let mut inputs = s.inputs();
            inputs.diagnostics = Some(Err(diag));
            s.tick_with(&inputs);
            assert_eq!(s.state(), RunState::Fault(fault));
        }
    }

    #[test]
    fn over_current_and_driver_fault() {
        for (current_a, flt, fault) in [
            (7.0, false, Fault::OverCurrent),
            (0.5, true, Fault::DriverFault),
        ] {
            let mut s = Script::new();
            s.start(RunParams::DEFAULT);
            let f = run_until_fault(&mut s, |s, i| {
                s.angle_deg += 0.06;
                let mut inputs = s.inputs();
                if i > 100 {
                    inputs.current_a = current_a;
                    inputs.driver_fault = flt;
                }
                inputs
            });
            assert_eq!(f, fault);
        }
    }

    #[test]
    fn host_silence_during_a_run() {
        let mut s = Script::new();
        s.start(RunParams {
            host_timeout_ms: 200,
            ..RunParams::DEFAULT
        });
        let mut f = None;
        for _ in 0..1000 {
            s.angle_deg += 0.06;
            // No requests: step directly, bypassing the script's polling.
            s.now_us += PERIOD_US;
            let out = s.c.step(s.now_us, &s.inputs());
            if let RunState::Fault(fault) = s.state() {
                assert!(!out.awake);
                f = Some(fault);
                break;
            }
        }
        assert_eq!(f, Some(Fault::HostSilent));
    }

    #[test]
    fn a_late_step_is_an_overrun_while_active_only() {
        let mut s = Script::new();
        // Idle: a late step is harmless (the board writes flash while idle).
        s.now_us += 50 * PERIOD_US;
        s.tick();
        assert_eq!(s.state(), RunState::Idle);
        s.start(RunParams::DEFAULT);
        s.tick();
        s.now_us += (OVERRUN_PERIODS + 1) * PERIOD_US;
        s.tick();
        assert_eq!(s.state(), RunState::Fault(Fault::StepOverrun));
    }

    #[test]
    fn a_blocked_reset_fails_with_a_typed_fault() {
        let mut s = Script::new();
        s.angle_deg = 40.0;
        s.tick();
        assert_eq!(s.request(Request::Reset), Response::Ok);
        // The hub never moves.
        assert_eq!(
            run_until_fault(&mut s, |s, _| s.inputs()),
            Fault::ResetFailed
        );
    }

    #[test]
    fn faults_latch_until_cleared_and_refuse_runs_meanwhile() {
        let mut s = Script::new();
        let mut inputs = s.inputs();
        inputs.driver_fault = true;
        s.tick_with(&inputs);
        assert_eq!(s.state(), RunState::Fault(Fault::DriverFault));
        // Latched: the cause going away changes nothing.
        s.tick();
        assert_eq!(s.state(), RunState::Fault(Fault::DriverFault));
        assert_eq!(
            s.request(Request::Run(RunParams::DEFAULT)),
            Response::Error(ErrorCode::Faulted(Fault::DriverFault))
        );
        assert_eq!(
            s.request(Request::SelfTest),
            Response::Error(ErrorCode::Faulted(Fault::DriverFault))
        );
        assert_eq!(s.request(Request::Abort), Response::Ok);
        assert_eq!(
            s.state(),
            RunState::Fault(Fault::DriverFault),
            "Abort does not clear a fault"
        );
        assert_eq!(s.request(Request::ClearFault), Response::Ok);
        assert_eq!(s.state(), RunState::Idle);
        // Reset also leaves a fault (and drives to zero).
        s.tick_with(&inputs);
        assert_eq!(s.request(Request::Reset), Response::Ok);
        assert_eq!(s.state(), RunState::Resetting);
    }

    #[test]
    fn abort_is_safe_in_the_next_tick_from_every_active_state() {
        for ticks in [5, 200, 1200] {
            let mut s = Script::new();
            s.start(RunParams::DEFAULT);
            for _ in 0..ticks {
                if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
                    s.angle_deg += 0.06;
                }
                s.tick();
            }
            assert!(s.c.is_active());
            assert_eq!(s.request(Request::Abort), Response::Ok);
            let out = s.tick();
            assert!(!out.awake && out.duty == 0.0, "after {ticks} ticks");
            assert_eq!(s.state(), RunState::Idle);
        }
    }

    #[test]
    fn invalid_params_and_out_of_order_requests_are_refused() {
        let mut s = Script::new();
        let bad = RunParams {
            target_force_n: f32::NAN,
            ..RunParams::DEFAULT
        };
        assert_eq!(
            s.request(Request::Run(bad)),
            Response::Error(ErrorCode::InvalidParam(
                kerfmeter_protocol::ParamField::TargetForceN
            ))
        );
        assert_eq!(
            s.request(Request::GetSamples { from: 0 }),
            Response::Error(ErrorCode::NoSamples)
        );
        s.angle_deg = 5.0;
        s.tick();
        assert_eq!(
            s.request(Request::Run(RunParams::DEFAULT)),
            Response::Error(ErrorCode::NotAtZero)
        );
        s.angle_deg = 0.0;
        s.tick();
        s.start(RunParams::DEFAULT);
        assert_eq!(
            s.request(Request::Run(RunParams::DEFAULT)),
            Response::Error(ErrorCode::Busy)
        );
        assert_eq!(s.request(Request::Reset), Response::Error(ErrorCode::Busy));
        assert_eq!(s.c.set_config(DeviceConfig::DEFAULT), Err(ErrorCode::Busy));
    }

    #[test]
    fn the_motor_is_driven_in_the_gauges_sense() {
        for (jam_direction, expect_dir_high) in [
            (kerfmeter_protocol::JamDirection::Clockwise, true),
            (kerfmeter_protocol::JamDirection::CounterClockwise, false),
        ] {
            let mut s = Script::new();
            let mut params = RunParams::DEFAULT;
            params.gauge.jam_direction = jam_direction;
            s.start(params);
            let mut out = MotorOutput::SAFE;
            for _ in 0..50 {
                out = s.tick();
            }
            assert!(out.awake && out.duty > 0.0);
            assert_eq!(out.dir_high, expect_dir_high, "{jam_direction:?}");
        }
    }
}
