//! Dilating closed cut contours by half the kerf: the core, independent of file formats.
//!
//! The laser removes a strip of width k centred on the line it follows, so a part cut along its
//! nominal outline comes out k/2 too small all round. Cutting instead along the boundary of the
//! part's **Minkowski sum with a disk of radius k/2** (the beam is round) gives back the nominal
//! part exactly: every closed contour is offset by k/2 with *round joins* — outer contours grow,
//! holes shrink, and a part lying inside another part's hole (an island) grows again.
//!
//! * **Nesting** decides the sign: a contour's *depth* is the number of contours enclosing it.
//!   Even depth = the outer contour of a part, odd depth = a hole of the part it lies in directly.
//!   The direction each contour is drawn in does not matter (it is normalised for the offset and
//!   restored afterwards, so fill rules and cut order keep working).
//! * **Offsets** come from `cavalier_contours` (`parallel_offset`): lines stay lines, arcs stay
//!   arcs, convex corners get round joins (arcs of radius k/2), concave corners stay sharp. For a
//!   part with holes the contours can be offset one by one: outer contours move outwards and holes
//!   move into the hole, away from each other, so they never interact — provided they do not
//!   meet as drawn, which is checked (two holes of a part however close, even closer than the
//!   kerf, shrink apart).
//! * **Kerf per part**: each part (an outer contour with its holes) uses one kerf, the one given
//!   at the part's area centroid (with a kerf map, interpolated there).
//! * **Recompensation** ([`Offsetting::Recompensate`], [`dilate_with`]): a plan already offset by
//!   a burn moves by kerf/2 − burn instead, with its drawn corners kept sharp (see
//!   [`crate::recompensate`]). With a burn above kerf/2 that moves into the part's material —
//!   holes grow, outlines shrink — so a part's loops are checked again once offset: where its
//!   material is narrower than twice the move, they would overlap.
//!
//! * **Memory**: [`dilate_releasing_drawn`] (what the plan pipeline uses) frees each drawn contour
//!   as soon as it is offset, so a large plan's drawn and dilated geometry are not held at once.
//!
//! Problems are collected, not stopped at, and reported together (each with the contours' labels
//! and a position in mm): contours that cross themselves or each other (holes of one part
//! included: two holes side by side are compared with a spatial index of the holes, nesting only
//! compares a contour with the larger ones around it), a loop drawn twice, a hole narrower than the
//! kerf (it would vanish or split), a part whose outline would close around a void, loops of a
//! part that a recompensation would move into each other, and two parts
//! that would *merge* — closer than the kerf, so their dilated regions overlap (or share a cut
//! line). A notch open to the outside and narrower than the kerf simply fills in: no kerf
//! compensation can cut it.
//!
//! The public types and the entry points are here; the work is one module each: `nesting` (the
//! contours as drawn, nested into parts), `offset` (each part's kerf and the offsets), `meeting`
//! (loops and parts that meet or would merge), `geometry` (the small questions they ask); tests
//! in `tests`.

use serde::Serialize;
use std::fmt;
use std::sync::Arc;

use super::geom::Pline;
use crate::error::{PlanError, Result};
use crate::progress::{Progress, Stage};

mod geometry;
mod meeting;
mod nesting;
mod offset;

#[cfg(test)]
mod tests;

use meeting::{check_holes, check_merges, check_offset_loops};
use nesting::{check_each, group_parts};

pub(crate) use nesting::nest;
use offset::{kerf_per_part, offset_all};

/// Largest kerf accepted, µm (a sanity bound: real kerfs are 50–500 µm).
pub const MAX_KERF_UM: f64 = 5000.0;

/// A closed cut contour in document space, mm.
#[derive(Debug, Clone)]
pub struct Contour {
    /// The contour (closed; either direction).
    pub pline: Pline,
    /// How to name it in messages, e.g. `path "side-a"` or `LWPOLYLINE 2F`.
    pub label: String,
}

/// The kerf (µm) at a point of the bed (x, y in mm).
pub type KerfField = dyn Fn(f64, f64) -> f64 + Send + Sync;

/// Where the kerf comes from.
#[derive(Clone)]
pub enum KerfSource {
    /// The same kerf everywhere, µm.
    Uniform(f64),
    /// A kerf that varies over the bed, e.g. a bed map's: each part uses the kerf at its
    /// centroid.
    Map(Arc<KerfField>),
}

impl fmt::Debug for KerfSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            KerfSource::Uniform(k) => f.debug_tuple("Uniform").field(k).finish(),
            KerfSource::Map(_) => f.write_str("Map(..)"),
        }
    }
}

impl KerfSource {
    /// The kerf at (`x_mm`, `y_mm`), µm.
    pub fn kerf_at_um(&self, x_mm: f64, y_mm: f64) -> f64 {
        match self {
            KerfSource::Uniform(k) => *k,
            KerfSource::Map(field) => field(x_mm, y_mm),
        }
    }

    /// Check a kerf value given by the user, µm.
    pub fn check_kerf_um(kerf_um: f64) -> Result<f64> {
        if kerf_um == 0.0 {
            // −0 is 0: a report says "by 0 µm".
            Ok(0.0)
        } else if kerf_um.is_finite() && (0.0..=MAX_KERF_UM).contains(&kerf_um) {
            Ok(kerf_um)
        } else {
            Err(PlanError::InvalidArgument(format!(
                "the kerf must be between 0 and {MAX_KERF_UM} µm, got {} µm",
                kerfmeter_protocol::Shown(kerf_um)
            )))
        }
    }
}

/// What a contour is within its part.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// The outline of a part (even nesting depth): grows.
    Outer,
    /// A hole of a part (odd nesting depth): shrinks.
    Hole,
}

/// A part: an outer contour and its holes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Part {
    /// Index of the outer contour.
    pub outer: usize,
    /// Indexes of its holes.
    pub holes: Vec<usize>,
    /// Nesting depth of the outer contour (0 = top level; 2, 4, … = an island in a hole).
    pub depth: usize,
    /// Area centroid of the part (outer minus holes), mm.
    pub centroid_mm: [f64; 2],
    /// Area of the part, mm².
    pub area_mm2: f64,
    /// The kerf used for this part, µm.
    pub kerf_um: f64,
}

/// The result of [`dilate`].
#[derive(Debug, Clone)]
pub struct Dilation {
    /// The dilated contours, one per input contour, drawn in the same direction as the input.
    pub contours: Vec<Pline>,
    /// Role of each input contour.
    pub roles: Vec<Role>,
    /// Part of each input contour (index into `parts`).
    pub part_of: Vec<usize>,
    /// The parts.
    pub parts: Vec<Part>,
}

/// How each contour is moved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Offsetting {
    /// By half the kerf, with round joins: the Minkowski sum with the beam's disk.
    Dilate,
    /// The plan is already offset by `burn_mm` (boxes.py's burn, or an earlier dilation): move
    /// every contour by half the kerf minus that, keeping the drawn corners sharp
    /// (see [`crate::recompensate`]).
    Recompensate {
        /// The offset already drawn, mm.
        burn_mm: f64,
    },
}

/// Dilate closed contours (document space, mm) by half the kerf, with nesting, per-part kerf and
/// the checks described in the module doc.
pub fn dilate(contours: &[Contour], kerf: &KerfSource) -> Result<Dilation> {
    dilate_with_progress(contours, kerf, Offsetting::Dilate, &Progress::default())
}

/// [`dilate`], with the contours moved as `how` says.
pub fn dilate_with(contours: &[Contour], kerf: &KerfSource, how: Offsetting) -> Result<Dilation> {
    dilate_with_progress(contours, kerf, how, &Progress::default())
}

/// [`dilate_with`], telling `progress` how many contours are offset.
///
/// The contours are independent, so the work on them (the checks of each, nesting, offsets, the
/// merge check) is spread over the cores with rayon; the results are put together in the input's
/// order, so they do not depend on the number of threads.
pub fn dilate_with_progress(
    contours: &[Contour],
    kerf: &KerfSource,
    how: Offsetting,
    progress: &Progress,
) -> Result<Dilation> {
    dilate_drawn(Drawn::Lent(contours), kerf, how, progress)
}

/// [`dilate_with_progress`], freeing each contour's drawn geometry (its polyline is left empty)
/// as soon as it is offset; the labels stay, for messages. Nothing after the offsets needs the
/// drawn geometry, and a large plan's drawn and dilated contours held at once were most of its
/// memory: this way the drawn ones go while the dilated ones are made. After an error the
/// contours may be partly emptied (those offset before it): the plan is not to be used again.
pub fn dilate_releasing_drawn(
    contours: &mut [Contour],
    kerf: &KerfSource,
    how: Offsetting,
    progress: &Progress,
) -> Result<Dilation> {
    dilate_drawn(Drawn::Given(contours), kerf, how, progress)
}

/// The drawn contours the kernel works on: lent (left as they are), or given (each one's
/// polyline freed once it is offset).
enum Drawn<'c> {
    Lent(&'c [Contour]),
    Given(&'c mut [Contour]),
}

impl Drawn<'_> {
    fn get(&self) -> &[Contour] {
        match self {
            Drawn::Lent(c) => c,
            Drawn::Given(c) => c,
        }
    }
}

fn dilate_drawn(
    mut drawn: Drawn,
    kerf: &KerfSource,
    how: Offsetting,
    progress: &Progress,
) -> Result<Dilation> {
    let contours = drawn.get();
    progress.start(Stage::Dilating, contours.len());
    let (areas, centroids) = check_each(contours)?;
    let (depth, parent) = nest(contours, &areas)?;
    let roles: Vec<Role> = depth
        .iter()
        .map(|d| if d % 2 == 0 { Role::Outer } else { Role::Hole })
        .collect();
    let (mut parts, part_index) = group_parts(&roles, &depth, &parent);
    check_holes(contours, &parts)?;
    kerf_per_part(&mut parts, contours, &areas, &centroids, kerf)?;
    let dilated = offset_all(&mut drawn, &roles, &parts, &part_index, how, progress)?;
    check_offset_loops(drawn.get(), &parts, &dilated, how)?;
    check_merges(drawn.get(), &parts, &dilated)?;
    Ok(Dilation {
        contours: dilated,
        roles,
        part_of: part_index,
        parts,
    })
}
