//! The motor current from the Pololu G2's current-sense (`CS`) output, and when it counts as
//! unknown.
//!
//! The board reads `CS` one ADC conversion behind: each tick takes the conversion started at the
//! end of the previous tick, so that the tick never waits for the ADC. A tick whose conversion
//! has not finished keeps the last current; after [`CURRENT_STALE_TICKS`] such ticks in a row the
//! current is unknown (`None`), and stays so until a conversion finishes again. Chip-independent,
//! so that it is tested on the host; the ADC itself is in `board::adc` (chip features).

/// Current-sense gain of the Pololu G2 18v17 (the reference driver): its `CS` output rises by
/// about 20 mV per amp of motor current. The gain depends on the G2 variant: look it up on
/// Pololu's page for yours and adjust this (and [`CURRENT_SENSE_OFFSET_MV`]) for any other.
pub const CURRENT_SENSE_MV_PER_A: f32 = 20.0;

/// Current-sense offset of the Pololu G2 18v17: its `CS` output sits about 50 mV above ground
/// at zero current. Depends on the G2 variant (and varies a little from board to board): adjust
/// it for another driver.
pub const CURRENT_SENSE_OFFSET_MV: f32 = 50.0;

/// Ticks without a finished current-sense conversion after which the current counts as unknown.
pub const CURRENT_STALE_TICKS: u32 = 10;

/// Motor current, A, from the G2's `CS` voltage in millivolts (never negative).
pub fn motor_current_a(cs_mv: u16) -> f32 {
    ((f32::from(cs_mv) - CURRENT_SENSE_OFFSET_MV) / CURRENT_SENSE_MV_PER_A).max(0.0)
}

/// The last measured motor current and how many ticks old it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurrentTracker {
    last_a: f32,
    stale_ticks: u32,
}

impl Default for CurrentTracker {
    fn default() -> Self {
        Self::new()
    }
}

impl CurrentTracker {
    /// Nothing measured yet: reads 0 A until [`CURRENT_STALE_TICKS`] ticks pass without a
    /// conversion.
    pub const fn new() -> Self {
        Self {
            last_a: 0.0,
            stale_ticks: 0,
        }
    }

    /// A conversion finished with `cs_mv` on the `CS` pin.
    pub fn finished(&mut self, cs_mv: u16) {
        self.last_a = motor_current_a(cs_mv);
        self.stale_ticks = 0;
    }

    /// The current for this tick, A, given the conversion that finished for it (`None`: it had
    /// not finished); `None` when it is unknown.
    pub fn at_tick(&mut self, finished_mv: Option<u16>) -> Option<f32> {
        match finished_mv {
            Some(cs_mv) => self.finished(cs_mv),
            None => self.stale_ticks = self.stale_ticks.saturating_add(1),
        }
        (self.stale_ticks <= CURRENT_STALE_TICKS).then_some(self.last_a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_g2_scaling_has_its_offset_and_never_goes_negative() {
        assert_eq!(motor_current_a(50), 0.0);
        assert_eq!(motor_current_a(250), 10.0);
        assert_eq!(motor_current_a(0), 0.0);
        assert_eq!(motor_current_a(u16::MAX), (65535.0 - 50.0) / 20.0);
    }

    #[test]
    fn a_missed_conversion_keeps_the_last_current_until_it_is_stale() {
        let mut tracker = CurrentTracker::new();
        assert_eq!(tracker.at_tick(Some(150)), Some(5.0));
        for tick in 1..=CURRENT_STALE_TICKS {
            assert_eq!(tracker.at_tick(None), Some(5.0), "missed tick {tick}");
        }
        assert_eq!(tracker.at_tick(None), None);
        assert_eq!(tracker.at_tick(None), None);
        // A conversion finished between ticks (started late in the tick) makes it known again.
        tracker.finished(90);
        assert_eq!(tracker.at_tick(None), Some(2.0));
    }

    #[test]
    fn before_any_conversion_the_current_reads_zero_then_unknown() {
        let mut tracker = CurrentTracker::default();
        for _ in 0..CURRENT_STALE_TICKS {
            assert_eq!(tracker.at_tick(None), Some(0.0));
        }
        assert_eq!(tracker.at_tick(None), None);
    }
}
