//! A plan file dilated into a file: the CLI's `dilate` and Python's `dilate()`. The output is
//! written atomically, never over the input, and replaces only kerfmeter's own files unless
//! forced.

use std::path::{Path, PathBuf};

use kerfmeter::files::{ensure_not_input, write_atomically_with};
use kerfmeter_plan::progress::Progress;
use kerfmeter_plan::{PlanError, PlanFormat, dilate_file_into};

use super::{DilateReport, Dilation};
use crate::Error;

/// Dilate the plan file `input` into `output`.
#[derive(Debug, Clone)]
pub struct DilateFileRequest {
    /// The plan (.svg or .dxf).
    pub input: PathBuf,
    /// The output, of the input's format (`None`, or ignored, on a dry run).
    pub output: Option<PathBuf>,
    /// Report what would change; write nothing.
    pub dry_run: bool,
    /// Make open cut paths (which cannot be dilated) an error instead of a warning.
    pub strict: bool,
    /// Replace the output even if kerfmeter did not write it.
    pub force: bool,
    /// The kerf and the rules.
    pub dilation: Dilation,
}

/// The format a plan's dilation is written in: `input`'s, which `output` must share (by its
/// extension), `output` never being `input` itself. The one check of a dilated plan's output
/// path, for `dilate` and a job.
pub fn plan_output_format(input: &Path, output: &Path) -> Result<PlanFormat, Error> {
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

/// Dilate as `req` says, reporting to `progress`.
pub fn dilate_file(req: &DilateFileRequest, progress: Progress) -> Result<DilateReport, Error> {
    let format = PlanFormat::of(&req.input)?;
    if let Some(out) = &req.output {
        plan_output_format(&req.input, out)?;
        if !req.dry_run {
            kerfmeter_plan::ownership::ensure_replaceable(out, req.force)?;
        }
    }
    let (kerf_um, kerf) = req.dilation.kerf()?;
    let options = req.dilation.options(req.strict, progress)?;
    // The dilated plan is written into the temporary output file as it is made (never held whole:
    // a dilated SVG is several times its source), and kept only if all went well.
    let summary = match &req.output {
        Some(out) if !req.dry_run => write_atomically_with(out, |w| {
            dilate_file_into(&req.input, &kerf, &options, out, w).map_err(Error::from)
        })?,
        _ => dilate_file_into(
            &req.input,
            &kerf,
            &options,
            Path::new("(none)"),
            &mut std::io::sink(),
        )?,
    };
    Ok(DilateReport {
        input: req.input.clone(),
        output: if req.dry_run {
            None
        } else {
            req.output.clone()
        },
        dry_run: req.dry_run,
        format,
        kerf_um,
        map: req.dilation.map.clone(),
        cut_rules: options.rules.describe(),
        summary,
    })
}
