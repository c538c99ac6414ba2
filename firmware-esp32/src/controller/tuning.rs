//! Every tuning constant of the controller, grouped by what it tunes, each with its unit and the
//! reason for its value. The rates and lengths in ticks assume the 1 kHz control rate
//! ([`CONTROL_RATE_HZ`]): one tick is one millisecond.
//!
//! # Late ticks
//!
//! A C3's control tick comes late now and then: an interrupt, a flash cache miss, USB work (the
//! twin draws up to 5 late ticks a second, up to 5 ms late). Until the next step the motor keeps
//! the last output, unwatched. The controller rides through a late tick when it is short and
//! rare, and faults (`StepOverrun`, only while the motor may be driven) otherwise:
//!
//! - **A stale output is harmless for [`MAX_GAP_PERIODS`] (8 ms).** During a gap the torque does
//!   not rise (the output is the last one; the ramp resumes after it, see below). At a fixed duty
//!   the current is highest at standstill (back-EMF only lowers it), so a stale output draws no
//!   more current than the held hub did, and the G2 limits its current itself. What can move is
//!   the hub: at the ramp's speed limit ([`MAX_TURN_SPEED_DEG_PER_S`], which the speed loop
//!   holds) it turns 0.72° in 8 ms, well inside the overtravel margin
//!   ([`OVERTRAVEL_MARGIN_DEG`], 10°). The worst case is a
//!   jam that breaks away entirely at the default torque cap (0.8 N·m) at the start of a gap:
//!   on the reference build (2.4e-4 kg·m² at the output: a 5e-7 kg·m² rotor through 21:1 plus the
//!   hub) the hub gains at most ½·(0.8 N·m / 2.4e-4 kg·m²)·(8 ms)² = 0.11 rad, about 6°, still
//!   inside the overtravel margin, and the next step sees it (overtravel, reverse motion, or a
//!   slip that resumes the ramp). A longer gap faults at once; the 50 ms hardware watchdog is the
//!   backstop for a loop that stops altogether.
//! - **Rare:** late time (what a gap longer than [`LATE_GAP_PERIODS`] lasts beyond one period) is
//!   a debt that a tenth of the time passing repays ([`LATE_REPAY_DIVISOR`]); a debt above
//!   [`LATE_BUDGET_US`] faults. A loop late more than a tenth of the time for long, or several
//!   late ticks in quick succession, is no longer a 1 kHz controller: its speed estimate (a
//!   regression over [`JAM_WINDOW_TICKS`] ticks) and its stillness test rest on ticks that did
//!   not come on time. Two ticks 5 ms late ride through even back to back; a third within some
//!   25 ms of them faults.
//! - **No kick:** the ramp, the release and the speed loop's integral integrate the time since
//!   the last step ([`MAX_STEP_DT_US`] at most), not a fixed period. A late step integrates at
//!   most two periods; the ticks it delayed then run at once (embassy's `Ticker` catches up) and
//!   integrate only the microseconds between them. Without the clamp a late step would add the
//!   whole gap's ramp in one go; with a fixed period per step the burst of catch-up steps would
//!   add it within microseconds. The windows counted in ticks (the regression, the stillness and
//!   the hold, the settle and timeout counts) stay counts of periods to within one gap, as the
//!   catch-up keeps the number of ticks in step with time.

use crate::build::CONTROL_RATE_HZ;

// ---- Timing ------------------------------------------------------------------------------------

/// Control period, µs: one tick at [`CONTROL_RATE_HZ`].
pub const PERIOD_US: u64 = 1_000_000 / CONTROL_RATE_HZ as u64;

// ---- Late ticks --------------------------------------------------------------------------------
//
/// A gap between two steps longer than this many periods is a late step: ridden through while
/// late steps are rare (see [`LATE_BUDGET_US`]); a gap up to this long is jitter.
pub const LATE_GAP_PERIODS: u64 = 3;
/// A gap between two steps longer than this many periods is an overrun (`StepOverrun`, only
/// while the motor may be driven), however rare: the most a stale output may be left unwatched.
pub const MAX_GAP_PERIODS: u64 = 8;
/// The late-time debt, µs, beyond which late steps are too frequent (`StepOverrun`): two steps
/// 5 ms late (6 ms gaps, 5 ms of late time each, plus jitter) fit, a third soon after does not.
pub const LATE_BUDGET_US: u64 = 12_000;
/// Time passing repays late-time debt at one part in this many: a loop may be late a tenth of
/// the time in the long run.
pub const LATE_REPAY_DIVISOR: u64 = 10;
/// The most time one step integrates (ramp, release, speed-loop integral), µs: two periods, so
/// that jitter (a gap of 1.2 ms, then 0.8 ms) integrates the time that passed, and a late step
/// no more than twice an on-time one.
pub const MAX_STEP_DT_US: u64 = 2 * PERIOD_US;

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
/// The most a held hub's angle drifts on encoder noise alone, in LSB between the means of the
/// hold's halves: the drift averages the noise down (an SD of 0.22σ over the 80-tick hold: under
/// 1 LSB for the 4 LSB of a weak magnet), so six LSB is never reached on noise (the on-target
/// tests check a held hub against it). The flag is [`HOLD_CREEP_LSB`]'s; the spread (max − min)
/// it used before grew with the noise and the window's length and fired on most healthy holds,
/// while the median it guarded is insensitive to noise, and a hold cannot move it by more than
/// [`JAM_SLIP_DEG`] (0.8 µm of kerf on the paper's gauge) without counting as a slip.
pub const HOLD_DRIFT_LSB: f32 = 6.0;
/// A hold whose halves' means are more than this many encoder LSB apart is taken again (up to
/// [`MAX_HOLD_RETRIES`] times, while [`HOLD_RETRY_RESERVE_MS`] of the run is left) instead of
/// read: the hub is still creeping into the contact. The stillness test lets a hub turning at up
/// to some 4°/s count as still (its threshold must stand clear of the regression's noise at 4 LSB
/// of encoder noise), and on a soft contact the last of the approach creeps on for hundreds of
/// ms: read early, such jams read 2–5 µm low on the twin, or were flagged `NOISY_HOLD`. One LSB
/// in 40 ms is 0.55°/s on an output-shaft encoder. Noise alone passes it often at 4 LSB of
/// encoder noise (the drift's SD is 0.22σ, see [`HOLD_DRIFT_LSB`]), but a hold taken again
/// for noise costs only 80 ms, and ten in a row never happen.
pub const HOLD_CREEP_LSB: f32 = 1.0;
/// The most holds taken again for a creep ([`HOLD_CREEP_LSB`]): 800 ms of waiting at most. The
/// last one is read whatever it shows, and flagged `NOISY_HOLD` if it still drifted past
/// [`HOLD_CREEP_LSB`] (a jam that never stops creeping); so is a creeping hold that may not be
/// taken again for want of run time ([`HOLD_RETRY_RESERVE_MS`]).
pub const MAX_HOLD_RETRIES: u32 = 10;
/// A creeping hold is taken again only while the run has this much of its `max_time_ms` left,
/// ms: the last hold, the probe (150 ms) and the release (200 ms at most) fit with room to
/// spare, so waiting on a creep never turns a slow run into a `MaxRunTime` fault.
pub const HOLD_RETRY_RESERVE_MS: u32 = 1_500;
/// The torque's relative uncertainty at the jam, as a fraction: the current sense's gain
/// (±10 %) through the winding's estimate, or, where the duty is too low to measure the winding
/// (`winding::MIN_DUTY`), the winding's temperature against the calibration's 25 °C (an
/// enclosure at 0–45 °C: −10 % to +8 %). After the hold the controller raises the torque by
/// this much ([`PROBE_TICKS`]) and watches how far the hub turns on: how far a torque error
/// this large moves the reading.
pub const TORQUE_UNCERTAINTY: f32 = 0.1;
/// The torque's relative uncertainty at a jam where the winding could not be measured (every
/// settle's duty below `winding::MIN_DUTY`: a high gear ratio or a high supply; and no check
/// after the probe, `winding::CHECK_DUTY`, for want of room under the run's cap or twice the
/// held torque, or of run time, or with the hub near the disengage, never still or giving way
/// under it, or an implausible estimate), as a fraction:
/// the factor stands where the last measurement, or the boot, left it, and the winding may be
/// anywhere from −10 °C to 130 °C (`winding::PLAUSIBLE_FACTOR`'s temperatures: −14 % to +41 %
/// of its resistance at 25 °C). The torque goes as the inverse of the resistance, so it may be
/// 29 % low (1/1.41) or 16 % high: the larger side, rounded up. At 0.2 (the hot winding's
/// shortfall left out) the robustness sweep read unflagged readings up to 4.6 µm low on
/// windings at 95 °C, whose probe said a 20 % torque error moved them by under 3 µm.
pub const TORQUE_UNCERTAINTY_UNMEASURED: f32 = 0.3;
/// The approach to the jam starts where the ramp's torque passes this fraction of its target
/// (`run.rs`, `Run::approach`): from there the contact bears most of the torque, so the hub's
/// turn from there to the jam over the torque's rise is the contact's compliance, stick-slip
/// included, which the probe after the hold misses where static friction holds the hub (on the
/// twin: a contact of 17 N/µm on a 63:1 build slipped 5° at the jam, read 7.3 µm high, and did
/// not move under the probe).
pub const APPROACH_FRACTION: f32 = 0.8;
/// A ramping tick with the hub turning slower than this, degrees per second, counts as pressing
/// into the contact ([`PRESSED_OVER_LIMIT`]): half the ramp's speed limit, which a free hub
/// runs at.
pub const PRESSING_SPEED_DEG_PER_S: f32 = 45.0;
/// A jam whose drive while pressing into the contact stood more than this fraction above the
/// hold's, and whose probe could not move the hub, is flagged `FORCE_SENSITIVE`: the contact
/// bore more than it is held with, and the self-locking spiral keeps what it pressed. A contact
/// that crushes lets the hub turn on while the ramp's falling target follows it down: on the
/// twin one yielding at 113 N was pressed 27 % over its hold and read 43 µm high, unflagged.
/// Without the probe's stillness the test flags high-ratio builds whose free hub crawls at its
/// ceiling (tried: some 60 more readings of 1,200 draws).
pub const PRESSED_OVER_LIMIT: f32 = 0.15;
/// A probe that turned the hub by less than this, encoder LSB, did not move it
/// ([`PRESSED_OVER_LIMIT`]).
pub const PRESSED_PROBE_STILL_LSB: f32 = 2.0;
/// An approach whose torque rose by less than this fraction of the held torque measures no
/// compliance for the winding check's allowance; for the `FORCE_SENSITIVE` flag it is judged by
/// the force's rise instead (at least a fifth: from at most [`APPROACH_FRACTION`] of the target
/// to all of it), where the probe could not move the hub (the target falls along the spiral: a
/// contact giving way at the run's force turns the hub on with no rise in torque), and is
/// judged without it where the probe moved the hub.
pub const MIN_APPROACH_FRACTION: f32 = 0.05;
/// The turn since the run's first settle measures nothing where the force rose by less than
/// this fraction of the settle's (a jam creeping in at the target's force). Over the
/// robustness sweep's seeds 1–56 any value from 2.5 % to 5 % flags the same readings (the
/// breakaway share in the compliance's denominator keeps small rises from reading as soft).
pub const SETTLE_MIN_FORCE_RISE: f32 = 0.03;
/// The probe's extra torque over the held one, as a fraction.
pub const PROBE_FRACTION: f32 = 0.1;
/// The probe after the hold, ticks: the torque rises by [`TORQUE_UNCERTAINTY`] at the ramp's
/// rate (some 50 ms at 1 N·m/s for a 0.5 N·m jam) and the contact settles under it.
pub const PROBE_TICKS: u32 = 150;
/// The probe's last ticks whose angles are averaged: the encoder's noise falls to a fifth.
pub const PROBE_AVERAGED_TICKS: u32 = 20;
/// A probe whose torque could rise by less than this fraction (the run's cap, or full duty,
/// held it) measures nothing: the reading is judged without it.
pub const MIN_PROBE_FRACTION: f32 = 0.02;
/// A jam whose contact bore more than this fraction above the held torque before the hold (a
/// winding estimate lowered the factor: the earlier drive was that much too strong) is flagged
/// `FORCE_SENSITIVE` whatever the probe says: the self-locking spiral keeps the deeper
/// compression, and its static friction keeps the probe from gauging the contact's compliance
/// past it (on the twin a contact of 1.2 N/µm pressed 28 % too hard read 13 µm high and moved
/// 0.1 µm under the probe). The first run after boot starts from a factor of 1, so a current
/// sense that reads high lowers the factor at its first settle by its gain error (5 % on the
/// twin's default board, on MDF some 0.5 µm of compression): the limit stands above that, and
/// the probe judges what is below it.
pub const OVERSHOOT_LIMIT: f32 = 0.08;
/// A reading that a [`TORQUE_UNCERTAINTY`] torque error could move by more than this, µm, is
/// flagged `FORCE_SENSITIVE`: issue 12's accuracy target for the device-added error (p95
/// ≤ 3 µm), so an unflagged reading is one the torque's uncertainty cannot take past it.
pub const FORCE_SENSITIVITY_LIMIT_UM: f32 = 3.0;
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

// ---- Measured play: backing off after the release (`run.rs`) -----------------------------------

/// Backing-off speed, degrees per second: the hole play's two sides (some 10°) pass in a third
/// of a second, slowly enough that the prongs meet the holes' far faces without a knock.
pub const BACK_OFF_SPEED_DEG_PER_S: f32 = 30.0;
/// The most torque backing off pulls with, N·m over the gearbox's breakaway (which the duty
/// already covers): past anything the gearbox's friction alone can hold, below what the jammed
/// inset resists being pulled back with. The self-locking spiral holds the inset with the
/// contact's normal force F_n = τ_jam / (c + μ·r) times (μ·r − c): τ_jam·(μ·r − c)/(μ·r + c),
/// over 0.7·τ_jam for any μ of 0.1 or more on the paper's gauge, so a hold of at least
/// [`BACK_OFF_MIN_HELD_RATIO`] times this cap is never pulled out. Not less: a high-ratio
/// gearbox's motor brakes the hub by its back-EMF, k_t²·N²·η/R (some 0.33 N·m per rad/s at
/// 58:1 on the twin), and at 0.04 N·m such hubs crawled back at 7°/s and ran out of time.
pub const BACK_OFF_MAX_TORQUE_NM: f32 = 0.08;
/// No back-off after a hold lighter than this many times [`BACK_OFF_MAX_TORQUE_NM`] (a light
/// target force): its pull could drag the inset back out of the jam, and a stick-slip on the
/// way could pass for a stall. The model's play stands (`PLAY_MODELLED`).
pub const BACK_OFF_MIN_HELD_RATIO: f32 = 2.0;
/// After the release, the hub must stand still this many ticks in a row before the back-off
/// takes its start: a hub still relaxing from the release would lengthen the turn.
pub const BACK_OFF_SETTLE_TICKS: u32 = 20;
/// The hub must have turned back this far before a stall counts, degrees: the hub leaving the
/// holes' forward faces, not the start.
pub const BACK_OFF_MIN_TURN_DEG: f32 = 1.0;
/// A stall is the hub still ([`JAM_STILL_LSB`] over the regression window) with the pull at
/// [`BACK_OFF_STALL_SHARE`] of its cap, for this many ticks in a row: the gearbox's friction is
/// already covered by the duty, so what holds the hub against the cap is the prongs on the
/// holes' far faces, not a gearbox that sticks.
pub const BACK_OFF_STILL_TICKS: u32 = 30;
/// The share of [`BACK_OFF_MAX_TORQUE_NM`] the pull must be at for a still hub to count as
/// stalled.
pub const BACK_OFF_STALL_SHARE: f32 = 0.9;
/// The longest back-off, ticks: both sides of the play (some 10°) at 7°/s, a high-ratio
/// gearbox's crawl. It starts only with this much of the run's `max_time_ms` left (plus
/// [`BACK_OFF_RESERVE_MS`]), so it never ends a run in `MaxRunTime`.
pub const BACK_OFF_MAX_TICKS: u32 = 1500;
/// Run time kept in hand beyond [`BACK_OFF_MAX_TICKS`] before a back-off starts, ms.
pub const BACK_OFF_RESERVE_MS: u32 = 100;
/// A measured play shorter than the model's by more than this, degrees, is not taken (a stall
/// that is not the far faces): the cut's imperfections shorten the play by less. A hub 100 µm
/// off the gauge's centre (twice the worst head repeatability the twin draws) shortens both
/// sides by 1.1°; a kerf tapered by 150 µm, by 0.4°.
pub const BACK_OFF_MAX_SHORTER_DEG: f32 = 2.0;
/// A measured play longer than the model's by more than this, degrees, is not taken: what the
/// cut does to the holes shortens the play (to first order; a prong thinner than drawn
/// lengthens it by a little), so a long one is an inset that slipped back under the pull, a hub
/// still relaxing, or gearbox backlash, each of which would read the kerf low.
pub const BACK_OFF_MAX_LONGER_DEG: f32 = 0.5;

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
/// How much farther from zero than where it started a reset may take the hub, degrees, before it
/// is judged to drive the wrong way (`ReverseMotion`: a motor or encoder sense set wrong pushed
/// it away for the whole timeout, several turns). Beyond any overshoot past zero, which the
/// speed loop's slowing near zero keeps to a fraction of a degree.
pub const RESET_AWAY_DEG: f32 = 20.0;

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
/// Self-test: duty of the torque-constant pulse (from standstill), at the reference supply (12 V):
/// scaled by the measured supply (and the winding's factor, `winding.rs`) like every duty, so the
/// pulse draws the same current (3.4 A at
/// standstill on the reference motor, under the default 6.5 A limit) and gives the same estimate
/// on any supply. High enough that at 24–26 V, where the scaled duty is least (0.28–0.3), the
/// current stands well above the current sense's noise and offset error divided by the duty, and
/// above the conversion's duty floor (0.2): at 0.45 the estimate at 24 V centred 11 % low
/// (median 0.89 of the configured value over 50 twins), at 0.6 within 5 % (0.96).
pub const SELFTEST_PULSE_DUTY: f32 = 0.6;
/// Self-test: torque-constant pulse length, ticks (current is averaged over the first ones, before
/// the hub has built up speed and back-EMF).
pub const SELFTEST_PULSE_TICKS: u32 = 20;
/// Self-test: the torque-constant estimate's own error, as a fraction (it rests on a few
/// filtered current readings taken as the hub starts to move: 0.86–1.09 of the expected value on
/// the twin). It passes where the winding's resistance factor, anywhere in
/// `winding::PLAUSIBLE_FACTOR` (temperature and the current sense's gain), widened by this,
/// explains it: 0.56–1.45 of the configured value (`self_test.rs`).
pub const SELFTEST_TORQUE_TOLERANCE: f32 = 0.1;
