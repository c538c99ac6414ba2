//! The `gauge` and `dilate` commands: their arguments (clap), entry points and reports (text via
//! `Display`, JSON via `serde`). The plan work itself is `kerfmeter_plan`'s; this module turns
//! arguments into its options and writes the output files (atomically, never over the input).

use std::fmt;
use std::path::PathBuf;
use std::sync::Arc;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use kerfmeter::files::{ensure_not_input, write_atomically};
use kerfmeter::map::KerfMap;
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::gauge::{self, GaugeOptions, TestPieceSpec};
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::rules::CutRules;
use kerfmeter_plan::{DilateOptions, PlanError, PlanFormat, dilate_file};
use kerfmeter_protocol::{GaugeGeometry, JamDirection};
use serde::Serialize;

use crate::CliError;

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

impl From<JamDirectionArg> for JamDirection {
    fn from(d: JamDirectionArg) -> Self {
        match d {
            JamDirectionArg::Cw => JamDirection::Clockwise,
            JamDirectionArg::Ccw => JamDirection::CounterClockwise,
        }
    }
}

/// `--units`: the names of [`AssumedUnits`], each with its description in `--help`.
fn units_parser() -> impl TypedValueParser<Value = AssumedUnits> {
    PossibleValuesParser::new(
        AssumedUnits::ALL.map(|u| PossibleValue::new(u.name()).help(u.describe())),
    )
    .map(|name| name.parse().expect("clap only passes the names listed"))
}

/// `kerfmeter gauge`: write the spiral gauge to cut.
#[derive(Debug, Clone, clap::Args)]
pub struct GaugeArgs {
    /// Output file: .svg or .dxf.
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
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
    #[arg(long, default_value_t = 4.0)]
    pub thickness_mm: f64,
    /// Finger (and slot) width of the test piece, mm.
    #[arg(long, default_value_t = 6.3)]
    pub finger_width_mm: f64,
    /// Kerf to dilate the test piece by, µm.
    #[arg(long)]
    pub test_piece_kerf_um: Option<f64>,
    /// Add an engraved label naming the geometry and the jam direction.
    #[arg(long)]
    pub label: bool,
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
            (false, _) => None,
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
    pub output: PathBuf,
    /// Its format.
    pub format: PlanFormat,
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
pub fn run_gauge(args: &GaugeArgs) -> Result<GaugeReport> {
    let format = PlanFormat::of(&args.output)?;
    let geometry = args.geometry();
    let drawing = gauge::build(&geometry, &args.options()?)?;
    let bytes = match format {
        PlanFormat::Svg => gauge::to_svg(&drawing).into_bytes(),
        PlanFormat::Dxf => gauge::to_dxf(&drawing)?,
    };
    write_atomically(&args.output, &bytes)?;
    let arcs = drawing
        .spiral
        .vertex_data
        .iter()
        .filter(|v| v.bulge != 0.0)
        .count();
    Ok(GaugeReport {
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
        test_piece: args.options()?.test_piece,
        label: args.label,
    })
}

/// `kerfmeter dilate`: offset every closed cut of a plan by half the kerf.
#[derive(Debug, Clone, clap::Args)]
pub struct DilateArgs {
    /// The plan to dilate: an .svg or .dxf file.
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// Kerf (full cut width), µm; every cut moves by half of it. With --map: the kerf measured
    /// at the map's reference cell.
    #[arg(long)]
    pub kerf_um: f64,
    /// Kerf map (JSON from the map command): each part uses the kerf at its centroid.
    #[arg(long, value_name = "MAP.json")]
    pub map: Option<PathBuf>,
    /// Output file, same format as the input (never the input itself).
    #[arg(short, long, value_name = "OUT", required_unless_present = "dry_run")]
    pub output: Option<PathBuf>,
    /// Make open cut paths (which cannot be dilated) an error instead of a warning.
    #[arg(long)]
    pub strict: bool,
    /// Report what would change; write nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// Colours that mean "cut" (CSS syntax; repeat or separate by commas) [default: red, blue,
    /// black].
    #[arg(long = "cut-color", value_name = "COLOR", value_delimiter = ',')]
    pub cut_colors: Vec<String>,
    /// Widest stroke (SVG) or lineweight (DXF) that is still a cut line, mm.
    #[arg(long, default_value_t = 0.3)]
    pub cut_max_width_mm: f64,
    /// DXF: the entities on these layers are the cuts (instead of the colour rules).
    #[arg(long = "cut-layer", value_name = "LAYER", value_delimiter = ',')]
    pub cut_layers: Vec<String>,
    /// What one drawing unit is, for files that do not say (unitless SVG, DXF without $INSUNITS).
    #[arg(long, value_parser = units_parser())]
    pub units: Option<AssumedUnits>,
}

/// What `dilate` did (or, with `--dry-run`, would do).
#[derive(Debug, Clone, Serialize)]
pub struct DilateReport {
    /// The plan read.
    pub input: PathBuf,
    /// The file written (`None` on a dry run).
    pub output: Option<PathBuf>,
    /// True when nothing was written.
    pub dry_run: bool,
    /// The file format.
    pub format: PlanFormat,
    /// The kerf given, µm (with a map: at the reference cell).
    pub kerf_um: f64,
    /// The kerf map used.
    pub map: Option<PathBuf>,
    /// The cut rules, in words.
    pub cut_rules: String,
    /// What was found and done.
    #[serde(flatten)]
    pub summary: PlanSummary,
}

impl fmt::Display for DilateReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.summary;
        match (&self.output, self.dry_run) {
            (Some(out), false) => writeln!(
                f,
                "dilated {} → {} ({}) by {} µm (each cut moved {} µm)",
                self.input.display(),
                out.display(),
                self.format,
                self.kerf_um,
                self.kerf_um / 2.0
            )?,
            _ => writeln!(
                f,
                "dry run, nothing written: {} ({}) by {} µm",
                self.input.display(),
                self.format,
                self.kerf_um
            )?,
        }
        writeln!(
            f,
            "  {} closed contour{} in {} part{} ({} hole{}, {} island{}) from {} cut element{}; {} element{} rewritten",
            s.contours_dilated,
            plural(s.contours_dilated),
            s.parts,
            plural(s.parts),
            s.holes,
            plural(s.holes),
            s.islands,
            plural(s.islands),
            s.cut_elements,
            plural(s.cut_elements),
            s.changed_elements,
            plural(s.changed_elements)
        )?;
        if let (Some(map), Some([lo, hi])) = (&self.map, s.kerf_range_um) {
            writeln!(
                f,
                "  kerf per part {lo:.1}–{hi:.1} µm from the map {}",
                map.display()
            )?;
        }
        writeln!(f, "  cut rules: {}", self.cut_rules)?;
        if s.passed_through.is_empty() {
            writeln!(f, "  passed through untouched: nothing")?;
        } else {
            let list: Vec<String> = s
                .passed_through
                .iter()
                .map(|(reason, n)| format!("{n} × {reason}"))
                .collect();
            writeln!(f, "  passed through untouched: {}", list.join(", "))?;
        }
        if !s.open_paths.is_empty() {
            writeln!(
                f,
                "  warning: {} open cut path{} cannot be dilated and {} left as drawn:",
                s.open_paths.len(),
                plural(s.open_paths.len()),
                if s.open_paths.len() == 1 {
                    "was"
                } else {
                    "were"
                }
            )?;
            for o in &s.open_paths {
                writeln!(f, "    - {o}")?;
            }
        }
        for n in &s.notes {
            writeln!(f, "  note: {n}")?;
        }
        Ok(())
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// Dilate the plan named by `args` (see [`DilateArgs`]).
pub fn run_dilate(args: &DilateArgs) -> Result<DilateReport> {
    let format = PlanFormat::of(&args.input)?;
    if let Some(out) = &args.output {
        let out_format = PlanFormat::of(out)?;
        if out_format != format {
            return Err(PlanError::InvalidArgument(format!(
                "the output {} must have the input's format ({format})",
                out.display()
            ))
            .into());
        }
        ensure_not_input(&args.input, out)?;
    }
    let kerf_um = KerfSource::check_kerf_um(args.kerf_um)?;
    let kerf = match &args.map {
        None => KerfSource::Uniform(kerf_um),
        Some(path) => {
            let map = KerfMap::load(path)?;
            KerfSource::Map(Arc::new(move |x_mm, y_mm| {
                map.kerf_at_um(kerf_um, x_mm, y_mm)
            }))
        }
    };
    let options = DilateOptions {
        rules: CutRules::new(&args.cut_colors, args.cut_max_width_mm, &args.cut_layers)?,
        assume_units: args.units,
        strict: args.strict,
    };
    let (output, summary) = dilate_file(&args.input, &kerf, &options)?;
    if !args.dry_run
        && let Some(out) = &args.output
    {
        write_atomically(out, &output)?;
    }
    Ok(DilateReport {
        input: args.input.clone(),
        output: if args.dry_run {
            None
        } else {
            args.output.clone()
        },
        dry_run: args.dry_run,
        format,
        kerf_um,
        map: args.map.clone(),
        cut_rules: options.rules.describe(),
        summary,
    })
}
