//! Paths in JSON reports: a report never fails to serialize over a file name that is not UTF-8.
//! Such a name is written with U+FFFD in place of the bytes that are not, and
//! [`any_replaced`] tells a front end to say so (the CLI prints a note on stderr).

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use serde::Serializer;

/// Set once a path was written lossily.
static REPLACED: AtomicBool = AtomicBool::new(false);

/// One path.
pub fn one<S: Serializer>(path: &Path, s: S) -> Result<S::Ok, S::Error> {
    let text = path.to_string_lossy();
    if matches!(text, Cow::Owned(_)) {
        REPLACED.store(true, Ordering::Relaxed);
    }
    s.serialize_str(&text)
}

/// A path that may be missing (`null`).
pub fn option<S: Serializer>(path: &Option<PathBuf>, s: S) -> Result<S::Ok, S::Error> {
    match path {
        Some(path) => one(path, s),
        None => s.serialize_none(),
    }
}

/// A list of paths.
pub fn list<S: Serializer>(paths: &[PathBuf], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeSeq;
    let mut seq = s.serialize_seq(Some(paths.len()))?;
    for path in paths {
        seq.serialize_element(&Lossy(path))?;
    }
    seq.end()
}

/// A path serialized by [`one`].
struct Lossy<'a>(&'a Path);

impl serde::Serialize for Lossy<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        one(self.0, s)
    }
}

/// Whether a path serialized so far in this process was written lossily.
pub fn any_replaced() -> bool {
    REPLACED.load(Ordering::Relaxed)
}
