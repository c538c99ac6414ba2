//! The board's ADC1 as the firmware's conversion schedule drives it (`board::conversion`): one
//! one-shot conversion at a time, each started just after a tick's output was applied and
//! collected at the next tick, the supply every tenth tick in the current sense's place. The
//! twin runs the firmware's own [`Conversions`](kerfmeter_firmware::board::conversion::Conversions)
//! over it, as the board binary does, restart included.
//!
//! A conversion can be made to stall ([`TwinAdc::stall_next`]): it then never finishes, as when
//! the ESP32-C3's ADC controller misses a one-shot start pulse, until the firmware gives it up
//! and opens the driver again ([`TwinAdc::restart`]).

use kerfmeter_firmware::board::conversion::{Channel, OneShot};

use crate::sense::Sensed;

/// The simulated ADC1.
#[derive(Debug, Clone, Default)]
pub struct TwinAdc {
    /// What the pins read now (the sense's last sample).
    pins: Option<Sensed>,
    /// The conversion running: its channel and the value it converts (taken at its start).
    running: Option<(Channel, Option<u16>)>,
    /// The running conversion never finishes.
    stalled: bool,
    /// Conversions still to start that will stall.
    stalls_armed: u32,
    /// Conversions that stalled since boot.
    stalls: u32,
}

impl TwinAdc {
    /// No conversion yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The pins read `sensed` from now on (the sense sampled after the tick's output).
    pub fn set_pins(&mut self, sensed: Sensed) {
        self.pins = Some(sensed);
    }

    /// The next conversion started never finishes.
    pub fn stall_next(&mut self) {
        self.stalls_armed += 1;
    }

    /// The driver opened again (`Conversions` gave the running conversion up): nothing runs.
    pub fn restart(&mut self) {
        self.running = None;
        self.stalled = false;
    }

    /// Conversions that stalled since boot.
    pub fn stalls(&self) -> u32 {
        self.stalls
    }
}

impl OneShot for TwinAdc {
    fn poll(&mut self, channel: Channel) -> Option<u16> {
        match self.running {
            None => {
                let value = self.pins.map(|p| match channel {
                    Channel::CurrentSense => p.cs_mv,
                    Channel::Supply => p.supply_mv,
                });
                self.running = Some((channel, value));
                self.stalled = self.stalls_armed > 0;
                if self.stalled {
                    self.stalls_armed -= 1;
                    self.stalls += 1;
                }
                // A conversion takes tens of µs: it has finished by the next tick.
                None
            }
            Some(_) if self.stalled => None,
            Some((running, value)) => {
                debug_assert_eq!(running, channel, "collected as started");
                self.running = None;
                value
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pins() -> Sensed {
        Sensed {
            cs_mv: 60,
            supply_v: 12.0,
            supply_mv: 909,
        }
    }

    #[test]
    fn a_conversion_finishes_at_its_next_poll_and_a_stalled_one_only_after_a_restart() {
        let mut adc = TwinAdc::new();
        adc.set_pins(pins());
        assert_eq!(adc.poll(Channel::Supply), None, "started");
        assert_eq!(adc.poll(Channel::Supply), Some(909));
        adc.stall_next();
        assert_eq!(adc.poll(Channel::CurrentSense), None, "started");
        for _ in 0..10 {
            assert_eq!(adc.poll(Channel::CurrentSense), None, "stalled");
        }
        adc.restart();
        assert_eq!(adc.poll(Channel::CurrentSense), None, "started afresh");
        assert_eq!(adc.poll(Channel::CurrentSense), Some(60));
        assert_eq!(adc.stalls(), 1);
    }
}
