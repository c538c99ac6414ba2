//! `kerfmeter info`: the device's protocol and firmware versions, boot id and hardware constants,
//! and its measured motor supply. `DeviceInfo` is frozen by design (the protocol's variant 0), so
//! the supply, a measurement, comes from a `GetStatus` asked right after it.

use std::fmt;

use kerfmeter::protocol::DeviceInfo;
use serde::Serialize;

use crate::connection::{Global, Session};
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

/// The device's identity; its JSON is the device's own [`DeviceInfo`] with `supply_v` beside
/// its fields.
#[derive(Serialize)]
pub struct InfoReport {
    /// The port the device answered on (text only).
    #[serde(skip)]
    pub port: String,
    /// What the device said.
    #[serde(flatten)]
    pub info: DeviceInfo,
    /// The motor supply the device measures, V (`Status.supply_v`, filtered; `null` where the
    /// board does not measure it).
    pub supply_v: Option<f32>,
}

/// Ask the device who it is, and what supply it measures.
pub fn run(g: &Global) -> Result<InfoReport, CliError> {
    report(&mut g.connect()?)
}

/// The info report of the device behind an open session (`kerfmeter serve` shares it).
pub fn report(s: &mut Session) -> Result<InfoReport, CliError> {
    let info = s.meter.info()?;
    let supply_v = s.meter.status()?.supply_v;
    Ok(InfoReport {
        port: s.meter.path().to_string(),
        info,
        supply_v,
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
        writeln!(f, "sample log: {} samples", h.max_samples)?;
        match self.supply_v {
            Some(v) => write!(f, "supply:     {v:.2} V"),
            None => write!(f, "supply:     not measured"),
        }
    }
}

impl Report for InfoReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
