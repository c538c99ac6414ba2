//! Which ADC1 conversion each tick starts and collects, and what is done about one that never
//! finishes. Chip-independent, so that it is tested on the host: the board's `board::adc`
//! drives the ESP32's ADC through it ([`OneShot`]), the tests a fake.
//!
//! # The schedule
//!
//! ADC1 converts one channel at a time, one conversion behind so that the control tick never
//! waits: each tick collects the conversion started at the end of the previous tick
//! ([`Conversions::read`]) and, at its own end, starts the next one
//! ([`Conversions::start_next`]): the current sense, or the supply every
//! [`SUPPLY_PERIOD_TICKS`] ticks in its place. The tick after a supply conversion has no
//! current-sense reading; `board::current::MotorCurrent` keeps the last current for it, and
//! [`SupplyReading`] keeps the last supply between its conversions.
//!
//! # A conversion that never finishes
//!
//! A conversion takes tens of microseconds; the next tick comes a millisecond later. One still
//! running after [`CONVERSION_TIMEOUT_TICKS`] collections has stalled (on the ESP32-C3 the
//! one-shot start pulse can be missed by the ADC's controller when its clock is slow: esp-hal's
//! `read_oneshot` notes the limitation), and the driver would wait for it for ever: no
//! current-sense reading would ever come again, the current would count as unknown after
//! `CURRENT_STALE_TICKS` (10) ticks, and the controller would fault with `OverCurrent` at every
//! tick, even after `ClearFault`, until a reboot. So it is given up: [`Conversions::read`]
//! says the ADC must be restarted (the board builds its driver afresh, which clears the stalled
//! conversion), and the next conversion is started as usual. Three ticks leave the restart,
//! and the conversion after it, well inside the ten after which the current counts unknown:
//! the controller never sees it.

use super::current::CURRENT_STALE_TICKS;
use super::supply::{SUPPLY_PERIOD_TICKS, SupplyReading};

/// Collections a conversion may stay unfinished before it is given up and the ADC restarted.
pub const CONVERSION_TIMEOUT_TICKS: u32 = 3;

// The restart and the conversion after it come before the current counts as unknown.
const _: () = assert!(CONVERSION_TIMEOUT_TICKS + 1 < CURRENT_STALE_TICKS);

/// The two channels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// The G2's RC-filtered current sense.
    CurrentSense,
    /// The motor supply's divider.
    Supply,
}

/// A one-shot ADC: one conversion at a time.
pub trait OneShot {
    /// Start a conversion on `channel` if none is running, or take the running one's result
    /// (calibrated mV) if it has finished; `None` while it runs.
    fn poll(&mut self, channel: Channel) -> Option<u16>;
}

/// What a tick's collection gave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Readings {
    /// The current sense's millivolts, if its conversion finished for this tick.
    pub cs_mv: Option<u16>,
    /// The motor supply, V: the last reading (`None` before the first or once it is stale).
    pub supply_v: Option<f32>,
    /// The conversion in flight was given up: restart the ADC before the next is started.
    pub restart: bool,
}

/// The conversions' schedule and state (module docs).
#[derive(Debug)]
pub struct Conversions {
    /// The conversion started and not yet collected.
    in_flight: Option<Channel>,
    /// A conversion that finished as it was started, for the next [`read`](Self::read).
    finished: Option<(Channel, u16)>,
    /// Collections the conversion in flight has been found unfinished at.
    waited_ticks: u32,
    /// Ticks since the last supply conversion was started.
    ticks_since_supply: u32,
    supply: SupplyReading,
    /// Conversions given up since boot.
    restarts: u32,
}

impl Default for Conversions {
    fn default() -> Self {
        Self::new()
    }
}

impl Conversions {
    /// Nothing in flight yet.
    pub const fn new() -> Self {
        Self {
            in_flight: None,
            finished: None,
            waited_ticks: 0,
            ticks_since_supply: 0,
            supply: SupplyReading::new(),
            restarts: 0,
        }
    }

    /// This tick's readings from `adc` (module docs); a conversion unfinished at its
    /// [`CONVERSION_TIMEOUT_TICKS`]th collection is given up, and [`Readings::restart`] says so.
    pub fn read(&mut self, adc: &mut impl OneShot) -> Readings {
        let finished = self.finished.take().or_else(|| self.collect(adc));
        let restart = self.in_flight.is_some() && self.waited_too_long();
        let pick = |want| match finished {
            Some((channel, mv)) if channel == want => Some(mv),
            _ => None,
        };
        Readings {
            cs_mv: pick(Channel::CurrentSense),
            supply_v: self.supply.at_tick(pick(Channel::Supply)),
            restart,
        }
    }

    /// Start the next conversion on `adc` (late in the tick, after the ADC restarted if
    /// [`read`](Self::read) said so): the supply's every [`SUPPLY_PERIOD_TICKS`] ticks, the
    /// current sense's otherwise. Nothing is started while the last one is still in flight.
    pub fn start_next(&mut self, adc: &mut impl OneShot) {
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
        match adc.poll(channel) {
            Some(mv) => self.finished = Some((channel, mv)),
            None => self.in_flight = Some(channel),
        }
    }

    /// Conversions given up since boot.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// The conversion in flight, if it has finished.
    fn collect(&mut self, adc: &mut impl OneShot) -> Option<(Channel, u16)> {
        let channel = self.in_flight?;
        let Some(mv) = adc.poll(channel) else {
            self.waited_ticks += 1;
            return None;
        };
        self.in_flight = None;
        self.waited_ticks = 0;
        Some((channel, mv))
    }

    /// The conversion in flight has been found unfinished too often: given up (the ADC is to
    /// be restarted, and the next tick's conversion started afresh).
    fn waited_too_long(&mut self) -> bool {
        if self.waited_ticks < CONVERSION_TIMEOUT_TICKS {
            return false;
        }
        self.in_flight = None;
        self.waited_ticks = 0;
        self.restarts = self.restarts.saturating_add(1);
        true
    }
}

#[cfg(test)]
mod tests;
