//! `kerfmeter dilate`: dilate a cutting plan (SVG or DXF) by the measured kerf, uniformly or per
//! part from a kerf map, or set a LightBurn project's Kerf Offset (the [`lightburn`] module). The
//! plan work is `kerfmeter_plan`'s; this module turns the arguments into its options and writes
//! the output atomically, never over the input.

use std::fmt;
use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
pub use kerfmeter_app::dilate::DilateReport;
use kerfmeter_app::dilate::{DilateFileRequest, Dilation, dilate_file, if_compensated};
use kerfmeter_lightburn::project::is_project_path;
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::outcome::AssumedUnits;
use serde::Serialize;

use super::lightburn::{self, LightBurnReport};
use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::progress::plan_progress;

type Result<T, E = CliError> = std::result::Result<T, E>;

/// `--units`: the names of [`AssumedUnits`], each with its description in `--help`.
pub fn units_parser() -> impl TypedValueParser<Value = AssumedUnits> {
    PossibleValuesParser::new(
        AssumedUnits::ALL.map(|u| PossibleValue::new(u.name()).help(u.describe())),
    )
    .map(|name| name.parse().expect("clap only passes the names listed"))
}

/// `kerfmeter dilate`: offset every closed cut of a plan by half the kerf.
#[derive(Debug, Clone, clap::Args)]
pub struct DilateArgs {
    /// The plan to dilate: an .svg or .dxf file, or a LightBurn project (.lbrn2, .lbrn), whose
    /// Line layers get a Kerf Offset of half the kerf instead.
    #[arg(value_name = "IN")]
    pub input: PathBuf,
    /// Output file, same format as the input (never the input itself).
    #[arg(short, long, value_name = "OUT", required_unless_present = "dry_run")]
    pub output: Option<PathBuf>,
    /// Make open cut paths (which cannot be dilated) an error instead of a warning.
    #[arg(long)]
    pub strict: bool,
    /// Report what would change; write nothing.
    #[arg(long)]
    pub dry_run: bool,
    /// Replace the output even if it exists and kerfmeter did not write it (by default only
    /// kerfmeter's own outputs are replaced: a typo must not replace a cutting plan).
    #[arg(long)]
    pub force: bool,
    /// LightBurn projects: set only these layers, each by index (0, 1, …) or name (repeat or
    /// separate by commas; a value that is a whole layer's name is not split) [default: every
    /// Line layer].
    #[arg(long = "layers", value_name = "LAYER")]
    pub layers: Vec<String>,
    /// The kerf, the cut rules and what to do with a compensated plan.
    #[command(flatten)]
    pub dilation: DilationArgs,
}

/// How to dilate a plan: the options `dilate` and `gcode` share.
#[derive(Debug, Clone, clap::Args)]
pub struct DilationArgs {
    /// Kerf (full cut width), µm; every cut moves by half of it. With --map: the kerf measured
    /// at the map's reference cell.
    #[arg(long)]
    pub kerf_um: f64,
    /// Kerf map (JSON from the map command): each part uses the kerf at its centroid.
    #[arg(long, value_name = "MAP.json")]
    pub map: Option<PathBuf>,
    /// Colours that mean "cut": CSS syntax (`#808080`, `rgb(255,0,0)`, names) or an ACI number
    /// 1–255, compared by colour both ways in DXF; repeat or separate by commas [default: red,
    /// blue, black].
    #[arg(long = "cut-color", value_name = "COLOR")]
    pub cut_colors: Vec<String>,
    /// Widest stroke (SVG) or lineweight (DXF) that is still a cut line, mm.
    #[arg(long, default_value_t = 0.3)]
    pub cut_max_width_mm: f64,
    /// DXF: the entities on these layers are the cuts (instead of the colour rules; repeat or
    /// separate by commas; a layer's whole name with a comma in it matches too).
    #[arg(long = "cut-layer", value_name = "LAYER")]
    pub cut_layers: Vec<String>,
    /// What one drawing unit is, for files that do not say (unitless SVG, DXF without $INSUNITS).
    #[arg(long, value_parser = units_parser())]
    pub units: Option<AssumedUnits>,
    /// A plan that says it is already compensated (a boxes.py --burn, or this tool's own output)
    /// is refused; dilate it by the full kerf on top anyway.
    #[arg(long, conflicts_with = "recompensate")]
    pub already_compensated_ok: bool,
    /// Undo the compensation the plan records (boxes.py's burn, this tool's earlier offset) and
    /// apply the kerf instead: each cut moves by kerf/2 − burn, inner corners kept sharp.
    #[arg(long)]
    pub recompensate: bool,
}

impl DilationArgs {
    /// The dilation these flags ask for.
    pub fn dilation(&self) -> Dilation {
        Dilation {
            kerf_um: self.kerf_um,
            map: self.map.clone(),
            cut_colors: self.cut_colors.clone(),
            cut_max_width_mm: self.cut_max_width_mm,
            cut_layers: self.cut_layers.clone(),
            units: self.units,
            if_compensated: self.if_compensated(),
        }
    }

    /// What to do with a plan already compensated, from the flags.
    pub fn if_compensated(&self) -> IfCompensated {
        if_compensated(self.recompensate, self.already_compensated_ok)
    }
}

/// What `dilate` reports: a dilated plan, or a LightBurn project whose Kerf Offset was set.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum DilateOutcome {
    /// An SVG or DXF plan.
    Plan(Box<DilateReport>),
    /// A LightBurn project.
    LightBurn(Box<LightBurnReport>),
}

impl fmt::Display for DilateOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DilateOutcome::Plan(r) => r.fmt(f),
            DilateOutcome::LightBurn(r) => r.fmt(f),
        }
    }
}

impl Report for DilateOutcome {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

/// Dilate the plan named by `args` (see [`DilateArgs`]), or set a LightBurn project's Kerf
/// Offset (the same arguments, the same never-over-the-input atomic write).
pub fn run(g: &Global, args: &DilateArgs) -> Result<DilateOutcome> {
    if is_project_path(&args.input) {
        return lightburn::run_offline(args).map(|r| DilateOutcome::LightBurn(Box::new(r)));
    }
    if !args.layers.is_empty() {
        return Err(CliError::Usage(
            "--layers chooses the layers of a LightBurn project; for a DXF's layers use --cut-layer"
                .into(),
        ));
    }
    plan(g, args).map(|r| DilateOutcome::Plan(Box::new(r)))
}

/// Dilate an SVG or DXF plan, with a progress bar on a terminal (not with `--json`).
fn plan(g: &Global, args: &DilateArgs) -> Result<DilateReport> {
    let request = DilateFileRequest {
        input: args.input.clone(),
        output: args.output.clone(),
        dry_run: args.dry_run,
        strict: args.strict,
        force: args.force,
        dilation: args.dilation.dilation(),
    };
    let (progress, bar) = plan_progress(g.json);
    let dilated = dilate_file(&request, progress);
    bar.finish_and_clear();
    Ok(dilated?)
}
