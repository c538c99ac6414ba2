//! Repeated measurements: mean, standard deviation, 95 % confidence interval, outliers, and the
//! median (which the bed map also uses for each cell).
//!
//! A mean of n runs on separately cut gauges shrinks the cutter's own repeatability term by √n
//! (the paper: ±15.5 µm for one gauge, ±8.9 µm for the mean of three). The confidence interval
//! uses Student's t with n − 1 degrees of freedom. An outlier is a run whose modified z-score
//! 0.6745·|x − median| / MAD exceeds 3.5 (Iglewicz and Hoaglin), which stays meaningful for small n.

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, StudentsT};

/// Modified z-score above which a run is flagged as an outlier.
pub const OUTLIER_Z: f64 = 3.5;

/// Summary of repeated kerf measurements.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Runs.
    pub n: usize,
    /// Mean kerf, µm.
    pub mean_um: f64,
    /// Sample standard deviation, µm (0 for one run).
    pub sd_um: f64,
    /// Half-width of the 95 % confidence interval of the mean, µm (`None` for one run).
    pub ci95_um: Option<f64>,
    /// Smallest and largest run, µm.
    pub min_um: f64,
    /// Largest run, µm.
    pub max_um: f64,
    /// Indices of runs flagged as outliers.
    pub outliers: Vec<usize>,
}

/// Median of a non-empty slice.
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Summarise `values` (at least one).
pub fn summarize(values: &[f64]) -> Summary {
    assert!(!values.is_empty(), "summarize needs at least one value");
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    let sd = if n > 1 {
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    let ci95_um = (n > 1).then(|| {
        let t = StudentsT::new(0.0, 1.0, (n - 1) as f64)
            .expect("n - 1 > 0 degrees of freedom")
            .inverse_cdf(0.975);
        t * sd / (n as f64).sqrt()
    });
    let med = median(values);
    let deviations: Vec<f64> = values.iter().map(|v| (v - med).abs()).collect();
    let mad = median(&deviations);
    let outliers = if n >= 3 && mad > 0.0 {
        (0..n)
            .filter(|&i| 0.6745 * deviations[i] / mad > OUTLIER_Z)
            .collect()
    } else {
        Vec::new()
    };
    Summary {
        n,
        mean_um: mean,
        sd_um: sd,
        ci95_um,
        min_um: values.iter().copied().fold(f64::INFINITY, f64::min),
        max_um: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        outliers,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_sd_and_t_interval() {
        let s = summarize(&[100.0, 102.0, 104.0]);
        assert_eq!(s.mean_um, 102.0);
        assert!((s.sd_um - 2.0).abs() < 1e-12);
        // t(0.975, 2) = 4.302653
        assert!((s.ci95_um.unwrap() - 4.302653 * 2.0 / 3f64.sqrt()).abs() < 1e-5);
        assert!(s.outliers.is_empty());
    }

    #[test]
    fn one_run_has_no_interval() {
        let s = summarize(&[150.0]);
        assert_eq!((s.n, s.sd_um, s.ci95_um), (1, 0.0, None));
    }

    #[test]
    fn a_wild_run_is_flagged() {
        let s = summarize(&[150.0, 151.0, 149.0, 150.5, 149.5, 190.0]);
        assert_eq!(s.outliers, vec![5]);
    }
}
