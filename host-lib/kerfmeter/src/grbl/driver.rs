//! The blocking GRBL driver: connect (banner, alarm, laser mode), stream a program with
//! character counting, wait for the motion to end, and stop the cutter on every failure.
//!
//! - this module: [`Cutter`], its options, and what a stream reports;
//! - `connect`: opening a port, the banner, the handshake and the refusals at connect;
//! - `lines`: the byte stream as lines, commands and their answers, status reports;
//! - `stream`: a program streamed with character counting, its holds and alarms;
//! - `check`: the check pass (`$C`) and the laser-off confirmation; `stop`: the stop;
//!   `travel`: the machine's travel, work offsets and parser state.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use kerfmeter_grbl::realtime::{self, SOFT_RESET};

use super::protocol::{Status, Streamer};
use super::transport::Link;
use super::travel::Travel;

mod check;
mod connect;
mod lines;
mod stop;
mod stream;
mod travel;

/// While a controller talks without its banner yet (a boot log), the banner is waited for
/// until it has been quiet this long...
const BOOT_LOG_QUIET: Duration = Duration::from_millis(500);
/// ...but no longer than this past the usual wait.
const BOOT_LOG_MAX: Duration = Duration::from_secs(15);
/// A command's answer is waited for while it comes, up to this many reply timeouts.
const COMMAND_WAIT_MAX_REPLIES: u32 = 10;
/// Alarm and message lines kept for a later error.
const NOTES_KEPT: usize = 32;
/// The most bytes kept without a line end (GRBL's longest line is far shorter).
const INCOMING_MAX: usize = 4096;
/// How many unrecognised lines a failed connection reports.
const SEEN_KEPT: usize = 8;
/// The line every program is closed with: laser off. Under M3 GRBL keeps the beam on at rest
/// after a cut, so a program that does not end with M5 would leave it burning one spot.
const CLOSING_LINE: &str = "M5";

/// How the driver connects and streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConnectOptions {
    /// Unlock (`$X`) a controller that is in alarm, instead of refusing it.
    pub unlock: bool,
    /// Accept a controller without laser mode (`$32=0`): only for a spindle machine, since GRBL
    /// then keeps the beam on during travel moves.
    pub allow_without_laser_mode: bool,
    /// How long to wait for the banner before waking the controller with a soft reset (a board
    /// that resets when its port opens needs about 2 s to boot).
    pub banner_wait: Duration,
    /// How long to wait for an answer to a command, a status request or a reset.
    pub reply_timeout: Duration,
    /// How often the state is polled (`?`) while streaming.
    pub poll_interval: Duration,
    /// How long the controller may say nothing at all while streaming before it is given up.
    pub silence_timeout: Duration,
    /// Run the whole program through GRBL's check mode (`$C`) before cutting it, so that a line
    /// it refuses is found before anything moves (see [`Cutter::stream`]).
    pub check_first: bool,
    /// Give up a job (stopping the cutter) once the machine has been held (feed hold, door
    /// open) this long; `None`: wait for cycle start or a cancel, however long.
    pub hold_timeout: Option<Duration>,
}

impl Default for ConnectOptions {
    fn default() -> Self {
        Self {
            unlock: false,
            allow_without_laser_mode: false,
            banner_wait: Duration::from_millis(2500),
            reply_timeout: Duration::from_secs(2),
            poll_interval: Duration::from_millis(200),
            silence_timeout: Duration::from_secs(5),
            check_first: true,
            hold_timeout: None,
        }
    }
}

/// Where a stream is, for a progress display.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamProgress {
    /// Lines the controller has answered.
    pub answered: usize,
    /// Lines in the program.
    pub total: usize,
    /// Bytes sent and not yet answered (never more than 128).
    pub unanswered_bytes: usize,
    /// The last status report.
    pub status: Option<Status>,
    /// True during the check pass (`$C`: answered, nothing moves), false while cutting.
    pub checking: bool,
}

impl StreamProgress {
    fn of(streamer: &Streamer, status: Option<Status>, checking: bool) -> Self {
        Self {
            answered: streamer.answered(),
            total: streamer.total(),
            unanswered_bytes: streamer.unanswered_bytes(),
            status,
            checking,
        }
    }
}

/// How a stream went.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamReport {
    /// Lines streamed.
    pub lines: usize,
    /// From the first line sent until the machine was idle again.
    pub elapsed: Duration,
    /// The most bytes that were unanswered at once.
    pub max_unanswered_bytes: usize,
    /// Where the machine ended, mm (when it reports its machine position).
    pub position_mm: Option<[f64; 3]>,
}

/// A connected GRBL 1.1 controller.
pub struct Cutter {
    link: Box<dyn Link>,
    address: String,
    incoming: Vec<u8>,
    options: ConnectOptions,
    version: String,
    settings: BTreeMap<u16, f64>,
    notes: Vec<String>,
    in_job: bool,
    /// Bytes that may be unanswered at once (GRBL's 128, or less for a smaller buffer).
    window: usize,
    /// The firmware, when its banner names one other than GRBL (`grblHAL`, `FluidNC`).
    flavour: Option<&'static str>,
    /// The alarm that came just before the last banner (`ALARM:3` after a reset in motion).
    alarm_before_banner: Option<u8>,
    /// The machine's travel, when the controller reports one (`$130`–`$132`).
    travel: Option<Travel>,
    /// Set from outside (Ctrl-C): ends a connect early.
    cancel: Arc<AtomicBool>,
    /// True while connecting: `cancel` is heard.
    connecting: bool,
    #[cfg(feature = "sim")]
    pub(super) sim: Option<super::twin::CutterServer>,
}

impl std::fmt::Debug for Cutter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cutter")
            .field("address", &self.address)
            .field("version", &self.version)
            .finish_non_exhaustive()
    }
}

impl Cutter {
    /// The address it was opened at.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// GRBL's version from the banner (`1.1h`).
    pub fn version(&self) -> &str {
        &self.version
    }

    /// The controller's settings (`$$`) as read at connect.
    pub fn settings(&self) -> &BTreeMap<u16, f64> {
        &self.settings
    }

    /// The firmware named in the banner: `GRBL` unless it is another (`grblHAL`, `FluidNC`).
    pub fn flavour(&self) -> &'static str {
        self.flavour.unwrap_or("GRBL")
    }
}

impl Drop for Cutter {
    /// Dropped in the middle of a job (a panic unwinding): stop the cutter, best effort.
    fn drop(&mut self) {
        if self.in_job {
            let _ = self.link.write_all(&[realtime::FEED_HOLD, SOFT_RESET]);
            let _ = self.link.flush();
        }
    }
}
