//! A DXF file as it is read: its text (a binary file converted to ASCII text pair for pair),
//! the drawing the `dxf` crate reads from that text, where things are in it, and the
//! compensation its comments record (the loaded drawing has lost them).
//!
//! The crate gives a block's entities new handles as it reads them; the file's are put back (on
//! the entities a dilation reads: cut geometry and `INSERT`s, see the `placing` submodule), so
//! that a message names a cut in a block by the handle the CAD program shows.
//!
//! One fault of the crate is worked around: it reads every `5` pair of a `DIMSTYLE` record as a
//! handle, but in R12 a dimension style's `5` is the name of its arrow block (`ARCHTICK`), and the
//! crate stops on it, so that such an R12 file (ezdxf writes them, as do CAD programs with custom
//! arrows) could not be read at all. When a load fails and the file has such names, the crate is
//! given a copy with them blanked (a dimension style matters nothing to the cuts); the output is
//! still made from the file's own text.

use std::borrow::Cow;

use dxf::{Drawing, Handle};

use super::layout::Layout;
use super::placing::align;
use super::{bad, binary, values};
use crate::compensation::{self, FoundCompensation};
use crate::error::Result;
use crate::progress::{Progress, Stage};

/// A DXF file as read.
pub(super) struct Source<'b> {
    /// Its text: the file's bytes, or their conversion when it was binary.
    pub text: Cow<'b, [u8]>,
    pub binary: bool,
    pub drawing: Drawing,
    pub layout: Layout,
    pub found: Option<FoundCompensation>,
}

impl<'b> Source<'b> {
    /// Read a DXF file's `bytes` (ASCII or binary).
    pub fn read(bytes: &'b [u8], progress: &Progress) -> Result<Self> {
        progress.start(Stage::Reading, 0);
        let binary = binary::is_binary(bytes);
        let text: Cow<[u8]> = if binary {
            Cow::Owned(binary::to_ascii(bytes).map_err(bad)?)
        } else {
            Cow::Borrowed(bytes)
        };
        // Where the entities are is found on another core while the crate parses the text.
        let (loaded, layout) = rayon::join(|| values::load(&text), || Layout::scan(&text));
        let mut drawing = match (loaded, &layout) {
            (Ok(drawing), _) => drawing,
            (Err(e), Ok(layout)) if !layout.dimstyle_names.is_empty() => {
                values::load(&without_dimstyle_names(&text, layout)).map_err(|_| bad(e))?
            }
            // A binary file's own offsets say more than the converted text's lines.
            (Err(e), _) if binary => return Err(bad(values::load(bytes).err().unwrap_or(e))),
            (Err(e), _) => return Err(bad(e)),
        };
        let layout = layout.map_err(|why| bad(format!("not a readable DXF file: {why}")))?;
        restore_block_handles(&mut drawing, &layout, &text);
        let found = compensation::find_in_dxf(&text);
        Ok(Source {
            text,
            binary,
            drawing,
            layout,
            found,
        })
    }
}

/// Give the entities of each block the handles the file gives them, where they can be matched.
fn restore_block_handles(drawing: &mut Drawing, layout: &Layout, text: &[u8]) {
    for block in drawing.blocks_mut() {
        let Some(Some(scanned)) = layout.blocks.get(&block.name.to_uppercase()) else {
            continue;
        };
        let Ok(found) = align(block.entities.iter(), &scanned.entities, text, false) else {
            continue;
        };
        for (e, k) in block.entities.iter_mut().zip(found) {
            if let Some(handle) = k.and_then(|k| scanned.entities[k].handle) {
                e.common.handle = Handle(handle);
            }
        }
    }
}

/// A copy of `text` with the `DIMSTYLE` names found by the scan blanked (`0`: no handle).
fn without_dimstyle_names(text: &[u8], layout: &Layout) -> Vec<u8> {
    let mut out = Vec::with_capacity(text.len());
    let mut at = 0;
    for &(start, end) in &layout.dimstyle_names {
        out.extend_from_slice(&text[at..start]);
        out.push(b'0');
        at = end;
    }
    out.extend_from_slice(&text[at..]);
    out
}
