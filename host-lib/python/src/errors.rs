//! The Python exceptions: one base, `KerfmeterError`, and a subclass per kind of failure, each
//! carrying the library's own message (which says what to do).

use kerfmeter::Category;
use kerfmeter_plan::PlanError as RustPlanError;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;

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
create_exception!(
    kerfmeter,
    BadArgumentError,
    KerfmeterError,
    "A bad argument or parameter; the message names it and its allowed range."
);
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
    m.add("BadArgumentError", py.get_type::<BadArgumentError>())?;
    m.add("PlanError", py.get_type::<PlanError>())?;
    Ok(())
}

/// The Python exception for a library error: by its category, a fault with its name in `fault`.
pub fn device(py: Python<'_>, error: kerfmeter::Error) -> PyErr {
    let message = error.to_string();
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
        RustPlanError::InvalidArgument(m) => BadArgumentError::new_err(m),
        other => PlanError::new_err(other.to_string()),
    }
}
