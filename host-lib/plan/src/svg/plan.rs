//! The SVG document in the plan pipeline: reading its cuts (the source parsed again to name and
//! place the instances, then each traced) and their groups for G-code. Writing the dilated
//! document is in `writing`.

use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;
use usvg::tiny_skia_path;

use super::elements::{Elements, LineIndex, describe, inkscape_layer, use_target};
use super::exact::{self, Exactness};
use super::reading::{Rendered, parse};
use super::trace::{Reach, Traced, check_reach, exact_geometry, place, trace};
use super::walk::subpaths_of;
use super::writing::{Contours, Records};
use super::{Instance, bad, lost};
use crate::compensation::{self, CompensatedBy};
use crate::error::{PlanError, Problems, Result};
use crate::geom::Pline;
use crate::outcome::{CutGroup, PlanSummary};
use crate::pipeline::{Format, MAX_CUT_VERTICES, Plan};
use crate::source_file::SourceFile;

/// An SVG document in the plan pipeline: the source text and the cut instances found by
/// rendering it. A contour's origin is (instance, subpath).
///
/// No XML tree of the source is kept between the steps (it was a fifth of the peak memory, held
/// through the dilation): reading parses the source to name the cuts and find where their new
/// path data goes, and drops it; writing parses it again only for cuts reached through `<use>`,
/// whose targets are copied. A plan read from a file does not even hold the source's text while
/// its cuts are dilated: the file is read again as the output is written (see [`SourceFile`]).
pub(super) struct SvgPlan<'w> {
    /// The source (empty between reading and writing when `file` can give it back).
    pub(super) text: String,
    /// The file the source was read from, when it is to be read again for writing.
    pub(super) file: Option<SourceFile>,
    /// The rendered occurrences of cut elements (set by `read`).
    pub(super) instances: Vec<Instance>,
    /// What rendering found, until `read` takes it.
    pub(super) rendered: Option<Rendered>,
    /// Where the compensation record goes (set by `read`).
    pub(super) records: Records,
    /// Where each line of the source starts, to name elements by line and column.
    pub(super) lines: LineIndex,
    /// Where the dilated document goes (taken when it is written).
    pub(super) out: Option<&'w mut (dyn Write + Sync)>,
}

impl<'w> SvgPlan<'w> {
    /// The plan of the source `text` (read from `file`, if given) as rendered.
    pub(super) fn new(
        text: String,
        file: Option<SourceFile>,
        rendered: Rendered,
        out: &'w mut (dyn Write + Sync),
    ) -> Self {
        SvgPlan {
            lines: LineIndex::new(&text),
            text,
            file,
            instances: Vec::new(),
            rendered: Some(rendered),
            records: Records::default(),
            out: Some(out),
        }
    }

    /// Trace the instances' subpaths (by instance; `paths[k]` and `names[k]` are instance `k`'s
    /// path data and name) on any core, freeing each one's path data as it goes (it is kept, as
    /// segments, only for elements with an open subpath, which is written back as drawn). With
    /// them, the farthest reach and the instance that has it.
    fn trace_all(
        &mut self,
        paths: Vec<tiny_skia_path::Path>,
        names: &[String],
    ) -> Result<(Vec<Vec<Traced>>, Reach, usize)> {
        let vertices = AtomicUsize::new(0);
        let (traced, reaches): (Vec<Vec<Traced>>, Vec<Reach>) = self
            .instances
            .par_iter_mut()
            .zip(paths)
            .zip(names)
            .map(|((inst, path), name)| {
                let segs = subpaths_of(&path);
                drop(path);
                let reach = Reach::of(inst, &segs);
                let eps = reach.eps_mm();
                let exact = exact_geometry(inst, &segs, eps);
                let traced = trace(inst, &segs, exact.as_deref(), eps, name, &vertices);
                inst.subpath_count = segs.len();
                let all_closed = traced.len() == segs.len()
                    && traced.iter().all(|t| matches!(t, Traced::Closed(..)));
                if !all_closed {
                    inst.drawn = segs;
                }
                (traced, reach)
            })
            .unzip();
        let farthest = (0..reaches.len())
            .max_by(|&a, &b| reaches[a].held_to_mm().total_cmp(&reaches[b].held_to_mm()))
            .unwrap_or(0);
        let reach = reaches.get(farthest).copied().unwrap_or_default();
        if vertices.load(Ordering::Relaxed) > MAX_CUT_VERTICES {
            return Err(bad(format!(
                "the drawing's cuts come to more than {MAX_CUT_VERTICES} vertices once their curves are flattened (curves metres long and full of turns?); check the drawing and its units"
            )));
        }
        Ok((traced, reach, farthest))
    }

    /// How to name an instance in messages.
    fn label(&self, el: &Elements, inst: &Instance) -> String {
        self.name(el, inst.element, inst.via_use)
    }

    /// How to name shape `element` drawn through the `<use>` `via_use` in messages.
    fn name(&self, el: &Elements, element: usize, via_use: Option<usize>) -> String {
        let mut s = describe(&self.lines, el.shapes[element]);
        if let Some(u) = via_use {
            s.push_str(&format!(" via <use> {}", describe(&self.lines, el.uses[u])));
        }
        s
    }

    /// Refuse cuts reached through nested `<use>` clones (they cannot be copied one by one).
    fn check_uses(&self, el: &Elements) -> Result<()> {
        let mut problems = Problems::default();
        for inst in &self.instances {
            if let Some(u) = inst.via_use {
                // `ancestors()` starts at the node itself: the target may be the shape.
                let target = use_target(el.uses[u], &el.ids);
                let inside =
                    target.is_some_and(|t| el.shapes[inst.element].ancestors().any(|a| a == t));
                if !inside {
                    problems.push(format!(
                        "{} is reached through nested <use> clones; unlink the clones first (Inkscape: Edit ▸ Clone ▸ Unlink Clone)",
                        self.label(el, inst)
                    ));
                }
            }
        }
        problems.into_error(PlanError::Svg)
    }

    /// Each instance's traced subpaths (by instance), in document order: closed ones are cuts,
    /// the rest open paths.
    fn contours(plan: &mut Plan<(usize, usize)>, traced: Vec<Vec<Traced>>) {
        for (ii, subpaths) in traced.into_iter().enumerate() {
            for t in subpaths {
                match t {
                    Traced::Closed(si, pline, name) => plan.cut(pline, name, (ii, si)),
                    Traced::Open(name, first, last) => plan.open_path(name, first, last),
                }
            }
        }
    }

    /// In a boxes.py plan, which instances are of its reference rectangle, which boxes.py draws
    /// without burn (by instance; empty for other plans).
    fn boxes_references(&self, el: &Elements, summary: &PlanSummary) -> Vec<bool> {
        let boxes = summary
            .compensation_found
            .as_ref()
            .is_some_and(|f| f.by == CompensatedBy::BoxesPy);
        if !boxes {
            return Vec::new();
        }
        (self.instances.iter())
            .map(|inst| compensation::is_boxes_reference(el.shapes[inst.element]))
            .collect()
    }

    /// Everything reading needs from the source's XML tree, found in one parse that is dropped
    /// before the cuts are traced (the tree and the traced contours held at once were the peak
    /// of reading): the uses checked, the instances placed, the compensation records found, and
    /// each instance's name and whether it is of boxes.py's reference rectangle (`mm_per_px`:
    /// document mm per usvg pixel).
    fn read_source(
        &mut self,
        summary: &PlanSummary,
        lost: &[(usize, Option<usize>)],
        mm_per_px: f64,
    ) -> Result<(Vec<String>, Vec<bool>)> {
        let doc = parse(&self.text)?;
        let el = Elements::of(&doc);
        let lost = lost.iter().map(|&(e, u)| self.name(&el, e, u));
        lost::refuse(lost)?;
        self.check_uses(&el)?;
        place(&mut self.instances, &self.text, &el, mm_per_px);
        self.records = Records {
            old: compensation::own_svg_records(&doc),
            at: doc.root_element().first_child().map(|n| n.range().start),
        };
        let names = (self.instances.iter())
            .map(|inst| self.label(&el, inst))
            .collect();
        Ok((names, self.boxes_references(&el, summary)))
    }
}

impl Format for SvgPlan<'_> {
    type Origin = (usize, usize);
    type Output = ();

    fn read(&mut self) -> Result<Plan<(usize, usize)>> {
        let Some(Rendered {
            mut plan,
            instances,
            paths,
            lost,
            mm_per_px,
        }) = self.rendered.take()
        else {
            return Err(bad("internal error: the SVG was read twice"));
        };
        self.instances = instances;
        let (names, boxes_reference) = self.read_source(&plan.summary, &lost, mm_per_px)?;
        let (traced, reach, farthest) = self.trace_all(paths, &names)?;
        if let Some(name) = names.get(farthest) {
            check_reach(reach, name, &mut plan.summary)?;
        }
        let approximated: Vec<&str> = (self.instances.iter().zip(&names))
            .filter(|(inst, _)| matches!(inst.exact, Exactness::Approximated))
            .map(|(_, name)| name.as_str())
            .collect();
        exact::note_approximated(&approximated, &mut plan.summary);
        drop(names);
        plan.summary.cut_elements = self.instances.len();
        Self::contours(&mut plan, traced);
        for (k, cut) in plan.cuts.iter().enumerate() {
            if boxes_reference.get(cut.origin.0) == Some(&true) {
                plan.unburnt.push(k);
            }
        }
        if self.file.is_some() {
            // Read again when the plan is written.
            self.text = String::new();
        }
        Ok(plan)
    }

    fn groups(&self, plan: &Plan<(usize, usize)>) -> Vec<CutGroup> {
        // The layers are read from the source parsed again (only G-code asks for them, and it
        // parsed in `read`: a failure now would be a bug, not bad input). The cuts' path never
        // reads from a file (`dilate_svg_cuts` keeps its text), so the text is here.
        debug_assert!(
            self.file.is_none(),
            "the cuts' groups need the source's text"
        );
        let doc = parse(&self.text).expect("the source parsed when it was read");
        let el = Elements::of(&doc);
        plan.cuts
            .iter()
            .map(|cut| {
                let inst = &self.instances[cut.origin.0];
                // A clone is on the layer of its <use>, not of the element it copies.
                let layer =
                    inkscape_layer(inst.via_use.map_or(el.shapes[inst.element], |u| el.uses[u]));
                CutGroup {
                    color: inst.stroke,
                    layer,
                }
            })
            .collect()
    }

    fn write(mut self, plan: &mut Plan<(usize, usize)>, dilated: Vec<Pline>) -> Result<()> {
        let mut contours = Contours::new(&plan.cuts, dilated);
        let mut edits = Vec::new();
        if self.instances.iter().any(|inst| inst.via_use.is_some()) {
            // The targets of `<use>` are copied from the source's text: it is read again whole.
            if let Some(file) = self.file.as_ref().filter(|_| self.text.is_empty()) {
                self.text = file.read_again()?;
            }
            let doc = parse(&self.text)?;
            let el = Elements::of(&doc);
            let clone_edits = self.clone_geometry_edits(&contours, &mut plan.summary)?;
            self.clone_uses(&el, clone_edits, &mut edits, &mut plan.summary)?;
        }
        edits.extend(self.record_edits(&plan.summary));
        let Some(sink) = self.out.take() else {
            return Err(bad("internal error: the SVG was written twice"));
        };
        self.write_document(edits, &mut contours, &mut plan.summary, sink)
    }
}
