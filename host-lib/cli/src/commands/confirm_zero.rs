//! `kerfmeter confirm-zero`: the user says the hub stands at its zero mark, so that a device
//! with its encoder on the motor shaft, which cannot know the hub's motor turn after power-up,
//! accepts runs again (protocol 2.5).

use kerfmeter::protocol::EncoderPlacement;

use super::Done;
use crate::connection::{Global, Session};
use crate::error::CliError;

/// Confirm the hub at its zero mark; says what that changed.
pub fn run(g: &Global) -> Result<Done, CliError> {
    confirm(&mut g.connect()?)
}

/// [`run`] on an open session (the server's `confirm_hub_at_zero`).
pub fn confirm(session: &mut Session) -> Result<Done, CliError> {
    let placement = session.meter.config()?.config.encoder_placement;
    session.meter.confirm_hub_at_zero()?;
    Ok(Done::new(match placement {
        EncoderPlacement::MotorShaft => {
            "hub confirmed at its zero mark: the encoder's turn count restarted there; `kerfmeter reset` brings the hub to zero exactly"
        }
        EncoderPlacement::OutputShaft => {
            "nothing to confirm: the encoder is on the output shaft, which knows the hub's angle at power-up"
        }
    }))
}
