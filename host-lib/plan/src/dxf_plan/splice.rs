//! Writing a dilated DXF by splicing: the input's text is copied as read, and only what changes
//! is rewritten in its place. This is the only way a DXF is written: the `dxf` crate's own save
//! rebuilt the whole drawing, which broke the structure other programs need (duplicated block
//! records pointing at layout 0, layouts without their plot settings, `BLOCK` and `ENDBLK`
//! sharing handles, R12 vertices without handles) and changed entities that are not cuts
//! (lineweights, pointers to handle 0, transparencies and true colours added). It also formatted
//! every number again: most of the time and memory of dilating a large DXF went there.
//!
//! The output is:
//!
//! * the record of what was applied (`999` comments; an earlier record of this tool at the top of
//!   the input is dropped, the file's other comments kept);
//! * every byte of the input as read (a binary input converted to ASCII first), except that
//!   - cut entities are edited in place or left out (see the `text` submodule), in model space
//!     and in blocks (whose cuts are drawn in model space instead, see the `blocks` submodule);
//!   - the new closed polylines are added at the end of the `ENTITIES` section, with new handles
//!     when the drawing has handles, and `$HANDSEED` moved past them;
//!   - units assumed for a drawing that did not say are written into its `$INSUNITS` (from
//!     R2000, the first version that has it).
//!
//! Formatting the new vertices is most of the work: the changed entities' text is made on every
//! core, a batch at a time, and put in file order (the output does not depend on the number of
//! cores). The scan stops at `0 EOF`, as readers do, and what follows is copied.

use std::collections::HashSet;
use std::io::Write as _;

use cavalier_contours::polyline::PlineSource;
use rayon::prelude::*;

use super::layout::{Layout, Scanned, Span};
use super::text::{Form, NewPolyline, Out, Precision, edit_circle, edit_lwpolyline, new_polyline};
use crate::geom::Pline;

/// Changed entities whose text is made at once, on any core, before it is put in its place (the
/// text of all of them would be more than the file).
const WRITE_BATCH: usize = 1024;

/// What is done to one entity of the input.
#[derive(Debug, Clone, Copy)]
pub(super) enum Change {
    /// A closed `LWPOLYLINE` whose vertices become the contour.
    Vertices,
    /// A `CIRCLE` whose centre becomes (x, y, z) and radius r (drawing units).
    Circle([f64; 4]),
    /// Left out (replaced by a new polyline).
    Drop,
}

/// How the new polylines are written: their form, and whether they get handles.
#[derive(Debug, Clone, Copy)]
pub(super) struct Style {
    pub form: Form,
    pub handles: bool,
}

/// The changes to make to the input.
pub(super) struct Splice<'p> {
    /// (span, change, contour) of entities changed.
    edits: Vec<(Span, Change, Option<&'p Pline>)>,
    /// The spans left out so far (an entity of a block is left out once, whatever the number
    /// of its insertions).
    dropped: HashSet<Span>,
    /// New polylines, in order.
    added: Vec<NewPolyline<'p>>,
    /// The `$INSUNITS` code to write.
    insunits: Option<i32>,
}

impl<'p> Splice<'p> {
    pub fn new() -> Self {
        Splice {
            edits: Vec::new(),
            dropped: HashSet::new(),
            added: Vec::new(),
            insunits: None,
        }
    }

    /// Change the entity `e` (an entity of a block is left out once, however often it is met).
    pub fn change(&mut self, e: &Scanned, change: Change, contour: Option<&'p Pline>) {
        if matches!(change, Change::Drop) && !self.dropped.insert(e.span) {
            return;
        }
        self.edits.push((e.span, change, contour));
    }

    /// Add a new closed polyline.
    pub fn add(&mut self, new: NewPolyline<'p>) {
        self.added.push(new);
    }

    /// Write `code` into the header's `$INSUNITS`.
    pub fn set_insunits(&mut self, code: i32) {
        self.insunits = Some(code);
    }

    /// The spliced file: `record` first, then the input (`bytes`, laid out as `layout` says) with
    /// the changes; numbers written as `precision` says, new polylines as `style` says. `None`
    /// when the changes cannot be placed (an entity changed twice, an entity not as scanned, no
    /// `ENTITIES` section for new polylines, no header for `$INSUNITS`).
    pub fn write(
        self,
        bytes: &[u8],
        layout: &Layout,
        record: Option<&str>,
        precision: Precision,
        style: Style,
    ) -> Option<Vec<u8>> {
        let mut out = Out {
            bytes: Vec::with_capacity(bytes.len() + bytes.len() / 4),
            eol: layout.eol,
            precision,
        };
        if let Some(record) = record {
            let record = record.replace("\r\n", "\n").replace('\n', layout.eol);
            out.bytes.extend_from_slice(record.as_bytes());
        }
        let handles = self.handles(layout, style)?;
        let cuts = self.cuts(layout, handles.as_ref().map(|h| h.1))?;
        let mut at = 0;
        for batch in cuts.chunks(WRITE_BATCH) {
            let made: Vec<Option<Vec<u8>>> = batch
                .par_iter()
                .map(|(span, cut)| {
                    let mut piece = out.sibling();
                    cut.write(bytes, *span, &mut piece)?;
                    Some(piece.bytes)
                })
                .collect();
            for ((span, cut), piece) in batch.iter().zip(made) {
                if span.0 < at {
                    // Two changes to one place.
                    return None;
                }
                out.bytes.extend_from_slice(&bytes[at..span.0]);
                if matches!(cut, Cut::Insert) {
                    self.write_added(bytes, style.form, handles.as_ref().map(|h| &h.0), &mut out);
                }
                out.bytes.extend_from_slice(&piece?);
                at = span.1;
            }
        }
        out.bytes.extend_from_slice(&bytes[at..]);
        Some(out.bytes)
    }

    /// When new entities get handles: the first handle of each new polyline, and the `$HANDSEED`
    /// after them. `Some(None)` when they get none; `None` when there are too many.
    fn handles(&self, layout: &Layout, style: Style) -> Option<Option<(Vec<u64>, u64)>> {
        if !style.handles {
            return Some(None);
        }
        let mut next = layout
            .handseed
            .map_or(0, |(_, h)| h)
            .max(layout.max_handle.checked_add(1)?);
        let mut firsts = Vec::with_capacity(self.added.len());
        for new in &self.added {
            firsts.push(next);
            next = next.checked_add(style.form.handles(new.contour.vertex_count()))?;
        }
        Some(Some((firsts, next)))
    }

    /// Every change at its span, in file order.
    fn cuts(&self, layout: &Layout, handseed: Option<u64>) -> Option<Vec<(Span, Cut<'p>)>> {
        let mut cuts: Vec<(Span, Cut)> = self
            .edits
            .iter()
            .map(|&(span, change, contour)| (span, Cut::Entity(change, contour)))
            .collect();
        cuts.extend(layout.old_records.iter().map(|&s| (s, Cut::Remove)));
        if !self.added.is_empty() {
            let at = layout.entities_end?;
            cuts.push(((at, at), Cut::Insert));
            if let (Some((span, _)), Some(seed)) = (layout.handseed, handseed) {
                cuts.push((span, Cut::Handseed(seed)));
            }
        }
        if let Some(code) = self.insunits {
            cuts.push(match layout.insunits {
                Some(span) => (span, Cut::Value(code.to_string())),
                None => {
                    let at = layout.header_end?;
                    let eol = layout.eol;
                    let variable = format!("  9{eol}$INSUNITS{eol} 70{eol}{code:>6}{eol}");
                    ((at, at), Cut::Value(variable))
                }
            });
        }
        cuts.sort_by_key(|(span, _)| *span);
        Some(cuts)
    }

    /// The new polylines, handles from `firsts` on (when they get handles), straight into
    /// `out`: formatted on every core a batch at a time, so that no more than a batch's text is
    /// held beside the output.
    fn write_added(&self, bytes: &[u8], form: Form, firsts: Option<&Vec<u64>>, out: &mut Out) {
        for (b, batch) in self.added.chunks(WRITE_BATCH).enumerate() {
            let made: Vec<Vec<u8>> = batch
                .par_iter()
                .enumerate()
                .map(|(k, new)| {
                    let mut text = out.sibling();
                    let first = firsts.map(|f| f[b * WRITE_BATCH + k]);
                    new_polyline(bytes, new, form, first, &mut text);
                    text.bytes
                })
                .collect();
            for text in made {
                out.bytes.extend_from_slice(&text);
            }
        }
    }
}

/// One change to the input, at a span.
enum Cut<'p> {
    Entity(Change, Option<&'p Pline>),
    Remove,
    /// The new polylines (written by [`Splice::write_added`], not here).
    Insert,
    Handseed(u64),
    /// Text in place of the span.
    Value(String),
}

impl Cut<'_> {
    fn write(&self, bytes: &[u8], span: Span, out: &mut Out) -> Option<()> {
        match self {
            Cut::Entity(Change::Drop, _) | Cut::Remove | Cut::Insert => {}
            Cut::Entity(Change::Vertices, contour) => {
                edit_lwpolyline(bytes, span, contour.as_ref()?, out)?
            }
            Cut::Entity(Change::Circle(c), _) => edit_circle(bytes, span, *c, out)?,
            Cut::Handseed(h) => {
                let _ = write!(out.bytes, "{h:X}");
            }
            Cut::Value(text) => out.bytes.extend_from_slice(text.as_bytes()),
        }
        Some(())
    }
}
