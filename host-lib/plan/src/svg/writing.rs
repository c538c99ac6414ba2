//! Writing the dilated document: each cut's new path data, made a batch at a time as the source
//! is copied with its edits; copies of the targets of `<use>` elements whose cuts were dilated;
//! and the compensation record.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::Write;
use std::ops::Range;

use rayon::prelude::*;
use roxmltree::Node;

use super::edits::{Edit, EditWriter, Src, apply_edits, edit_key, filled, sorted};
use super::elements::{Elements, describe, is_svg, use_target};
use super::path_writer::{digits_for, write_pline, write_segs};
use super::plan::SvgPlan;
use super::{Instance, XLINK_NS, bad};
use crate::error::Result;
use crate::geom::Pline;
use crate::outcome::PlanSummary;
use crate::pipeline::Cut;

/// Elements whose dilated path data is made at once when the document is written (see
/// `SvgPlan::write_document`).
const WRITE_BATCH: usize = 256;

/// Edits inside the targets of `<use>` elements, by `<use>` (index into the `<use>` elements).
type CloneEdits = BTreeMap<usize, Vec<Edit>>;

/// The dilated contour of each (instance, subpath) that is a cut, with the cut's label. A
/// contour is freed once its instance's new path data is made (see [`Contours::free`]).
pub(super) struct Contours<'p> {
    plines: Vec<Pline>,
    labels: Vec<&'p str>,
    by_origin: HashMap<(usize, usize), usize>,
}

impl<'p> Contours<'p> {
    /// The dilated contours `dilated` of `cuts` (in the same order).
    pub(super) fn new(cuts: &'p [Cut<(usize, usize)>], dilated: Vec<Pline>) -> Self {
        Contours {
            by_origin: cuts
                .iter()
                .enumerate()
                .map(|(k, c)| (c.origin, k))
                .collect(),
            labels: cuts.iter().map(|c| c.contour.label.as_str()).collect(),
            plines: dilated,
        }
    }

    /// The dilated contour of subpath `si` of instance `ii`, if it is a cut, and its label.
    fn get(&self, ii: usize, si: usize) -> Option<(&Pline, &'p str)> {
        let &k = self.by_origin.get(&(ii, si))?;
        Some((self.plines.get(k)?, self.labels[k]))
    }

    /// Free the dilated contours of the instances `made` (of `instances`), whose path data is
    /// made: their memory goes to the path data made next, rather than the arena growing by as
    /// much.
    fn free(&mut self, made: &[usize], instances: &[Instance]) {
        for &ii in made {
            for si in 0..instances[ii].subpath_count {
                if let Some(&k) = self.by_origin.get(&(ii, si)) {
                    self.plines[k] = Pline::new_closed();
                }
            }
        }
    }
}

/// Where this tool's compensation record goes in the source (right after the root's start tag),
/// and its earlier records there, to drop.
#[derive(Default)]
pub(super) struct Records {
    pub(super) old: Vec<Range<usize>>,
    pub(super) at: Option<usize>,
}

/// Write a batch of instances' new geometry (`made`, in document order) and, before each edit of
/// it, the other `edits` that come first.
fn write_batch(
    made: Vec<Option<Result<Vec<Edit>>>>,
    edits: &mut std::iter::Peekable<std::vec::IntoIter<Edit>>,
    out: &mut EditWriter,
    summary: &mut PlanSummary,
) -> Result<()> {
    for geometry in made.into_iter().flatten() {
        summary.changed_elements += 1;
        // On a tie the geometry goes first, as it did when all edits were sorted at once.
        for e in sorted(geometry?) {
            while let Some(x) = edits.next_if(|x| edit_key(x) < edit_key(&e)) {
                out.apply(x)?;
            }
            out.apply(e)?;
        }
    }
    Ok(())
}

impl<'w> SvgPlan<'w> {
    /// The new geometry of the instances reached through `<use>`, as edits by `<use>`: their
    /// targets are copied whole (see [`Self::clone_uses`]), so these are made before writing.
    pub(super) fn clone_geometry_edits(
        &self,
        contours: &Contours,
        summary: &mut PlanSummary,
    ) -> Result<CloneEdits> {
        let made: Vec<(usize, Option<Result<Vec<Edit>>>)> = self
            .instances
            .par_iter()
            .enumerate()
            .filter_map(|(ii, inst)| {
                let u = inst.via_use?;
                Some((u, self.instance_edits(ii, inst, contours)))
            })
            .collect();
        let mut clone_edits: CloneEdits = BTreeMap::new();
        for (u, edits) in made {
            if let Some(edits) = edits {
                clone_edits.entry(u).or_default().extend(edits?);
                summary.changed_elements += 1;
            }
        }
        Ok(clone_edits)
    }

    /// Write the document with `edits` applied and the instances drawn directly (not through
    /// `<use>`) given their dilated geometry. That geometry is made batch by batch as the
    /// document is written (each batch's path data on any core, the next one while this one is
    /// written), so no more than two batches of it are held at once: the path data of a whole
    /// plan is larger than its file.
    pub(super) fn write_document(
        &self,
        edits: Vec<Edit>,
        contours: &mut Contours,
        summary: &mut PlanSummary,
        sink: &mut (dyn Write + Sync),
    ) -> Result<()> {
        let mut direct: Vec<usize> = (0..self.instances.len())
            .filter(|&ii| self.instances[ii].via_use.is_none())
            .collect();
        direct.sort_by_key(|&ii| self.instances[ii].start);
        let mut edits = sorted(edits).into_iter().peekable();
        let src = match (&self.file, self.text.is_empty()) {
            (Some(file), true) => Src::File(file.copier()?),
            _ => Src::Text(&self.text),
        };
        let mut out = EditWriter::new(src, sink);
        let batches: Vec<&[usize]> = direct.chunks(WRITE_BATCH).collect();
        let make = |batch: &[usize], contours: &Contours| -> Vec<Option<Result<Vec<Edit>>>> {
            batch
                .par_iter()
                .map(|&ii| self.instance_edits(ii, &self.instances[ii], contours))
                .collect()
        };
        let mut made = batches.first().map(|b| make(b, contours));
        for (k, batch) in batches.iter().enumerate() {
            let current = made.take().unwrap_or_default();
            contours.free(batch, &self.instances);
            let contours = &*contours;
            // The next batch is made on the pool while this thread writes this one.
            let written = rayon::in_place_scope(|scope| {
                scope.spawn(|_| made = batches.get(k + 1).map(|b| make(b, contours)));
                write_batch(current, &mut edits, &mut out, summary)
            });
            written?;
        }
        for x in edits {
            out.apply(x)?;
        }
        out.finish()
    }

    /// The compensation record (see [`compensation`](crate::compensation)) right after the root's
    /// start tag, replacing any this tool wrote before.
    pub(super) fn record_edits(&self, summary: &PlanSummary) -> Vec<Edit> {
        let mut edits: Vec<Edit> = (self.records.old.iter())
            .map(|range| Edit {
                range: range.clone(),
                text: String::new(),
            })
            .collect();
        if let (Some(applied), Some(at)) = (&summary.compensation_applied, self.records.at) {
            edits.push(Edit {
                range: at..at,
                text: applied.svg_record(),
            });
        }
        edits
    }

    /// The edits that give instance `ii` its dilated subpaths (the others re-emitted as drawn);
    /// `None` when none of its subpaths was dilated.
    fn instance_edits(
        &self,
        ii: usize,
        inst: &Instance,
        contours: &Contours,
    ) -> Option<Result<Vec<Edit>>> {
        let (_, label) = (0..inst.subpath_count).find_map(|si| contours.get(ii, si))?;
        let Some(to_local) = inst.to_doc.inverse() else {
            return Some(Err(bad(format!(
                "{label} has a degenerate transform (zero scale)"
            ))));
        };
        let digits = digits_for(&inst.to_doc);
        let mut d = String::new();
        for si in 0..inst.subpath_count {
            if !d.is_empty() {
                d.push(' ');
            }
            match (contours.get(ii, si), inst.drawn.get(si)) {
                (Some((pline, _)), _) => write_pline(pline, &to_local, digits, &mut d),
                (None, Some(segs)) => write_segs(segs, digits, &mut d),
                // Not kept: every subpath of this instance is a dilated contour.
                (None, None) => {}
            }
        }
        Some(Ok(filled(&inst.slots, &d)))
    }

    /// Copies of the targets of `<use>` elements whose cuts were dilated (ids suffixed `-kerfN`),
    /// each `<use>` pointed at its copy: edits to `main_edits`, one note per copied target.
    pub(super) fn clone_uses(
        &self,
        el: &Elements,
        clone_edits: CloneEdits,
        main_edits: &mut Vec<Edit>,
        summary: &mut PlanSummary,
    ) -> Result<()> {
        let mut taken: HashSet<String> = el.ids.keys().map(|s| s.to_string()).collect();
        let mut inserts: BTreeMap<usize, (Node, String)> = BTreeMap::new();
        let mut counter = 0usize;
        for (u, edits) in clone_edits {
            let node = el.uses[u];
            let target = use_target(node, &el.ids).expect("checked above");
            let suffix = loop {
                counter += 1;
                let s = format!("-kerf{counter}");
                let root_id = format!("{}{s}", target.attribute("id").unwrap_or(""));
                if !taken.contains(&root_id) {
                    break s;
                }
            };
            let clone = self.clone_of(target, edits, &suffix, &mut taken)?;
            let new_root = format!("{}{suffix}", target.attribute("id").unwrap_or(""));
            for a in node.attributes() {
                let is_href = a.name() == "href"
                    && (a.namespace().is_none() || a.namespace() == Some(XLINK_NS));
                if is_href {
                    main_edits.push(Edit {
                        range: a.range_value(),
                        text: format!("#{}", crate::xml::escape(&new_root)),
                    });
                }
            }
            let entry = inserts
                .entry(target.range().end)
                .or_insert_with(|| (target, String::new()));
            entry.1.push('\n');
            entry.1.push_str(&clone);
        }
        for (at, (target, clones)) in inserts {
            let in_defs = target.parent_element().is_some_and(|p| is_svg(p, "defs"));
            let text = if in_defs {
                clones
            } else {
                format!("<defs>{clones}</defs>")
            };
            main_edits.push(Edit {
                range: at..at,
                text,
            });
            summary.notes.push(format!(
                "cuts reached through <use> were dilated in copies of {} (ids suffixed -kerfN)",
                describe(&self.lines, target)
            ));
        }
        Ok(())
    }

    /// The source of `target` with `edits` (source ranges) applied and every id suffixed.
    fn clone_of(
        &self,
        target: Node,
        edits: Vec<Edit>,
        suffix: &str,
        taken: &mut HashSet<String>,
    ) -> Result<String> {
        let tr = target.range();
        let mut local: Vec<Edit> = edits
            .into_iter()
            .map(|e| Edit {
                range: e.range.start - tr.start..e.range.end - tr.start,
                text: e.text,
            })
            .collect();
        for n in target.descendants().filter(|n| n.is_element()) {
            if let Some(a) = n
                .attributes()
                .find(|a| a.name() == "id" && a.namespace().is_none())
            {
                // roxmltree gives the value unescaped: written back, it is escaped again.
                let new_id = format!("{}{suffix}", a.value());
                let r = a.range_value();
                local.push(Edit {
                    range: r.start - tr.start..r.end - tr.start,
                    text: crate::xml::escape(&new_id),
                });
                taken.insert(new_id);
            }
        }
        apply_edits(&self.text[tr], local)
    }
}
