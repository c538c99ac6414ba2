//! The one dilation pipeline every plan format runs: read the file into closed cut contours
//! (each with where it came from) and open cut paths, dilate the contours, and write the dilated
//! geometry back into the original document.
//!
//! A format ([`Format`]) only knows its own file: how to find the cuts in it (with the
//! [`rules`](crate::rules)), what each contour came from (an SVG element, a DXF entity or chain
//! of entities), and how to put a dilated contour back in its place. Everything else happens
//! here, once for every format: the summary and its counts, the open cut paths, and the dilation
//! itself (nesting, the kerf per part and the geometry checks, in [`dilate`]). A format collects
//! the problems it finds while reading in one `Problems` list (in `error`) and reports them
//! together; the `--strict` refusal of open paths is in [`file`](mod@crate::file).

use crate::dilate::{self, Contour, KerfSource};
use crate::error::Result;
use crate::geom::{Pline, V2};
use crate::outcome::{OpenPath, PlanSummary};
use crate::progress::{Progress, Stage};

/// A closed cut contour and what it came from in the file.
pub(crate) struct Cut<O> {
    /// The contour, document space (mm), with its label for messages.
    pub contour: Contour,
    /// Where it came from, and so how to write it back.
    pub origin: O,
}

/// A plan as read: its cuts, and the summary so far (units, counts, what passed through, open
/// paths, notes).
pub(crate) struct Plan<O> {
    /// The closed cut contours, in file order.
    pub cuts: Vec<Cut<O>>,
    /// What was found so far.
    pub summary: PlanSummary,
}

impl<O> Plan<O> {
    /// An empty plan of the format called `format` (`svg`, `dxf`).
    pub fn new(format: &str) -> Self {
        Plan {
            cuts: Vec::new(),
            summary: PlanSummary {
                format: format.into(),
                ..PlanSummary::default()
            },
        }
    }

    /// Add a closed cut contour.
    pub fn cut(&mut self, pline: Pline, label: String, origin: O) {
        self.cuts.push(Cut {
            contour: Contour { pline, label },
            origin,
        });
    }

    /// Record an open cut path (it cannot be dilated and is left as drawn), from `start` to `end`
    /// (mm).
    pub fn open_path(&mut self, id: String, start: V2, end: V2) {
        self.summary.open_paths.push(OpenPath {
            id,
            start_mm: [start.x, start.y],
            end_mm: [end.x, end.y],
        });
    }
}

/// A plan file format: read its cuts, and write dilated cuts back.
pub(crate) trait Format {
    /// What a contour came from in this format.
    type Origin;
    /// The dilated document.
    type Output;

    /// Read the document's cuts.
    fn read(&mut self) -> Result<Plan<Self::Origin>>;

    /// Write the dilated contours (`dilated[k]` replaces `plan.cuts[k]`) back into the document;
    /// counts the elements changed and adds notes to `plan.summary`. The contours are given, so
    /// that a format can free them as soon as they are in the document.
    fn write(self, plan: &mut Plan<Self::Origin>, dilated: Vec<Pline>) -> Result<Self::Output>;
}

/// Read, dilate and write back a plan in any format: the dilated document and what was found
/// and done. The dilation and writing stages are told to `progress` (the format tells when it
/// starts reading).
pub(crate) fn dilate_plan<F: Format>(
    mut format: F,
    kerf: &KerfSource,
    progress: &Progress,
) -> Result<(F::Output, PlanSummary)> {
    let mut plan = format.read()?;
    // The contours are lent to the kernel, not copied (a large plan's geometry is most of its
    // memory).
    let (contours, origins): (Vec<Contour>, Vec<F::Origin>) = std::mem::take(&mut plan.cuts)
        .into_iter()
        .map(|c| (c.contour, c.origin))
        .unzip();
    let dilation = dilate::dilate_with_progress(&contours, kerf, progress)?;
    plan.cuts = contours
        .into_iter()
        .zip(origins)
        .map(|(contour, origin)| Cut { contour, origin })
        .collect();
    plan.summary.record_parts(&dilation);
    progress.start(Stage::Writing, 0);
    let output = format.write(&mut plan, dilation.contours)?;
    Ok((output, plan.summary))
}
