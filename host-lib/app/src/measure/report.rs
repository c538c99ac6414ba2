//! What a measurement reports ([`RunReport`]): every run with its flags, their summary, the
//! kerf at other forces, where it was recorded; on the twin, the truth beside the reading. Its
//! JSON is `kerfmeter run --json`'s and the server's `run_kerfmeter` answer; its text the
//! command's lines.

use std::fmt;
use std::path::PathBuf;

use kerfmeter::protocol::{KerfResult, RunParams};
use kerfmeter::stats::Summary;
use kerfmeter::{Category, Measurement};
use serde::Serialize;

use crate::history::Recorded;
use crate::result::ResultsTable;

/// The kerf at another force, read off the last run's curve.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct KerfAtForce {
    /// The force, N.
    pub force_n: f32,
    /// The kerf there, µm (`None` beyond the force the run reached).
    pub kerf_um: Option<f32>,
}

/// What the simulated device was told to cut (text only).
#[derive(Debug, Clone, Copy)]
pub struct SimNote {
    /// The twin's true kerf, µm.
    pub kerf_um: f64,
    /// Its gauge-to-gauge spread, µm.
    pub kerf_sd_um: f64,
    /// What an ideal device reads on the gauges at the force asked for (the mean truth), µm.
    pub ideal_reading_um: f64,
}

/// The measurement: every run, their summary and the readings at other forces.
#[derive(Serialize)]
pub struct RunReport {
    /// The joint force the runs were made at, N.
    pub force_n: f32,
    /// Kerf at the other forces asked for.
    pub kerf_at_force_um: Vec<KerfAtForce>,
    /// The mean kerf, µm.
    pub kerf_um: f64,
    /// The curve's file, if drawn.
    #[serde(serialize_with = "crate::lossy_path::option")]
    pub plot: Option<PathBuf>,
    /// Every run, in order, its flags also by name.
    #[serde(serialize_with = "crate::result::results_json")]
    pub runs: Vec<KerfResult>,
    /// What was measured (`--label`).
    pub label: Option<String>,
    /// Where the measurement was recorded, or why not, and its drift (`None` until recorded).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub history: Option<Recorded>,
    /// True on the simulated device.
    pub simulated: bool,
    /// Mean, spread, confidence interval and outliers.
    pub summary: Summary,
    /// Sheet thickness, mm.
    pub thickness_mm: f32,
    /// On the simulated device, the truth beside `kerf_um`: the mean of what an ideal device
    /// reads on each run's gauge at the force asked for, µm, from the twin's physics.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_truth_um: Option<f64>,
    /// On the simulated device, each run's truth, µm, in the order of `runs`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sim_truths_um: Vec<f64>,
    /// Why the curve could not be read or drawn after the measurement (which stands, and is
    /// recorded); the command then fails after printing the report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curve_error: Option<CurveError>,
    /// What the simulated device was told to cut, for the text output.
    #[serde(skip)]
    pub sim: Option<SimNote>,
}

/// Why the curve could not be read or drawn after a measurement; its JSON is the message.
#[derive(Debug, Clone, Serialize)]
#[serde(transparent)]
pub struct CurveError {
    /// What failed.
    pub message: String,
    /// Its kind, for the exit code (and, on the server, whether the link is lost).
    #[serde(skip)]
    pub category: Category,
}

impl RunReport {
    /// The report of `measurement`, made with `params`: no readings at other forces, no plot, no
    /// record yet; on the twin, [`RunReport::with_twin_truth`] adds its truth.
    pub fn new(params: &RunParams, measurement: Measurement) -> Self {
        let Measurement { runs, summary } = measurement;
        RunReport {
            force_n: params.target_force_n,
            kerf_at_force_um: Vec::new(),
            kerf_um: summary.mean_um,
            plot: None,
            runs,
            label: None,
            history: None,
            simulated: false,
            summary,
            thickness_mm: params.thickness_mm,
            sim_truth_um: None,
            sim_truths_um: Vec::new(),
            curve_error: None,
            sim: None,
        }
    }

    /// On the twin: each run's truth (`truth_um` of its run id, from the twin's physics) and what
    /// its cutter was told to cut (`kerf_um` ± `kerf_sd_um`).
    pub fn with_twin_truth(
        mut self,
        kerf_um: f64,
        kerf_sd_um: f64,
        truth_um: impl Fn(u32) -> Option<f64>,
    ) -> Self {
        self.simulated = true;
        self.sim_truths_um = self
            .runs
            .iter()
            .filter_map(|r| truth_um(r.run_id))
            .collect();
        let n = self.sim_truths_um.len();
        self.sim_truth_um = (n > 0).then(|| self.sim_truths_um.iter().sum::<f64>() / n as f64);
        self.sim = self.sim_truth_um.map(|ideal_reading_um| SimNote {
            kerf_um,
            kerf_sd_um,
            ideal_reading_um,
        });
        self
    }

    /// Note that the curve could not be read or drawn after the measurement (`message`, of
    /// `category`).
    pub fn curve_failed(&mut self, message: String, category: Category) {
        self.curve_error = Some(CurveError { message, category });
    }
}

impl fmt::Display for RunReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}\n", ResultsTable(&self.runs))?;
        let s = &self.summary;
        match s.ci95_um {
            Some(ci) => write!(
                f,
                "kerf {:.1} µm ± {:.1} µm (95 % CI, n = {}, SD {:.1} µm) at {:.1} N",
                s.mean_um, ci, s.n, s.sd_um, self.force_n
            )?,
            None => write!(f, "kerf {:.1} µm at {:.1} N", s.mean_um, self.force_n)?,
        }
        for KerfAtForce { force_n, kerf_um } in &self.kerf_at_force_um {
            match kerf_um {
                Some(k) => write!(
                    f,
                    "\n  at {force_n:.1} N (from the last run's curve): {k:.1} µm"
                )?,
                None => write!(
                    f,
                    "\n  at {force_n:.1} N: beyond the force the last run reached"
                )?,
            }
        }
        for &i in &s.outliers {
            write!(
                f,
                "\nwarning: run {} ({:.1} µm) is an outlier; check that gauge",
                i + 1,
                self.runs[i].kerf_um
            )?;
        }
        write_run_warnings(f, &self.runs, self.force_n)?;
        if let Some(path) = &self.plot {
            write!(f, "\ncurve: {}", path.display())?;
        }
        if let Some(sim) = &self.sim {
            write!(f, "\n{sim}")?;
        }
        match &self.history {
            Some(history) => write!(f, "\n{history}"),
            None => Ok(()),
        }
    }
}

/// A run the quality flags distrust (its kerf may be off by more than the device vouches for),
/// and a run whose joint force was not the one asked for (the supply or the torque cap held it
/// back): a warning line each, so that a number is never read without them.
fn write_run_warnings(
    f: &mut fmt::Formatter<'_>,
    runs: &[KerfResult],
    force_n: f32,
) -> fmt::Result {
    for (i, r) in runs.iter().enumerate() {
        let distrusting = r.flags.distrusting();
        if !distrusting.is_empty() {
            let names: Vec<&str> = distrusting.names().collect();
            write!(
                f,
                "\nwarning: run {} is flagged {}: its kerf may be off by more than 3 µm (docs/measurement.md)",
                i + 1,
                names.join(", ")
            )?;
        }
        if (r.force_at_jam_n - force_n).abs() > 0.05 * force_n {
            write!(
                f,
                "\nwarning: run {} pressed the joint at {:.1} N, not the {:.1} N asked for",
                i + 1,
                r.force_at_jam_n,
                force_n
            )?;
        }
    }
    Ok(())
}

impl fmt::Display for SimNote {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let spread = if self.kerf_sd_um > 0.0 {
            format!(" ± {:.1} µm SD", self.kerf_sd_um)
        } else {
            String::new()
        };
        write!(
            f,
            "(simulated device: gauges cut with a nominal {:.1} µm{spread}, as a real cutter cuts them; an ideal device reads {:.1} µm on them at the force asked for, the spiral contact compressing under it)",
            self.kerf_um, self.ideal_reading_um
        )
    }
}
