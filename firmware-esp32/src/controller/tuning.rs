//! Every tuning constant of the controller, grouped by what it tunes, each with its unit and the
//! reason for its value. The rates and lengths in ticks assume the 1 kHz control rate
//! ([`CONTROL_RATE_HZ`]): one tick is one millisecond.

use crate::build::CONTROL_RATE_HZ;

// ---- Timing ------------------------------------------------------------------------------------

/// Control period, µs: one tick at [`CONTROL_RATE_HZ`].
pub const PERIOD_US: u64 = 1_000_000 / CONTROL_RATE_HZ as u64;
/// Control period, seconds (the integration step of the ramp and the speed loop).
pub(super) const DT_S: f32 = 1.0 / CONTROL_RATE_HZ as f32;
/// A step later than this many periods after the previous one is an overrun (`StepOverrun`, only
/// while the motor may be driven): for that long the motor ran on a stale output, unwatched.
pub const OVERRUN_PERIODS: u64 = 3;

// ---- Jam detection -----------------------------------------------------------------------------

pub use crate::jam::{HOLD_TICKS, JAM_WINDOW_TICKS};

/// Hub still: the fitted angle change over the [`JAM_WINDOW_TICKS`] regression window within this
/// many encoder LSB. The encoder's noise is about one LSB either way, which the regression
/// averages down; a hub turning at the ramp's speed limit covers some 78 LSB of an output-shaft
/// encoder in one window.
pub const JAM_STILL_LSB: f32 = 4.0;
/// Ticks the hub must stay still, at target torque, before the hold starts: one more regression
/// window, so that a momentary stall (stick-slip) is not taken for the jam.
pub const JAM_SETTLE_TICKS: u32 = 20;
/// A jam only counts with the inset turned at least this far past the zero-kerf play, degrees:
/// less is no inset motion at all (the prongs stalled in the holes).
pub const JAM_MIN_INSET_DEG: f32 = 1.0;
/// Movement during the hold that means the jam slipped, degrees: back to ramping. Also the
/// margin by which engaging may stop short of the zero-kerf play. About 14 LSB: far above the
/// noise of a held hub, far below a real slip.
pub const JAM_SLIP_DEG: f32 = 0.3;
/// A hold whose angles spread more than this many encoder LSB is flagged `NOISY_HOLD` (twice the
/// stillness band: a held jam's angles stay within a few LSB).
pub const NOISY_HOLD_LSB: f32 = 8.0;
/// Flag `NEAR_DISENGAGE` when the inset turned past this fraction of the disengage angle: the
/// spiral lets go soon after, so such a reading may be a gauge that barely held.
pub const NEAR_DISENGAGE_FRACTION: f32 = 0.9;

// ---- Drive: engaging, ramping, releasing -------------------------------------------------------

/// Engaging speed target, degrees per second: the hole play (a few degrees) passes in well under
/// a second, slowly enough that the prongs do not knock the inset on.
pub const ENGAGE_SPEED_DEG_PER_S: f32 = 60.0;
/// Engaging torque ceiling, N·m: well above breakaway, far below any measuring torque.
pub const ENGAGE_MAX_TORQUE_NM: f32 = 0.12;
/// While ramping, the hub never turns faster than this, degrees per second, so that the inset
/// does not slam into the jam (the impact would compress the contact beyond the static value).
pub const MAX_TURN_SPEED_DEG_PER_S: f32 = 90.0;
/// Speed loop (engage, ramp ceiling, reset): proportional gain, N·m per (degree per second).
/// A 100 °/s error asks for 0.05 N·m: gentle, since the integral term does the holding.
pub const SPEED_KP: f32 = 0.0005;
/// Speed loop: integral gain, N·m per second per (degree per second). A 10 °/s shortfall builds
/// 0.1 N·m in one second, enough to overcome the gearbox's breakaway on its own.
pub const SPEED_KI: f32 = 0.01;
/// Torque ramp-down rate when releasing, N·m per second: the default torque cap (0.8 N·m) unloads
/// in 200 ms.
pub const RELEASE_RATE_NM_PER_S: f32 = 4.0;

// ---- Fault limits ------------------------------------------------------------------------------

/// No motion: the hub moved less than this since the run started, degrees...
pub const NO_MOTION_DEG: f32 = 0.5;
/// ...for this many ticks with torque above breakaway (`NoMotion`): half a second of driving
/// without turning means no inset, or a disconnected motor.
pub const NO_MOTION_TICKS: u32 = 500;
/// Overtravel: the inset may turn this far past the gauge's nominal disengage angle, degrees (the
/// spiral of the paper's gauge lets go between 155° and 180°; a jam at the largest kerf plus the
/// contact's compression lands just past 155°).
pub const OVERTRAVEL_MARGIN_DEG: f32 = 10.0;
/// Reverse motion: the hub fell back this far from the furthest angle it reached, degrees: far
/// beyond the encoder noise and the slip tolerance ([`JAM_SLIP_DEG`]).
pub const REVERSE_TOLERANCE_DEG: f32 = 2.0;
/// Over-current: the check compares the mean of this many ticks' motor currents with
/// `max_current_a`. The current is the filtered current sense divided by the filtered duty
/// (`board::current`), which multiplies the ADC's noise by up to five at low duty; four readings
/// halve it, for 4 ms more of the RC filter's 1 ms lag.
pub const OVER_CURRENT_MEAN_TICKS: usize = 4;
/// Over-current: a single reading above this many times `max_current_a` trips at once (a short,
/// which the mean would take a few ticks to show).
pub const OVER_CURRENT_PEAK_FACTOR: f32 = 2.0;
/// Encoder errors in a row that fault the device (`EncoderErrors`). Fewer are ridden through on
/// the last good angle (and flag the result `ENCODER_ERRORS`): 5 ms without an angle is the most
/// the controller drives blind.
pub const MAX_CONSECUTIVE_ENCODER_ERRORS: u16 = 5;
/// Communication watchdog for reset and self-test (which have no run parameters to take it
/// from), ms: the host polls every 20 ms, so a second of silence means it is gone.
pub const DEFAULT_HOST_TIMEOUT_MS: u32 = 1_000;

// ---- Reset -------------------------------------------------------------------------------------

/// Reset: hub speed target per degree from zero, (degrees per second) per degree: the return
/// slows as it nears zero, so that it stops there instead of overshooting.
pub const RESET_SPEED_PER_DEG: f32 = 4.0;
/// Reset: fastest return, degrees per second (the ramp's own speed limit).
pub const RESET_MAX_SPEED_DEG_PER_S: f32 = 90.0;
/// Reset: torque ceiling, N·m: enough to drag an empty hub back, far below measuring torques.
pub const RESET_MAX_TORQUE_NM: f32 = 0.15;
/// Reset settles once the hub comes within this angle of zero, degrees (well inside the run's
/// start tolerance, `kerfmeter_protocol::START_TOLERANCE_DEG`)...
pub const RESET_TOLERANCE_DEG: f32 = 0.3;
/// ...and stays settled while it stays within this wider one, degrees: hysteresis, so that a hub
/// that stopped near the tolerance's edge is not carried in and out by the encoder's noise (about
/// one LSB, 0.022° on the output shaft) and never settles. A finished reset thus leaves the hub
/// within this angle: under half the start tolerance, and inside the 0.5° the acceptance suite
/// (`hil-tests`) asks of a reset.
pub const RESET_RELEASE_DEG: f32 = 0.45;
/// Reset is done once the hub has been settled for this many ticks, so that a hub passing
/// through zero does not count.
pub const RESET_SETTLE_TICKS: u32 = 50;
/// Reset gives up (`ResetFailed`) after this many ticks: a free hub returns from the disengage
/// angle (about 165° at most) in under three seconds at the speeds above.
pub const RESET_TIMEOUT_TICKS: u32 = 5_000;

// ---- Self-test ---------------------------------------------------------------------------------

/// Self-test: ticks of encoder reads with the motor off (enough reads for a 1 % error rate to
/// show).
pub const SELFTEST_ENCODER_TICKS: u32 = 100;
/// Self-test: fraction of good encoder reads that passes: one bad read in a hundred.
pub const SELFTEST_ENCODER_MIN_OK: f32 = 0.99;
/// Self-test: direction-check torque, N·m: above breakaway, low enough to be harmless with no
/// gauge under the prongs.
pub const SELFTEST_DIRECTION_TORQUE_NM: f32 = 0.08;
/// Self-test: direction-check duration, ticks.
pub const SELFTEST_DIRECTION_TICKS: u32 = 150;
/// Self-test: minimum motion that passes the direction check, degrees (far above the noise).
pub const SELFTEST_DIRECTION_MIN_DEG: f32 = 1.0;
/// Self-test: settling time before the torque-constant pulse, ticks, so that the pulse starts from
/// standstill.
pub const SELFTEST_SETTLE_TICKS: u32 = 150;
/// Self-test: duty of the torque-constant pulse (from standstill): high enough that the current
/// stands well above the current sense's noise divided by the duty (the signal grows with the
/// duty, the noise shrinks with it), low enough that the current stays under the default limit
/// at 26 V (4.9 A on the reference motor), and its filtered duty is above the conversion's floor
/// from the first millisecond (0.25 against 0.2).
pub const SELFTEST_PULSE_DUTY: f32 = 0.4;
/// Self-test: torque-constant pulse length, ticks (current is averaged over the first ones, before
/// the hub has built up speed and back-EMF).
pub const SELFTEST_PULSE_TICKS: u32 = 20;
/// Self-test: the estimate passes within this fraction of the configured torque constant (it
/// rests on a few filtered current readings taken as the hub starts to move, against the
/// G2's current-sense gain, known to ±10 %, so it is rough).
pub const SELFTEST_TORQUE_TOLERANCE: f32 = 0.3;
/// Self-test: the supply at which the configuration's `torque_per_duty_nm` holds, V (the
/// reference build's 12 V); the estimate is scaled to it from the measured supply.
pub const SELFTEST_REFERENCE_SUPPLY_V: f32 = 12.0;
