//! `kerfmeter dilate`: dilate a cutting plan (SVG or DXF) by the measured kerf, uniformly or per
//! part from a kerf map, or set a LightBurn project's Kerf Offset (the [`lightburn`] module). The
//! plan work is `kerfmeter_plan`'s; this module turns the arguments into its options and writes
//! the output atomically, never over the input.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use kerfmeter::files::{ensure_not_input, write_atomically_with};
use kerfmeter::map::KerfMap;
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::lightburn::is_project_path;
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::progress::Progress;
use kerfmeter_plan::rules::CutRules;
use kerfmeter_plan::{DilateOptions, PlanError, PlanFormat, dilate_file_into};
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
    /// Colours that mean "cut" (CSS syntax, `rgb(255,0,0)` too; repeat or separate by commas)
    /// [default: red, blue, black].
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
    /// The kerf, checked: uniform, or from the kerf map.
    pub fn kerf(&self) -> Result<(f64, KerfSource)> {
        let kerf_um = KerfSource::check_kerf_um(self.kerf_um)?;
        let kerf = match &self.map {
            None => KerfSource::Uniform(kerf_um),
            Some(path) => {
                let map = KerfMap::load(path)?;
                KerfSource::Map(Arc::new(move |x_mm, y_mm| {
                    map.kerf_at_um(kerf_um, x_mm, y_mm)
                }))
            }
        };
        Ok((kerf_um, kerf))
    }

    /// The plan library's options, reporting to `progress`.
    pub fn options(&self, strict: bool, progress: Progress) -> Result<DilateOptions> {
        Ok(DilateOptions {
            rules: CutRules::new(&self.cut_colors, self.cut_max_width_mm, &self.cut_layers)?,
            assume_units: self.units,
            strict,
            if_compensated: self.if_compensated(),
            progress,
        })
    }

    /// What to do with a plan already compensated, from the flags.
    pub fn if_compensated(&self) -> IfCompensated {
        if self.recompensate {
            IfCompensated::Recompensate
        } else if self.already_compensated_ok {
            IfCompensated::DilateAnyway
        } else {
            IfCompensated::Refuse
        }
    }
}

/// What `dilate` did (or, with `--dry-run`, would do).
#[derive(Debug, Clone, Serialize)]
pub struct DilateReport {
    /// The plan read.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub input: PathBuf,
    /// The file written (`None` on a dry run).
    #[serde(serialize_with = "crate::output::lossy_path::option")]
    pub output: Option<PathBuf>,
    /// True when nothing was written.
    pub dry_run: bool,
    /// The file format (for the text; the JSON has the summary's `format`, one key).
    #[serde(skip)]
    pub format: PlanFormat,
    /// The kerf given, µm (with a map: at the reference cell).
    pub kerf_um: f64,
    /// The kerf map used.
    #[serde(serialize_with = "crate::output::lossy_path::option")]
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
        // With a map each part has its own kerf: the headline names the map's reference.
        let by = match &self.map {
            Some(_) => format!(
                "by the kerf map ({} µm at its reference cell; each cut moved half its part's kerf)",
                self.kerf_um
            ),
            None => format!(
                "by {} µm (each cut moved {} µm)",
                self.kerf_um,
                moved_um(s, self.kerf_um)
            ),
        };
        match (&self.output, self.dry_run) {
            (Some(out), false) => writeln!(
                f,
                "dilated {} → {} ({}) {by}",
                self.input.display(),
                out.display(),
                self.format,
            )?,
            _ => writeln!(
                f,
                "dry run, nothing written: {} ({}) {by}",
                self.input.display(),
                self.format,
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
        write_open_paths(f, s)?;
        write_compensation(f, s)?;
        for n in &s.notes {
            writeln!(f, "  note: {n}")?;
        }
        Ok(())
    }
}

/// The warning about open cut paths, which stay as drawn (nothing when there are none).
fn write_open_paths(f: &mut fmt::Formatter<'_>, s: &PlanSummary) -> fmt::Result {
    if s.open_paths.is_empty() {
        return Ok(());
    }
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
    Ok(())
}

/// How far the cuts moved, µm, as text: the net offset applied (with `--recompensate`, the
/// kerf's half less the burn undone), else the kerf's half.
fn moved_um(s: &PlanSummary, kerf_um: f64) -> String {
    s.compensation_applied.as_ref().map_or_else(
        || (kerf_um / 2.0).to_string(),
        |a| a.net_offset_um.to_string(),
    )
}

/// What compensation was found and what was applied (nothing when none was found).
pub(crate) fn write_compensation(f: &mut fmt::Formatter<'_>, s: &PlanSummary) -> fmt::Result {
    let (Some(found), Some(applied)) = (&s.compensation_found, &s.compensation_applied) else {
        return Ok(());
    };
    writeln!(f, "  found: {}", found.describe())?;
    let what = match applied.action.as_str() {
        "recompensate" => "undone and replaced by the kerf (--recompensate)",
        "dilate_anyway" => "kept, the kerf added on top (--already-compensated-ok)",
        _ => "none (not a compensation)",
    };
    writeln!(
        f,
        "  compensation: {what}; cuts moved {} µm, now {} µm outside the parts{}",
        applied.net_offset_um,
        applied.offset_um,
        if applied.corner_loops_removed > 0 {
            format!(
                "; {} loop{} at inner corners removed",
                applied.corner_loops_removed,
                plural(applied.corner_loops_removed)
            )
        } else {
            String::new()
        }
    )
}

/// "s" unless `n` is 1.
pub(crate) fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
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

/// The format a plan's dilation is written in: `input`'s, which `output` must share (by its
/// extension), `output` never being `input` itself. The one check of a dilated plan's output
/// path, for `dilate` and `job`.
pub(crate) fn plan_output_format(input: &Path, output: &Path) -> Result<PlanFormat> {
    let format = PlanFormat::of(input)?;
    if PlanFormat::of(output)? != format {
        return Err(PlanError::InvalidArgument(format!(
            "the output {} must have the input's format ({format})",
            output.display()
        ))
        .into());
    }
    ensure_not_input(input, output)?;
    Ok(format)
}

/// Dilate an SVG or DXF plan, with a progress bar on a terminal (not with `--json`).
fn plan(g: &Global, args: &DilateArgs) -> Result<DilateReport> {
    let format = PlanFormat::of(&args.input)?;
    if let Some(out) = &args.output {
        plan_output_format(&args.input, out)?;
        if !args.dry_run {
            kerfmeter_plan::ownership::ensure_replaceable(out, args.force)?;
        }
    }
    let (kerf_um, kerf) = args.dilation.kerf()?;
    let (progress, bar) = plan_progress(g.json);
    let options = args.dilation.options(args.strict, progress)?;
    // The dilated plan is written into the temporary output file as it is made (never held whole:
    // a dilated SVG is several times its source), and kept only if all went well.
    let dilated = match &args.output {
        Some(out) if !args.dry_run => write_atomically_with(out, |w| {
            dilate_file_into(&args.input, &kerf, &options, out, w).map_err(CliError::from)
        }),
        _ => dilate_file_into(
            &args.input,
            &kerf,
            &options,
            Path::new("(none)"),
            &mut std::io::sink(),
        )
        .map_err(CliError::from),
    };
    bar.finish_and_clear();
    let summary = dilated?;
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
        map: args.dilation.map.clone(),
        cut_rules: options.rules.describe(),
        summary,
    })
}
