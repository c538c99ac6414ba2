//! What a job reports: the loop's outcome ([`JobCliReport`]: the CLI prints it, the server
//! answers it without its file names) and a dry run's programs ([`DryRunReport`]).

use std::fmt;
use std::path::PathBuf;

use kerfmeter::job::{Stage, StageTime};
use serde::Serialize;

use crate::history::Recorded;

/// What the loop did.
#[derive(Debug, Clone, Serialize)]
pub struct JobCliReport {
    /// The plan read.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub input: PathBuf,
    /// The dilated plan written.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub output: PathBuf,
    /// The job's G-code written (and streamed).
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub gcode_out: PathBuf,
    /// The cutter's address.
    pub cutter: String,
    /// The kerf measured, µm.
    pub kerf_um: f32,
    /// Each stage's wall-clock time, s.
    pub stages: Vec<StageTime>,
    /// All stages, s.
    pub total_s: f64,
    /// Where the gauge was cut, mm.
    pub gauge_at_mm: [f64; 2],
    /// Where the prongs came down, mm.
    pub landing_mm: [f64; 2],
    /// Lines of the job streamed.
    pub job_lines: usize,
    /// On the simulated device: what an ideal device reads on the gauge the cutter twin cut, µm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_truth_um: Option<f64>,
    /// What was measured (the label).
    pub label: Option<String>,
    /// Where the measurement was recorded, or why not, and its drift.
    pub history: Recorded,
}

impl fmt::Display for JobCliReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "kerf {:.1} µm", self.kerf_um)?;
        if let Some(t) = self.sim_truth_um {
            write!(f, " (simulated truth {t:.1} µm)")?;
        }
        writeln!(
            f,
            "; gauge cut at ({:.1}, {:.1}) mm on {}",
            self.gauge_at_mm[0], self.gauge_at_mm[1], self.cutter
        )?;
        for s in &self.stages {
            writeln!(f, "  {:<12} {:8.2} s", s.stage.name(), s.elapsed_s)?;
        }
        writeln!(f, "  {:<12} {:8.2} s", "total", self.total_s)?;
        writeln!(
            f,
            "wrote {} and {} ({} lines streamed); the laser is off",
            self.output.display(),
            self.gcode_out.display(),
            self.job_lines
        )?;
        write!(f, "{}", self.history)
    }
}

/// One stage's G-code, for a dry run.
#[derive(Debug, Clone, Serialize)]
pub struct StageGcode {
    /// The stage.
    pub stage: Stage,
    /// Its program.
    pub gcode: String,
}

/// What a dry run gives: every stage's program, moving nothing.
#[derive(Debug, Clone, Serialize)]
pub struct DryRunReport {
    /// Where the gauge would be cut, mm.
    pub gauge_at_mm: [f64; 2],
    /// The kerf the job is shown dilated by, µm.
    pub kerf_um: f64,
    /// The programs, in order.
    pub stages: Vec<StageGcode>,
}

impl fmt::Display for DryRunReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for s in &self.stages {
            writeln!(f, "; ==== stage {}: {}", s.stage, s.stage.describe())?;
            if s.stage == Stage::StreamJob {
                writeln!(
                    f,
                    "; (dilated by {} um here; the job uses the kerf measured)",
                    self.kerf_um
                )?;
            }
            f.write_str(&s.gcode)?;
        }
        Ok(())
    }
}
