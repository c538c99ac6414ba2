//! `kerfmeter config get|set`: read or change the device configuration (stored in its flash).

use std::fmt;

use clap::{Args, Subcommand};
use kerfmeter::protocol::{ConfigReport, DeviceConfig, EncoderPlacement, REFERENCE_SUPPLY_V};
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

#[derive(Subcommand)]
pub enum ConfigCommand {
    /// Print the configuration and whether it is the default.
    Get,
    /// Change some values; the others stay as they are. The torque calibration
    /// (--torque-per-duty-nm, --breakaway-duty) is given at the reference supply, 12 V, whatever
    /// the supply: the device scales the duty by the supply it measures.
    Set(ConfigSet),
}

#[derive(Args)]
pub struct ConfigSet {
    #[arg(long, help = format!(
        "Output torque at full duty and standstill on a {REFERENCE_SUPPLY_V} V supply (the \
         reference), N·m; measured at V volts, give it × {REFERENCE_SUPPLY_V} / V"
    ))]
    torque_per_duty_nm: Option<f32>,
    #[arg(long, help = format!(
        "Duty (0–0.5) below which the gearbox does not move, on a {REFERENCE_SUPPLY_V} V supply \
         (the reference); measured at V volts, give it × V / {REFERENCE_SUPPLY_V}"
    ))]
    breakaway_duty: Option<f32>,
    /// Raw encoder reading (0–16383) at the hub's zero position.
    #[arg(long)]
    encoder_zero_raw: Option<u16>,
    /// Encoder magnet on the output shaft (hub) or the motor shaft.
    #[arg(long, value_parser = ["output", "motor"])]
    encoder_on: Option<String>,
    /// Gearbox ratio.
    #[arg(long)]
    gear_ratio: Option<f32>,
    /// Motor wired the other way round.
    #[arg(long)]
    motor_inverted: Option<bool>,
    /// Encoder counting the other way round.
    #[arg(long)]
    encoder_inverted: Option<bool>,
    /// Over-current trip, A.
    #[arg(long)]
    max_current_a: Option<f32>,
    /// Output torque per motor amp, N·m/A.
    #[arg(long)]
    torque_per_amp_nm: Option<f32>,
}

impl ConfigSet {
    /// `config` with the values given here changed.
    fn apply(&self, mut config: DeviceConfig) -> DeviceConfig {
        macro_rules! apply {
            ($($field:ident),*) => { $( if let Some(v) = self.$field { config.$field = v; } )* };
        }
        apply!(
            torque_per_duty_nm,
            breakaway_duty,
            encoder_zero_raw,
            gear_ratio,
            motor_inverted,
            encoder_inverted,
            max_current_a,
            torque_per_amp_nm
        );
        if let Some(on) = &self.encoder_on {
            config.encoder_placement = if on == "motor" {
                EncoderPlacement::MotorShaft
            } else {
                EncoderPlacement::OutputShaft
            };
        }
        config
    }
}

/// The configuration in use; its JSON is the device's own [`ConfigReport`].
#[derive(Serialize)]
#[serde(transparent)]
pub struct ConfigOutcome(pub ConfigReport);

/// Read the configuration, or change it and read back what the device keeps.
pub fn run(g: &Global, c: &ConfigCommand) -> Result<ConfigOutcome, CliError> {
    let mut s = g.connect()?;
    let report = match c {
        ConfigCommand::Get => s.meter.config()?,
        ConfigCommand::Set(set) => {
            let config = set.apply(s.meter.config()?.config);
            s.meter.set_config(&config)?
        }
    };
    Ok(ConfigOutcome(report))
}

impl fmt::Display for ConfigOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.0.config;
        writeln!(f, "torque_per_duty_nm  {}", c.torque_per_duty_nm)?;
        writeln!(f, "breakaway_duty      {}", c.breakaway_duty)?;
        writeln!(f, "encoder_zero_raw    {}", c.encoder_zero_raw)?;
        let on = if c.encoder_placement == EncoderPlacement::MotorShaft {
            "motor"
        } else {
            "output"
        };
        writeln!(f, "encoder_on          {on}")?;
        writeln!(f, "gear_ratio          {}", c.gear_ratio)?;
        writeln!(f, "motor_inverted      {}", c.motor_inverted)?;
        writeln!(f, "encoder_inverted    {}", c.encoder_inverted)?;
        writeln!(f, "max_current_a       {}", c.max_current_a)?;
        write!(f, "torque_per_amp_nm   {}", c.torque_per_amp_nm)?;
        if self.0.defaults_in_use {
            write!(
                f,
                "\n(defaults: no valid configuration is stored on the device)"
            )?;
        }
        if !self.0.saved && !self.0.defaults_in_use {
            write!(
                f,
                "\n(applied but not saved: it lasts until the device restarts)"
            )?;
        }
        Ok(())
    }
}

impl Report for ConfigOutcome {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
