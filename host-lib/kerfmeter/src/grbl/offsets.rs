//! Where GRBL puts a program's numbers: its work offsets (`$#`: G54–G59, G28, G30, G92 and the
//! tool length offset) and its parser's modal state (`$G`: the active work system, units,
//! distance mode, plane and motion), read from the controller and followed through a program by
//! [`super::extent`].
//!
//! GRBL 1.1 (`gc_execute_line`): a target in work coordinates is the machine position minus the
//! work offset, which is the active system's G54–G59 offset plus the G92 offset, plus the tool
//! length offset on Z. G54–G59, G28 and G30 are kept in the controller's EEPROM; G92 and the tool
//! length offset are lost at a soft reset, which also puts the parser back to G0 G54 G17 G21 G90
//! ([`Modal::after_reset`]). `$#` reports positions in inches when `$13=1`.

/// Millimetres per inch.
pub const MM_PER_INCH: f64 = 25.4;

/// A position (X, Y, Z), mm.
pub type Point = [f64; 3];

/// The plane arcs are drawn in (G17–G19).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    /// G17.
    Xy,
    /// G18.
    Zx,
    /// G19.
    Yz,
}

impl Plane {
    /// The plane's two axes and the linear one, as GRBL orders them (G18 is Z then X).
    pub fn axes(self) -> [usize; 3] {
        match self {
            Plane::Xy => [0, 1, 2],
            Plane::Zx => [2, 0, 1],
            Plane::Yz => [1, 2, 0],
        }
    }
}

/// The motion mode (modal group 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// G0 or G1: straight to the target.
    Straight,
    /// G2 (`true`) or G3.
    Arc {
        /// G2.
        clockwise: bool,
    },
    /// G38.x: a probe.
    Probe,
    /// G80: motion cancelled.
    Cancelled,
}

/// The parser state that decides where a line's numbers go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Modal {
    /// The active work system, 0 (G54) to 5 (G59).
    pub coord_system: usize,
    /// G20.
    pub inches: bool,
    /// G91.
    pub incremental: bool,
    /// G17–G19.
    pub plane: Plane,
    /// G0–G3, G38.x, G80.
    pub motion: Motion,
}

impl Modal {
    /// GRBL's state after a reset (and at power-up): G0 G54 G17 G21 G90.
    pub fn after_reset() -> Self {
        Self {
            coord_system: 0,
            inches: false,
            incremental: false,
            plane: Plane::Xy,
            motion: Motion::Straight,
        }
    }

    /// The state a `$G` report gives (`[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]`); `None`
    /// when `line` is not one.
    pub fn parse(line: &str) -> Option<Self> {
        let words = line.trim().strip_prefix("[GC:")?.strip_suffix(']')?;
        let mut modal = Self::after_reset();
        for word in words.split_whitespace() {
            modal.apply(word);
        }
        Some(modal)
    }

    fn apply(&mut self, word: &str) {
        match word {
            "G0" | "G1" => self.motion = Motion::Straight,
            "G2" => self.motion = Motion::Arc { clockwise: true },
            "G3" => self.motion = Motion::Arc { clockwise: false },
            "G80" => self.motion = Motion::Cancelled,
            w if w.starts_with("G38") => self.motion = Motion::Probe,
            "G17" => self.plane = Plane::Xy,
            "G18" => self.plane = Plane::Zx,
            "G19" => self.plane = Plane::Yz,
            "G20" => self.inches = true,
            "G21" => self.inches = false,
            "G90" => self.incremental = false,
            "G91" => self.incremental = true,
            w => {
                let system = w.strip_prefix('G').and_then(|n| n.parse::<usize>().ok());
                if let Some(n @ 54..=59) = system {
                    self.coord_system = n - 54;
                }
            }
        }
    }
}

/// GRBL's stored offsets, mm (machine coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Offsets {
    /// G54 to G59.
    pub coord_systems_mm: [Point; 6],
    /// G28's stored position.
    pub g28_mm: Point,
    /// G30's stored position.
    pub g30_mm: Point,
    /// The G92 offset.
    pub g92_mm: Point,
    /// The tool length offset (Z).
    pub tool_length_mm: f64,
}

impl Offsets {
    /// The offsets a `$#` report gives (its lines, without the `ok`), in mm: `mm_per_unit` is
    /// 25.4 for a controller that reports inches (`$13=1`). `None` unless every one of G54–G59,
    /// G28, G30, G92 and TLO came.
    pub fn parse<S: AsRef<str>>(lines: &[S], mm_per_unit: f64) -> Option<Self> {
        let mut offsets = Self::default();
        let mut seen = [false; 10];
        for (name, values) in lines.iter().filter_map(|l| bracketed(l.as_ref())) {
            let numbers: Vec<f64> = values
                .split(',')
                .map_while(|v| v.parse::<f64>().ok())
                .map(|v| v * mm_per_unit)
                .collect();
            let slot = match (name, numbers.as_slice()) {
                ("TLO", [z]) => {
                    offsets.tool_length_mm = *z;
                    9
                }
                (name, [x, y, z, ..]) => {
                    let Some((slot, point)) = offsets.slot(name) else {
                        continue;
                    };
                    *point = [*x, *y, *z];
                    slot
                }
                _ => continue,
            };
            seen[slot] = true;
        }
        seen.iter().all(|s| *s).then_some(offsets)
    }

    /// The stored position `$#` names `name` (`G54`…`G59`, `G28`, `G30`, `G92`), and its
    /// number among those the report must give.
    fn slot(&mut self, name: &str) -> Option<(usize, &mut Point)> {
        match name {
            "G28" => Some((6, &mut self.g28_mm)),
            "G30" => Some((7, &mut self.g30_mm)),
            "G92" => Some((8, &mut self.g92_mm)),
            _ => {
                let number: usize = name.strip_prefix('G')?.parse().ok()?;
                let system = number.checked_sub(54).filter(|s| *s < 6)?;
                Some((system, &mut self.coord_systems_mm[system]))
            }
        }
    }

    /// The offsets after a soft reset: G92 and the tool length offset are gone.
    pub fn after_reset(self) -> Self {
        Self {
            g92_mm: [0.0; 3],
            tool_length_mm: 0.0,
            ..self
        }
    }

    /// The work offset in `coord_system`: machine = work + this.
    pub fn work_offset_mm(&self, coord_system: usize) -> Point {
        let system = self.coord_systems_mm[coord_system];
        let mut offset: Point = std::array::from_fn(|i| system[i] + self.g92_mm[i]);
        offset[2] += self.tool_length_mm;
        offset
    }
}

/// `[NAME:values]` as `(NAME, values)`.
fn bracketed(line: &str) -> Option<(&str, &str)> {
    line.trim()
        .strip_prefix('[')?
        .strip_suffix(']')?
        .split_once(':')
}

#[cfg(test)]
mod tests {
    use super::*;

    const REPORT: [&str; 11] = [
        "[G54:-200.000,-200.000,-50.000]",
        "[G55:4.000,6.000,7.000]",
        "[G56:0.000,0.000,0.000]",
        "[G57:0.000,0.000,0.000]",
        "[G58:0.000,0.000,0.000]",
        "[G59:0.000,0.000,0.000]",
        "[G28:1.000,2.000,0.000]",
        "[G30:4.000,6.000,0.000]",
        "[G92:10.000,0.000,0.000]",
        "[TLO:2.500]",
        "[PRB:0.000,0.000,0.000:0]",
    ];

    #[test]
    fn grbls_offsets_report_gives_the_work_offset_of_each_system() {
        let offsets = Offsets::parse(&REPORT, 1.0).unwrap();
        assert_eq!(offsets.g28_mm, [1.0, 2.0, 0.0]);
        assert_eq!(offsets.work_offset_mm(0), [-190.0, -200.0, -47.5]);
        assert_eq!(offsets.work_offset_mm(1), [14.0, 6.0, 9.5]);
        let reset = offsets.after_reset();
        assert_eq!(reset.work_offset_mm(0), [-200.0, -200.0, -50.0]);
        let inches = Offsets::parse(&REPORT, MM_PER_INCH).unwrap();
        assert_eq!(inches.coord_systems_mm[1][0], 4.0 * MM_PER_INCH);
        // A report without G92 is not a whole one.
        let partial: Vec<&str> = REPORT
            .iter()
            .copied()
            .filter(|l| !l.contains("G92"))
            .collect();
        assert_eq!(Offsets::parse(&partial, 1.0), None);
    }

    #[test]
    fn the_parser_state_is_read_from_its_report() {
        let modal = Modal::parse("[GC:G2 G55 G18 G20 G91 G94 M5 M9 T0 F0 S0]").unwrap();
        assert_eq!(modal.motion, Motion::Arc { clockwise: true });
        assert_eq!(
            (
                modal.coord_system,
                modal.plane,
                modal.inches,
                modal.incremental
            ),
            (1, Plane::Zx, true, true)
        );
        let after_end = Modal::parse("[GC:G1 G54 G17 G21 G90 G94 M5 M9 T0 F100 S0]").unwrap();
        assert_eq!(after_end, Modal::after_reset());
        assert_eq!(Modal::parse("ok"), None);
    }
}
