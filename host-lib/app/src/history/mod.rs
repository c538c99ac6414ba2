//! Recording a measurement into the history (`kerfmeter_history`), for a measurement and a job
//! from any front end: the database is the one the user named (the CLI's `--db` or
//! `KERFMETER_DB`), else the user's data directory's.
//!
//! A measurement is never lost to the history: a failure to record is a warning in the report
//! ([`Recorded::error`]), and the command still succeeds with its kerf. The record says who
//! measured it: the device's board with its USB serial number (the ESP32-C3's is its MAC
//! address), or with its port when the system tells no serial number, and `twin` on the
//! simulated device, whose records are kept apart (`simulated`).
//!
//! Build a [`Measured`] from a run and call [`record`]; the [`Recorded`] it hands back serializes
//! as a report's `history` key. Listing is `kerfmeter_history::History::listing`, whose JSON is
//! the server's `history` method's result.

pub mod listing;

use std::fmt;
use std::path::{Path, PathBuf};

use kerfmeter::Kerfmeter;
use kerfmeter::protocol::KerfResult;
use kerfmeter_history::{Drift, History, NewRecord};
use serde::Serialize;

/// A measurement to record: the joint it was made for and its runs.
#[derive(Debug, Clone, Copy)]
pub struct Measured<'a> {
    /// What was measured (material, cutter).
    pub label: Option<&'a str>,
    /// Sheet thickness, mm.
    pub thickness_mm: f64,
    /// Joint force, N.
    pub force_n: f64,
    /// The kerf (mean of the runs), µm.
    pub kerf_um: f64,
    /// Half-width of its 95 % confidence interval, µm.
    pub ci95_um: Option<f64>,
    /// The runs (their flags are recorded).
    pub runs: &'a [KerfResult],
}

/// Where a measurement was recorded, or why not, and its drift; in the JSON as `history`.
#[derive(Debug, Clone, Serialize)]
pub struct Recorded {
    /// The database (`null` when there is none: no data directory).
    #[serde(serialize_with = "crate::lossy_path::option")]
    pub db: Option<PathBuf>,
    /// The record's id (`null` when it could not be recorded).
    pub id: Option<i64>,
    /// Why it could not be recorded.
    pub error: Option<String>,
    /// The drift warning, when the label's kerf left its usual spread.
    pub drift: Option<Drift>,
}

/// Check a label (`--label`, `label`): not blank, no control characters, at most 200 characters.
pub fn parse_label(label: &str) -> Result<String, String> {
    kerfmeter_history::check_label(label).map_err(|e| e.to_string())?;
    Ok(label.to_owned())
}

/// Record `m`, measured by `meter`, in the history at `named` (the one the user named; `None`:
/// the user's data directory's), as simulated when `meter` is the twin ([`is_twin`]).
pub fn record(named: Option<&Path>, meter: &Kerfmeter, m: &Measured<'_>) -> Recorded {
    let db = match named.map_or_else(History::default_path, |db| Ok(db.to_owned())) {
        Ok(db) => db,
        Err(e) => {
            return Recorded {
                db: None,
                id: None,
                error: Some(e.to_string()),
                drift: None,
            };
        }
    };
    let new = new_record(meter, m);
    // The user's data directory may not have its folder yet; a path the user gave must.
    let open = if named.is_some() {
        History::open
    } else {
        History::open_creating_folder
    };
    let outcome = open(&db).and_then(|mut h| {
        let id = h.record(&new)?;
        // A drift that cannot be worked out is no reason to call the record lost.
        Ok((id, h.drift_at(id).ok().flatten()))
    });
    match outcome {
        Ok((id, drift)) => Recorded {
            db: Some(db),
            id: Some(id),
            error: None,
            drift,
        },
        Err(e) => Recorded {
            db: Some(db),
            id: None,
            error: Some(e.to_string()),
            drift: None,
        },
    }
}

/// The board name the digital twin gives in `GetInfo`, in process or behind a PTY
/// (`kerfmeter-twin`): its measurements are simulated wherever they come from.
const TWIN_BOARD: &str = "twin";

/// Whether `meter` is the digital twin (by the board it names), wherever it is reached.
pub fn is_twin(meter: &Kerfmeter) -> bool {
    meter.cached_info().hardware.board.as_str() == TWIN_BOARD
}

/// The record of `m`.
fn new_record(meter: &Kerfmeter, m: &Measured<'_>) -> NewRecord {
    let info = meter.cached_info();
    let simulated = is_twin(meter);
    let v = info.firmware;
    let mut flags: Vec<String> = Vec::new();
    for name in m.runs.iter().flat_map(|r| r.flags.names()) {
        if !flags.iter().any(|f| f == name) {
            flags.push(name.to_owned());
        }
    }
    NewRecord {
        device_id: device_id(meter, simulated),
        firmware: format!("{}.{}.{}", v.major, v.minor, v.patch),
        label: m.label.map(str::to_owned),
        thickness_mm: m.thickness_mm,
        force_n: m.force_n,
        kerf_um: m.kerf_um,
        ci95_um: m.ci95_um,
        flags,
        simulated,
    }
}

/// The device's board and USB serial number, or its port when the system tells none.
fn device_id(meter: &Kerfmeter, simulated: bool) -> String {
    let board = meter.cached_info().hardware.board.as_str();
    if simulated {
        return board.to_owned();
    }
    let serial = serialport::available_ports()
        .ok()
        .into_iter()
        .flatten()
        .find(|p| p.port_name == meter.path())
        .and_then(|p| match p.port_type {
            serialport::SerialPortType::UsbPort(usb) => usb.serial_number,
            _ => None,
        });
    match serial {
        Some(serial) => format!("{board}:{serial}"),
        None => format!("{board}@{}", meter.path()),
    }
}

impl fmt::Display for Recorded {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.id, &self.error) {
            (Some(id), _) => {
                let db = self.db.as_deref().unwrap_or_else(|| "?".as_ref());
                write!(f, "recorded as #{id} in {}", db.display())?;
            }
            (None, error) => write!(
                f,
                "warning: not recorded in the history: {}",
                error.as_deref().unwrap_or("unknown error")
            )?,
        }
        if let Some(d) = &self.drift {
            write!(f, "\nwarning: {}", d.message)?;
        }
        Ok(())
    }
}
