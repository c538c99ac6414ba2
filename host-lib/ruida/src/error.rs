//! What the protocol does not allow, as typed errors: a bad packet or reply from a controller,
//! a command the decoder does not know, a value the encoding cannot carry.

/// A Ruida protocol error.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RuidaError {
    /// A packet shorter than its 2-byte checksum.
    #[error("a Ruida packet of {len} bytes is shorter than its 2-byte checksum")]
    PacketTooShort {
        /// The packet's length, bytes.
        len: usize,
    },
    /// A packet longer than a controller takes.
    #[error("a Ruida packet of {len} bytes is longer than the {max} a controller takes")]
    PacketTooLong {
        /// The packet's length, bytes (checksum included).
        len: usize,
        /// The longest allowed.
        max: usize,
    },
    /// A packet whose checksum does not match its payload.
    #[error(
        "Ruida packet checksum mismatch: it says {stated:#06x}, its payload sums to {computed:#06x}"
    )]
    ChecksumMismatch {
        /// The checksum the packet carries.
        stated: u16,
        /// The sum of its swizzled payload.
        computed: u16,
    },
    /// A reply byte that is none of ACK, NAK, ERR or keep-alive.
    #[error(
        "the Ruida controller answered {byte:#04x} (unswizzled), which is no reply the protocol allows"
    )]
    UnknownReply {
        /// The reply, unswizzled.
        byte: u8,
    },
    /// A datagram of several bytes where a one-byte reply was due.
    #[error("the Ruida controller answered {len} bytes where a one-byte reply was due")]
    NotAReply {
        /// The datagram's length.
        len: usize,
    },
    /// A payload whose next byte starts no command (commands start with a byte ≥ 0x80).
    #[error("byte {byte:#04x} at offset {offset} starts no Ruida command")]
    NotACommand {
        /// The byte.
        byte: u8,
        /// Its offset in the payload.
        offset: usize,
    },
    /// A command this crate does not decode.
    #[error("unknown Ruida command {opcode:02x?} at offset {offset}")]
    UnknownCommand {
        /// Its first byte or two.
        opcode: Vec<u8>,
        /// Its offset in the payload.
        offset: usize,
    },
    /// A command cut short, or with a data byte ≥ 0x80.
    #[error("Ruida command {opcode:#04x} at offset {offset} is cut short or malformed")]
    MalformedCommand {
        /// Its first byte.
        opcode: u8,
        /// Its offset in the payload.
        offset: usize,
    },
    /// A register answer for another register than the one asked.
    #[error("asked Ruida register {asked:#06x}, the answer is for {answered:#06x}")]
    WrongRegister {
        /// The register asked.
        asked: u16,
        /// The register answered.
        answered: u16,
    },
    /// A register answer that is not `DA 01 hi lo` and a 5-byte value.
    #[error("not a Ruida register answer: {bytes:02x?}")]
    NotARegisterAnswer {
        /// The answer, unswizzled.
        bytes: Vec<u8>,
    },
    /// A value the encoding cannot carry (a coordinate beyond ±2^31 µm, a power outside
    /// 0–100 %, a speed not above zero, a NaN).
    #[error("{what} = {value} cannot be encoded for a Ruida controller ({allowed})")]
    OutOfRange {
        /// The quantity, with its unit (`x_mm`, `speed_mm_per_s`, ...).
        what: &'static str,
        /// The value given.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// A program that is refused as a whole (no layer, a path of fewer than two points, min
    /// power above max).
    #[error("Ruida program refused: {0}")]
    BadProgram(String),
}
