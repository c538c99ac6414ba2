//! Host-side errors: every failure a caller can meet, each with a message that says what to do.

use kerfmeter_protocol::advice::{Advice, Advised};
use kerfmeter_protocol::{
    Conditions, ErrorCode, Fault, ProtocolVersion, REFERENCE_SUPPLY_V, SUPPLY_MAX_V, SUPPLY_MIN_V,
};

/// Result of every fallible call of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What went wrong.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The serial port could not be opened.
    #[error(
        "cannot open serial port {path}: {source}. Check the path and that no other program (a serial monitor?) holds the port"
    )]
    Open {
        /// The port's path.
        path: String,
        /// Why.
        source: serialport::Error,
    },
    /// The port disappeared while in use (device unplugged, twin stopped).
    #[error("serial port {path} went away ({source}); is the device still plugged in?")]
    PortVanished {
        /// The port's path.
        path: String,
        /// The I/O error that revealed it.
        source: std::io::Error,
    },
    /// Any other I/O error on the port.
    #[error("I/O error on serial port {path}: {source}")]
    Io {
        /// The port's path.
        path: String,
        /// The error.
        source: std::io::Error,
    },
    /// The device did not answer in time, even after retries.
    #[error(
        "no answer from the device on {path} to {request} ({attempts} attempts, {timeout_ms} ms each). Check that it is powered and runs Kerfmeter firmware"
    )]
    Timeout {
        /// The port's path.
        path: String,
        /// The request that went unanswered.
        request: &'static str,
        /// Attempts made.
        attempts: u32,
        /// Timeout of each attempt, ms.
        timeout_ms: u64,
    },
    /// Host and device speak incompatible protocol versions.
    #[error("the device speaks protocol {}.{}, this program speaks {}.{}: update the firmware (`cargo xtask flash`) or this program", device.major, device.minor, host.major, host.minor)]
    ProtocolMismatch {
        /// The device's version.
        device: ProtocolVersion,
        /// This crate's version.
        host: ProtocolVersion,
    },
    /// The device refused the request.
    #[error("the device refused {request}: {}", describe_error_code(*code))]
    Device {
        /// The refused request.
        request: &'static str,
        /// Its typed reason.
        code: ErrorCode,
    },
    /// The device answered with a response that does not fit the request.
    #[error(
        "the device answered {request} with an unexpected {response}; is this Kerfmeter firmware?"
    )]
    UnexpectedResponse {
        /// The request.
        request: &'static str,
        /// What came back.
        response: &'static str,
    },
    /// The device restarted since it was opened.
    #[error(
        "the device restarted (boot id {old:08x} is now {new:08x}): any run in progress and its result are lost; check its power supply and start again"
    )]
    DeviceReset {
        /// Boot id seen when the port was opened.
        old: u32,
        /// Boot id now.
        new: u32,
    },
    /// The device stopped a run (or reset, or self-test) on a fault, and latched it.
    #[error("the device stopped: {} Fix the cause, then {} and {}", sentence(describe_fault(*fault)), Advice::ClearFault, Advice::Reset)]
    Fault {
        /// The latched fault.
        fault: Fault,
    },
    /// The run ended without a result: aborted by another program, or the device was reset.
    #[error(
        "the run ended without a result (aborted from elsewhere, or the device was reset); start it again"
    )]
    RunInterrupted,
    /// The caller stopped the run (Ctrl-C); the device was told to abort, its motor is safe.
    #[error("the run was stopped on request; the device aborted it and its motor is stopped")]
    Cancelled,
    /// The device did not finish in time.
    #[error("the device did not finish within {seconds} s; it was told to abort")]
    RunTimeout {
        /// The time allowed.
        seconds: u64,
    },
    /// `discover` found no device, or more than one.
    #[error("{0}")]
    Discover(String),
    /// The `--sim` twin could not be started.
    #[error("cannot start the simulated device: {0}")]
    Sim(String),
    /// A bad argument or parameter; the message names it and its allowed range.
    #[error("{0}")]
    InvalidArgument(Advised),
    /// A file could not be read, parsed or written.
    #[error("{}: {message}", path.display())]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// What went wrong.
        message: String,
    },
}

impl Error {
    /// A bad argument or parameter, `message` naming it and its allowed range.
    pub fn invalid(message: impl Into<Advised>) -> Self {
        Error::InvalidArgument(message.into())
    }

    /// The advice this error gives, as data: what its message tells the reader to do next.
    pub fn advice(&self) -> Vec<Advice> {
        match self {
            Error::InvalidArgument(m) => m.advice().collect(),
            Error::Fault { .. } => vec![Advice::ClearFault, Advice::Reset],
            Error::Device { code, .. } => code_advice(*code),
            _ => Vec::new(),
        }
    }

    /// The device fault behind this error, if the device refused because of a latched fault.
    pub fn fault(&self) -> Option<Fault> {
        match self {
            Error::Device {
                code: ErrorCode::Faulted(f),
                ..
            }
            | Error::Fault { fault: f } => Some(*f),
            _ => None,
        }
    }

    /// The idle conditions that refused the request (`ErrorCode::Blocked`); empty otherwise.
    pub fn blocking_conditions(&self) -> Conditions {
        match self {
            Error::Device {
                code: ErrorCode::Blocked(c),
                ..
            } => *c,
            _ => Conditions::empty(),
        }
    }

    /// What kind of failure this is (the command-line tool's exit code follows from it).
    pub fn category(&self) -> Category {
        match self {
            Error::Open { .. }
            | Error::PortVanished { .. }
            | Error::Io { .. }
            | Error::Timeout { .. }
            | Error::ProtocolMismatch { .. }
            | Error::UnexpectedResponse { .. }
            | Error::DeviceReset { .. }
            | Error::Discover(_)
            | Error::Sim(_) => Category::Communication,
            Error::Device { .. }
            | Error::Fault { .. }
            | Error::RunInterrupted
            | Error::Cancelled
            | Error::RunTimeout { .. } => Category::Device,
            Error::InvalidArgument(_) => Category::Usage,
            Error::File { .. } => Category::File,
        }
    }

    /// True for errors of the link itself (port, timeout, protocol), as opposed to the device
    /// refusing or failing a request.
    pub fn is_communication(&self) -> bool {
        self.category() == Category::Communication
    }
}

/// The kinds of failure, coarse enough for a script to act on (see [`Error::category`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Category {
    /// A bad argument or parameter: change the command.
    Usage,
    /// The link to the device: the port, a timeout, the protocol, a restarted device.
    Communication,
    /// The device refused, faulted or could not finish.
    Device,
    /// A file could not be read, parsed or written.
    File,
}

/// The advice of [`describe_error_code`]'s sentence for `code`, in its order.
fn code_advice(code: ErrorCode) -> Vec<Advice> {
    advised_error_code(code).advice().collect()
}

/// A sentence for a device error code, saying what to do about it.
pub fn describe_error_code(code: ErrorCode) -> String {
    advised_error_code(code).to_string()
}

/// [`describe_error_code`]'s sentence, its advice kept apart from its words.
fn advised_error_code(code: ErrorCode) -> Advised {
    match code {
        ErrorCode::UnknownRequest => {
            "its firmware does not know this request; update the firmware".into()
        }
        ErrorCode::Unsupported => "this firmware build does not implement it".into(),
        ErrorCode::Busy => "it is busy with a run, reset or self-test; wait, or abort it".into(),
        ErrorCode::Faulted(f) => Advised::text(format!(
            "a fault is latched ({}); fix the cause, then ",
            describe_fault(f)
        ))
        .advise(Advice::ClearFault)
        .then(" or ")
        .advise(Advice::Reset),
        ErrorCode::InvalidParam(field) => field.out_of_range(None).to_string().into(),
        ErrorCode::NoSamples => "there are no (more) samples for that run".into(),
        ErrorCode::Storage => {
            "the configuration could not be saved to flash; the old one stays in use".into()
        }
        ErrorCode::NotAtZero => Advised::text(
            "the hub is not at its zero position (prongs centred in the gauge holes): run ",
        )
        .advise(Advice::Reset)
        .then(" first"),
        ErrorCode::Blocked(conditions) => advised_conditions(conditions)
            .then(". Nothing is latched: fix it and try again (")
            .advise(Advice::Status)
            .then(" shows the conditions)"),
        ErrorCode::SupplyTooLow {
            supply_mv,
            needed_mv,
        } => advised_supply_too_low(supply_mv, needed_mv),
    }
}

/// The sentence for `ErrorCode::SupplyTooLow`: the figures, and the two ways out.
fn advised_supply_too_low(supply_mv: u16, needed_mv: u16) -> Advised {
    let (supply_v, needed_v) = (f32::from(supply_mv) / 1000.0, f32::from(needed_mv) / 1000.0);
    let raise = if needed_v <= SUPPLY_MAX_V {
        Advised::text(format!(
            "use a motor supply of at least {needed_v:.1} V (rated up to {SUPPLY_MAX_V} V)"
        ))
    } else {
        Advised::text(format!(
            "no supply within the rated {SUPPLY_MIN_V}–{SUPPLY_MAX_V} V can: check the torque calibration ("
        ))
        .advise(Advice::ConfigGet)
        .then(format!(", given at {REFERENCE_SUPPLY_V} V)"))
    };
    Advised::text(format!(
        "the motor supply measures {supply_v:.1} V, but the most torque this run may ask for needs {needed_v:.1} V at full duty. The motor did not move: "
    ))
    .append(raise)
    .then(", or measure at a lower joint force (")
    .advise(Advice::LowerForce)
    .then(")")
}

/// A sentence for the idle conditions that stand, each with what to do about it.
pub fn describe_conditions(conditions: Conditions) -> String {
    advised_conditions(conditions).to_string()
}

/// [`describe_conditions`]'s sentence, its advice kept apart from its words.
fn advised_conditions(conditions: Conditions) -> Advised {
    Conditions::NAMES
        .iter()
        .filter(|(c, _)| conditions.contains(*c))
        .map(|(c, _)| advised_condition(*c))
        .reduce(|sentence, one| sentence.then("; ").append(one))
        .unwrap_or_else(|| "no condition stands".into())
}

/// A sentence for one idle condition.
fn advised_condition(condition: Conditions) -> Advised {
    let plain = match condition {
        Conditions::NO_MAGNET => {
            "no magnet: the encoder sees no magnet in range; check the magnet's distance to the chip"
        }
        Conditions::ENCODER_DIAGNOSTICS => {
            "the encoder fails its diagnostics (stuck bus or no offset compensation); check the encoder wiring"
        }
        Conditions::ENCODER_UNREADABLE => "the encoder cannot be read; check the encoder wiring",
        Conditions::DRIVER_FAULT => {
            "the motor driver reports a fault (FLT low): check that the motor supply is on and above the driver's under-voltage lockout"
        }
        Conditions::SUPPLY_OUT_OF_RANGE => {
            return Advised::text(
                "the motor supply is outside the rated 9–26 V, or above the motor driver's safe maximum (24 V on a G2 18v17; ",
            )
            .advise(Advice::Status)
            .then(" shows the supply): use a supply within that range");
        }
        Conditions::ADC_UNCALIBRATED => {
            "the chip has no ADC calibration eFuses: the current sense reads some 30–40 % high (the self-test's torque constant with it); measurements still run, their torque set from the duty"
        }
        Conditions::HUB_TURN_UNKNOWN => {
            return Advised::text(
                "the encoder is on the motor shaft and, since power-up, the device cannot tell which motor turn the hub is on: lift the prongs, turn the hub to its zero mark by hand (",
            )
            .advise(Advice::Reset)
            .then(" first brings it to the nearest zero it knows), then run ")
            .advise(Advice::ConfirmZero);
        }
        _ => "an unknown condition (a newer firmware?)",
    };
    plain.into()
}

/// `text` ended as a sentence: a full stop added unless it ends in one already (or in `?`).
fn sentence(text: &str) -> String {
    if text.ends_with(['.', '?', '!']) {
        text.to_owned()
    } else {
        format!("{text}.")
    }
}

/// A sentence for a latched device fault.
pub fn describe_fault(fault: Fault) -> &'static str {
    match fault {
        Fault::MaxRunTime => "the run took longer than its time limit",
        Fault::Overtravel => {
            "the inset turned past the gauge's disengage angle without jamming: kerf too large for this gauge, or the inset is loose"
        }
        Fault::NoMotion => {
            "torque but no motion: is a gauge inset under the prongs, and the motor connected?"
        }
        Fault::ReverseMotion => {
            "the hub turned backwards: check the motor and encoder direction settings"
        }
        Fault::EncoderErrors => "too many encoder read errors: check the encoder wiring",
        Fault::EncoderDiagnostics => {
            "the encoder failed its diagnostics (stuck bus or no offset compensation): check the encoder wiring"
        }
        Fault::Magnet => {
            "the encoder magnet is missing or out of range: check the magnet's distance to the chip"
        }
        Fault::OverCurrent => "motor over-current: is the hub blocked?",
        Fault::DriverFault => {
            "the motor driver reported a fault (a short, or its supply under-voltage)"
        }
        Fault::HostSilent => "the host stopped talking during a run",
        Fault::StepOverrun => "the control loop could not keep its rate",
        Fault::ResetFailed => "the hub did not return to zero: is it blocked?",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_supply_too_low_says_the_figures_and_what_to_do() {
        let message = describe_error_code(ErrorCode::SupplyTooLow {
            supply_mv: 9_050,
            needed_mv: 11_389,
        });
        for part in [
            "measures 9.1 V",
            "needs 11.4 V",
            "did not move",
            "at least 11.4 V",
            // Advice in the library's own words where no front end set its own.
            "`RunParams::target_force_n`",
        ] {
            assert!(message.contains(part), "{part:?} in {message}");
        }
        // Beyond the rated range no supply helps: say so, and where to look instead.
        let message = describe_error_code(ErrorCode::SupplyTooLow {
            supply_mv: 24_000,
            needed_mv: 30_000,
        });
        assert!(message.contains("no supply within the rated"), "{message}");
        assert!(message.contains("`Kerfmeter::config`"), "{message}");
        let refused = Error::Device {
            request: "run",
            code: ErrorCode::SupplyTooLow {
                supply_mv: 24_000,
                needed_mv: 30_000,
            },
        };
        assert_eq!(refused.advice(), [Advice::ConfigGet, Advice::LowerForce]);
    }

    #[test]
    fn every_condition_has_its_own_sentence() {
        for (condition, name) in Conditions::NAMES {
            let sentence = advised_condition(condition).to_string();
            assert!(!sentence.contains("unknown"), "{name}: {sentence}");
        }
        let supply = describe_conditions(Conditions::SUPPLY_OUT_OF_RANGE);
        assert!(supply.contains("9–26 V"), "{supply}");
        let blocked = describe_error_code(ErrorCode::Blocked(Conditions::SUPPLY_OUT_OF_RANGE));
        assert!(blocked.contains("motor supply is outside"), "{blocked}");
        // The advice of a refusal is the advice its sentence gives, in its order.
        let both = Conditions::SUPPLY_OUT_OF_RANGE.union(Conditions::HUB_TURN_UNKNOWN);
        let refused = Error::Device {
            request: "run",
            code: ErrorCode::Blocked(both),
        };
        assert_eq!(
            refused.advice(),
            [
                Advice::Status,
                Advice::Reset,
                Advice::ConfirmZero,
                Advice::Status
            ]
        );
    }
}
