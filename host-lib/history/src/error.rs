//! What can go wrong with the history, each with a message that says what to do.

use std::path::{Path, PathBuf};

/// A history error.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The database was written by a newer kerfmeter; it is left untouched. (`path` is the
    /// SQLite file, or the PostgreSQL server's URL without its password.)
    #[error(
        "{}: the history database has schema version {found}, but this kerfmeter knows versions up to {known}: it was written by a newer kerfmeter. Upgrade kerfmeter to read it, or give another history with --db (the database was left untouched)",
        path.display()
    )]
    NewerSchema {
        /// The database.
        path: PathBuf,
        /// Its version.
        found: i64,
        /// The newest version this build knows.
        known: i64,
    },
    /// The database (an SQLite file, or a PostgreSQL database holding a `measurements` table)
    /// is one of something else.
    #[error(
        "{}: this database is not a kerfmeter history (it has tables but no history schema); give another history with --db (it was left untouched)",
        path.display()
    )]
    Foreign {
        /// The database.
        path: PathBuf,
    },
    /// SQLite failed (the file is not a database, the disk is full, it is locked too long, ...).
    #[error("{}: history database: {source}", path.display())]
    Sqlite {
        /// The database.
        path: PathBuf,
        /// What SQLite said.
        source: rusqlite::Error,
    },
    /// The PostgreSQL server failed or could not be reached (refused, authentication, a lost
    /// connection, ...).
    #[cfg(feature = "postgres")]
    #[error("{url}: history database: {source}")]
    Postgres {
        /// The server's URL, without its password.
        url: String,
        /// What the client said.
        source: postgres::Error,
    },
    /// The database's folder could not be made.
    #[error("{}: cannot create the history's folder: {source}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The database's folder does not exist (a path given by the user: not made).
    #[error(
        "{}: the history's folder does not exist; give a file in an existing folder (--db or KERFMETER_DB)",
        path.display()
    )]
    NoFolder {
        /// The folder.
        path: PathBuf,
    },
    /// There is no history at the path given to read: the file, or its folder, does not exist.
    /// (A mistyped path is not an empty history; the caller decides where one not made yet
    /// is: the user's data directory before the first measurement.)
    #[error(
        "no history at {}: {}; check the path (--db or KERFMETER_DB)",
        path.display(),
        absent(folder.as_deref())
    )]
    NoHistory {
        /// The database asked for.
        path: PathBuf,
        /// Its folder, when that is what does not exist.
        folder: Option<PathBuf>,
    },
    /// The path names a folder, not a database file.
    #[error(
        "{} is a folder, not a history file; give a file (--db or KERFMETER_DB), such as {}",
        path.display(),
        path.join("history.sqlite3").display()
    )]
    IsFolder {
        /// The folder.
        path: PathBuf,
    },
    /// The system names no data directory for this user.
    #[error(
        "this system names no data directory for the history (no HOME?); give a file with --db or KERFMETER_DB"
    )]
    NoDataDir,
    /// A record or a query is out of range.
    #[error("{0}")]
    Invalid(String),
}

/// What does not exist of a history asked for: its file, or its `folder`.
fn absent(folder: Option<&Path>) -> String {
    match folder {
        Some(dir) => format!("the folder {} does not exist", dir.display()),
        None => "the file does not exist (nothing was recorded there, or the path is mistyped)"
            .to_string(),
    }
}

impl Error {
    /// An SQLite error on the database at `path`.
    pub(crate) fn sqlite(path: &Path, source: rusqlite::Error) -> Self {
        Error::Sqlite {
            path: path.to_owned(),
            source,
        }
    }
}
