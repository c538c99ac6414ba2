//! The Python exceptions: one base, `KerfmeterError`, and a subclass per kind of failure, each
//! carrying the library's own message (which says what to do). `BadArgumentError` is also a
//! `ValueError`, as Python's own functions raise for a bad value: PyO3's `create_exception!`
//! takes one base, so that class is made with `type()` when the module is imported.

use kerfmeter::Category;
use kerfmeter::protocol::advice::{Advice, Wording, in_words_of};
use kerfmeter_plan::PlanError as RustPlanError;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

create_exception!(
    kerfmeter,
    KerfmeterError,
    PyException,
    "Every error of this package."
);
create_exception!(
    kerfmeter,
    CommunicationError,
    KerfmeterError,
    "The link to the device failed: the port, a timeout, the protocol, a restarted device."
);
create_exception!(
    kerfmeter,
    DeviceError,
    KerfmeterError,
    "The device refused a request, or could not finish it."
);
create_exception!(
    kerfmeter,
    DeviceFaultError,
    DeviceError,
    "The device stopped on a fault and latched it; `fault` names it (e.g. \"NoMotion\")."
);
/// `kerfmeter.BadArgumentError`, a subclass of both `KerfmeterError` and `ValueError`.
pub struct BadArgumentError;

/// The class, made once.
static BAD_ARGUMENT: PyOnceLock<Py<PyType>> = PyOnceLock::new();

impl BadArgumentError {
    /// The class object.
    fn type_object(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
        let ty = BAD_ARGUMENT.get_or_try_init(py, || {
            let bases = PyTuple::new(
                py,
                [
                    py.get_type::<KerfmeterError>(),
                    py.get_type::<PyValueError>(),
                ],
            )?;
            let namespace = PyDict::new(py);
            namespace.set_item(
                "__doc__",
                "A bad argument or parameter; the message names it and its allowed range.",
            )?;
            namespace.set_item("__module__", "kerfmeter")?;
            let class = py
                .get_type::<PyType>()
                .call1(("BadArgumentError", bases, namespace))?;
            Ok::<_, PyErr>(class.cast_into::<PyType>()?.unbind())
        })?;
        Ok(ty.bind(py).clone())
    }

    /// The exception with `message`.
    pub fn new_err(message: impl Into<String>) -> PyErr {
        let message = message.into();
        Python::attach(|py| match Self::type_object(py) {
            Ok(ty) => PyErr::from_type(ty, message),
            Err(e) => e,
        })
    }
}
create_exception!(
    kerfmeter,
    PlanError,
    KerfmeterError,
    "A cutting plan or another file could not be read, dilated or written."
);

/// Add the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("KerfmeterError", py.get_type::<KerfmeterError>())?;
    m.add("CommunicationError", py.get_type::<CommunicationError>())?;
    m.add("DeviceError", py.get_type::<DeviceError>())?;
    m.add("DeviceFaultError", py.get_type::<DeviceFaultError>())?;
    m.add("BadArgumentError", BadArgumentError::type_object(py)?)?;
    m.add("PlanError", py.get_type::<PlanError>())?;
    Ok(())
}

/// The Python exception for a library error: by its category, a fault with its name in `fault`.
pub fn device(py: Python<'_>, error: kerfmeter::Error) -> PyErr {
    let message = in_python_words(&error);
    if matches!(error, kerfmeter::Error::Cancelled) {
        return PyKeyboardInterrupt::new_err(message);
    }
    if let Some(fault) = error.fault() {
        let err = DeviceFaultError::new_err(message);
        let name = format!("{fault:?}");
        if let Err(e) = err.value(py).setattr("fault", name) {
            return e;
        }
        return err;
    }
    match error.category() {
        Category::Communication => CommunicationError::new_err(message),
        Category::Device => DeviceError::new_err(message),
        Category::Usage => BadArgumentError::new_err(message),
        Category::File => PlanError::new_err(message),
    }
}

/// The Python exception for a plan error: a bad argument or the plan's own problem.
pub fn plan(error: RustPlanError) -> PyErr {
    match error {
        RustPlanError::InvalidArgument(m) => BadArgumentError::new_err(in_python_words(&m)),
        other => PlanError::new_err(in_python_words(&other)),
    }
}

/// Python's words for the libraries' advice: each thing to do next named as the method or
/// keyword argument that does it.
struct PythonApi;

static PYTHON: PythonApi = PythonApi;

impl Wording for PythonApi {
    fn advice(&self, advice: Advice) -> &'static str {
        match advice {
            Advice::ClearFault => "`clear_fault()`",
            Advice::Reset => "`reset_kerfmeter()`",
            Advice::ConfirmZero => "`confirm_hub_at_zero()`",
            Advice::Status => "`status()`",
            Advice::ConfigGet => "`kerfmeter config get`",
            Advice::LowerForce => "`force_n`",
            Advice::ForceParam => "force_n",
            Advice::Recompensate => "if_compensated=\"recompensate\"",
            Advice::AlreadyCompensatedOk => "if_compensated=\"dilate_anyway\"",
            Advice::LightBurnApply => "`kerfmeter lightburn apply`",
            _ => "(see docs/python.md)",
        }
    }
}

/// `message` shown with its advice in Python's words.
fn in_python_words(message: &impl std::fmt::Display) -> String {
    in_words_of(&PYTHON, || message.to_string())
}
