//! `kerfmeter history`: the measurements recorded by `run` and `job`, newest first, with the
//! drift warning of each label whose newest kerf left its usual spread. The real measurements,
//! or with `--sim` the simulated ones (they are never mixed). The device is not opened.
//!
//! The listing tells the truth about its file: a history in the user's data directory that does
//! not exist yet is "no measurements recorded yet", but one the user named (`--db`,
//! `KERFMETER_DB`) that does not exist, or is a folder, is refused (exit 4) as such: a mistyped
//! path is not an empty history. Nothing is created or written to list.

use std::fmt;
use std::path::PathBuf;

use clap::Args;
use kerfmeter_history::{Error, History, Listing, Query, Record};
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use kerfmeter_app::history::parse_label;

use super::dilate::plural;

#[derive(Args)]
pub struct HistoryArgs {
    /// Only this label's measurements.
    #[arg(long, value_parser = parse_label)]
    label: Option<String>,
    /// The newest this many.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    limit: u32,
}

/// The records and drift warnings; its JSON is the server's `history` result plus `db`.
#[derive(Serialize)]
pub struct HistoryReport {
    /// The database read.
    pub db: PathBuf,
    /// The simulated records (`--sim`) rather than the real ones.
    pub simulated: bool,
    /// The records and the drift warnings.
    #[serde(flatten)]
    pub listing: Listing,
    /// Whether the database exists (if not, nothing was recorded yet), for the text.
    #[serde(skip)]
    exists: bool,
    /// The label asked for, for the text.
    #[serde(skip)]
    label: Option<String>,
    /// The most records asked for, for the text.
    #[serde(skip)]
    limit: u32,
}

/// List the history as `args` say: one the user named must exist.
pub fn run(g: &Global, args: &HistoryArgs) -> Result<HistoryReport, CliError> {
    read(g, g.sim, args.label.clone(), args.limit, g.db.is_some())
}

/// The newest `limit` records of the history `g` names (of `label` only, if given), the
/// `simulated` ones or the real ones, with the drift warnings: `kerfmeter serve`'s `history`.
/// The server records into that history, so one whose file is not made yet is empty (its
/// folder must exist, unless it is the user's data directory's).
pub fn list(
    g: &Global,
    simulated: bool,
    label: Option<String>,
    limit: u32,
) -> Result<HistoryReport, CliError> {
    read(g, simulated, label, limit, false)
}

/// [`list`], the history refused when it does not exist if `must_exist`; else a history that
/// does not exist is empty when it is the default one, or only its file is missing.
fn read(
    g: &Global,
    simulated: bool,
    label: Option<String>,
    limit: u32,
    must_exist: bool,
) -> Result<HistoryReport, CliError> {
    let db = g.db_path()?;
    let query = Query {
        label: label.clone(),
        limit: Some(limit as usize),
        simulated,
    };
    // Read-only: listing creates and writes nothing.
    let (listing, exists) = match History::open_to_read(&db) {
        Ok(history) => (history.listing(&query)?, true),
        Err(Error::NoHistory { folder, .. })
            if !must_exist && (g.db.is_none() || folder.is_none()) =>
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
        label,
        limit,
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
                write!(f, " (simulated ones are listed with --sim)")?;
            }
            return Ok(());
        }
        let n = records.len();
        let order = if n == self.limit as usize {
            format!(" (--limit {n}: there may be more)")
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
            plural(n),
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

impl Report for HistoryReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
