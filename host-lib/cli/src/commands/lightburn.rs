//! LightBurn: `kerfmeter dilate project.lbrn2 --kerf-um K -o out.lbrn2` sets the Kerf Offset of
//! the project's Line layers (the plan library's `lightburn` module does the work and documents
//! LightBurn's convention: half the kerf, mm, positive outward); this module checks the arguments
//! that apply to a project, writes the output atomically (never over the input) and reports.

use std::fmt;
use std::path::PathBuf;

use kerfmeter::files::{ensure_not_input, write_atomically};
use kerfmeter_plan::PlanError;
use kerfmeter_plan::lightburn::{
    LightBurnOptions, LightBurnSummary, format_mm, is_project_path, set_kerf_offset_file,
};
use serde::Serialize;

use super::dilate::DilateArgs;
use crate::error::CliError;

type Result<T, E = CliError> = std::result::Result<T, E>;

/// What `dilate` did to a LightBurn project (or, with `--dry-run`, would do).
#[derive(Debug, Clone, Serialize)]
pub struct LightBurnReport {
    /// The project read.
    pub input: PathBuf,
    /// The project written (`None` on a dry run).
    pub output: Option<PathBuf>,
    /// True when nothing was written.
    pub dry_run: bool,
    /// Always `lightburn`.
    pub format: &'static str,
    /// What was found and done.
    #[serde(flatten)]
    pub summary: LightBurnSummary,
}

/// The options of `dilate` that mean nothing for a LightBurn project, if any were given.
fn refuse_plan_only_options(args: &DilateArgs) -> Result<()> {
    let d = &args.dilation;
    let given: Vec<&str> = [
        (d.map.is_some(), "--map"),
        (!d.cut_colors.is_empty(), "--cut-color"),
        (!d.cut_layers.is_empty(), "--cut-layer (use --layers)"),
        (d.units.is_some(), "--units"),
        (args.strict, "--strict"),
    ]
    .into_iter()
    .filter_map(|(on, name)| on.then_some(name))
    .collect();
    if given.is_empty() {
        return Ok(());
    }
    Err(CliError::Usage(format!(
        "{} do{} not apply to a LightBurn project: LightBurn applies one Kerf Offset per layer to its shapes",
        given.join(", "),
        if given.len() == 1 { "es" } else { "" }
    )))
}

/// Set the Kerf Offset of the LightBurn project `args.input` (see the module doc).
pub fn run_offline(args: &DilateArgs) -> Result<LightBurnReport> {
    refuse_plan_only_options(args)?;
    if let Some(out) = &args.output {
        if !is_project_path(out) {
            return Err(PlanError::InvalidArgument(format!(
                "the output {} must be a LightBurn project too (.lbrn2 or .lbrn)",
                out.display()
            ))
            .into());
        }
        ensure_not_input(&args.input, out)?;
    }
    let options = LightBurnOptions {
        layers: args.layers.clone(),
        if_compensated: args.dilation.if_compensated(),
    };
    let (bytes, summary) = set_kerf_offset_file(&args.input, args.dilation.kerf_um, &options)?;
    let output = if args.dry_run {
        None
    } else {
        args.output.clone()
    };
    if let Some(out) = &output {
        write_atomically(out, &bytes)?;
    }
    Ok(LightBurnReport {
        input: args.input.clone(),
        output,
        dry_run: args.dry_run,
        format: "lightburn",
        summary,
    })
}

impl fmt::Display for LightBurnReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.summary;
        match &self.output {
            Some(out) => write!(f, "set {} → {}", self.input.display(), out.display())?,
            None => write!(f, "dry run, nothing written: {}", self.input.display())?,
        }
        writeln!(
            f,
            " (LightBurn project) for a kerf of {} µm: Kerf Offset {} mm (half the kerf, positive = outward, LightBurn's convention)",
            s.kerf_um,
            format_mm(s.kerf_offset_mm)
        )?;
        for l in &s.layers {
            write!(f, "  layer {} \"{}\" ({}): ", l.index, l.name, l.mode)?;
            match &l.left_alone {
                Some(why) => writeln!(f, "left alone, {why}")?,
                None => writeln!(f, "{}", passes(l))?,
            }
        }
        if let Some(found) = &s.compensation_found {
            writeln!(f, "  found: {found}")?;
            let what = match s.compensation_applied.action.as_str() {
                "recompensate" => "replaced by this kerf's (--recompensate)",
                _ => "kept, this kerf's added on top (--already-compensated-ok)",
            };
            writeln!(f, "  compensation: {what}")?;
        }
        Ok(())
    }
}

/// The passes of a layer that were set, in words.
fn passes(l: &kerfmeter_plan::lightburn::LayerOutcome) -> String {
    let each: Vec<String> = l
        .set
        .iter()
        .map(|p| {
            let whose = match p.sub_layer {
                None => "line pass".to_string(),
                Some(i) => format!("line sub-layer {i}"),
            };
            match p.before_mm {
                Some(b) => format!("{whose} {} → {} mm", format_mm(b), format_mm(p.after_mm)),
                None => format!("{whose} (none) → {} mm", format_mm(p.after_mm)),
            }
        })
        .collect();
    format!(
        "{} pass{} set: {}",
        l.set.len(),
        if l.set.len() == 1 { "" } else { "es" },
        each.join(", ")
    )
}
