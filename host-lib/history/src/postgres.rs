//! The history on a PostgreSQL server: a makerspace's one history, shared by the PCs that drive
//! its cutters (feature `postgres`; see [`History::connect`](crate::History::connect)).
//!
//! The same records, the same meaning and the same rules as the SQLite file: one transaction per
//! write, records listed newest first by id, the simulated ones apart, the drift rule of
//! [`crate::drift`]. What differs is only where it lives:
//!
//! - The client is `postgres` (why: see the crate's docs); no TLS yet: a site's server on its
//!   own network, or a tunnel.
//! - The schema's version is the one row of the table `kerfmeter_schema` (PostgreSQL has no
//!   `user_version`); [`MIGRATIONS`]`[i]` takes it from `i` to `i + 1`, all missing ones applied
//!   in one transaction under an advisory lock, so that the PCs of a site opening a new database
//!   at once migrate it once. A database written by a newer build is refused before anything is
//!   written ([`Error::NewerSchema`]); a database that holds a `measurements` table but no
//!   version is not a Kerfmeter history ([`Error::Foreign`]).
//! - Ids come from an identity column: increasing in the order records are inserted; two PCs
//!   committing at the same instant may commit in the other order (SQLite's writers take turns,
//!   so there the id order is the commit order). The listing stays by id: the newest records a
//!   site inserted, never reordered by a PC's clock.
//! - Times are kept as the same RFC 3339 text as in SQLite, so that a record reads back exactly
//!   as it was written, whichever back end holds it.

use std::path::PathBuf;
use std::time::Duration;

use postgres::{Client, NoTls, Row};

use crate::error::Error;
use crate::{NewRecord, Query, Record, trusted};

/// Each step, in order: `MIGRATIONS[i]` takes version `i` to `i + 1` (as SQLite's, in
/// PostgreSQL's types).
const MIGRATIONS: &[&str] = &[
    // 1: the measurements.
    "CREATE TABLE measurements (
        id           BIGINT GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
        time         TEXT             NOT NULL,
        device_id    TEXT             NOT NULL,
        firmware     TEXT             NOT NULL,
        label        TEXT,
        thickness_mm DOUBLE PRECISION NOT NULL,
        force_n      DOUBLE PRECISION NOT NULL,
        kerf_um      DOUBLE PRECISION NOT NULL,
        ci95_um      DOUBLE PRECISION,
        flags        TEXT             NOT NULL,
        simulated    BOOLEAN          NOT NULL
    );
    CREATE INDEX measurements_by_label ON measurements (simulated, label, id);",
];

/// The key of the advisory lock that makes migrations one at a time (any constant: "kerf").
const MIGRATION_LOCK: i64 = 0x6b65_7266;

/// How long connecting may take when the URL does not say (`connect_timeout`), s.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// The columns [`read_record`] reads, in its order.
const COLUMNS: &str = crate::COLUMNS;

/// A connection to a history on a PostgreSQL server.
pub(crate) struct Postgres {
    client: Client,
    /// What connected it: a connection the server closed (a restart, a network cut) is made
    /// again before the next call.
    config: postgres::Config,
    /// The URL without its password: what messages name.
    shown: String,
}

impl std::fmt::Debug for Postgres {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Postgres")
            .field("url", &self.shown)
            .finish()
    }
}

/// `url` as messages show it: user, hosts, ports and database, never the password.
fn shown(config: &postgres::Config) -> String {
    let hosts: Vec<String> = config
        .get_hosts()
        .iter()
        .zip(config.get_ports().iter().chain(std::iter::repeat(&5432)))
        .map(|(host, port)| match host {
            postgres::config::Host::Tcp(name) => format!("{name}:{port}"),
            #[cfg(unix)]
            postgres::config::Host::Unix(dir) => format!("{}:{port}", dir.display()),
        })
        .collect();
    format!(
        "postgres://{}@{}/{}",
        config.get_user().unwrap_or(""),
        hosts.join(","),
        config.get_dbname().unwrap_or("")
    )
}

impl Postgres {
    /// Connect to the server `url` names (`postgres://USER[:PASSWORD]@HOST[:PORT]/DB`, or
    /// libpq's `key=value` form) and bring the schema up to date.
    pub(crate) fn connect(url: &str) -> Result<Postgres, Error> {
        let mut config: postgres::Config = url.parse().map_err(|source| Error::Postgres {
            url: "the history's PostgreSQL URL".into(),
            source,
        })?;
        if config.get_connect_timeout().is_none() {
            config.connect_timeout(CONNECT_TIMEOUT);
        }
        let shown = shown(&config);
        let client = config.connect(NoTls).map_err(|source| Error::Postgres {
            url: shown.clone(),
            source,
        })?;
        let mut db = Postgres {
            client,
            config,
            shown,
        };
        db.migrate()?;
        Ok(db)
    }

    /// The URL without its password.
    pub(crate) fn shown(&self) -> &str {
        &self.shown
    }

    /// The connection, made again first when the server closed it. Only a closed connection is
    /// made again, before a call: a call that failed is never sent twice (had its commit reached
    /// the server, a second one would record it twice), its error goes to the caller.
    fn client(&mut self) -> Result<&mut Client, Error> {
        if self.client.is_closed() {
            self.client = self
                .config
                .connect(NoTls)
                .map_err(|source| Error::Postgres {
                    url: self.shown.clone(),
                    source,
                })?;
        }
        Ok(&mut self.client)
    }

    fn err(&self, source: postgres::Error) -> Error {
        Error::Postgres {
            url: self.shown.clone(),
            source,
        }
    }

    /// Bring the schema up to [`crate::SCHEMA_VERSION`] in one transaction, or refuse a newer or
    /// foreign database without writing anything.
    fn migrate(&mut self) -> Result<(), Error> {
        let shown = self.shown.clone();
        let err = |source| Error::Postgres {
            url: shown.clone(),
            source,
        };
        let mut tx = self.client.transaction().map_err(err)?;
        tx.execute("SELECT pg_advisory_xact_lock($1)", &[&MIGRATION_LOCK])
            .map_err(err)?;
        let tables = tx
            .query_one(
                "SELECT to_regclass('kerfmeter_schema') IS NOT NULL,
                        to_regclass('measurements') IS NOT NULL",
                &[],
            )
            .map_err(err)?;
        let (versioned, measurements): (bool, bool) = (tables.get(0), tables.get(1));
        let found: i64 = if versioned {
            tx.query_one("SELECT version FROM kerfmeter_schema", &[])
                .map_err(err)?
                .get(0)
        } else if measurements {
            return Err(Error::Foreign {
                path: PathBuf::from(&shown),
            });
        } else {
            tx.batch_execute(
                "CREATE TABLE kerfmeter_schema (version BIGINT NOT NULL);
                 INSERT INTO kerfmeter_schema VALUES (0);",
            )
            .map_err(err)?;
            0
        };
        if found > crate::SCHEMA_VERSION {
            // Dropping the transaction rolls it back: nothing was written.
            return Err(Error::NewerSchema {
                path: PathBuf::from(&shown),
                found,
                known: crate::SCHEMA_VERSION,
            });
        }
        if found == crate::SCHEMA_VERSION {
            return tx.rollback().map_err(err);
        }
        for (from, step) in MIGRATIONS.iter().enumerate().skip(found as usize) {
            tx.batch_execute(step).map_err(err)?;
            tx.execute(
                "UPDATE kerfmeter_schema SET version = $1",
                &[&(from as i64 + 1)],
            )
            .map_err(err)?;
        }
        tx.commit().map_err(err)
    }

    /// Record `record` at `time` in one transaction; its id.
    pub(crate) fn record(&mut self, record: &NewRecord, time: &str) -> Result<i64, Error> {
        let flags = serde_json::to_string(&record.flags).expect("strings serialize");
        let shown = self.shown.clone();
        let err = |source| Error::Postgres {
            url: shown.clone(),
            source,
        };
        let mut tx = self.client()?.transaction().map_err(err)?;
        let row = tx
            .query_one(
                "INSERT INTO measurements (time, device_id, firmware, label, thickness_mm, force_n,
                     kerf_um, ci95_um, flags, simulated)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10)
                 RETURNING id",
                &[
                    &time,
                    &record.device_id,
                    &record.firmware,
                    &record.label,
                    &record.thickness_mm,
                    &record.force_n,
                    &record.kerf_um,
                    &record.ci95_um,
                    &flags,
                    &record.simulated,
                ],
            )
            .map_err(err)?;
        tx.commit().map_err(err)?;
        Ok(row.get(0))
    }

    /// The records `query` asks for, newest first.
    pub(crate) fn list(&mut self, query: &Query) -> Result<Vec<Record>, Error> {
        let limit = query.limit.map(|n| i64::try_from(n).unwrap_or(i64::MAX));
        let rows = self
            .client()?
            .query(
                &format!(
                    "SELECT {COLUMNS} FROM measurements
                     WHERE simulated = $1 AND ($2::TEXT IS NULL OR label = $2)
                     ORDER BY id DESC LIMIT $3"
                ),
                &[&query.simulated, &query.label, &limit],
            )
            .map_err(|e| self.err(e))?;
        rows.iter().map(|r| self.read_record(r)).collect()
    }

    /// One record by its id.
    pub(crate) fn get(&mut self, id: i64) -> Result<Option<Record>, Error> {
        let row = self
            .client()?
            .query_opt(
                &format!("SELECT {COLUMNS} FROM measurements WHERE id = $1"),
                &[&id],
            )
            .map_err(|e| self.err(e))?;
        row.map(|r| self.read_record(&r)).transpose()
    }

    /// The kerfs of the trusted records like `record` before it (same population, label,
    /// thickness and force), newest first, at most [`crate::drift::BASELINE_RECORDS`].
    pub(crate) fn baseline(&mut self, record: &Record, label: &str) -> Result<Vec<f64>, Error> {
        let m = &record.measurement;
        let mut baseline = Vec::with_capacity(crate::drift::BASELINE_RECORDS);
        // Read in pages (the untrusted ones are skipped in Rust, by the protocol's flag names),
        // so that a label with thousands of records is not read whole.
        let mut before = record.id;
        loop {
            let rows = self
                .client()?
                .query(
                    &format!(
                        "SELECT {COLUMNS} FROM measurements
                         WHERE simulated = $1 AND label = $2 AND id < $3
                           AND abs(thickness_mm - $4) < 1e-9 AND abs(force_n - $5) < 1e-9
                         ORDER BY id DESC LIMIT 64"
                    ),
                    &[&m.simulated, &label, &before, &m.thickness_mm, &m.force_n],
                )
                .map_err(|e| self.err(e))?;
            for row in &rows {
                let r = self.read_record(row)?;
                before = r.id;
                if trusted(&r.measurement) {
                    baseline.push(r.measurement.kerf_um);
                    if baseline.len() == crate::drift::BASELINE_RECORDS {
                        return Ok(baseline);
                    }
                }
            }
            if rows.len() < 64 {
                return Ok(baseline);
            }
        }
    }

    fn read_record(&self, row: &Row) -> Result<Record, Error> {
        let flags: String = row.try_get(9).map_err(|e| self.err(e))?;
        let flags = serde_json::from_str(&flags).map_err(|e| {
            Error::Invalid(format!(
                "{}: a record's flags are not a JSON list: {e}",
                self.shown
            ))
        })?;
        let text = |i| -> Result<String, Error> { row.try_get(i).map_err(|e| self.err(e)) };
        let real = |i| -> Result<f64, Error> { row.try_get(i).map_err(|e| self.err(e)) };
        Ok(Record {
            id: row.try_get(0).map_err(|e| self.err(e))?,
            time: text(1)?,
            measurement: NewRecord {
                device_id: text(2)?,
                firmware: text(3)?,
                label: row.try_get(4).map_err(|e| self.err(e))?,
                thickness_mm: real(5)?,
                force_n: real(6)?,
                kerf_um: real(7)?,
                ci95_um: row.try_get(8).map_err(|e| self.err(e))?,
                flags,
                simulated: row.try_get(10).map_err(|e| self.err(e))?,
            },
        })
    }
}
