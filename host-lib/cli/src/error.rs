//! Why a command failed, and the process's exit code for it. The code comes from the error's
//! category, except for the one outcome worse than any category: 0 success; 2 bad arguments; 3
//! communication error (port, timeout, protocol, device restarted, or the same with the cutter);
//! 4 the device refused, faulted, failed its self-test or could not finish, the cutter refused a
//! line, raised an alarm or was stopped (Ctrl-C), or a file could not be read or written; 5 the
//! cutter failed and could not be stopped: its laser may still be on; 128 + n a device command
//! interrupted by signal n (130 Ctrl-C, 143 SIGTERM), its motor stopped.

use std::path::PathBuf;

use kerfmeter::grbl::CutterError;
use kerfmeter::job::JobError;
use kerfmeter::{Category, Error};
use kerfmeter_lightburn::rest::LightBurnError;
use kerfmeter_plan::PlanError;
use kerfmeter_plan::compensation::FoundCompensation;
use serde::Serialize;

use kerfmeter_app::history::Recorded;

/// Exit code for bad arguments (clap uses it too).
const EXIT_USAGE: u8 = 2;
/// Exit code for errors of the serial link.
const EXIT_COMMUNICATION: u8 = 3;
/// Exit code for device refusals and faults.
const EXIT_DEVICE: u8 = 4;
/// Exit code for a cutter that could not be stopped: its laser may still be on.
const EXIT_LASER_MAY_BE_ON: u8 = 5;

/// Why a command failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The arguments do not fit together.
    #[error("{0}")]
    Usage(String),
    /// The library (device, map, files) failed.
    #[error(transparent)]
    Meter(#[from] Error),
    /// A cutting plan could not be drawn, read or dilated.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The cutter failed, refused or was stopped.
    #[error(transparent)]
    Cutter(#[from] CutterError),
    /// The automatic loop stopped (the cutter stopped, the laser off, unless it says otherwise).
    #[error(transparent)]
    Job(#[from] JobError),
    /// The automatic loop stopped after its measurement: the error, and what the job had by
    /// then (the kerf, its record in the history, the files written), which `--json` reports
    /// beside the error.
    #[error("{source}")]
    JobAfterMeasuring {
        /// Why the loop stopped.
        source: JobError,
        /// What it had done.
        so_far: Box<JobSoFar>,
    },
    /// The measurement history could not be read.
    #[error(transparent)]
    History(#[from] kerfmeter_history::Error),
    /// LightBurn's REST API refused or could not be reached.
    #[error(transparent)]
    LightBurn(#[from] LightBurnError),
    /// The measurement stands (printed, and recorded) but what was asked after it failed (the
    /// curve, its plot).
    #[error("{message} (the kerf above is measured and recorded)")]
    AfterMeasuring {
        /// What failed.
        message: String,
        /// Its kind, for the exit code.
        category: Category,
    },
    /// The device ran its self-test and an item failed.
    #[error("the self-test failed; see the items above")]
    SelfTestFailed,
    /// A bring-up step failed (the report, printed and saved, says which and why).
    #[error("the bring-up failed; see the steps above and the report saved")]
    BringupFailed,
    /// A signal (Ctrl-C, SIGTERM, SIGHUP) stopped a command that moves the motor: the device was
    /// told to abort and reported its motor at rest. Exits 128 + the signal's number.
    #[error("interrupted ({signal}): the device aborted and reports its motor at rest")]
    Interrupted {
        /// The signal's name.
        signal: &'static str,
        /// The exit code it gives.
        exit_code: u8,
    },
}

/// `e` as the command's error once `signal` came: a device call that the signal stopped (the
/// device aborted, its motor at rest) is [`CliError::Interrupted`]; any other error stays what
/// it is (an abort that failed keeps its own error and exit code).
pub fn after_signal(e: CliError, signal: Option<crate::interrupt::Signal>) -> CliError {
    match (e, signal) {
        (CliError::Meter(Error::Cancelled), Some(signal)) => CliError::Interrupted {
            signal: signal.name(),
            exit_code: signal.exit_code(),
        },
        (e, _) => e,
    }
}

/// What a job that stopped after measuring had done (in `--json`'s error object).
#[derive(Debug, Clone, Serialize)]
pub struct JobSoFar {
    /// The kerf the device measured, µm (`null` when its result could not be read back).
    pub kerf_um: Option<f32>,
    /// Where it was recorded, or why not.
    pub history: Option<Recorded>,
    /// The files written before the job stopped, each complete (the plan was not cut, or not
    /// all of it).
    #[serde(serialize_with = "crate::output::lossy_path::list")]
    pub written: Vec<PathBuf>,
}

impl From<kerfmeter_app::Error> for CliError {
    fn from(e: kerfmeter_app::Error) -> Self {
        match e {
            kerfmeter_app::Error::Meter(e) => CliError::Meter(e),
            kerfmeter_app::Error::Plan(e) => CliError::Plan(e),
            kerfmeter_app::Error::History(e) => CliError::History(e),
        }
    }
}

impl CliError {
    /// Whether the command's report, already printed, says this failure itself (a failed
    /// self-test's items, a run's `curve_error`): `--json` then prints no second object.
    pub fn is_in_report(&self) -> bool {
        matches!(
            self,
            CliError::SelfTestFailed | CliError::BringupFailed | CliError::AfterMeasuring { .. }
        )
    }

    /// What kind of failure this is.
    pub fn category(&self) -> Category {
        match self {
            CliError::Usage(_) => Category::Usage,
            CliError::Meter(e) => e.category(),
            // A plan error about a file is the file's; any other is about the arguments.
            CliError::Plan(e) if e.path().is_some() => Category::File,
            CliError::Plan(_) => Category::Usage,
            CliError::SelfTestFailed | CliError::BringupFailed | CliError::Interrupted { .. } => {
                Category::Device
            }
            CliError::AfterMeasuring { category, .. } => *category,
            CliError::Cutter(e) => e.category(),
            CliError::Job(e) | CliError::JobAfterMeasuring { source: e, .. } => e.category(),
            CliError::History(kerfmeter_history::Error::Invalid(_))
            | CliError::History(kerfmeter_history::Error::NoDataDir) => Category::Usage,
            CliError::History(_) => Category::File,
            CliError::LightBurn(e) => e.category(),
        }
    }

    /// What a job that stopped after measuring had done, if this is such a stop.
    pub fn job_so_far(&self) -> Option<JobSoFar> {
        match self {
            CliError::JobAfterMeasuring { so_far, .. } => Some(so_far.as_ref().clone()),
            _ => None,
        }
    }

    /// The compensation a plan (or a running LightBurn's project) was refused for already
    /// carrying, if that is the error.
    pub fn compensation_found(&self) -> Option<FoundCompensation> {
        match self {
            CliError::Plan(e) => e.compensation_found().cloned(),
            CliError::LightBurn(LightBurnError::AlreadyCompensated { found, offsets_um }) => {
                FoundCompensation::lightburn(found.join("; "), offsets_um)
            }
            _ => None,
        }
    }

    /// The device fault behind the error, if any (named as in the protocol).
    pub fn fault(&self) -> Option<String> {
        match self {
            CliError::Meter(m)
            | CliError::Job(JobError::Device { source: m, .. })
            | CliError::JobAfterMeasuring {
                source: JobError::Device { source: m, .. },
                ..
            } => m.fault().map(|f| format!("{f:?}")),
            CliError::Usage(_)
            | CliError::Plan(_)
            | CliError::SelfTestFailed
            | CliError::BringupFailed
            | CliError::Interrupted { .. }
            | CliError::AfterMeasuring { .. }
            | CliError::Cutter(_)
            | CliError::Job(_)
            | CliError::JobAfterMeasuring { .. }
            | CliError::History(_)
            | CliError::LightBurn(_) => None,
        }
    }

    /// The idle conditions that refused the request, by name (empty for any other error).
    pub fn conditions(&self) -> Vec<&'static str> {
        match self {
            CliError::Meter(m) => m.blocking_conditions().names().collect(),
            CliError::Usage(_)
            | CliError::Plan(_)
            | CliError::SelfTestFailed
            | CliError::BringupFailed
            | CliError::Interrupted { .. }
            | CliError::AfterMeasuring { .. }
            | CliError::Cutter(_)
            | CliError::Job(_)
            | CliError::JobAfterMeasuring { .. }
            | CliError::History(_)
            | CliError::LightBurn(_) => Vec::new(),
        }
    }
}

/// The process's exit code for an error: from its category, or 5 when a cutter's laser may
/// still be on.
pub fn exit_code(e: &CliError) -> u8 {
    let laser_may_be_on = match e {
        CliError::Cutter(cutter) => cutter.laser_may_be_on(),
        CliError::Job(job) | CliError::JobAfterMeasuring { source: job, .. } => {
            job.laser_may_be_on()
        }
        CliError::Interrupted { exit_code, .. } => return *exit_code,
        _ => false,
    };
    if laser_may_be_on {
        return EXIT_LASER_MAY_BE_ON;
    }
    match e.category() {
        Category::Usage => EXIT_USAGE,
        Category::Communication => EXIT_COMMUNICATION,
        Category::Device | Category::File => EXIT_DEVICE,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cutter_that_could_not_be_stopped_has_its_own_exit_code() {
        let silent = || CutterError::Silent {
            address: "grbl:/dev/ttyUSB0".into(),
            waited_ms: 2000,
            doing: "streaming",
        };
        let not_stopped = CutterError::NotStopped {
            cause: Box::new(silent()),
            stop: Box::new(silent()),
        };
        assert_eq!(exit_code(&CliError::Cutter(not_stopped)), 5);
        let stopped = CutterError::Stopped {
            cause: Box::new(silent()),
            position_lost: false,
        };
        assert_eq!(exit_code(&CliError::Cutter(stopped)), EXIT_COMMUNICATION);
    }
}
