//! Text edits of the source: byte-range replacements, the places a cut element's new path data
//! changes (its slots), and the writer that copies the source with edits applied, from memory or
//! from its file read again.

use std::io::Write;
use std::ops::Range;

use roxmltree::Node;

use super::{INKSCAPE_NS, SODIPODI_NS, bad};
use crate::error::{PlanError, Result};
use crate::source_file::Copier;

const GEOMETRY_ATTRIBUTES: [&str; 14] = [
    "x", "y", "width", "height", "rx", "ry", "cx", "cy", "r", "x1", "y1", "x2", "y2", "points",
];

/// A place in the source that writing a cut element's new path data changes, found while reading
/// (see [`geometry_slots`]), so that writing needs no XML tree of the source.
#[derive(Debug, Clone)]
pub(super) struct Slot {
    range: Range<usize>,
    put: Put,
}

/// What goes in a [`Slot`].
#[derive(Debug, Clone, Copy)]
enum Put {
    /// The new path data (the value of the element's `d`).
    D,
    /// A new `d` attribute with the path data.
    NewD,
    /// Nothing: an attribute removed.
    Nothing,
    /// `path`: the element's new name.
    Path,
}

/// A byte-range replacement in the source (an insertion when the range is empty).
#[derive(Debug, Clone)]
pub(super) struct Edit {
    pub(super) range: Range<usize>,
    pub(super) text: String,
}

/// The edits that give an element with these `slots` the path data `d`.
pub(super) fn filled(slots: &[Slot], d: &str) -> Vec<Edit> {
    slots
        .iter()
        .map(|slot| Edit {
            range: slot.range.clone(),
            text: match slot.put {
                Put::D => d.to_string(),
                Put::NewD => format!(" d=\"{d}\""),
                Put::Nothing => String::new(),
                Put::Path => "path".into(),
            },
        })
        .collect()
}

/// Where giving `node` new path data changes the source (see the module doc).
pub(super) fn geometry_slots(src: &str, node: Node) -> Vec<Slot> {
    let mut slots = Vec::new();
    let is_path = node.tag_name().name() == "path";
    let dropped = |a: &roxmltree::Attribute| match a.namespace() {
        Some(SODIPODI_NS) => true,
        Some(INKSCAPE_NS) => matches!(a.name(), "original-d" | "path-effect"),
        None => !is_path && GEOMETRY_ATTRIBUTES.contains(&a.name()),
        _ => false,
    };
    let mut last_end = tag_name_range(src, node).end;
    let mut has_d = false;
    for a in node.attributes() {
        last_end = last_end.max(a.range().end);
        if is_path && a.name() == "d" && a.namespace().is_none() {
            has_d = true;
            slots.push(Slot {
                range: a.range_value(),
                put: Put::D,
            });
        } else if dropped(&a) {
            slots.push(Slot {
                range: attribute_with_space(src, &a),
                put: Put::Nothing,
            });
        }
    }
    if !has_d {
        slots.push(Slot {
            range: last_end..last_end,
            put: Put::NewD,
        });
    }
    if !is_path {
        slots.push(Slot {
            range: local_name(src, tag_name_range(src, node)),
            put: Put::Path,
        });
        let r = node.range();
        if !src[..r.end].ends_with("/>")
            && let Some(i) = src[r.clone()].rfind("</")
        {
            let start = r.start + i + 2;
            let end = src[start..r.end]
                .find(|c: char| c.is_whitespace() || c == '>')
                .map_or(r.end, |k| start + k);
            slots.push(Slot {
                range: local_name(src, start..end),
                put: Put::Path,
            });
        }
    }
    slots
}

/// `<tag` … the byte range of the tag's qualified name in a start tag.
pub(super) fn tag_name_range(src: &str, n: Node) -> Range<usize> {
    let start = n.range().start + 1;
    let end = src[start..]
        .find(|c: char| c.is_whitespace() || c == '/' || c == '>')
        .map_or(src.len(), |i| start + i);
    start..end
}

/// The range of the local name within a qualified name range.
fn local_name(src: &str, qname: Range<usize>) -> Range<usize> {
    match src[qname.clone()].rfind(':') {
        Some(i) => qname.start + i + 1..qname.end,
        None => qname,
    }
}

/// An attribute's range including the whitespace before it.
fn attribute_with_space(src: &str, a: &roxmltree::Attribute) -> Range<usize> {
    let r = a.range();
    let mut start = r.start;
    while start > 0 && src.as_bytes()[start - 1].is_ascii_whitespace() {
        start -= 1;
    }
    start..r.end
}

/// The order edits are applied in: by where they start, then end (an insertion before a
/// replacement at the same place).
pub(super) fn edit_key(e: &Edit) -> (usize, usize) {
    (e.range.start, e.range.end)
}

/// `edits` in the order they are applied in (equal ones keep their order).
pub(super) fn sorted(mut edits: Vec<Edit>) -> Vec<Edit> {
    edits.sort_by_key(edit_key);
    edits
}

/// The source text an [`EditWriter`] copies: in memory, or its file read as it is copied.
pub(super) enum Src<'s> {
    Text(&'s str),
    File(Copier<'s>),
}

/// A source text being copied to a writer with non-overlapping edits applied, given in order.
pub(super) struct EditWriter<'s, 'o> {
    src: Src<'s>,
    /// How far the source has been copied.
    pos: usize,
    out: &'o mut dyn Write,
}

impl<'s, 'o> EditWriter<'s, 'o> {
    pub(super) fn new(src: Src<'s>, out: &'o mut dyn Write) -> Self {
        EditWriter { src, pos: 0, out }
    }

    /// Copy the source up to `e`, then `e`'s text in place of its range.
    pub(super) fn apply(&mut self, e: Edit) -> Result<()> {
        if e.range.start < self.pos {
            return Err(bad(
                "internal error: overlapping edits of the SVG text (please report this file)",
            ));
        }
        self.put(self.pos..e.range.start)?;
        self.write(&e.text)?;
        if let Src::File(file) = &mut self.src {
            file.copy_to(e.range.end as u64, None)?;
        }
        self.pos = e.range.end;
        Ok(())
    }

    /// Copy the rest of the source.
    pub(super) fn finish(mut self) -> Result<()> {
        match self.src {
            Src::Text(text) => {
                let rest = self.pos..text.len();
                self.put(rest)?;
            }
            Src::File(file) => file.finish(self.out)?,
        }
        self.out.flush().map_err(write_error)
    }

    fn put(&mut self, range: Range<usize>) -> Result<()> {
        match &mut self.src {
            Src::Text(src) => {
                let text = src.get(range).ok_or_else(|| {
                    bad("internal error: an edit of the SVG text splits a character (please report this file)")
                })?;
                self.out.write_all(text.as_bytes()).map_err(write_error)
            }
            Src::File(file) => file.copy_to(range.end as u64, Some(&mut *self.out)),
        }
    }

    fn write(&mut self, text: &str) -> Result<()> {
        self.out.write_all(text.as_bytes()).map_err(write_error)
    }
}

/// An error writing the output; the caller names the output.
fn write_error(source: std::io::Error) -> PlanError {
    PlanError::Write {
        path: std::path::PathBuf::new(),
        source,
    }
}

/// Apply non-overlapping edits.
pub(super) fn apply_edits(src: &str, edits: Vec<Edit>) -> Result<String> {
    // The exact size: the tagged copy of a large plan is held while usvg parses it, at the peak.
    let grown: usize = edits.iter().map(|e| e.text.len()).sum();
    let cut: usize = edits.iter().map(|e| e.range.len()).sum();
    let mut out = Vec::with_capacity((src.len() + grown).saturating_sub(cut));
    let mut writer = EditWriter::new(Src::Text(src), &mut out);
    for e in sorted(edits) {
        writer.apply(e)?;
    }
    writer.finish()?;
    String::from_utf8(out)
        .map_err(|_| bad("internal error: the edited SVG is not UTF-8 (please report this file)"))
}
