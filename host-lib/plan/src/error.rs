//! What can go wrong with a cutting plan, by kind: a file that is not readable in its format, units
//! that are not known, a plan that cannot be dilated as drawn or is already compensated, open paths
//! where none are allowed, a bad argument, or the files themselves (reading the plan, writing the
//! output). Every message says what to do.

use std::path::{Path, PathBuf};

use crate::compensation::FoundCompensation;
use kerfmeter_protocol::advice::{Advice, Advised};

/// Result of every fallible function of this crate.
pub type Result<T, E = PlanError> = std::result::Result<T, E>;

/// What went wrong with a plan.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The SVG text cannot be read or used (not XML, not SVG, a cut that cannot be traced).
    #[error("{0}")]
    Svg(String),
    /// The DXF data cannot be read or written.
    #[error("{0}")]
    Dxf(String),
    /// The file does not say how long a drawing unit is (or says it inconsistently).
    #[error("{0}")]
    Units(String),
    /// The plan cannot be dilated as drawn: parts would merge, a hole is narrower than the kerf,
    /// or cuts cross. The message lists every problem found, with positions.
    #[error("{0}")]
    CannotDilate(Advised),
    /// The plan says it is already compensated for the kerf (boxes.py's `--burn`, this tool's
    /// own output, a LightBurn project's Kerf Offsets): dilating it again would compensate twice.
    /// The message names what was found and the two ways on (`--recompensate`,
    /// `--already-compensated-ok`).
    #[error("{message}")]
    AlreadyCompensated {
        /// What was found, why it is refused and what to do.
        message: Advised,
        /// What was found, for a caller to act on (`--json`'s `compensation_found`).
        found: Box<FoundCompensation>,
    },
    /// A LightBurn project that cannot be read or set (not its XML, a layer without an index, a
    /// Kerf Offset that is not a number, too large a file).
    #[error("{0}")]
    LightBurn(String),
    /// No closed contour of the plan is a cut by the rules: there is nothing to dilate, and an
    /// output recording a compensation would be a lie. The message says what the elements were
    /// taken for and how to choose the cuts.
    #[error("{0}")]
    NoCuts(String),
    /// Open cut paths, which cannot be dilated, where the caller refuses them.
    #[error("{0}")]
    OpenPaths(String),
    /// A bad argument: the kerf, a colour, a width, the gauge geometry, a file name's extension.
    #[error("{0}")]
    InvalidArgument(String),
    /// A plan file could not be read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The dilated plan could not be written.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// Any of the above, in a particular plan file.
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        source: Box<PlanError>,
    },
}

impl PlanError {
    /// The same error, said of the plan file at `path`.
    pub fn in_file(self, path: &Path) -> PlanError {
        PlanError::InFile {
            path: path.to_owned(),
            source: Box::new(self),
        }
    }

    /// The compensation the plan was refused for already carrying, if that is the error (said
    /// of a file or not).
    pub fn compensation_found(&self) -> Option<&FoundCompensation> {
        match self {
            PlanError::AlreadyCompensated { found, .. } => Some(found),
            PlanError::InFile { source, .. } => source.compensation_found(),
            _ => None,
        }
    }

    /// The advice this error gives, as data: what its message tells the reader to do next
    /// (each front end words it: `--recompensate`, `if_compensated="recompensate"`).
    pub fn advice(&self) -> Vec<Advice> {
        match self {
            PlanError::AlreadyCompensated { message, .. } | PlanError::CannotDilate(message) => {
                message.advice().collect()
            }
            PlanError::InFile { source, .. } => source.advice(),
            _ => Vec::new(),
        }
    }

    /// The plan file this error is about, if it is about a file rather than the arguments.
    pub fn path(&self) -> Option<&Path> {
        match self {
            PlanError::Io { path, .. }
            | PlanError::Write { path, .. }
            | PlanError::InFile { path, .. } => Some(path),
            _ => None,
        }
    }
}

/// Problems found in a plan: collected, not stopped at, then reported together as one error.
#[derive(Debug, Default)]
pub struct Problems(Vec<Advised>);

/// The problems an error lists; the rest are counted (an array of 90,000 bad copies printed its
/// one problem 90,000 times, 16 MB of message).
const SHOWN: usize = 50;

impl Problems {
    /// Note one problem.
    pub fn push(&mut self, problem: impl Into<Advised>) {
        self.0.push(problem.into());
    }

    /// `Ok` when there were none; otherwise one error (made by `kind`, e.g. [`PlanError::Svg`])
    /// listing them (the first 50), one a line. For problems reading a file.
    pub fn into_error(self, kind: fn(String) -> PlanError) -> Result<()> {
        if self.0.is_empty() {
            return Ok(());
        }
        Err(kind(self.listing("", "").to_string()))
    }

    /// `Ok` when there were none; otherwise [`PlanError::CannotDilate`] listing them (the first
    /// 50) under a heading. For problems with the geometry.
    pub(crate) fn cannot_dilate(self) -> Result<()> {
        if self.0.is_empty() {
            return Ok(());
        }
        let n = self.0.len();
        Err(PlanError::CannotDilate(
            Advised::text(format!(
                "cannot dilate this plan ({n} problem{}; nothing was written):\n",
                if n == 1 { "" } else { "s" },
            ))
            .append(self.listing("  ", "- ")),
        ))
    }

    /// The first [`SHOWN`] problems, one a line after `indent` and `bullet`, and a line (after
    /// `indent`) counting the rest.
    fn listing(&self, indent: &str, bullet: &str) -> Advised {
        let mut listing = Advised::default();
        for (i, p) in self.0.iter().take(SHOWN).enumerate() {
            let newline = if i == 0 { "" } else { "\n" };
            listing = listing
                .then(format!("{newline}{indent}{bullet}"))
                .append(p.clone());
        }
        if self.0.len() > SHOWN {
            listing = listing.then(format!("\n{indent}… and {} more", self.0.len() - SHOWN));
        }
        listing
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_error_lists_fifty_problems_and_counts_the_rest() {
        let mut problems = Problems::default();
        for k in 0..90_000 {
            problems.push(format!("copy {k} is bad"));
        }
        let Err(PlanError::Svg(message)) = problems.into_error(PlanError::Svg) else {
            panic!("an error");
        };
        assert_eq!(message.lines().count(), 51, "{message}");
        assert!(message.ends_with("… and 89950 more"), "{message}");
        assert!(Problems::default().into_error(PlanError::Svg).is_ok());
        // The geometry's problems: under a heading, bulleted, the rest counted alike.
        let mut problems = Problems::default();
        for k in 0..52 {
            problems.push(format!("loop {k} crosses itself"));
        }
        let Err(PlanError::CannotDilate(message)) = problems.cannot_dilate() else {
            panic!("an error");
        };
        let message = message.to_string();
        let lines: Vec<&str> = message.lines().collect();
        assert_eq!(
            (lines[0], lines[1], lines[51]),
            (
                "cannot dilate this plan (52 problems; nothing was written):",
                "  - loop 0 crosses itself",
                "  … and 2 more"
            )
        );
    }
}
