//! `kerfmeter info`: the device's protocol and firmware versions, boot id and hardware constants.

use std::fmt;

use kerfmeter::protocol::DeviceInfo;
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

/// The device's identity; its JSON is the device's own [`DeviceInfo`].
#[derive(Serialize)]
#[serde(transparent)]
pub struct InfoReport {
    /// The port the device answered on (text only).
    #[serde(skip)]
    pub port: String,
    /// What the device said.
    pub info: DeviceInfo,
}

/// Ask the device who it is.
pub fn run(g: &Global) -> Result<InfoReport, CliError> {
    let mut s = g.connect()?;
    let info = s.meter.info()?;
    Ok(InfoReport {
        port: s.meter.path().to_string(),
        info,
    })
}

impl fmt::Display for InfoReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (info, h) = (&self.info, &self.info.hardware);
        writeln!(f, "port:       {}", self.port)?;
        writeln!(f, "board:      {}", h.board)?;
        let v = &info.firmware;
        writeln!(f, "firmware:   {}.{}.{}", v.major, v.minor, v.patch)?;
        let p = &info.protocol;
        writeln!(f, "protocol:   {}.{}", p.major, p.minor)?;
        writeln!(f, "boot id:    {:08x}", info.boot_id)?;
        writeln!(f, "control:    {} Hz", h.control_rate_hz)?;
        writeln!(f, "encoder:    {} bit", h.encoder_bits)?;
        writeln!(f, "pwm:        {} bit", h.pwm_bits)?;
        write!(f, "sample log: {} samples", h.max_samples)
    }
}

impl Report for InfoReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
