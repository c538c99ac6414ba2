//! How far a dilation has got, told to whoever shows it (the CLI draws a bar on a terminal; the
//! plan benchmark times the stages). This crate only reports: it draws and prints nothing.
//!
//! A dilation goes through three [`Stage`]s in order: reading the file into contours, dilating
//! them (with a count of contours done, from any of the worker threads), and writing the result.

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A stage of a dilation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Parsing the file and tracing its cuts into contours.
    Reading,
    /// Nesting, offsetting and checking the contours.
    Dilating,
    /// Putting the dilated contours back into the document and encoding it.
    Writing,
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stage::Reading => "reading",
            Stage::Dilating => "dilating",
            Stage::Writing => "writing",
        })
    }
}

/// Told `(stage, done, total)`: a stage starts with `done` = 0; `total` is 0 when the stage has
/// no count. Called from any thread.
pub type ProgressFn = dyn Fn(Stage, usize, usize) + Send + Sync;

/// Where progress goes: nowhere (the default), or a function.
#[derive(Clone, Default)]
pub struct Progress(Option<Arc<ProgressFn>>);

impl fmt::Debug for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(..)"
        } else {
            "Progress(none)"
        })
    }
}

impl Progress {
    /// Progress told to `f`.
    pub fn new(f: impl Fn(Stage, usize, usize) + Send + Sync + 'static) -> Self {
        Progress(Some(Arc::new(f)))
    }

    /// `stage` starts, with `total` steps (0: not counted).
    pub(crate) fn start(&self, stage: Stage, total: usize) {
        if let Some(f) = &self.0 {
            f(stage, 0, total);
        }
    }

    /// A counter of `total` steps of `stage` that tells about every hundredth of them.
    pub(crate) fn counter(&self, stage: Stage, total: usize) -> Counter<'_> {
        self.start(stage, total);
        Counter {
            progress: self,
            stage,
            total,
            every: (total / 100).max(1),
            done: AtomicUsize::new(0),
        }
    }
}

/// Counts the steps of a stage done by any number of threads (see [`Progress::counter`]).
pub(crate) struct Counter<'p> {
    progress: &'p Progress,
    stage: Stage,
    total: usize,
    every: usize,
    done: AtomicUsize,
}

impl Counter<'_> {
    /// One more step done.
    pub(crate) fn step(&self) {
        let Some(f) = &self.progress.0 else {
            return;
        };
        let done = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        if done.is_multiple_of(self.every) || done == self.total {
            f(self.stage, done, self.total);
        }
    }
}
