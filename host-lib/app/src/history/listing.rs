//! Listing the history: the newest records, of one label or all, the real or the simulated
//! ones, with the drift warnings ([`ListRequest`], [`HistoryReport`]): the CLI's `history` and
//! the server's `history` method.
//!
//! The listing tells the truth about its file: a history in the user's data directory that does
//! not exist yet is "no measurements recorded yet", but one the user named that does not exist,
//! or is a folder, is refused as such (when it must exist): a mistyped path is not an empty
//! history. Nothing is created or written to list.

use std::fmt;
use std::path::{Path, PathBuf};

use kerfmeter::protocol::advice::Advice;
use kerfmeter_history::{Error as HistoryError, History, Listing, Query, Record};
use serde::{Deserialize, Serialize};

use crate::Error;
use crate::request::text_or_number;

/// The most records one listing may ask for.
pub const MAX_LIMIT: u32 = 100_000;

/// Which records to list.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ListRequest {
    /// Only this label's measurements.
    pub label: Option<String>,
    /// The newest this many (1 to [`MAX_LIMIT`]).
    #[serde(deserialize_with = "text_or_number::u32")]
    pub limit: u32,
}

impl Default for ListRequest {
    fn default() -> Self {
        Self {
            label: None,
            limit: 50,
        }
    }
}

impl ListRequest {
    /// The request, its label and limit checked.
    pub fn checked(&self) -> Result<&Self, Error> {
        if let Some(label) = &self.label {
            kerfmeter_history::check_label(label)?;
        }
        if !(1..=MAX_LIMIT).contains(&self.limit) {
            return Err(kerfmeter::Error::invalid(format!(
                "limit must be between 1 and {MAX_LIMIT}, got {}",
                self.limit
            ))
            .into());
        }
        Ok(self)
    }
}

/// The records and drift warnings; its JSON is the server's `history` result plus `db`.
#[derive(Serialize)]
pub struct HistoryReport {
    /// The database read.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub db: PathBuf,
    /// The simulated records (`--sim`) rather than the real ones.
    pub simulated: bool,
    /// The records and the drift warnings.
    #[serde(flatten)]
    pub listing: Listing,
    /// Whether the database exists (if not, nothing was recorded yet), for the text.
    #[serde(skip)]
    pub exists: bool,
    /// The label asked for, for the text.
    #[serde(skip)]
    pub label: Option<String>,
    /// The most records asked for, for the text.
    #[serde(skip)]
    pub limit: u32,
}

/// The records `req` asks for, in the history at `named` (the one the user named; `None`: the
/// user's data directory's), the `simulated` ones or the real ones. A history whose file does not
/// exist is refused if `must_exist`; else it is empty when it is the default one, or only its
/// file is missing (a server records into it later).
pub fn list(
    named: Option<&Path>,
    req: &ListRequest,
    simulated: bool,
    must_exist: bool,
) -> Result<HistoryReport, Error> {
    req.checked()?;
    let db = named.map_or_else(History::default_path, |db| Ok(db.to_owned()))?;
    let query = Query {
        label: req.label.clone(),
        limit: Some(req.limit as usize),
        simulated,
    };
    // Read-only: listing creates and writes nothing.
    let (listing, exists) = match History::open_to_read(&db) {
        Ok(history) => (history.listing(&query)?, true),
        Err(HistoryError::NoHistory { folder, .. })
            if !must_exist && (named.is_none() || folder.is_none()) =>
        {
            (Listing::default(), false)
        }
        Err(e) => return Err(e.into()),
    };
    Ok(HistoryReport {
        db,
        simulated,
        listing,
        exists,
        label: req.label.clone(),
        limit: req.limit,
    })
}

impl fmt::Display for HistoryReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = if self.simulated { "simulated" } else { "real" };
        let labelled = match &self.label {
            Some(label) => format!(" labelled {label:?}"),
            None => String::new(),
        };
        let records = &self.listing.records;
        if !self.exists {
            return write!(
                f,
                "no measurements recorded yet (`kerfmeter run` and `job` record them in {})",
                self.db.display()
            );
        }
        if records.is_empty() {
            write!(
                f,
                "no {kind} measurements{labelled} in {}",
                self.db.display()
            )?;
            if !self.simulated {
                write!(
                    f,
                    " (simulated ones are listed with {})",
                    Advice::Param("sim")
                )?;
            }
            return Ok(());
        }
        let n = records.len();
        let order = if n == self.limit as usize {
            format!(" ({} {n}: there may be more)", Advice::Param("limit"))
        } else {
            ", newest first".to_owned()
        };
        let which = if n == self.limit as usize {
            "the newest "
        } else {
            ""
        };
        writeln!(
            f,
            "{which}{n} {kind} measurement{}{labelled} in {}{order}",
            crate::dilate::plural(n),
            self.db.display()
        )?;
        write!(
            f,
            "{:>5}  {:<20}  {:>8} {:>7} {:>6} {:>6}  {:<20}  {:<16}  flags",
            "id", "time (UTC)", "kerf µm", "± CI", "mm", "N", "label", "device"
        )?;
        for r in records {
            write!(f, "\n{}", Row(r))?;
        }
        for d in &self.listing.drift {
            write!(f, "\nwarning: {}", d.message)?;
        }
        Ok(())
    }
}

/// One record as a table row.
struct Row<'a>(&'a Record);

impl fmt::Display for Row<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (id, m) = (self.0.id, &self.0.measurement);
        // 2026-12-02T04:40:12.345Z → 2026-12-02 04:40:12
        let time: String = self.0.time.replace('T', " ").chars().take(19).collect();
        let ci = m.ci95_um.map_or("-".into(), |c| format!("{c:.1}"));
        let flags = if m.flags.is_empty() {
            "ok".into()
        } else {
            m.flags.join(",")
        };
        write!(
            f,
            "{:>5}  {:<20}  {:>8.1} {:>7} {:>6.2} {:>6.1}  {:<20}  {:<16}  {flags}",
            id,
            time,
            m.kerf_um,
            ci,
            m.thickness_mm,
            m.force_n,
            m.label.as_deref().unwrap_or("-"),
            m.device_id,
        )
    }
}
