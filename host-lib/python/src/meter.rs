//! `kerfmeter.Kerfmeter`: a connected device (or the in-process twin) and its calls, and the
//! result objects they return (`KerfResult`, `Measurement`).
//!
//! Every call that talks to the device runs with the GIL released; the device is behind a mutex
//! that is only taken with the GIL released, so a thread waiting for it never blocks one that
//! needs the GIL to report progress.

use std::ops::ControlFlow;
use std::sync::Mutex;
use std::time::Duration;

use kerfmeter::protocol::{GaugeGeometry, KerfResult};
use kerfmeter::sim::{PlantParams, SimDevice, SimFault, SimOptions};
use kerfmeter::{JointSpec, Options, Progress};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{self, BadArgumentError, CommunicationError};
use crate::to_py;

/// Add the classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyKerfmeter>()?;
    m.add_class::<PyKerfResult>()?;
    m.add_class::<PyMeasurement>()?;
    Ok(())
}

/// An `f32` as the decimal it was written as (199.8, not 199.8000030517578).
fn clean(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// The result of a run, as the device keeps it.
#[pyclass(name = "KerfResult", module = "kerfmeter", frozen, get_all, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyKerfResult {
    /// Which run produced it.
    run_id: u32,
    /// Kerf (full cut width), µm.
    kerf_um: f64,
    /// Hub angle at the jam, degrees.
    angle_deg: f64,
    /// Hole play included in `angle_deg`, degrees.
    play_deg: f64,
    /// Output torque at the jam, N·m.
    torque_at_jam_nm: f64,
    /// Joint assembly force this torque represents, N.
    force_at_jam_n: f64,
    /// Reasons to distrust the number (empty when there are none).
    flags: Vec<String>,
}

impl From<&KerfResult> for PyKerfResult {
    fn from(r: &KerfResult) -> Self {
        Self {
            run_id: r.run_id,
            kerf_um: clean(r.kerf_um),
            angle_deg: clean(r.angle_deg),
            play_deg: clean(r.play_deg),
            torque_at_jam_nm: clean(r.torque_at_jam_nm),
            force_at_jam_n: clean(r.force_at_jam_n),
            flags: r.flags.names().map(str::to_owned).collect(),
        }
    }
}

#[pymethods]
impl PyKerfResult {
    fn __repr__(&self) -> String {
        format!(
            "KerfResult(run_id={}, kerf_um={}, angle_deg={}, play_deg={}, torque_at_jam_nm={}, force_at_jam_n={}, flags={:?})",
            self.run_id,
            self.kerf_um,
            self.angle_deg,
            self.play_deg,
            self.torque_at_jam_nm,
            self.force_at_jam_n,
            self.flags
        )
    }
}

/// Repeated runs and their summary (`Kerfmeter.measure`).
#[pyclass(name = "Measurement", module = "kerfmeter", frozen, get_all)]
pub struct PyMeasurement {
    /// Every run's result, in order.
    runs: Vec<PyKerfResult>,
    /// Runs.
    n: usize,
    /// Mean kerf, µm.
    mean_um: f64,
    /// Sample standard deviation, µm (0 for one run).
    sd_um: f64,
    /// Half-width of the 95 % confidence interval of the mean, µm (`None` for one run).
    ci95_um: Option<f64>,
    /// Smallest run, µm.
    min_um: f64,
    /// Largest run, µm.
    max_um: f64,
    /// Indices of runs flagged as outliers.
    outliers: Vec<usize>,
}

#[pymethods]
impl PyMeasurement {
    fn __repr__(&self) -> String {
        format!(
            "Measurement(n={}, mean_um={:.2}, sd_um={:.2}, ci95_um={:?}, outliers={:?})",
            self.n, self.mean_um, self.sd_um, self.ci95_um, self.outliers
        )
    }
}

/// The client, and the twin it talks to when it is simulated. Fields drop in order: the client
/// (and its port) before the twin.
struct Connected {
    meter: kerfmeter::Kerfmeter,
    _sim: Option<SimDevice>,
}

/// A Kerfmeter: on a serial port, or the digital twin in this process.
#[pyclass(name = "Kerfmeter", module = "kerfmeter")]
pub struct PyKerfmeter {
    /// `None` once closed.
    inner: Mutex<Option<Connected>>,
}

/// Client options with a request timeout of `timeout_ms`.
fn client_options(timeout_ms: u64) -> Options {
    Options {
        timeout: Duration::from_millis(timeout_ms),
        ..Options::default()
    }
}

/// Run parameters for a joint, on the paper's gauge.
fn run_params(
    thickness_mm: f64,
    force_n: Option<f64>,
    fingers: u32,
    finger_length_mm: f64,
) -> kerfmeter::Result<kerfmeter::protocol::RunParams> {
    let joint = JointSpec {
        thickness_mm,
        fingers,
        finger_length_mm,
        force_n,
    };
    joint.run_params(GaugeGeometry::PAPER)
}

/// Call `progress(state, torque_nm, angle_deg)` if given, after checking for signals (Ctrl-C).
/// An error (KeyboardInterrupt, or what `progress` raised) stops the run.
fn report(
    progress: Option<&Py<PyAny>>,
    p: &Progress,
    pending: &mut Option<PyErr>,
) -> ControlFlow<()> {
    let outcome = Python::attach(|py| {
        py.check_signals()?;
        if let Some(f) = progress {
            f.call1(py, (format!("{:?}", p.state), p.torque_nm, p.angle_deg))?;
        }
        Ok::<(), PyErr>(())
    });
    match outcome {
        Ok(()) => ControlFlow::Continue(()),
        Err(e) => {
            *pending = Some(e);
            ControlFlow::Break(())
        }
    }
}

/// The twin's options from `Kerfmeter.sim`'s arguments.
fn sim_options(
    kerf_um: f64,
    seed: u64,
    fault: Option<&str>,
    kerf_sd_um: f64,
    realtime: bool,
    plant: Option<&Bound<'_, PyDict>>,
) -> PyResult<SimOptions> {
    let fault = fault
        .map(|name| name.parse::<SimFault>())
        .transpose()
        .map_err(|e| BadArgumentError::new_err(e.to_string()))?;
    let mut params = PlantParams::default();
    for (name, value) in plant.into_iter().flat_map(|d| d.iter()) {
        let name: String = name.extract()?;
        let value: f64 = value.extract().map_err(|_| {
            BadArgumentError::new_err(format!("plant parameter {name} must be a number"))
        })?;
        params
            .set(&name, value)
            .map_err(|e| BadArgumentError::new_err(e.to_string()))?;
    }
    Ok(SimOptions {
        kerf_um,
        kerf_sd_um,
        seed,
        fault,
        realtime,
        plant: params,
        ..SimOptions::default()
    })
}

impl PyKerfmeter {
    fn new(meter: kerfmeter::Kerfmeter, sim: Option<SimDevice>) -> Self {
        Self {
            inner: Mutex::new(Some(Connected { meter, _sim: sim })),
        }
    }

    /// Run `f` on the client with the GIL released; library errors become Python exceptions.
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut kerfmeter::Kerfmeter) -> kerfmeter::Result<T> + Send,
    ) -> PyResult<T> {
        let outcome = py.detach(|| {
            let mut guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
            guard.as_mut().map(|c| f(&mut c.meter))
        });
        match outcome {
            None => Err(CommunicationError::new_err(
                "this Kerfmeter is closed; open it again",
            )),
            Some(result) => result.map_err(|e| errors::device(py, e)),
        }
    }

    /// Like [`Self::with`] for a call that reports progress: a Python error raised while it ran
    /// (Ctrl-C, or from `progress`) wins over the library's "cancelled".
    fn with_progress<T: Send>(
        &self,
        py: Python<'_>,
        progress: Option<Py<PyAny>>,
        f: impl FnOnce(
            &mut kerfmeter::Kerfmeter,
            &mut dyn FnMut(&Progress) -> ControlFlow<()>,
        ) -> kerfmeter::Result<T>
        + Send,
    ) -> PyResult<T> {
        let mut pending = None;
        let result = self.with(py, |meter| {
            f(meter, &mut |p| report(progress.as_ref(), p, &mut pending))
        });
        match pending {
            Some(e) => Err(e),
            None => result,
        }
    }
}

#[pymethods]
impl PyKerfmeter {
    /// Open the device on the serial port at `port` (e.g. "/dev/ttyACM0").
    #[staticmethod]
    #[pyo3(signature = (port, timeout_ms = 300))]
    fn open(py: Python<'_>, port: &str, timeout_ms: u64) -> PyResult<Self> {
        let options = client_options(timeout_ms);
        let meter = py
            .detach(|| kerfmeter::Kerfmeter::open_with(port, options))
            .map_err(|e| errors::device(py, e))?;
        Ok(Self::new(meter, None))
    }

    /// Find the device among the serial ports (Espressif's USB-Serial-JTAG ids, or the only USB
    /// serial port) and open it.
    #[staticmethod]
    #[pyo3(signature = (timeout_ms = 300))]
    fn discover(py: Python<'_>, timeout_ms: u64) -> PyResult<Self> {
        let options = client_options(timeout_ms);
        let meter = py
            .detach(|| kerfmeter::Kerfmeter::discover(options))
            .map_err(|e| errors::device(py, e))?;
        Ok(Self::new(meter, None))
    }

    /// Start the digital twin (the real firmware on simulated hardware) in this process and
    /// connect to it. `fault` injects a named fault ("no-inset", "magnet-lost", ...); `plant`
    /// sets the twin's physics by name (e.g. `supply_v=24`).
    #[staticmethod]
    #[pyo3(signature = (kerf_um = 150.0, seed = 1, fault = None, kerf_sd_um = 0.0, realtime = false, **plant))]
    fn sim(
        py: Python<'_>,
        kerf_um: f64,
        seed: u64,
        fault: Option<&str>,
        kerf_sd_um: f64,
        realtime: bool,
        plant: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let options = sim_options(kerf_um, seed, fault, kerf_sd_um, realtime, plant)?;
        let (sim, meter) = py
            .detach(|| SimDevice::connect(options, Options::default()))
            .map_err(|e| errors::device(py, e))?;
        Ok(Self::new(meter, Some(sim)))
    }

    /// Measure the kerf: reset the hub if needed, run, and return the result. `progress`, if
    /// given, is called with (state, torque_nm, angle_deg) at every status poll. Ctrl-C aborts
    /// the run (the motor stops) and raises KeyboardInterrupt. `force_n=None` is 18.3 N per
    /// finger (55 N for three).
    #[pyo3(signature = (thickness_mm = 4.0, force_n = None, fingers = 3, finger_length_mm = 6.3, progress = None))]
    fn run_kerfmeter(
        &self,
        py: Python<'_>,
        thickness_mm: f64,
        force_n: Option<f64>,
        fingers: u32,
        finger_length_mm: f64,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyKerfResult> {
        let params = run_params(thickness_mm, force_n, fingers, finger_length_mm)
            .map_err(|e| errors::device(py, e))?;
        let result = self.with_progress(py, progress, |meter, report| {
            meter.prepare_for_run()?;
            meter.run_kerfmeter_until(&params, report)
        })?;
        Ok(PyKerfResult::from(&result))
    }

    /// The last result the device holds, or None after a reset or before the first run.
    fn get_kerf_value(&self, py: Python<'_>) -> PyResult<Option<PyKerfResult>> {
        let result = self.with(py, |meter| meter.get_kerf_value())?;
        Ok(result.as_ref().map(PyKerfResult::from))
    }

    /// Turn the hub back to zero (prongs aligned for the next gauge), clear the result and any
    /// latched fault; returns when the hub is there.
    fn reset_kerfmeter(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |meter| meter.reset_kerfmeter())
    }

    /// Measure `n` gauges and summarise them (mean, SD, 95 % CI, outliers). Before each gauge
    /// the hub is reset and `before_gauge(i)` is called (place gauge i).
    #[pyo3(signature = (n, thickness_mm = 4.0, force_n = None, fingers = 3, finger_length_mm = 6.3, before_gauge = None, progress = None))]
    #[allow(clippy::too_many_arguments)]
    fn measure(
        &self,
        py: Python<'_>,
        n: usize,
        thickness_mm: f64,
        force_n: Option<f64>,
        fingers: u32,
        finger_length_mm: f64,
        before_gauge: Option<Py<PyAny>>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyMeasurement> {
        if n == 0 {
            return Err(BadArgumentError::new_err("measure at least one gauge"));
        }
        let mut runs = Vec::with_capacity(n);
        for i in 0..n {
            self.reset_kerfmeter(py)?;
            if let Some(f) = &before_gauge {
                f.call1(py, (i,))?;
            }
            runs.push(self.run_kerfmeter(
                py,
                thickness_mm,
                force_n,
                fingers,
                finger_length_mm,
                progress.as_ref().map(|p| p.clone_ref(py)),
            )?);
        }
        let kerfs: Vec<f64> = runs.iter().map(|r| r.kerf_um).collect();
        let s = kerfmeter::stats::summarize(&kerfs);
        Ok(PyMeasurement {
            runs,
            n: s.n,
            mean_um: s.mean_um,
            sd_um: s.sd_um,
            ci95_um: s.ci95_um,
            min_um: s.min_um,
            max_um: s.max_um,
            outliers: s.outliers,
        })
    }

    /// Protocol and firmware versions, boot id and hardware constants, as a dict.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let info = self.with(py, |meter| meter.info())?;
        to_py(py, &info)
    }

    /// What the device is doing (state, torque, angle, conditions, supply), as a dict.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let status = self.with(py, |meter| meter.status())?;
        to_py(py, &status)
    }

    /// Stop the motor now, ending any run, reset or self-test.
    fn abort(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |meter| meter.abort())
    }

    /// Leave a latched fault (fix its cause first).
    fn clear_fault(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |meter| meter.clear_fault())
    }

    /// Run the self-test (no gauge under the prongs) and return its report as a dict.
    fn self_test<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = self.with(py, |meter| meter.self_test(|_| {}))?;
        to_py(py, &report)
    }

    /// Close the port (and stop the twin); later calls raise CommunicationError.
    fn close(&self, py: Python<'_>) {
        let connected = py.detach(|| self.inner.lock().unwrap_or_else(|e| e.into_inner()).take());
        py.detach(move || drop(connected));
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> bool {
        self.close(py);
        false
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        let path = py.detach(|| {
            let guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
            guard.as_ref().map(|c| c.meter.path().to_owned())
        });
        match path {
            Some(p) => format!("Kerfmeter({p:?})"),
            None => "Kerfmeter(closed)".into(),
        }
    }
}
