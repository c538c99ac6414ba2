//! The cutter twin (feature `sim`): a simulated laser cutter that speaks GRBL 1.1, sans-IO (bytes
//! in, bytes out, a simulated clock moved on by the caller), for the GRBL driver beside it to be
//! tested against, for `--cutter sim` ([`super::Cutter::sim`]) and for `kerfmeter-twin
//! --cutter` to serve on a pseudo-terminal or a TCP port ([`serve`](mod@serve)). GRBL's facts it
//! emulates (buffer, line limit, codes, status report, settings) are the driver's, from one
//! table (`kerfmeter-grbl`).
//!
//! # What it emulates
//!
//! - The serial link as GRBL has it: a 128-byte receive buffer for lines ([`RX_BUFFER_LEN`]); bytes
//!   that arrive while it is full are lost, as on the real controller, and recorded as a
//!   [`ProtocolViolation`] (a sender that counts characters never causes one). The realtime
//!   commands `?` (status report), `!` (feed hold), `~` (resume) and 0x18 (soft reset) are taken
//!   out of the stream as they arrive and never occupy the buffer.
//! - Lines: `ok` or `error:N` for each, in order; `ok` is delayed while the planner queue
//!   ([`PLANNER_BLOCKS`] blocks, as GRBL's) is full, which is how a real controller paces a
//!   sender. Lines over 79 characters (GRBL's 80-byte line buffer less its terminator) are
//!   refused (`error:11`). A line that changes the spindle (M3/M4/M5, or a new `S` with the
//!   spindle on and no motion) waits for the planner to empty before its `ok`, as GRBL's
//!   `spindle_sync` does; lines behind it wait in the receive buffer.
//! - G-code ([`gcode`]): G0 G1 G2 G3 (I/J arcs in XY) G4 G17 G20 G21 G54 G90 G91 G94, M2 M30 M3
//!   M4 M5 (M7–M9 accepted), F S X Y Z I J P N. Anything else is `error:20`; the other checks
//!   give GRBL's codes (missing feed `error:22`, arc end off its circle `error:33`, ...).
//! - `$` commands: `$$` (settings), `$N=V`, `$X` (unlock), `$G` (parser state), `$I` (build
//!   info), `$#` (work offsets: G54 as set up, the others zero), `$` (help), `$C` (check mode:
//!   every line parsed and answered, state `Check`, nothing moves; toggled off with a soft
//!   reset, as GRBL does); `$H` homes at once with homing enabled (`$22=1`), and is `error:5`
//!   without; others `error:3`.
//! - Travel ([`travel`]): end stops where [`CutterOptions::travel_mm`] puts them (a move past one
//!   is recorded, [`EndStopHit`]), `$130`–`$132` from it, homing (`$22`, booting in alarm) and
//!   GRBL's soft limits (`$20=1`: a target outside −`$13x`..0 is `ALARM:2` before anything
//!   moves, then only a reset is heard), and the G54 work offset applied to absolute targets.
//! - Motion ([`motion`]): each move at its programmed feed (travels at `$110`), no acceleration;
//!   G4 waits for the queue to empty, then dwells as a block (real GRBL answers `ok` only after
//!   the dwell). M2/M30 wait for the queue to empty, then reset the modal state (M5, G90) and say
//!   `[MSG:Pgm End]` before their `ok`.
//! - The laser: with laser mode (`$32=1`) it fires only during G1/G2/G3 (M3 or M4, at `S`; M4's
//!   scaling by speed is not modelled since the feed is constant), never on G0, and it is off
//!   during a completed feed hold. At rest it is off under M4 or after a G0, but under M3 after
//!   a G1/G2/G3 it stays on at `S` until M5, as GRBL's constant-power mode does (a program that
//!   ends without M5 leaves a stationary beam burning). Without laser mode it is a spindle: on from M3
//!   or M4 with S > 0 until M5, travels included (each such travel is a [`TravelFiring`]).
//! - Status reports: `<State|MPos:x,y,z|Bf:blocks,bytes|FS:feed,S>`, the states Idle, Run,
//!   Hold:1 (decelerating at `$120` along the path), Hold:0, Alarm.
//! - Feed hold, resume and soft reset. A reset during motion (running, or a hold still
//!   decelerating) raises `ALARM:3` as GRBL does: the position may be lost. A reset at a
//!   completed hold or at rest keeps the position. Every reset turns the laser off, empties the
//!   queue and the buffer (bytes sent with the reset, after it, are lost, realtime ones too, as GRBL
//!   re-initialising loses them), prints the banner, and keeps an alarm until `$X`.
//! - Injected faults ([`CutterOptions`]): boot in alarm (as a machine with homing enabled), a
//!   hard limit after some motion time (`ALARM:1`, then nothing but a reset is heard, not even
//!   `?`, as in GRBL's code), an `error:N` for the Nth G-code line, and a soft-limit alarm at
//!   the Nth line run whose `ALARM:2` line is lost (only the status reports show it).
//!
//! Everything it did is recorded in its [`CutterLog`] ([`trace`]). What it cuts is what its laser
//! traced, with the kerf, spread and repeatability of [`CutterOptions::kerf`] (the one kerf
//! model, [`kerfmeter_twin::plant::Cutter`]): a gauge it cut is recovered from the trace and
//! measured by the device twin ([`kerfmeter_twin::gauge_trace`],
//! [`kerfmeter_twin::Twin::place_traced_gauge_cut_by`]).

pub mod gcode;
pub mod motion;
pub mod serve;
pub mod trace;
pub mod travel;

mod machine;
mod options;
mod system;

pub use machine::Grbl;
pub use options::CutterOptions;
pub use serve::{CutterServer, ServeError};
pub use trace::{
    CutterLog, CutterRecord, EndStopHit, ProtocolViolation, Segment, SegmentKind, TravelFiring,
};

/// GRBL's facts the twin emulates, from the one table: its receive buffer, planner blocks,
/// version and the soft-reset character.
pub use kerfmeter_grbl::realtime::SOFT_RESET;
pub use kerfmeter_grbl::{PLANNER_BLOCKS, RX_BUFFER_LEN, VERSION};
