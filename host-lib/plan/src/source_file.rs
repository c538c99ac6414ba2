//! A plan's source file read again when the dilated plan is written, so that its text need not
//! be held in memory while the cuts are dilated (with the dilated contours, the largest things a
//! large plan holds).
//!
//! The input file is never modified by this tool, but another program could change it between
//! reading and writing: the file is opened once and read again through the same handle (so a
//! file renamed over it, as editors save, or a symlink turned elsewhere is not what is read), and
//! its length and a hash of its bytes are recorded when it is first read; the text read again
//! must match them, or the plan is refused (the output is then incomplete: the CLI and the
//! Python binding write into a temporary file and keep nothing). Read whole
//! ([`SourceFile::read_again`]), or copied piece by piece as the output is written
//! ([`SourceFile::copier`]), when the hash is checked at the end. Only a regular file is read
//! again: a pipe or a device is read once and held in memory, as before ([`read_plan_file`]).
//!
//! The hash is std's `RandomState` hasher, keyed afresh for each file: it only has to tell,
//! within one run, whether the bytes are the ones first read.

use std::fs::File;
use std::hash::{BuildHasher, Hasher, RandomState};
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::error::{PlanError, Result};

/// A source file as first read: its handle, its length and a hash of its bytes.
#[derive(Debug)]
pub(crate) struct SourceFile {
    path: PathBuf,
    file: File,
    len_bytes: u64,
    keys: RandomState,
    hash: u64,
}

/// Read the plan file at `path` once: its bytes, and a [`SourceFile`] to read it again by where
/// it is a regular file (`None` for a pipe or a device, which cannot be read twice).
pub(crate) fn read_plan_file(path: &Path) -> Result<(Vec<u8>, Option<SourceFile>)> {
    let io = |source| PlanError::Io {
        path: path.to_owned(),
        source,
    };
    let mut file = File::open(path).map_err(io)?;
    let regular = file.metadata().map_err(io)?.is_file();
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes).map_err(io)?;
    refuse_empty(path, &bytes)?;
    let source = regular.then(|| {
        let keys = RandomState::new();
        SourceFile {
            path: path.to_owned(),
            file,
            len_bytes: bytes.len() as u64,
            hash: hash_of(&keys, &bytes),
            keys,
        }
    });
    Ok((bytes, source))
}

/// A plan file with nothing in it (or only blanks) is said to be empty, not taken for a drawing
/// that lacks its units or its cuts.
pub(crate) fn refuse_empty(path: &Path, bytes: &[u8]) -> Result<()> {
    if !bytes.iter().all(u8::is_ascii_whitespace) {
        return Ok(());
    }
    Err(PlanError::Io {
        path: path.to_owned(),
        source: std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "it is empty: there is no drawing in it (was it saved?)",
        ),
    })
}

impl SourceFile {
    /// The file's text, read again: refused unless it is the text first read.
    pub(crate) fn read_again(&self) -> Result<String> {
        let mut bytes = Vec::with_capacity(self.len_bytes as usize);
        self.rewound()?
            .read_to_end(&mut bytes)
            .map_err(|e| self.unreadable(e))?;
        if bytes.len() as u64 != self.len_bytes || hash_of(&self.keys, &bytes) != self.hash {
            return Err(self.changed());
        }
        String::from_utf8(bytes).map_err(|_| self.changed())
    }

    /// A reader that copies the file's bytes out in order, checking them as they go.
    pub(crate) fn copier(&self) -> Result<Copier<'_>> {
        Ok(Copier {
            source: self,
            reader: BufReader::new(self.rewound()?),
            pos: 0,
            hasher: self.keys.build_hasher(),
        })
    }

    /// The file's handle, back at its start (a clone shares the position: one reader at a time).
    fn rewound(&self) -> Result<File> {
        let mut file = self.file.try_clone().map_err(|e| self.unreadable(e))?;
        file.seek(SeekFrom::Start(0))
            .map_err(|e| self.unreadable(e))?;
        Ok(file)
    }

    fn unreadable(&self, source: std::io::Error) -> PlanError {
        PlanError::Io {
            path: self.path.clone(),
            source,
        }
    }

    fn changed(&self) -> PlanError {
        PlanError::Svg(format!(
            "{} changed while it was being dilated (another program wrote to it): the dilated \
             plan is incomplete and is not kept; run the command again",
            self.path.display()
        ))
    }
}

/// A hash of `bytes` with `keys`.
fn hash_of(keys: &RandomState, bytes: &[u8]) -> u64 {
    let mut h = keys.build_hasher();
    h.write(bytes);
    h.finish()
}

/// Copies a [`SourceFile`]'s bytes to a writer in order (see [`SourceFile::copier`]).
pub(crate) struct Copier<'s> {
    source: &'s SourceFile,
    reader: BufReader<File>,
    /// How far the file has been read.
    pos: u64,
    hasher: std::hash::DefaultHasher,
}

impl Copier<'_> {
    /// Copy the bytes from where the copy is to `end` into `out` (`out`'s errors are
    /// [`PlanError::Write`]), or skip them when `out` is `None`.
    pub(crate) fn copy_to(&mut self, end: u64, mut out: Option<&mut dyn Write>) -> Result<()> {
        // Straight from the reader's buffer: a buffer of this call's own, zeroed at every call
        // (one a gap between two edits), was a third of the writing thread's time.
        while self.pos < end {
            let read = self
                .reader
                .fill_buf()
                .map_err(|e| self.source.unreadable(e))?;
            if read.is_empty() {
                return Err(self.source.changed());
            }
            let got = read
                .len()
                .min(usize::try_from(end - self.pos).unwrap_or(usize::MAX));
            let chunk = &read[..got];
            self.hasher.write(chunk);
            if let Some(out) = out.as_deref_mut() {
                out.write_all(chunk).map_err(|source| PlanError::Write {
                    path: PathBuf::new(),
                    source,
                })?;
            }
            self.reader.consume(got);
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
            .map_err(|e| self.source.unreadable(e))?;
        if more != 0 || self.hasher.finish() != self.source.hash {
            return Err(self.source.changed());
        }
        Ok(())
    }
}
