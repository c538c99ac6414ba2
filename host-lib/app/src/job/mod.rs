//! A job: the paper's whole loop on a laser cutter (cut the gauge beside the plan, lower the
//! prongs into it, measure, lift, dilate the plan by the kerf measured and cut it), as asked by
//! any front end.
//!
//! A front end turns its input into a [`JobRequest`] (the CLI's flags; the server's `job` params,
//! deserialized straight into it) and names the files ([`JobFiles`]). [`JobSetup::new`] reads
//! and checks the plan before anything moves, and places the gauge when the bed is known (else
//! [`JobSetup::on_machine`] does once the cutter reports its travel), checking every planned
//! move: against the machine's travel first ([`kerfmeter::job::check_travel`]), then
//! ([`kerfmeter::job::Placement::check_layout`]) the plan and the gauge on the bed, the gauge 5
//! mm clear of the plan, the head's move over the gauge on the bed, the insert Z below the travel
//! Z. The gauge is cut with the job's own settings (the kerf depends on them). On the machines a
//! front end opened, [`JobSetup::drive`] runs the loop ([`kerfmeter::job::run_job`]'s; its
//! dilate stage is [`JobSetup::dilate_and_write`]), [`JobSetup::record`] records the
//! measurement in the history, and what the job did is a [`JobCliReport`] (a dry run's programs,
//! a [`DryRunReport`]).
//!
//! # Modules
//!
//! - `request`: the request and its files; `setup`: the setup, the placing and the dry run;
//!   `plan`: the plan's outputs, settings, reading and dilation; `drive`: the loop driven, its
//!   measurement recorded, its report; `report`: the reports; `error`: why a setup was refused.

mod drive;
mod error;
mod plan;
mod report;
mod request;
mod setup;

pub use drive::{RecordedAfterStop, Stopped};
pub use error::JobSetupError;
pub use plan::cut_settings;
pub use report::{DryRunReport, JobCliReport, StageGcode};
pub use request::{DEFAULT_PLUNGE_FEED_MM_PER_MIN, DEFAULT_TRAVEL_Z_MM, JobFiles, JobRequest};
pub use setup::{DEFAULT_BED_MM, GAUGE_MARGIN_MM, JobSetup, Placed};

#[cfg(test)]
mod tests;
