//! `kerfmeter reset`: turn the hub back to zero and clear the last result (and a latched fault,
//! which it names: a reset that clears a fault should not make it vanish unseen).

use std::fmt;

use kerfmeter::Kerfmeter;
use kerfmeter::protocol::{Conditions, Fault, RunState};
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

/// What `reset` did: the fault it cleared, if one was latched, and what the user must know when
/// the hub's zero is only the encoder count's.
#[derive(Serialize)]
pub struct ResetReport {
    /// The latched fault the reset cleared (named as in the protocol).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cleared_fault: Option<Fault>,
    /// Set when the hub's zero is only the encoder count's (hub-turn-unknown).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub warning: Option<&'static str>,
    /// Always true: a failure is an error, not a report.
    pub ok: bool,
}

impl fmt::Display for ResetReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.warning {
            Some(w) => write!(
                f,
                "reset: the hub is at the zero of the encoder's count; {w}"
            )?,
            None => f.write_str("reset: the hub is at zero")?,
        }
        if let Some(fault) = self.cleared_fault {
            write!(
                f,
                "\nthe latched fault {fault:?} was cleared ({}); fix its cause before the next run",
                kerfmeter::describe_fault(fault)
            )?;
        }
        Ok(())
    }
}

impl Report for ResetReport {
    const JSON: JsonLayout = JsonLayout::CompactSorted;
}

/// Reset the device; says which fault it cleared and where the hub is when its zero is only the
/// encoder count's.
pub fn run(g: &Global) -> Result<ResetReport, CliError> {
    let mut session = g.connect()?;
    let cleared_fault = latched_fault(&mut session.meter)?;
    session
        .meter
        .reset_kerfmeter_until(|_| crate::interrupt::check())?;
    Ok(ResetReport {
        cleared_fault,
        warning: warning(&mut session.meter)?,
        ok: true,
    })
}

/// The fault latched now, which a reset clears (the server's `reset_kerfmeter` names it too).
pub fn latched_fault(meter: &mut Kerfmeter) -> Result<Option<Fault>, CliError> {
    Ok(match meter.status()?.state {
        RunState::Fault(fault) => Some(fault),
        _ => None,
    })
}

/// After a reset: what the user must know when the hub's zero is only the encoder count's (the
/// server's `reset_kerfmeter` says it too).
pub fn warning(meter: &mut Kerfmeter) -> Result<Option<&'static str>, CliError> {
    let status = meter.status()?;
    Ok(status
        .conditions
        .contains(Conditions::HUB_TURN_UNKNOWN)
        .then_some("that may be whole motor turns from its mark (hub-turn-unknown: the encoder is on the motor shaft); check the prongs against the mark, turn the hub to it by hand if they are not there, then run `kerfmeter confirm-zero`"))
}
