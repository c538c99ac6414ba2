//! Kerfmeter's application layer: what the command line, the server and Python each do, once.
//!
//! The device library (`kerfmeter`), the plan crate (`kerfmeter_plan`) and the history
//! (`kerfmeter_history`) each know one thing. A front end needs them together: a measurement
//! asked with a joint, a number of gauges and a label, recorded in the history; a plan dilated
//! by a kerf with its cut rules. Those requests and their reports live here, typed and
//! serializable, so that each front end only turns its own input into a request (the CLI's
//! flags, the server's JSON-RPC params deserialized straight into the request types, Python's
//! keyword arguments) and prints the report its own way. No clap, axum, tokio or pyo3 type is
//! used here (`cargo xtask check-deps` checks it).

pub mod bringup;
pub mod dilate;
mod error;
pub mod gauge;
pub mod gcode;
pub mod history;
pub mod job;
pub mod lossy_path;
pub mod measure;
pub mod request;
pub mod result;
pub mod self_test;

pub use error::Error;
