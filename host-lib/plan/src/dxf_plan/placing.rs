//! Where each entity the `dxf` crate read is in the file, and what a new entity drawn for a cut
//! copies from there.
//!
//! The crate reads a container's entities (the `ENTITIES` section, or a block) in file order,
//! gathering a `POLYLINE`'s vertices and an `INSERT`'s attributes into them as the scan does
//! (see the `layout` submodule), and skipping the types it does not know. So the entities of the
//! kinds a dilation changes or reads through — `LWPOLYLINE`, `POLYLINE`, `LINE`, `ARC`,
//! `CIRCLE`, `ELLIPSE`, `SPLINE`, `INSERT`, all of which it knows — come in the same order in
//! both: they are matched one to one by that order, each pair checked to be of the same type and,
//! where the file gives one, the same handle. No handle is needed (R12 files often have none)
//! and none is trusted alone (a handle used twice in a damaged file).

use std::collections::HashMap;

use dxf::Drawing;
use dxf::entities::{Entity, EntityType};

use super::blocks::{Container, EntityRef};
use super::layout::{Layout, Scanned, Span};

/// The type names a file may give an entity the crate read as `e`, when it is of a kind that is
/// matched.
fn names(e: &EntityType) -> Option<&'static [&'static [u8]]> {
    Some(match e {
        EntityType::LwPolyline(_) => &[b"LWPOLYLINE"],
        EntityType::Polyline(_) => &[b"POLYLINE"],
        EntityType::Line(_) => &[b"LINE", b"3DLINE"],
        EntityType::Arc(_) => &[b"ARC"],
        EntityType::Circle(_) => &[b"CIRCLE"],
        EntityType::Ellipse(_) => &[b"ELLIPSE"],
        EntityType::Spline(_) => &[b"SPLINE"],
        EntityType::Insert(_) => &[b"INSERT"],
        _ => return None,
    })
}

/// Whether the file's type name `kind` is one of the kinds matched.
fn is_matched_kind(kind: &[u8]) -> bool {
    matches!(
        kind,
        b"LWPOLYLINE"
            | b"POLYLINE"
            | b"LINE"
            | b"3DLINE"
            | b"ARC"
            | b"CIRCLE"
            | b"ELLIPSE"
            | b"SPLINE"
            | b"INSERT"
    )
}

/// For each of the crate's `entities`, the index in `scanned` of the same entity in the file
/// (`None` for a kind that is not matched); why not, when they do not correspond. The handles
/// are compared when `handles_kept` (the crate keeps model space's, and gives a block's entities
/// new ones as it reads them).
pub(super) fn align<'e>(
    entities: impl Iterator<Item = &'e Entity>,
    scanned: &[Scanned],
    bytes: &[u8],
    handles_kept: bool,
) -> Result<Vec<Option<usize>>, String> {
    let mut in_file = scanned
        .iter()
        .enumerate()
        .filter(|(_, s)| is_matched_kind(s.kind(bytes)));
    let mut found = Vec::new();
    for e in entities {
        let Some(names) = names(&e.specific) else {
            found.push(None);
            continue;
        };
        let Some((k, s)) = in_file.next() else {
            return Err(format!(
                "the file has fewer entities than were read (at {})",
                e.common.handle.as_string()
            ));
        };
        let handle_differs = handles_kept && s.handle.is_some_and(|h| h != e.common.handle.0);
        if !names.contains(&s.kind(bytes)) || handle_differs {
            return Err(format!(
                "entity {} in the file is not the {} that was read there",
                String::from_utf8_lossy(s.kind(bytes)),
                e.common.handle.as_string()
            ));
        }
        found.push(Some(k));
    }
    match in_file.next() {
        Some(_) => Err("the file has more entities than were read".into()),
        None => Ok(found),
    }
}

/// The file's span of every entity a dilation touches, found as needed.
pub(super) struct Places<'a> {
    bytes: &'a [u8],
    layout: &'a Layout,
    drawing: &'a Drawing,
    /// Model space's entities (the crate's order) to indexes into `layout.model`.
    model: Vec<Option<usize>>,
    /// Each block's, by upper-case name, once matched.
    blocks: HashMap<String, Vec<Option<usize>>>,
}

impl<'a> Places<'a> {
    pub fn new(bytes: &'a [u8], layout: &'a Layout, drawing: &'a Drawing) -> Result<Self, String> {
        let model = align(drawing.entities(), &layout.model, bytes, true)
            .map_err(|why| format!("in the ENTITIES section, {why}"))?;
        Ok(Places {
            bytes,
            layout,
            drawing,
            model,
            blocks: HashMap::new(),
        })
    }

    /// The scanned entity of `at`.
    pub fn get(&mut self, at: &EntityRef) -> Result<Scanned, String> {
        let (found, scanned) = match &at.container {
            Container::Model => (&self.model, &self.layout.model),
            Container::Block(name) => {
                let scanned = match self.layout.blocks.get(name) {
                    Some(Some(block)) => &block.entities,
                    Some(None) => return Err(format!("two blocks are named \"{name}\"")),
                    None => return Err(format!("block \"{name}\" is not in the BLOCKS section")),
                };
                if !self.blocks.contains_key(name) {
                    let block = self
                        .drawing
                        .blocks()
                        .find(|b| b.name.eq_ignore_ascii_case(name))
                        .ok_or_else(|| format!("block \"{name}\" was not read"))?;
                    let found = align(block.entities.iter(), scanned, self.bytes, false)
                        .map_err(|why| format!("in block \"{name}\", {why}"))?;
                    self.blocks.insert(name.clone(), found);
                }
                (&self.blocks[name], scanned)
            }
        };
        found
            .get(at.index)
            .copied()
            .flatten()
            .map(|k| scanned[k])
            .ok_or_else(|| "an entity to change is not where it was read".into())
    }
}

/// The pairs that style a new entity drawn for a cut: layer (`8`), colour (`62`, with its true
/// colour `420` and colour name `430`), linetype (`6`) and lineweight (`370`), each as the file
/// writes it, taken from the first of `chain` (the cut's entity, then the `INSERT`s it was read
/// through, innermost first) that does not leave it to its block's insertion: layer `0`, colour
/// `BYBLOCK` (0), linetype `BYBLOCK` and lineweight −2 pass it on, as the `dxf` crate's reading
/// of the cut did. Absent pairs (`BYLAYER`) are left absent; a layer absent is layer `0`.
pub(super) fn style_pairs(bytes: &[u8], chain: &[Scanned]) -> Vec<Span> {
    const GROUPS: [&[i32]; 4] = [&[8], &[62, 420, 430], &[6], &[370]];
    let mut out = Vec::new();
    for group in GROUPS {
        for (k, e) in chain.iter().enumerate() {
            let mut own: Vec<(i32, Span, &[u8])> = Vec::new();
            for p in e.own_pairs(bytes) {
                if group.contains(&p.code) && !own.iter().any(|(c, _, _)| *c == p.code) {
                    own.push((p.code, (p.start, p.end), p.value));
                }
            }
            let lead = own.iter().find(|(c, _, _)| *c == group[0]);
            let passes_on = match lead {
                Some((code, _, value)) => passes_on(*code, value),
                None => group[0] == 8,
            };
            if !passes_on || k + 1 == chain.len() {
                out.extend(own.iter().map(|(_, span, _)| *span));
                break;
            }
        }
    }
    out
}

/// Whether a property's value leaves it to the block's insertion.
fn passes_on(code: i32, value: &[u8]) -> bool {
    match code {
        8 | 62 => value == b"0",
        6 => value.eq_ignore_ascii_case(b"BYBLOCK"),
        370 => value == b"-2",
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_new_entity_takes_what_its_block_entity_passes_on_from_the_insert() {
        let text = "0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n2\nP\n\
            0\nLINE\n5\n10\n8\n0\n62\n0\n6\nDASHED\n370\n-2\n0\nENDBLK\n0\nENDSEC\n\
            0\nSECTION\n2\nENTITIES\n0\nINSERT\n5\n11\n8\nCUTS\n62\n1\n420\n16711680\n370\n13\n2\nP\n0\nENDSEC\n0\nEOF\n";
        let bytes = text.as_bytes();
        let layout = Layout::scan(bytes).unwrap();
        let line = layout.blocks["P"].as_ref().unwrap().entities[0];
        let chain = [line, layout.model[0]];
        let pairs: Vec<String> = style_pairs(bytes, &chain)
            .iter()
            .map(|&(s, e)| String::from_utf8_lossy(&bytes[s..e]).replace('\n', " "))
            .collect();
        assert_eq!(
            pairs,
            ["8 CUTS ", "62 1 ", "420 16711680 ", "6 DASHED ", "370 13 "]
        );
        // Alone, in model space, BYBLOCK stays BYBLOCK.
        let own: Vec<Span> = style_pairs(bytes, &chain[..1]);
        assert_eq!(own.len(), 4);
    }

    #[test]
    fn entities_are_matched_by_order_type_and_handle() {
        let text = "0\nSECTION\n2\nENTITIES\n0\nTEXT\n1\nx\n0\nLINE\n10\n0\n0\nCIRCLE\n5\n2A\n40\n1\n0\nENDSEC\n0\nEOF\n";
        let drawing = Drawing::load(&mut std::io::Cursor::new(text)).unwrap();
        let layout = Layout::scan(text.as_bytes()).unwrap();
        let mut places = Places::new(text.as_bytes(), &layout, &drawing).unwrap();
        let circle = places.get(&EntityRef::model(2)).unwrap();
        assert_eq!(circle.kind(text.as_bytes()), b"CIRCLE");
        assert!(
            places.get(&EntityRef::model(0)).is_err(),
            "TEXT is not matched"
        );
        // A handle that differs is a mismatch.
        let other = text.replace("5\n2A", "5\n2B");
        let layout = Layout::scan(other.as_bytes()).unwrap();
        assert!(Places::new(other.as_bytes(), &layout, &drawing).is_err());
    }
}
