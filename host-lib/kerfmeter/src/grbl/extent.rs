//! How far a program's moves reach, in machine coordinates: GRBL 1.1's reading of a program
//! (`gc_execute_line`) for the head's positions alone, from where the head stands and the
//! controller's offsets and parser state ([`Start`]).
//!
//! Followed as GRBL does: units (G20/G21), distance mode (G90/G91), the work systems
//! (G54–G59, with their offsets), G92 and G92.1, G10 L2/L20, the tool length offset (G43.1,
//! G49), G53, G28/G30 and their stored positions (and G28.1/G30.1), the end of a program
//! (M2/M30: G1 G17 G90 G54), G0/G1, and G2/G3 in any plane (G17–G19), with I/J/K or R, where the
//! arc's bulge counts as well as its ends. Every point a move ends at (and an arc's furthest
//! points) is kept with the line that reaches it ([`Extent`]).
//!
//! What cannot be bounded is refused rather than guessed ([`Unbounded`]): a probe (G38.x stops
//! where it touches, so every later position is unknown), a G command GRBL 1.1 does not have
//! (another firmware may move for it: canned cycles, splines), an arc by radius GRBL cannot
//! draw (it refuses it, and the next move starts elsewhere than written), and a word without a
//! number.

use std::f64::consts::{FRAC_PI_2, TAU};

use super::offsets::{MM_PER_INCH, Modal, Motion, Offsets, Plane, Point};
use super::protocol::ProgramLine;

/// How near an arc's end a quarter point is taken for the end itself, rad.
const ARC_END_RAD: f64 = 1e-9;

/// GRBL's `ARC_ANGULAR_TRAVEL_EPSILON`: an arc's ends closer in angle are a full circle.
const ARC_ANGULAR_TRAVEL_EPSILON: f64 = 5e-7;

/// Where a program starts: the head's machine position, the controller's offsets and its parser
/// state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    /// The head, mm (machine coordinates).
    pub head_mm: Point,
    /// `$#`.
    pub offsets: Offsets,
    /// `$G`.
    pub modal: Modal,
}

/// One end of the extent on one axis: the machine coordinate, and the program line that reaches
/// it (`None`: where the head stood before the program).
#[derive(Debug, Clone, PartialEq)]
pub struct Reached {
    /// Machine coordinate, mm.
    pub machine_mm: f64,
    /// Its line's number in the file and its text as written.
    pub line: Option<(usize, String)>,
}

/// The lowest and highest machine coordinate a program's moves reach on each axis (X, Y, Z),
/// the head's starting position included.
#[derive(Debug, Clone, PartialEq)]
pub struct Extent {
    /// Per axis, the lowest.
    pub min: [Reached; 3],
    /// Per axis, the highest.
    pub max: [Reached; 3],
}

impl Extent {
    /// The extent of the head standing at `head_mm`.
    pub fn at(head_mm: Point) -> Self {
        let here = |axis: usize| Reached {
            machine_mm: head_mm[axis],
            line: None,
        };
        Self {
            min: std::array::from_fn(here),
            max: std::array::from_fn(here),
        }
    }

    /// Grow it to take in `p`, reached by `line`.
    pub fn take_in(&mut self, p: Point, line: Option<&ProgramLine>) {
        let reached = |machine_mm: f64| Reached {
            machine_mm,
            line: line.map(|l| (l.number, l.written.clone())),
        };
        for (axis, &v) in p.iter().enumerate() {
            if v < self.min[axis].machine_mm {
                self.min[axis] = reached(v);
            }
            if v > self.max[axis].machine_mm {
                self.max[axis] = reached(v);
            }
        }
    }
}

/// A line whose moves cannot be bounded, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Unbounded {
    /// Its number in the file.
    pub line: usize,
    /// As written.
    pub written: String,
    /// Why.
    pub reason: String,
}

/// How far `lines` reach when run from `start` (see the [module docs](self)).
pub fn extent(lines: &[ProgramLine], start: &Start) -> Result<Extent, Unbounded> {
    let mut reader = Reader {
        position: start.head_mm,
        offsets: start.offsets,
        modal: start.modal,
        extent: Extent::at(start.head_mm),
    };
    for line in lines {
        reader.line(line).map_err(|reason| Unbounded {
            line: line.number,
            written: line.written.clone(),
            reason,
        })?;
    }
    Ok(reader.extent)
}

/// A line's words: its G commands (whole number, hundredths) and the last value of each letter.
#[derive(Default)]
struct Words {
    g: Vec<(u32, u32)>,
    m: Vec<u32>,
    values: [Option<f64>; 26],
}

impl Words {
    fn get(&self, letter: char) -> Option<f64> {
        self.values[usize::from(letter as u8 - b'A')]
    }

    /// X, Y and Z, each scaled by `scale` (25.4 for inches).
    fn axes(&self, scale: f64) -> [Option<f64>; 3] {
        ['X', 'Y', 'Z'].map(|a| self.get(a).map(|v| v * scale))
    }

    fn has_axes(&self) -> bool {
        self.axes(1.0).iter().any(Option::is_some)
    }
}

/// Split a cleaned line (upper case, no spaces) into its words.
fn words(text: &str) -> Result<Words, String> {
    let mut words = Words::default();
    let mut rest = text;
    while let Some(letter) = rest.chars().next() {
        if !letter.is_ascii_uppercase() {
            return Err(format!("has `{letter}` where GRBL expects a letter"));
        }
        let digits = &rest[1..];
        let end = digits
            .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+')))
            .unwrap_or(digits.len());
        let value: f64 = digits[..end]
            .parse()
            .map_err(|_| format!("its `{letter}` has no number GRBL can read"))?;
        match letter {
            'G' => words.g.push(command(value)),
            'M' => words.m.push(command(value).0),
            _ => words.values[usize::from(letter as u8 - b'A')] = Some(value),
        }
        rest = &digits[end..];
    }
    Ok(words)
}

/// A command number as GRBL splits it: whole part and hundredths (`G38.2` is (38, 20)).
fn command(value: f64) -> (u32, u32) {
    let whole = value.trunc();
    (whole as u32, (100.0 * (value - whole)).round() as u32)
}

/// A non-modal command of GRBL's group 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum NonModal {
    Dwell,
    SetSystem,
    GoStored { g30: bool },
    Store { g30: bool },
    MachineCoords,
    SetG92,
    ClearG92,
}

/// What a line's G commands ask for besides the modal changes applied to the reader.
#[derive(Default)]
struct Commands {
    non_modal: Option<NonModal>,
    /// G43.1 (`true`) or G49.
    tool_length: Option<bool>,
}

/// GRBL's state while the program is read.
struct Reader {
    position: Point,
    offsets: Offsets,
    modal: Modal,
    extent: Extent,
}

impl Reader {
    fn line(&mut self, line: &ProgramLine) -> Result<(), String> {
        let w = words(&line.text)?;
        let commands = self.commands(&w)?;
        let scale = if self.modal.inches { MM_PER_INCH } else { 1.0 };
        let axes = w.axes(scale);
        match (commands.tool_length, commands.non_modal) {
            (Some(dynamic), _) => {
                self.offsets.tool_length_mm = if dynamic { axes[2].unwrap_or(0.0) } else { 0.0 };
            }
            (None, Some(NonModal::Dwell)) => {}
            (None, Some(NonModal::SetSystem)) => self.set_system(&w, axes)?,
            (None, Some(NonModal::SetG92)) => self.set_g92(axes),
            (None, Some(NonModal::ClearG92)) => self.offsets.g92_mm = [0.0; 3],
            (None, Some(NonModal::Store { g30 })) => *self.stored(g30) = self.position,
            (None, Some(NonModal::GoStored { g30 })) => self.go_stored(g30, axes, line),
            (None, non_modal) if w.has_axes() => {
                let machine = non_modal == Some(NonModal::MachineCoords);
                self.motion(&w, axes, machine, scale, line)?;
            }
            _ => {}
        }
        if w.m.iter().any(|&m| m == 2 || m == 30) {
            self.end_program();
        }
        Ok(())
    }

    /// Apply the line's modal G commands to the reader; the rest, for the line to act on.
    fn commands(&mut self, w: &Words) -> Result<Commands, String> {
        let mut c = Commands::default();
        for &(number, hundredths) in &w.g {
            let m = &mut self.modal;
            match (number, hundredths) {
                (0 | 1, 0) => m.motion = Motion::Straight,
                (2 | 3, 0) => {
                    m.motion = Motion::Arc {
                        clockwise: number == 2,
                    }
                }
                (38, _) => {
                    return Err("probes (G38.x): a probe stops where it touches, so where \
                                every later move starts is unknown"
                        .into());
                }
                (80, 0) => m.motion = Motion::Cancelled,
                (17, 0) => m.plane = Plane::Xy,
                (18, 0) => m.plane = Plane::Zx,
                (19, 0) => m.plane = Plane::Yz,
                (20 | 21, 0) => m.inches = number == 20,
                (90 | 91, 0) => m.incremental = number == 91,
                (54..=59, 0) => m.coord_system = number as usize - 54,
                (4, 0) => c.non_modal = Some(NonModal::Dwell),
                (10, 0) => c.non_modal = Some(NonModal::SetSystem),
                (28 | 30, 0) => c.non_modal = Some(NonModal::GoStored { g30: number == 30 }),
                (28 | 30, 10) => c.non_modal = Some(NonModal::Store { g30: number == 30 }),
                (53, 0) => c.non_modal = Some(NonModal::MachineCoords),
                (92, 0) => c.non_modal = Some(NonModal::SetG92),
                (92, 10) => c.non_modal = Some(NonModal::ClearG92),
                (43, 10) | (49, 0) => c.tool_length = Some(number == 43),
                // Cutter compensation off, exact path, feed modes, incremental arc centres.
                (40 | 61 | 93 | 94, 0) | (91, 10) => {}
                _ => {
                    return Err(format!(
                        "uses {}, which GRBL 1.1 does not have: another firmware may move for it",
                        show_g(number, hundredths)
                    ));
                }
            }
        }
        Ok(c)
    }

    /// Where `axes` send the head: machine coordinates with G53, else work ones in the distance
    /// mode; an axis without a word stays.
    fn target(&self, axes: [Option<f64>; 3], machine: bool) -> Point {
        let offset = self.offsets.work_offset_mm(self.modal.coord_system);
        std::array::from_fn(|i| match axes[i] {
            None => self.position[i],
            Some(v) if machine => v,
            Some(v) if self.modal.incremental => self.position[i] + v,
            Some(v) => v + offset[i],
        })
    }

    fn go_to(&mut self, p: Point, line: &ProgramLine) {
        self.extent.take_in(p, Some(line));
        self.position = p;
    }

    fn motion(
        &mut self,
        w: &Words,
        axes: [Option<f64>; 3],
        machine: bool,
        scale: f64,
        line: &ProgramLine,
    ) -> Result<(), String> {
        let target = self.target(axes, machine);
        match self.modal.motion {
            Motion::Straight => self.go_to(target, line),
            Motion::Arc { clockwise } => {
                for p in self.arc(w, target, clockwise, scale)? {
                    self.extent.take_in(p, Some(line));
                }
                self.position = target;
            }
            Motion::Probe => return Err("probes (G38.x) with its axis words".into()),
            // GRBL refuses axis words with G80; nothing moves.
            Motion::Cancelled => {}
        }
        Ok(())
    }

    /// The points of an arc to `target` that reach furthest: its end and the points of its
    /// circle at each quarter turn it passes.
    fn arc(
        &self,
        w: &Words,
        target: Point,
        clockwise: bool,
        scale: f64,
    ) -> Result<Vec<Point>, String> {
        let [a0, a1, _] = self.modal.plane.axes();
        let from = self.position;
        let centre_offset = match w.get('R') {
            Some(r) => radius_centre(from, target, [a0, a1], r * scale, clockwise)?,
            None => {
                let ijk = ['I', 'J', 'K'].map(|l| w.get(l).map(|v| v * scale));
                if ijk[a0].is_none() && ijk[a1].is_none() {
                    return Err(
                        "draws an arc without its centre in the plane (GRBL refuses it)".into(),
                    );
                }
                [ijk[a0].unwrap_or(0.0), ijk[a1].unwrap_or(0.0)]
            }
        };
        let centre = [from[a0] + centre_offset[0], from[a1] + centre_offset[1]];
        let r_start = [-centre_offset[0], -centre_offset[1]];
        let r_end = [target[a0] - centre[0], target[a1] - centre[1]];
        let radius = r_start[0].hypot(r_start[1]);
        let start_angle = r_start[1].atan2(r_start[0]);
        let travel = angular_travel(r_start, r_end, clockwise);
        let (low, high) = match travel < 0.0 {
            true => (start_angle + travel, start_angle),
            false => (start_angle, start_angle + travel),
        };
        let mut points = vec![target];
        // Quarter points strictly inside the arc: at an end, the end itself counts (the start is
        // where the head stands, the target as written), not the circle through the start,
        // whose radius a program's rounded numbers make differ from the end's by a few 0.1 µm.
        let mut quarter = ((low + ARC_END_RAD) / FRAC_PI_2).ceil();
        while quarter * FRAC_PI_2 < high - ARC_END_RAD {
            let angle = quarter * FRAC_PI_2;
            let mut p = from;
            p[a0] = centre[0] + radius * angle.cos();
            p[a1] = centre[1] + radius * angle.sin();
            points.push(p);
            quarter += 1.0;
        }
        Ok(points)
    }

    /// G10 L2 (the offset given) or L20 (the offset that makes the head stand at the numbers
    /// given) for system P (0: the active one).
    fn set_system(&mut self, w: &Words, axes: [Option<f64>; 3]) -> Result<(), String> {
        let system = match w.get('P').map(|p| p.round() as i64) {
            Some(0) => self.modal.coord_system,
            Some(p @ 1..=6) => p as usize - 1,
            _ => {
                return Err("sets a work offset (G10) without a system GRBL has (P0 to P6)".into());
            }
        };
        let l20 = match w.get('L').map(|l| l.round() as i64) {
            Some(2) => false,
            Some(20) => true,
            _ => return Err("uses G10 without L2 or L20, which GRBL 1.1 does not have".into()),
        };
        for (i, value) in axes.iter().enumerate() {
            let Some(v) = value else { continue };
            let slot = &mut self.offsets.coord_systems_mm[system][i];
            *slot = match l20 {
                false => *v,
                true => {
                    let tool = if i == 2 {
                        self.offsets.tool_length_mm
                    } else {
                        0.0
                    };
                    self.position[i] - self.offsets.g92_mm[i] - v - tool
                }
            };
        }
        Ok(())
    }

    /// G92: the offset that makes the head stand at the numbers given.
    fn set_g92(&mut self, axes: [Option<f64>; 3]) {
        let system = self.offsets.coord_systems_mm[self.modal.coord_system];
        for (i, value) in axes.iter().enumerate() {
            if let Some(v) = value {
                let tool = if i == 2 {
                    self.offsets.tool_length_mm
                } else {
                    0.0
                };
                self.offsets.g92_mm[i] = self.position[i] - system[i] - v - tool;
            }
        }
    }

    fn stored(&mut self, g30: bool) -> &mut Point {
        match g30 {
            true => &mut self.offsets.g30_mm,
            false => &mut self.offsets.g28_mm,
        }
    }

    /// G28/G30: through the point the axis words give (if any), then to the stored position on
    /// those axes (on every axis without words), as GRBL 1.1h does.
    fn go_stored(&mut self, g30: bool, axes: [Option<f64>; 3], line: &ProgramLine) {
        let stored = *self.stored(g30);
        let any = axes.iter().any(Option::is_some);
        if any {
            let through = self.target(axes, false);
            self.go_to(through, line);
        }
        let to = std::array::from_fn(|i| match axes[i].is_some() || !any {
            true => stored[i],
            false => self.position[i],
        });
        self.go_to(to, line);
    }

    /// M2/M30: G1 G17 G90 G54, as GRBL resets them at a program's end (the units stay).
    fn end_program(&mut self) {
        self.modal = Modal {
            inches: self.modal.inches,
            ..Modal::after_reset()
        };
    }
}

/// The centre of an arc by radius `r` from `from` to `target` in the plane `[a0, a1]`, relative
/// to `from`, as GRBL computes it (a negative radius: the arc over 180°).
fn radius_centre(
    from: Point,
    target: Point,
    [a0, a1]: [usize; 2],
    r: f64,
    clockwise: bool,
) -> Result<[f64; 2], String> {
    let (x, y) = (target[a0] - from[a0], target[a1] - from[a1]);
    let discriminant = 4.0 * r * r - x * x - y * y;
    if from == target || discriminant < 0.0 {
        return Err(format!(
            "draws an arc of radius {} mm GRBL cannot draw between its ends (it refuses it, and \
             the next move would start elsewhere than written)",
            r.abs()
        ));
    }
    let mut h = -discriminant.sqrt() / x.hypot(y);
    if !clockwise {
        h = -h;
    }
    if r < 0.0 {
        h = -h;
    }
    Ok([0.5 * (x - y * h), 0.5 * (y + x * h)])
}

/// The signed angle an arc turns from `r_start` to `r_end` about its centre, as GRBL's
/// `mc_arc` computes it: clockwise negative, and ends that meet a whole turn.
fn angular_travel(r_start: [f64; 2], r_end: [f64; 2], clockwise: bool) -> f64 {
    let [r0, r1] = r_start;
    let [t0, t1] = r_end;
    let travel = (r0 * t1 - r1 * t0).atan2(r0 * t0 + r1 * t1);
    match clockwise {
        true if travel >= -ARC_ANGULAR_TRAVEL_EPSILON => travel - TAU,
        false if travel <= ARC_ANGULAR_TRAVEL_EPSILON => travel + TAU,
        _ => travel,
    }
}

/// `G38.2`, `G5`: a G command as written.
fn show_g(number: u32, hundredths: u32) -> String {
    match hundredths {
        0 => format!("G{number}"),
        h if h % 10 == 0 => format!("G{number}.{}", h / 10),
        h => format!("G{number}.{h:02}"),
    }
}

#[cfg(test)]
mod tests {
    use super::super::protocol::prepare;
    use super::*;

    fn start(head_mm: Point) -> Start {
        Start {
            head_mm,
            offsets: Offsets::default(),
            modal: Modal::after_reset(),
        }
    }

    fn reach(program: &str, from: &Start) -> ([f64; 3], [f64; 3]) {
        let e = extent(&prepare(program).unwrap(), from).unwrap();
        (
            e.min.clone().map(|r| r.machine_mm),
            e.max.clone().map(|r| r.machine_mm),
        )
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9)
    }

    #[test]
    fn absolute_relative_inch_and_machine_moves_are_followed() {
        let from = start([10.0, 10.0, 0.0]);
        let (min, max) = reach("G90 G0 X50 Y20\nG91 G1 X-70 F100\nG90 G53 G0 Z-5\n", &from);
        assert_eq!((min, max), ([-20.0, 10.0, -5.0], [50.0, 20.0, 0.0]));
        let (_, max) = reach("G20\nG0 X2\n", &from);
        assert_eq!(max[0], 50.8);
        // The line that reaches the far end is named, as written.
        let lines = prepare("G0 X1\n\nG0  X99 (far)\nG0 X5\n").unwrap();
        let e = extent(&lines, &from).unwrap();
        assert_eq!(e.max[0].line, Some((3, "G0  X99 (far)".into())));
        assert_eq!(e.min[0].line, Some((1, "G0 X1".into())));
        assert_eq!(e.max[1].line, None, "the head's own position");
    }

    #[test]
    fn work_offsets_g92_g10_and_the_tool_length_move_the_numbers() {
        let mut from = start([-100.0, -100.0, -10.0]);
        from.offsets.coord_systems_mm[0] = [-200.0, -200.0, -50.0];
        from.offsets.coord_systems_mm[1] = [-150.0, 0.0, 0.0];
        let (min, max) = reach("G0 X10 Y20\n", &from);
        assert_eq!((min[0], max[1]), (-190.0, -100.0));
        let (min, _) = reach("G55 G0 X10\n", &from);
        assert_eq!(min[0], -140.0);
        // G92: the head (machine -100) is work X0 from here on.
        let (_, max) = reach("G92 X0\nG0 X30\n", &from);
        assert_eq!(max[0], -70.0);
        let (min, _) = reach("G92 X0\nG92.1\nG0 X30\n", &from);
        assert_eq!(min[0], -170.0);
        // G10 L20 P1: as G92, stored in G54; L2 sets it outright.
        let (_, max) = reach("G10 L20 P1 X5\nG0 X10\n", &from);
        assert_eq!(max[0], -95.0);
        let (min, _) = reach("G10 L2 P0 X-300\nG0 X10\n", &from);
        assert_eq!(min[0], -290.0);
        let (min, _) = reach("G43.1 Z-4\nG0 Z1\n", &from);
        assert_eq!(min[2], -53.0);
    }

    #[test]
    fn g28_goes_through_its_point_to_the_stored_position() {
        let mut from = start([0.0, 0.0, 0.0]);
        from.offsets.g28_mm = [-5.0, -6.0, -7.0];
        let (min, max) = reach("G28 G91 Z20\n", &from);
        assert_eq!((min, max), ([0.0, 0.0, -7.0], [0.0, 0.0, 20.0]));
        let (min, _) = reach("G28\n", &from);
        assert_eq!(min, [-5.0, -6.0, -7.0]);
        let (min, _) = reach("G0 X-30\nG28.1\nG0 X0\nG28\n", &from);
        assert_eq!(min[0], -30.0);
    }

    #[test]
    fn an_arc_that_ends_at_its_circles_lowest_point_reaches_its_end_as_written() {
        // A rounded corner as a program writes it, to 4 decimals: the centre's offset from the
        // start is 0.0003 mm longer than the end's, so the circle through the start dips below
        // the end that the arc goes to; the end as written is what the head reaches.
        let from = start([0.0, 0.0, 0.0]);
        let (min, _) = reach("G1 X10.0003 Y5 F100\nG2 X5 Y0 I-5.0003 J0\n", &from);
        assert_eq!(min[1], 0.0, "{min:?}");
    }

    #[test]
    fn an_arcs_bulge_counts_not_only_its_ends() {
        let from = start([0.0, 0.0, 0.0]);
        // A half circle over the top: from (0,0) to (20,0) about (10,0), clockwise.
        let (min, max) = reach("G2 X20 Y0 I10 J0 F100\n", &from);
        assert!(
            close(max, [20.0, 10.0, 0.0]) && close(min, [0.0, 0.0, 0.0]),
            "{min:?} {max:?}"
        );
        // Counter-clockwise: under it.
        let (min, _) = reach("G3 X20 Y0 I10 J0 F100\n", &from);
        assert!((min[1] + 10.0).abs() < 1e-9, "{min:?}");
        // A whole circle, end on start.
        let (min, max) = reach("G2 X0 Y0 I5 J0 F100\n", &from);
        assert!(close(min, [0.0, -5.0, 0.0]) && close(max, [10.0, 5.0, 0.0]));
        // By radius: the short way and (negative R) the long way round.
        let (_, max) = reach("G2 X20 Y0 R10 F100\n", &from);
        assert!((max[1] - 10.0).abs() < 1e-9, "{max:?}");
        // About (0, 10): three quarters round, through (-10, 10) and (0, 20).
        let (min, max) = reach("G2 X10 Y10 R-10 F100\n", &from);
        assert!(
            close(min, [-10.0, 0.0, 0.0]) && close(max, [10.0, 20.0, 0.0]),
            "{min:?} {max:?}"
        );
        // In the ZX plane (GRBL's axes Z then X), G2 from X0 to X20 bulges down in Z.
        let (min, max) = reach("G18 G2 X20 Z0 I10 K0 F100\n", &from);
        assert!(
            (min[2] + 10.0).abs() < 1e-9 && max[2].abs() < 1e-9,
            "{min:?}"
        );
        assert_eq!((min[1], max[1]), (0.0, 0.0));
    }

    #[test]
    fn what_cannot_be_bounded_is_refused_with_the_line() {
        let from = start([0.0; 3]);
        for (program, says) in [
            ("G0 X1\nG38.2 Z-10 F100\n", "probe"),
            ("G81 X1 Y1 Z-1 R1\n", "G81"),
            ("G2 X50 Y0 R10 F100\n", "cannot draw"),
            ("G5.1 X1\n", "G5.1"),
        ] {
            let lines = prepare(program).unwrap();
            let e = extent(&lines, &from).unwrap_err();
            assert!(e.reason.contains(says), "{program}: {}", e.reason);
            assert_eq!(e.written, lines.last().unwrap().written);
        }
    }

    #[test]
    fn a_programs_end_puts_back_g90_and_g54() {
        let mut from = start([0.0; 3]);
        from.offsets.coord_systems_mm[1] = [100.0, 0.0, 0.0];
        let (_, max) = reach("G55 G91\nM2\nG0 X5\n", &from);
        assert_eq!(max[0], 5.0);
    }
}
