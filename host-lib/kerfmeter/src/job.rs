//! The paper's automatic loop, driven from the host: cut the gauge beside the job, wait for the
//! motion to end, move the prongs over the gauge and lower them (Z), measure, lift, dilate the
//! plan by the kerf measured and stream the job ([`run_job`]).
//!
//! # Design
//!
//! - The cutter is a [`JobCutter`]: what the loop needs of a laser cutter, whatever its
//!   controller ([`cutter`](mod@cutter)): the GRBL driver ([`crate::grbl::Cutter`]: every program
//!   streamed with its character counting and its stop on every failure) and the Ruida driver
//!   ([`crate::ruida::RuidaCutter`]: the same G-code read into cut programs and direct moves,
//!   sent over UDP, stopped with `D8 01` on every failure). The device is the
//!   [`Kerfmeter`](crate::Kerfmeter) client.
//! - The plan is the caller's: [`run_job`] gets the gauge's G-code and a `dilate` function that
//!   turns the measured kerf into the job's G-code (the command-line tool's uses the plan crate's
//!   dilation and G-code writer), so this crate stays free of SVG/DXF code.
//! - Each stage is timed ([`StageTime`]) and reported to a progress callback ([`JobEvent`]).
//! - Safety: a measurement that fails or is flagged (any quality flag but `decimated`) stops
//!   before the job: the device's run is aborted (motor safe), the prongs lifted and the cutter
//!   stopped ([`JobCutter::stop`]; GRBL's: feed hold, soft reset, laser off). The `cancel` flag is watched in
//!   every stage: a stream stops the cutter itself, a device run is aborted, and the cutter is
//!   stopped. The laser is never on during the Z and XY moves of the prongs: they are `G0`
//!   travels and a `G1` Z plunge after `M5` with `S0`.
//! - The prongs' axis is at `prong_offset_mm` from the nozzle: the head goes to the gauge's
//!   centre minus the offset ([`Placement::head_over_gauge_mm`]). Where the head ended (the
//!   controller's reported position) plus the offset is where the prongs landed, which the
//!   simulated device is told ([`SimLink`]).
//! - The gauge and the plan are cut at one height: where the head stood when the job began (the
//!   user's focus, [`CutHeight`]). The gauge programs and the plan's make no Z move; after the
//!   prongs are lifted to the travel height the head goes back down to that height (`G53` when the
//!   controller reports its machine position), so the plan is cut as the gauge was, in focus. A
//!   stop in the stages that lower, hold or lift the prongs moves nothing: its error says the
//!   prongs may still be down ([`Stage::prongs_note`]).
//! - A gauge position can be chosen on a free spot of the bed beside the plan ([`free_spot_mm`]).
//! - Before anything moves, [`Placement::check_layout`] checks every move the job plans: the
//!   plan and the gauge on the bed, the gauge a margin clear of the plan, the head's move over
//!   the gauge on the bed, and the insert Z below the travel Z (Z grows upward: the prongs plunge
//!   down). [`run_job`] checks the numbers again ([`Placement::check`]); it knows no bed.
//! - Also before anything moves, [`run_job`] checks them against the machine's travel when the
//!   controller reports one ([`check_travel`]: the gauge, the prong offset, the Z heights and the
//!   plan as placed, each refused with its flag, [`JobError::Travel`]).
//!
//! # Modules
//!
//! - [`cutter`](mod@cutter): the [`JobCutter`] trait, and its GRBL implementation.
//! - `run`: the loop ([`run_job`], [`Devices`], [`JobRequest`]) and its safe stop.
//! - `placement`: the gauge's place, the prongs' moves, the cut height and the bed's checks.
//! - `report`: events, the report, the errors and the flags that stop the job.
//! - `stage`: the stages and their words; `travel`: the checks against the machine's travel.

pub mod cutter;
mod placement;
mod report;
mod run;
mod stage;
mod travel;

pub use cutter::{HeadState, HeadStatus, JobCutter};
pub use placement::{CutHeight, Layout, Placement, free_spot_mm};
pub use report::{JobError, JobEvent, JobReport, StageTime, stopping_flags};
#[cfg(feature = "sim")]
pub use run::SimLink;
pub use run::{Devices, Dilate, JobRequest, run_job};
pub use stage::Stage;
pub use travel::{check_plan_travel, check_travel};
