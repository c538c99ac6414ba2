//! Tick timing since boot: the longest control step and the longest gap between the starts of
//! two steps, the figures that show whether the 1 kHz control rate holds on the chip.
//!
//! [`Controller::step`](super::Controller::step) notes every step's start (its `now_us`), which
//! gives the gaps. How long a step took is only known to its caller, which reads the clock again
//! once the tick's work is done and reports it with
//! [`Controller::step_finished`](super::Controller::step_finished). Plain integer work, no
//! allocation: the board's loop and the twin call it the same way.

/// The longest step and gap seen since boot.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TickTiming {
    /// When the last step started, µs (none before the first).
    last_start_us: Option<u64>,
    /// The longest time between two step starts, µs.
    longest_gap_us: u64,
    /// The longest step, from its start to its reported end, µs.
    longest_step_us: u64,
}

impl TickTiming {
    /// Nothing seen yet.
    pub const fn new() -> Self {
        Self {
            last_start_us: None,
            longest_gap_us: 0,
            longest_step_us: 0,
        }
    }

    /// A step starts at `now_us`.
    pub(super) fn started(&mut self, now_us: u64) {
        if let Some(last) = self.last_start_us {
            self.longest_gap_us = self.longest_gap_us.max(now_us.saturating_sub(last));
        }
        self.last_start_us = Some(now_us);
    }

    /// The step that started last ended at `end_us` (ignored before the first step).
    pub(super) fn finished(&mut self, end_us: u64) {
        if let Some(start) = self.last_start_us {
            self.longest_step_us = self.longest_step_us.max(end_us.saturating_sub(start));
        }
    }

    /// The longest time between the starts of two consecutive steps since boot, µs (0 before the
    /// second step).
    pub fn longest_gap_us(&self) -> u64 {
        self.longest_gap_us
    }

    /// The longest step since boot, from its start to the end its caller reported, µs.
    pub fn longest_step_us(&self) -> u64 {
        self.longest_step_us
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_longest_gap_and_step_are_kept() {
        let mut t = TickTiming::new();
        t.finished(50);
        assert_eq!(
            t,
            TickTiming::new(),
            "an end before any start counts for nothing"
        );
        t.started(1_000);
        assert_eq!(t.longest_gap_us(), 0, "one step has no gap");
        t.finished(1_180);
        t.started(2_000);
        t.finished(2_090);
        t.started(5_500);
        t.finished(5_600);
        t.started(6_500);
        assert_eq!(t.longest_gap_us(), 3_500);
        assert_eq!(t.longest_step_us(), 180);
        // A clock that steps back does not wrap.
        t.started(6_400);
        t.finished(6_300);
        assert_eq!((t.longest_gap_us(), t.longest_step_us()), (3_500, 180));
    }
}
