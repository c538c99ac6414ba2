//! The cutter twin's motion: a planned move (line, arc or dwell), its length and duration at a
//! constant feed, and where the head is part-way through it.
//!
//! Motion model: every move runs at its programmed feed (travels at the maximum rate) from start
//! to end, with no acceleration; only a feed hold decelerates (see [`super`]). A job's time is
//! therefore slightly short of a real machine's, whose corners slow it down.

use kerfmeter_twin::traced::sweep_rad;

use super::trace::{Point, SegmentKind};

/// How far an arc's end may be off its circle (GRBL's own tolerance: 0.005 mm, or 0.1 % of the
/// radius when larger).
const ARC_END_TOLERANCE_MM: f64 = 0.005;

/// One block in the planner queue.
#[derive(Debug, Clone, PartialEq)]
pub struct Move {
    /// Its kind.
    pub kind: SegmentKind,
    /// Start, mm.
    pub start: Point,
    /// Target, mm.
    pub end: Point,
    /// Feed, mm/min (the maximum rate for a travel; 0 for a dwell).
    pub feed_mm_per_min: f64,
    /// How long it takes, µs.
    pub duration_us: u64,
    /// The laser's output while it runs (`S`, 0 = off).
    pub power_s: f64,
    /// The power the program switched the beam on with (`M3`/`M4` and `S`, 0 when off):
    /// `power_s`, except where laser mode keeps a travel (or a dynamic-power dwell) dark.
    pub enabled_s: f64,
    /// The received G-code line it came from.
    pub line: u32,
}

impl Move {
    /// A straight move (`travel` for G0) at `feed_mm_per_min`.
    pub fn straight(start: Point, end: Point, feed_mm_per_min: f64, travel: bool) -> Self {
        let kind = if travel {
            SegmentKind::Travel
        } else {
            SegmentKind::Line
        };
        let length_mm = distance(start, end);
        Self::with_length(kind, start, end, feed_mm_per_min, length_mm)
    }

    /// An arc about `center` from `start` to `end`, or the `error:33` code when `end` is not on
    /// the circle.
    pub fn arc(
        start: Point,
        end: Point,
        center: [f64; 2],
        clockwise: bool,
        feed_mm_per_min: f64,
    ) -> Result<Self, u8> {
        let radius = planar_distance(start, center);
        let end_radius = planar_distance(end, center);
        let tolerance = ARC_END_TOLERANCE_MM.max(radius * 1e-3);
        if radius == 0.0 || (radius - end_radius).abs() > tolerance {
            return Err(kerfmeter_grbl::codes::INVALID_TARGET);
        }
        let kind = SegmentKind::Arc { center, clockwise };
        let sweep = sweep_rad(start, end, center, clockwise);
        let length_mm = (radius * sweep).hypot(end[2] - start[2]);
        Ok(Self::with_length(
            kind,
            start,
            end,
            feed_mm_per_min,
            length_mm,
        ))
    }

    /// A pause of `seconds` at `at`.
    pub fn dwell(at: Point, seconds: f64) -> Self {
        Self {
            kind: SegmentKind::Dwell,
            start: at,
            end: at,
            feed_mm_per_min: 0.0,
            duration_us: (seconds * 1e6).round() as u64,
            power_s: 0.0,
            enabled_s: 0.0,
            line: 0,
        }
    }

    fn with_length(
        kind: SegmentKind,
        start: Point,
        end: Point,
        feed_mm_per_min: f64,
        length_mm: f64,
    ) -> Self {
        let duration_us = (length_mm / feed_mm_per_min * 60e6).round() as u64;
        Self {
            kind,
            start,
            end,
            feed_mm_per_min,
            duration_us,
            power_s: 0.0,
            enabled_s: 0.0,
            line: 0,
        }
    }

    /// Where the head is after `elapsed_us` of this move.
    pub fn position_at(&self, elapsed_us: u64) -> Point {
        if self.duration_us == 0 || elapsed_us >= self.duration_us {
            return self.end;
        }
        let f = elapsed_us as f64 / self.duration_us as f64;
        let z = lerp(self.start[2], self.end[2], f);
        match self.kind {
            SegmentKind::Arc { center, clockwise } => {
                let sweep = sweep_rad(self.start, self.end, center, clockwise);
                let radius = planar_distance(self.start, center);
                let a0 = (self.start[1] - center[1]).atan2(self.start[0] - center[0]);
                let a = if clockwise {
                    a0 - sweep * f
                } else {
                    a0 + sweep * f
                };
                [
                    center[0] + radius * a.cos(),
                    center[1] + radius * a.sin(),
                    z,
                ]
            }
            _ => [
                lerp(self.start[0], self.end[0], f),
                lerp(self.start[1], self.end[1], f),
                z,
            ],
        }
    }
}

fn lerp(a: f64, b: f64, f: f64) -> f64 {
    a + (b - a) * f
}

fn distance(a: Point, b: Point) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

fn planar_distance(p: Point, c: [f64; 2]) -> f64 {
    (p[0] - c[0]).hypot(p[1] - c[1])
}

#[cfg(test)]
mod tests {
    use std::f64::consts::TAU;

    use super::*;

    #[test]
    fn a_line_takes_its_length_over_its_feed() {
        let m = Move::straight([0.0; 3], [30.0, 40.0, 0.0], 600.0, false);
        assert_eq!(m.duration_us, 5_000_000);
        assert_eq!(m.position_at(2_500_000), [15.0, 20.0, 0.0]);
    }

    #[test]
    fn a_quarter_arc_sweeps_a_quarter_turn_in_its_sense() {
        let ccw = Move::arc([10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0], false, 600.0).unwrap();
        let quarter_us = (10.0 * TAU / 4.0 / 10.0 * 1e6_f64).round() as u64;
        assert_eq!(ccw.duration_us, quarter_us);
        let mid = ccw.position_at(quarter_us / 2);
        assert!((mid[0] - mid[1]).abs() < 1e-6 && mid[0] > 0.0, "{mid:?}");
        let cw = Move::arc([10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [0.0, 0.0], true, 600.0).unwrap();
        assert!(cw.duration_us.abs_diff(3 * quarter_us) <= 1);
        assert!(Move::arc([10.0, 0.0, 0.0], [0.0, 12.0, 0.0], [0.0, 0.0], true, 600.0).is_err());
    }
}
