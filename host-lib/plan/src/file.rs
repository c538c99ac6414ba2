//! Plan files: the format a file name says, and dilating a plan read from disk into the bytes of
//! the dilated plan. Writing those bytes is the caller's (the CLI writes them atomically and never
//! over the input).

use std::fmt;
use std::path::Path;

use serde::Serialize;

use crate::compensation::IfCompensated;
use crate::dilate::KerfSource;
use crate::dxf_plan::{DxfOptions, dilate_dxf};
use crate::error::{PlanError, Result};
use crate::outcome::{AssumedUnits, PlanSummary};
use crate::progress::Progress;
use crate::rules::CutRules;
use crate::svg::{SvgOptions, dilate_svg};

/// Plan file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PlanFormat {
    /// SVG.
    Svg,
    /// DXF.
    Dxf,
}

impl PlanFormat {
    /// The format a path's extension names.
    pub fn of(path: &Path) -> Result<PlanFormat> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("svg") => Ok(PlanFormat::Svg),
            Some("dxf") => Ok(PlanFormat::Dxf),
            _ => Err(PlanError::InvalidArgument(format!(
                "{}: the file name must end in .svg or .dxf",
                path.display()
            ))),
        }
    }
}

impl fmt::Display for PlanFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PlanFormat::Svg => "SVG",
            PlanFormat::Dxf => "DXF",
        })
    }
}

/// How to dilate a plan file.
#[derive(Debug, Clone, Default)]
pub struct DilateOptions {
    /// Which lines are cuts.
    pub rules: CutRules,
    /// What one drawing unit is, for files that do not say.
    pub assume_units: Option<AssumedUnits>,
    /// Refuse open cut paths (which cannot be dilated) instead of leaving them as drawn.
    pub strict: bool,
    /// What to do when the plan is already compensated (boxes.py's burn, this tool's output).
    pub if_compensated: IfCompensated,
    /// Where to tell how far the work has got (nowhere by default).
    pub progress: Progress,
}

/// Read the plan at `input` (SVG or DXF, by its extension) and dilate it by `kerf`: the dilated
/// plan in the same format, and what was found and done. Every error about the file's content
/// names the file.
pub fn dilate_file(
    input: &Path,
    kerf: &KerfSource,
    options: &DilateOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    let format = PlanFormat::of(input)?;
    let bytes = std::fs::read(input).map_err(|source| PlanError::Io {
        path: input.to_owned(),
        source,
    })?;
    let (output, summary) = match format {
        PlanFormat::Svg => dilate_svg_bytes(bytes, kerf, options),
        PlanFormat::Dxf => dilate_dxf(
            &bytes,
            kerf,
            &DxfOptions {
                rules: options.rules.clone(),
                assume_units: options.assume_units,
                if_compensated: options.if_compensated,
                progress: options.progress.clone(),
            },
        ),
    }
    .map_err(|e| e.in_file(input))?;
    if options.strict {
        refuse_open_paths(&summary).map_err(|e| e.in_file(input))?;
    }
    Ok((output, summary))
}

/// The `--strict` policy: open cut paths cannot be dilated, so a plan with any is refused.
fn refuse_open_paths(summary: &PlanSummary) -> Result<()> {
    if summary.open_paths.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = summary.open_paths.iter().map(|o| o.to_string()).collect();
    Err(PlanError::OpenPaths(format!(
        "{} open cut path(s) cannot be dilated (--strict; nothing was written):\n  - {}",
        list.len(),
        list.join("\n  - ")
    )))
}

/// An SVG file's bytes, dilated: refuses compressed SVG and text that is not UTF-8.
fn dilate_svg_bytes(
    bytes: Vec<u8>,
    kerf: &KerfSource,
    options: &DilateOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    if bytes.starts_with(&[0x1f, 0x8b]) {
        return Err(PlanError::Svg(
            "a compressed SVG (.svgz) is not supported; save it uncompressed".into(),
        ));
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| PlanError::Svg("not a readable SVG file (not UTF-8 text)".into()))?;
    let svg_options = SvgOptions {
        rules: options.rules.clone(),
        assume_units: options.assume_units,
        if_compensated: options.if_compensated,
        progress: options.progress.clone(),
    };
    let (out, summary) = dilate_svg(&text, kerf, &svg_options)?;
    Ok((out.into_bytes(), summary))
}
