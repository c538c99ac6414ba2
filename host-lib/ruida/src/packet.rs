//! Packets and replies. A packet is a 2-byte big-endian checksum (the sum of the swizzled
//! payload's bytes, mod 2^16) followed by the swizzled payload; it is at most [`MAX_LEN`] bytes,
//! checksum included, and a stream is split into packets only between commands (MeerK40t's
//! decoder breaks on a command split across two). Every packet is answered with one swizzled
//! byte: [`Reply::Ack`] or, on a checksum mismatch, [`Reply::Nak`].

use crate::swizzle::{swizzle, swizzle_byte, unswizzle, unswizzle_byte};
use crate::{Command, RuidaError};

/// The longest packet, bytes, checksum included (MeerK40t's emulator NAKs one of 1,102).
pub const MAX_LEN: usize = 1024;

/// The longest payload of a packet, bytes.
pub const MAX_PAYLOAD_LEN: usize = MAX_LEN - 2;

/// A packet as it goes on the wire: checksum, then swizzled payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet(Vec<u8>);

impl Packet {
    /// The packet carrying the unswizzled `payload`, swizzled with `magic`.
    pub fn new(payload: &[u8], magic: u8) -> Result<Self, RuidaError> {
        if payload.len() > MAX_PAYLOAD_LEN {
            return Err(RuidaError::PacketTooLong {
                len: payload.len() + 2,
                max: MAX_LEN,
            });
        }
        let body = swizzle(payload, magic);
        let mut bytes = checksum(&body).to_be_bytes().to_vec();
        bytes.extend(body);
        Ok(Self(bytes))
    }

    /// The bytes to send.
    pub fn as_bytes(&self) -> &[u8] {
        &self.0
    }

    /// A received packet's unswizzled payload, its length and checksum checked.
    pub fn open(bytes: &[u8], magic: u8) -> Result<Vec<u8>, RuidaError> {
        if bytes.len() < 2 {
            return Err(RuidaError::PacketTooShort { len: bytes.len() });
        }
        if bytes.len() > MAX_LEN {
            return Err(RuidaError::PacketTooLong {
                len: bytes.len(),
                max: MAX_LEN,
            });
        }
        let stated = u16::from_be_bytes([bytes[0], bytes[1]]);
        let computed = checksum(&bytes[2..]);
        if stated != computed {
            return Err(RuidaError::ChecksumMismatch { stated, computed });
        }
        Ok(unswizzle(&bytes[2..], magic))
    }
}

/// The sum of `swizzled` bytes, mod 2^16.
pub fn checksum(swizzled: &[u8]) -> u16 {
    swizzled
        .iter()
        .fold(0u16, |sum, &b| sum.wrapping_add(u16::from(b)))
}

/// `commands` in as few packets as fit, each split between two commands.
pub fn packets(commands: &[Command], magic: u8) -> Result<Vec<Packet>, RuidaError> {
    let mut packets = Vec::new();
    let mut payload = Vec::new();
    for command in commands {
        let bytes = command.to_bytes();
        if payload.len() + bytes.len() > MAX_PAYLOAD_LEN && !payload.is_empty() {
            packets.push(Packet::new(&payload, magic)?);
            payload.clear();
        }
        payload.extend(bytes);
    }
    if !payload.is_empty() {
        packets.push(Packet::new(&payload, magic)?);
    }
    Ok(packets)
}

/// A controller's one-byte answer to a packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reply {
    /// `CC`: received.
    Ack,
    /// `CF`: checksum mismatch; the packet was dropped.
    Nak,
    /// `CD`: an error.
    Err,
    /// `CE`: keep-alive.
    KeepAlive,
}

impl Reply {
    /// The reply's unswizzled byte.
    pub fn byte(self) -> u8 {
        match self {
            Self::Ack => 0xCC,
            Self::Nak => 0xCF,
            Self::Err => 0xCD,
            Self::KeepAlive => 0xCE,
        }
    }

    /// The reply's byte on the wire.
    pub fn swizzled(self, magic: u8) -> u8 {
        swizzle_byte(self.byte(), magic)
    }

    /// The reply a received (swizzled) byte is, or the error naming it.
    pub fn from_swizzled(byte: u8, magic: u8) -> Result<Self, RuidaError> {
        match unswizzle_byte(byte, magic) {
            0xCC => Ok(Self::Ack),
            0xCF => Ok(Self::Nak),
            0xCD => Ok(Self::Err),
            0xCE => Ok(Self::KeepAlive),
            other => Err(RuidaError::UnknownReply { byte: other }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MAGIC;
    use proptest::prelude::*;

    fn command() -> impl Strategy<Value = Command> {
        prop_oneof![
            (any::<i32>(), any::<i32>()).prop_map(|(x_um, y_um)| Command::MoveAbs { x_um, y_um }),
            (any::<i32>(), any::<i32>()).prop_map(|(x_um, y_um)| Command::CutAbs { x_um, y_um }),
            (1u32..1 << 31).prop_map(|speed_um_per_s| Command::Speed { speed_um_per_s }),
            (0u16..1 << 14).prop_map(|power_steps| Command::MaxPower { power_steps }),
            Just(Command::EndOfFile),
        ]
    }

    proptest! {
        /// Every packet fits, opens to whole commands, and all of them together are the stream.
        #[test]
        fn packets_round_trip(commands in proptest::collection::vec(command(), 0..400), magic in any::<u8>()) {
            let mut opened = Vec::new();
            for packet in packets(&commands, magic).unwrap() {
                prop_assert!(packet.as_bytes().len() <= MAX_LEN);
                let payload = Packet::open(packet.as_bytes(), magic).unwrap();
                opened.extend(Command::decode_all(&payload).unwrap());
            }
            prop_assert_eq!(opened, commands);
        }

        #[test]
        fn a_flipped_byte_fails_the_checksum(payload in proptest::collection::vec(any::<u8>(), 1..500), at in any::<prop::sample::Index>(), flip in 1u8..) {
            let mut bytes = Packet::new(&payload, MAGIC).unwrap().as_bytes().to_vec();
            let i = 2 + at.index(payload.len());
            bytes[i] ^= flip;
            let is_mismatch = matches!(Packet::open(&bytes, MAGIC), Err(RuidaError::ChecksumMismatch { .. }));
            prop_assert!(is_mismatch);
        }
    }

    #[test]
    fn a_long_stream_is_split_between_commands_into_full_packets() {
        let commands = vec![Command::CutAbs { x_um: 1, y_um: 2 }; 300];
        let packets = packets(&commands, MAGIC).unwrap();
        // 11 bytes a command: 92 commands (1012 bytes) to a packet.
        assert_eq!(packets.len(), 4);
        assert_eq!(packets[0].as_bytes().len(), 2 + 92 * 11);
        assert!(Packet::new(&[0xD7; MAX_PAYLOAD_LEN + 1], MAGIC).is_err());
    }

    #[test]
    fn replies_read_from_the_wire() {
        assert_eq!(Reply::from_swizzled(0xC6, MAGIC), Ok(Reply::Ack));
        for reply in [Reply::Ack, Reply::Nak, Reply::Err, Reply::KeepAlive] {
            assert_eq!(
                Reply::from_swizzled(reply.swizzled(MAGIC), MAGIC),
                Ok(reply)
            );
        }
        assert_eq!(
            Reply::from_swizzled(swizzle_byte(0x41, MAGIC), MAGIC),
            Err(RuidaError::UnknownReply { byte: 0x41 })
        );
        assert!(matches!(
            Packet::open(&[1], MAGIC),
            Err(RuidaError::PacketTooShort { len: 1 })
        ));
    }
}
