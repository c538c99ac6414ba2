//! `kerfmeter reset`: turn the hub back to zero and clear the last result (and a latched fault).

use super::Done;
use crate::connection::Global;
use crate::error::CliError;

/// Reset the device.
pub fn run(g: &Global) -> Result<Done, CliError> {
    g.connect()?.meter.reset_kerfmeter()?;
    Ok(Done::new("reset: the hub is at zero"))
}
