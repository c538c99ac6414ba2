//! The one place a command's report reaches stdout: as its text (`Display`) or, with `--json`, as
//! its `serde` form. Both come from the same typed value, so they cannot disagree. Writing stops
//! the program quietly when stdout is closed (`kerfmeter … | head`).

use std::fmt;
use std::io::Write as _;

use kerfmeter_plan::compensation::FoundCompensation;
use serde::Serialize;

use crate::error::{CliError, JobSoFar};

/// How a report is laid out as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JsonLayout {
    /// Indented, fields in the report's own order.
    Pretty,
    /// Indented, every object's keys sorted.
    PrettySorted,
    /// One line, every object's keys sorted.
    CompactSorted,
}

/// What a command hands back: text via `Display`, `--json` via `Serialize`.
pub trait Report: fmt::Display + Serialize {
    /// The JSON layout scripts already read for this command.
    const JSON: JsonLayout;

    /// Whether the command succeeded, once its report is printed (the self-test can fail
    /// after reporting every item).
    fn verdict(&self) -> Result<(), CliError> {
        Ok(())
    }
}

/// Print `report` as JSON (`json`) or as its text, then give its verdict.
pub fn emit<R: Report>(json: bool, report: &R) -> Result<(), CliError> {
    if json {
        print_line(&to_json(report, R::JSON));
        lossy_path::warn_if_replaced();
    } else {
        print_line(&report.to_string());
    }
    report.verdict()
}

/// `value` as JSON in `layout`. A report never fails to print: should one not serialize, the
/// line is an `{"error": …}` object saying so (whatever the command wrote stays written).
pub fn to_json(value: &impl Serialize, layout: JsonLayout) -> String {
    let text = match layout {
        JsonLayout::Pretty => serde_json::to_string_pretty(value),
        JsonLayout::PrettySorted => serde_json::to_value(value).and_then(|v| {
            // A `serde_json::Value` keeps its objects' keys sorted.
            serde_json::to_string_pretty(&v)
        }),
        JsonLayout::CompactSorted => {
            serde_json::to_value(value).and_then(|v| serde_json::to_string(&v))
        }
    };
    text.unwrap_or_else(|e| {
        serde_json::json!({
            "error": format!("the report could not be written as JSON ({e}); the command itself finished"),
        })
        .to_string()
    })
}

/// Paths in JSON reports, written lossily (the library's serializers), and the note that says so.
pub mod lossy_path {
    pub use kerfmeter_app::lossy_path::{list, one, option};

    /// Tell stderr when a path above was written lossily.
    pub fn warn_if_replaced() {
        if kerfmeter_app::lossy_path::any_replaced() {
            eprintln!(
                "note: a file name in this report is not UTF-8; the JSON shows it with U+FFFD in \
                 place of the bytes that are not"
            );
        }
    }
}

pub use kerfmeter_app::result::{ResultJson, ResultsTable, result_json};

/// Print one line to stdout; end the program quietly if no one reads it any more.
pub fn print_line(line: &str) {
    if writeln!(std::io::stdout().lock(), "{line}").is_err() {
        // The reader went away: there is no one left to tell anything.
        std::process::exit(0);
    }
}

/// A failed command with `--json`: its message and the device fault or idle conditions behind
/// it, if any.
#[derive(Serialize)]
pub struct ErrorReport {
    /// The error's message.
    pub error: String,
    /// The device fault, named as in the protocol.
    pub fault: Option<String>,
    /// The idle conditions that refused the request (`no-magnet`, `driver-fault`, ...); empty
    /// when none did.
    pub conditions: Vec<&'static str>,
    /// The compensation a plan already carries, when that is why it was refused (what
    /// `dilate --json` reports as `compensation_found`); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compensation_found: Option<FoundCompensation>,
    /// A job that stopped after measuring: its kerf, history record and files written
    /// (`kerf_um`, `history`, `written` beside the error); absent otherwise.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub job_so_far: Option<JobSoFar>,
}
