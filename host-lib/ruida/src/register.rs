//! Register reads: `DA 00 hi lo` is ACKed, then answered by a separate packet `DA 01 hi lo`
//! with a 5-byte value. The registers a driver reads: the head's position (X, Y, Z, U, in µm),
//! the machine status, the bed size (µm) and the card ID.
//!
//! What the status bits mean on a real controller is not settled (MeerK40t's two readers
//! disagree on the rest); both take bit 0 as "a job is running", and the job reader bit 24 as
//! "moving", which is all [`MachineStatus::is_busy`] reads.

use crate::swizzle::unswizzle;
use crate::value::{decode_coord_um, decode_u35};
use crate::{Command, RuidaError};

/// A register this project reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Register {
    /// The controller card's ID.
    CardId,
    /// The machine status bits.
    MachineStatus,
    /// The head's X, µm.
    PositionX,
    /// The head's Y, µm.
    PositionY,
    /// The Z table, µm.
    PositionZ,
    /// The U axis, µm.
    PositionU,
    /// The bed's X size, µm.
    BedSizeX,
    /// The bed's Y size, µm.
    BedSizeY,
}

/// A register's value, as read.
pub type RegisterValue = u64;

impl Register {
    /// Every register this project reads.
    pub const ALL: [Register; 8] = [
        Self::CardId,
        Self::MachineStatus,
        Self::PositionX,
        Self::PositionY,
        Self::PositionZ,
        Self::PositionU,
        Self::BedSizeX,
        Self::BedSizeY,
    ];

    /// The register's two address bytes.
    pub fn address(self) -> [u8; 2] {
        match self {
            Self::CardId => [0x05, 0x7E],
            Self::MachineStatus => [0x04, 0x00],
            Self::PositionX => [0x04, 0x21],
            Self::PositionY => [0x04, 0x31],
            Self::PositionZ => [0x04, 0x41],
            Self::PositionU => [0x04, 0x51],
            Self::BedSizeX => [0x00, 0x26],
            Self::BedSizeY => [0x00, 0x36],
        }
    }

    /// The register at `address`, if it is one of these.
    pub fn from_address(address: [u8; 2]) -> Option<Self> {
        Self::ALL.into_iter().find(|r| r.address() == address)
    }

    /// The command that reads it.
    pub fn read(self) -> Command {
        Command::ReadRegister {
            address: self.address(),
        }
    }

    /// The command a controller answers with.
    pub fn answer(self, value: RegisterValue) -> Command {
        Command::RegisterValue {
            address: self.address(),
            value,
        }
    }

    /// The value in a received answer datagram: swizzled, with no checksum (as MeerK40t's
    /// client and emulator have it; unverified on a controller).
    pub fn parse_reply(self, datagram: &[u8], magic: u8) -> Result<RegisterValue, RuidaError> {
        self.parse_answer(&unswizzle(datagram, magic))
    }

    /// The value in the unswizzled answer `payload` (`DA 01 hi lo` and five 7-bit bytes),
    /// refused when it is no answer or another register's.
    pub fn parse_answer(self, payload: &[u8]) -> Result<RegisterValue, RuidaError> {
        let not_an_answer = || RuidaError::NotARegisterAnswer {
            bytes: payload.to_vec(),
        };
        let [0xDA, 0x01, hi, lo, v0, v1, v2, v3, v4] = *payload else {
            return Err(not_an_answer());
        };
        let value = decode_u35([v0, v1, v2, v3, v4]).ok_or_else(not_an_answer)?;
        if [hi, lo] != self.address() {
            let word = |a: [u8; 2]| u16::from_be_bytes(a);
            return Err(RuidaError::WrongRegister {
                asked: word(self.address()),
                answered: word([hi, lo]),
            });
        }
        Ok(value)
    }
}

/// A position or length register's value (µm, signed) in mm; `None` beyond 32 bits.
pub fn value_to_mm(value: RegisterValue) -> Option<f64> {
    let bytes = crate::value::encode_u35(value);
    decode_coord_um(bytes).map(|um| f64::from(um) / 1000.0)
}

/// The machine status register's bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MachineStatus(pub RegisterValue);

impl MachineStatus {
    /// Bit 0: a job is running (both MeerK40t readers).
    pub const JOB_RUNNING: RegisterValue = 0x0000_0001;
    /// Bit 1: the part (program) has ended (MeerK40t's job reader).
    pub const PART_END: RegisterValue = 0x0000_0002;
    /// Bit 24: the head is moving (MeerK40t's job reader).
    pub const MOVING: RegisterValue = 0x0100_0000;

    /// Whether a job runs or the head moves.
    pub fn is_busy(self) -> bool {
        self.0 & (Self::JOB_RUNNING | Self::MOVING) != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::value::encode_coord_um;

    #[test]
    fn an_answer_reads_back_its_value_and_is_checked_for_its_register() {
        let answer = Register::PositionX
            .answer(u64::from(-1500i32 as u32))
            .to_bytes();
        let value = Register::PositionX.parse_answer(&answer).unwrap();
        assert_eq!(value_to_mm(value), Some(-1.5));
        let datagram = crate::swizzle::swizzle(&answer, crate::MAGIC);
        assert_eq!(
            Register::PositionX.parse_reply(&datagram, crate::MAGIC),
            Ok(value)
        );
        assert_eq!(
            Register::PositionY.parse_answer(&answer),
            Err(RuidaError::WrongRegister {
                asked: 0x0431,
                answered: 0x0421
            })
        );
        let mut long = answer.clone();
        long.push(0);
        assert!(matches!(
            Register::PositionX.parse_answer(&long),
            Err(RuidaError::NotARegisterAnswer { .. })
        ));
        assert!(matches!(
            Register::PositionX.parse_answer(&[0xCC]),
            Err(RuidaError::NotARegisterAnswer { .. })
        ));
        let mut bad = vec![0xDA, 0x01, 0x04, 0x21];
        bad.extend(encode_coord_um(5));
        bad[8] = 0x85;
        assert!(Register::PositionX.parse_answer(&bad).is_err());
    }

    #[test]
    fn addresses_are_distinct_and_found_again() {
        for r in Register::ALL {
            assert_eq!(Register::from_address(r.address()), Some(r));
            assert_eq!(r.read().to_bytes()[..2], [0xDA, 0x00]);
        }
        assert_eq!(Register::from_address([0x7F, 0x7F]), None);
    }

    #[test]
    fn busy_is_a_running_job_or_a_moving_head() {
        assert!(!MachineStatus(22).is_busy());
        assert!(MachineStatus(21).is_busy());
        assert!(MachineStatus(MachineStatus::MOVING).is_busy());
        assert!(!MachineStatus(MachineStatus::PART_END).is_busy());
    }
}
