//! The G2's current-sense output on the chip: ADC1 with 11 dB attenuation (range ≈2.5 V),
//! calibrated to millivolts by the chip's eFuse curve, read one conversion behind so that the
//! control tick never waits for the ADC. The conversion to amps and the staleness rule are the
//! chip-independent [`CurrentTracker`].

use esp_hal::{
    Blocking,
    analog::adc::{Adc, AdcCalCurve, AdcConfig, AdcPin, Attenuation},
    peripherals::ADC1,
};

use super::current::CurrentTracker;
use super::pins::CurrentSensePin;

/// The G2 current-sense input on ADC1: each tick collects the conversion started at the end of
/// the previous tick ([`read_a`](Self::read_a)) and starts the next one
/// ([`start_next`](Self::start_next)).
pub struct CurrentSense {
    adc: Adc<'static, ADC1<'static>, Blocking>,
    pin: AdcPin<CurrentSensePin, ADC1<'static>, AdcCalCurve<ADC1<'static>>>,
    tracker: CurrentTracker,
}

impl CurrentSense {
    /// ADC1 on the current-sense pin, 11 dB, calibrated.
    pub fn new(adc1: ADC1<'static>, pin: CurrentSensePin) -> Self {
        let mut adc_config = AdcConfig::new();
        let pin = adc_config.enable_pin_with_cal::<_, AdcCalCurve<ADC1>>(pin, Attenuation::_11dB);
        Self {
            adc: Adc::new(adc1, adc_config),
            pin,
            tracker: CurrentTracker::new(),
        }
    }

    /// The motor current for this tick, A: the last finished conversion; `None` (unknown) once
    /// conversions have been missing for too long (see [`CurrentTracker`]).
    pub fn read_a(&mut self) -> Option<f32> {
        let finished = self.poll();
        self.tracker.at_tick(finished)
    }

    /// Start the next conversion (late in the tick, well after the last one was read out, as
    /// the ADC needs a few of its clock cycles between the two).
    pub fn start_next(&mut self) {
        if let Some(cs_mv) = self.poll() {
            self.tracker.finished(cs_mv);
        }
    }

    /// Start a conversion if none is running, or take the running one's result (mV) if it has
    /// finished.
    fn poll(&mut self) -> Option<u16> {
        self.adc.read_oneshot(&mut self.pin).ok()
    }
}
