//! Cutting plans: the spiral gauge to cut before a measurement, and dilating a plan by the
//! measured kerf.
//!
//! * [`gauge`] draws the spiral gauge (SVG or DXF) from the same
//!   [`GaugeGeometry`](crate::protocol::GaugeGeometry) the device receives with every run; its
//!   module doc shows the sense convention (which way φ grows, which way the hub turns).
//! * [`dilate`] offsets closed cut contours by half the kerf (Minkowski sum with the beam's disk,
//!   round joins, arcs kept, even-odd nesting, a kerf per part from a map) and finds the problems
//!   (parts that would merge, holes too narrow, crossing cuts).
//! * [`svg`] and [`dxf_plan`] read plans in those formats, decide which lines are cuts by the
//!   [`rules`] (colour and width conventions of laser software, documented there), and write the
//!   dilated plan back — SVG by editing the original text, so everything else survives unchanged.
//! * [`cli`] holds the command-line arguments, entry points and reports: [`run_gauge`] and
//!   [`run_dilate`].
//!
//! Everything below the CLI works on strings, bytes and geometry, so it can be used as a library:
//!
//! ```
//! use kerfmeter::plan::dilate::KerfSource;
//! use kerfmeter::plan::svg::{SvgOptions, dilate_svg};
//!
//! let plan = r#"<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50">
//!   <rect id="part" x="10" y="10" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>
//! </svg>"#;
//! let (dilated, summary) = dilate_svg(plan, &KerfSource::Uniform(200.0), &SvgOptions::default())?;
//! assert_eq!(summary.contours_dilated, 1);
//! assert!(dilated.contains(r#"<path id="part""#));
//! # Ok::<(), kerfmeter::Error>(())
//! ```

pub mod cli;
pub mod dilate;
pub mod dxf_plan;
pub mod gauge;
pub mod geom;
pub mod outcome;
pub mod rules;
pub mod svg;

pub use cli::{DilateArgs, DilateReport, GaugeArgs, GaugeReport, run_dilate, run_gauge};
