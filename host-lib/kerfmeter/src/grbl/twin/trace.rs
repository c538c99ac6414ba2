//! What the cutter twin did, shared with whoever serves it: every move it executed with the
//! laser's power and feed (the geometry the laser traced, for the twin that "cuts" later), every
//! moment the laser fired during a travel move (a safety violation: tests assert there is none),
//! every travel that only laser mode kept dark (the beam left switched on for it: a sender that
//! relies on `$32=1`, which would fire on a controller without it; tests assert none either),
//! every breach of the serial protocol by the sender (bytes lost to a full receive buffer), every
//! move that left the machine's travel, every G-code line received, and the machine's state and
//! laser output now. Cloning a [`CutterLog`] shares it.

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

/// What the laser traced is in the device twin's vocabulary, which measures the gauge it cut.
pub use kerfmeter_twin::traced::{Point, Segment, SegmentKind};

/// A travel move made with the laser switched on: where, and at what power. In
/// [`CutterRecord::travel_firings`] the laser fired through it; in
/// [`CutterRecord::blanked_travels`] laser mode kept it dark.
#[derive(Debug, Clone, PartialEq)]
pub struct TravelFiring {
    /// Simulated time when the travel started, µs.
    pub at_us: u64,
    /// The travel's start, mm.
    pub start: Point,
    /// The travel's target, mm.
    pub end: Point,
    /// The power the laser was switched on with (`S`).
    pub power_s: f64,
}

/// A move whose path left the machine's travel: on a real machine the head runs into its end
/// stop (see [`super::travel`]).
#[derive(Debug, Clone, PartialEq)]
pub struct EndStopHit {
    /// Simulated time when the move started, µs.
    pub at_us: u64,
    /// The received G-code line it came from.
    pub line: u32,
    /// The move's start, mm (machine coordinates).
    pub start: Point,
    /// The move's target, mm (machine coordinates).
    pub end: Point,
    /// The first axis it leaves the travel on (0 X, 1 Y, 2 Z).
    pub axis: usize,
    /// How far past the end stop it goes, mm.
    pub beyond_mm: f64,
}

/// A breach of GRBL's serial protocol by the sender.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProtocolViolation {
    /// Bytes arrived while the 128-byte receive buffer was full; they were lost.
    RxOverflow {
        /// Simulated time, µs.
        at_us: u64,
        /// Bytes lost.
        lost_bytes: usize,
    },
}

/// Everything recorded (see the [module docs](self)).
#[derive(Debug, Clone, Default)]
pub struct CutterRecord {
    /// Executed moves, in order.
    pub segments: Vec<Segment>,
    /// Travels during which the laser fired.
    pub travel_firings: Vec<TravelFiring>,
    /// Travels made with the beam switched on (`M3`/`M4` and `S` above 0, the `power_s` here)
    /// that only laser mode (`$32=1`) kept dark. GRBL does blank them, but a program that relies
    /// on it fires through every travel on a controller whose setting was changed.
    pub blanked_travels: Vec<TravelFiring>,
    /// The sender's protocol breaches.
    pub violations: Vec<ProtocolViolation>,
    /// Moves that ran into an end stop (soft limits off, or set wider than the machine).
    pub end_stop_hits: Vec<EndStopHit>,
    /// Every G-code line received (not `$` commands), as received, check passes included.
    pub gcode_received: Vec<String>,
    /// The laser's power now (0 when off).
    pub laser_power_s: f64,
    /// The state as a status report names it (`Idle`, `Run`, `Hold:0`, `Alarm`, ...).
    pub state: String,
    /// Alarms raised since boot (GRBL's `ALARM:N` codes).
    pub alarms: Vec<u8>,
    /// Soft resets received.
    pub resets: u32,
}

/// The shared record of a cutter twin.
#[derive(Debug, Clone, Default)]
pub struct CutterLog(Arc<Mutex<CutterRecord>>);

impl CutterLog {
    /// Lock the record (to read it, or for the twin to write it).
    pub fn lock(&self) -> MutexGuard<'_, CutterRecord> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A copy of the record now.
    pub fn snapshot(&self) -> CutterRecord {
        self.lock().clone()
    }
}
