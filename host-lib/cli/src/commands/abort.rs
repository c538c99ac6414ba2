//! `kerfmeter abort`: stop the motor and end whatever the device is doing.

use super::Done;
use crate::connection::Global;
use crate::error::CliError;

/// Abort whatever the device is doing.
pub fn run(g: &Global) -> Result<Done, CliError> {
    g.connect()?.meter.abort()?;
    Ok(Done::new("aborted: the motor is stopped"))
}
