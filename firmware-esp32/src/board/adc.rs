//! The board's two analog inputs on ADC1, both calibrated to millivolts by the chip's eFuse
//! curve, read one conversion behind so that the control tick never waits for the ADC:
//!
//! - the G2's RC-filtered current sense (`CS`), at 0 dB attenuation (about 0–750 mV on the C3:
//!   the filtered signal is 50–200 mV, which 11 dB's 2.5 V range would resolve four times more
//!   coarsely, `board::current::CS_ADC_MAX_MV`);
//! - the motor supply's divider, at 11 dB (about 0–2.5 V, `board::supply::ADC_MAX_MV`).
//!
//! ADC1 converts one channel at a time. Each tick collects the conversion started at the end of
//! the previous tick ([`AnalogInputs::read`]) and, at its own end, starts the next one
//! ([`AnalogInputs::start_next`]): the current sense, or the supply every
//! [`SUPPLY_PERIOD_TICKS`] ticks in its place. The tick after a supply conversion has no
//! current-sense reading; the chip-independent conversion (`board::current::MotorCurrent`)
//! keeps the last current for it, and [`SupplyReading`] keeps the last supply between its
//! conversions.

use esp_hal::{
    Blocking,
    analog::adc::{Adc, AdcCalCurve, AdcChannel, AdcConfig, AdcPin, Attenuation},
    peripherals::ADC1,
};

use super::pins::{CurrentSensePin, SupplySensePin};
use super::supply::{SUPPLY_PERIOD_TICKS, SupplyReading};

/// A calibrated ADC1 input on `PIN`.
type CalibratedPin<PIN> = AdcPin<PIN, ADC1<'static>, AdcCalCurve<ADC1<'static>>>;

/// The two channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Channel {
    CurrentSense,
    Supply,
}

/// The current-sense and supply inputs on ADC1.
pub struct AnalogInputs {
    adc: Adc<'static, ADC1<'static>, Blocking>,
    current_sense: CalibratedPin<CurrentSensePin>,
    supply_sense: CalibratedPin<SupplySensePin>,
    /// The conversion started and not yet collected.
    in_flight: Option<Channel>,
    /// A conversion that finished as it was started, for the next [`read`](Self::read).
    finished: Option<(Channel, u16)>,
    /// Ticks since the last supply conversion was started.
    ticks_since_supply: u32,
    supply: SupplyReading,
}

impl AnalogInputs {
    /// ADC1 with the current sense at 0 dB and the supply divider at 11 dB, both calibrated.
    pub fn new(
        adc1: ADC1<'static>,
        current_sense: CurrentSensePin,
        supply_sense: SupplySensePin,
    ) -> Self {
        let mut config = AdcConfig::new();
        let current_sense =
            config.enable_pin_with_cal::<_, AdcCalCurve<ADC1>>(current_sense, Attenuation::_0dB);
        let supply_sense =
            config.enable_pin_with_cal::<_, AdcCalCurve<ADC1>>(supply_sense, Attenuation::_11dB);
        Self {
            adc: Adc::new(adc1, config),
            current_sense,
            supply_sense,
            in_flight: None,
            finished: None,
            ticks_since_supply: 0,
            supply: SupplyReading::new(),
        }
    }

    /// This tick's readings: the current sense's millivolts if its conversion finished for this
    /// tick (`None` otherwise), and the motor supply, V (the last reading; `None` before the first
    /// or once it is stale).
    pub fn read(&mut self) -> (Option<u16>, Option<f32>) {
        let finished = self.finished.take().or_else(|| self.collect());
        let cs_mv = match finished {
            Some((Channel::CurrentSense, mv)) => Some(mv),
            _ => None,
        };
        let supply_mv = match finished {
            Some((Channel::Supply, mv)) => Some(mv),
            _ => None,
        };
        (cs_mv, self.supply.at_tick(supply_mv))
    }

    /// Start the next conversion (late in the tick, well after the last one was read out, as
    /// the ADC needs a few of its clock cycles between the two): the supply's every
    /// [`SUPPLY_PERIOD_TICKS`] ticks, the current sense's otherwise. Nothing is started while
    /// the last conversion has not been collected.
    pub fn start_next(&mut self) {
        if self.in_flight.is_some() || self.finished.is_some() {
            return;
        }
        self.ticks_since_supply += 1;
        let channel = if self.ticks_since_supply >= SUPPLY_PERIOD_TICKS {
            self.ticks_since_supply = 0;
            Channel::Supply
        } else {
            Channel::CurrentSense
        };
        // Starts the conversion; it finishes at once only on a very slow tick.
        match self.poll(channel) {
            Some(mv) => self.finished = Some((channel, mv)),
            None => self.in_flight = Some(channel),
        }
    }

    /// The conversion in flight, if it has finished.
    fn collect(&mut self) -> Option<(Channel, u16)> {
        let channel = self.in_flight?;
        let mv = self.poll(channel)?;
        self.in_flight = None;
        Some((channel, mv))
    }

    /// Start a conversion on `channel` if none is running, or take the running one's result
    /// (mV) if it has finished.
    fn poll(&mut self, channel: Channel) -> Option<u16> {
        match channel {
            Channel::CurrentSense => read(&mut self.adc, &mut self.current_sense),
            Channel::Supply => read(&mut self.adc, &mut self.supply_sense),
        }
    }
}

/// One non-blocking step of a oneshot conversion on `pin`.
fn read<PIN: AdcChannel>(
    adc: &mut Adc<'static, ADC1<'static>, Blocking>,
    pin: &mut CalibratedPin<PIN>,
) -> Option<u16> {
    adc.read_oneshot(pin).ok()
}
