//! `kerfmeter clear-fault`: leave a latched fault (its cause must be fixed first).

use super::Done;
use crate::connection::Global;
use crate::error::CliError;

/// Clear the device's latched fault.
pub fn run(g: &Global) -> Result<Done, CliError> {
    g.connect()?.meter.clear_fault()?;
    Ok(Done::new("fault cleared"))
}
