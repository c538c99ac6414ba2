//! The machine's travel: where GRBL's `$130`–`$132` put the head's reach in machine
//! coordinates, how work coordinates map onto it, and the check of a program's extent
//! ([`super::extent`]) or of single points against it ([`Travel`]).
//!
//! # The rule
//!
//! GRBL knows its travel only as the lengths `$130`–`$132`; where they lie in machine
//! coordinates depends on homing:
//!
//! - Homing on (`$22=1`): homing sets machine zero at the home switches and the travel lies in
//!   negative space, −`$13x` to 0 on every axis, whatever `$23` says (GRBL 1.1's default build;
//!   the box its own soft limits, `$20=1`, check: `system_check_travel_limits`). A GRBL built with
//!   `HOMING_FORCE_SET_ORIGIN` puts an axis that homes toward negative (`$23`) at 0 to +`$13x`
//!   instead; such an axis is taken so when the head stands above 0 on it.
//! - Homing off (`$22=0`, GRBL's default): machine zero is where the head stood at power-up.
//!   X and Y are taken to run from there, 0 to +`$13x`: the head switched on at the origin
//!   corner, as a laser without homing switches is used. Where the head stands in Z's travel is
//!   not known, so for Z only the span is checked: everything the head reaches in Z, its own
//!   height included, within `$132`.
//!
//! A work coordinate is the machine one less the work offset (`$#` and `$G`: the active
//! G54–G59, plus G92, plus the tool length offset on Z). The head's own position must lie in the
//! travel as taken; if it does not, the rule does not fit the machine, and nothing is let
//! through.
//!
//! # Its limits
//!
//! Without homing the rule trusts that the controller was switched on with the head at the
//! origin corner; a head switched on elsewhere shifts the travel by as much, which no check here
//! can see. A Z without homing may still reach an end within its span. A controller that
//! reports no `$130`–`$132` (or zero) is not checked.

use std::collections::BTreeMap;
use std::fmt;

use super::extent::{Extent, Reached, Start, Unbounded, extent};
use super::offsets::{Modal, Point};
use super::protocol::ProgramLine;

/// `$130`–`$132`: the X, Y and Z travel, mm.
pub use kerfmeter_grbl::settings::MAX_TRAVEL_MM as TRAVEL_SETTINGS;
use kerfmeter_grbl::settings::{
    HOMING as HOMING_SETTING, HOMING_DIR_MASK as HOMING_DIR_SETTING,
    SOFT_LIMITS as SOFT_LIMITS_SETTING,
};
/// The axes' names.
pub const AXES: [char; 3] = ['X', 'Y', 'Z'];
/// Rounding allowed at a limit, mm (programs are written to 0.1 µm).
const TOLERANCE_MM: f64 = 1e-4;

/// Where an axis may take the head.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reach {
    /// From `min_mm` to `max_mm`, machine coordinates.
    Between {
        /// The lowest, mm.
        min_mm: f64,
        /// The highest, mm.
        max_mm: f64,
    },
    /// Anywhere within `span_mm` of everything else the head reaches on it (where the head
    /// stands in the travel is not known).
    Span {
        /// The travel, mm.
        span_mm: f64,
    },
}

/// Whose travel it is: which words a refusal uses for where it comes from and what to change.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TravelSource {
    /// GRBL's `$130`–`$132`, read by the GRBL driver.
    #[default]
    Grbl,
    /// A Ruida controller's bed size (or the address's `bed-mm`) and the address's `z-mm`.
    Ruida,
}

/// The machine's travel as the controller reports it, and where its head and offsets stand.
#[derive(Debug, Clone, PartialEq)]
pub struct Travel {
    /// `$130`–`$132`, mm.
    pub travel_mm: [f64; 3],
    /// `$20`.
    pub soft_limits: bool,
    /// `$22`.
    pub homing: bool,
    /// Per axis, where the head may go (see the [module docs](self)).
    pub reach: [Reach; 3],
    /// Where the program would start: the head, the offsets, the parser state.
    pub start: Start,
    /// Whose travel it is.
    pub source: TravelSource,
}

/// A point beyond the travel, or a span wider than it.
#[derive(Debug, Clone, PartialEq)]
pub struct Beyond {
    /// The axis (0 X, 1 Y, 2 Z).
    pub axis: usize,
    /// The point beyond the travel (for a span: its far end).
    pub at: Reached,
    /// For a span: the other end.
    pub from: Option<Reached>,
    /// How it maps to work coordinates (machine = work + this), mm.
    pub work_offset_mm: f64,
    /// The travel, as the message tells it.
    pub limit: String,
    /// What GRBL would do: stop with a soft-limit alarm, or drive into the end stop.
    pub soft_limits: bool,
    /// Whose travel it is.
    pub source: TravelSource,
}

impl Travel {
    /// The travel `settings` report, with the head at `start` (`None` when the controller does
    /// not report `$130`–`$132`, or reports one as zero).
    pub fn read(settings: &BTreeMap<u16, f64>, start: Start) -> Option<Self> {
        let travel_mm = Self::reported(settings)?;
        let flag = |n: u16| settings.get(&n).is_some_and(|v| *v != 0.0);
        let homing = flag(HOMING_SETTING);
        let homes_negative = settings.get(&HOMING_DIR_SETTING).copied().unwrap_or(0.0) as u32;
        let reach = std::array::from_fn(|axis| {
            let t = travel_mm[axis];
            match (homing, axis) {
                (true, _)
                    if homes_negative & (1 << axis) != 0 && start.head_mm[axis] > TOLERANCE_MM =>
                {
                    Reach::Between {
                        min_mm: 0.0,
                        max_mm: t,
                    }
                }
                (true, _) => Reach::Between {
                    min_mm: -t,
                    max_mm: 0.0,
                },
                (false, 0 | 1) => Reach::Between {
                    min_mm: 0.0,
                    max_mm: t,
                },
                (false, _) => Reach::Span { span_mm: t },
            }
        });
        Some(Self {
            travel_mm,
            soft_limits: flag(SOFT_LIMITS_SETTING),
            homing,
            reach,
            start,
            source: TravelSource::Grbl,
        })
    }

    /// `$130`–`$132` when the controller reports all three above zero.
    pub fn reported(settings: &BTreeMap<u16, f64>) -> Option<[f64; 3]> {
        let mut travel = [0.0; 3];
        for (slot, number) in travel.iter_mut().zip(TRAVEL_SETTINGS) {
            *slot = settings
                .get(&number)
                .copied()
                .filter(|v| v.is_finite() && *v > 0.0)?;
        }
        Some(travel)
    }

    /// The bed a gauge may be placed on by default: the X and Y travel, mm.
    pub fn bed_mm(&self) -> [f64; 2] {
        [self.travel_mm[0], self.travel_mm[1]]
    }

    /// The work offset now: machine = work + this, mm.
    pub fn work_offset_mm(&self) -> Point {
        self.start
            .offsets
            .work_offset_mm(self.start.modal.coord_system)
    }

    /// The same machine after a soft reset (the check pass ends with one): G92 and the tool
    /// length offset gone, the parser at G0 G54 G17 G21 G90.
    pub fn after_reset(&self) -> Self {
        let start = Start {
            offsets: self.start.offsets.after_reset(),
            modal: Modal::after_reset(),
            ..self.start
        };
        Self {
            start,
            ..self.clone()
        }
    }

    /// How far `lines` reach from here.
    pub fn extent(&self, lines: &[ProgramLine]) -> Result<Extent, Unbounded> {
        extent(lines, &self.start)
    }

    /// An extent (its head included) within the travel, or the first axis where it is not;
    /// the head's own position is checked first.
    pub fn check(&self, extent: &Extent) -> Result<(), Box<Beyond>> {
        self.check_head()?;
        (0..3).try_for_each(|axis| self.check_axis(axis, &extent.min[axis], &extent.max[axis]))
    }

    /// The head stands in the travel as taken (else the rule does not fit this machine).
    pub fn check_head(&self) -> Result<(), Box<Beyond>> {
        let here = Extent::at(self.start.head_mm);
        (0..3).try_for_each(|axis| self.check_axis(axis, &here.min[axis], &here.max[axis]))
    }

    /// Points given in work coordinates on `axis` (the head's position taken in with them)
    /// within the travel.
    pub fn check_work(&self, axis: usize, work_mm: &[f64]) -> Result<(), Box<Beyond>> {
        let offset = self.work_offset_mm()[axis];
        let mut extent = Extent::at(self.start.head_mm);
        for &w in work_mm {
            let mut p = self.start.head_mm;
            p[axis] = w + offset;
            extent.take_in(p, None);
        }
        self.check_axis(axis, &extent.min[axis], &extent.max[axis])
    }

    fn check_axis(&self, axis: usize, min: &Reached, max: &Reached) -> Result<(), Box<Beyond>> {
        let beyond = |at: &Reached, from: Option<&Reached>| {
            Box::new(Beyond {
                axis,
                at: at.clone(),
                from: from.cloned(),
                work_offset_mm: self.work_offset_mm()[axis],
                limit: self.describe(axis),
                soft_limits: self.soft_limits,
                source: self.source,
            })
        };
        match self.reach[axis] {
            Reach::Between { min_mm, .. } if min.machine_mm < min_mm - TOLERANCE_MM => {
                Err(beyond(min, None))
            }
            Reach::Between { max_mm, .. } if max.machine_mm > max_mm + TOLERANCE_MM => {
                Err(beyond(max, None))
            }
            Reach::Span { span_mm } if max.machine_mm - min.machine_mm > span_mm + TOLERANCE_MM => {
                let head = self.start.head_mm[axis];
                // The end that is not the head's is the one the program went to.
                match max.machine_mm - head >= head - min.machine_mm {
                    true => Err(beyond(max, Some(min))),
                    false => Err(beyond(min, Some(max))),
                }
            }
            _ => Ok(()),
        }
    }

    /// The travel on `axis` as a message tells it: where it lies, and why.
    pub fn describe(&self, axis: usize) -> String {
        let name = AXES[axis];
        if let (TravelSource::Ruida, Reach::Between { min_mm, max_mm }) =
            (self.source, self.reach[axis])
        {
            let from = match axis {
                2 => "the z-mm of the ruida: address",
                _ => "the bed size the controller reports, or the address's bed-mm",
            };
            return format!("{name} runs {min_mm:.3} to {max_mm:.3} mm (machine; {from})");
        }
        let setting = format!("${}={}", TRAVEL_SETTINGS[axis], self.travel_mm[axis]);
        let offset = self.work_offset_mm()[axis];
        match self.reach[axis] {
            Reach::Between { min_mm, max_mm } => {
                let basis = match (self.homing, min_mm < 0.0) {
                    (true, true) => {
                        "homing is on ($22=1): GRBL's machine space runs from −travel to 0 from the home switches"
                    }
                    (true, false) => {
                        "homing is on ($22=1) toward negative ($23) on a GRBL that sets machine zero at the switch: 0 to +travel"
                    }
                    (false, _) => {
                        "homing is off ($22=0): machine zero is where the head stood at power-up, taken as the origin corner"
                    }
                };
                format!(
                    "{name} runs {:.3} to {:.3} mm in work coordinates (machine {min_mm:.3} to \
                     {max_mm:.3}; {setting}; {basis})",
                    min_mm - offset,
                    max_mm - offset
                )
            }
            Reach::Span { span_mm } => format!(
                "{name} travels {span_mm:.3} mm ({setting}); homing is off ($22=0), so where the \
                 head stands in it is not known and only the span of its moves, the head's \
                 height included, is checked"
            ),
        }
    }
}

impl Beyond {
    /// What to change when the machine's own travel setting is what is wrong.
    pub fn change_setting(&self) -> String {
        match (self.source, self.axis) {
            (TravelSource::Grbl, axis) => format!("set ${} to it", TRAVEL_SETTINGS[axis]),
            (TravelSource::Ruida, 2) => "give it as the ruida: address's z-mm=MIN,MAX".into(),
            (TravelSource::Ruida, _) => {
                "set the controller's bed size (or the ruida: address's bed-mm, for a controller \
                 that reports none)"
                    .into()
            }
        }
    }

    /// Where the point lies in work coordinates, mm.
    pub fn work_mm(&self) -> f64 {
        self.at.machine_mm - self.work_offset_mm
    }

    /// True when it is the head's own position (the rule does not fit the machine).
    pub fn is_head(&self) -> bool {
        self.from.is_none() && self.at.line.is_none()
    }

    /// What GRBL would do with it.
    pub fn consequence(&self) -> &'static str {
        if self.source == TravelSource::Ruida {
            return "a Ruida controller's own limits are not known here";
        }
        match self.soft_limits {
            true => "GRBL would stop with a soft-limit alarm (ALARM:2)",
            false => "soft limits are off ($20=0), so GRBL would drive the head into its end stop",
        }
    }
}

impl fmt::Display for Beyond {
    /// `X 350.000 mm in work coordinates (machine 350.000), beyond the machine's travel: …`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = AXES[self.axis];
        let at = |r: &Reached| r.machine_mm - self.work_offset_mm;
        match &self.from {
            None => write!(
                f,
                "{name} {:.3} mm in work coordinates (machine {:.3}), beyond the machine's \
                 travel: {}; {}",
                self.work_mm(),
                self.at.machine_mm,
                self.limit,
                self.consequence()
            ),
            Some(from) => {
                let seen = match &from.line {
                    Some((number, written)) => format!(" (line {number}, `{written}`)"),
                    None => String::new(),
                };
                write!(
                    f,
                    "{name} {:.3} mm in work coordinates (machine {:.3}), {:.3} mm from the \
                     {name} {:.3} mm it also reaches{seen}, more than the machine's travel: {}; {}",
                    self.work_mm(),
                    self.at.machine_mm,
                    (self.at.machine_mm - from.machine_mm).abs(),
                    at(from),
                    self.limit,
                    self.consequence()
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::offsets::Offsets;
    use super::super::protocol::prepare;
    use super::*;

    fn settings(homing: bool, soft_limits: bool) -> BTreeMap<u16, f64> {
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        [
            (130, 200.0),
            (131, 200.0),
            (132, 50.0),
            (20, flag(soft_limits)),
            (22, flag(homing)),
            (23, 0.0),
        ]
        .into_iter()
        .collect()
    }

    fn start(head_mm: Point, work_offset_mm: Point) -> Start {
        let mut offsets = Offsets::default();
        offsets.coord_systems_mm[0] = work_offset_mm;
        Start {
            head_mm,
            offsets,
            modal: Modal::after_reset(),
        }
    }

    fn check(travel: &Travel, program: &str) -> Result<(), Box<Beyond>> {
        travel.check(&travel.extent(&prepare(program).unwrap()).unwrap())
    }

    #[test]
    fn without_homing_x_and_y_run_from_the_power_up_corner_and_z_is_a_span() {
        let travel =
            Travel::read(&settings(false, false), start([10.0, 10.0, 0.0], [0.0; 3])).unwrap();
        assert_eq!(travel.bed_mm(), [200.0, 200.0]);
        check(&travel, "G0 X200 Y0\nG0 Z-20\nG0 Z25\n").unwrap();
        let e = check(&travel, "G0 X10\nG0 X350 Y20\n").unwrap_err();
        assert_eq!(
            (e.axis, e.at.line.clone()),
            (0, Some((2, "G0 X350 Y20".into())))
        );
        let message = e.to_string();
        assert!(
            message.starts_with("X 350.000 mm in work coordinates (machine 350.000)"),
            "{message}"
        );
        assert!(
            message.contains("$130=200") && message.contains("$22=0"),
            "{message}"
        );
        assert!(message.contains("end stop"), "{message}");
        assert!(check(&travel, "G0 Y-0.5\n").is_err());
        // Z: 60 mm apart is more than 50, wherever the head stands.
        let e = check(&travel, "G0 Z-30\nG0 Z30\n").unwrap_err();
        assert!(e.from.is_some());
        assert!(
            e.to_string().contains("60.000 mm from the Z -30.000 mm"),
            "{e}"
        );
        // The head left of where it was switched on: the rule does not fit.
        let lost =
            Travel::read(&settings(false, false), start([-5.0, 0.0, 0.0], [0.0; 3])).unwrap();
        assert!(lost.check_head().unwrap_err().is_head());
    }

    #[test]
    fn with_homing_the_travel_is_negative_space_and_work_offsets_map_onto_it() {
        let head = [-100.0, -100.0, -1.0];
        let travel =
            Travel::read(&settings(true, true), start(head, [-200.0, -200.0, -50.0])).unwrap();
        check(&travel, "G0 X0 Y0 Z0\nG0 X200 Y200 Z50\n").unwrap();
        let e = check(&travel, "G0 X210\n").unwrap_err();
        assert_eq!((e.work_mm(), e.at.machine_mm), (210.0, 10.0));
        let message = e.to_string();
        assert!(
            message.contains(
                "runs 0.000 to 200.000 mm in work coordinates (machine -200.000 to 0.000"
            ),
            "{message}"
        );
        assert!(message.contains("ALARM:2"), "{message}");
        // Without a work offset, work X10 is machine +10: past the home switch.
        let no_offset = Travel::read(&settings(true, false), start(head, [0.0; 3])).unwrap();
        assert!(check(&no_offset, "G0 X10\n").is_err());
        assert!(no_offset.check_work(0, &[-150.0]).is_ok());
        assert!(no_offset.check_work(2, &[-60.0]).is_err());
        // A GRBL that sets zero at a switch it homes toward negative: X at 0 to +200.
        let mut negative = settings(true, false);
        negative.insert(23, 1.0);
        let travel = Travel::read(&negative, start([5.0, -5.0, -1.0], [0.0; 3])).unwrap();
        assert_eq!(
            travel.reach[0],
            Reach::Between {
                min_mm: 0.0,
                max_mm: 200.0
            }
        );
        assert_eq!(
            travel.reach[1],
            Reach::Between {
                min_mm: -200.0,
                max_mm: 0.0
            }
        );
    }

    #[test]
    fn a_controller_without_its_travel_is_not_checked() {
        let mut partial = settings(false, false);
        partial.remove(&132);
        assert!(Travel::read(&partial, start([0.0; 3], [0.0; 3])).is_none());
        partial.insert(132, 0.0);
        assert!(Travel::reported(&partial).is_none());
    }

    #[test]
    fn after_the_check_passs_reset_g92_is_gone() {
        let mut s = start([50.0, 50.0, 0.0], [0.0; 3]);
        s.offsets.g92_mm = [100.0, 0.0, 0.0];
        let travel = Travel::read(&settings(false, false), s).unwrap();
        assert!(
            check(&travel, "G0 X150\n").is_err(),
            "G92 puts X150 at machine 250"
        );
        check(&travel.after_reset(), "G0 X150\n").unwrap();
    }
}
