//! The `kerfmeter` Python package's native module (`kerfmeter._kerfmeter`), bound with PyO3.
//!
//! It exposes the `kerfmeter` library's client ([`meter`]: the three calls, the rest of what the
//! device does, repeated measurements, the in-process twin) and the plan crate's dilation and
//! gauge drawing ([`plan`]) to Python, with the library's error messages ([`errors`]).
//!
//! Design notes:
//!
//! * **Workspace member.** The crate is built by `cargo build/clippy/doc --workspace` like the
//!   others, so it cannot drift from the library it binds and shares the workspace's lock file
//!   and target directory (the wheel build reuses them). PyO3's build script needs a `python3`
//!   on the PATH for its build configuration (any CPython 3.9 or later). The workspace's
//!   `.cargo/config.toml` sets `PYO3_BUILD_EXTENSION_MODULE`, as maturin does, so every cargo
//!   build links the module as an extension, to no libpython (no python3-dev needed). The
//!   library target has no Rust tests (`test = false`): a test harness would have to link
//!   libpython; the tests are pytest's, in `host-lib/python/tests/`, run by `cargo xtask test`.
//! * **The GIL** is released (`Python::detach`) for every call that waits on the device. A long
//!   run re-takes it at each status poll (every 20 ms) only to call the `progress` callable and
//!   to check for signals: Ctrl-C (or an exception raised by `progress`) stops the run through
//!   [`kerfmeter::Kerfmeter::run_kerfmeter_until`], which tells the device to abort, and the
//!   Python exception is raised once the motor is stopped.
//! * **Reports** are the Rust types' serde serialisations turned into Python dicts (through
//!   JSON), so their keys are the CLI's `--json` keys.

use pyo3::prelude::*;

pub mod errors;
pub mod meter;
pub mod plan;

/// Turn a serde-serialisable value into the Python object its JSON stands for (dicts, lists,
/// numbers, strings, `None`).
pub(crate) fn to_py<'py>(
    py: Python<'py>,
    value: &impl serde::Serialize,
) -> PyResult<Bound<'py, PyAny>> {
    let json = serde_json::to_string(value)
        .map_err(|e| errors::KerfmeterError::new_err(format!("cannot serialise a report: {e}")))?;
    py.import("json")?.call_method1("loads", (json,))
}

/// The native module.
#[pymodule]
fn _kerfmeter(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    meter::register(m)?;
    plan::register(m)?;
    Ok(())
}
