//! `kerfmeter confirm-zero`: the user says the hub stands at its zero mark, so that a device
//! with its encoder on the motor shaft, which cannot know the hub's motor turn after power-up,
//! accepts runs again (protocol 2.5).

use kerfmeter::protocol::EncoderPlacement;

use super::Done;
use crate::connection::{Global, Session};
use crate::error::CliError;

/// Confirm the hub at its zero mark; says what that changed.
pub fn run(g: &Global) -> Result<Done, CliError> {
    // Each `--sim` command is a twin of its own, gone when the command ends.
    confirm(&mut g.connect()?, g.sim)
}

/// [`run`] on an open session (the server's `confirm_hub_at_zero`, whose twin lives on:
/// `one_shot_twin` false). With the encoder on the output shaft nothing is sent, so that this
/// works with a device older than protocol 2.5 too.
pub fn confirm(session: &mut Session, one_shot_twin: bool) -> Result<Done, CliError> {
    match session.meter.config()?.config.encoder_placement {
        EncoderPlacement::MotorShaft => {
            session.meter.confirm_hub_at_zero()?;
            Ok(if one_shot_twin {
                Done::with_warning(
                    "hub confirmed at its zero mark",
                    "but this simulated device ends with this command, and the next --sim command starts a fresh one: to confirm and then measure, use a twin that lives on (`kerfmeter --sim --sim-encoder-on-motor-shaft serve`, or `kerfmeter-twin --encoder-on-motor-shaft` and --port)",
                )
            } else {
                Done::new(
                    "hub confirmed at its zero mark: the encoder's turn count restarted there; `kerfmeter reset` brings the hub to zero exactly",
                )
            })
        }
        EncoderPlacement::OutputShaft => Ok(Done::new(
            "nothing to confirm: the encoder is on the output shaft, which knows the hub's angle at power-up",
        )),
    }
}
