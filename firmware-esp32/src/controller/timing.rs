//! Tick timing: the longest control step and the longest gap between the starts of two steps
//! since boot, the figures that show whether the 1 kHz control rate holds on the chip; and the
//! pacing of each step ([`Pacing`]): the time it integrates, and whether its gap is an overrun
//! under the late-tick rules (the tuning's docs, "Late ticks", give them and their reasons).
//!
//! [`Controller::step`](super::Controller::step) notes every step's start (its `now_us`), which
//! gives the gaps. How long a step took is only known to its caller, which reads the clock again
//! once the tick's work is done and reports it with
//! [`Controller::step_finished`](super::Controller::step_finished). Plain integer work, no
//! allocation: the board's loop and the twin call it the same way.

use super::{
    LATE_BUDGET_US, LATE_GAP_PERIODS, LATE_REPAY_DIVISOR, MAX_GAP_PERIODS, MAX_STEP_DT_US,
    PERIOD_US,
};

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

// The rules' figures in µs, as `u32`: the step's arithmetic stays in 32 bits (a `u64` division
// is a library call on the C3's RV32 core). All are a few ms.
const PERIOD: u32 = PERIOD_US as u32;
const LATE_GAP: u32 = (LATE_GAP_PERIODS * PERIOD_US) as u32;
const MAX_GAP: u32 = (MAX_GAP_PERIODS * PERIOD_US) as u32;
const MAX_STEP_DT: u32 = MAX_STEP_DT_US as u32;
const BUDGET: u32 = LATE_BUDGET_US as u32;
const REPAY_DIVISOR: u32 = LATE_REPAY_DIVISOR as u32;

/// What the gap before a step means for it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Pace {
    /// The time the step integrates (ramp, release, speed-loop integral), µs: the gap, clamped
    /// to [`MAX_STEP_DT_US`]; one period for the first step. (In µs: the conversion to seconds,
    /// soft-float on the C3, is left to the steps that integrate.)
    pub(super) dt_us: u32,
    /// The gap is too long, or late steps too frequent: `StepOverrun` while the motor may be
    /// driven.
    pub(super) overrun: bool,
}

/// The late-tick rules: each step's gap, checked against [`MAX_GAP_PERIODS`] and the late-time
/// debt ([`LATE_BUDGET_US`], repaid at one part in [`LATE_REPAY_DIVISOR`] of the time passing).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Pacing {
    /// When the last step started, µs (none before the first).
    last_start_us: Option<u64>,
    /// Late time not yet repaid, µs.
    debt_us: u32,
    /// Whether the last step was active (the motor could be driven then).
    last_active: bool,
}

impl Pacing {
    /// No step yet, no debt.
    pub(super) const fn new() -> Self {
        Self {
            last_start_us: None,
            debt_us: 0,
            last_active: false,
        }
    }

    /// A step starts at `now_us`; `active` while the motor may be driven (at rest the debt is
    /// forgiven: a gap there leaves no stale output behind, and a flash write makes long ones).
    /// A gap counts only between two active steps: one that began at rest left the motor safe
    /// through it, even when a request served in it (after a `SetConfig`'s flash write in the
    /// same pass) started a run before this step.
    pub(super) fn step(&mut self, now_us: u64, active: bool) -> Pace {
        let counted = active && self.last_active;
        self.last_active = active;
        // In u32 (saturated past an hour): a u64 division is a library call on the C3.
        let gap_us = self
            .last_start_us
            .map(|last| u32::try_from(now_us.saturating_sub(last)).unwrap_or(u32::MAX));
        self.last_start_us = Some(now_us);
        let Some(gap_us) = gap_us else {
            return Pace {
                dt_us: PERIOD,
                overrun: false,
            };
        };
        let dt_us = gap_us.min(MAX_STEP_DT);
        if !counted {
            self.debt_us = 0;
            return Pace {
                dt_us,
                overrun: false,
            };
        }
        self.debt_us = self.debt_us.saturating_sub(gap_us / REPAY_DIVISOR);
        if gap_us > LATE_GAP {
            self.debt_us = self.debt_us.saturating_add(gap_us - PERIOD);
        }
        Pace {
            dt_us,
            overrun: gap_us > MAX_GAP || self.debt_us > BUDGET,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Step `pacing` after gaps of `gaps_ms` (ms), counted; the steps that overran.
    fn overruns(pacing: &mut Pacing, now_us: &mut u64, gaps_ms: &[f64]) -> Vec<usize> {
        let mut over = Vec::new();
        for (i, gap_ms) in gaps_ms.iter().enumerate() {
            *now_us += (gap_ms * 1000.0) as u64;
            if pacing.step(*now_us, true).overrun {
                over.push(i);
            }
        }
        over
    }

    /// `n` on-time gaps.
    fn on_time(n: usize) -> Vec<f64> {
        vec![1.0; n]
    }

    #[test]
    fn an_isolated_late_step_up_to_the_limit_is_ridden_through() {
        let mut p = Pacing::new();
        let mut now = 0;
        assert_eq!(p.step(0, true).dt_us, 1000, "the first step: one period");
        let mut gaps = on_time(100);
        gaps.push(MAX_GAP_PERIODS as f64);
        // The ticks it delayed come at once (the ticker catches up), then on time again.
        gaps.extend([0.02; 7]);
        gaps.extend(on_time(100));
        gaps.push(MAX_GAP_PERIODS as f64);
        assert_eq!(overruns(&mut p, &mut now, &gaps), Vec::<usize>::new());
    }

    #[test]
    fn a_gap_over_the_limit_is_an_overrun_however_rare() {
        let mut p = Pacing::new();
        let mut now = 0;
        let mut gaps = on_time(1000);
        gaps.push(MAX_GAP_PERIODS as f64 + 0.01);
        assert_eq!(overruns(&mut p, &mut now, &gaps), [1000]);
    }

    #[test]
    fn frequent_late_steps_are_an_overrun() {
        // Two steps 5 ms late back to back ride through; a third 10 ms later does not.
        let mut p = Pacing::new();
        let mut now = 0;
        let mut gaps = on_time(50);
        gaps.extend([6.0, 6.0]);
        gaps.extend(on_time(10));
        gaps.push(6.0);
        assert_eq!(overruns(&mut p, &mut now, &gaps), [62]);
        // A steady 4 ms late every 20 ms (a fifth of the time late) runs up the debt too.
        let mut p = Pacing::new();
        let gaps: Vec<f64> = (0..40)
            .flat_map(|_| [5.0].into_iter().chain(on_time(15)))
            .collect();
        let over = overruns(&mut p, &mut now, &gaps);
        assert!(!over.is_empty(), "a loop late a fifth of the time");
        // While one late step every 100 ms (4 % of the time) never does.
        let mut p = Pacing::new();
        let gaps: Vec<f64> = (0..40)
            .flat_map(|_| [5.0].into_iter().chain(on_time(96)))
            .collect();
        assert_eq!(overruns(&mut p, &mut now, &gaps), Vec::<usize>::new());
    }

    #[test]
    fn a_step_integrates_its_gap_up_to_two_periods() {
        let mut p = Pacing::new();
        p.step(10_000, true);
        let dt = |p: &mut Pacing, now| p.step(now, true).dt_us;
        assert_eq!(dt(&mut p, 11_200), 1_200, "jitter: the time");
        assert_eq!(dt(&mut p, 12_000), 800);
        assert_eq!(dt(&mut p, 18_000), 2_000, "late: two periods");
        assert_eq!(dt(&mut p, 18_030), 30, "catching up");
    }

    #[test]
    fn at_rest_gaps_are_forgiven() {
        let mut p = Pacing::new();
        p.step(0, true);
        p.step(6_000, true);
        p.step(12_000, true);
        // A flash write at rest: a long gap, no overrun, and the debt is gone.
        assert!(!p.step(500_000, false).overrun);
        assert!(!p.step(501_000, true).overrun);
        assert!(!p.step(507_000, true).overrun);
        assert!(!p.step(513_000, true).overrun);
        // A run started by a request served after a rest step's long flash write: that gap
        // was spent at rest, not late in the run; the run's own gaps count from the next.
        p.step(514_000, false);
        assert!(!p.step(914_000, true).overrun);
        assert!(p.step(915_000 + u64::from(MAX_GAP) + 1, true).overrun);
    }

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
