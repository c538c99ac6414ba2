//! Ruida CO2-laser controllers' protocol (the RDC644x family), written once from the facts in
//! `docs/ruida.md` and checked against MeerK40t's own Ruida parser: what a Ruida driver, a cut
//! program's writer and the simulated controller all read, so that none can disagree with
//! another about a byte.
//!
//! - [`swizzle`]: the per-byte scrambling every packet's payload goes through (magic 0x88).
//! - [`value`]: the 7-bit-per-byte numbers: coordinates in µm, speeds, powers.
//! - [`command`]: the commands this project sends ([`Command`]), encoded and decoded.
//! - [`packet`]: a packet (checksum + swizzled payload, at most [`packet::MAX_LEN`] bytes, split
//!   only between commands) and the one-byte replies ([`Reply`]).
//! - [`register`]: register reads (`DA 00 hi lo`) and their answers (`DA 01 hi lo value`): the
//!   position, the machine status, the bed size.
//! - [`program`]: a cut program from polylines in mm with per-layer speed and power, the laser
//!   off on every travel.
//! - [`link`]: the UDP link a driver sends packets over, each waited for, a program packet never
//!   sent twice.
//! - `twin` (feature `twin`): a simulated controller on UDP, as unkind as a real one.
//!
//! The crate does no I/O outside the link and the twin; everything else is pure functions.

pub mod command;
mod error;
pub mod link;
pub mod packet;
pub mod program;
pub mod register;
pub mod swizzle;
#[cfg(feature = "twin")]
pub mod twin;
pub mod value;

pub use command::Command;
pub use error::RuidaError;
pub use packet::{Packet, Reply};
pub use program::{CutLayer, Program};
pub use register::{Register, RegisterValue};

/// The controller's UDP port for swizzled, checksummed packets.
pub const UDP_PORT: u16 = 50200;

/// The local UDP port a controller sends its answers to, whatever port the packet came from
/// (MeerK40t's UDP driver listens there for them; unverified on a controller here).
pub const REPLY_UDP_PORT: u16 = 40200;

/// The "jog" UDP port: raw bytes, neither swizzled nor checksummed (not used by this crate's
/// writer).
pub const JOG_UDP_PORT: u16 = 50207;

/// The common swizzle magic (RDC644x); some models use another.
pub const MAGIC: u8 = 0x88;
