//! The commands this project sends to a Ruida controller, and their bytes. Only commands that
//! MeerK40t 0.9.9100 and `ruida-pa` 0.23.0 decode alike are written (`docs/ruida.md`): absolute
//! moves and cuts (never relative ones, which wrap beyond ±8.191 mm; never `80 00`/`A0 00`,
//! which the two decoders read differently), speed `C9 02`, minimum/maximum power `C6 01`/`C6 02`.
//! Nor `CA 01 00`: "end layer" to MeerK40t, "overscan off" to ruida-pa.
//!
//! Each command starts with a byte ≥ 0x80 and its data bytes are below 0x80 ([`crate::value`]),
//! which is how a stream splits into commands. [`Command::decode`] reads back what
//! [`Command::encode`] writes (the twin and the tests use it); anything else is refused with a
//! typed error.

use crate::RuidaError;
use crate::value::{
    decode_coord_um, decode_u14, decode_u35, encode_coord_um, encode_u14, encode_u35,
};

/// The rapid-move (`D9`) option byte for a move to absolute machine coordinates: "machine" to
/// ruida-pa, "origin" to MeerK40t, whose own driver sends it for its absolute moves. Not 0x02,
/// which both read as relative to the current position (ruida-pa's "current"; MeerK40t's driver
/// sends it with its relative single-axis moves).
pub const RAPID_OPTION_ABSOLUTE: u8 = 0x00;

/// A command, with its values as sent (µm, µm/s, 14-bit power steps).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// `88 x y`: travel to an absolute position, laser off.
    MoveAbs {
        /// X, µm.
        x_um: i32,
        /// Y, µm.
        y_um: i32,
    },
    /// `A8 x y`: cut in a straight line to an absolute position, laser on.
    CutAbs {
        /// X, µm.
        x_um: i32,
        /// Y, µm.
        y_um: i32,
    },
    /// `C9 02 v`: the cutting speed, µm/s.
    Speed {
        /// Speed, µm/s.
        speed_um_per_s: u32,
    },
    /// `C6 01 p`: laser 1's minimum power (at corners), in 2^14ths of full.
    MinPower {
        /// Power, 2^14ths.
        power_steps: u16,
    },
    /// `C6 02 p`: laser 1's maximum power, in 2^14ths of full.
    MaxPower {
        /// Power, 2^14ths.
        power_steps: u16,
    },
    /// `CA 02 n`: the layer (part) number the settings that follow belong to.
    LayerNumber {
        /// The layer, 0–127.
        layer: u8,
    },
    /// `E6 01`: coordinates are absolute.
    SetAbsolute,
    /// `E5 05 v`: the file's checksum (see [`crate::program`]).
    FileSum {
        /// The sum.
        sum: u32,
    },
    /// `D7`: the end of the file.
    EndOfFile,
    /// `D8 00`: start the loaded program.
    StartProcess,
    /// `D8 01`: stop the running program.
    StopProcess,
    /// `D9 10 00 x y`: move the head now to an absolute X/Y, laser off.
    RapidMoveXy {
        /// X, µm.
        x_um: i32,
        /// Y, µm.
        y_um: i32,
    },
    /// `D9 02 00 z`: move the Z table now to an absolute position.
    RapidMoveZ {
        /// Z, µm.
        z_um: i32,
    },
    /// `D9 03 00 u`: move the U axis now to an absolute position.
    RapidMoveU {
        /// U, µm.
        u_um: i32,
    },
    /// `DA 00 hi lo`: read a register (answered by `DA 01 hi lo value`).
    ReadRegister {
        /// The register's two address bytes.
        address: [u8; 2],
    },
    /// `DA 01 hi lo v`: a register's value (the controller's answer to a read).
    RegisterValue {
        /// The register's two address bytes.
        address: [u8; 2],
        /// Its value (35 bits).
        value: u64,
    },
    /// `CE`: keep-alive (answered with an ACK).
    KeepAlive,
}

impl Command {
    /// Append the command's bytes to `out`.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let xy = |out: &mut Vec<u8>, x: i32, y: i32| {
            out.extend(encode_coord_um(x));
            out.extend(encode_coord_um(y));
        };
        match *self {
            Self::MoveAbs { x_um, y_um } => {
                out.push(0x88);
                xy(out, x_um, y_um);
            }
            Self::CutAbs { x_um, y_um } => {
                out.push(0xA8);
                xy(out, x_um, y_um);
            }
            Self::Speed { speed_um_per_s } => {
                out.extend([0xC9, 0x02]);
                out.extend(encode_u35(speed_um_per_s.into()));
            }
            Self::MinPower { power_steps } => {
                out.extend([0xC6, 0x01]);
                out.extend(encode_u14(power_steps));
            }
            Self::MaxPower { power_steps } => {
                out.extend([0xC6, 0x02]);
                out.extend(encode_u14(power_steps));
            }
            Self::LayerNumber { layer } => out.extend([0xCA, 0x02, layer & 0x7F]),
            Self::SetAbsolute => out.extend([0xE6, 0x01]),
            Self::FileSum { sum } => {
                out.extend([0xE5, 0x05]);
                out.extend(encode_u35(sum.into()));
            }
            Self::EndOfFile => out.push(0xD7),
            Self::StartProcess => out.extend([0xD8, 0x00]),
            Self::StopProcess => out.extend([0xD8, 0x01]),
            Self::RapidMoveXy { x_um, y_um } => {
                out.extend([0xD9, 0x10, RAPID_OPTION_ABSOLUTE]);
                xy(out, x_um, y_um);
            }
            Self::RapidMoveZ { z_um } => {
                out.extend([0xD9, 0x02, RAPID_OPTION_ABSOLUTE]);
                out.extend(encode_coord_um(z_um));
            }
            Self::RapidMoveU { u_um } => {
                out.extend([0xD9, 0x03, RAPID_OPTION_ABSOLUTE]);
                out.extend(encode_coord_um(u_um));
            }
            Self::ReadRegister { address } => out.extend([0xDA, 0x00, address[0], address[1]]),
            Self::RegisterValue { address, value } => {
                out.extend([0xDA, 0x01, address[0], address[1]]);
                out.extend(encode_u35(value));
            }
            Self::KeepAlive => out.push(0xCE),
        }
    }

    /// The command's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.encode(&mut out);
        out
    }

    /// Whether the laser fires during this command.
    pub fn fires_laser(&self) -> bool {
        matches!(self, Self::CutAbs { .. })
    }

    /// Split an unswizzled payload into commands.
    pub fn decode_all(payload: &[u8]) -> Result<Vec<Command>, RuidaError> {
        let mut commands = Vec::new();
        let mut offset = 0;
        while offset < payload.len() {
            let (command, len) = Self::decode(&payload[offset..], offset)?;
            commands.push(command);
            offset += len;
        }
        Ok(commands)
    }

    /// The command `bytes` starts with, and its length; `offset` is where it stands in the
    /// payload, for the error.
    pub fn decode(bytes: &[u8], offset: usize) -> Result<(Command, usize), RuidaError> {
        let opcode = bytes[0];
        if opcode < 0x80 {
            return Err(RuidaError::NotACommand {
                byte: opcode,
                offset,
            });
        }
        // A command runs to the next byte ≥ 0x80.
        let len = 1 + bytes[1..].iter().take_while(|&&b| b < 0x80).count();
        let data = &bytes[1..len];
        let unknown = || RuidaError::UnknownCommand {
            opcode: bytes[..len.min(2)].to_vec(),
            offset,
        };
        let malformed = RuidaError::MalformedCommand { opcode, offset };
        let command = match (opcode, data) {
            (0x88 | 0xA8, _) | (0xD9, [0x10, ..]) => decode_xy(opcode, data),
            (0xC9, [0x02, v @ ..]) => five(v).map(|v| Self::Speed {
                speed_um_per_s: v as u32,
            }),
            (0xC6, [which @ (0x01 | 0x02), p0, p1]) => {
                decode_u14([*p0, *p1]).map(|p| match which {
                    0x01 => Self::MinPower { power_steps: p },
                    _ => Self::MaxPower { power_steps: p },
                })
            }
            (0xCA, [0x02, layer]) => Some(Self::LayerNumber { layer: *layer }),
            (0xE6, [0x01]) => Some(Self::SetAbsolute),
            (0xE5, [0x05, v @ ..]) => five(v).map(|v| Self::FileSum { sum: v as u32 }),
            (0xD7, []) => Some(Self::EndOfFile),
            (0xD8, [0x00]) => Some(Self::StartProcess),
            (0xD8, [0x01]) => Some(Self::StopProcess),
            (0xD9, [0x02, RAPID_OPTION_ABSOLUTE, v @ ..]) => {
                coord(v).map(|z_um| Self::RapidMoveZ { z_um })
            }
            (0xD9, [0x03, RAPID_OPTION_ABSOLUTE, v @ ..]) => {
                coord(v).map(|u_um| Self::RapidMoveU { u_um })
            }
            (0xDA, [0x00, hi, lo]) => Some(Self::ReadRegister {
                address: [*hi, *lo],
            }),
            (0xDA, [0x01, hi, lo, v @ ..]) => five(v).map(|value| Self::RegisterValue {
                address: [*hi, *lo],
                value,
            }),
            (0xCE, []) => Some(Self::KeepAlive),
            _ if known_prefix(opcode, data) => None,
            _ => return Err(unknown()),
        };
        command.map(|c| (c, len)).ok_or(malformed)
    }
}

/// Whether a command this crate decodes starts `opcode data` (so a bad length is "malformed",
/// not "unknown").
fn known_prefix(opcode: u8, data: &[u8]) -> bool {
    matches!(
        (opcode, data.first()),
        (0xD7 | 0xCE, _)
            | (0xC9, Some(0x02))
            | (0xC6, Some(0x01 | 0x02))
            | (0xCA, Some(0x02))
            | (0xE6, Some(0x01))
            | (0xE5, Some(0x05))
            | (0xD8, Some(0x00 | 0x01))
            | (0xD9, Some(0x02 | 0x03 | 0x10))
            | (0xDA, Some(0x00 | 0x01))
    )
}

/// A 5-byte value that is the whole of `v`.
fn five(v: &[u8]) -> Option<u64> {
    decode_u35(v.try_into().ok()?)
}

/// A 5-byte coordinate that is the whole of `v`.
fn coord(v: &[u8]) -> Option<i32> {
    decode_coord_um(v.try_into().ok()?)
}

/// `88`/`A8` (data: x y) or `D9 10` (data: 10 02 x y).
fn decode_xy(opcode: u8, data: &[u8]) -> Option<Command> {
    let xy = match opcode {
        0xD9 => data.strip_prefix(&[0x10, RAPID_OPTION_ABSOLUTE])?,
        _ => data,
    };
    if xy.len() != 10 {
        return None;
    }
    let (x_um, y_um) = (coord(&xy[..5])?, coord(&xy[5..])?);
    Some(match opcode {
        0x88 => Command::MoveAbs { x_um, y_um },
        0xA8 => Command::CutAbs { x_um, y_um },
        _ => Command::RapidMoveXy { x_um, y_um },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> Vec<Command> {
        vec![
            Command::MoveAbs {
                x_um: -5,
                y_um: 300_000,
            },
            Command::CutAbs {
                x_um: 12_345,
                y_um: 0,
            },
            Command::Speed {
                speed_um_per_s: 100_000,
            },
            Command::MinPower { power_steps: 1638 },
            Command::MaxPower { power_steps: 16383 },
            Command::LayerNumber { layer: 3 },
            Command::SetAbsolute,
            Command::FileSum { sum: 123_456 },
            Command::EndOfFile,
            Command::StartProcess,
            Command::StopProcess,
            Command::RapidMoveXy { x_um: 1, y_um: -1 },
            Command::RapidMoveZ { z_um: -2500 },
            Command::RapidMoveU { u_um: 7 },
            Command::ReadRegister {
                address: [0x04, 0x21],
            },
            Command::RegisterValue {
                address: [0x04, 0x31],
                value: 42,
            },
            Command::KeepAlive,
        ]
    }

    #[test]
    fn every_command_decodes_as_encoded() {
        let commands = all();
        let mut payload = Vec::new();
        for c in &commands {
            c.encode(&mut payload);
        }
        assert_eq!(Command::decode_all(&payload).unwrap(), commands);
    }

    #[test]
    fn bytes_are_as_the_notes_give_them() {
        assert_eq!(
            Command::MoveAbs {
                x_um: 1000,
                y_um: 0
            }
            .to_bytes(),
            [0x88, 0, 0, 0, 0x07, 0x68, 0, 0, 0, 0, 0]
        );
        assert_eq!(
            Command::MaxPower { power_steps: 1638 }.to_bytes(),
            [0xC6, 0x02, 0x0C, 0x66]
        );
        assert_eq!(
            Command::ReadRegister {
                address: [0x04, 0x21]
            }
            .to_bytes(),
            [0xDA, 0, 4, 0x21]
        );
    }

    #[test]
    fn what_the_protocol_does_not_allow_is_refused_by_kind() {
        let err = |bytes: &[u8]| Command::decode_all(bytes).unwrap_err();
        assert!(matches!(
            err(&[0x12]),
            RuidaError::NotACommand {
                byte: 0x12,
                offset: 0
            }
        ));
        assert!(matches!(
            err(&[0xD7, 0x80, 0x00]),
            RuidaError::UnknownCommand { offset: 1, .. }
        ));
        assert!(matches!(
            err(&[0x88, 0, 0, 0]),
            RuidaError::MalformedCommand { opcode: 0x88, .. }
        ));
        assert!(matches!(
            err(&[0xC6, 0x01, 0x01]),
            RuidaError::MalformedCommand { .. }
        ));
        assert!(matches!(
            err(&[0xD7, 0x00]),
            RuidaError::MalformedCommand { opcode: 0xD7, .. }
        ));
        // A relative move is a real command, but not one this crate writes or reads.
        assert!(matches!(
            err(&[0x89, 0, 1, 0, 1]),
            RuidaError::UnknownCommand { .. }
        ));
        assert!(!Command::MoveAbs { x_um: 0, y_um: 0 }.fires_laser());
        assert!(Command::CutAbs { x_um: 0, y_um: 0 }.fires_laser());
    }
}
