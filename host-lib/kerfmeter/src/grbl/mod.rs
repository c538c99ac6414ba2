//! Drive a laser cutter's GRBL 1.1 controller: over a serial port (`grbl:/dev/ttyUSB0`), over
//! TCP (`grbl+tcp://HOST:PORT`: FluidNC and other networked controllers) or the simulated cutter
//! in this process (`sim`, with the `sim` feature).
//!
//! - [`protocol`]: the protocol without I/O: a program cleaned into lines, replies and status
//!   reports parsed, and the character-counting [`protocol::Streamer`].
//! - [`codes`]: what each `error:N` and `ALARM:N` means.
//! - [`Cutter`]: the blocking driver on a byte stream ([`CutterAddress`] says which).
//!
//! # Connecting
//!
//! [`Cutter::open`] waits for GRBL's banner (`Grbl 1.1h ['$' for help]`); a controller that says
//! nothing (one that does not reset when its port opens, a TCP controller) is woken with a soft
//! reset. The banner's absence is an error naming what came instead. It then asks for the state:
//! a controller in alarm is refused with the alarm's meaning unless unlocking was asked for
//! (`$X`); one that is not idle is refused. Finally it reads the settings (`$$`) and refuses a
//! controller without laser mode (`$32=1`): without it GRBL keeps the beam on through travel
//! moves, which cuts across the work (override only for a spindle machine).
//!
//! # Streaming
//!
//! [`Cutter::stream`] sends a program with character counting: never more than GRBL's 128-byte
//! receive buffer unanswered, each `ok`/`error:N` matched to its line in order. It polls the
//! state (`?`) meanwhile, and returns once every line is accepted and the machine reports Idle
//! twice. Every failure stops the cutter before it is returned ([`Cutter::stop`]: feed hold `!`,
//! then soft reset ctrl-X, which empties the queue and turns the laser off; after an alarm, which
//! has stopped the machine already, the reset alone): a refused line
//! (reported with its line number in the file, its text and the code's meaning), an alarm (with
//! the last line accepted), silence, a restart, and a cancel flag set (Ctrl-C). If even stopping
//! fails, the error says so and asks for the laser to be switched off at the machine.

pub mod codes;
mod driver;
mod error;
pub mod protocol;
#[cfg(feature = "sim")]
mod sim;
mod transport;

pub use driver::{ConnectOptions, Cutter, StreamProgress, StreamReport};
pub use error::CutterError;
#[cfg(feature = "sim")]
pub use sim::SimCutterOptions;
pub use transport::{CutterAddress, DEFAULT_BAUD, Link};
