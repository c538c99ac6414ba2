//! The board's two analog inputs on ADC1, both calibrated to millivolts by the chip's eFuse
//! curve:
//!
//! - the G2's RC-filtered current sense (`CS`), at 0 dB attenuation (about 0–750 mV on the C3:
//!   the filtered signal is 50–200 mV, which 11 dB's 2.5 V range would resolve four times more
//!   coarsely, `board::current::CS_ADC_MAX_MV`);
//! - the motor supply's divider, at 11 dB (about 0–2.5 V, `board::supply::ADC_MAX_MV`).
//!
//! Which conversion each tick starts and collects, and when a conversion that never finishes
//! is given up, is chip-independent (`board::conversion::Conversions`); this module is the
//! esp-hal side of it ([`OneShot`]).
//!
//! # Restarting the driver
//!
//! esp-hal's blocking `Adc` keeps the channel it is converting until that conversion finishes,
//! and offers no way to abandon it: a conversion that never finishes would block every later
//! one. The only restart is a new driver. So the control task owns ADC1 and its two pins
//! ([`AnalogParts`]) and builds the driver on them by borrowing ([`AnalogParts::open`]); when
//! `Conversions::read` gives a conversion up, it drops the driver and opens it again, which
//! re-enables the pins, calibrates them again and starts from no conversion (safe Rust: no
//! peripheral is stolen). The calibration reads the eFuses' init code; on a chip without it
//! esp-hal calibrates by converting, waiting on each conversion without a bound (its
//! `adc_calibrate`): if the ADC itself no longer converts, that tick never ends and the
//! watchdog resets the chip 50 ms later, a reset the host sees (a new boot id) instead of a
//! current unknown until someone reboots it.

use esp_hal::{
    Blocking,
    analog::adc::{Adc, AdcCalCurve, AdcChannel, AdcConfig, AdcPin, Attenuation},
    gpio::AnalogPin,
    peripherals::ADC1,
};

use super::conversion::{Channel, OneShot};
use super::pins::{CurrentSensePin, SupplySensePin};

/// ADC1 and the two pins it converts, owned by the control task for as long as it runs.
pub struct AnalogParts {
    adc1: ADC1<'static>,
    current_sense: CurrentSensePin,
    supply_sense: SupplySensePin,
}

impl AnalogParts {
    /// ADC1 with the current-sense and supply-sense pins.
    pub fn new(
        adc1: ADC1<'static>,
        current_sense: CurrentSensePin,
        supply_sense: SupplySensePin,
    ) -> Self {
        Self {
            adc1,
            current_sense,
            supply_sense,
        }
    }

    /// The driver on these parts, no conversion running ([`AnalogInputs`]; module docs: drop
    /// it and open again to restart).
    pub fn open(&mut self) -> impl OneShot + '_ {
        let mut config = AdcConfig::new();
        let current_sense = calibrated(
            &mut config,
            self.current_sense.reborrow(),
            Attenuation::_0dB,
        );
        let supply_sense = calibrated(
            &mut config,
            self.supply_sense.reborrow(),
            Attenuation::_11dB,
        );
        AnalogInputs {
            adc: Adc::new(self.adc1.reborrow(), config),
            current_sense,
            supply_sense,
        }
    }
}

/// The ADC1 driver on borrowed [`AnalogParts`]: the current sense at 0 dB and the supply
/// divider at 11 dB, both calibrated.
pub struct AnalogInputs<'d, CS, SUP> {
    adc: Adc<'d, ADC1<'d>, Blocking>,
    current_sense: AdcPin<CS, ADC1<'d>, AdcCalCurve<ADC1<'d>>>,
    supply_sense: AdcPin<SUP, ADC1<'d>, AdcCalCurve<ADC1<'d>>>,
}

/// `pin` enabled in `config` at `attenuation`, with the eFuse curve's calibration.
fn calibrated<'d, PIN: AdcChannel + AnalogPin>(
    config: &mut AdcConfig<ADC1<'d>>,
    pin: PIN,
    attenuation: Attenuation,
) -> AdcPin<PIN, ADC1<'d>, AdcCalCurve<ADC1<'d>>> {
    config.enable_pin_with_cal::<_, AdcCalCurve<ADC1<'d>>>(pin, attenuation)
}

impl<CS: AdcChannel, SUP: AdcChannel> OneShot for AnalogInputs<'_, CS, SUP> {
    fn poll(&mut self, channel: Channel) -> Option<u16> {
        // One non-blocking step of a oneshot conversion.
        match channel {
            Channel::CurrentSense => self.adc.read_oneshot(&mut self.current_sense).ok(),
            Channel::Supply => self.adc.read_oneshot(&mut self.supply_sense).ok(),
        }
    }
}
