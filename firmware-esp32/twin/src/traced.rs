//! What a laser traced: the moves a cutter made, each with its laser's power and feed, as the
//! device twin takes them to recover the gauge a cutter cut ([`crate::gauge_trace`]). The cutter
//! twin that records them (a simulated GRBL cutter) lives beside the GRBL driver, in the
//! `kerfmeter` library's `grbl::twin` (its `sim` feature); this is the vocabulary the two twins
//! share, so that the device twin needs nothing of a cutter but what it traced.

use std::f64::consts::TAU;

/// A position, mm (X, Y, Z).
pub type Point = [f64; 3];

/// What kind of move a segment is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SegmentKind {
    /// G0: a travel at the maximum rate.
    Travel,
    /// G1: a straight feed move.
    Line,
    /// G2/G3: an arc about `center` (XY).
    Arc {
        /// The arc's centre, mm.
        center: [f64; 2],
        /// G2.
        clockwise: bool,
    },
    /// G4: a pause where the head stands still.
    Dwell,
}

/// One executed move.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Its kind (and an arc's centre and sense).
    pub kind: SegmentKind,
    /// Where it started, mm.
    pub start: Point,
    /// Where it ended, mm: its target, or where it was stopped.
    pub end: Point,
    /// The laser's power while it ran (the `S` value; 0 when off).
    pub power_s: f64,
    /// Its feed rate, mm/min.
    pub feed_mm_per_min: f64,
    /// False when it was cut short (reset, alarm).
    pub complete: bool,
    /// The received G-code line it came from (1 = the first G-code line since boot).
    pub line: u32,
}

/// The angle an arc sweeps, rad, in (0, 2π]: a whole turn when it ends where it starts.
pub fn sweep_rad(start: Point, end: Point, center: [f64; 2], clockwise: bool) -> f64 {
    let a0 = (start[1] - center[1]).atan2(start[0] - center[0]);
    let a1 = (end[1] - center[1]).atan2(end[0] - center[0]);
    let ccw = if clockwise { a0 - a1 } else { a1 - a0 };
    let sweep = ccw.rem_euclid(TAU);
    if sweep < 1e-9 { TAU } else { sweep }
}
