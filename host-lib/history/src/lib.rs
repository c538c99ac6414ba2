//! The Kerfmeter's measurement history: every kerf measured, kept in an SQLite file (one
//! machine's history, the default) or, with the `postgres` feature, on a PostgreSQL server (a
//! site's shared history, `History::connect`), listed newest first, with a drift warning when
//! a label's kerf moves beyond its usual spread. Both back ends hold the same records with the
//! same meaning behind the same methods.
//!
//! ```no_run
//! use kerfmeter_history::{History, NewRecord, Query};
//!
//! let mut history = History::open_creating_folder(&History::default_path()?)?;
//! let id = history.record(&NewRecord {
//!     device_id: "esp32c3:A0:76:4E:12:34:56".into(),
//!     firmware: "0.1.0".into(),
//!     label: Some("birch 3 mm, CO2 40 W".into()),
//!     thickness_mm: 3.0,
//!     force_n: 36.6,
//!     kerf_um: 152.3,
//!     ci95_um: None,
//!     flags: vec![],
//!     simulated: false,
//! })?;
//! if let Some(drift) = history.drift_at(id)? {
//!     eprintln!("warning: {}", drift.message);
//! }
//! let listing = history.listing(&Query { label: None, limit: Some(20), simulated: false })?;
//! println!("{}", serde_json::to_string(&listing).unwrap());
//! # Ok::<(), kerfmeter_history::Error>(())
//! ```
//!
//! # Design
//!
//! - Where: [`History::default_path`] is `history.sqlite3` in a `kerfmeter` folder of the user's
//!   data directory (`~/.local/share` on Linux, `~/Library/Application Support` on macOS,
//!   `%APPDATA%` on Windows); the command-line tool's `--db` or `KERFMETER_DB` overrides it.
//! - Crash safety: every write is one transaction. The journal is SQLite's default rollback
//!   journal with `synchronous = FULL`: a committed record is on disk when [`History::record`]
//!   returns, and a process killed mid-write leaves the database as of its last commit (the
//!   journal is rolled back at the next open). The rollback journal rather than WAL: at rest the
//!   history is one file, safe to copy, and it works on any file system (WAL needs shared
//!   memory, which network file systems lack). Writers wait for each other up to 5 s.
//! - Versions: the schema's version is `PRAGMA user_version`, its migrations are in one place
//!   (`schema`), and a database from a newer build is refused untouched ([`Error::NewerSchema`]).
//! - Order: records are listed newest first by their id (the order they were committed in), not
//!   by their time, which a clock set back would reorder.
//! - Simulated measurements are kept apart: each record says whether it was `simulated`, and
//!   a [`Query`] and the drift rule see one population at a time (real ones by default), so a
//!   twin's results never shift a real label's baseline, nor appear among real results unless
//!   asked for.
//! - Drift: see [`drift`] for the rule and why.
//!
//! # PostgreSQL (feature `postgres`)
//!
//! - The client: `postgres`, the synchronous client of the rust-postgres project, the most used
//!   and maintained pure-Rust PostgreSQL client (no libpq to install). Its blocking API matches
//!   rusqlite's, so one blocking [`History`] serves both back ends and the app layer does not
//!   change its calls. It drives `tokio-postgres` on a private current-thread runtime: hence a
//!   feature, off by default, so that a program embedding only the SQLite history builds no
//!   async runtime. An async client (`tokio-postgres` itself, `sqlx`) would force one on every
//!   caller for a few writes a minute. No TLS yet.
//! - Writes: one transaction each, as in SQLite; the server's own durability (`fsync`,
//!   `synchronous_commit`) says when a commit is on disk.
//! - Versions: the one row of the table `kerfmeter_schema` (PostgreSQL has no `user_version`),
//!   migrated in one transaction under an advisory lock, so that a site's PCs opening a new
//!   database at once create it once; a newer database, or one holding a `measurements` table
//!   without a version, is refused before anything is written.
//! - Order: ids come from an identity column, increasing in the order records are inserted
//!   (two PCs committing at the same instant may commit in the other order).
//! - Names: [`History::path`] is the server's URL without its password, and errors name it so.

#[cfg(feature = "postgres")]
use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::time::Duration;

use rusqlite::{Connection, OpenFlags, OptionalExtension, Row, params};
use serde::Serialize;

pub mod drift;
mod error;
#[cfg(feature = "postgres")]
mod postgres;
mod schema;

pub use drift::Drift;
pub use error::Error;
pub use schema::SCHEMA_VERSION;

/// Longest label, characters.
pub const MAX_LABEL_CHARS: usize = 200;

/// A measurement to record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NewRecord {
    /// What identifies the device (its board and serial number, or `twin`).
    pub device_id: String,
    /// Its firmware version, `major.minor.patch`.
    pub firmware: String,
    /// What was measured: material, cutter, settings ([`check_label`]).
    pub label: Option<String>,
    /// Sheet thickness, mm.
    pub thickness_mm: f64,
    /// Joint force the kerf is for, N.
    pub force_n: f64,
    /// The kerf (the mean of the runs), µm.
    pub kerf_um: f64,
    /// Half-width of its 95 % confidence interval, µm (`None` for one run).
    pub ci95_um: Option<f64>,
    /// The quality flags of its runs, by name.
    pub flags: Vec<String>,
    /// Measured by the simulated device.
    pub simulated: bool,
}

/// A recorded measurement; its JSON is the server's `history` record: `id`, `time` and the
/// measurement's fields side by side.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Record {
    /// Its id in the database (increasing in commit order).
    pub id: i64,
    /// When it was recorded, RFC 3339 in UTC.
    pub time: String,
    /// What was measured.
    #[serde(flatten)]
    pub measurement: NewRecord,
}

/// Which records to list.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Query {
    /// Only this label's.
    pub label: Option<String>,
    /// At most this many, newest first (`None`: all).
    pub limit: Option<usize>,
    /// The simulated records instead of the real ones.
    pub simulated: bool,
}

/// What `kerfmeter history --json` prints and the server's `history` method returns.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Listing {
    /// The records, newest first.
    pub records: Vec<Record>,
    /// The drift of each listed label's newest measurement, where it drifts.
    pub drift: Vec<Drift>,
}

/// The folder `path` names, if it names one (a bare file name is in the current folder).
fn folder_of(path: &Path) -> Option<&Path> {
    path.parent().filter(|d| !d.as_os_str().is_empty())
}

/// Where a history is kept: the back end behind [`History`]'s methods.
#[derive(Debug)]
enum Store {
    /// An SQLite file (the embedded default, one machine's history).
    Sqlite(Connection),
    /// A PostgreSQL server (a site's shared history): its client needs `&mut` to query, and a
    /// listing only reads, so it is borrowed per call (a [`History`] is used by one thread at a
    /// time, as rusqlite's connection is).
    #[cfg(feature = "postgres")]
    Postgres(Box<RefCell<postgres::Postgres>>),
}

/// An open history database.
#[derive(Debug)]
pub struct History {
    conn: Store,
    /// The SQLite file, or the PostgreSQL URL without its password.
    path: PathBuf,
    /// Opened by [`History::open_to_read`]: [`History::record`] is refused.
    read_only: bool,
}

/// How long a writer waits for another writer, or a reader for a commit, before giving up.
const BUSY_TIMEOUT: Duration = Duration::from_secs(5);

/// Check a label: not blank, at most [`MAX_LABEL_CHARS`] characters, no control characters.
pub fn check_label(label: &str) -> Result<(), Error> {
    if label.trim().is_empty() {
        return Err(Error::Invalid("a label must not be blank".into()));
    }
    if label.chars().count() > MAX_LABEL_CHARS {
        return Err(Error::Invalid(format!(
            "a label has at most {MAX_LABEL_CHARS} characters"
        )));
    }
    if label.chars().any(char::is_control) {
        return Err(Error::Invalid(
            "a label must not hold control characters (new lines, tabs, ...)".into(),
        ));
    }
    Ok(())
}

// Each method matches on the back end; without the `postgres` feature there is one.
#[cfg_attr(
    not(feature = "postgres"),
    allow(clippy::infallible_destructuring_match)
)]
impl History {
    /// The default database: `kerfmeter/history.sqlite3` in the user's data directory.
    pub fn default_path() -> Result<PathBuf, Error> {
        let dir = dirs::data_dir().ok_or(Error::NoDataDir)?;
        Ok(dir.join("kerfmeter").join("history.sqlite3"))
    }

    /// Whether the database at `path` has a folder to be made in ([`Error::NoFolder`] if not),
    /// and is not itself a folder ([`Error::IsFolder`]): checked before a measurement, so that a
    /// mistyped path is said before the gauge is used.
    pub fn check_folder(path: &Path) -> Result<(), Error> {
        if path.is_dir() {
            return Err(Error::IsFolder {
                path: path.to_owned(),
            });
        }
        match folder_of(path) {
            Some(dir) if !dir.is_dir() => Err(Error::NoFolder {
                path: dir.to_owned(),
            }),
            _ => Ok(()),
        }
    }

    /// [`History::open`], making the database's folder first: for the user's data directory
    /// ([`History::default_path`]), which may not exist yet. A path the user gave is opened with
    /// [`History::open`], so that a mistyped folder is said, not made.
    pub fn open_creating_folder(path: &Path) -> Result<History, Error> {
        if let Some(dir) = folder_of(path) {
            std::fs::create_dir_all(dir).map_err(|source| Error::Folder {
                path: dir.to_owned(),
                source,
            })?;
        }
        History::open(path)
    }

    /// Open (or create) the database at `path`, in a folder that exists, and bring its schema up
    /// to date.
    pub fn open(path: &Path) -> Result<History, Error> {
        History::check_folder(path)?;
        let sql = |source| Error::sqlite(path, source);
        let mut conn = Connection::open(path).map_err(sql)?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(sql)?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(sql)?;
        schema::migrate(&mut conn, path)?;
        Ok(History {
            conn: Store::Sqlite(conn),
            path: path.to_owned(),
            read_only: false,
        })
    }

    /// Open the database at `path` only to read it ([`History::record`] is refused): nothing is
    /// created or written, and no write lock is taken, so a listing waits only while a writer
    /// commits, and works on a database the user may only read (a shared one, a read-only
    /// mount). An empty file (no schema yet) reads as an empty history, and is left as it is.
    /// A file that does not exist, or whose folder does not, is [`Error::NoHistory`] (the
    /// caller decides whether that is an empty history: the user's data directory before the
    /// first measurement); a folder is [`Error::IsFolder`]; a newer or foreign database is
    /// refused as [`History::open`] refuses it. The exceptions write: a database that needs a
    /// migration (an older version), or a recovery after a crash (its journal left behind), is
    /// opened by [`History::open`], which can do them.
    pub fn open_to_read(path: &Path) -> Result<History, Error> {
        match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => {
                return Err(Error::IsFolder {
                    path: path.to_owned(),
                });
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(Error::NoHistory {
                    path: path.to_owned(),
                    folder: folder_of(path).filter(|d| !d.is_dir()).map(Path::to_owned),
                });
            }
            // Otherwise SQLite reads it, or says why it cannot (no permission, ...).
            _ => {}
        }
        let sql = |source| Error::sqlite(path, source);
        let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
        let conn = Connection::open_with_flags(path, flags).map_err(sql)?;
        conn.busy_timeout(BUSY_TIMEOUT).map_err(sql)?;
        let conn = match schema::version(&conn, path) {
            Ok(SCHEMA_VERSION) => conn,
            // No schema yet (an empty file): an empty history, made in memory.
            Ok(0) => {
                drop(conn);
                let mut empty = Connection::open_in_memory().map_err(sql)?;
                schema::migrate(&mut empty, path)?;
                empty
            }
            Ok(_) | Err(Error::Sqlite { .. }) => return History::open(path),
            Err(e) => return Err(e),
        };
        Ok(History {
            conn: Store::Sqlite(conn),
            path: path.to_owned(),
            read_only: true,
        })
    }

    /// Connect to a site's shared history on the PostgreSQL server `url` names
    /// (`postgres://USER[:PASSWORD]@HOST[:PORT]/DB`), and bring its schema up to date (or refuse
    /// a newer or foreign one untouched, as [`History::open`] does). The same methods, records
    /// and rules as an SQLite file; see the `postgres` module's docs for what differs.
    #[cfg(feature = "postgres")]
    pub fn connect(url: &str) -> Result<History, Error> {
        let db = postgres::Postgres::connect(url)?;
        Ok(History {
            path: PathBuf::from(db.shown()),
            conn: Store::Postgres(Box::new(RefCell::new(db))),
            read_only: false,
        })
    }

    /// Whether `location` names a PostgreSQL server (`postgres://` or `postgresql://`) rather
    /// than an SQLite file.
    pub fn is_url(location: &str) -> bool {
        location.starts_with("postgres://") || location.starts_with("postgresql://")
    }

    /// The database's file (for a PostgreSQL history, its URL without the password).
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn sql(&self, source: rusqlite::Error) -> Error {
        Error::sqlite(&self.path, source)
    }

    /// Record `record` now (one transaction); its id.
    pub fn record(&mut self, record: &NewRecord) -> Result<i64, Error> {
        if self.read_only {
            return Err(Error::Invalid(format!(
                "{} was opened only to read: nothing can be recorded through it",
                self.path.display()
            )));
        }
        check_record(record)?;
        let time = jiff::Timestamp::now()
            .round(jiff::Unit::Millisecond)
            .map_err(|e| Error::Invalid(format!("the clock: {e}")))?
            .to_string();
        let conn = match &mut self.conn {
            Store::Sqlite(conn) => conn,
            #[cfg(feature = "postgres")]
            Store::Postgres(db) => return db.get_mut().record(record, &time),
        };
        let flags = serde_json::to_string(&record.flags).expect("strings serialize");
        let path = &self.path;
        let tx = conn.transaction().map_err(|e| Error::sqlite(path, e))?;
        tx.execute(
            "INSERT INTO measurements (time, device_id, firmware, label, thickness_mm, force_n,
                 kerf_um, ci95_um, flags, simulated)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10)",
            params![
                time,
                record.device_id,
                record.firmware,
                record.label,
                record.thickness_mm,
                record.force_n,
                record.kerf_um,
                record.ci95_um,
                flags,
                record.simulated
            ],
        )
        .map_err(|e| Error::sqlite(path, e))?;
        let id = tx.last_insert_rowid();
        tx.commit().map_err(|e| Error::sqlite(path, e))?;
        Ok(id)
    }

    /// The records `query` asks for, newest first.
    pub fn list(&self, query: &Query) -> Result<Vec<Record>, Error> {
        let limit = query
            .limit
            .map_or(-1, |n| i64::try_from(n).unwrap_or(i64::MAX));
        let conn = match &self.conn {
            Store::Sqlite(conn) => conn,
            #[cfg(feature = "postgres")]
            Store::Postgres(db) => return db.borrow_mut().list(query),
        };
        let mut stmt = conn
            .prepare_cached(&format!(
                "SELECT {COLUMNS} FROM measurements
                 WHERE simulated = ?1 AND (?2 IS NULL OR label = ?2)
                 ORDER BY id DESC LIMIT ?3"
            ))
            .map_err(|e| self.sql(e))?;
        let rows = stmt
            .query_map(params![query.simulated, query.label, limit], read_record)
            .map_err(|e| self.sql(e))?;
        rows.collect::<Result<_, _>>().map_err(|e| self.sql(e))
    }

    /// One record by its id.
    pub fn get(&self, id: i64) -> Result<Option<Record>, Error> {
        let conn = match &self.conn {
            Store::Sqlite(conn) => conn,
            #[cfg(feature = "postgres")]
            Store::Postgres(db) => return db.borrow_mut().get(id),
        };
        conn.query_row(
            &format!("SELECT {COLUMNS} FROM measurements WHERE id = ?1"),
            [id],
            read_record,
        )
        .optional()
        .map_err(|e| self.sql(e))
    }

    /// The records and the drift of each listed label's newest measurement.
    pub fn listing(&self, query: &Query) -> Result<Listing, Error> {
        let records = self.list(query)?;
        let mut drift = Vec::new();
        let mut seen: Vec<&str> = Vec::new();
        for r in &records {
            let Some(label) = r.measurement.label.as_deref() else {
                continue;
            };
            if seen.contains(&label) {
                continue;
            }
            seen.push(label);
            if let Some(d) = self.drift(label, query.simulated)? {
                drift.push(d);
            }
        }
        Ok(Listing { records, drift })
    }

    /// The drift of `label`'s newest measurement (real, or `simulated`), if it drifts.
    pub fn drift(&self, label: &str, simulated: bool) -> Result<Option<Drift>, Error> {
        let newest = self.list(&Query {
            label: Some(label.to_owned()),
            limit: Some(1),
            simulated,
        })?;
        match newest.first() {
            Some(r) => self.drift_of(r),
            None => Ok(None),
        }
    }

    /// The drift of record `id` from its label's measurements before it, if it drifts (an
    /// unlabelled record has no baseline: only a label says two measurements are alike).
    pub fn drift_at(&self, id: i64) -> Result<Option<Drift>, Error> {
        match self.get(id)? {
            Some(r) => self.drift_of(&r),
            None => Ok(None),
        }
    }

    /// No drift for an unlabelled record, nor for an untrusted one (flagged other than
    /// `decimated`): a flagged run's kerf says more about that run (a slip, a jam missed) than
    /// about the cutter, so a drift warning on it would blame the cutter for a bad measurement;
    /// its flags already say it is suspect. The baseline is the label's trusted records at the
    /// same thickness and force: the kerf a run measures grows as the force squeezes the
    /// contact, so a record at another force is not the same measurement.
    fn drift_of(&self, record: &Record) -> Result<Option<Drift>, Error> {
        let m = &record.measurement;
        let Some(label) = m.label.as_deref() else {
            return Ok(None);
        };
        if !trusted(m) {
            return Ok(None);
        }
        let conn = match &self.conn {
            Store::Sqlite(conn) => conn,
            #[cfg(feature = "postgres")]
            Store::Postgres(db) => {
                let baseline = db.borrow_mut().baseline(record, label)?;
                return Ok(drift::drift(label, m.kerf_um, &baseline));
            }
        };
        let mut stmt = conn
            .prepare_cached(&format!(
                "SELECT {COLUMNS} FROM measurements
                 WHERE simulated = ?1 AND label = ?2 AND id < ?3
                   AND abs(thickness_mm - ?4) < 1e-9 AND abs(force_n - ?5) < 1e-9
                 ORDER BY id DESC"
            ))
            .map_err(|e| self.sql(e))?;
        let mut baseline = Vec::with_capacity(drift::BASELINE_RECORDS);
        let rows = stmt
            .query_map(
                params![m.simulated, label, record.id, m.thickness_mm, m.force_n],
                read_record,
            )
            .map_err(|e| self.sql(e))?;
        for row in rows {
            let r = row.map_err(|e| self.sql(e))?.measurement;
            if trusted(&r) {
                baseline.push(r.kerf_um);
                if baseline.len() == drift::BASELINE_RECORDS {
                    break;
                }
            }
        }
        Ok(drift::drift(label, m.kerf_um, &baseline))
    }
}

/// Whether a record is trusted: flagged with nothing but advisory flags
/// ([`QualityFlags::ADVISORY`](kerfmeter_protocol::QualityFlags::ADVISORY)).
pub(crate) fn trusted(record: &NewRecord) -> bool {
    record
        .flags
        .iter()
        .all(|f| kerfmeter_protocol::QualityFlags::is_advisory_name(f))
}

/// The columns [`read_record`] reads, in its order.
pub(crate) const COLUMNS: &str = "id, time, device_id, firmware, label, thickness_mm, force_n, kerf_um, \
                       ci95_um, flags, simulated";

fn read_record(row: &Row<'_>) -> rusqlite::Result<Record> {
    let flags: String = row.get(9)?;
    let flags = serde_json::from_str(&flags).map_err(|e| {
        rusqlite::Error::FromSqlConversionFailure(9, rusqlite::types::Type::Text, Box::new(e))
    })?;
    Ok(Record {
        id: row.get(0)?,
        time: row.get(1)?,
        measurement: NewRecord {
            device_id: row.get(2)?,
            firmware: row.get(3)?,
            label: row.get(4)?,
            thickness_mm: row.get(5)?,
            force_n: row.get(6)?,
            kerf_um: row.get(7)?,
            ci95_um: row.get(8)?,
            flags,
            simulated: row.get(10)?,
        },
    })
}

/// Refuse a record SQLite would store wrongly (a NaN becomes NULL) or that means nothing.
fn check_record(r: &NewRecord) -> Result<(), Error> {
    if let Some(label) = &r.label {
        check_label(label)?;
    }
    let numbers = [
        ("thickness_mm", Some(r.thickness_mm)),
        ("force_n", Some(r.force_n)),
        ("kerf_um", Some(r.kerf_um)),
        ("ci95_um", r.ci95_um),
    ];
    for (name, value) in numbers {
        if value.is_some_and(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!(
                "{name} must be a finite number to be recorded"
            )));
        }
    }
    Ok(())
}
