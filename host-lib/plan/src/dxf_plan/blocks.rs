//! Block references (`INSERT`) in DXF plans: the cuts inside a block are read through the
//! insertion's transform and dilated like any other, and the rest of the block is kept.
//!
//! An `INSERT` places a block at its insertion point, scaled (x and y, either may be negative: a
//! mirror), rotated about that point, and, for an array (`MINSERT`), repeated in rows and
//! columns; blocks may insert other blocks. Each instance of a cut entity in a block becomes its
//! own contour in document mm (each instance can need its own kerf from a map), written back as a
//! new model-space `LWPOLYLINE`. Inside a block, layer `0` and `BYBLOCK` colour, linetype and
//! lineweight take the inserting entity's, as CAD programs draw them.
//!
//! The block itself is left as it was, for any other user of it. An `INSERT` whose block held
//! cuts is pointed at a copy of the block without them (named `NAME_KERFn`; its nested
//! references pointed at such copies in turn), so that what is not a cut — text, engraving,
//! open paths — stays where it was, drawn once.

use std::collections::HashMap;

use dxf::entities::{Entity, EntityCommon, EntityType, Insert};
use dxf::{Block, Drawing};

use super::{DxfPlan, Origin, Piece, Place, Read, close_chains, label};
use crate::error::Problems;
use crate::geom::{Affine, v2};
use crate::outcome::PlanSummary;
use crate::pipeline::Plan;

/// Blocks nested deeper than this are refused.
const MAX_NESTING: usize = 16;

/// More block instances than this in one drawing are refused (a damaged array count).
const MAX_INSTANCES: usize = 100_000;

/// More entities than this read through block instances (each instance's entities) are refused:
/// 100,000 instances of a block of 50 circles ran out of memory.
const MAX_EXPANDED_ENTITIES: usize = 1_000_000;

/// What a block's copy changes: entity `k` removed (`None`, a cut) or its `INSERT` pointed at
/// another block (`Some(name)`).
type BlockEdits = Vec<(usize, Option<String>)>;

/// The state of expanding a drawing's block references.
pub(super) struct Expansion<'d> {
    /// Blocks by upper-case name.
    blocks: HashMap<String, &'d Block>,
    /// Layer colours by upper-case name.
    layer_colors: HashMap<String, dxf::Color>,
    /// Copies made, by the block and what they change: their names.
    copies: HashMap<(String, BlockEdits), String>,
    /// The copies, to add to the drawing.
    rest: Vec<Block>,
    /// Model-space `INSERT`s to point at a copy.
    retargets: Vec<(usize, String)>,
    /// Block instances seen.
    instances: usize,
    /// Entities met through them (each instance's block entities).
    expanded_entities: usize,
    /// The blocks being expanded, outermost first (upper-case names).
    stack: Vec<String>,
}

impl<'d> Expansion<'d> {
    pub(super) fn new(drawing: &'d Drawing) -> Self {
        Expansion {
            blocks: drawing
                .blocks()
                .map(|b| (b.name.to_uppercase(), b))
                .collect(),
            layer_colors: drawing
                .layers()
                .map(|l| (l.name.to_uppercase(), l.color.clone()))
                .collect(),
            copies: HashMap::new(),
            rest: Vec::new(),
            retargets: Vec::new(),
            instances: 0,
            expanded_entities: 0,
            stack: Vec::new(),
        }
    }

    pub(super) fn layer_colors(&self) -> &HashMap<String, dxf::Color> {
        &self.layer_colors
    }

    /// Point the model-space `INSERT` `i` at the block copy `name`.
    pub(super) fn retarget(&mut self, i: usize, name: String) {
        self.retargets.push((i, name));
    }

    /// The `INSERT`s to point at copies and the copies to add; notes them in `summary`.
    pub(super) fn finish(self, summary: &mut PlanSummary) -> (Vec<(usize, String)>, Vec<Block>) {
        if !self.rest.is_empty() {
            let names: Vec<&str> = self.rest.iter().map(|b| b.name.as_str()).collect();
            summary.notes.push(format!(
                "cuts inside blocks were dilated as model-space LWPOLYLINEs; the rest of each block is kept in a copy ({})",
                names.join(", ")
            ));
        }
        (self.retargets, self.rest)
    }

    /// The name of the copy of `block` with `edits`, made once.
    fn copy(&mut self, block: &Block, edits: BlockEdits) -> String {
        let key = (block.name.to_uppercase(), edits);
        if let Some(name) = self.copies.get(&key) {
            return name.clone();
        }
        let base = block.name.trim_start_matches('*');
        let name = (1..)
            .map(|n| format!("{base}_KERF{n}"))
            .find(|n| {
                let up = n.to_uppercase();
                !self.blocks.contains_key(&up)
                    && !self.rest.iter().any(|b| b.name.to_uppercase() == up)
            })
            .expect("an unused name");
        let mut copy = block.clone();
        copy.name = name.clone();
        copy.set_is_anonymous(false);
        let entities = std::mem::take(&mut copy.entities);
        copy.entities = entities
            .into_iter()
            .enumerate()
            .filter_map(|(k, mut e)| {
                match key.1.iter().find(|(j, _)| *j == k) {
                    Some((_, None)) => return None,
                    Some((_, Some(target))) => {
                        if let EntityType::Insert(ins) = &mut e.specific {
                            ins.name = target.clone();
                        }
                    }
                    None => {}
                }
                e.common.handle = dxf::Handle::empty();
                Some(e)
            })
            .collect();
        self.rest.push(copy);
        self.copies.insert(key, name.clone());
        name
    }
}

/// An entity's properties inside a block inserted by `by`: layer `0` and `BYBLOCK` colour,
/// linetype and lineweight become the inserting entity's.
fn inherit(own: &EntityCommon, by: &EntityCommon) -> EntityCommon {
    let mut c = own.clone();
    if c.layer == "0" {
        c.layer = by.layer.clone();
    }
    if c.color.is_by_block() {
        c.color = by.color.clone();
        c.color_24_bit = by.color_24_bit;
    }
    if c.line_type_name.eq_ignore_ascii_case("BYBLOCK") {
        c.line_type_name = by.line_type_name.clone();
    }
    // −2 is BYBLOCK.
    if c.lineweight_enum_value == -2 {
        c.lineweight_enum_value = by.lineweight_enum_value;
    }
    c
}

/// The frames (block coordinates → document mm) of every cell of an insertion inside `parent`.
fn cell_frames(ins: &Insert, block: &Block, parent: &Affine) -> Result<Vec<Affine>, String> {
    let numbers = [
        ins.location.x,
        ins.location.y,
        ins.x_scale_factor,
        ins.y_scale_factor,
        ins.rotation,
        ins.column_spacing,
        ins.row_spacing,
        block.base_point.x,
        block.base_point.y,
    ];
    if numbers.iter().any(|v| !v.is_finite()) {
        return Err("has a position, scale or angle that is not a number".into());
    }
    let mirrored = super::mirrored(&ins.extrusion_direction)
        .ok_or("is not in the XY plane (its extrusion direction is not ±z); flatten the drawing")?;
    if ins.x_scale_factor == 0.0 || ins.y_scale_factor == 0.0 {
        return Err("has a zero scale".into());
    }
    let (cols, rows) = (ins.column_count.max(1), ins.row_count.max(1));
    let cells = usize::from(cols.unsigned_abs()) * usize::from(rows.unsigned_abs());
    if cells > MAX_INSTANCES {
        return Err(format!(
            "is an array of {cells} copies, more than {MAX_INSTANCES}"
        ));
    }
    let (sin, cos) = ins.rotation.to_radians().sin_cos();
    let rotate = |x: f64, y: f64| v2(cos * x - sin * y, sin * x + cos * y);
    let (sx, sy) = (ins.x_scale_factor, ins.y_scale_factor);
    let ocs = Affine {
        a: if mirrored { -1.0 } else { 1.0 },
        ..Affine::IDENTITY
    };
    let mut frames = Vec::with_capacity(cells);
    for r in 0..rows {
        for c in 0..cols {
            let at = v2(ins.location.x, ins.location.y)
                + rotate(
                    f64::from(c) * ins.column_spacing,
                    f64::from(r) * ins.row_spacing,
                );
            // p ↦ at + R·S·(p − base)
            let (b, d) = (block.base_point.x, block.base_point.y);
            let m = Affine {
                a: cos * sx,
                b: sin * sx,
                c: -sin * sy,
                d: cos * sy,
                e: at.x - (cos * sx * b - sin * sy * d),
                f: at.y - (sin * sx * b + cos * sy * d),
            };
            frames.push(parent.then_after(&ocs.then_after(&m)));
        }
    }
    Ok(frames)
}

impl DxfPlan<'_> {
    /// Read the cuts of the block that `ins` (properties `by`, named `via` in messages) inserts
    /// inside `parent` (block coordinates of the inserting block → document mm), nested `depth`
    /// deep: the name of the copy of its block without them, when it held any.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn expand_insert<'d>(
        &self,
        by: &EntityCommon,
        ins: &Insert,
        parent: &Affine,
        via: &str,
        depth: usize,
        st: &mut Expansion<'d>,
        plan: &mut Plan<Origin>,
        problems: &mut Problems,
    ) -> Option<String> {
        if st.instances > MAX_INSTANCES || st.expanded_entities > MAX_EXPANDED_ENTITIES {
            // Said once, when a count was passed.
            return None;
        }
        let key = ins.name.to_uppercase();
        if st.stack.contains(&key) {
            problems.push(format!(
                "{via} inserts block \"{}\" inside itself; fix the block in the CAD program",
                ins.name
            ));
            return None;
        }
        if depth >= MAX_NESTING {
            problems.push(format!(
                "{via}: blocks nested more than {MAX_NESTING} deep (a block that inserts itself?); explode the blocks in the CAD program"
            ));
            return None;
        }
        let Some(&block) = st.blocks.get(&ins.name.to_uppercase()) else {
            problems.push(format!(
                "{via} inserts block \"{}\", which is not in the file; the file is incomplete (save it again from the CAD program)",
                ins.name
            ));
            return None;
        };
        if block.is_xref() {
            plan.summary
                .pass("INSERT of an external reference (not read)");
            return None;
        }
        let frames = match cell_frames(ins, block, parent) {
            Ok(f) => f,
            Err(why) => {
                problems.push(format!("{via} {why}"));
                return None;
            }
        };
        st.instances += frames.len();
        if st.instances > MAX_INSTANCES {
            problems.push(format!(
                "{via}: more than {MAX_INSTANCES} block instances in the drawing; explode the blocks in the CAD program"
            ));
            return None;
        }
        st.expanded_entities = (st.expanded_entities)
            .saturating_add(frames.len().saturating_mul(block.entities.len()));
        if st.expanded_entities > MAX_EXPANDED_ENTITIES {
            problems.push(format!(
                "{via}: its copies of block \"{}\" come to more than {MAX_EXPANDED_ENTITIES} entities in the drawing, with the blocks read before; explode and simplify the blocks in the CAD program",
                ins.name
            ));
            return None;
        }
        let mut edits: BlockEdits = Vec::new();
        st.stack.push(key);
        for (cell, frame) in frames.iter().enumerate() {
            let cell_edits = self.expand_cell(by, block, frame, via, depth, st, plan, problems);
            if cell == 0 {
                edits = cell_edits;
            }
        }
        st.stack.pop();
        if edits.is_empty() {
            return None;
        }
        edits.sort();
        Some(st.copy(block, edits))
    }

    /// Read the cuts of one instance of `block` (see [`Self::expand_insert`]): what the block's
    /// copy must change.
    #[allow(clippy::too_many_arguments)]
    fn expand_cell<'d>(
        &self,
        by: &EntityCommon,
        block: &'d Block,
        frame: &Affine,
        via: &str,
        depth: usize,
        st: &mut Expansion<'d>,
        plan: &mut Plan<Origin>,
        problems: &mut Problems,
    ) -> BlockEdits {
        let name_of = |k: usize| {
            format!(
                "{} in block {} via {via}",
                label(&block.entities[k]),
                block.name
            )
        };
        let mut edits: BlockEdits = Vec::new();
        let mut pieces: Vec<Piece> = Vec::new();
        for (k, e) in block.entities.iter().enumerate() {
            let common = inherit(&e.common, by);
            if !common.is_visible {
                plan.summary.pass("invisible");
                continue;
            }
            if let EntityType::Insert(inner) = &e.specific {
                let inner_via = name_of(k);
                let rest = self.expand_insert(
                    &common,
                    inner,
                    frame,
                    &inner_via,
                    depth + 1,
                    st,
                    plan,
                    problems,
                );
                if let Some(rest) = rest {
                    edits.push((k, Some(rest)));
                }
                continue;
            }
            if !self.is_cut(&common, &e.specific, &st.layer_colors, &mut plan.summary) {
                continue;
            }
            match self.read_checked(e, Place::Block(&common), k, frame, &mut plan.summary) {
                Ok(Read::Closed(pl, origin)) => {
                    plan.cut(pl, name_of(k), origin);
                    edits.push((k, None));
                }
                Ok(Read::Piece(piece)) => pieces.push(piece),
                Ok(Read::Nothing) => {}
                Err(problem) => {
                    problems.push(format!("{problem} (in block {} via {via})", block.name))
                }
            }
        }
        let origin_of = |list: &[usize]| {
            let first: &Entity = &block.entities[list[0]];
            Origin::Added(Box::new(inherit(&first.common, by)))
        };
        for k in close_chains(pieces, &name_of, &origin_of, plan) {
            edits.push((k, None));
        }
        edits
    }
}
