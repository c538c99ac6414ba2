//! `kerfmeter info`: the device's protocol and firmware versions, boot id and hardware constants,
//! and its measured motor supply. `DeviceInfo` is frozen by design (the protocol's variant 0), so
//! the supply, a measurement, comes from a `GetStatus` asked right after it, and the device's
//! health (the last reset's reason in words, the chip, the ADC's calibration, the brown-out
//! detector, the motor driver) from a `GetDiagnostics` (protocol 2.6; an older device has none).

use std::fmt;

use crate::health::{describe_adc, describe_brown_out, describe_reset, health_warnings};
use kerfmeter::protocol::{DeviceInfo, Diagnostics};
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
    /// The device's health since boot (protocol 2.6: the last reset's reason, the chip, the
    /// ADC's calibration, the brown-out detector, ...); `null` from an older device.
    pub diagnostics: Option<Diagnostics>,
}

/// Ask the device who it is, and what supply it measures.
pub fn run(g: &Global) -> Result<InfoReport, CliError> {
    report(&mut g.connect()?)
}

/// The info report of the device behind an open session (`kerfmeter serve` shares it).
pub fn report(s: &mut Session) -> Result<InfoReport, CliError> {
    let info = s.meter.info()?;
    let supply_v = s.meter.status()?.supply_v;
    let diagnostics = s.meter.diagnostics()?;
    Ok(InfoReport {
        port: s.meter.path().to_string(),
        info,
        supply_v,
        diagnostics,
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
            Some(v) => write!(f, "supply:     {v:.2} V")?,
            None => write!(f, "supply:     not measured")?,
        }
        match &self.diagnostics {
            Some(d) => write_health(f, d),
            None => write!(
                f,
                "\nhealth:     not reported (a firmware before protocol 2.6: update it for the \
                 last reset's reason and the ADC's calibration)"
            ),
        }
    }
}

/// The health lines of `info`: the last reset in words, the chip, the ADC, the brown-out
/// detector and the driver; then each warning.
fn write_health(f: &mut fmt::Formatter<'_>, d: &Diagnostics) -> fmt::Result {
    writeln!(f)?;
    writeln!(f, "last reset: {}", describe_reset(d.reset_reason))?;
    match d.chip_revision {
        Some(r) => writeln!(f, "chip:       revision {}.{}", r.major, r.minor)?,
        None => writeln!(f, "chip:       revision not reported")?,
    }
    writeln!(f, "adc:        {}", describe_adc(d.adc_calibration))?;
    writeln!(f, "brown-out:  {}", describe_brown_out(d.brown_out))?;
    write!(
        f,
        "driver:     Pololu G2 {} ({} mV/A, supply up to {} V)",
        d.driver.name(),
        d.driver.cs_mv_per_a(),
        d.driver.supply_max_v()
    )?;
    for warning in health_warnings(d) {
        write!(f, "\nwarning:    {warning}")?;
    }
    Ok(())
}

impl Report for InfoReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
