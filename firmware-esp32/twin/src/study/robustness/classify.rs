//! How an ending is classified (see the module docs): a correct reading, a flagged one, an
//! unflagged wrong reading, a typed fault or refusal, or a failure of the sweep itself.

use kerfmeter_protocol::{ErrorCode, QualityFlags};

use crate::study::Outcome;

/// Whether `flags` distrust the number: any flag but the advisory ones
/// ([`QualityFlags::ADVISORY`]: `decimated`, `play-modelled`).
pub fn distrusted(flags: QualityFlags) -> bool {
    !flags.distrusting().is_empty()
}

/// What an ending counts as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Class {
    /// A reading within the tolerance, not distrusted.
    Correct,
    /// A reading with a flag that distrusts it (right or wrong).
    Flagged,
    /// A reading off by more than the tolerance with no flag: what must never happen.
    UnflaggedWrong,
    /// A typed fault (allowed: the device said why).
    Fault,
    /// A typed refusal (allowed).
    Refused,
    /// No result and no fault within the limit.
    NoEnd,
    /// An answer that does not belong to the request.
    Unexpected,
    /// A panic.
    Panic,
}

impl Class {
    /// Its name in reports.
    pub const fn name(self) -> &'static str {
        match self {
            Class::Correct => "correct",
            Class::Flagged => "flagged",
            Class::UnflaggedWrong => "unflagged_wrong",
            Class::Fault => "fault",
            Class::Refused => "refused",
            Class::NoEnd => "no_end",
            Class::Unexpected => "unexpected",
            Class::Panic => "panic",
        }
    }

    /// Whether this ending is allowed by the sweep's rules (a reading or a typed fault or
    /// refusal), leaving aside whether an unflagged reading is right.
    pub fn ends_properly(self) -> bool {
        !matches!(self, Class::NoEnd | Class::Unexpected | Class::Panic)
    }
}

/// The class of `outcome` with the tolerance `tolerance_um` on the device-added error.
pub fn classify(outcome: &Outcome, tolerance_um: f64) -> Class {
    match outcome {
        Outcome::Reading { result, .. } => {
            let error = outcome.error_um().unwrap_or(f64::NAN);
            if distrusted(result.flags) {
                Class::Flagged
            } else if error.abs() <= tolerance_um {
                Class::Correct
            } else {
                Class::UnflaggedWrong
            }
        }
        Outcome::Fault { .. } => Class::Fault,
        Outcome::Refused { .. } => Class::Refused,
        Outcome::NoEnd { .. } => Class::NoEnd,
        Outcome::Unexpected { .. } => Class::Unexpected,
        Outcome::Panic(_) => Class::Panic,
    }
}

/// The name of an ending that is not a reading, by its type: `fault OverCurrent (run)`,
/// `refused NotAtZero (run)`, `no end (reset, Resetting)`, ...
pub fn failure_name(outcome: &Outcome) -> Option<String> {
    Some(match outcome {
        Outcome::Reading { .. } => return None,
        Outcome::Fault { phase, fault } => format!("fault {fault:?} ({})", phase.name()),
        // The figures of a supply refusal differ from draw to draw: counted by kind.
        Outcome::Refused {
            phase,
            code: ErrorCode::SupplyTooLow { .. },
        } => format!("refused SupplyTooLow ({})", phase.name()),
        Outcome::Refused { phase, code } => format!("refused {code:?} ({})", phase.name()),
        Outcome::NoEnd { phase, state } => format!("no end ({}, {state:?})", phase.name()),
        Outcome::Unexpected { phase, .. } => format!("unexpected answer ({})", phase.name()),
        Outcome::Panic(_) => "panic".to_owned(),
    })
}
