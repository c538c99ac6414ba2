//! The motor current from the Pololu G2's current-sense (`CS`) output: an RC-filtered `CS`
//! divided by the duty filtered the same way, and when the current counts as unknown.
//! Chip-independent, so that it is tested on the host, and used by [`Hardware::tick`] on the
//! board and in the digital twin alike: both hand it the ADC's millivolts, nothing else.
//!
//! # Why an RC filter and a division by duty
//!
//! The G2's `CS` follows the motor current only in the drive phase of each 20 kHz PWM period; in
//! the brake phase (and while the driver limits current) it sits at its offset. A single
//! unsynchronised sample per 1 ms tick therefore reads either the current or about nothing, and
//! an over-current check on it is statistical. Two cures exist:
//!
//! - sampling in the drive phase, synchronised to the PWM: the C3's LEDC cannot trigger the ADC
//!   (no event matrix from LEDC to the SAR ADC), and an interrupt in every 50 µs PWM period to
//!   start a conversion would cost 20,000 interrupts a second for one reading a millisecond;
//! - an RC low-pass on the `CS` pin, which averages the pulse train to D·|i| (D: the fraction of
//!   each period the bridge drives, the duty), read at any instant: chosen.
//!
//! The motor current is then the filtered reading divided by the duty. The duty changes from
//! tick to tick, so the division uses the duty *filtered with the same time constant*
//! ([`MotorCurrent`]: a first-order filter of the duty applied, stepped once a tick), so that
//! the ratio stays right while the duty ramps: both numerator and denominator are then the same
//! weighted average over the recent past, of D·|i| and of D.
//!
//! # The filter: 10 kΩ and 100 nF, τ = 1 ms
//!
//! - Ripple: the pulse train leaves a sawtooth of about i·D(1−D)·T/τ peak to peak (T = 50 µs):
//!   at most 1.25 % of the current, 1.6 mV at the 6.5 A limit, under two of the calibrated
//!   ADC's 1 mV steps. A shorter τ lets more ripple through; at random sampling phases it is noise.
//! - Lag: τ plus the ADC's one-conversion delay (the reading a tick uses was taken at the end of
//!   the previous tick): a short's current shows within 2–3 ms, before a stalled motor's
//!   winding or the G2 come to harm (the G2 also limits current itself). A longer τ is slower.
//! - Source impedance: Pololu publishes no output impedance for `CS`; 10 kΩ in series keeps the
//!   filter's R set by the resistor for any output impedance well below it (check on the bench:
//!   the reading at a steady duty with the resistor shorted and with it in place agree), and
//!   100 nF holds the charge the ADC's sample-and-hold takes (a few pF) with no visible droop.
//!
//! # The duty filter, and when a reading was taken
//!
//! The board reads `CS` one conversion behind: the conversion started at the end of tick *k*,
//! just after the motor output of tick *k* was applied, is read at tick *k* + 1. So a reading
//! holds the filter's state at the moment tick *k*'s output was applied, and [`MotorCurrent`]
//! pairs it with the duty filter's state at that same moment: [`MotorCurrent::applied`] advances
//! the duty filter over the time since the last output (by e^(−Δt/τ), Δt counted in whole
//! ticks) with the duty held meanwhile, then takes the new output as the duty held from now on.
//!
//! # The rules
//!
//! - Motor current = (reading − offset) / [`CURRENT_SENSE_MV_PER_A`] / max(filtered duty,
//!   [`DUTY_FLOOR`]), never negative; 0 A asleep and where the duty filter has settled at zero
//!   (below).
//! - The floor: below it the filtered duty is too small to divide by (the ADC's 1 mV step and
//!   its noise would be multiplied without bound; at the floor, by five: 1 mV reads 0.25 A).
//!   Under the floor the current reads low by the factor duty/floor; but there the motor cannot
//!   draw more than a fifth of its full-duty stall current, so no over-current is missed unless
//!   that stall current is over five times the limit (the reference build's is 5.6 A at 12 V,
//!   11 A at 24 V, against 6.5 A). A short (tens of amps in the drive phase) still reads above
//!   the limit at any duty above a few percent, and the G2 limits current on its own.
//! - The offset: the G2's is "about 50 mV" and varies from board to board (60 mV is reported).
//!   An error in it is divided like the reading: e mV of offset error reads as
//!   e / [`CURRENT_SENSE_MV_PER_A`] amps of D·|i|, divided by the filtered duty, so at the floor
//!   10 mV reads 10 / 20 / 0.2 = 2.5 A ([`offset_error_a`]; on the 18v22's 10 mV/A it would be
//!   5 A). So it is learnt, from readings whose filter holds no drive and no sleep: with the
//!   driver awake and braking (duty 0: the brake phase is the whole period, and `CS` shows no
//!   current there) for [`OFFSET_SETTLE_TICKS`] at least, so that the RC filter has forgotten
//!   both the last drive and the sleep level (e^−8: 0.02 mV of a 50 mV step). Each wake starts
//!   a fresh mean (then an average over some 16 ticks), from readings within
//!   [`OFFSET_RANGE_MV`] only; it starts at [`CURRENT_SENSE_OFFSET_MV`]. The controller brakes
//!   for [`OFFSET_WINDOW_TICKS`] before each run drives, and the self-test's first phase brakes
//!   longer, so each learns it afresh before it drives.
//! - Never asleep: what `CS` reads while the G2 sleeps is not documented (Pololu gives the
//!   offset awake only), and the controller idles asleep, so an offset learnt at rest would be
//!   the sleep level. Nor is such a reading a current: the current reads 0 A for a reading
//!   whose last tick the driver slept through (a sleeping G2 drives nothing), and for one whose
//!   filter holds no drive (braking once the duty filter has settled at zero), whatever the
//!   level. So a sleep level far from the offset reads as no current at rest, as the driver
//!   falls asleep after a run (the filter moving to the sleep level as the duty filter decays),
//!   or as it wakes (the brake before a run, and before a reset or a self-test drives).
//! - A tick without a reading (the board's ADC was busy with the supply, or its conversion had
//!   not finished) keeps the last current.
//! - Unknown (`None`, which the controller treats as an over-current): no reading for more than
//!   [`CURRENT_STALE_TICKS`] ticks in a row, or a reading at the top of the ADC's range
//!   ([`CS_ADC_MAX_MV`], clipped: the true value may be anywhere above).
//!
//! [`Hardware::tick`]: crate::hardware::Hardware::tick

use crate::controller::PERIOD_US;
use crate::motor::MotorOutput;

/// Current-sense gain of the Pololu G2 18v17 (the reference driver): its `CS` output rises by
/// about 20 mV per amp of motor current in the drive phase. [`MotorCurrent`] starts with it;
/// the device's driver (`G2Variant`, the board's `board::DRIVER`) sets its own gain each tick
/// (`Hardware::tick`): 40 mV/A on a 24v13, whose sources `G2Variant` cites.
pub const CURRENT_SENSE_MV_PER_A: f32 = 20.0;

/// Current-sense offset of the Pololu G2 18v17: its `CS` output sits about 50 mV above ground
/// at zero current. The starting point of the offset [`MotorCurrent`] learns.
pub const CURRENT_SENSE_OFFSET_MV: f32 = 50.0;

/// Readings that may be the offset, mV: about 50 mV give or take what boards show. A reading
/// outside it with the bridge braking is not taken for the offset.
pub const OFFSET_RANGE_MV: core::ops::RangeInclusive<f32> = 30.0..=80.0;

/// Ticks the bridge must have braked, awake, before a reading is the offset: the RC filter
/// has then forgotten the last drive and the sleep level alike (e^−8 < 0.04 % of either).
pub const OFFSET_SETTLE_TICKS: u64 = SETTLED_TICKS;

/// Ticks the controller brakes, awake, before a run drives (the self-test's first phase brakes
/// longer): [`OFFSET_SETTLE_TICKS`], then 12 readings of the offset (10 or 11 once the supply's
/// conversions, one tick in ten, take their place) averaging the ADC's 1 mV noise and steps to
/// about 0.3 mV, 0.08 A at the duty floor. It lengthens each run by 20 ms.
pub const OFFSET_WINDOW_TICKS: u64 = OFFSET_SETTLE_TICKS + 12;

/// What an offset error of `error_mv` reads as at a filtered duty of `duty` (at most the
/// floor's division), A: 10 mV at the floor is 2.5 A.
pub fn offset_error_a(error_mv: f32, duty: f32) -> f32 {
    error_mv / CURRENT_SENSE_MV_PER_A / duty.max(DUTY_FLOOR)
}

/// The RC filter's resistor, in series from the G2's `CS` to the ADC pin, Ω.
pub const CS_FILTER_OHM: f32 = 10_000.0;
/// The RC filter's capacitor, from the ADC pin to ground, nF.
pub const CS_FILTER_NF: f32 = 100.0;
/// The RC filter's time constant, µs (10 kΩ × 100 nF).
pub const CS_FILTER_TAU_US: u64 = 1_000;

/// e^(−[`PERIOD_US`] / [`CS_FILTER_TAU_US`]): how much of the filter's state is left after one
/// tick (a constant: no `expf` on the hot path; a test checks it against the time constant).
pub const FILTER_DECAY_PER_TICK: f32 = 0.367_879_44;

/// Ticks after which the filter counts as fully settled (e^−8 < 0.04 %): a longer gap between
/// two outputs is counted as this many.
const SETTLED_TICKS: u64 = 8;

/// Below this filtered duty the division uses this instead (see the module docs).
pub const DUTY_FLOOR: f32 = 0.2;

/// A filtered duty below this counts as zero: the bridge has been idle for the filter to settle,
/// so the reading holds no current (the offset awake, the sleep level asleep).
const IDLE_DUTY: f32 = 1e-3;

/// The learnt offset is the mean of the first braking readings since the driver woke, then
/// follows them with a weight of one in this many (an average over some 16 ticks).
const OFFSET_AVERAGED: u32 = 16;

/// The highest trusted calibrated reading of the ADC at 0 dB attenuation, the `CS` channel's,
/// mV: Espressif gives the ESP32-C3's range at 0 dB as about 0–750 mV (the ESP32-C6's is no
/// narrower). esp-hal's calibrated output does not clip at it (its 0 dB curve is fitted through
/// the eFuse reference point at 400 mV), so a reading at or above it counts as clipped: the
/// current is unknown. The filtered `CS` stays far below it: 50 mV plus 20 mV/A times D·i,
/// 180 mV at the 6.5 A limit, four times finer than at 11 dB (2.5 V over the same 12 bits).
pub const CS_ADC_MAX_MV: u16 = 750;

/// Ticks without a finished current-sense conversion after which the current counts as unknown.
pub const CURRENT_STALE_TICKS: u32 = 10;

/// The filtered `CS`, as amps of D·|i| above `offset_mv` (never negative), at a gain of
/// `mv_per_a`.
fn filtered_a(cs_mv: u16, offset_mv: f32, mv_per_a: f32) -> f32 {
    ((f32::from(cs_mv) - offset_mv) / mv_per_a).max(0.0)
}

/// The motor current from the filtered `CS` reading and the duty filtered alike (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorCurrent {
    /// The duty through the filter, at the moment the last output was applied.
    duty_filtered: f32,
    /// The duty the bridge holds since then (0 asleep).
    held_duty: f32,
    /// When the last output was applied, µs.
    last_applied_us: Option<u64>,
    /// The driver is awake since the last output.
    held_awake: bool,
    /// The driver was awake over the tick before the last output: the last tick the reading
    /// (taken as that output was applied) saw.
    awake_before: bool,
    /// Since when the bridge brakes awake (duty 0), held to the last output; `None` while it
    /// drives or sleeps.
    braking_since_us: Option<u64>,
    /// The learnt `CS` offset, mV.
    offset_mv: f32,
    /// Braking readings learnt from since the driver last woke, up to [`OFFSET_AVERAGED`].
    offset_readings: u32,
    /// The last current, A, and how many ticks without a reading have passed since.
    last_a: f32,
    stale_ticks: u32,
    /// The driver's current-sense gain, mV/A ([`CURRENT_SENSE_MV_PER_A`] until set).
    mv_per_a: f32,
    /// Since when the driver sleeps, held to the last output; `None` while it is awake.
    asleep_since_us: Option<u64>,
    /// The last reading taken with the driver asleep long enough for the filter to hold the
    /// sleep level, mV (for `Diagnostics`; never used as the offset).
    asleep_mv: Option<u16>,
    /// An offset was learnt since boot.
    offset_learnt: bool,
}

impl Default for MotorCurrent {
    fn default() -> Self {
        Self::new()
    }
}

/// Whole ticks from `from_us` to `to_us`, rounded.
fn ticks_between(from_us: u64, to_us: u64) -> u64 {
    (to_us.saturating_sub(from_us) + PERIOD_US / 2) / PERIOD_US
}

impl MotorCurrent {
    /// The bridge asleep, the offset at its nominal value; 0 A until a reading with drive in it
    /// comes (or [`CURRENT_STALE_TICKS`] ticks pass without a reading).
    pub const fn new() -> Self {
        Self {
            duty_filtered: 0.0,
            held_duty: 0.0,
            last_applied_us: None,
            held_awake: false,
            awake_before: false,
            braking_since_us: None,
            offset_mv: CURRENT_SENSE_OFFSET_MV,
            offset_readings: 0,
            last_a: 0.0,
            stale_ticks: 0,
            mv_per_a: CURRENT_SENSE_MV_PER_A,
            asleep_since_us: None,
            asleep_mv: None,
            offset_learnt: false,
        }
    }

    /// The driver's current-sense gain is `mv_per_a` (`G2Variant::cs_mv_per_a`).
    pub fn set_mv_per_a(&mut self, mv_per_a: f32) {
        self.mv_per_a = mv_per_a;
    }

    /// The motor current, A, from this tick's `CS` reading (mV; `None`: there is none this
    /// tick), taken when the last output was applied; `None` when it is unknown (module docs). A
    /// reading taken braking, awake, long enough also updates the learnt offset.
    pub fn current_a(&mut self, cs_mv: Option<u16>) -> Option<f32> {
        let Some(cs_mv) = cs_mv else {
            self.stale_ticks = self.stale_ticks.saturating_add(1);
            return (self.stale_ticks <= CURRENT_STALE_TICKS).then_some(self.last_a);
        };
        if cs_mv >= CS_ADC_MAX_MV {
            return None;
        }
        self.stale_ticks = 0;
        self.last_a = if !self.awake_before {
            // The driver slept through the reading's last tick: it drove nothing.
            self.note_asleep(cs_mv);
            0.0
        } else if self.duty_filtered < IDLE_DUTY {
            // No drive in the filter's memory: no current to show, maybe an offset to learn.
            self.learn_offset(f32::from(cs_mv));
            0.0
        } else {
            filtered_a(cs_mv, self.offset_mv, self.mv_per_a) / self.duty_filtered.max(DUTY_FLOOR)
        };
        Some(self.last_a)
    }

    /// Learn from `reading_mv` if it was taken braking, awake, for [`OFFSET_SETTLE_TICKS`] at
    /// least, and is a plausible offset: the first since the driver woke replaces the offset,
    /// the next ones are averaged in.
    fn learn_offset(&mut self, reading_mv: f32) {
        let settled = match (self.braking_since_us, self.last_applied_us) {
            (Some(since_us), Some(last_us)) => {
                ticks_between(since_us, last_us) >= OFFSET_SETTLE_TICKS
            }
            _ => false,
        };
        if settled && OFFSET_RANGE_MV.contains(&reading_mv) {
            self.offset_learnt = true;
            self.offset_readings = (self.offset_readings + 1).min(OFFSET_AVERAGED);
            self.offset_mv += (reading_mv - self.offset_mv) / self.offset_readings as f32;
        }
    }

    /// Keep `cs_mv` as the sleep level if the driver has slept for the filter to settle on it.
    fn note_asleep(&mut self, cs_mv: u16) {
        let settled = match (self.asleep_since_us, self.last_applied_us) {
            (Some(since_us), Some(last_us)) => ticks_between(since_us, last_us) >= SETTLED_TICKS,
            _ => false,
        };
        if settled {
            self.asleep_mv = Some(cs_mv);
        }
    }

    /// The bridge was set to `out` at `now_us` (the safe state if applying it failed): the duty
    /// filter advances over the time since the last output, then holds `out`'s duty. A driver
    /// woken starts a fresh offset; braking starts (or goes on) counting towards one.
    pub fn applied(&mut self, out: &MotorOutput, now_us: u64) {
        if let Some(last_us) = self.last_applied_us {
            let mut left = 1.0;
            for _ in 0..ticks_between(last_us, now_us).min(SETTLED_TICKS) {
                left *= FILTER_DECAY_PER_TICK;
            }
            self.duty_filtered = self.held_duty + (self.duty_filtered - self.held_duty) * left;
        }
        self.held_duty = if out.awake {
            out.duty.clamp(0.0, 1.0)
        } else {
            0.0
        };
        if out.awake && !self.held_awake {
            self.offset_readings = 0;
        }
        let braking = out.awake && self.held_duty == 0.0;
        self.braking_since_us = braking.then(|| self.braking_since_us.unwrap_or(now_us));
        self.asleep_since_us = (!out.awake).then(|| self.asleep_since_us.unwrap_or(now_us));
        self.awake_before = self.held_awake;
        self.held_awake = out.awake;
        self.last_applied_us = Some(now_us);
    }

    /// The duty through the filter when the last output was applied.
    pub fn duty_filtered(&self) -> f32 {
        self.duty_filtered
    }

    /// The learnt `CS` offset, mV.
    pub fn offset_mv(&self) -> f32 {
        self.offset_mv
    }

    /// Whether the offset was learnt since boot (false: still the nominal one).
    pub fn offset_learnt(&self) -> bool {
        self.offset_learnt
    }

    /// The last reading with the driver asleep and the filter settled on its sleep level, mV.
    pub fn asleep_mv(&self) -> Option<u16> {
        self.asleep_mv
    }
}

#[cfg(test)]
mod tests;
