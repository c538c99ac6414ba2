//! The drift rule: when a label's newest kerf has moved beyond its usual spread.
//!
//! The baseline is the label's last [`BASELINE_RECORDS`] trusted measurements before the newest one
//! (same label, same thickness and force, same population: real or simulated; a record flagged for
//! anything but the advisory `decimated` and `play-modelled` is not trusted and left out). With at
//! least [`MIN_BASELINE`] of them, the newest kerf drifts when it is farther from their mean than
//! `max(3 · SD, FLOOR_UM)`.
//!
//! Why these numbers:
//! - 3 · SD: for a steady cutter, a new measurement lands beyond 3 SD about once in 370 times,
//!   so a warning is rare unless something changed.
//! - [`FLOOR_UM`] = 20 µm: a few identical past results (or a very steady cutter) give an SD near
//!   zero, and every next measurement would warn. One gauge repeats to about ±15.5 µm (the
//!   paper's figure for the cutter's repeatability), so a move under 20 µm is not evidence of a
//!   change.
//! - [`MIN_BASELINE`] = 3: an SD from two values means little; [`BASELINE_RECORDS`] = 10 keeps
//!   the baseline recent, so a lens cleaned last month does not hide a worn nozzle today.

use serde::Serialize;

/// Measurements of a label the newest one is compared with, at most.
pub const BASELINE_RECORDS: usize = 10;
/// Fewest measurements that make a baseline.
pub const MIN_BASELINE: usize = 3;
/// The smallest spread that counts as drift, µm.
pub const FLOOR_UM: f64 = 20.0;
/// Spreads (SD) that count as drift.
pub const SD_FACTOR: f64 = 3.0;

/// A drift warning: the label's newest kerf is beyond its usual spread.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Drift {
    /// The label.
    pub label: String,
    /// The newest kerf, µm.
    pub kerf_um: f64,
    /// The mean of the baseline, µm.
    pub usual_mean_um: f64,
    /// The baseline's standard deviation, µm.
    pub usual_sd_um: f64,
    /// The warning in words: the label, the kerf, the usual mean and spread, the likely causes.
    pub message: String,
}

/// The drift of `kerf_um` from `baseline_um` (the label's earlier kerfs), if it drifts.
pub fn drift(label: &str, kerf_um: f64, baseline_um: &[f64]) -> Option<Drift> {
    let n = baseline_um.len();
    if n < MIN_BASELINE {
        return None;
    }
    let mean = baseline_um.iter().sum::<f64>() / n as f64;
    let variance = baseline_um.iter().map(|k| (k - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let sd = variance.sqrt();
    let limit = (SD_FACTOR * sd).max(FLOOR_UM);
    if (kerf_um - mean).abs() <= limit {
        return None;
    }
    let direction = if kerf_um > mean { "wider" } else { "narrower" };
    let message = format!(
        "drift: {label} measured {kerf_um:.1} µm, {direction} than its usual {mean:.1} µm ± {sd:.1} µm SD (last {n} measurements; warned beyond ± {limit:.1} µm). Likely causes: a dirty lens, a worn nozzle, a changed focus or power, or a different batch of material"
    );
    Some(Drift {
        label: label.to_owned(),
        kerf_um,
        usual_mean_um: mean,
        usual_sd_um: sd,
        message,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kerf_beyond_three_sd_drifts_and_says_why() {
        let baseline = [150.0, 160.0, 140.0, 150.0];
        let d = drift("birch 3 mm", 200.0, &baseline).expect("drifts");
        assert_eq!(d.usual_mean_um, 150.0);
        assert!((d.usual_sd_um - 8.165).abs() < 1e-3, "{d:?}");
        for word in [
            "birch 3 mm",
            "200.0 µm",
            "150.0 µm",
            "dirty lens",
            "worn nozzle",
        ] {
            assert!(d.message.contains(word), "{word}: {}", d.message);
        }
        // 3 SD = 24.5 µm: 170 is within it.
        assert_eq!(drift("birch 3 mm", 170.0, &baseline), None);
        assert!(drift("birch 3 mm", 125.0, &baseline).is_some());
    }

    #[test]
    fn the_floor_keeps_a_steady_label_from_warning_at_every_wobble() {
        let baseline = [150.0; 5];
        assert_eq!(drift("mdf", 165.0, &baseline), None);
        assert!(drift("mdf", 171.0, &baseline).is_some());
    }

    #[test]
    fn too_few_measurements_make_no_baseline() {
        assert_eq!(drift("mdf", 500.0, &[150.0, 150.0]), None);
    }
}
