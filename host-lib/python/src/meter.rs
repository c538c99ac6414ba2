//! `kerfmeter.Kerfmeter`: a connected device (or the in-process twin) and its calls, and the
//! result objects they return (`KerfResult`, `Measurement`).
//!
//! Every call that talks to the device runs with the GIL released; the device is behind a mutex
//! that is only taken with the GIL released, so a thread waiting for it never blocks one that
//! needs the GIL to report progress.
//!
//! A call made on the same meter from inside its own `progress` callback would wait for a mutex
//! its own thread holds: the meter remembers which thread holds it and refuses such a call
//! with `KerfmeterError` (`abort()` is the exception: it asks the running call to stop). A call
//! from another thread waits for the running one, except `abort()`, which raises a stop flag
//! that the running call sees at its next status poll (and then tells the device to abort).
//! The port's path is kept outside the mutex so that `repr()` never waits.
//!
//! `progress` runs between two status polls, which are also the device's sign that the host is
//! alive: a callback (or another thread holding the GIL) that takes longer than the device's
//! host timeout (1 s) makes it stop its motor on the `HostSilent` fault.

use std::ops::ControlFlow;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::ThreadId;
use std::time::Duration;

use kerfmeter::protocol::KerfResult;
use kerfmeter::sim::{PlantParams, SimDevice, SimFault, SimOptions};
use kerfmeter::{Options, Progress};
use kerfmeter_app::measure::MeasureRequest;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{self, BadArgumentError, CommunicationError, DeviceError, KerfmeterError};
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
            "Measurement(n={}, mean_um={:.2}, sd_um={:.2}, ci95_um={}, outliers={:?})",
            self.n,
            self.mean_um,
            self.sd_um,
            self.ci95_um
                .map_or_else(|| "None".to_owned(), |ci| format!("{ci:.2}")),
            self.outliers
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
#[pyclass(name = "Kerfmeter", module = "kerfmeter", frozen)]
pub struct PyKerfmeter {
    /// `None` once closed.
    inner: Mutex<Option<Connected>>,
    /// The thread inside a call (holding `inner`), if any: a call from that same thread is one
    /// made from a `progress` callback.
    holder: Mutex<Option<ThreadId>>,
    /// Raised by `abort()`: the running call stops at its next status poll.
    stop: AtomicBool,
    /// The port's path, for `repr()`.
    path: String,
    /// Set by `close()`, for `repr()`.
    closed: AtomicBool,
}

/// Marks the meter as held by this thread while a call runs; unmarks it when dropped.
struct Holding<'a>(&'a Mutex<Option<ThreadId>>);

impl<'a> Holding<'a> {
    fn new(holder: &'a Mutex<Option<ThreadId>>) -> Self {
        *holder.lock().unwrap_or_else(|e| e.into_inner()) = Some(std::thread::current().id());
        Self(holder)
    }
}

impl Drop for Holding<'_> {
    fn drop(&mut self) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = None;
    }
}

/// What ended a call that reports progress before the library did: a Python error (Ctrl-C, or
/// raised by `progress`), or `abort()` from elsewhere.
type Pending = Option<PyErr>;

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
    fingers: i64,
    finger_length_mm: f64,
) -> kerfmeter::Result<kerfmeter::protocol::RunParams> {
    // Any integer Python gives is refused as a bad argument, not as an overflow.
    let fingers =
        u32::try_from(fingers).map_err(|_| kerfmeter::params::fingers_out_of_range(fingers))?;
    // The same request as the CLI's `run` and the server's `run_kerfmeter`, one gauge a call.
    let asked = MeasureRequest {
        thickness_mm,
        fingers,
        finger_length_mm,
        force_n,
        ..MeasureRequest::default()
    };
    asked.checked()
}

/// Whether the call must stop now: `abort()` was called, or a signal (Ctrl-C) is pending. The
/// reason goes to `pending`.
fn interrupted(stop: &AtomicBool, pending: &mut Pending) -> bool {
    let outcome = if stop.load(Ordering::SeqCst) {
        Err(Python::attach(|_| {
            DeviceError::new_err(
                "stopped by Kerfmeter.abort(); the device aborted it and its motor is stopped",
            )
        }))
    } else {
        Python::attach(|py| py.check_signals())
    };
    match outcome {
        Ok(()) => false,
        Err(e) => {
            *pending = Some(e);
            true
        }
    }
}

/// Call `progress(state, torque_nm, angle_deg)` if given, after checking for `abort()` and
/// signals (Ctrl-C). Any of these, or an error raised by `progress`, stops the call.
fn report(
    progress: Option<&Py<PyAny>>,
    stop: &AtomicBool,
    p: &Progress,
    pending: &mut Pending,
) -> ControlFlow<()> {
    if interrupted(stop, pending) {
        return ControlFlow::Break(());
    }
    let Some(f) = progress else {
        return ControlFlow::Continue(());
    };
    let outcome = Python::attach(|py| {
        f.call1(py, (format!("{:?}", p.state), p.torque_nm, p.angle_deg))
            .map(drop)
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
            path: meter.path().to_owned(),
            inner: Mutex::new(Some(Connected { meter, _sim: sim })),
            holder: Mutex::new(None),
            stop: AtomicBool::new(false),
            closed: AtomicBool::new(false),
        }
    }

    /// Whether this thread is inside a call on this meter (so a new call comes from `progress`).
    fn held_by_this_thread(&self) -> bool {
        *self.holder.lock().unwrap_or_else(|e| e.into_inner()) == Some(std::thread::current().id())
    }

    /// Run `f` on the client with the GIL released and the stop flag cleared. The library's
    /// result is returned as it is; the outer error is a meter that is closed, or a call made
    /// from this meter's own `progress` callback (which would otherwise wait for ever).
    fn with_raw<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut kerfmeter::Kerfmeter) -> kerfmeter::Result<T> + Send,
    ) -> PyResult<kerfmeter::Result<T>> {
        if self.held_by_this_thread() {
            return Err(KerfmeterError::new_err(
                "a Kerfmeter cannot be called from its own progress callback (only abort() can); \
                 return from the callback, or raise an exception to stop the run",
            ));
        }
        let outcome = py.detach(|| {
            let mut guard = self.inner.lock().unwrap_or_else(|e| e.into_inner());
            let _holding = Holding::new(&self.holder);
            self.stop.store(false, Ordering::SeqCst);
            guard.as_mut().map(|c| f(&mut c.meter))
        });
        outcome
            .ok_or_else(|| CommunicationError::new_err("this Kerfmeter is closed; open it again"))
    }

    /// [`Self::with_raw`] with library errors turned into Python exceptions.
    fn with<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut kerfmeter::Kerfmeter) -> kerfmeter::Result<T> + Send,
    ) -> PyResult<T> {
        self.with_raw(py, f)?.map_err(|e| errors::device(py, e))
    }

    /// Like [`Self::with`] for a call that reports progress and can be stopped (Ctrl-C,
    /// `abort()`, an error raised by `progress`): that reason wins over the library's
    /// "cancelled". If stopping failed too (the abort request could not be sent), the library's
    /// error is attached to it as its `__cause__`.
    fn with_progress<T: Send>(
        &self,
        py: Python<'_>,
        progress: Option<&Py<PyAny>>,
        f: impl FnOnce(&mut kerfmeter::Kerfmeter, &mut Stopper<'_>) -> kerfmeter::Result<T> + Send,
    ) -> PyResult<T> {
        let mut stopper = Stopper {
            progress,
            stop: &self.stop,
            pending: None,
        };
        let result = self.with_raw(py, |meter| f(meter, &mut stopper))?;
        match (stopper.pending, result) {
            (None, result) => result.map_err(|e| errors::device(py, e)),
            (Some(reason), Err(e)) if !matches!(e, kerfmeter::Error::Cancelled) => {
                reason.set_cause(py, Some(errors::device(py, e)));
                Err(reason)
            }
            (Some(reason), _) => Err(reason),
        }
    }
}

/// What a stoppable call checks between its steps and at every status poll.
struct Stopper<'a> {
    progress: Option<&'a Py<PyAny>>,
    stop: &'a AtomicBool,
    pending: Pending,
}

impl Stopper<'_> {
    /// The `progress` for the library's `..._until` calls.
    fn report(&mut self, p: &Progress) -> ControlFlow<()> {
        report(self.progress, self.stop, p, &mut self.pending)
    }

    /// Check for `abort()` and Ctrl-C between two steps of a call (no status to report).
    fn check(&mut self) -> kerfmeter::Result<()> {
        if interrupted(self.stop, &mut self.pending) {
            return Err(kerfmeter::Error::Cancelled);
        }
        Ok(())
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
    /// sets the twin's physics by name (e.g. `supply_v=24`); `encoder_on_motor_shaft` boots a
    /// twin so configured, which refuses runs until `confirm_hub_at_zero()`.
    #[staticmethod]
    #[pyo3(signature = (kerf_um = 150.0, seed = 1, fault = None, kerf_sd_um = 0.0, realtime = false, encoder_on_motor_shaft = false, **plant))]
    // Python's keyword arguments, one each.
    #[allow(clippy::too_many_arguments)]
    fn sim(
        py: Python<'_>,
        kerf_um: f64,
        seed: u64,
        fault: Option<&str>,
        kerf_sd_um: f64,
        realtime: bool,
        encoder_on_motor_shaft: bool,
        plant: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let options = SimOptions {
            encoder_on_motor_shaft,
            ..sim_options(kerf_um, seed, fault, kerf_sd_um, realtime, plant)?
        };
        let (sim, meter) = py
            .detach(|| SimDevice::connect(options, Options::default()))
            .map_err(|e| errors::device(py, e))?;
        Ok(Self::new(meter, Some(sim)))
    }

    /// Measure the kerf: reset the hub if needed, run, and return the result. `progress`, if
    /// given, is called with (state, torque_nm, angle_deg) at every status poll (every 20 ms)
    /// and must return quickly: the device stops on a HostSilent fault when it hears nothing
    /// for 1 s. Ctrl-C (on the main thread) aborts the run (the motor stops) and raises
    /// KeyboardInterrupt; so does an exception raised by `progress`, which propagates.
    /// `force_n=None` is 18.3 N per finger (55 N for three).
    #[pyo3(signature = (thickness_mm = 4.0, force_n = None, fingers = 3, finger_length_mm = 6.3, progress = None))]
    fn run_kerfmeter(
        &self,
        py: Python<'_>,
        thickness_mm: f64,
        force_n: Option<f64>,
        fingers: i64,
        finger_length_mm: f64,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyKerfResult> {
        let params = run_params(thickness_mm, force_n, fingers, finger_length_mm)
            .map_err(|e| errors::device(py, e))?;
        let result = self.with_progress(py, progress.as_ref(), |meter, stopper| {
            prepare_and_run(meter, &params, stopper)
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
        self.with_progress(py, None, |meter, stopper| {
            meter.reset_kerfmeter_until(|p| stopper.report(p))
        })
    }

    /// Measure `n` gauges and summarise them (mean, SD, 95 % CI, outliers). Before each gauge
    /// the hub is reset if it is away from zero and `before_gauge(i)` is called (place gauge
    /// i). A latched fault stops it (clear it knowingly first). `progress` is as in
    /// `run_kerfmeter`.
    #[pyo3(signature = (n, thickness_mm = 4.0, force_n = None, fingers = 3, finger_length_mm = 6.3, before_gauge = None, progress = None))]
    #[allow(clippy::too_many_arguments)]
    fn measure(
        &self,
        py: Python<'_>,
        n: i64,
        thickness_mm: f64,
        force_n: Option<f64>,
        fingers: i64,
        finger_length_mm: f64,
        before_gauge: Option<Py<PyAny>>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyMeasurement> {
        let n = match usize::try_from(n) {
            Ok(n) if n > 0 => n,
            _ => {
                let why = format!("measure at least one gauge, got n={n}");
                return Err(BadArgumentError::new_err(why));
            }
        };
        let params = run_params(thickness_mm, force_n, fingers, finger_length_mm)
            .map_err(|e| errors::device(py, e))?;
        let mut runs = Vec::with_capacity(n);
        for i in 0..n {
            self.with_progress(py, None, |meter, stopper| {
                meter.prepare_for_run_until(|p| stopper.report(p))
            })?;
            if let Some(f) = &before_gauge {
                f.call1(py, (i,))?;
            }
            runs.push(self.with_progress(py, progress.as_ref(), |meter, stopper| {
                prepare_and_run(meter, &params, stopper)
            })?);
        }
        // The library's statistics, over the device's own numbers (as `Kerfmeter::measure`).
        let kerfs: Vec<f64> = runs.iter().map(|r| f64::from(r.kerf_um)).collect();
        let s = kerfmeter::stats::summarize(&kerfs);
        Ok(PyMeasurement {
            runs: runs.iter().map(PyKerfResult::from).collect(),
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

    /// Stop the motor now, ending any run, reset or self-test. From another thread (or from a
    /// `progress` callback) while a call runs, it asks that call to stop: the call tells the
    /// device to abort at its next status poll (within 20 ms) and raises DeviceError.
    fn abort(&self, py: Python<'_>) -> PyResult<()> {
        self.stop.store(true, Ordering::SeqCst);
        if self.held_by_this_thread() {
            return Ok(());
        }
        let idle = py.detach(|| match self.inner.try_lock() {
            Ok(mut guard) => Some(guard.as_mut().map(|c| c.meter.abort())),
            Err(std::sync::TryLockError::Poisoned(e)) => {
                Some(e.into_inner().as_mut().map(|c| c.meter.abort()))
            }
            // A call is running: it sees the stop flag at its next poll.
            Err(std::sync::TryLockError::WouldBlock) => None,
        });
        match idle {
            None => Ok(()),
            Some(None) => Err(CommunicationError::new_err(
                "this Kerfmeter is closed; open it again",
            )),
            Some(Some(result)) => result.map_err(|e| errors::device(py, e)),
        }
    }

    /// Leave a latched fault (fix its cause first).
    fn clear_fault(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |meter| meter.clear_fault())
    }

    /// Say the hub stands at its zero mark (turned there by hand, prongs lifted): with the
    /// encoder on the motor shaft the device refuses runs after power-up until told so.
    fn confirm_hub_at_zero(&self, py: Python<'_>) -> PyResult<()> {
        self.with(py, |meter| meter.confirm_hub_at_zero())
    }

    /// Run the self-test (no gauge under the prongs) and return its report as a dict.
    fn self_test<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = self.with_progress(py, None, |meter, stopper| {
            meter.self_test_until(|p| stopper.report(p))
        })?;
        to_py(py, &report)
    }

    /// Close the port (and stop the twin); later calls raise CommunicationError.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let closed = self.with_raw(py, |_| Ok(()));
        if closed.is_ok() {
            let connected =
                py.detach(|| self.inner.lock().unwrap_or_else(|e| e.into_inner()).take());
            self.closed.store(true, Ordering::SeqCst);
            py.detach(move || drop(connected));
        }
        closed.map(drop).or_else(|e| {
            if e.is_instance_of::<CommunicationError>(py) {
                Ok(()) // closing a closed meter is fine
            } else {
                Err(e)
            }
        })
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<()> {
        self.close(py)
    }

    fn __repr__(&self) -> String {
        if self.closed.load(Ordering::SeqCst) {
            "Kerfmeter(closed)".into()
        } else {
            format!("Kerfmeter({:?})", self.path)
        }
    }
}

/// Make the device ready (a reset if needed), check for a stop, and run: every step stoppable.
fn prepare_and_run(
    meter: &mut kerfmeter::Kerfmeter,
    params: &kerfmeter::protocol::RunParams,
    stopper: &mut Stopper<'_>,
) -> kerfmeter::Result<KerfResult> {
    meter.prepare_for_run_until(|p| stopper.report(p))?;
    stopper.check()?;
    meter.run_kerfmeter_until(params, |p| stopper.report(p))
}
