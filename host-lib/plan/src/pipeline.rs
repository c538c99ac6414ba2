//! The one dilation pipeline every plan format runs: read the file into closed cut contours
//! (each with where it came from) and open cut paths, dilate the contours, and write the dilated
//! geometry back into the original document.
//!
//! A format ([`Format`]) only knows its own file: how to find the cuts in it (with the
//! [`rules`](crate::rules)), what each contour came from (an SVG element, a DXF entity or chain
//! of entities), and how to put a dilated contour back in its place. Everything else happens
//! here, once for every format: the summary and its counts, the open cut paths, and the dilation
//! itself (nesting, the kerf per part and the geometry checks, in [`dilate`]), and what to do
//! with a plan that is already compensated ([`compensation`]). A format collects
//! the problems it finds while reading in one `Problems` list (in `error`) and reports them
//! together; the `--strict` refusal of open paths is in [`file`](mod@crate::file).

use crate::compensation::{self, IfCompensated};
use crate::dilate::{self, Contour, KerfSource, Offsetting};
use crate::error::Result;
use crate::geom::{Pline, V2};
use crate::outcome::{CutGroup, CutPath, OpenPath, PlanSummary};
use crate::progress::{Progress, Stage};
use crate::recompensate;
use crate::rules::CutRules;

/// More vertices than this in a plan's cuts, once its curves are flattened (and a DXF's blocks
/// expanded), are refused as they are read, in every format: the dilation of as many needs
/// gigabytes, and a small hostile file (a 4 km ellipse in a 300 × 300 array, curves kilometres
/// long fitted within 0.05 µm) asks for billions.
pub(crate) const MAX_CUT_VERTICES: usize = 5_000_000;

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
    /// Cuts (indexes into `cuts`) that the plan's recorded compensation did not reach (boxes.py's
    /// reference rectangle): when recompensating they are dilated by the kerf's half alone.
    pub unburnt: Vec<usize>,
}

impl<O> Plan<O> {
    /// An empty plan of the format called `format` (`svg`, `dxf`).
    pub fn new(format: &str) -> Self {
        Plan {
            cuts: Vec::new(),
            unburnt: Vec::new(),
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

    /// Remove the small loops where a cut crosses itself (boxes.py's inner corners, no larger than
    /// `max_mm`) from every cut: how many went.
    pub fn remove_corner_loops(&mut self, max_mm: f64) -> usize {
        self.cuts
            .iter_mut()
            .map(|c| {
                let (pline, n) = recompensate::remove_corner_loops(&c.contour.pline, max_mm);
                c.contour.pline = pline;
                n
            })
            .sum()
    }

    /// Give the cuts the compensation did not reach the `burn_mm` the others carry (outwards, round
    /// corners), so that undoing it leaves them dilated by the kerf's half alone.
    fn burn_unburnt(&mut self, burn_mm: f64) {
        let mut done = 0;
        for &k in &self.unburnt {
            let contour = &mut self.cuts[k].contour;
            if let Some(grown) = recompensate::grow_outline(&contour.pline, burn_mm) {
                contour.pline = grown;
                done += 1;
            }
        }
        if done > 0 {
            self.summary.notes.push(format!(
                "{done} cut(s) of boxes.py's reference rectangle, drawn without burn, were dilated by the kerf's half alone"
            ));
        }
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

    /// Read the document's cuts, and any compensation it records (in the summary).
    fn read(&mut self) -> Result<Plan<Self::Origin>>;

    /// Write the dilated contours (`dilated[k]` replaces `plan.cuts[k]`, whose drawn geometry is
    /// gone by then: only its origin and label are left) back into the document; counts the
    /// elements changed and adds notes to `plan.summary`. The contours are given, so that a
    /// format can free them as soon as they are in the document.
    fn write(self, plan: &mut Plan<Self::Origin>, dilated: Vec<Pline>) -> Result<Self::Output>;

    /// The colour and layer each cut was drawn with (`plan.cuts` order), which choose its cut
    /// settings when the plan becomes G-code.
    fn groups(&self, plan: &Plan<Self::Origin>) -> Vec<CutGroup>;
}

/// Read, dilate and write back a plan in any format: the dilated document and what was found
/// and done (see [`read_and_dilate`]). The writing stage is told to `progress`.
pub(crate) fn dilate_plan<F: Format>(
    format: F,
    kerf: &KerfSource,
    policy: IfCompensated,
    rules: &CutRules,
    progress: &Progress,
) -> Result<(F::Output, PlanSummary)> {
    let (format, mut plan, dilated) = read_and_dilate(format, kerf, policy, rules, progress)?;
    progress.start(Stage::Writing, 0);
    let output = format.write(&mut plan, dilated)?;
    Ok((output, plan.summary))
}

/// Read and dilate a plan in any format, and give the dilated cuts back as contours (each with
/// its colour and layer) instead of writing them into the document: what G-code is made from.
pub(crate) fn dilate_plan_cuts<F: Format>(
    format: F,
    kerf: &KerfSource,
    policy: IfCompensated,
    rules: &CutRules,
    progress: &Progress,
) -> Result<(Vec<CutPath>, PlanSummary)> {
    let (format, plan, dilated) = read_and_dilate(format, kerf, policy, rules, progress)?;
    let groups = format.groups(&plan);
    let cuts = plan
        .cuts
        .into_iter()
        .zip(dilated)
        .zip(groups)
        .map(|((cut, pline), group)| CutPath {
            pline,
            label: cut.contour.label,
            group,
        })
        .collect();
    Ok((cuts, plan.summary))
}

/// The refusal of a plan none of whose closed contours is a cut by `rules`: what the elements
/// were taken for, and how to choose the cuts.
fn no_cuts(summary: &PlanSummary, rules: &CutRules) -> crate::PlanError {
    let passed: Vec<String> = summary
        .passed_through
        .iter()
        .map(|(reason, n)| format!("{n} {reason}"))
        .collect();
    let mut found = if passed.is_empty() {
        "nothing drawn".to_owned()
    } else {
        format!("left as drawn: {}", passed.join(", "))
    };
    if !summary.open_paths.is_empty() {
        found.push_str(&format!(
            "; {} open cut path(s), which cannot be dilated",
            summary.open_paths.len()
        ));
    }
    crate::PlanError::NoCuts(format!(
        "no closed cut contour found, so nothing to dilate ({found}); the cuts are {}. Choose them with --cut-color (a CSS colour such as '#808080' or rgb(128,128,128), or an ACI number from 1 to 255: compared by colour, so ACI 9 and '#C0C0C0' are one), --cut-max-width-mm or --cut-layer (DXF), or close the open paths",
        rules.describe()
    ))
}

/// Read a plan and dilate its cuts: the format (to write with), the plan read and the dilated
/// contours (`dilated[k]` for `plan.cuts[k]`). A plan that records a compensation is refused,
/// dilated anyway or recompensated as `policy` says, before its geometry is checked (boxes.py's
/// compensated plans cross themselves at every inner corner). The dilation stage is told to
/// `progress` (the format tells when it starts reading).
fn read_and_dilate<F: Format>(
    mut format: F,
    kerf: &KerfSource,
    policy: IfCompensated,
    rules: &CutRules,
    progress: &Progress,
) -> Result<(F, Plan<F::Origin>, Vec<Pline>)> {
    let mut plan = format.read()?;
    if plan.cuts.is_empty() {
        return Err(no_cuts(&plan.summary, rules));
    }
    let treatment =
        compensation::treatment(plan.summary.compensation_found.as_ref(), policy, kerf)?;
    if treatment.action == "dilate" && policy != IfCompensated::Refuse {
        plan.summary.notes.push(
            "the plan records no compensation (boxes.py burn or an earlier dilation): it was dilated by the kerf as usual".into(),
        );
    }
    let loops = treatment
        .corner_loop_max_mm
        .map_or(0, |max_mm| plan.remove_corner_loops(max_mm));
    if let Offsetting::Recompensate { burn_mm } = treatment.offsetting {
        plan.burn_unburnt(burn_mm);
    }
    // The contours are given to the kernel, not copied, and it frees each one's drawn geometry
    // as soon as it is offset: writing needs each cut's origin and label, not its drawn
    // geometry (a large plan's drawn and dilated geometry held at once were most of its memory).
    let (mut contours, origins): (Vec<Contour>, Vec<F::Origin>) = std::mem::take(&mut plan.cuts)
        .into_iter()
        .map(|c| (c.contour, c.origin))
        .unzip();
    let dilation =
        dilate::dilate_releasing_drawn(&mut contours, kerf, treatment.offsetting, progress)?;
    plan.cuts = contours
        .into_iter()
        .zip(origins)
        .map(|(contour, origin)| Cut { contour, origin })
        .collect();
    plan.summary.record_parts(&dilation);
    plan.summary.compensation_applied = Some(compensation::applied(
        &treatment,
        plan.summary.kerf_range_um,
        kerf,
        rules.describe(),
        loops,
    ));
    Ok((format, plan, dilation.contours))
}
