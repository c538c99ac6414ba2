//! The truth of every run a twin starts: the kerf an ideal device would read on the gauge placed
//! for it, at the force it asks for ([`crate::plant::Plant::truth_um`]), recorded by run id when
//! the run starts and shared with whoever serves the twin (the host's `--sim` reports it beside
//! the device's reading as `sim_truth_um`).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};

/// How many runs' truths are kept.
const KEPT_RUNS: usize = 4096;

/// The truths of a twin's runs since its last boot, by run id. Cloning shares the log.
#[derive(Debug, Clone, Default)]
pub struct TruthLog(Arc<Mutex<VecDeque<(u32, f64)>>>);

impl TruthLog {
    /// Record `truth_um` for run `run_id`.
    pub fn record(&self, run_id: u32, truth_um: f64) {
        let mut log = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        if log.len() == KEPT_RUNS {
            log.pop_front();
        }
        log.push_back((run_id, truth_um));
    }

    /// The truth of run `run_id`, µm.
    pub fn truth_um(&self, run_id: u32) -> Option<f64> {
        let log = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        log.iter()
            .rev()
            .find(|(id, _)| *id == run_id)
            .map(|(_, t)| *t)
    }

    /// The last run's id and truth.
    pub fn last(&self) -> Option<(u32, f64)> {
        let log = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        log.back().copied()
    }

    /// Forget every run (the device rebooted: its run ids start again).
    pub fn clear(&self) {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_latest_truth_of_a_run_id_is_found_and_old_runs_are_dropped() {
        let log = TruthLog::default();
        assert_eq!(log.last(), None);
        log.record(1, 150.0);
        log.clone().record(2, 151.0);
        assert_eq!(log.truth_um(1), Some(150.0));
        assert_eq!(log.last(), Some((2, 151.0)));
        for id in 3..(KEPT_RUNS as u32 + 3) {
            log.record(id, 0.0);
        }
        assert_eq!(log.truth_um(1), None);
        log.clear();
        assert_eq!(log.truth_um(KEPT_RUNS as u32), None);
    }
}
