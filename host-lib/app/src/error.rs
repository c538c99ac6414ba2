//! Why an application-layer call failed: the device library's, the plan crate's or the
//! history's error, kept as it is so that each front end maps it to its own exit code,
//! JSON-RPC error or Python exception.

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The device, a file, or a bad argument (the device library's error).
    #[error(transparent)]
    Meter(#[from] kerfmeter::Error),
    /// A plan could not be drawn, read or dilated.
    #[error(transparent)]
    Plan(#[from] kerfmeter_plan::PlanError),
    /// The history could not be read or written.
    #[error(transparent)]
    History(#[from] kerfmeter_history::Error),
}
