//! GRBL 1.1's facts, written once: what Kerfmeter knows about the controller, read by the GRBL
//! driver (`kerfmeter::grbl`), by the G-code writer (`kerfmeter_plan::gcode`) and by the
//! simulated cutter (`kerfmeter::grbl::twin`, the `sim` feature), so that the three cannot
//! disagree about a buffer size, a line limit, a code or a setting's number.
//!
//! - This module: the receive buffer ([`RX_BUFFER_LEN`]), the line limit ([`LINE_MAX_LEN`]),
//!   the planner's blocks, the version the twin reports, the banner, the reply prefixes and the
//!   realtime characters ([`realtime`]), and the header comment by which a program declares the
//!   `S` of full power it assumes ([`S_MAX_TAG`]).
//! - [`codes`]: every `error:N` and `ALARM:N` GRBL 1.1 sends, by name, each with its meaning
//!   as a sentence for the person at the cutter.
//! - [`settings`]: the numbers of the `$N` settings this project reads or sets, and the values a
//!   stock GRBL 1.1 reports.
//! - [`status`]: the status report (`<Idle|MPos:0.000,0.000,0.000|Bf:15,128|FS:0,0>`): its
//!   states and fields, read and written.
//!
//! # Why a crate of its own
//!
//! The table is needed by three crates that must not depend on each other: the plan crate knows
//! nothing of serial ports (it must not depend on the `kerfmeter` library), the library must not
//! depend on the plan crate (its users embed it without SVG/DXF code), and the cutter twin sits
//! in the library behind `sim`. A crate below all three, plain `std` Rust with no dependencies,
//! is the one place each can reach without a cycle and without pulling anything else in. It
//! holds facts and the small pure functions that read and write GRBL's text (replies, status
//! reports); the driver, the writer and the twin keep their behaviour.

pub mod codes;
pub mod settings;
pub mod status;

/// GRBL's serial receive buffer, bytes: a sender may have at most this many unacknowledged.
pub const RX_BUFFER_LEN: usize = 128;

/// The longest line GRBL 1.1 takes, without spaces and comments: its line buffer is 80 bytes
/// and one is kept for the terminator, so 79 characters; longer lines are refused
/// (`error:11`, [`codes::LINE_OVERFLOW`]).
pub const LINE_MAX_LEN: usize = 79;

/// Blocks GRBL's planner queue holds (its 16-slot ring keeps one free).
pub const PLANNER_BLOCKS: usize = 15;

/// The GRBL version the cutter twin reports in its banner and `$I`.
pub const VERSION: &str = "1.1h";

/// What a banner starts with: `Grbl 1.1h ['$' for help]` (FluidNC's says `Grbl 3.x [FluidNC
/// ...]`).
pub const BANNER_PREFIX: &str = "Grbl ";

/// What grblHAL's banner starts with.
pub const GRBLHAL_BANNER_PREFIX: &str = "GrblHAL ";

/// GRBL's banner for `version`, as it prints it after a (re)start.
pub fn banner(version: &str) -> String {
    format!("{BANNER_PREFIX}{version} ['$' for help]")
}

/// The reply that accepts a line.
pub const OK: &str = "ok";
/// What a refused line's reply starts with (`error:N`).
pub const ERROR_PREFIX: &str = "error:";
/// What an alarm's line starts with (`ALARM:N`).
pub const ALARM_PREFIX: &str = "ALARM:";
/// What a `[MSG:...]` feedback message starts with.
pub const MESSAGE_PREFIX: &str = "[MSG:";
/// What the `$I` build-options line starts with: `[OPT:V,15,128]` (options, planner blocks,
/// receive-buffer bytes).
pub const BUILD_OPTIONS_PREFIX: &str = "[OPT:";

/// The realtime commands: single characters GRBL acts on as they arrive, wherever they appear
/// (even inside a comment), without entering the receive buffer.
pub mod realtime {
    /// `?`: a status report.
    pub const STATUS_REPORT: u8 = b'?';
    /// `!`: feed hold.
    pub const FEED_HOLD: u8 = b'!';
    /// `~`: cycle start (resume after a hold).
    pub const CYCLE_START: u8 = b'~';
    /// Ctrl-X: soft reset.
    pub const SOFT_RESET: u8 = 0x18;

    /// The printable realtime characters, which no program line may carry.
    pub const PRINTABLE: [char; 3] = ['?', '!', '~'];
}

/// The `$` commands this project sends or answers.
pub mod commands {
    /// `$$`: the settings.
    pub const SETTINGS: &str = "$$";
    /// `$X`: leave the alarm state.
    pub const UNLOCK: &str = "$X";
    /// `$H`: home.
    pub const HOME: &str = "$H";
    /// `$G`: the parser state.
    pub const PARSER_STATE: &str = "$G";
    /// `$I`: the build info.
    pub const BUILD_INFO: &str = "$I";
    /// `$#`: the work offsets.
    pub const PARAMETERS: &str = "$#";
    /// `$C`: check mode on, or (again) off with a soft reset.
    pub const CHECK_MODE: &str = "$C";
}

/// The comment by which a program declares the `S` of full power (GRBL's `$30`,
/// [`settings::MAX_POWER_S`]) its powers assume: `(S_MAX=1000 must equal GRBL setting 30)`.
/// Kerfmeter's G-code writer writes it, and its driver refuses a program whose value differs
/// from the controller's `$30`.
pub const S_MAX_TAG: &str = "S_MAX=";
