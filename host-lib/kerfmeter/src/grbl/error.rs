//! Why a cutter operation failed, each with a message that says what to do.

use crate::error::Category;

use super::codes::{describe_alarm, describe_error};
use super::travel::Beyond;

/// What went wrong with the cutter.
#[derive(Debug, thiserror::Error)]
pub enum CutterError {
    /// The cutter's address is not one this program understands.
    #[error(
        "cannot understand the cutter address {0:?}: use grbl:/dev/ttyUSB0[?baud=N], grbl+tcp://HOST:PORT, sim, ruida:HOST?z-mm=MIN,MAX or ruida-sim"
    )]
    BadAddress(String),
    /// The serial port or TCP connection could not be opened.
    #[error("cannot connect to the cutter at {address}: {reason}")]
    Open {
        /// The address.
        address: String,
        /// Why.
        reason: String,
    },
    /// The connection failed while in use.
    #[error("lost the connection to the cutter at {address}: {source}")]
    Io {
        /// The address.
        address: String,
        /// The I/O error.
        source: std::io::Error,
    },
    /// No GRBL banner came, even after a soft reset.
    #[error(
        "no GRBL 1.1 banner from {address} within {waited_ms} ms, even after a soft reset; {}. Check the address, the baud rate and that the controller runs GRBL 1.1",
        describe_seen(seen)
    )]
    NoBanner {
        /// The address.
        address: String,
        /// How long it waited, ms.
        waited_ms: u64,
        /// The lines that did come.
        seen: Vec<String>,
    },
    /// The controller stopped answering.
    #[error("the cutter at {address} did not answer for {waited_ms} ms while {doing}")]
    Silent {
        /// The address.
        address: String,
        /// How long, ms.
        waited_ms: u64,
        /// What the driver was waiting for.
        doing: &'static str,
    },
    /// The banner names a GRBL older than 1.1, whose protocol differs.
    #[error(
        "the controller runs GRBL {version}; this program speaks GRBL 1.1 (status reports, realtime commands and laser mode differ before it): update its firmware"
    )]
    OldVersion {
        /// The version in its banner.
        version: String,
    },
    /// The controller is in alarm and was not to be unlocked.
    #[error(
        "the cutter is in alarm{}: {reason}. Check the machine, then home it or unlock it (`--unlock` sends $X)",
        code.map(|c| format!(" (ALARM:{c})")).unwrap_or_default()
    )]
    AlarmAtConnect {
        /// The alarm code, when it said one.
        code: Option<u8>,
        /// What the controller said about it.
        reason: String,
    },
    /// The controller is not idle after connecting (door open, holding, running).
    #[error(
        "the cutter is not idle but {state}; make it idle (close the door, finish or stop its job) and try again"
    )]
    NotIdle {
        /// Its state.
        state: String,
    },
    /// Laser mode (`$32=1`) is off: GRBL would keep the beam on through travel moves.
    #[error(
        "the controller is not in laser mode ($32={value}): it would keep the laser on during travel moves. If it drives a laser, send it `$32=1` (from a serial terminal or your sender's console: GRBL keeps it in its EEPROM) and try again; for a spindle machine only, `kerfmeter cut --allow-without-laser-mode` skips this check. Nothing was sent"
    )]
    LaserModeOff {
        /// `$32` as read (`?` when absent).
        value: String,
    },
    /// The program's powers assume another `S` of full power than the controller's `$30`.
    #[error(
        "the program was written for S max {program} but the controller's $30 is {controller}: its powers would be wrong (on $30=255, 25 % would fire at 98 %). Write the G-code again with --s-max {controller}, or set $30={program}. Nothing was sent"
    )]
    SMaxMismatch {
        /// The `S` of full power the program declares.
        program: f64,
        /// `$30` as read (`?` when absent).
        controller: String,
    },
    /// A program line would take the head beyond the machine's travel (or the head stands
    /// outside it as read); nothing was sent.
    #[error("{}. Nothing was sent. {}", beyond_what(beyond), beyond_fix(beyond))]
    BeyondTravel {
        /// Where, and the travel it passes.
        beyond: Box<Beyond>,
    },
    /// A program line whose moves cannot be bounded; nothing was sent.
    #[error(
        "line {line} (`{written}`) {reason}; the program's moves cannot be checked against the machine's travel, so it is refused. Nothing was sent"
    )]
    Unbounded {
        /// Its line number in the file.
        line: usize,
        /// The line as written in the file.
        written: String,
        /// Why it cannot be bounded.
        reason: String,
    },
    /// The program has a line that cannot be streamed; nothing was sent.
    #[error("line {line} of the program cannot be sent: {reason}. Nothing was sent")]
    BadProgram {
        /// Its line number in the file.
        line: usize,
        /// Why.
        reason: String,
    },
    /// The controller refused a line.
    #[error(
        "the cutter refused line {line} (`{text}`) with error:{code}: {}",
        describe_error(*code)
    )]
    Rejected {
        /// Its line number in the file.
        line: usize,
        /// The line as written in the file.
        text: String,
        /// The `error:N` code.
        code: u8,
    },
    /// The check pass (`$C`) found a line the controller refuses; nothing moved.
    #[error(
        "the cutter's check pass ($C) refused line {line} (`{text}`) with error:{code}: {}. Nothing was cut",
        describe_error(*code)
    )]
    CheckRejected {
        /// Its line number in the file.
        line: usize,
        /// The line as written in the file.
        text: String,
        /// The `error:N` code.
        code: u8,
    },
    /// The machine stayed held (feed hold, door open) longer than the hold timeout.
    #[error(
        "the cutter stayed held ({state}) for {waited_ms} ms: nobody pressed cycle start, so the job was given up"
    )]
    HeldTooLong {
        /// Its state.
        state: String,
        /// The hold timeout, ms.
        waited_ms: u64,
    },
    /// The controller raised an alarm during the job.
    #[error(
        "the cutter raised ALARM:{code} during the job: {}. {}{}",
        describe_alarm(*code),
        after.as_ref().map(|(n, t)| format!("The last line it had accepted was line {n} (`{t}`)")).unwrap_or_else(|| "It had accepted no line yet".into()),
        last_position_mm.map(|[x, y, z]| format!(" (lines are accepted ahead of the motion; the last status report before the alarm had the head at X{x:.2} Y{y:.2} Z{z:.2} mm)")).unwrap_or_default()
    )]
    Alarm {
        /// The alarm code.
        code: u8,
        /// The last line accepted before it: file line number and text.
        after: Option<(usize, String)>,
        /// Where the last status report before it had the head, mm (machine position).
        last_position_mm: Option<[f64; 3]>,
    },
    /// The controller reported a state that ends any job (alarm, sleep) during it, with no
    /// `ALARM:N` line before (a controller that reports its alarm only by its state).
    #[error(
        "the cutter reported {state} during the job, without an alarm message; it runs no more of it. {}",
        after.as_ref().map(|(n, t)| format!("The last line it had accepted was line {n} (`{t}`)")).unwrap_or_else(|| "It had accepted no line yet".into())
    )]
    StoppedItself {
        /// The state it reported.
        state: String,
        /// The last line accepted before it: file line number and text.
        after: Option<(usize, String)>,
    },
    /// The controller restarted during the job.
    #[error(
        "the cutter restarted during the job (its banner came again); the job is lost. Check its power and cable"
    )]
    Restarted,
    /// The job was cancelled (Ctrl-C, a termination signal).
    #[error("cancelled after {answered} of {total} lines")]
    Cancelled {
        /// Lines the controller had accepted.
        answered: usize,
        /// Lines in the program.
        total: usize,
    },
    /// The controller said something the protocol does not allow here.
    #[error("the cutter broke the GRBL protocol: {0}")]
    Protocol(String),
    /// Cancelled (Ctrl-C, a termination signal) while connecting, before any program line was
    /// sent.
    #[error("cancelled while connecting to the cutter at {address}; no program line was sent")]
    ConnectCancelled {
        /// The address.
        address: String,
    },
    /// The program ran, but the controller does not confirm the laser off at its end.
    #[error("the job ran, but the cutter does not confirm the laser off afterwards ({said})")]
    LaserNotOff {
        /// What it said instead (its `$G` parser state or its status report).
        said: String,
    },
    /// A numbered error or alarm from a controller that is not GRBL itself (grblHAL, FluidNC):
    /// the meaning given is GRBL 1.1's, which it may not share (grblHAL's `ALARM:10` is its
    /// E-stop, not a failed homing).
    #[error(
        "{error} [the meaning given is GRBL 1.1's; {flavour} may number its codes otherwise: check its documentation]"
    )]
    OtherFlavour {
        /// The controller's firmware (`grblHAL`, `FluidNC`).
        flavour: &'static str,
        /// The error with the code.
        error: Box<CutterError>,
    },
    /// A failure, after which the cutter was stopped (feed hold, soft reset): the laser is off.
    #[error(
        "{cause}. The cutter was stopped and the laser is off{}",
        if *position_lost { "; the reset came while it moved (ALARM:3): its position may be lost, home it before the next job" } else { "" }
    )]
    Stopped {
        /// The failure.
        cause: Box<CutterError>,
        /// The reset raised `ALARM:3`: it came while the machine still moved.
        position_lost: bool,
    },
    /// A failure, and then the cutter could not be stopped: the most dangerous outcome.
    #[error(
        "THE LASER MAY STILL BE ON: switch it off at the machine now. {cause}; then the cutter could not be stopped ({stop})"
    )]
    NotStopped {
        /// The first failure.
        cause: Box<CutterError>,
        /// Why stopping failed.
        stop: Box<CutterError>,
    },
    /// The simulated cutter could not be started.
    #[error("cannot start the simulated cutter: {0}")]
    Sim(String),
    /// A Ruida controller's failure ([`crate::ruida`]).
    #[error(transparent)]
    Ruida(Box<crate::ruida::RuidaFailure>),
}

impl CutterError {
    /// What kind of failure this is (the command-line tool's exit code follows from it).
    pub fn category(&self) -> Category {
        match self {
            Self::BadAddress(_) | Self::BadProgram { .. } => Category::Usage,
            Self::Open { .. }
            | Self::Io { .. }
            | Self::NoBanner { .. }
            | Self::Silent { .. }
            | Self::Protocol(_)
            | Self::Restarted
            | Self::Sim(_) => Category::Communication,
            Self::AlarmAtConnect { .. }
            | Self::OldVersion { .. }
            | Self::NotIdle { .. }
            | Self::LaserModeOff { .. }
            | Self::SMaxMismatch { .. }
            | Self::BeyondTravel { .. }
            | Self::Unbounded { .. }
            | Self::Rejected { .. }
            | Self::CheckRejected { .. }
            | Self::HeldTooLong { .. }
            | Self::Alarm { .. }
            | Self::StoppedItself { .. }
            | Self::Cancelled { .. }
            | Self::ConnectCancelled { .. }
            | Self::LaserNotOff { .. }
            | Self::NotStopped { .. } => Category::Device,
            Self::Stopped { cause, .. } => cause.category(),
            Self::OtherFlavour { error, .. } => error.category(),
            Self::Ruida(failure) => failure.category(),
        }
    }

    /// True when the message gives the meaning of a controller's numbered code.
    pub(super) fn has_code(&self) -> bool {
        matches!(
            self,
            Self::Rejected { .. }
                | Self::CheckRejected { .. }
                | Self::Alarm { .. }
                | Self::AlarmAtConnect { code: Some(_), .. }
        )
    }

    /// True when the cutter could not be stopped after a failure: its laser may still be on
    /// (the command-line tool gives this its own exit code).
    pub fn laser_may_be_on(&self) -> bool {
        matches!(self, Self::NotStopped { .. })
    }

    /// True when this error already tells how the stop after the failure went
    /// ([`CutterError::Stopped`], [`CutterError::NotStopped`]): a stream's failures once it
    /// began sending do; its refusals before sending (a line that cannot be streamed, another
    /// `S` max), a status read's and a connection's failures do not, and leave any stopping to
    /// the caller.
    pub fn stop_was_tried(&self) -> bool {
        match self {
            Self::Stopped { .. } | Self::NotStopped { .. } => true,
            Self::OtherFlavour { error, .. } => error.stop_was_tried(),
            _ => false,
        }
    }

    /// The first failure, without the stop that followed it ([`CutterError::Stopped`],
    /// [`CutterError::NotStopped`]).
    pub fn cause(&self) -> &CutterError {
        match self {
            Self::Stopped { cause, .. } | Self::NotStopped { cause, .. } => cause.cause(),
            Self::OtherFlavour { error, .. } => error.cause(),
            other => other,
        }
    }
}

/// Which line takes the head beyond the travel, and where.
fn beyond_what(beyond: &Beyond) -> String {
    match &beyond.at.line {
        Some((number, written)) => {
            format!("line {number} (`{written}`) takes the head to {beyond}")
        }
        None if beyond.is_head() => format!(
            "the head stands at {beyond}: where the controller puts it does not fit its travel as \
             read"
        ),
        None => format!("the program takes the head to {beyond}"),
    }
}

/// What to change.
fn beyond_fix(beyond: &Beyond) -> String {
    let setting = super::travel::TRAVEL_SETTINGS[beyond.axis];
    if beyond.source == super::travel::TravelSource::Ruida {
        return format!(
            "Place the program inside the travel (`kerfmeter gcode` and `kerfmeter job` place a \
             plan with --origin-mm X,Y); if the machine's travel is larger, {}",
            beyond.change_setting()
        );
    }
    if beyond.is_head() {
        return format!(
            "Home the machine, or switch the controller on with the head at its origin corner; \
             if the machine's travel is not ${setting}, set it"
        );
    }
    format!(
        "Place the program inside the travel (`kerfmeter gcode` and `kerfmeter job` place a plan \
         with --origin-mm X,Y), or set ${setting} to the machine's real travel if it is larger"
    )
}

/// "nothing came" or the first lines that did.
fn describe_seen(seen: &[String]) -> String {
    if seen.is_empty() {
        return "nothing came".into();
    }
    let shown: Vec<&str> = seen.iter().take(3).map(String::as_str).collect();
    format!("it said {:?}", shown.join(" | "))
}
