//! `kerfmeter-plan`: cutting plans for a Kerfmeter. The spiral gauge to cut before a
//! measurement, and dilating a plan by the measured kerf.
//!
//! * [`gauge`] draws the spiral gauge (SVG or DXF) from the same
//!   [`GaugeGeometry`](kerfmeter_protocol::GaugeGeometry) the device receives with every run; its
//!   module doc shows the sense convention (which way φ grows, which way the hub turns).
//! * [`dilate`] offsets closed cut contours by half the kerf (Minkowski sum with the beam's disk,
//!   round joins, arcs kept, even-odd nesting, a kerf per part from a map) and finds the problems
//!   (parts that would merge, holes too narrow, crossing cuts).
//! * [`svg`] and [`dxf_plan`] read plans in those formats, decide which lines are cuts by the
//!   [`rules`] (colour and width conventions of laser software, documented there), and write the
//!   dilated plan back — SVG by editing the original text, so everything else survives unchanged.
//! * Both formats run one pipeline (the crate-private `pipeline` module): read the cuts into
//!   closed contours, each with the element or entity it came from, and open paths; dilate them;
//!   write the dilated contours back in place. Counting, the summary, the problems reported
//!   together and the open paths are done there once, not per format.
//! * [`compensation`] recognises plans that are already compensated (boxes.py's `--burn`, this
//!   tool's own outputs), refuses to compensate them twice or undoes their compensation
//!   ([`recompensate`]: boxes.py's corner loops, inner corners kept sharp), and records what was
//!   applied in every output.
//! * [`gcode`] turns a dilated plan (or the gauge drawing) into G-code for GRBL 1.1 laser mode:
//!   a typed program first (checked without parsing text), then its text; holes before the
//!   outline that holds them, short travels, per-colour or per-layer settings from a [`profile`].
//! * [`selectors`] is the rule by which a list option's values name colours or layers, and
//!   [`decimal`] writes the numbers of the files written; LightBurn projects (`.lbrn2`), which
//!   use both with [`compensation`], are edited by the `kerfmeter-lightburn` crate.
//! * [`file`](mod@file) reads a plan file and dilates it into bytes; [`PlanError`] says what went wrong,
//!   by kind. [`progress`] tells a caller how far a long dilation has got (the work on contours is
//!   spread over the cores; the result does not depend on how many).
//!
//! This crate is not the command-line tool (`kerfmeter gauge`, `kerfmeter dilate` and `kerfmeter gcode` live in
//! `kerfmeter-cli`, which also writes the output files) and does not talk to the device: it has no
//! serial port, no argument parser and no plotting. It shares the gauge geometry (and its checks)
//! with the device through `kerfmeter-protocol`.
//!
//! It works on strings, bytes, files read and geometry, so it can be used as a library:
//!
//! ```
//! use kerfmeter_plan::dilate::KerfSource;
//! use kerfmeter_plan::svg::{SvgOptions, dilate_svg};
//!
//! let plan = r#"<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50">
//!   <rect id="part" x="10" y="10" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>
//! </svg>"#;
//! let (dilated, summary) = dilate_svg(plan, &KerfSource::Uniform(200.0), &SvgOptions::default())?;
//! assert_eq!(summary.contours_dilated, 1);
//! assert!(dilated.contains(r#"<path id="part""#));
//! # Ok::<(), kerfmeter_plan::PlanError>(())
//! ```

#![warn(missing_docs)]

mod aci;
pub mod compensation;
pub mod decimal;
pub mod dilate;
pub mod dxf_plan;
mod entities;
mod error;
pub mod file;
pub mod gauge;
pub mod gcode;
pub mod geom;
mod nurbs;
pub mod outcome;
pub mod ownership;
mod pipeline;
pub mod profile;
pub mod progress;
pub mod recompensate;
pub mod rules;
pub mod selectors;
mod source_file;
pub mod svg;
mod xml;

pub use error::{PlanError, Problems, Result};
pub use file::{
    DilateOptions, PlanFormat, dilate_bytes, dilate_file, dilate_file_cuts, dilate_file_into,
};
