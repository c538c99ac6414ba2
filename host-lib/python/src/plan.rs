//! `kerfmeter.dilate` and `kerfmeter.gauge`: the plan crate's dilation and gauge drawing, with
//! the outputs written atomically (never over the input) by the library's file helpers, a
//! dilated plan into its temporary file as it is made (as the CLI does: never held whole), and a
//! report dict with the keys of the CLI's `--json` report.

use std::path::PathBuf;

use kerfmeter::files::write_atomically;
use kerfmeter_app::dilate::{DilateFileRequest, Dilation, dilate_file};
use kerfmeter_app::gauge::{GaugeRequest, JamSense, draw};
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::outcome::AssumedUnits;
use kerfmeter_plan::{PlanError, PlanFormat};
use pyo3::prelude::*;

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

/// "cw" or "ccw" as the gauge's jam direction.
fn jam_sense(name: &str) -> PyResult<JamSense> {
    match name {
        "cw" => Ok(JamSense::Cw),
        "ccw" => Ok(JamSense::Ccw),
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
    // The same request as the CLI's `gauge` and the server's `gauge`.
    let request = GaugeRequest {
        format: format.into(),
        jam_direction: jam_sense(jam_direction)?,
        label,
        test_piece: test_piece_kerf_um.is_some(),
        test_piece_kerf_um,
        thickness_mm,
        finger_width_mm,
        ..GaugeRequest::default()
    };
    let (bytes, mut report) = draw(&request).map_err(|e| app_error(py, e))?;
    write_atomically(&out_path, &bytes).map_err(|e| errors::PlanError::new_err(e.to_string()))?;
    report.output = Some(out_path);
    to_py(py, &report)
}
