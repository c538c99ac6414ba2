//! The tagged copy of a source that usvg parses: every shape tagged with its number and every
//! `<use>` given an id, so that what usvg draws can be traced back to its element; and the
//! source made again from the copy.

use std::collections::HashMap;
use std::ops::Range;

use roxmltree::Node;

use super::bad;
use super::edits::{Edit, apply_edits, sorted, tag_name_range};
use crate::error::Result;

/// Prefix of the private ids given to `<use>` elements that have none (never written out).
pub(super) const USE_TAG: &str = "__kerfmeter_use_";

/// The source with tags inserted (see [`tagged`]), and where they are, so that the source can be
/// made again from it.
pub(super) struct Tagged {
    pub(super) text: String,
    /// The inserted tags' ranges in `text`, in order.
    pub(super) tags: Vec<Range<usize>>,
}

impl Tagged {
    /// The source `text` with the insertions `edits` (empty source ranges) applied.
    pub(super) fn new(src: &str, edits: Vec<Edit>) -> Result<Self> {
        let edits = sorted(edits);
        let mut grown = 0;
        let mut tags = Vec::with_capacity(edits.len());
        for e in &edits {
            if !e.range.is_empty() {
                return Err(bad(
                    "internal error: a tag replaces SVG text (please report this file)",
                ));
            }
            let at = e.range.start + grown;
            tags.push(at..at + e.text.len());
            grown += e.text.len();
        }
        Ok(Tagged {
            text: apply_edits(src, edits)?,
            tags,
        })
    }

    /// The source again: the text without the tags.
    pub(super) fn untagged(self) -> String {
        let tagged_len: usize = self.tags.iter().map(Range::len).sum();
        let mut src = String::with_capacity(self.text.len() - tagged_len);
        let mut pos = 0;
        for tag in &self.tags {
            src.push_str(&self.text[pos..tag.start]);
            pos = tag.end;
        }
        src.push_str(&self.text[pos..]);
        src
    }
}

/// The source `text` with every shape tagged by its number (`stroke-miterlimit`, which usvg
/// keeps) and every `<use>` given an id, so that what usvg renders can be traced back to its
/// element; and the `<use>` elements by id.
pub(super) fn tagged(
    text: &str,
    shapes: &[Node],
    uses: &[Node],
) -> Result<(Tagged, HashMap<String, usize>)> {
    let mut tags: Vec<Edit> = Vec::new();
    for (k, n) in shapes.iter().enumerate() {
        let code = k + 1;
        match n
            .attributes()
            .find(|a| a.name() == "style" && a.namespace().is_none())
        {
            Some(style) => tags.push(Edit {
                range: style.range_value().end..style.range_value().end,
                text: format!(";stroke-miterlimit:{code}"),
            }),
            None => {
                let at = tag_name_range(text, *n).end;
                tags.push(Edit {
                    range: at..at,
                    text: format!(" style=\"stroke-miterlimit:{code}\""),
                });
            }
        }
    }
    let mut use_by_id: HashMap<String, usize> = HashMap::new();
    for (k, u) in uses.iter().enumerate() {
        match u.attribute("id") {
            Some(id) => {
                use_by_id.insert(id.to_string(), k);
            }
            None => {
                let id = format!("{USE_TAG}{k}");
                let at = tag_name_range(text, *u).end;
                tags.push(Edit {
                    range: at..at,
                    text: format!(" id=\"{id}\""),
                });
                use_by_id.insert(id, k);
            }
        }
    }
    Ok((Tagged::new(text, tags)?, use_by_id))
}
