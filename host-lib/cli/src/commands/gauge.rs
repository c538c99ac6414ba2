//! `kerfmeter gauge`: draw the spiral gauge to cut before a measurement (SVG, DXF or G-code by
//! the output's extension). The drawing and the G-code are `kerfmeter_plan`'s; this module turns
//! the arguments into their options, writes the file atomically and reports what it drew.
//!
//! As G-code the gauge is not dilated (the kerf is what it measures), its spiral centre is put at
//! `--at-mm` (default: the drawing's lower-left corner at the machine origin), and the cut-setting
//! flags are required: the kerf it measures depends on them, so it must be cut with the job's own
//! settings, and a silent default would measure another kerf than the job's. The refusal suggests
//! [`GAUGE_SETTINGS`] as a first try when no job settings exist yet.

use std::fmt;
use std::path::PathBuf;

use kerfmeter::files::write_atomically;
use kerfmeter_plan::gauge::{self, GaugeDrawing, GaugeOptions, TestPieceSpec};
use kerfmeter_plan::gcode::{DEFAULT_S_MAX, GcodeOptions, ProgramStats, Provenance, gauge_program};
use kerfmeter_plan::profile::CutSettings;
use kerfmeter_plan::{PlanError, PlanFormat};
use kerfmeter_protocol::{GaugeGeometry, JamDirection};
use serde::Serialize;

use super::gcode::{CutArgs, GCODE_EXTENSIONS, is_gcode, parse_xy};
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

type Result<T, E = CliError> = std::result::Result<T, E>;

/// A first try for cutting the gauge when no job settings exist yet (suggested, never used
/// silently): slow and at full power, one pass.
pub const GAUGE_SETTINGS: CutSettings = CutSettings {
    feed_mm_per_min: 300.0,
    power_percent: 100.0,
    passes: 1,
};

/// What `gauge` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GaugeFormat {
    /// SVG.
    Svg,
    /// DXF.
    Dxf,
    /// G-code for GRBL 1.1 laser mode.
    Gcode,
}

impl fmt::Display for GaugeFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            GaugeFormat::Svg => "SVG",
            GaugeFormat::Dxf => "DXF",
            GaugeFormat::Gcode => "G-code",
        })
    }
}

/// Sense in which the hub turns to close the gauge's gap, seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum JamDirectionArg {
    /// Clockwise.
    Cw,
    /// Counter-clockwise.
    Ccw,
}

impl From<JamDirectionArg> for JamDirection {
    fn from(d: JamDirectionArg) -> Self {
        match d {
            JamDirectionArg::Cw => JamDirection::Clockwise,
            JamDirectionArg::Ccw => JamDirection::CounterClockwise,
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
    /// The gauge geometry these arguments describe.
    pub fn geometry(&self) -> GaugeGeometry {
        GaugeGeometry {
            pitch_um_per_deg: self.pitch_um_per_deg,
            radius_mm: self.radius_mm,
            prong_radius_mm: self.prong_radius_mm,
            hole_radius_mm: self.hole_radius_mm,
            hole_distance_mm: self.hole_distance_mm,
            jam_direction: self.jam_direction.into(),
            disengage_deg: self.disengage_deg,
        }
    }

    fn options(&self) -> Result<GaugeOptions, PlanError> {
        let test_piece = match (self.test_piece, self.test_piece_kerf_um) {
            (false, None) => None,
            (false, Some(_)) => {
                return Err(PlanError::InvalidArgument(
                    "--test-piece-kerf-um is the kerf of the test piece, which is drawn only with --test-piece: add it, or leave the kerf out".into(),
                ));
            }
            (true, None) => {
                return Err(PlanError::InvalidArgument(
                    "--test-piece needs --test-piece-kerf-um (the kerf to dilate it by)".into(),
                ));
            }
            (true, Some(kerf_um)) => Some(TestPieceSpec {
                thickness_mm: self.thickness_mm,
                finger_width_mm: self.finger_width_mm,
                kerf_um,
            }),
        };
        Ok(GaugeOptions {
            test_piece,
            label: self.label,
        })
    }
}

/// What `gauge` wrote.
#[derive(Debug, Clone, Serialize)]
pub struct GaugeReport {
    /// The file written.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub output: PathBuf,
    /// Its format.
    pub format: GaugeFormat,
    /// Page size (width, height), mm.
    pub page_mm: [f64; 2],
    /// Spiral pitch, µm per degree.
    pub pitch_um_per_deg: f64,
    /// Spiral pitch c, mm per radian.
    pub pitch_mm_per_rad: f64,
    /// Spiral radius at φ = 0 (a), mm.
    pub start_radius_mm: f64,
    /// Spiral radius at φ = 2π (a + 2πc), mm; the radial step is the difference.
    pub end_radius_mm: f64,
    /// Arcs approximating the spiral.
    pub spiral_arcs: usize,
    /// Largest distance between the drawn spiral and the true one, µm.
    pub max_deviation_um: f64,
    /// Hole radius as drawn, mm.
    pub hole_radius_mm: f64,
    /// Hole centres' distance from the gauge centre, mm.
    pub hole_distance_mm: f64,
    /// Jam direction, seen from above.
    pub jam_direction: JamDirectionArg,
    /// The test piece, if added.
    pub test_piece: Option<TestPieceSpec>,
    /// Whether a label was engraved.
    pub label: bool,
    /// The G-code, when that was written.
    pub gcode: Option<GaugeGcode>,
}

/// The gauge's G-code: where and how it is cut.
#[derive(Debug, Clone, Serialize)]
pub struct GaugeGcode {
    /// The spiral centre on the machine, mm.
    pub at_mm: [f64; 2],
    /// How it is cut.
    pub settings: CutSettings,
    /// The S of full power ($30).
    pub s_max: f64,
    /// What the program cuts and travels.
    pub program: ProgramStats,
}

impl fmt::Display for GaugeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "wrote {} ({}, {:.1} × {:.1} mm)",
            self.output.display(),
            self.format,
            self.page_mm[0],
            self.page_mm[1]
        )?;
        writeln!(
            f,
            "spiral r(φ) = {:.4} + {:.6}·φ mm (c = {} µm/°), one turn closed by a radial step of {:.4} mm, as {} arcs within {:.3} µm",
            self.start_radius_mm,
            self.pitch_mm_per_rad,
            self.pitch_um_per_deg,
            self.end_radius_mm - self.start_radius_mm,
            self.spiral_arcs,
            self.max_deviation_um
        )?;
        let (sense, turn) = match self.jam_direction {
            JamDirectionArg::Cw => ("counter-clockwise", "clockwise"),
            JamDirectionArg::Ccw => ("clockwise", "counter-clockwise"),
        };
        writeln!(
            f,
            "holes r = {} mm at ±{} mm (φ = 0 and π); seen from above φ grows {sense}, the hub turns the inset {turn}",
            self.hole_radius_mm, self.hole_distance_mm
        )?;
        if let Some(t) = &self.test_piece {
            writeln!(
                f,
                "test piece: one-finger box joint, finger {} mm × {} mm, dilated by {} µm",
                t.finger_width_mm, t.thickness_mm, t.kerf_um
            )?;
        }
        if let Some(gc) = &self.gcode {
            writeln!(
                f,
                "G-code: spiral centre at ({:.3}, {:.3}) mm, {}, {} contours, {:.1} mm cut; needs GRBL $32=1, $30={}",
                gc.at_mm[0],
                gc.at_mm[1],
                gc.settings,
                gc.program.contours,
                gc.program.cut_mm,
                gc.s_max
            )?;
        }
        write!(
            f,
            "cut the red hairlines with the sheet's top face up; there is no outer cut"
        )
    }
}

/// An `f32` as the decimal it was written as (2.774, not 2.7739999294).
fn clean(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// Write the gauge described by `args`.
pub fn run(args: &GaugeArgs) -> Result<GaugeReport> {
    let (bytes, report) = draw(args)?;
    kerfmeter_plan::ownership::ensure_replaceable(&args.output, args.force)?;
    write_atomically(&args.output, &bytes)?;
    Ok(report)
}

/// Draw the gauge described by `args` in the format `args.output` names, without writing it:
/// the file's content and the report (`kerfmeter serve` sends the content to its client).
pub fn draw(args: &GaugeArgs) -> Result<(Vec<u8>, GaugeReport)> {
    let geometry = args.geometry();
    let options = args.options()?;
    let drawing = gauge::build(&geometry, &options)?;
    let (format, bytes, gcode) = if is_gcode(&args.output) {
        let (text, gcode) = gauge_gcode(args, &drawing)?;
        (GaugeFormat::Gcode, text.into_bytes(), Some(gcode))
    } else {
        if args.at_mm.is_some() || args.cut.settings()?.is_some() || args.cut.s_max != DEFAULT_S_MAX
        {
            return Err(PlanError::InvalidArgument(
                "--at-mm, --s-max and the cut settings are for G-code output (a .gcode file)"
                    .into(),
            )
            .into());
        }
        let format = PlanFormat::of(&args.output).map_err(|_| {
            PlanError::InvalidArgument(format!(
                "{}: the gauge's file name must end in .svg, .dxf or a G-code extension ({})",
                args.output.display(),
                GCODE_EXTENSIONS.map(|e| format!(".{e}")).join(", ")
            ))
        })?;
        match format {
            PlanFormat::Svg => (GaugeFormat::Svg, gauge::to_svg(&drawing).into_bytes(), None),
            PlanFormat::Dxf => (GaugeFormat::Dxf, gauge::to_dxf(&drawing)?, None),
        }
    };
    let arcs = drawing
        .spiral
        .vertex_data
        .iter()
        .filter(|v| v.bulge != 0.0)
        .count();
    let report = GaugeReport {
        output: args.output.clone(),
        format,
        page_mm: drawing.page_mm,
        pitch_um_per_deg: clean(geometry.pitch_um_per_deg),
        pitch_mm_per_rad: drawing.pitch_mm_per_rad,
        start_radius_mm: drawing.start_radius_mm,
        end_radius_mm: drawing.start_radius_mm + std::f64::consts::TAU * drawing.pitch_mm_per_rad,
        spiral_arcs: arcs,
        max_deviation_um: drawing.max_deviation_mm * 1e3,
        hole_radius_mm: clean(geometry.hole_radius_mm),
        hole_distance_mm: clean(geometry.hole_distance_mm),
        jam_direction: args.jam_direction,
        test_piece: options.test_piece,
        label: args.label,
        gcode,
    };
    Ok((bytes, report))
}

/// The gauge's G-code text, and what it cuts where.
fn gauge_gcode(args: &GaugeArgs, drawing: &GaugeDrawing) -> Result<(String, GaugeGcode)> {
    let Some(settings) = args.cut.settings()? else {
        return Err(PlanError::InvalidArgument(format!(
            "say how to cut the gauge: --feed-mm-per-min and --power-percent (and --passes) as the job will be cut, since the kerf it measures depends on them (a first try: --feed-mm-per-min {} --power-percent {})",
            GAUGE_SETTINGS.feed_mm_per_min, GAUGE_SETTINGS.power_percent
        ))
        .into());
    };
    let at_mm = args.at_mm.unwrap_or([drawing.center.x, drawing.center.y]);
    let options = GcodeOptions {
        s_max: args.cut.s_max,
        origin_mm: at_mm,
    };
    let g = &drawing.geometry;
    let provenance = Provenance {
        source: format!(
            "gauge, pitch {} um/deg, radius {} mm",
            clean(g.pitch_um_per_deg),
            clean(g.radius_mm)
        ),
        kerf: "none: the gauge measures it".into(),
    };
    let (program, _) = gauge_program(drawing, &settings, &options, &provenance)?;
    let gcode = GaugeGcode {
        at_mm,
        settings,
        s_max: options.s_max,
        program: program.stats(),
    };
    Ok((program.to_text(), gcode))
}

impl Report for GaugeReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
