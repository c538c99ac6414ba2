//! The motor supply (the G2's `VIN`) as a supply-sense divider into an ADC channel measures it:
//! the divider's values and the conversion from the pin's millivolts to volts. Chip-independent,
//! so that it is tested on the host and the digital twin hands the firmware exactly what the board
//! would read.
//!
//! The divider: [`SUPPLY_DIVIDER_TOP_OHM`] from `VIN` to the pin, [`SUPPLY_DIVIDER_BOTTOM_OHM`]
//! from the pin to ground, and a 100 nF capacitor across the bottom resistor. Why these values:
//!
//! - The G2 18v17's absolute maximum, 30 V, gives 2.27 V at the pin: inside the ESP32-C3 ADC's
//!   11 dB range (about 2.5 V) with room for ripple, so that no supply the driver survives clips
//!   the reading. 100k/10k would put 28 V at the edge of the range.
//! - The pin's source impedance (7.6 kΩ) is low enough for the ADC's sample-and-hold, and with
//!   the capacitor (τ ≈ 0.76 ms) it averages the 20 kHz PWM ripple on the bus.
//! - 0.28 mA through the divider at 30 V: negligible for the supply.
//! - E12 values with 1 % resistors: a gain error within ±2 %, plus the ADC's calibration error.
//!
//! The ADC reports calibrated millivolts, so one step is 1 mV at the pin, 13.2 mV at the bus.
//!
//! Not wired on the board yet: the C3's ADC1 channels (GPIO0–4) are all taken (current sense,
//! `SLP`, a strapping pin, `PWM`, `DIR`), so the board binary passes no supply reading; issue 12
//! moves a pin and wires it.

/// The divider's resistor from `VIN` to the ADC pin, Ω.
pub const SUPPLY_DIVIDER_TOP_OHM: f32 = 100_000.0;
/// The divider's resistor from the ADC pin to ground, Ω.
pub const SUPPLY_DIVIDER_BOTTOM_OHM: f32 = 8_200.0;
/// Supply volts per volt at the pin.
pub const SUPPLY_DIVIDER_RATIO: f32 =
    (SUPPLY_DIVIDER_TOP_OHM + SUPPLY_DIVIDER_BOTTOM_OHM) / SUPPLY_DIVIDER_BOTTOM_OHM;
/// The highest calibrated reading of the ADC at 11 dB attenuation (any channel), mV: a pin above
/// it reads this.
pub const ADC_MAX_MV: u16 = 2_500;

/// The motor supply, V, from the ADC's calibrated reading of the divider's pin, mV.
pub fn supply_v(pin_mv: u16) -> f32 {
    f32::from(pin_mv) * 1e-3 * SUPPLY_DIVIDER_RATIO
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_g2s_maximum_supply_stays_inside_the_adcs_range() {
        let pin_mv = 30.0 / SUPPLY_DIVIDER_RATIO * 1e3;
        assert!(pin_mv < f32::from(ADC_MAX_MV) * 0.95, "{pin_mv}");
        assert!(pin_mv > 2_000.0, "uses most of the range: {pin_mv}");
    }

    #[test]
    fn a_reading_converts_back_to_the_supply() {
        let pin_mv = (24.0 / SUPPLY_DIVIDER_RATIO * 1e3).round() as u16;
        assert!(
            (supply_v(pin_mv) - 24.0).abs() < 0.01,
            "{}",
            supply_v(pin_mv)
        );
        assert_eq!(supply_v(0), 0.0);
    }
}
