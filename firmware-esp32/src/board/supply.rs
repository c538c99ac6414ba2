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
//! The board converts the supply on ADC1 (11 dB) every [`SUPPLY_PERIOD_TICKS`] ticks, in place of
//! that tick's current-sense conversion (`board::adc`), and keeps the last reading in between
//! ([`SupplyReading`]): the supply changes slowly against 10 ms, and the current sense misses
//! one tick in ten, which its conversion rides through.

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

/// The supply is converted every this many ticks (100 Hz at the 1 kHz control rate).
pub const SUPPLY_PERIOD_TICKS: u32 = 10;

/// A supply reading older than this many ticks is no reading (`None`): three conversions missed.
pub const SUPPLY_STALE_TICKS: u32 = 3 * SUPPLY_PERIOD_TICKS;

/// The last supply reading and its age, so that every tick has one between conversions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SupplyReading {
    last_v: Option<f32>,
    stale_ticks: u32,
}

impl SupplyReading {
    /// No reading yet.
    pub const fn new() -> Self {
        Self {
            last_v: None,
            stale_ticks: 0,
        }
    }

    /// The supply for this tick, V, given the conversion that finished for it (mV on the pin;
    /// `None`: none did): the last reading until it is [`SUPPLY_STALE_TICKS`] old, then `None`.
    pub fn at_tick(&mut self, finished_mv: Option<u16>) -> Option<f32> {
        match finished_mv {
            Some(mv) => {
                self.last_v = Some(supply_v(mv));
                self.stale_ticks = 0;
            }
            None => self.stale_ticks = self.stale_ticks.saturating_add(1),
        }
        self.last_v
            .filter(|_| self.stale_ticks <= SUPPLY_STALE_TICKS)
    }
}

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

    #[test]
    fn a_reading_stands_between_conversions_until_it_is_stale() {
        let mut r = SupplyReading::new();
        assert_eq!(r.at_tick(None), None, "nothing converted yet");
        let v = r.at_tick(Some(1_000)).unwrap();
        assert_eq!(v, supply_v(1_000));
        for tick in 1..=SUPPLY_STALE_TICKS {
            assert_eq!(r.at_tick(None), Some(v), "tick {tick}");
        }
        assert_eq!(r.at_tick(None), None);
        assert_eq!(r.at_tick(Some(0)), Some(0.0));
    }
}
