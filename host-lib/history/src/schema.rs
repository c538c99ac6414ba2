//! The database's schema and its migrations, in one place.
//!
//! The schema's version is SQLite's `PRAGMA user_version`. [`MIGRATIONS`]`[i]` takes a database
//! from version `i` to `i + 1`; [`migrate`] applies the missing ones in one transaction (so a
//! crash mid-migration leaves the old version whole) and refuses a database written by a newer
//! build ([`Error::NewerSchema`]) without touching it. A new version appends one migration here;
//! none is ever edited once released.

use std::path::Path;

use rusqlite::{Connection, TransactionBehavior};

use crate::error::Error;

/// Each step, in order: `MIGRATIONS[i]` takes version `i` to `i + 1`.
const MIGRATIONS: &[&str] = &[
    // 1: the measurements.
    "CREATE TABLE measurements (
        id           INTEGER PRIMARY KEY,
        time         TEXT    NOT NULL,
        device_id    TEXT    NOT NULL,
        firmware     TEXT    NOT NULL,
        label        TEXT,
        thickness_mm REAL    NOT NULL,
        force_n      REAL    NOT NULL,
        kerf_um      REAL    NOT NULL,
        ci95_um      REAL,
        flags        TEXT    NOT NULL,
        simulated    INTEGER NOT NULL
    );
    CREATE INDEX measurements_by_label ON measurements (simulated, label, id);",
];

/// The schema version this build writes (and the newest it can read).
pub const SCHEMA_VERSION: i64 = MIGRATIONS.len() as i64;

/// The schema version of the database at `path` (open as `conn`, perhaps read-only): 0 for one
/// with no tables (an empty file); refused when it is newer than this build's, or when it holds
/// tables but no version (not a Kerfmeter history).
pub fn version(conn: &Connection, path: &Path) -> Result<i64, Error> {
    let sql = |source| Error::sqlite(path, source);
    let found: i64 = conn
        .query_row("PRAGMA user_version", [], |r| r.get(0))
        .map_err(sql)?;
    if found > SCHEMA_VERSION {
        return Err(Error::NewerSchema {
            path: path.to_owned(),
            found,
            known: SCHEMA_VERSION,
        });
    }
    if found == 0 {
        let tables: i64 = conn
            .query_row("SELECT count(*) FROM sqlite_master", [], |r| r.get(0))
            .map_err(sql)?;
        if tables > 0 {
            return Err(Error::Foreign {
                path: path.to_owned(),
            });
        }
    }
    Ok(found)
}

/// Bring the database at `path` (open as `conn`) up to [`SCHEMA_VERSION`].
pub fn migrate(conn: &mut Connection, path: &Path) -> Result<(), Error> {
    let sql = |source| Error::sqlite(path, source);
    // IMMEDIATE: the write lock is taken before the version is read, so two processes opening
    // a new database at once cannot both migrate it.
    let tx = conn
        .transaction_with_behavior(TransactionBehavior::Immediate)
        .map_err(sql)?;
    let found = version(&tx, path)?;
    for (from, step) in MIGRATIONS.iter().enumerate().skip(found as usize) {
        tx.execute_batch(step).map_err(sql)?;
        tx.pragma_update(None, "user_version", from as i64 + 1)
            .map_err(sql)?;
    }
    tx.commit().map_err(sql)
}
