//! `kerfmeter gauge`: draw the spiral gauge to cut before a measurement (SVG, DXF or G-code by
//! the output's extension). The drawing and the G-code are `kerfmeter_plan`'s; this module turns
//! the arguments into their options, writes the file atomically and reports what it drew.
//!
//! As G-code the gauge is not dilated (the kerf is what it measures), its spiral centre is put at
//! `--at-mm` (default: the drawing's lower-left corner at the machine origin), and the cut-setting
//! flags are required: the kerf it measures depends on them, so it must be cut with the job's own
//! settings, and a silent default would measure another kerf than the job's. The refusal suggests
//! [`kerfmeter_app::gauge::GAUGE_SETTINGS`] as a first try when no job settings exist yet.

use std::path::PathBuf;

use kerfmeter::files::write_atomically;
pub use kerfmeter_app::gauge::GaugeReport;
use kerfmeter_app::gauge::{GaugeCut, GaugeFormat, GaugeRequest, JamSense, draw};
use kerfmeter_plan::{PlanError, PlanFormat};
use kerfmeter_protocol::GaugeGeometry;
use serde::Serialize;

use super::gcode::{CutArgs, GCODE_EXTENSIONS, is_gcode, parse_xy};
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

type Result<T, E = CliError> = std::result::Result<T, E>;

/// Sense in which the hub turns to close the gauge's gap, seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum JamDirectionArg {
    /// Clockwise.
    Cw,
    /// Counter-clockwise.
    Ccw,
}

impl From<JamDirectionArg> for JamSense {
    fn from(d: JamDirectionArg) -> Self {
        match d {
            JamDirectionArg::Cw => JamSense::Cw,
            JamDirectionArg::Ccw => JamSense::Ccw,
        }
    }
}

/// `kerfmeter gauge`: write the spiral gauge to cut.
#[derive(Debug, Clone, clap::Args)]
// The cut-setting flags are `gcode`'s, whose help speaks of its --profile; the gauge has none.
#[command(
    mut_arg("feed_mm_per_min", |a| a.help("G-code: feed while cutting, mm/min")),
    mut_arg("power_percent", |a| a.help("G-code: laser power, percent of full power"))
)]
pub struct GaugeArgs {
    /// Output file: .svg, .dxf or .gcode.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Replace the output even if it exists and kerfmeter did not write it (by default only
    /// kerfmeter's own outputs are replaced: a typo must not replace a cutting plan).
    #[arg(long)]
    pub force: bool,
    /// Spiral pitch c, µm of radius per degree of turn.
    #[arg(long, default_value_t = GaugeGeometry::PAPER.pitch_um_per_deg)]
    pub pitch_um_per_deg: f32,
    /// Mean radius of the spiral, mm.
    #[arg(long, default_value_t = GaugeGeometry::PAPER.radius_mm)]
    pub radius_mm: f32,
    /// Radius of the device's prongs, mm (checked against the holes).
    #[arg(long, default_value_t = GaugeGeometry::PAPER.prong_radius_mm)]
    pub prong_radius_mm: f32,
    /// Radius of the two prong holes as drawn, mm.
    #[arg(long, default_value_t = GaugeGeometry::PAPER.hole_radius_mm)]
    pub hole_radius_mm: f32,
    /// Distance of each hole's centre from the gauge centre, mm.
    #[arg(long, default_value_t = GaugeGeometry::PAPER.hole_distance_mm)]
    pub hole_distance_mm: f32,
    /// Sense in which the device turns the hub to close the gap, seen from above.
    #[arg(long, value_enum, default_value_t = JamDirectionArg::Cw)]
    pub jam_direction: JamDirectionArg,
    /// Rotation past which the inset disengages, degrees.
    #[arg(long, default_value_t = GaugeGeometry::PAPER.disengage_deg)]
    pub disengage_deg: f32,
    /// Add the paper's test piece beside the gauge: a one-finger box-joint pair dilated by
    /// --test-piece-kerf-um.
    #[arg(long, requires = "test_piece_kerf_um")]
    pub test_piece: bool,
    /// Sheet thickness for the test piece (finger length, slot depth), mm.
    #[arg(long, default_value_t = 4.0, requires = "test_piece")]
    pub thickness_mm: f64,
    /// Finger (and slot) width of the test piece, mm.
    #[arg(long, default_value_t = 6.3, requires = "test_piece")]
    pub finger_width_mm: f64,
    /// Kerf to dilate the test piece by, µm.
    #[arg(long)]
    pub test_piece_kerf_um: Option<f64>,
    /// Add an engraved label naming the geometry and the jam direction (not in G-code).
    #[arg(long)]
    pub label: bool,
    /// G-code: where the spiral centre goes on the machine, mm [default: the drawing's
    /// lower-left corner at 0,0].
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_xy)]
    pub at_mm: Option<[f64; 2]>,
    /// G-code: how to cut the gauge (required: the job's own settings, since the kerf depends on
    /// them).
    #[command(flatten)]
    pub cut: CutArgs,
}

impl GaugeArgs {
    /// The gauge these flags ask for, in the format the output's name says.
    pub fn request(&self) -> Result<GaugeRequest> {
        let format = if is_gcode(&self.output) {
            GaugeFormat::Gcode
        } else {
            PlanFormat::of(&self.output)
                .map_err(|_| {
                    PlanError::InvalidArgument(format!(
                        "{}: the gauge's file name must end in .svg, .dxf or a G-code extension ({})",
                        self.output.display(),
                        GCODE_EXTENSIONS.map(|e| format!(".{e}")).join(", ")
                    ))
                })?
                .into()
        };
        Ok(GaugeRequest {
            format,
            pitch_um_per_deg: self.pitch_um_per_deg,
            radius_mm: self.radius_mm,
            prong_radius_mm: self.prong_radius_mm,
            hole_radius_mm: self.hole_radius_mm,
            hole_distance_mm: self.hole_distance_mm,
            jam_direction: self.jam_direction.into(),
            disengage_deg: self.disengage_deg,
            test_piece: self.test_piece,
            thickness_mm: self.thickness_mm,
            finger_width_mm: self.finger_width_mm,
            test_piece_kerf_um: self.test_piece_kerf_um,
            label: self.label,
            cut: GaugeCut {
                at_mm: self.at_mm,
                settings: self.cut.settings()?,
                s_max: self.cut.s_max,
            },
        })
    }
}

/// Write the gauge described by `args`.
pub fn run(args: &GaugeArgs) -> Result<GaugeReport> {
    let (bytes, mut report) = draw(&args.request()?)?;
    report.output = Some(args.output.clone());
    kerfmeter_plan::ownership::ensure_replaceable(&args.output, args.force)?;
    write_atomically(&args.output, &bytes)?;
    Ok(report)
}

impl Report for GaugeReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
