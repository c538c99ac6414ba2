//! A measurement asked for: the joint the kerf must fit, how many gauges, and what is measured.
//! The CLI's `run` flags, the server's `run_kerfmeter` params and Python's keyword arguments all
//! become a [`MeasureRequest`], checked here once before anything moves.

mod report;

pub use report::{CurveError, KerfAtForce, RunReport, SimNote};

use kerfmeter::params::{DEFAULT_FINGER_LENGTH_MM, DEFAULT_FINGERS, DEFAULT_THICKNESS_MM};
use std::ops::ControlFlow;
use std::path::Path;

use kerfmeter::protocol::{GaugeGeometry, RunParams};
use kerfmeter::{Error, JointSpec, Kerfmeter, Progress};
use serde::{Deserialize, Serialize};

/// The most gauges one measurement may take.
pub const MAX_SAMPLES: u32 = 50;

/// A measurement: the joint (its defaults are the paper's), the gauges, the label.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeasureRequest {
    /// Sheet thickness, mm.
    pub thickness_mm: f64,
    /// Fingers in the joint (1 to 100).
    pub fingers: u32,
    /// Length of each finger's pressed face, mm.
    pub finger_length_mm: f64,
    /// The joint's assembly force, N (`None`: 18.3 N per finger).
    pub force_n: Option<f64>,
    /// Gauges to measure, a fresh one each (1 to [`MAX_SAMPLES`]).
    pub samples: u32,
    /// What is measured, for the history (material, cutter).
    pub label: Option<String>,
}

impl Default for MeasureRequest {
    fn default() -> Self {
        Self {
            thickness_mm: DEFAULT_THICKNESS_MM,
            fingers: DEFAULT_FINGERS,
            finger_length_mm: DEFAULT_FINGER_LENGTH_MM,
            force_n: None,
            samples: 1,
            label: None,
        }
    }
}

impl MeasureRequest {
    /// The joint measured for.
    pub fn joint(&self) -> JointSpec {
        JointSpec {
            thickness_mm: self.thickness_mm,
            fingers: self.fingers,
            finger_length_mm: self.finger_length_mm,
            force_n: self.force_n,
        }
    }

    /// The device's run parameters, with the gauges and the label checked first: a request the
    /// history would refuse is refused before the motor moves.
    pub fn checked(&self) -> Result<RunParams, Error> {
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(Error::invalid(format!(
                "samples must be between 1 and {MAX_SAMPLES}, got {}",
                self.samples
            )));
        }
        if let Some(label) = &self.label {
            crate::history::parse_label(label).map_err(Error::invalid)?;
        }
        self.joint().run_params(GaugeGeometry::PAPER)
    }
}

/// A measurement session: `samples` gauges measured with `params` on `meter` (`before_gauge(i)`
/// before each, e.g. asking for gauge i; `progress(i, p)` at every poll, breaking to abort), then
/// recorded in the history at `history_at` (the one the user named; `None`: the user's data
/// directory's) under `label`. The report has no curve yet: the front end reads it if it wants
/// it, after the record, so that a curve that cannot be read never loses the measurement.
pub fn measure_and_record(
    meter: &mut Kerfmeter,
    params: &RunParams,
    samples: usize,
    label: Option<&str>,
    history_at: Option<&Path>,
    before_gauge: impl FnMut(usize) -> Result<(), Error>,
    progress: impl FnMut(usize, &Progress) -> ControlFlow<()>,
) -> Result<RunReport, Error> {
    let measurement = meter.measure_until(params, samples, before_gauge, progress)?;
    // Recorded before anything else can fail: the measurement is made.
    let history = crate::history::record(
        history_at,
        meter,
        &crate::history::Measured {
            label,
            thickness_mm: f64::from(params.thickness_mm),
            force_n: f64::from(params.target_force_n),
            kerf_um: measurement.summary.mean_um,
            ci95_um: measurement.summary.ci95_um,
            runs: &measurement.runs,
        },
    );
    let mut report = RunReport::new(params, measurement);
    report.label = label.map(str::to_owned);
    report.history = Some(history);
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::request::from_params;
    use serde_json::json;

    #[test]
    fn the_defaults_are_the_papers_joint_and_one_gauge() {
        let asked: MeasureRequest = from_params(json!({})).unwrap();
        assert_eq!(asked, MeasureRequest::default());
        assert_eq!(asked.joint(), JointSpec::default());
        assert!(asked.checked().is_ok());
    }

    #[test]
    fn what_the_device_or_the_history_would_refuse_is_refused_first() {
        for bad in [
            json!({"samples": 0}),
            json!({"samples": 51}),
            json!({"fingers": 0}),
            json!({"fingers": 101}),
            json!({"label": "  "}),
            json!({"force_n": 0.0}),
            json!({"thickness_mm": 80.0}),
        ] {
            let asked: MeasureRequest = from_params(bad.clone()).unwrap();
            assert!(asked.checked().is_err(), "{bad}");
        }
        let e = from_params::<MeasureRequest>(json!({"fingers": -1})).unwrap_err();
        assert_eq!(e.name.as_deref(), Some("fingers"), "{e}");
        let e = from_params::<MeasureRequest>(json!({"force": 50})).unwrap_err();
        assert!(e.to_string().contains("`force`"), "{e}");
    }
}
