//! A set-up job driven to its end: the loop run on the machines a front end opened (the
//! measurement told apart from what came after it, and the files written by then), the
//! measurement recorded in the history, and the job's report.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use kerfmeter::Kerfmeter;
use kerfmeter::job::{Devices, JobError, JobEvent, JobReport, Stage, run_job};
use kerfmeter::protocol::KerfResult;

use super::{JobCliReport, JobSetup, Placed};
use crate::history::{Measured, Recorded, record};

/// Why the loop stopped: before its measurement, or after it (with the files written by then,
/// each complete).
#[derive(Debug)]
pub enum Stopped {
    /// Nothing was measured.
    Before(JobError),
    /// The kerf was measured; the job stopped after.
    After {
        /// Why.
        error: JobError,
        /// The dilated plan and the G-code, as far as they were written.
        written: Vec<PathBuf>,
    },
}

/// What a job that stopped after its measurement could record: the device's last result read
/// back, where it was recorded, and a line saying so (or why not).
#[derive(Debug, Clone)]
pub struct RecordedAfterStop {
    /// The kerf the device measured, µm (`None` when it could not be read back).
    pub kerf_um: Option<f32>,
    /// Where it was recorded, or why not.
    pub history: Option<Recorded>,
    /// In words.
    pub note: String,
}

impl JobSetup {
    /// Run the loop with the gauge `placed` on `devices`, until done or `cancel` is raised;
    /// `on_event` hears of every stage. The loop's dilate stage writes the plan and its G-code.
    pub fn drive(
        &self,
        placed: &Placed,
        devices: Devices<'_>,
        cancel: &AtomicBool,
        on_event: &mut dyn FnMut(JobEvent<'_>),
    ) -> Result<JobReport, Stopped> {
        let request = self.loop_request(placed);
        let mut written = Vec::new();
        let mut dilate = |kerf_um: f64| self.dilate_and_write(kerf_um, &mut written);
        let mut measured = false;
        let report = run_job(devices, &request, &mut dilate, cancel, &mut |e| {
            measured |= matches!(e, JobEvent::Finished(Stage::Measure, _));
            on_event(e)
        });
        match report {
            Ok(report) => Ok(report),
            Err(error) if !measured => Err(Stopped::Before(error)),
            Err(error) => Err(Stopped::After { error, written }),
        }
    }

    /// Record the job's measurement `kerf`, made by `meter`, in the history at `db` (`None`:
    /// the user's).
    pub fn record(&self, db: Option<&Path>, meter: &Kerfmeter, kerf: &KerfResult) -> Recorded {
        let params = self.params();
        let measured = Measured {
            label: self.request().label.as_deref(),
            thickness_mm: f64::from(params.thickness_mm),
            force_n: f64::from(params.target_force_n),
            kerf_um: f64::from(kerf.kerf_um),
            ci95_um: None,
            runs: std::slice::from_ref(kerf),
        };
        record(db, meter, &measured)
    }

    /// After a stop that followed the measurement: read the device's last result back and
    /// record it.
    pub fn record_after_stop(&self, db: Option<&Path>, meter: &mut Kerfmeter) -> RecordedAfterStop {
        match meter.get_kerf_value() {
            Ok(Some(kerf)) => {
                let recorded = self.record(db, meter, &kerf);
                RecordedAfterStop {
                    kerf_um: Some(kerf.kerf_um),
                    note: recorded.to_string(),
                    history: Some(recorded),
                }
            }
            Ok(None) => RecordedAfterStop {
                kerf_um: None,
                history: None,
                note: "warning: not recorded in the history: the device kept no result".into(),
            },
            Err(e) => RecordedAfterStop {
                kerf_um: None,
                history: None,
                note: format!("warning: not recorded in the history: cannot read the result: {e}"),
            },
        }
    }

    /// The report of the job `done` with the gauge `placed` on the cutter at `cutter`; on the
    /// simulated device, `sim_truth_um` is what an ideal device reads on the gauge cut.
    pub fn report(
        &self,
        placed: &Placed,
        cutter: String,
        done: JobReport,
        sim_truth_um: Option<f64>,
        history: Recorded,
    ) -> JobCliReport {
        let files = self.files();
        JobCliReport {
            input: files.input.clone(),
            output: files.output.clone(),
            gcode_out: self.gcode_out().clone(),
            cutter,
            kerf_um: done.kerf.kerf_um,
            total_s: done.stages.iter().map(|s| s.elapsed_s).sum(),
            stages: done.stages,
            gauge_at_mm: placed.placement.gauge_at_mm,
            landing_mm: done.landing_mm,
            job_lines: done.job_lines,
            sim_truth_um,
            label: self.request().label.clone(),
            history,
        }
    }
}
