//! Plan files: the format a file name says, and dilating a plan read from disk into the bytes of
//! the dilated plan ([`dilate_file`]), into a writer as it is made ([`dilate_file_into`]: what the
//! CLI uses, so a large plan's output is never held whole) or into its dilated cuts
//! ([`dilate_file_cuts`], for G-code).
//! Writing the output is the caller's (the CLI writes it atomically and never over the input).

use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::compensation::IfCompensated;
use crate::dilate::KerfSource;
use crate::dxf_plan::{DxfOptions, dilate_dxf_cuts, dilate_dxf_owned};
use crate::error::{PlanError, Result};
use crate::outcome::{AssumedUnits, CutPath, PlanSummary};
use crate::progress::Progress;
use crate::rules::CutRules;
use crate::source_file::read_plan_file;
use crate::svg::{SvgOptions, dilate_svg_cuts, dilate_svg_file_into, dilate_svg_into};

/// Plan file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
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
    let (format, bytes) = read_plan(input)?;
    dilate_bytes(bytes, format, kerf, options).map_err(|e| e.in_file(input))
}

/// Dilate a plan held in memory (`bytes`, in `format`), like [`dilate_file`]: for plans that
/// come from no file (the server's clients send them as text).
pub fn dilate_bytes(
    bytes: Vec<u8>,
    format: PlanFormat,
    kerf: &KerfSource,
    options: &DilateOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    let (output, summary) = match format {
        PlanFormat::Svg => dilate_svg_bytes(bytes, kerf, options),
        PlanFormat::Dxf => dilate_dxf_owned(bytes, kerf, &dxf_options(options)),
    }?;
    if options.strict {
        refuse_open_paths(&summary, "--strict")?;
    }
    Ok((output, summary))
}

/// Read the plan at `input` (SVG or DXF, by its extension) and dilate it by `kerf`, like
/// [`dilate_file`], but write the dilated plan to `out` (called `output` in messages) as it is
/// made: a dilated SVG plan, its arcs written out, is several times the size of its file, and is
/// never held whole in memory. A regular SVG file is read again as the output is written (its
/// text is not held meanwhile): it must not change in between, or the plan is refused after
/// part of the output was written; a pipe or a device is read once and held. On an error (even
/// `--strict`'s refusal, which comes after the writing) part of the plan may have been written:
/// write into a temporary file, and keep it only on success. An error writing to `out` is a
/// [`PlanError::Write`] naming `output`.
pub fn dilate_file_into(
    input: &Path,
    kerf: &KerfSource,
    options: &DilateOptions,
    output: &Path,
    out: &mut (dyn Write + Sync),
) -> Result<PlanSummary> {
    let format = PlanFormat::of(input)?;
    let (bytes, file) = read_plan_file(input)?;
    let summary = match format {
        PlanFormat::Svg => {
            // A regular file is read again as the dilated plan is written, so its text is not
            // held while the cuts are dilated.
            svg_text(bytes)
                .and_then(|text| dilate_svg_file_into(text, file, kerf, &svg_options(options), out))
        }
        PlanFormat::Dxf => {
            dilate_dxf_owned(bytes, kerf, &dxf_options(options)).and_then(|(dxf, summary)| {
                out.write_all(&dxf)
                    .and_then(|()| out.flush())
                    .map_err(|source| PlanError::Write {
                        path: PathBuf::new(),
                        source,
                    })?;
                Ok(summary)
            })
        }
    }
    .map_err(|e| match e {
        PlanError::Write { source, .. } => PlanError::Write {
            path: output.to_owned(),
            source,
        },
        e => e.in_file(input),
    })?;
    if options.strict {
        refuse_open_paths(&summary, "--strict").map_err(|e| e.in_file(input))?;
    }
    Ok(summary)
}

/// Read the plan at `input` (SVG or DXF, by its extension) and dilate it by `kerf`, like
/// [`dilate_file`], but give back the dilated cuts (mm, in the file's own frame: SVG's y axis
/// points down, DXF's up) with their colours and layers, and what was found and done. Open cut
/// paths are always refused: they cannot be dilated, and a G-code program made from this would
/// silently leave them out.
pub fn dilate_file_cuts(
    input: &Path,
    kerf: &KerfSource,
    options: &DilateOptions,
) -> Result<(PlanFormat, Vec<CutPath>, PlanSummary)> {
    let (format, bytes) = read_plan(input)?;
    let (cuts, summary) = match format {
        PlanFormat::Svg => {
            svg_text(bytes).and_then(|text| dilate_svg_cuts(text, kerf, &svg_options(options)))
        }
        PlanFormat::Dxf => dilate_dxf_cuts(&bytes, kerf, &dxf_options(options)),
    }
    .map_err(|e| e.in_file(input))?;
    refuse_open_paths(&summary, "G-code cuts closed contours only")
        .map_err(|e| e.in_file(input))?;
    Ok((format, cuts, summary))
}

/// The plan file at `input`: its format (by its extension) and its bytes.
fn read_plan(input: &Path) -> Result<(PlanFormat, Vec<u8>)> {
    let format = PlanFormat::of(input)?;
    let bytes = std::fs::read(input).map_err(|source| PlanError::Io {
        path: input.to_owned(),
        source,
    })?;
    crate::source_file::refuse_empty(input, &bytes)?;
    Ok((format, bytes))
}

/// The `--strict` policy (and G-code's): open cut paths cannot be dilated, so a plan with any is
/// refused; `why` says which policy.
fn refuse_open_paths(summary: &PlanSummary, why: &str) -> Result<()> {
    if summary.open_paths.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = summary.open_paths.iter().map(|o| o.to_string()).collect();
    Err(PlanError::OpenPaths(format!(
        "{} open cut path(s) cannot be dilated ({why}; nothing was written):\n  - {}",
        list.len(),
        list.join("\n  - ")
    )))
}

/// An SVG file's bytes, dilated.
fn dilate_svg_bytes(
    bytes: Vec<u8>,
    kerf: &KerfSource,
    options: &DilateOptions,
) -> Result<(Vec<u8>, PlanSummary)> {
    let text = svg_text(bytes)?;
    let mut out = Vec::with_capacity(text.len());
    let summary = dilate_svg_into(text, kerf, &svg_options(options), &mut out)?;
    Ok((out, summary))
}

/// An SVG file's text: refuses compressed SVG and text that is not UTF-8.
fn svg_text(bytes: Vec<u8>) -> Result<String> {
    if bytes.starts_with(&[0x1f, 0x8b]) {
        return Err(PlanError::Svg(
            "a compressed SVG (.svgz) is not supported; save it uncompressed".into(),
        ));
    }
    String::from_utf8(bytes)
        .map_err(|_| PlanError::Svg("not a readable SVG file (not UTF-8 text)".into()))
}

fn svg_options(options: &DilateOptions) -> SvgOptions {
    SvgOptions {
        rules: options.rules.clone(),
        assume_units: options.assume_units,
        if_compensated: options.if_compensated,
        progress: options.progress.clone(),
    }
}

fn dxf_options(options: &DilateOptions) -> DxfOptions {
    DxfOptions {
        rules: options.rules.clone(),
        assume_units: options.assume_units,
        if_compensated: options.if_compensated,
        progress: options.progress.clone(),
    }
}
