//! Supply-aware torque: the measured motor supply, filtered, and what it means for the duty.
//!
//! At standstill the motor's torque is proportional to the voltage it is driven with, duty ×
//! supply. The configuration's `torque_per_duty_nm` and `breakaway_duty` are figures at
//! [`REFERENCE_SUPPLY_V`] (12 V), so the duty for a torque at the reference is scaled by
//! `REFERENCE_SUPPLY_V / supply` ([`SupplyFilter::duty_scale`]): a torque is then the same from
//! [`SUPPLY_MIN_V`] to [`SUPPLY_MAX_V`](kerfmeter_protocol::SUPPLY_MAX_V), and so are the `max_torque_nm` cap and the current.
//!
//! The reading is the driver's bus *after* the supply's sag under load, so the scaling makes up
//! for the sag as well (the sag that a stiff 12 V bench supply does not have). It is filtered by
//! a first-order low-pass, one multiply-add a tick ([`SUPPLY_FILTER_GAIN`], a 32 ms time
//! constant): the supply-sense noise (up to 0.5 V SD) falls to a eighth (0.06 V, 0.5 % of the
//! torque at 12 V), while the sag, which follows the current and so the torque ramp (at most
//! about 1.5 V per second), is followed within some 0.05 V.
//!
//! # The winding's resistance
//!
//! The calibration holds for the winding's resistance at calibration; a winding ρ times as
//! resistive (warm: `winding.rs` estimates ρ from the measured current at each jam) needs ρ times
//! the duty for the same torque, as if the calibration had been made at ρ·`REFERENCE_SUPPLY_V`.
//! So the filter keeps that *effective reference* ([`SupplyFilter::set_winding_factor`]), which
//! the duty scale and the torque full duty gives use (no extra operation a tick: the scale was a
//! division by the supply already). The refusal of a run for its supply does not: it is judged
//! with the winding as at calibration, since warmth passes within minutes and a run that a warm
//! winding leaves short of torque is held to full duty and flagged `SUPPLY_LIMITED` as for a
//! sag.
//!
//! # Not measured
//!
//! A reading of 0 V is a reading, not a missing one: the motor supply is off (or the divider is
//! not fitted), `SUPPLY_OUT_OF_RANGE` stands and blocks a run, reset and self-test (first bench
//! check 3 in the README).
//!
//! Where the board passes no reading (`None` since boot), the supply is taken to be
//! [`REFERENCE_SUPPLY_V`]: the duty is not scaled, no run is refused for its supply and
//! [`Conditions::SUPPLY_OUT_OF_RANGE`](kerfmeter_protocol::Conditions::SUPPLY_OUT_OF_RANGE) never
//! stands; `Status.supply_v` says `None`, so a host can tell. Such a device's torque is right on
//! a 12 V supply only (on 24 V it doubles, and the over-current trip is what stops it). Once a
//! reading has been seen, a tick without one keeps the filtered value: a dropped ADC conversion
//! must not swing the duty back to the reference's mid-run.
//!
//! # Limits
//!
//! - Rated range: outside [`SUPPLY_MIN_V`]–[`SUPPLY_MAX_V`](kerfmeter_protocol::SUPPLY_MAX_V), or above the motor driver's own
//!   safe maximum ([`G2Variant::supply_max_v`]: 24 V on the G2 18v17), at rest, by more than the
//!   reading's own uncertainty ([`SUPPLY_SENSE_TOLERANCE`] of it plus
//!   [`SUPPLY_SENSE_ADC_ERROR_V`]), the controller reports the idle condition
//!   `SUPPLY_OUT_OF_RANGE`, which blocks a run, reset and self-test (latching nothing). The
//!   condition is judged only at rest, on the unloaded supply: under load the bus sags by
//!   design, and a sag is judged by what it does to the torque (next item).
//! - Reachable torque: a run is refused with `ErrorCode::SupplyTooLow` when the most torque it
//!   may ask for needs more than full duty at the measured supply ([`needed_supply_v`]), with
//!   the winding as at calibration.
//! - Mid-run sag: should the bus sag so far under load that the ramp's torque needs more than
//!   full duty, the ramp holds the torque to what full duty delivers at the measured supply
//!   ([`SupplyFilter::full_duty_torque_nm`]), like the `max_torque_nm` cap; a jam reached so is
//!   flagged `SUPPLY_LIMITED`, with the torque and force it was really measured at. No fault: the
//!   motor is driven as asked, only less hard, and the result says so.

use kerfmeter_protocol::{DeviceConfig, G2Variant, REFERENCE_SUPPLY_V, SUPPLY_MIN_V};

/// The least supply the duty's scale is taken at, V: below the G2's under-voltage lockout
/// (5.8 V typical), where the bridge does not drive, so the scale only has to stay finite for a
/// supply that is off (0 V) and not swing far past the rated minimum's while the filter follows
/// a supply switched on.
pub(super) const SCALE_FLOOR_V: f32 = 4.0;

/// The supply filter's gain per tick: a first-order low-pass of time constant 1/gain ticks
/// (32 ms at 1 kHz). It divides white noise's SD by √(2/gain − 1) ≈ 8.
pub const SUPPLY_FILTER_GAIN: f32 = 1.0 / 32.0;

/// How far a reading may stray from the true supply in proportion to it: the divider's 1 %
/// resistors (±2 %). The ADC's own error is not proportional: [`SUPPLY_SENSE_ADC_ERROR_V`].
pub const SUPPLY_SENSE_TOLERANCE: f32 = 0.02;

/// How far a reading may stray from the true supply for the ADC's error, V: Espressif gives
/// the ESP32-C3's calibrated ADC as about ±35 mV at 11 dB, which the 100 k/8.2 k divider
/// multiplies by 13.2: ±0.46 V (3.8 % at 12 V, 5.1 % at 9 V, 1.9 % at 24 V; the 3 % assumed
/// before issue 34 was loose at 12 V and below). A supply at the edge of the rated range is
/// not refused for the sense's error: the range is widened by both either way (8.36–24.94 V as
/// read on a G2 18v17, 8.36–26.98 V on a 24 V variant).
pub const SUPPLY_SENSE_ADC_ERROR_V: f32 = 0.035 * crate::board::supply::SUPPLY_DIVIDER_RATIO;

/// The filtered motor supply and the duty scale it gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SupplyFilter {
    /// The filtered supply, V; `None` until the first reading.
    supply_v: Option<f32>,
    /// `reference_v / supply_v` (the winding factor while not measured), kept so that the duty
    /// costs a multiply, not a division, wherever it is computed.
    duty_scale: f32,
    /// The effective reference supply, V: `REFERENCE_SUPPLY_V` × the winding's resistance factor.
    reference_v: f32,
    /// 1 / `reference_v`, 1/V.
    per_reference_v: f32,
    /// The highest rated supply, V: the motor driver's ([`G2Variant::supply_max_v`]).
    max_v: f32,
}

impl SupplyFilter {
    /// Nothing measured yet.
    pub(super) const fn new() -> Self {
        Self {
            supply_v: None,
            duty_scale: 1.0,
            reference_v: REFERENCE_SUPPLY_V,
            per_reference_v: 1.0 / REFERENCE_SUPPLY_V,
            max_v: G2Variant::V18v17.supply_max_v(),
        }
    }

    /// The motor driver is `driver`: its safe maximum bounds the rated range.
    pub(super) fn set_driver(&mut self, driver: G2Variant) {
        self.max_v = driver.supply_max_v();
    }

    /// The winding is `factor` times as resistive as at calibration (`winding.rs`): every duty
    /// is scaled by it from now on.
    pub(super) fn set_winding_factor(&mut self, factor: f32) {
        self.reference_v = REFERENCE_SUPPLY_V * factor;
        self.per_reference_v = 1.0 / self.reference_v;
        self.duty_scale = match self.supply_v {
            Some(v) => self.reference_v / v,
            None => factor,
        };
    }

    /// Take this tick's reading (`None`: none this tick, the filtered value stands). The first
    /// reading starts the filter; a reading that is not a number, or negative, is skipped. Zero
    /// is a reading: the motor supply is off (or its divider is not fitted), which is out of the
    /// rated range and blocks a run until it is on. The duty's scale is taken at no less than
    /// [`SCALE_FLOOR_V`] (finite at 0 V; below any G2's under-voltage lockout, so a bus the
    /// bridge can drive is scaled by what it reads).
    pub(super) fn update(&mut self, reading_v: Option<f32>) {
        let Some(v) = reading_v.filter(|v| *v >= 0.0) else {
            return;
        };
        let filtered = match self.supply_v {
            Some(f) => f + (v - f) * SUPPLY_FILTER_GAIN,
            None => v,
        };
        self.supply_v = Some(filtered);
        self.duty_scale = self.reference_v / filtered.max(SCALE_FLOOR_V);
    }

    /// The filtered supply, V; `None` where it is not measured.
    pub(super) fn supply_v(&self) -> Option<f32> {
        self.supply_v
    }

    /// What a duty at the reference supply is multiplied by at this supply.
    pub(super) fn duty_scale(&self) -> f32 {
        self.duty_scale
    }

    /// The measured supply is outside the rated range, beyond the sense's tolerance (false
    /// where it is not measured).
    pub(super) fn out_of_range(&self) -> bool {
        let rated_as_read = SUPPLY_MIN_V * (1.0 - SUPPLY_SENSE_TOLERANCE) - SUPPLY_SENSE_ADC_ERROR_V
            ..=self.max_v * (1.0 + SUPPLY_SENSE_TOLERANCE) + SUPPLY_SENSE_ADC_ERROR_V;
        self.supply_v.is_some_and(|v| !rated_as_read.contains(&v))
    }

    /// The output torque full duty gives at this supply, N·m (at standstill, past breakaway);
    /// `f32::INFINITY` where the supply is not measured (no limit is known).
    pub(super) fn full_duty_torque_nm(&self, config: &DeviceConfig) -> f32 {
        match self.supply_v {
            Some(v) => {
                (v * self.per_reference_v - config.breakaway_duty) * config.torque_per_duty_nm
            }
            None => f32::INFINITY,
        }
    }
}

/// The least supply at which `torque_nm` is reachable at full duty with the winding as at
/// calibration, V. A run is refused on this figure, not on the warm winding's: warmth passes
/// within minutes, and a run it leaves short of torque is flagged `SUPPLY_LIMITED` (module docs).
pub(super) fn needed_supply_v(config: &DeviceConfig, torque_nm: f32) -> f32 {
    REFERENCE_SUPPLY_V * (config.breakaway_duty + torque_nm / config.torque_per_duty_nm)
}

/// `v` in millivolts, saturated to a `u16` (the figures of `ErrorCode::SupplyTooLow`).
pub(super) fn millivolts(v: f32) -> u16 {
    // Rounded half up (no `f32::round` without std); `as` saturates, and maps NaN and negative
    // figures to 0.
    (v * 1000.0 + 0.5) as u16
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_starts_at_the_first_reading_and_averages_the_noise_down() {
        let mut f = SupplyFilter::new();
        assert_eq!((f.supply_v(), f.duty_scale()), (None, 1.0));
        f.update(None);
        assert_eq!(f.supply_v(), None);
        f.update(Some(24.0));
        assert_eq!(f.supply_v(), Some(24.0));
        assert_eq!(f.duty_scale(), 0.5);
        // ±0.5 V alternating (the worst case for a low-pass is white noise; this is its
        // highest-frequency part): the filtered value stays within 0.02 V.
        for i in 0..200 {
            f.update(Some(if i % 2 == 0 { 24.5 } else { 23.5 }));
            assert!(
                (f.supply_v().unwrap() - 24.0).abs() < 0.02,
                "{:?}",
                f.supply_v()
            );
        }
        // A step is followed with the filter's time constant: 63 % after 32 ticks.
        for _ in 0..32 {
            f.update(Some(12.0));
        }
        let v = f.supply_v().unwrap();
        assert!((v - (24.0 - 12.0 * 0.638)).abs() < 0.1, "{v}");
    }

    #[test]
    fn a_supply_that_is_off_reads_0_v_out_of_range_with_a_bounded_scale() {
        let mut f = SupplyFilter::new();
        f.update(Some(0.0));
        assert_eq!(f.supply_v(), Some(0.0));
        assert!(f.out_of_range());
        assert_eq!(f.duty_scale(), REFERENCE_SUPPLY_V / SCALE_FLOOR_V);
        // Switched on: the filter follows, and the scale never exceeds the floor's.
        for _ in 0..300 {
            f.update(Some(12.0));
            assert!(f.duty_scale() <= REFERENCE_SUPPLY_V / SCALE_FLOOR_V);
        }
        assert!(!f.out_of_range());
    }

    #[test]
    fn a_missing_reading_keeps_the_filtered_value() {
        let mut f = SupplyFilter::new();
        f.update(Some(9.0));
        f.update(None);
        f.update(Some(f32::NAN));
        f.update(Some(-1.0));
        assert_eq!(f.supply_v(), Some(9.0));
        assert_eq!(f.duty_scale(), REFERENCE_SUPPLY_V / 9.0);
    }

    #[test]
    fn the_rated_range_and_the_torque_full_duty_gives() {
        let config = DeviceConfig::DEFAULT;
        let mut f = SupplyFilter::new();
        assert!(!f.out_of_range(), "not measured: no condition");
        assert_eq!(f.full_duty_torque_nm(&config), f32::INFINITY);
        // 9 V × 0.98 − 0.46 V and, on the reference G2 18v17, 24 V × 1.02 + 0.46 V (its safe
        // maximum); on a 24 V driver the device's own 26 V × 1.02 + 0.46 V.
        for (v, out) in [(8.3, true), (8.4, false), (24.9, false), (25.0, true)] {
            let mut f = SupplyFilter::new();
            f.update(Some(v));
            assert_eq!(f.out_of_range(), out, "{v}");
        }
        for (v, out) in [(26.9, false), (27.0, true)] {
            let mut f = SupplyFilter::new();
            f.set_driver(G2Variant::V24v13);
            f.update(Some(v));
            assert_eq!(f.out_of_range(), out, "{v}");
        }
        f.update(Some(REFERENCE_SUPPLY_V));
        let full = f.full_duty_torque_nm(&config);
        assert!((full - 0.96 * 0.88).abs() < 1e-5, "{full}");
        // And the supply needed for that torque is the one it was computed at.
        let needed = needed_supply_v(&config, full);
        assert!((needed - REFERENCE_SUPPLY_V).abs() < 1e-4, "{needed}");
        assert_eq!(millivolts(11.3899), 11_390);
    }

    #[test]
    fn a_warm_winding_scales_the_duty_and_what_full_duty_gives() {
        let config = DeviceConfig::DEFAULT;
        let mut f = SupplyFilter::new();
        f.set_winding_factor(1.25);
        assert_eq!(f.duty_scale(), 1.25, "not measured: the factor alone");
        f.update(Some(24.0));
        assert!((f.duty_scale() - 0.625).abs() < 1e-6, "{}", f.duty_scale());
        // Full duty at 12 V gives a quarter less drive over breakaway's share...
        let mut f12 = SupplyFilter::new();
        f12.update(Some(REFERENCE_SUPPLY_V));
        f12.set_winding_factor(1.25);
        let full = f12.full_duty_torque_nm(&config);
        assert!((full - (0.8 - 0.04) * 0.88).abs() < 1e-5, "{full}");
        // Back to the reference.
        f12.set_winding_factor(1.0);
        assert!((f12.duty_scale() - 1.0).abs() < 1e-6);
        assert_eq!(millivolts(100.0), u16::MAX);
    }
}
