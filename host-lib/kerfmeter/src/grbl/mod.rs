//! Drive a laser cutter's GRBL 1.1 controller: over a serial port (`grbl:/dev/ttyUSB0`), over
//! TCP (`grbl+tcp://HOST:PORT`: FluidNC and other networked controllers) or the simulated cutter
//! in this process (`sim`, with the `sim` feature).
//!
//! - [`protocol`]: the protocol without I/O: a program cleaned into lines, replies and status
//!   reports parsed, and the character-counting [`protocol::Streamer`].
//! - [`codes`]: what each `error:N` and `ALARM:N` means (GRBL's facts are one table, the
//!   `kerfmeter-grbl` crate, which the G-code writer and the cutter twin read too).
//! - [`travel`], [`extent`], [`offsets`]: the machine's travel (`$130`–`$132`, homing, soft
//!   limits), how far a program's moves reach as GRBL reads them, and the work offsets and parser
//!   state that place its numbers.
//! - [`Cutter`]: the blocking driver on a byte stream ([`CutterAddress`] says which).
//! - `twin` (feature `sim`): the cutter twin, a simulated GRBL 1.1 laser cutter (sans-IO), and its
//!   server on a pseudo-terminal or a TCP port, with a record of what its laser traced; the
//!   driver is tested against it, and `--cutter sim` is it.
//!
//! # Connecting
//!
//! [`Cutter::open`] waits for GRBL's banner (`Grbl 1.1h ['$' for help]`), longer while the
//! controller prints a boot log (ESP32 boards); a controller that says nothing (one that does
//! not reset when its port opens, a TCP controller) is asked its state and, unless it is busy
//! (another client's job: refused, not reset), woken with a soft reset. The banner's absence is
//! an error naming what came instead; a GRBL older than 1.1 is refused. It then asks for the
//! state:
//! a controller in alarm is refused with the alarm's meaning unless unlocking was asked for
//! (`$X`); one that is not idle is refused. Finally it reads the settings (`$$`) and refuses a
//! controller without laser mode (`$32=1`): without it GRBL keeps the beam on through travel
//! moves, which cuts across the work (override only for a spindle machine). When the settings
//! give the travel (`$130`–`$132`) it also reads the work offsets (`$#`), the parser state
//! (`$G`) and where the head stands ([`Cutter::travel`]).
//!
//! The soft reset at connect: a controller silent for the banner wait (one that does not restart
//! when its port opens, a networked one) is asked its state first. One that reports a job, a hold
//! or homing is refused and not reset. One that reports Idle, Alarm or Sleep, or whose answer does
//! not come within the reply timeout (late, or never), gets one soft reset (ctrl-X): the banner it
//! brings names the version, and it empties whatever another sender left in the controller's
//! receive buffer. On an idle GRBL a soft reset moves
//! nothing and keeps the machine position, G54–G59 and the settings; it clears G92 and the tool
//! length offset and puts the parser at G0 G54 G17 G21 G90, as the check pass's own reset does.
//!
//! # Streaming
//!
//! [`Cutter::stream`] first runs the program through GRBL's check mode (`$C`, unless
//! [`ConnectOptions::check_first`] is off): every line parsed and answered, nothing moving. GRBL
//! keeps reading the lines already in its receive buffer after it refuses one, before any stop
//! can arrive, so a refused travel mid-job would let the next cut start from the wrong point;
//! the check pass finds the refusal before anything moves (GRBL's own remedy).
//!
//! Before that, the program's moves are followed as GRBL reads them ([`extent`]) from where the
//! head stands, and a program that would leave the machine's travel, or that cannot be bounded
//! (a probe), is refused with nothing sent ([`CutterError::BeyondTravel`],
//! [`CutterError::Unbounded`]).
//!
//! It then sends the program with character counting: never more than GRBL's 128-byte
//! receive buffer unanswered, each `ok`/`error:N` matched to its line in order, closed by an
//! `M5` of its own (under M3 GRBL keeps the beam on at rest after a cut). It polls the state
//! (`?`) meanwhile, and returns once every line is accepted, the machine reports Idle twice and
//! the controller confirms the laser off (`$G` says M5, the status spindle 0). Every failure
//! stops the cutter before it is returned ([`Cutter::stop`]: feed hold `!`, waited for as long
//! as the machine's rates and accelerations say, then soft reset ctrl-X, sent again until the
//! banner comes, which empties the queue and turns the laser off; after an alarm, which has
//! stopped the machine already, the reset alone): a refused line (reported with its line
//! number in the file, its text and the code's meaning), an alarm (with the last line
//! accepted), silence, a restart, and a cancel flag set (Ctrl-C). The error then says that the
//! cutter was stopped and the laser is off ([`CutterError::Stopped`], also when the reset found
//! the machine still moving: `ALARM:3`, home it). If even stopping fails, the error starts with
//! THE LASER MAY STILL BE ON ([`CutterError::NotStopped`]) and asks for the laser to be switched
//! off at the machine.

pub use kerfmeter_grbl::codes;
mod driver;
mod error;
pub mod extent;
pub mod offsets;
pub mod protocol;
#[cfg(feature = "sim")]
mod sim;
mod transport;
pub mod travel;
#[cfg(feature = "sim")]
pub mod twin;

pub use driver::{ConnectOptions, Cutter, StreamProgress, StreamReport};
pub use error::CutterError;
#[cfg(feature = "sim")]
pub use sim::SimCutterOptions;
pub use transport::{CutterAddress, DEFAULT_BAUD, Link};
