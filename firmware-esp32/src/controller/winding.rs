//! The winding's resistance, from the measured motor current at the jam, and what it does to
//! the duty: torque that stays right as the winding warms.
//!
//! # Why
//!
//! At standstill the motor's torque is proportional to its current, i = D·V/R: the duty sets a
//! torque only for the resistance R the calibration was made at. Copper's resistance rises
//! 0.39 %/°C, so a winding at 102 °C (30 % more) gives 30 % less torque for the same duty, and
//! back-to-back runs warm it by a few degrees each: readings drift low (some 4 µm at 100 µm on the
//! twin at 102 °C). The configuration implies the reference resistance, R_ref =
//! `torque_per_amp_nm` · V_ref / `torque_per_duty_nm` (V_ref = 12 V: the stall current at the
//! reference supply is `torque_per_duty_nm / torque_per_amp_nm`).
//!
//! # How
//!
//! Where the hub stands still with the bridge driving, the back-EMF is zero and the winding's
//! resistance is R = V·D / I. The still moments with a well-known duty are the jam's settle: the
//! [`JAM_SETTLE_TICKS`](super::JAM_SETTLE_TICKS) ticks at the target torque before the hold. Over
//! its first ticks (after the first [`SKIP_TICKS`], once the current sense's RC filter has
//! followed the duty) the controller sums V·D (the filtered supply times the duty applied) and I
//! (the motor current); on the settle's [`ESTIMATE_TICK`]-th tick it divides once:
//!
//! ```text
//!   ρ = Σ(V·D) / (Σ I · R_ref)          the winding's resistance over the reference
//! ```
//!
//! and from then on every duty is multiplied by ρ (folded into the supply's duty scale, so no
//! extra operation a tick: a winding ρ times as resistive acts like a calibration made at ρ·12 V,
//! see `supply.rs`). A factor that rose by more than [`MAX_STEP`] would step the torque up at the
//! jam, and the inset would overshoot into the self-locking spiral; the commanded torque is then
//! lowered to what was really applied, and the ramp takes it up again (`run.rs`). Otherwise the
//! settle's remaining ticks let the hub take the corrected torque (a hub that moves starts the
//! settle, and the estimate, again). So the hold of this very run, and
//! everything after it (reset, self-test, the next runs, whose ramps start from it), drives the
//! torque the controller commands. The factor is kept in RAM across runs and starts at 1 at
//! boot.
//!
//! - **Noise.** The current's noise (±0.05 A and more) is divided by the duty; only ticks with
//!   a duty of at least [`MIN_DUTY`] count (the current sense's conversion divides by at least 0.2
//!   and reads low below it), and the sums average 7 readings: about 1 % at a 1 A jam. Each
//!   run's settle gives a fresh factor; it is taken whole, not filtered across runs, because a run
//!   warms the winding by a few per cent, which a slow filter would lag behind.
//! - **Gain error.** The current sense's gain is known to ±10 % (the supply sense's to ±3 %), and
//!   ρ inherits it: a torque set from current is as good as the current sense, where one from
//!   duty alone is as good as the calibration. Estimating only the *change* of resistance since a
//!   first still estimate after boot would cancel the gain error, but a device that boots warm
//!   (restarted mid-job), or in a cold or hot enclosure (0–45 °C: −10 % to +8 %), then starts
//!   from a wrong reference and never learns it, and the warmth is systematic and larger (+37 % at
//!   120 °C) than the gain error, which is random from board to board. So ρ is absolute, and
//!   the gain error is what remains: 5 % of torque, some 0.7 µm at kerf 100 µm, on the twin's
//!   default sense (which reads 5 % high).
//! - **Cost.** Three soft-float operations on each settle tick, three divisions and a few more
//!   on the estimate's tick; nothing on the hold's last tick (the worst one).
//!
//! # After the hold, where no settle could measure
//!
//! Where every settle's duty stays under [`MIN_DUTY`] (a light force on a 24 V supply), the
//! torque is known only as well as the factor left by the last measurement or the boot. After
//! the probe (the reading's angles are taken), the run then ramps the torque to what drives
//! [`CHECK_DUTY`], within its cap, what full duty gives and [`CHECK_MAX_TORQUE_RATIO`] times the
//! held torque, with the run's time left for it ([`CHECK_MARGIN_MS`]) and the inset clear of
//! the spiral's disengage; once the hub stands still, the winding is measured over
//! [`CHECK_READINGS`] ticks as at a settle. The factor found applies from then on, and the hold
//! is judged with the torque error it reveals, (r − 1)(1 + b·k/τ) for a winding r =
//! ρ_held/ρ_found times as conductive as the hold assumed (`run.rs`, `conclude_check`); the
//! result reports the torque and force really held. A build whose check duty is past the run's
//! cap (a high gear ratio at the default 0.8 N·m), a hub that never stands still under it, and
//! a check whose estimate is implausible (at a fraction of an amp the sense's noise and offset
//! can do that as well as a wrong calibration: the factor stands, nothing is flagged, and a
//! normal run's settle is what judges the calibration) stay unmeasured.
//!
//! # Torque mismatch
//!
//! A factor outside [`PLAUSIBLE_FACTOR`] is more than the winding's temperature (−10–130 °C) and
//! the senses' gain errors explain: the torque set from the duty and the measured current
//! disagree (a wrong `torque_per_duty_nm` or `torque_per_amp_nm`, a driver limiting its current
//! below the stall current, a loose motor lead). The result is flagged
//! [`QualityFlags::TORQUE_MISMATCH`](kerfmeter_protocol::QualityFlags::TORQUE_MISMATCH) and the
//! factor applied is held to the range.

use core::ops::RangeInclusive;

use kerfmeter_protocol::{DeviceConfig, REFERENCE_SUPPLY_V};

/// The first settle ticks (counted from 1) whose readings are left out: the current sense's
/// RC filter (τ = 1 ms) and its conversion, one tick behind, still follow the last ramp steps.
pub const SKIP_TICKS: u32 = 4;

/// The least duty whose current counts, fraction: above the current conversion's floor (0.2),
/// below which the current reads low, with margin for the duty filter's lag.
pub const MIN_DUTY: f32 = 0.22;

/// The fewest readings a factor is estimated from.
pub const MIN_READINGS: u32 = 6;

/// The most the factor may rise at a jam without the torque being ramped up to it again
/// (fraction): twice the estimate's noise, some 0.1 µm of contact compression at the jam.
pub const MAX_STEP: f32 = 0.02;

/// The settle tick (counted from 1) on which the factor is estimated and applied: readings from
/// tick [`SKIP_TICKS`] + 1 up to here (7 of them), and the settle's last
/// [`JAM_SETTLE_TICKS`](super::JAM_SETTLE_TICKS) − 12 ticks for the hub to take the new torque
/// before the hold collects its angles.
pub const ESTIMATE_TICK: u32 = 12;

/// The duty the winding check after the probe drives, fraction: [`MIN_DUTY`] with margin for
/// the supply's filter moving under the check's load (a sag raises the duty scale, and the
/// check's torque was set from the scale before it), so that the duty applied stays past
/// [`MIN_DUTY`].
pub const CHECK_DUTY: f32 = 0.26;

/// The most the winding check may press the jam, as a multiple of the held torque: the spiral
/// keeps the check's compression (a gauge is not measured twice), and a torque many times the
/// requested force's would crush a soft gauge's contact for nothing; a light run whose check
/// would need more stays unmeasured.
pub const CHECK_MAX_TORQUE_RATIO: f32 = 2.0;

/// The readings the winding check averages: far more than a settle's 7 (it has the time), for
/// it reads the current at a duty just past [`MIN_DUTY`], where a motor of a few ohms draws under
/// an amp: some 5 mV of filtered `CS` against an ADC noise of up to 2.6 mV (the robustness
/// sweep's draws). 64 readings bring that to 0.3 mV, some 6 %.
pub const CHECK_READINGS: u32 = 64;

/// The most ticks the winding check waits for the hub to stand still and take its readings:
/// the regression's window, [`SKIP_TICKS`] and [`CHECK_READINGS`] with room for the contact to
/// settle under the new torque.
pub const CHECK_MAX_TICKS: u32 = 200;

/// How many times the turn the contact's measured compliance predicts for the check's extra
/// torque the hub may turn on under the check before the contact counts as giving way (besides
/// `JAM_SLIP_DEG`): the compliance was measured at the hold's torque, and a contact stiffens as
/// it is pressed, so twice is a wide margin for a sound one.
pub const CHECK_COMPLIANCE_MARGIN: f32 = 2.0;

/// The least turn under the probe, encoder LSB, for the probe's compliance to stand alone in
/// the check's allowance. The probe measures the contact at the held torque, the tangent a
/// stiffening contact only departs from downwards; the approach's turn (from 80 % of the target)
/// is a secant over the softer start of a tapered contact, up to several times larger, which let
/// a contact crushing 17 % above the held force turn 3.3° on under the check unnoticed on the
/// twin. A probe held by static friction (less than this) measured nothing: the approach's is
/// taken then.
pub const CHECK_PROBE_MIN_RISE_LSB: f32 = 4.0;

/// The largest held-torque error, as a fraction, the check's estimate is trusted with: beyond
/// it the torque is left unknown (uncertain by `TORQUE_UNCERTAINTY_UNMEASURED`) rather than
/// corrected. Copper between −10 and 130 °C with a factor from boot moves the torque by at most
/// some 40 % with the breakaway's share.
pub const CHECK_MAX_ERROR: f32 = 0.5;

/// Run time the winding check keeps in hand beyond its ramp, its [`CHECK_MAX_TICKS`] and the
/// release after it, ms (the ramp's and the release's times follow from the torques), so that it
/// never turns a run into a `MaxRunTime` fault.
pub const CHECK_MARGIN_MS: u32 = 100;

/// The factors the winding's temperature and the senses' gain errors explain: copper at
/// −10–130 °C (0.86–1.41 of its resistance at 25 °C), read through a current sense ±10 % and a
/// supply sense ±3 % off (0.88–1.14 of the ratio).
pub const PLAUSIBLE_FACTOR: RangeInclusive<f32> = 0.76..=1.61;

/// The winding's resistance over the reference one, and the sums it is estimated from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct WindingEstimate {
    /// ρ, the factor applied to every duty (1 at boot).
    factor: f32,
    /// Σ V·D over the readings, V.
    drive_v: f32,
    /// Σ I over the readings, A.
    current_a: f32,
    /// The readings summed.
    readings: u32,
}

impl WindingEstimate {
    /// At boot: the reference resistance, nothing summed.
    pub(super) const fn new() -> Self {
        Self {
            factor: 1.0,
            drive_v: 0.0,
            current_a: 0.0,
            readings: 0,
        }
    }

    /// The factor applied to every duty.
    pub(super) fn factor(&self) -> f32 {
        self.factor
    }

    /// The readings summed so far.
    pub(super) fn readings(&self) -> u32 {
        self.readings
    }

    /// Forget the readings (the hub moved).
    pub(super) fn clear(&mut self) {
        self.drive_v = 0.0;
        self.current_a = 0.0;
        self.readings = 0;
    }

    /// A still tick: `drive_v` (supply × duty applied) drove `current_a` through the winding.
    pub(super) fn push(&mut self, drive_v: f32, current_a: f32) {
        self.drive_v += drive_v;
        self.current_a += current_a;
        self.readings += 1;
    }

    /// Estimate the factor from the readings, which are then forgotten: `None` with too few of
    /// them (the factor stands), else whether the estimate was implausible (a torque mismatch;
    /// the factor is then held to [`PLAUSIBLE_FACTOR`]).
    pub(super) fn conclude(&mut self, config: &DeviceConfig) -> Option<bool> {
        let estimate = self.estimate(config)?;
        let plausible = PLAUSIBLE_FACTOR.contains(&estimate);
        self.factor = estimate.clamp(*PLAUSIBLE_FACTOR.start(), *PLAUSIBLE_FACTOR.end());
        Some(!plausible)
    }

    /// Like [`Self::conclude`], for the check after the hold, where the current is read at a
    /// duty just past [`MIN_DUTY`] and may be a fraction of an amp: a factor is taken only if
    /// it is plausible; an implausible one is the sense's noise and offset as likely as a wrong
    /// calibration, and the factor stands (whether it was taken).
    pub(super) fn conclude_if_plausible(&mut self, config: &DeviceConfig) -> bool {
        match self.estimate(config) {
            Some(estimate) if PLAUSIBLE_FACTOR.contains(&estimate) => {
                self.factor = estimate;
                true
            }
            _ => false,
        }
    }

    /// ρ from the readings, which are then forgotten; `None` with too few of them.
    fn estimate(&mut self, config: &DeviceConfig) -> Option<f32> {
        let enough = self.readings >= MIN_READINGS;
        let (drive_v, current_a) = (self.drive_v, self.current_a);
        self.clear();
        if !enough {
            return None;
        }
        // ρ = Σ(V·D) / (Σ I · R_ref), R_ref = torque_per_amp · V_ref / torque_per_duty. No
        // current at all (a loose lead) is an infinite resistance.
        let reference_ohm =
            config.torque_per_amp_nm * REFERENCE_SUPPLY_V / config.torque_per_duty_nm;
        let denominator = current_a * reference_ohm;
        Some(if denominator > 0.0 {
            drive_v / denominator
        } else {
            f32::INFINITY
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R_ref of the default configuration, Ω (0.157 · 12 / 0.88).
    fn reference_ohm() -> f32 {
        let c = DeviceConfig::DEFAULT;
        c.torque_per_amp_nm * REFERENCE_SUPPLY_V / c.torque_per_duty_nm
    }

    /// `n` readings of a winding `rho` times the reference, at `duty` on 12 V, the current
    /// alternating ±`noise_a`.
    fn estimate(rho: f32, duty: f32, n: u32, noise_a: f32) -> (Option<bool>, f32) {
        let mut w = WindingEstimate::new();
        let drive_v = 12.0 * duty;
        for i in 0..n {
            let noise = if i % 2 == 0 { noise_a } else { -noise_a };
            w.push(drive_v, drive_v / (rho * reference_ohm()) + noise);
        }
        let mismatch = w.conclude(&DeviceConfig::DEFAULT);
        (mismatch, w.factor())
    }

    #[test]
    fn the_factor_is_the_resistance_over_the_reference() {
        assert_eq!(WindingEstimate::new().factor(), 1.0);
        for rho in [0.9, 1.0, 1.3] {
            let (mismatch, factor) = estimate(rho, 0.5, 16, 0.05);
            assert_eq!(mismatch, Some(false));
            assert!((factor - rho).abs() < 2e-3 * rho, "{rho}: {factor}");
        }
    }

    #[test]
    fn too_few_readings_keep_the_factor() {
        let mut w = WindingEstimate::new();
        w.push(6.0, 3.0);
        assert_eq!(w.conclude(&DeviceConfig::DEFAULT), None);
        assert_eq!(w.factor(), 1.0);
        // The readings were forgotten: a later settle starts afresh.
        for _ in 0..MIN_READINGS {
            w.push(6.0, 6.0 / (1.2 * reference_ohm()));
        }
        assert_eq!(w.conclude(&DeviceConfig::DEFAULT), Some(false));
        assert!((w.factor() - 1.2).abs() < 1e-3, "{}", w.factor());
    }

    #[test]
    fn an_implausible_factor_is_a_mismatch_and_held_to_the_range() {
        let (mismatch, factor) = estimate(0.6, 0.5, 16, 0.0);
        assert_eq!((mismatch, factor), (Some(true), 0.76));
        let (mismatch, factor) = estimate(2.0, 0.5, 16, 0.0);
        assert_eq!((mismatch, factor), (Some(true), 1.61));
        // No current at all while driven.
        let mut w = WindingEstimate::new();
        for _ in 0..MIN_READINGS {
            w.push(6.0, 0.0);
        }
        assert_eq!(w.conclude(&DeviceConfig::DEFAULT), Some(true));
        assert_eq!(w.factor(), 1.61);
    }
}
