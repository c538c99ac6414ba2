//! LightBurn, in one home: the measured kerf written into the **Kerf Offset** of LightBurn's Line
//! layers, offline in a project file or online in the project open in LightBurn.
//!
//! * [`project`] edits a `.lbrn2` (or `.lbrn`) project's text: `kerfmeter dilate box.lbrn2`.
//! * [`rest`] is a client of LightBurn's local REST API (pairing, request signing, the cut list,
//!   one change per layer read back): `kerfmeter lightburn pair` and `apply`. Its replies are
//!   read into typed structs, and one of the wrong shape is an error naming where.
//! * `twin` (the `twin` feature, off by default) serves that API from its published spec on a
//!   loopback port: `kerfmeter --sim lightburn` and the tests, no LightBurn needed.
//!
//! Both ways choose layers by the same rule (`--layers 0,Outline`, a name with a comma kept whole:
//! `kerfmeter_plan::selectors`), write the same offset (half the kerf, positive outward) and refuse
//! a project already compensated the same way (`kerfmeter_plan::compensation`).
//!
//! **Its dependencies, and why there is no cycle.** This crate depends on `kerfmeter-plan` (the
//! selector rule, the compensation record and refusal, [`kerfmeter_plan::PlanError`], numbers as
//! written, the kerf's range) and on `kerfmeter` (its error [`kerfmeter::Category`] and its
//! atomic file writer, for the pairing secret); neither depends on this crate, so neither
//! re-exports it: the front ends (the CLI) name `kerfmeter_lightburn` themselves. The REST client
//! brings its own dependencies (`ureq`, `hmac`, `sha2`, `hex`, `dirs`), which the device's library
//! and the plan crate no longer carry; the twin alone reads HTTP requests (`httparse`).

#![warn(missing_docs)]

pub mod project;
pub mod rest;
#[cfg(feature = "twin")]
pub mod twin;
