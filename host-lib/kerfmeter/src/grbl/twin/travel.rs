//! The cutter twin's travel: where its end stops are, GRBL's soft limits (`$20`), its homing
//! cycle (`$H`) and its report of the work offsets (`$#`).
//!
//! - End stops: the machine's real travel is [`CutterOptions::travel_mm`], fixed where the twin
//!   booted. Without homing it boots with its head at the origin corner of X and Y (each runs
//!   from 0 to its travel from there) and half-way up Z (−Z/2 to +Z/2). With homing it boots at
//!   its home corner, the positive end of every axis: each runs from −travel to 0, GRBL's
//!   machine space. A move whose path leaves that box is recorded when it starts
//!   ([`EndStopHit`]): a real head runs into its end stop there and loses its position (or trips
//!   a hard limit). The twin's head goes on as GRBL believes it does; the hit is only recorded.
//! - Soft limits, as GRBL 1.1 does them (`limits_soft_check` and `system_check_travel_limits`,
//!   default build): with `$20=1`, every target of a motion (each point of an arc) must lie
//!   within −`$13x` to 0 in machine coordinates. A target outside raises `ALARM:2` before the
//!   line moves anything (in check mode too): motion stops where it is, the position is kept,
//!   and nothing but a soft reset is heard (`[MSG:Reset to continue]`), as after a hard limit.
//!   GRBL checks against its settings, the twin's end stops are its real travel: a wrong
//!   `$130` lets a move through to the end stop, as on a real machine.
//! - `$H` (homing enabled, `$22=1`): the head is at once where GRBL's homing leaves it: `−$27`
//!   on each axis that homes toward positive, `−$13x + $27` on those `$23` sends toward
//!   negative; the alarm is cleared.
//! - `$#`: G54 is [`CutterOptions::work_offset_mm`] (as stored in GRBL's EEPROM; it applies to
//!   every absolute target but G53's), every other offset zero.

use super::machine::Grbl;
use super::motion::Move;
use super::options::CutterOptions;
use super::trace::{EndStopHit, Point, SegmentKind};

/// Points sampled along an arc to find how far it reaches.
const ARC_SAMPLES: u64 = 360;
/// How far a point may lie past a limit and still count as on it, mm: the grid Kerfmeter writes
/// G-code on (0.1 µm, `kerfmeter_plan::gcode`), as the host's own travel check allows. An arc
/// whose centre is rounded to that grid bulges up to about that far past its exact extreme, so
/// a plan placed on the travel's edge reaches a few hundredths of a micrometre past it; no end
/// stop can tell, and GRBL's own arc, computed in single precision, strays as far.
const TOLERANCE_MM: f64 = 1e-4;

/// Where the twin's end stops are on each axis, `[min, max]` mm in machine coordinates (see
/// the [module docs](self)).
pub fn end_stops_mm(options: &CutterOptions) -> [[f64; 2]; 3] {
    let [x, y, z] = options.travel_mm;
    if options.homing {
        [[-x, 0.0], [-y, 0.0], [-z, 0.0]]
    } else {
        [[0.0, x], [0.0, y], [-z / 2.0, z / 2.0]]
    }
}

/// The points a move takes the head to that can reach furthest: its target, or points along an
/// arc (as GRBL checks each of an arc's segments). Its start is the last move's.
fn reach(m: &Move) -> Vec<Point> {
    match m.kind {
        SegmentKind::Arc { .. } => (1..=ARC_SAMPLES)
            .map(|k| m.position_at(m.duration_us * k / ARC_SAMPLES))
            .collect(),
        _ => vec![m.end],
    }
}

/// How far `p` lies past `bounds` on `axis`, mm (negative inside).
fn excess(p: Point, bounds: [[f64; 2]; 3], axis: usize) -> f64 {
    let [min, max] = bounds[axis];
    (min - p[axis]).max(p[axis] - max)
}

/// The first axis on which `p` lies outside `bounds`, further than `from` did (a head already
/// past a stop on one axis hits nothing new moving along another), and how far, mm.
fn outside(p: Point, bounds: [[f64; 2]; 3], from: Option<Point>) -> Option<(usize, f64)> {
    (0..3).find_map(|axis| {
        let before = from.map_or(0.0, |f| excess(f, bounds, axis).max(0.0));
        let beyond = excess(p, bounds, axis);
        (beyond > before + TOLERANCE_MM).then_some((axis, beyond))
    })
}

impl Grbl {
    /// True when soft limits are on and `m` targets a point outside GRBL's machine space.
    pub(super) fn beyond_soft_limits(&self, m: &Move) -> bool {
        if !self.settings.soft_limits() || m.kind == SegmentKind::Dwell {
            return false;
        }
        let travel = self.settings.max_travel_mm();
        let space = travel.map(|t| [-t, 0.0]);
        reach(m)
            .into_iter()
            .any(|p| outside(p, space, None).is_some())
    }

    /// The end stop `m` runs into, if its path leaves the machine's travel.
    pub(super) fn end_stop_hit(&self, m: &Move) -> Option<EndStopHit> {
        if m.kind == SegmentKind::Dwell {
            return None;
        }
        let stops = end_stops_mm(&self.options);
        let from = Some(m.start);
        let (axis, beyond_mm) = reach(m).into_iter().find_map(|p| outside(p, stops, from))?;
        Some(EndStopHit {
            at_us: self.now_us(),
            line: m.line,
            start: m.start,
            end: m.end,
            axis,
            beyond_mm,
        })
    }

    /// `$H`: the head where GRBL's homing cycle leaves it, the alarm cleared.
    pub(super) fn home(&mut self) -> String {
        let travel = self.settings.max_travel_mm();
        let pulloff = self.settings.homing_pulloff_mm();
        let homed: Point = std::array::from_fn(|axis| match self.settings.homes_negative(axis) {
            true => -travel[axis] + pulloff,
            false => -pulloff,
        });
        self.move_to_home(homed);
        self.unlock();
        super::machine::ok()
    }

    /// The `$#` report (without its `ok`).
    pub(super) fn parameters_report(&self) -> String {
        let show = |p: Point| format!("{:.3},{:.3},{:.3}", p[0], p[1], p[2]);
        let zero = [0.0; 3];
        let mut out = format!("[G54:{}]\r\n", show(self.options.work_offset_mm));
        for name in ["G55", "G56", "G57", "G58", "G59", "G28", "G30", "G92"] {
            out += &format!("[{name}:{}]\r\n", show(zero));
        }
        out + "[TLO:0.000]\r\n[PRB:0.000,0.000,0.000:0]\r\n"
    }
}
