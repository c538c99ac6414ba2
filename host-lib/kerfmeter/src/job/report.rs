//! What the loop tells as it goes and when it ends: its events ([`JobEvent`]), its report
//! ([`JobReport`], each stage timed), why it stopped ([`JobError`]), and which quality flags stop
//! it ([`stopping_flags`]).

use std::time::Duration;

use kerfmeter_protocol::{KerfResult, QualityFlags};
use serde::Serialize;

use super::Stage;
use crate::error::Error;
use crate::grbl::{CutterError, StreamProgress};
use crate::{Category, Progress};

/// What the loop reports as it goes.
#[derive(Debug)]
pub enum JobEvent<'a> {
    /// A stage began.
    Started(Stage),
    /// A stream of the stage went on.
    Cutter(Stage, &'a StreamProgress),
    /// The device run went on.
    Device(&'a Progress),
    /// A stage ended, after `elapsed`.
    Finished(Stage, Duration),
}

/// How long a stage took.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StageTime {
    /// The stage.
    pub stage: Stage,
    /// Its wall-clock time, s.
    pub elapsed_s: f64,
}

/// What the loop did.
#[derive(Debug, Clone, Serialize)]
pub struct JobReport {
    /// The measurement.
    pub kerf: KerfResult,
    /// Each stage's time, in order.
    pub stages: Vec<StageTime>,
    /// The job's G-code as streamed.
    #[serde(skip)]
    pub job_gcode: String,
    /// Lines of the job streamed.
    pub job_lines: usize,
    /// Where the prongs came down, mm (the head's reported position plus the prong offset).
    pub landing_mm: [f64; 2],
}

/// Why the loop stopped. Every error is returned with the cutter stopped (laser off) and any
/// device run aborted, unless it says otherwise.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// A setting is out of range.
    #[error("{0}")]
    Invalid(String),
    /// Something the job moves over lies outside the machine's travel; nothing was sent.
    #[error("{0}")]
    Travel(String),
    /// The cutter failed (it stopped itself, or says it could not).
    #[error("{stage} ({}): {source}{}", stage.describe(), stage.prongs_note())]
    Cutter {
        /// The stage.
        stage: Stage,
        /// The driver's error.
        source: CutterError,
    },
    /// The device failed or refused.
    #[error("{stage} ({}): {source}; the job was not cut and the laser is off", stage.describe())]
    Device {
        /// The stage.
        stage: Stage,
        /// The client's error.
        source: Error,
    },
    /// The motion did not end as it should.
    #[error("{0}; the laser is off")]
    Motion(String),
    /// The measurement carries a reason to distrust it.
    #[error(
        "the measurement ({kerf_um:.1} µm) was flagged {flags}: the job was not cut and the laser is off; check the gauge and the prongs, then run the job again"
    )]
    Flagged {
        /// The kerf read, µm.
        kerf_um: f32,
        /// The flags' names.
        flags: String,
    },
    /// The plan could not be dilated or written as G-code.
    #[error("dilating the plan by {kerf_um:.1} µm failed: {reason}; the job was not cut")]
    Dilate {
        /// The kerf measured, µm.
        kerf_um: f32,
        /// Why.
        reason: String,
    },
    /// The cancel flag was set.
    #[error(
        "cancelled while {}: the cutter was stopped (laser off) and the device run aborted{}",
        stage.describe(),
        stage.prongs_note()
    )]
    Cancelled {
        /// The stage it was in.
        stage: Stage,
    },
    /// Stopping the cutter after an error failed too.
    #[error(
        "THE LASER MAY STILL BE ON: switch it off at the machine now. {cause}; then stopping the \
         cutter failed ({stop})"
    )]
    NotStopped {
        /// The first error.
        cause: Box<JobError>,
        /// The stop's error.
        stop: CutterError,
    },
}

impl JobError {
    /// What kind of failure this is (the command-line tool's exit code follows from it).
    pub fn category(&self) -> Category {
        match self {
            JobError::Invalid(_) => Category::Usage,
            JobError::Cutter { source, .. } => source.category(),
            JobError::Device { source, .. } => source.category(),
            JobError::Flagged { .. }
            | JobError::Cancelled { .. }
            | JobError::Motion(_)
            | JobError::Travel(_) => Category::Device,
            JobError::Dilate { .. } => Category::File,
            JobError::NotStopped { cause, .. } => cause.category(),
        }
    }

    /// True when the cutter could not be stopped after a failure: its laser may still be on (the
    /// command-line tool gives this its own exit code, as for [`CutterError::laser_may_be_on`]).
    pub fn laser_may_be_on(&self) -> bool {
        match self {
            JobError::NotStopped { .. } => true,
            JobError::Cutter { source, .. } => source.laser_may_be_on(),
            _ => false,
        }
    }
}

/// The quality flags that stop the job: those that distrust the number (all but the advisory
/// `decimated` and `play-modelled`, [`QualityFlags::ADVISORY`]).
pub fn stopping_flags(flags: QualityFlags) -> QualityFlags {
    flags.distrusting()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_decimation_lets_a_flagged_measurement_through() {
        assert!(stopping_flags(QualityFlags::DECIMATED).is_empty());
        let mut f = QualityFlags::DECIMATED;
        f.insert(QualityFlags::NOISY_HOLD);
        assert_eq!(stopping_flags(f), QualityFlags::NOISY_HOLD);
    }
}
