//! A sweep summed up: the error statistics of its readings and the count of each kind of
//! ending.

use std::collections::BTreeMap;

use super::classify::{Class, classify, failure_name};
use super::run::DrawReport;
use crate::study::{mean_sd, quantile};

/// Device-added error statistics, µm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Readings.
    pub n: usize,
    /// Mean error.
    pub mean_um: f64,
    /// Its standard deviation.
    pub sd_um: f64,
    /// 95th percentile of |error|.
    pub p95_abs_um: f64,
    /// Largest |error|.
    pub max_abs_um: f64,
}

impl ErrorStats {
    /// Statistics of `errors`.
    pub fn of(errors: &[f64]) -> Self {
        let (mean_um, sd_um) = mean_sd(errors);
        let abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
        Self {
            n: errors.len(),
            mean_um,
            sd_um,
            p95_abs_um: quantile(&abs, 0.95),
            max_abs_um: abs.iter().copied().fold(f64::NAN, f64::max),
        }
    }
}

/// A sweep's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Draws run.
    pub draws: usize,
    /// Draw indices by class.
    pub by_class: BTreeMap<Class, Vec<u32>>,
    /// Draw indices of every ending that is not a reading, by [`failure_name`].
    pub failures: BTreeMap<String, Vec<u32>>,
    /// Error of every reading.
    pub all_readings: ErrorStats,
    /// Error of the readings no flag distrusts.
    pub unflagged_readings: ErrorStats,
    /// Draw indices of the readings, largest |error| first.
    pub worst: Vec<u32>,
    /// Draws that ended with the motor not in its safe state (or panicked).
    pub motor_unsafe: Vec<u32>,
}

impl Summary {
    /// The figures of `reports` with `tolerance_um`.
    pub fn of(reports: &[DrawReport], tolerance_um: f64) -> Self {
        let mut by_class: BTreeMap<Class, Vec<u32>> = BTreeMap::new();
        let mut failures: BTreeMap<String, Vec<u32>> = BTreeMap::new();
        let (mut all, mut unflagged, mut readings) = (Vec::new(), Vec::new(), Vec::new());
        for report in reports {
            let index = report.draw.index;
            let class = classify(&report.outcome, tolerance_um);
            by_class.entry(class).or_default().push(index);
            if let Some(name) = failure_name(&report.outcome) {
                failures.entry(name).or_default().push(index);
            }
            if let Some(error) = report.outcome.error_um() {
                all.push(error);
                readings.push((index, error.abs()));
                if class != Class::Flagged {
                    unflagged.push(error);
                }
            }
        }
        readings.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        Self {
            draws: reports.len(),
            by_class,
            failures,
            all_readings: ErrorStats::of(&all),
            unflagged_readings: ErrorStats::of(&unflagged),
            worst: readings.into_iter().map(|(index, _)| index).collect(),
            motor_unsafe: reports
                .iter()
                .filter(|r| r.motor_safe != Some(true))
                .map(|r| r.draw.index)
                .collect(),
        }
    }

    /// Draw indices of `class`.
    pub fn of_class(&self, class: Class) -> &[u32] {
        self.by_class.get(&class).map_or(&[], Vec::as_slice)
    }

    /// Draws that ended in a reading.
    pub fn readings(&self) -> usize {
        self.all_readings.n
    }

    /// Whether every draw ended properly (a reading or a typed fault or refusal) with the motor
    /// safe: what the short sweep in `cargo xtask test` asserts.
    pub fn all_ended_safely(&self) -> bool {
        self.motor_unsafe.is_empty()
            && self
                .by_class
                .iter()
                .all(|(class, draws)| class.ends_properly() || draws.is_empty())
    }
}
