//! `kerfmeter.dilate` and `kerfmeter.gauge`: the plan crate's dilation and gauge drawing, with
//! the outputs written atomically (never over the input) by the library's file helpers, a
//! dilated plan into its temporary file as it is made (as the CLI does: never held whole), and a
//! report dict with the keys of the CLI's `--json` report.

use std::path::PathBuf;

use kerfmeter::files::write_atomically;
use kerfmeter::protocol::{GaugeGeometry, JamDirection};
use kerfmeter_app::dilate::{DilateFileRequest, Dilation, dilate_file};
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::gauge::{self as drawing, GaugeOptions, TestPieceSpec};
use kerfmeter_plan::outcome::AssumedUnits;
use kerfmeter_plan::{PlanError, PlanFormat};
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

/// What to do with a plan already compensated, by name.
fn if_compensated(name: &str) -> PyResult<IfCompensated> {
    match name {
        "refuse" => Ok(IfCompensated::Refuse),
        "dilate_anyway" => Ok(IfCompensated::DilateAnyway),
        "recompensate" => Ok(IfCompensated::Recompensate),
        other => Err(errors::plan(PlanError::InvalidArgument(format!(
            "if_compensated must be \"refuse\", \"dilate_anyway\" or \"recompensate\", not {other:?}"
        )))),
    }
}

/// An application-layer error as the Python exception for it.
fn app_error(py: Python<'_>, e: kerfmeter_app::Error) -> PyErr {
    match e {
        kerfmeter_app::Error::Plan(e) => errors::plan(e),
        // The output's own refusals (the input itself, a file that cannot be written).
        kerfmeter_app::Error::Meter(
            e @ (kerfmeter::Error::File { .. } | kerfmeter::Error::InvalidArgument(_)),
        ) => errors::PlanError::new_err(e.to_string()),
        kerfmeter_app::Error::Meter(e) => errors::device(py, e),
        kerfmeter_app::Error::History(e) => errors::KerfmeterError::new_err(e.to_string()),
    }
}

/// Dilate the cutting plan `in_path` (.svg or .dxf) by `kerf_um` and write it to `out_path`
/// (same format, never the input; `None` with `dry_run=True`; a file there is replaced only if
/// kerfmeter wrote it, unless `force=True`). Returns the report as a dict: the CLI's
/// `kerfmeter dilate --json` report, the same type.
#[pyfunction]
#[pyo3(signature = (in_path, out_path, kerf_um, *, map = None, dry_run = false, strict = false, cut_colors = Vec::new(), cut_max_width_mm = 0.3, cut_layers = Vec::new(), units = None, if_compensated = "refuse", force = false))]
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
    force: bool,
) -> PyResult<Bound<'py, PyAny>> {
    if out_path.is_none() && !dry_run {
        return Err(errors::BadArgumentError::new_err(
            "out_path is needed unless dry_run=True",
        ));
    }
    let units = units
        .map(|u| u.parse::<AssumedUnits>())
        .transpose()
        .map_err(|e| errors::plan(PlanError::InvalidArgument(e)))?;
    let request = DilateFileRequest {
        input: in_path,
        output: out_path,
        dry_run,
        strict,
        force,
        dilation: Dilation {
            kerf_um,
            map,
            cut_colors,
            cut_max_width_mm,
            cut_layers,
            units,
            if_compensated: self::if_compensated(if_compensated)?,
        },
    };
    let report = py
        .detach(|| dilate_file(&request, Default::default()))
        .map_err(|e| app_error(py, e))?;
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
