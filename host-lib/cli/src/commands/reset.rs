//! `kerfmeter reset`: turn the hub back to zero and clear the last result (and a latched fault).

use kerfmeter::Kerfmeter;
use kerfmeter::protocol::Conditions;

use super::Done;
use crate::connection::Global;
use crate::error::CliError;

/// Reset the device; says where the hub is when its zero is only the encoder count's.
pub fn run(g: &Global) -> Result<Done, CliError> {
    let mut session = g.connect()?;
    session.meter.reset_kerfmeter()?;
    Ok(match warning(&mut session.meter)? {
        Some(w) => Done::with_warning("reset: the hub is at the zero of the encoder's count", w),
        None => Done::new("reset: the hub is at zero"),
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
