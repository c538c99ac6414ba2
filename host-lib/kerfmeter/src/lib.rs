//! Drive a Kerfmeter from a PC.
//!
//! [`Kerfmeter`] is a blocking client over a serial port (the device's USB-Serial-JTAG port, or a
//! pseudo-terminal served by the digital twin). It frames requests with the shared
//! [`kerfmeter_protocol`], retries lost responses with the same sequence number (so the device
//! answers from memory instead of acting twice), skips garbage on the line, and turns every
//! device refusal into an [`Error`] whose message says what to do. Opening a port never resets the
//! device's ESP32-C3: its modem lines are released in the one order its USB-Serial-JTAG reads as
//! no reset ([`lines`]).
//!
//! Beside the client: the calls ([`Kerfmeter::run_kerfmeter`], [`Kerfmeter::get_kerf_value`],
//! [`Kerfmeter::reset_kerfmeter`] and the rest), run parameters from a joint ([`params`]),
//! statistics over repeated runs ([`stats`]), the bed map ([`map`]), safe output files
//! ([`files`]), the laser cutter's GRBL driver ([`grbl`]), the Ruida driver ([`ruida`]: the
//! G-code Kerfmeter writes, sent to a Ruida CO2 controller over UDP), the automatic loop that cuts a gauge, measures
//! it and cuts the job dilated ([`job`]) and, with the `sim` feature (off by default: the CLI
//! and Python turn it on), the digital twin in-process ([`sim`]). LightBurn (its project files,
//! its REST API and its twin) is the `kerfmeter-lightburn` crate's.
//!
//! This crate is not the command-line tool (that is `kerfmeter-cli`, which also draws the plots)
//! and does not read or write cutting plans (that is `kerfmeter-plan`): it has no argument parser,
//! no plotting and no SVG/DXF code.
//!
//! ```no_run
//! let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
//! let info = meter.info()?;
//! println!("firmware {}.{}.{}", info.firmware.major, info.firmware.minor, info.firmware.patch);
//! # Ok::<(), kerfmeter::Error>(())
//! ```

#![warn(missing_docs)]

mod calls;
mod client;
mod error;
pub mod files;
pub mod grbl;
pub mod job;
pub mod lines;
pub mod map;
pub mod params;
pub mod ruida;
#[cfg(feature = "sim")]
pub mod sim;
pub mod stats;

pub use calls::{Curve, Measurement, Progress};
pub use client::{Kerfmeter, Options};
pub use error::{
    Category, Error, Result, describe_conditions, describe_error_code, describe_fault,
};
pub use kerfmeter_protocol as protocol;
pub use params::JointSpec;

/// The code of `docs/rust.md`, run as this crate's doctests so that the page stays true.
#[cfg(all(doctest, feature = "sim"))]
#[doc = include_str!("../../../docs/rust.md")]
struct RustDocsPage;
