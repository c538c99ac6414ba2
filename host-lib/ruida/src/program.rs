//! A cut program: polylines in mm, grouped in layers each with its speed and minimum/maximum
//! power, written as Ruida commands. Every travel is an absolute move (`88`, laser off) and every
//! cut an absolute cut (`A8`); nothing else moves the head, so the laser is off on every travel
//! by construction.
//!
//! The stream: `E6 01` (absolute coordinates); per layer `CA 02 n`, speed `C9 02`, powers
//! `C6 01`/`C6 02` and its paths (a move to each path's start, cuts along it); then the file
//! sum `E5 05` and `D7`. No layer end (`CA 01 00`): MeerK40t reads it as one, ruida-pa as
//! "overscan off". The file sum is the sum of every byte before it, unswizzled, plus
//! the `D7` byte, as MeerK40t writes it; `ruida-pa` flags a file without it. Whether a real
//! controller checks it is unverified (`docs/ruida.md`).

use crate::packet::{Packet, packets};
use crate::value::{mm_to_um, power_steps, speed_um_per_s};
use crate::{Command, RuidaError};

/// The most layers a program may have (a layer number is 7 bits).
pub const MAX_LAYERS: usize = 128;

/// One layer of a program: its paths and the settings they are cut with.
#[derive(Debug, Clone, PartialEq)]
pub struct CutLayer {
    /// The cutting speed, mm/s.
    pub speed_mm_per_s: f64,
    /// The power at corners (the controller slows there), percent.
    pub min_power_percent: f64,
    /// The power at full speed, percent.
    pub max_power_percent: f64,
    /// The polylines to cut, each at least two points `[x, y]`, mm, in machine coordinates.
    pub paths_mm: Vec<Vec<[f64; 2]>>,
}

/// A program's commands, checked and encoded.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    commands: Vec<Command>,
}

impl Program {
    /// The program cutting `layers` in order, or why it is refused.
    pub fn new(layers: &[CutLayer]) -> Result<Self, RuidaError> {
        if layers.is_empty() || layers.len() > MAX_LAYERS {
            return Err(RuidaError::BadProgram(format!(
                "{} layers (1 to {MAX_LAYERS} are allowed)",
                layers.len()
            )));
        }
        let mut commands = vec![Command::SetAbsolute];
        for (index, layer) in layers.iter().enumerate() {
            write_layer(&mut commands, index as u8, layer)?;
        }
        let mut body = Vec::new();
        for command in &commands {
            command.encode(&mut body);
        }
        let sum = body.iter().map(|&b| u32::from(b)).sum::<u32>() + 0xD7;
        commands.push(Command::FileSum { sum });
        commands.push(Command::EndOfFile);
        Ok(Self { commands })
    }

    /// The commands, in order.
    pub fn commands(&self) -> &[Command] {
        &self.commands
    }

    /// The whole stream, unswizzled (an `.rd` file's content before swizzling).
    pub fn payload(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for command in &self.commands {
            command.encode(&mut out);
        }
        out
    }

    /// The stream in packets for `magic`, each split between commands.
    pub fn packets(&self, magic: u8) -> Result<Vec<Packet>, RuidaError> {
        packets(&self.commands, magic)
    }

    /// The smallest and largest X and Y the head is sent to, µm (for a travel check).
    pub fn extent_um(&self) -> ([i32; 2], [i32; 2]) {
        let mut min = [i32::MAX; 2];
        let mut max = [i32::MIN; 2];
        for command in &self.commands {
            if let Command::MoveAbs { x_um, y_um } | Command::CutAbs { x_um, y_um } = *command {
                for (axis, v) in [x_um, y_um].into_iter().enumerate() {
                    min[axis] = min[axis].min(v);
                    max[axis] = max[axis].max(v);
                }
            }
        }
        (min, max)
    }
}

/// Append layer `index`'s settings and paths.
fn write_layer(out: &mut Vec<Command>, index: u8, layer: &CutLayer) -> Result<(), RuidaError> {
    let refuse = |why: String| Err(RuidaError::BadProgram(format!("layer {index}: {why}")));
    if layer.paths_mm.is_empty() {
        return refuse("no path to cut".into());
    }
    if layer.min_power_percent > layer.max_power_percent {
        return refuse(format!(
            "minimum power {} % above maximum {} %",
            layer.min_power_percent, layer.max_power_percent
        ));
    }
    out.push(Command::LayerNumber { layer: index });
    out.push(Command::Speed {
        speed_um_per_s: speed_um_per_s(layer.speed_mm_per_s)?,
    });
    out.push(Command::MinPower {
        power_steps: power_steps(layer.min_power_percent)?,
    });
    out.push(Command::MaxPower {
        power_steps: power_steps(layer.max_power_percent)?,
    });
    for (n, path) in layer.paths_mm.iter().enumerate() {
        if path.len() < 2 {
            return refuse(format!(
                "path {n} has {} point(s), 2 or more needed",
                path.len()
            ));
        }
        for (i, &[x, y]) in path.iter().enumerate() {
            let (x_um, y_um) = (mm_to_um("x_mm", x)?, mm_to_um("y_mm", y)?);
            out.push(match i {
                0 => Command::MoveAbs { x_um, y_um },
                _ => Command::CutAbs { x_um, y_um },
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MAGIC;

    fn square(at: f64, side: f64) -> Vec<[f64; 2]> {
        vec![
            [at, at],
            [at + side, at],
            [at + side, at + side],
            [at, at + side],
            [at, at],
        ]
    }

    fn layer(paths_mm: Vec<Vec<[f64; 2]>>) -> CutLayer {
        CutLayer {
            speed_mm_per_s: 20.0,
            min_power_percent: 10.0,
            max_power_percent: 60.0,
            paths_mm,
        }
    }

    /// Travels are moves and only moves: each path starts with `88`, the rest are `A8`.
    #[test]
    fn every_travel_is_a_move_and_every_cut_follows_its_path() {
        let program = Program::new(&[layer(vec![square(10.0, 5.0), square(30.0, 2.5)])]).unwrap();
        let moves: Vec<_> = program
            .commands()
            .iter()
            .filter(|c| matches!(c, Command::MoveAbs { .. }))
            .collect();
        assert_eq!(
            moves,
            [
                &Command::MoveAbs {
                    x_um: 10_000,
                    y_um: 10_000
                },
                &Command::MoveAbs {
                    x_um: 30_000,
                    y_um: 30_000
                }
            ]
        );
        let cuts = program
            .commands()
            .iter()
            .filter(|c| c.fires_laser())
            .count();
        assert_eq!(cuts, 8);
        assert_eq!(program.extent_um(), ([10_000, 10_000], [32_500, 32_500]));
    }

    #[test]
    fn the_file_ends_with_its_sum_then_d7() {
        let program = Program::new(&[layer(vec![square(0.0, 1.0)])]).unwrap();
        let payload = program.payload();
        assert_eq!(payload.last(), Some(&0xD7));
        let [.., Command::FileSum { sum }, Command::EndOfFile] = program.commands() else {
            panic!("no file sum before D7");
        };
        let before: u32 = payload[..payload.len() - 8]
            .iter()
            .map(|&b| u32::from(b))
            .sum();
        assert_eq!(*sum, before + 0xD7);
        assert_eq!(Command::decode_all(&payload).unwrap(), program.commands());
        assert_eq!(program.packets(MAGIC).unwrap().len(), 1);
    }

    #[test]
    fn a_program_the_encoding_cannot_carry_is_refused() {
        let refused = |layers: &[CutLayer]| Program::new(layers).unwrap_err();
        assert!(matches!(refused(&[]), RuidaError::BadProgram(_)));
        assert!(matches!(
            refused(&[layer(vec![])]),
            RuidaError::BadProgram(_)
        ));
        assert!(matches!(
            refused(&[layer(vec![vec![[0.0, 0.0]]])]),
            RuidaError::BadProgram(_)
        ));
        let mut hot = layer(vec![square(0.0, 1.0)]);
        hot.max_power_percent = 120.0;
        hot.min_power_percent = 110.0;
        assert!(matches!(
            refused(&[hot.clone()]),
            RuidaError::OutOfRange {
                what: "power_percent",
                ..
            }
        ));
        hot.min_power_percent = 50.0;
        hot.max_power_percent = 40.0;
        assert!(matches!(refused(&[hot]), RuidaError::BadProgram(_)));
        let far = layer(vec![vec![[0.0, 0.0], [f64::NAN, 1.0]]]);
        assert!(matches!(
            refused(&[far]),
            RuidaError::OutOfRange { what: "x_mm", .. }
        ));
        let still = CutLayer {
            speed_mm_per_s: 0.0,
            ..layer(vec![square(0.0, 1.0)])
        };
        assert!(matches!(
            refused(&[still]),
            RuidaError::OutOfRange {
                what: "speed_mm_per_s",
                ..
            }
        ));
    }
}
