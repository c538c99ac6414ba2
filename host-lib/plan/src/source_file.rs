//! A plan's source file read again when the dilated plan is written, so that its text need not
//! be held in memory while the cuts are dilated (with the dilated contours, the largest things a
//! large plan holds).
//!
//! The input file is never modified by this tool, but another program could change it between
//! reading and writing: its length and a hash of its bytes are recorded when it is first read,
//! and the text read again must match them, or the plan is refused (the caller writes into a
//! temporary file and keeps nothing on an error). Read whole ([`SourceFile::read_again`]), or
//! copied piece by piece as the output is written ([`SourceFile::copier`]), when the hash is
//! checked at the end.

use std::fs::File;
use std::hash::{DefaultHasher, Hasher};
use std::io::{BufReader, Read, Write};
use std::path::{Path, PathBuf};

use crate::error::{PlanError, Result};

/// A source file as first read: where it is, its length and a hash of its bytes.
#[derive(Debug, Clone)]
pub(crate) struct SourceFile {
    path: PathBuf,
    len_bytes: u64,
    hash: u64,
}

impl SourceFile {
    /// The file at `path`, whose bytes were read as `bytes`.
    pub(crate) fn new(path: &Path, bytes: &[u8]) -> Self {
        SourceFile {
            path: path.to_owned(),
            len_bytes: bytes.len() as u64,
            hash: hash_of(bytes),
        }
    }

    /// The file's text, read again: refused unless it is the text first read.
    pub(crate) fn read_again(&self) -> Result<String> {
        let bytes = std::fs::read(&self.path).map_err(|e| self.unreadable(&e))?;
        if bytes.len() as u64 != self.len_bytes || hash_of(&bytes) != self.hash {
            return Err(self.changed());
        }
        String::from_utf8(bytes).map_err(|_| self.changed())
    }

    /// A reader that copies the file's bytes out in order, checking them as they go.
    pub(crate) fn copier(&self) -> Result<Copier<'_>> {
        let file = File::open(&self.path).map_err(|e| self.unreadable(&e))?;
        let len_bytes = file.metadata().map_err(|e| self.unreadable(&e))?.len();
        if len_bytes != self.len_bytes {
            return Err(self.changed());
        }
        Ok(Copier {
            source: self,
            reader: BufReader::new(file),
            pos: 0,
            hasher: DefaultHasher::new(),
        })
    }

    fn unreadable(&self, e: &std::io::Error) -> PlanError {
        PlanError::Svg(format!(
            "cannot read the plan again to write the dilated plan ({e}); nothing was written"
        ))
    }

    fn changed(&self) -> PlanError {
        PlanError::Svg(
            "the plan file changed while it was being dilated; nothing was written: run the command again"
                .into(),
        )
    }
}

/// A hash of `bytes` (std's SipHash with fixed keys: the same for the same bytes within a run).
fn hash_of(bytes: &[u8]) -> u64 {
    let mut h = DefaultHasher::new();
    h.write(bytes);
    h.finish()
}

/// Copies a [`SourceFile`]'s bytes to a writer in order (see [`SourceFile::copier`]).
pub(crate) struct Copier<'s> {
    source: &'s SourceFile,
    reader: BufReader<File>,
    /// How far the file has been read.
    pos: u64,
    hasher: DefaultHasher,
}

impl Copier<'_> {
    /// Copy the bytes from where the copy is to `end` into `out` (`out`'s errors are
    /// [`PlanError::Write`]), or skip them when `out` is `None`.
    pub(crate) fn copy_to(&mut self, end: u64, mut out: Option<&mut dyn Write>) -> Result<()> {
        let mut buf = [0u8; 8192];
        while self.pos < end {
            let want = (end - self.pos).min(buf.len() as u64) as usize;
            let got = self
                .reader
                .read(&mut buf[..want])
                .map_err(|e| self.source.unreadable(&e))?;
            if got == 0 {
                return Err(self.source.changed());
            }
            self.hasher.write(&buf[..got]);
            if let Some(out) = out.as_deref_mut() {
                out.write_all(&buf[..got])
                    .map_err(|source| PlanError::Write {
                        path: PathBuf::new(),
                        source,
                    })?;
            }
            self.pos += got as u64;
        }
        Ok(())
    }

    /// Copy the rest of the file into `out`, and check that it is the file first read.
    pub(crate) fn finish(mut self, out: &mut dyn Write) -> Result<()> {
        self.copy_to(self.source.len_bytes, Some(out))?;
        let mut rest = [0u8; 1];
        let more = self
            .reader
            .read(&mut rest)
            .map_err(|e| self.source.unreadable(&e))?;
        if more != 0 || self.hasher.finish() != self.source.hash {
            return Err(self.source.changed());
        }
        Ok(())
    }
}
