//! `kerfmeter.dilate` and `kerfmeter.gauge`: the plan crate's dilation and gauge drawing, with
//! the outputs written atomically (never over the input) by the library's file helpers, a
//! dilated plan into its temporary file as it is made (as the CLI does: never held whole), and a
//! report dict with the keys of the CLI's `--json` report.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use kerfmeter::files::{ensure_not_input, write_atomically, write_atomically_with};
use kerfmeter::map::KerfMap;
use kerfmeter::protocol::{GaugeGeometry, JamDirection};
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::gauge::{self as drawing, GaugeOptions, TestPieceSpec};
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::rules::CutRules;
use kerfmeter_plan::{DilateOptions, PlanError, PlanFormat, dilate_file_into};
use pyo3::prelude::*;
use serde::Serialize;

use crate::errors;
use crate::to_py;

/// Add the functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dilate, m)?)?;
    m.add_function(wrap_pyfunction!(gauge, m)?)?;
    Ok(())
}

/// What `dilate` did: the fields of the CLI's `kerfmeter dilate --json` report.
#[derive(Serialize)]
struct DilateReport {
    input: PathBuf,
    output: Option<PathBuf>,
    dry_run: bool,
    format: PlanFormat,
    kerf_um: f64,
    map: Option<PathBuf>,
    cut_rules: String,
    #[serde(flatten)]
    summary: PlanSummary,
}

/// What failed in a dilation into a file: the plan, or the file.
enum Failure {
    Plan(PlanError),
    File(kerfmeter::Error),
}

impl From<kerfmeter::Error> for Failure {
    fn from(e: kerfmeter::Error) -> Self {
        Failure::File(e)
    }
}

/// The dilation's options from `dilate`'s keyword arguments.
fn dilate_options(
    cut_colors: &[String],
    cut_max_width_mm: f64,
    cut_layers: &[String],
    units: Option<&str>,
    strict: bool,
    compensated: &str,
) -> Result<DilateOptions, PlanError> {
    let assume_units = units
        .map(|u| u.parse::<AssumedUnits>())
        .transpose()
        .map_err(PlanError::InvalidArgument)?;
    let if_compensated = match compensated {
        "refuse" => IfCompensated::Refuse,
        "dilate_anyway" => IfCompensated::DilateAnyway,
        "recompensate" => IfCompensated::Recompensate,
        other => {
            return Err(PlanError::InvalidArgument(format!(
                "if_compensated must be \"refuse\", \"dilate_anyway\" or \"recompensate\", not {other:?}"
            )));
        }
    };
    Ok(DilateOptions {
        rules: CutRules::new(cut_colors, cut_max_width_mm, cut_layers)?,
        assume_units,
        strict,
        if_compensated,
        progress: Default::default(),
    })
}

/// The kerf: uniform, or per part from a kerf map measured with `kerf_um` at its reference cell.
fn kerf_source(kerf_um: f64, map: Option<&Path>) -> Result<KerfSource, kerfmeter::Error> {
    let kerf_um = KerfSource::check_kerf_um(kerf_um)
        .map_err(|e| kerfmeter::Error::invalid(e.to_string()))?;
    Ok(match map {
        None => KerfSource::Uniform(kerf_um),
        Some(path) => {
            let map = KerfMap::load(path)?;
            KerfSource::Map(Arc::new(move |x_mm, y_mm| {
                map.kerf_at_um(kerf_um, x_mm, y_mm)
            }))
        }
    })
}

/// Check that `output` may receive the dilation of `input`: same format, not the input itself.
fn check_output(input: &Path, output: &Path, format: PlanFormat) -> PyResult<()> {
    let out_format = PlanFormat::of(output).map_err(errors::plan)?;
    if out_format != format {
        return Err(errors::plan(PlanError::InvalidArgument(format!(
            "the output {} must have the input's format ({format})",
            output.display()
        ))));
    }
    ensure_not_input(input, output).map_err(|e| errors::PlanError::new_err(e.to_string()))
}

/// Dilate the cutting plan `in_path` (.svg or .dxf) by `kerf_um` and write it to `out_path`
/// (same format, never the input; `None` with `dry_run=True`). Returns the report as a dict.
#[pyfunction]
#[pyo3(signature = (in_path, out_path, kerf_um, *, map = None, dry_run = false, strict = false, cut_colors = Vec::new(), cut_max_width_mm = 0.3, cut_layers = Vec::new(), units = None, if_compensated = "refuse"))]
#[allow(clippy::too_many_arguments)]
fn dilate<'py>(
    py: Python<'py>,
    in_path: PathBuf,
    out_path: Option<PathBuf>,
    kerf_um: f64,
    map: Option<PathBuf>,
    dry_run: bool,
    strict: bool,
    cut_colors: Vec<String>,
    cut_max_width_mm: f64,
    cut_layers: Vec<String>,
    units: Option<&str>,
    if_compensated: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let format = PlanFormat::of(&in_path).map_err(errors::plan)?;
    match &out_path {
        Some(out) => check_output(&in_path, out, format)?,
        None if !dry_run => {
            return Err(errors::BadArgumentError::new_err(
                "out_path is needed unless dry_run=True",
            ));
        }
        None => {}
    }
    let options = dilate_options(
        &cut_colors,
        cut_max_width_mm,
        &cut_layers,
        units,
        strict,
        if_compensated,
    )
    .map_err(errors::plan)?;
    let kerf = kerf_source(kerf_um, map.as_deref()).map_err(|e| errors::device(py, e))?;
    let output = if dry_run { None } else { out_path };
    // As the CLI does: the dilated plan goes into the temporary output file as it is made (a
    // dilated SVG is several times its source), kept only if all went well.
    let summary = py
        .detach(|| match &output {
            Some(out) => write_atomically_with(out, |w| {
                dilate_file_into(&in_path, &kerf, &options, out, w).map_err(Failure::Plan)
            }),
            None => dilate_file_into(
                &in_path,
                &kerf,
                &options,
                Path::new("(none)"),
                &mut std::io::sink(),
            )
            .map_err(Failure::Plan),
        })
        .map_err(|e| match e {
            Failure::Plan(e) => errors::plan(e),
            Failure::File(e) => errors::PlanError::new_err(e.to_string()),
        })?;
    let report = DilateReport {
        input: in_path,
        output,
        dry_run,
        format,
        kerf_um,
        map,
        cut_rules: options.rules.describe(),
        summary,
    };
    to_py(py, &report)
}

/// What `gauge` wrote: the fields of the CLI's `kerfmeter gauge --json` report.
#[derive(Serialize)]
struct GaugeReport {
    output: PathBuf,
    format: PlanFormat,
    page_mm: [f64; 2],
    pitch_um_per_deg: f64,
    pitch_mm_per_rad: f64,
    start_radius_mm: f64,
    end_radius_mm: f64,
    spiral_arcs: usize,
    max_deviation_um: f64,
    hole_radius_mm: f64,
    hole_distance_mm: f64,
    jam_direction: &'static str,
    test_piece: Option<TestPieceSpec>,
    label: bool,
}

/// An `f32` as the decimal it was written as (2.774, not 2.7739999294).
fn clean(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// "cw" or "ccw" as the protocol's jam direction.
fn jam_direction(name: &str) -> PyResult<JamDirection> {
    match name {
        "cw" => Ok(JamDirection::Clockwise),
        "ccw" => Ok(JamDirection::CounterClockwise),
        other => Err(errors::BadArgumentError::new_err(format!(
            "jam_direction must be \"cw\" or \"ccw\", not {other:?}"
        ))),
    }
}

/// Draw the spiral gauge to cut before measuring and write it to `out_path` (.svg or .dxf).
/// `test_piece_kerf_um` adds the paper's one-finger test joint dilated by that kerf. Returns the
/// report as a dict.
#[pyfunction]
#[pyo3(signature = (out_path, *, jam_direction = "cw", label = false, test_piece_kerf_um = None, thickness_mm = 4.0, finger_width_mm = 6.3))]
fn gauge<'py>(
    py: Python<'py>,
    out_path: PathBuf,
    jam_direction: &str,
    label: bool,
    test_piece_kerf_um: Option<f64>,
    thickness_mm: f64,
    finger_width_mm: f64,
) -> PyResult<Bound<'py, PyAny>> {
    let format = PlanFormat::of(&out_path).map_err(errors::plan)?;
    let geometry = GaugeGeometry {
        jam_direction: self::jam_direction(jam_direction)?,
        ..GaugeGeometry::PAPER
    };
    let test_piece = test_piece_kerf_um.map(|kerf_um| TestPieceSpec {
        thickness_mm,
        finger_width_mm,
        kerf_um,
    });
    let options = GaugeOptions { test_piece, label };
    let drawn = drawing::build(&geometry, &options).map_err(errors::plan)?;
    let bytes = match format {
        PlanFormat::Svg => drawing::to_svg(&drawn).into_bytes(),
        PlanFormat::Dxf => drawing::to_dxf(&drawn).map_err(errors::plan)?,
    };
    write_atomically(&out_path, &bytes).map_err(|e| errors::PlanError::new_err(e.to_string()))?;
    let spiral_arcs = drawn
        .spiral
        .vertex_data
        .iter()
        .filter(|v| v.bulge != 0.0)
        .count();
    let report = GaugeReport {
        output: out_path,
        format,
        page_mm: drawn.page_mm,
        pitch_um_per_deg: clean(geometry.pitch_um_per_deg),
        pitch_mm_per_rad: drawn.pitch_mm_per_rad,
        start_radius_mm: drawn.start_radius_mm,
        end_radius_mm: drawn.start_radius_mm + std::f64::consts::TAU * drawn.pitch_mm_per_rad,
        spiral_arcs,
        max_deviation_um: drawn.max_deviation_mm * 1e3,
        hole_radius_mm: clean(geometry.hole_radius_mm),
        hole_distance_mm: clean(geometry.hole_distance_mm),
        jam_direction: if jam_direction == "cw" { "cw" } else { "ccw" },
        test_piece,
        label,
    };
    to_py(py, &report)
}
