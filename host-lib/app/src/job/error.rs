//! Why a job could not be set up: the request, a file or the plan, or a planned move.

use kerfmeter::job::JobError;
use kerfmeter_plan::PlanError;

/// Why a job was refused before anything moved (or its plan could not be dilated after).
#[derive(Debug, thiserror::Error)]
pub enum JobSetupError {
    /// The request does not fit together (no room for the gauge, an output named twice).
    #[error("{0}")]
    Invalid(String),
    /// A file could not be checked or written; the plan, the profile or the gauge could not be
    /// read, drawn or dilated.
    #[error(transparent)]
    App(#[from] crate::Error),
    /// A planned move is refused (out of the bed or the machine's travel, a bad Z order).
    #[error(transparent)]
    Job(#[from] JobError),
}

impl From<kerfmeter::Error> for JobSetupError {
    fn from(e: kerfmeter::Error) -> Self {
        JobSetupError::App(e.into())
    }
}

impl From<PlanError> for JobSetupError {
    fn from(e: PlanError) -> Self {
        JobSetupError::App(e.into())
    }
}
