//! `kerfmeter reset`: turn the hub back to zero and clear the last result (and a latched fault).

use kerfmeter::protocol::Conditions;

use super::Done;
use crate::connection::Global;
use crate::error::CliError;

/// Reset the device; says where the hub is when its zero is only the encoder count's.
pub fn run(g: &Global) -> Result<Done, CliError> {
    let mut session = g.connect()?;
    session.meter.reset_kerfmeter()?;
    let status = session.meter.status()?;
    Ok(Done::new(
        if status.conditions.contains(Conditions::HUB_TURN_UNKNOWN) {
            "reset: the hub is at the zero of the encoder's count, which may be whole motor turns from its mark (hub-turn-unknown: the encoder is on the motor shaft); check the prongs against the mark, turn the hub to it by hand if they are not there, then run `kerfmeter confirm-zero`"
        } else {
            "reset: the hub is at zero"
        },
    ))
}
