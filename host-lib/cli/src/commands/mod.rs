//! One module per `kerfmeter` command. Each takes its arguments and returns a typed report (see
//! [`crate::output::Report`]); `main` prints it as text or JSON.

pub mod abort;
pub mod bringup;
pub mod clear_fault;
pub mod config;
pub mod confirm_zero;
pub mod cut;
pub mod dilate;
pub mod gauge;
pub mod gcode;
pub mod history;
pub mod info;
pub mod job;
pub mod kerf;
pub mod lightburn;
pub mod map;
pub mod reset;
pub mod run;
pub mod self_test;
pub mod serve;
pub mod status;

use std::fmt;

use serde::Serialize;

use crate::output::{JsonLayout, Report};

/// What a command that only acts reports: `{"ok":true}`, or a sentence saying what is done.
#[derive(Serialize)]
pub struct Done {
    /// The sentence printed as text.
    #[serde(skip)]
    pub done: &'static str,
    /// What the user must still know or do, printed after `done` and in the JSON (absent when
    /// there is nothing).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<&'static str>,
    /// Always true: a failure is an error, not a report.
    pub ok: bool,
}

impl Done {
    /// The report of a command that did what `done` says.
    pub fn new(done: &'static str) -> Self {
        Done {
            done,
            warning: None,
            ok: true,
        }
    }

    /// ... and that leaves the user `warning` to heed.
    pub fn with_warning(done: &'static str, warning: &'static str) -> Self {
        Done {
            warning: Some(warning),
            ..Done::new(done)
        }
    }
}

impl fmt::Display for Done {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.done)?;
        match self.warning {
            Some(w) => write!(f, "; {w}"),
            None => Ok(()),
        }
    }
}

impl Report for Done {
    const JSON: JsonLayout = JsonLayout::CompactSorted;
}
