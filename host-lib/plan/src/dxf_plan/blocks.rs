//! Block references (`INSERT`) in DXF plans: the cuts inside a block are read through the
//! insertion's transform and dilated like any other, and the rest of the block is kept.
//!
//! An `INSERT` places a block at its insertion point, scaled (x and y, either may be negative: a
//! mirror), rotated about that point, and, for an array (`MINSERT`), repeated in rows and
//! columns; blocks may insert other blocks. Each instance of a cut entity in a block becomes its
//! own contour in document mm (each instance can need its own kerf from a map, and a rotated,
//! mirrored or unequally scaled one has its own shape), written as a new model-space polyline:
//! the cuts are exploded. Inside a block, layer `0` and `BYBLOCK` colour, linetype and lineweight
//! take the inserting entity's, as CAD programs draw them, and so do the new polylines.
//!
//! The cut entities are then taken out of the block, whose other entities (text, engraving,
//! open paths) stay as they were, byte for byte, and so do the `INSERT`s: every insertion still
//! shows what is not a cut, once. That is only right when every insertion of the block was
//! dilated: a block holding cuts that is also inserted where its cuts are not read (in paper
//! space, by an invisible `INSERT`, through a block inserted so) is refused, naming that
//! insertion; so is a block whose chains close in one insertion and not in another.

use std::collections::{HashMap, HashSet};

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

/// Where an entity is: model space (the `ENTITIES` section, paper space's entities there
/// included) or a block (upper-case name).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(super) enum Container {
    Model,
    Block(String),
}

/// An entity by its container and its index there (the `dxf` crate's order, the file's).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(super) struct EntityRef {
    pub container: Container,
    pub index: usize,
}

impl EntityRef {
    pub(super) fn model(index: usize) -> Self {
        EntityRef {
            container: Container::Model,
            index,
        }
    }
}

/// A cut read inside a block: what the new model-space polyline is drawn with, and what it came
/// from.
#[derive(Debug, Clone)]
pub(super) struct BlockCut {
    /// Its properties, the block's layer `0` and `BYBLOCK` ones resolved.
    pub common: EntityCommon,
    /// The block (upper-case name) and the entities of it the contour came from.
    pub block: String,
    pub entities: Vec<usize>,
    /// The `INSERT`s it was reached through, outermost (in model space) first.
    pub via: Vec<EntityRef>,
}

/// The state of expanding a drawing's block references.
pub(super) struct Expansion<'d> {
    drawing: &'d Drawing,
    /// Blocks by upper-case name.
    blocks: HashMap<String, &'d Block>,
    /// Layer colours by upper-case name.
    layer_colors: HashMap<String, dxf::Color>,
    /// Block instances seen.
    instances: usize,
    /// Entities met through them (each instance's block entities).
    expanded_entities: usize,
    /// The `INSERT`s being expanded, outermost first, and their blocks' upper-case names.
    via: Vec<EntityRef>,
    stack: Vec<String>,
    /// The `INSERT`s that were expanded.
    expanded: HashSet<EntityRef>,
    /// The entities taken out of each block (upper-case name) by its first instance, sorted.
    removed: HashMap<String, Vec<usize>>,
    /// Blocks whose instances took out different entities.
    inconsistent: Vec<String>,
}

impl<'d> Expansion<'d> {
    pub(super) fn new(drawing: &'d Drawing) -> Self {
        Expansion {
            drawing,
            blocks: drawing
                .blocks()
                .map(|b| (b.name.to_uppercase(), b))
                .collect(),
            layer_colors: drawing
                .layers()
                .map(|l| (l.name.to_uppercase(), l.color.clone()))
                .collect(),
            instances: 0,
            expanded_entities: 0,
            via: Vec::new(),
            stack: Vec::new(),
            expanded: HashSet::new(),
            removed: HashMap::new(),
            inconsistent: Vec::new(),
        }
    }

    pub(super) fn layer_colors(&self) -> &HashMap<String, dxf::Color> {
        &self.layer_colors
    }

    /// Check that every block whose cuts were taken out was dilated wherever it is inserted (see
    /// the module doc), adding a problem for each that was not; notes the blocks in `summary`.
    pub(super) fn finish(self, summary: &mut PlanSummary, problems: &mut Problems) {
        let refs = self.references();
        let mut names: Vec<&String> = self
            .removed
            .iter()
            .filter(|(_, removed)| !removed.is_empty())
            .map(|(name, _)| name)
            .collect();
        names.sort();
        for name in &names {
            if let Some(why) = self.uncovered(name, &refs, &mut Vec::new()) {
                problems.push(format!(
                    "block \"{}\" holds cuts, which are dilated as model-space polylines and taken out of it, but it is also {why}, where they would be lost; explode that insertion in the CAD program, or delete it",
                    self.blocks.get(*name).map_or(name.as_str(), |b| b.name.as_str())
                ));
            }
        }
        for name in &self.inconsistent {
            problems.push(format!(
                "block \"{name}\" holds pieces of cuts that close into a contour in one insertion and not in another (its scales differ too much); explode the block in the CAD program"
            ));
        }
        if !names.is_empty() {
            let shown: Vec<&str> = names.iter().map(|n| n.as_str()).collect();
            summary.notes.push(format!(
                "cuts inside blocks were dilated as model-space polylines, one for each insertion, and taken out of their blocks ({}), whose other entities are kept",
                shown.join(", ")
            ));
        }
    }

    /// Every `INSERT` of the drawing by the upper-case name of the block it inserts.
    fn references(&self) -> HashMap<String, Vec<EntityRef>> {
        let mut refs: HashMap<String, Vec<EntityRef>> = HashMap::new();
        let mut note = |name: &str, at: EntityRef| {
            refs.entry(name.to_uppercase()).or_default().push(at);
        };
        for (i, e) in self.drawing.entities().enumerate() {
            if let EntityType::Insert(ins) = &e.specific {
                note(&ins.name, EntityRef::model(i));
            }
        }
        for block in self.drawing.blocks() {
            let container = Container::Block(block.name.to_uppercase());
            for (k, e) in block.entities.iter().enumerate() {
                if let EntityType::Insert(ins) = &e.specific {
                    let at = EntityRef {
                        container: container.clone(),
                        index: k,
                    };
                    note(&ins.name, at);
                }
            }
        }
        refs
    }

    /// Where block `name` is inserted without its cuts being read, in words; `None` when every
    /// insertion of it was expanded: in model space, or inside blocks that are themselves so or
    /// never inserted (a definition no drawing shows). A layout's block (`*Paper_Space…`) is
    /// paper space.
    fn uncovered(
        &self,
        name: &str,
        refs: &HashMap<String, Vec<EntityRef>>,
        seen: &mut Vec<String>,
    ) -> Option<String> {
        if seen.iter().any(|s| s == name) {
            return None;
        }
        seen.push(name.to_owned());
        for at in refs.get(name).map_or(&[][..], Vec::as_slice) {
            let outer = match &at.container {
                Container::Model if self.expanded.contains(at) => continue,
                Container::Model => return Some(self.model_insert_not_read(at.index)),
                Container::Block(outer) => outer,
            };
            if outer.starts_with("*PAPER_SPACE") || outer.starts_with("*MODEL_SPACE") {
                return Some(format!("inserted in the layout block \"{outer}\""));
            }
            if let Some(why) = self.uncovered(outer, refs, seen) {
                return Some(format!("inserted inside block \"{outer}\", which is {why}"));
            }
            if refs.contains_key(outer) && !self.expanded.contains(at) {
                return Some(format!(
                    "inserted by an INSERT that is not drawn (invisible) in block \"{outer}\""
                ));
            }
        }
        None
    }

    /// Why the model-space `INSERT` `i` was not read, in words.
    fn model_insert_not_read(&self, i: usize) -> String {
        match self.drawing.entities().nth(i) {
            Some(e) if e.common.is_in_paper_space => {
                format!("inserted in paper space by {}", label(e))
            }
            Some(e) => format!("inserted by {}, which is not drawn (invisible)", label(e)),
            None => "inserted where it is not read".into(),
        }
    }

    /// Note that one instance of `block` took out `removed` (its first instance's are kept; any
    /// other must take out the same).
    fn note_removed(&mut self, block: &str, mut removed: Vec<usize>) {
        removed.sort_unstable();
        removed.dedup();
        match self.removed.get(block) {
            None => {
                self.removed.insert(block.to_owned(), removed);
            }
            Some(first) if *first != removed && !self.inconsistent.iter().any(|n| n == block) => {
                self.inconsistent.push(block.to_owned());
            }
            Some(_) => {}
        }
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

/// One `INSERT` to expand: its properties (inheritance resolved), what it says, where it is,
/// and its name in messages.
pub(super) struct Insertion<'e> {
    pub by: &'e EntityCommon,
    pub ins: &'e Insert,
    pub at: EntityRef,
    pub label: &'e str,
}

impl DxfPlan<'_> {
    /// Read the cuts of the block that `insertion` inserts inside `parent` (block coordinates of
    /// the inserting block → document mm), nested `depth` deep.
    pub(super) fn expand_insert<'d>(
        &self,
        insertion: Insertion,
        parent: &Affine,
        depth: usize,
        st: &mut Expansion<'d>,
        plan: &mut Plan<Origin>,
        problems: &mut Problems,
    ) {
        let Some((block, frames)) = self.instances(&insertion, parent, depth, st, plan, problems)
        else {
            return;
        };
        let key = block.name.to_uppercase();
        st.expanded.insert(insertion.at.clone());
        st.stack.push(key.clone());
        st.via.push(insertion.at);
        for frame in &frames {
            let removed = self.expand_cell(
                insertion.by,
                block,
                frame,
                insertion.label,
                depth,
                st,
                plan,
                problems,
            );
            st.note_removed(&key, removed);
        }
        st.via.pop();
        st.stack.pop();
    }

    /// The block an insertion inserts and the frame of each of its cells; `None` (with a problem
    /// when it is one) when it inserts nothing to read.
    fn instances<'d>(
        &self,
        insertion: &Insertion,
        parent: &Affine,
        depth: usize,
        st: &mut Expansion<'d>,
        plan: &mut Plan<Origin>,
        problems: &mut Problems,
    ) -> Option<(&'d Block, Vec<Affine>)> {
        let (ins, via) = (insertion.ins, insertion.label);
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
        let Some(&block) = st.blocks.get(&key) else {
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
        let frames = cell_frames(ins, block, parent)
            .map_err(|why| problems.push(format!("{via} {why}")))
            .ok()?;
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
        Some((block, frames))
    }

    /// Read the cuts of one instance of `block` (see [`Self::expand_insert`]): the entities of the
    /// block that its closed cuts came from, which are taken out of it.
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
    ) -> Vec<usize> {
        let key = block.name.to_uppercase();
        let name_of = |k: usize| {
            format!(
                "{} in block {} via {via}",
                label(&block.entities[k]),
                block.name
            )
        };
        let mut removed: Vec<usize> = Vec::new();
        let mut pieces: Vec<Piece> = Vec::new();
        for (k, e) in block.entities.iter().enumerate() {
            let common = inherit(&e.common, by);
            if !common.is_visible {
                plan.summary.pass("invisible");
                continue;
            }
            if let EntityType::Insert(inner) = &e.specific {
                let inner_via = name_of(k);
                let at = EntityRef {
                    container: Container::Block(key.clone()),
                    index: k,
                };
                let insertion = Insertion {
                    by: &common,
                    ins: inner,
                    at,
                    label: &inner_via,
                };
                self.expand_insert(insertion, frame, depth + 1, st, plan, problems);
                continue;
            }
            if !self.is_cut(&common, &e.specific, &st.layer_colors, &mut plan.summary) {
                continue;
            }
            let place = Place::Block {
                common: &common,
                block: &key,
                via: &st.via,
            };
            match self.read_checked(e, place, k, frame, &mut plan.summary) {
                Ok(Read::Closed(pl, origin)) => {
                    plan.cut(pl, name_of(k), origin);
                    removed.push(k);
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
            Origin::Block(Box::new(BlockCut {
                common: inherit(&first.common, by),
                block: key.clone(),
                entities: list.to_vec(),
                via: st.via.clone(),
            }))
        };
        removed.extend(close_chains(pieces, &name_of, &origin_of, plan, problems));
        removed
    }
}
