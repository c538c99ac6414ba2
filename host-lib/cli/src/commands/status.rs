//! `kerfmeter status`: what the device is doing now: its state, a latched fault, the idle
//! conditions that stand, the motor supply, the longest control step and gap since boot, and
//! what the device's health says is wrong (a watchdog or brown-out reset, said as such).

use std::fmt;

use kerfmeter::describe_conditions;
use kerfmeter::protocol::{RunState, Status};
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

/// The device's status, every field at the top level of the JSON.
#[derive(Serialize)]
pub struct StatusReport {
    /// The state's name: `idle`, `ramping`, `fault`, ...
    pub state: &'static str,
    /// The latched fault (`null` without one).
    pub fault: Option<kerfmeter::protocol::Fault>,
    /// The idle conditions that stand, by name (`no-magnet`, `driver-fault`, ...).
    pub conditions: Vec<&'static str>,
    /// Motor supply, volts (`null` where the board does not measure it).
    pub supply_v: Option<f32>,
    /// The longest control step since boot, µs.
    pub longest_step_us: u32,
    /// The longest gap between two control steps since boot, µs.
    pub longest_gap_us: u32,
    /// Id of the current or last run (0: none since boot).
    pub run_id: u32,
    /// Commanded torque now, N·m.
    pub torque_nm: f32,
    /// Hub angle from zero, degrees, in the jam direction.
    pub angle_deg: f32,
    /// The device's conditions, for the text's sentences.
    #[serde(skip)]
    raw: Status,
    /// The device is the simulated one, whose steps take no time (the text says so).
    #[serde(skip)]
    simulated: bool,
    /// What the device's health says is wrong (protocol 2.6: a watchdog, brown-out or panic
    /// reset, an uncalibrated ADC, ...), in words; empty from an older device.
    pub warnings: Vec<String>,
}

/// Ask the device for its status.
pub fn run(g: &Global) -> Result<StatusReport, CliError> {
    let mut session = g.connect()?;
    let mut report = StatusReport::from(session.meter.status()?);
    report.simulated = session.sim.is_some();
    if let Some(d) = session.meter.diagnostics()? {
        report.warnings = crate::health::health_warnings(&d);
    }
    Ok(report)
}

impl From<Status> for StatusReport {
    fn from(s: Status) -> Self {
        let fault = match s.state {
            RunState::Fault(f) => Some(f),
            _ => None,
        };
        StatusReport {
            state: state_name(s.state),
            fault,
            conditions: s.conditions.names().collect(),
            supply_v: s.supply_v,
            longest_step_us: s.longest_step_us,
            longest_gap_us: s.longest_gap_us,
            run_id: s.run_id,
            torque_nm: s.torque_nm,
            angle_deg: s.angle_deg,
            raw: s,
            simulated: false,
            warnings: Vec::new(),
        }
    }
}

/// A state's name, as text and JSON show it.
fn state_name(state: RunState) -> &'static str {
    match state {
        RunState::Idle => "idle",
        RunState::Engaging => "engaging",
        RunState::Ramping => "ramping",
        RunState::Jammed => "jammed",
        RunState::Releasing => "releasing",
        RunState::Done => "done",
        RunState::Resetting => "resetting",
        RunState::SelfTest => "self-test",
        RunState::Fault(_) => "fault",
    }
}

impl fmt::Display for StatusReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "state:        {}", self.state)?;
        match self.fault {
            Some(fault) => writeln!(
                f,
                "fault:        {fault:?}: {}",
                kerfmeter::describe_fault(fault)
            )?,
            None => writeln!(f, "fault:        none")?,
        }
        if self.conditions.is_empty() {
            writeln!(f, "conditions:   none")?;
        } else {
            writeln!(
                f,
                "conditions:   {}: {}",
                self.conditions.join(", "),
                describe_conditions(self.raw.conditions)
            )?;
        }
        match self.supply_v {
            Some(v) => writeln!(f, "supply:       {v:.2} V")?,
            None => writeln!(f, "supply:       not measured")?,
        }
        let unmodelled = if self.simulated && self.longest_step_us == 0 {
            " (the simulated device does not model a step's duration; a board measures it)"
        } else {
            ""
        };
        writeln!(f, "longest step: {} µs{unmodelled}", self.longest_step_us)?;
        writeln!(f, "longest gap:  {} µs", self.longest_gap_us)?;
        writeln!(f, "run id:       {}", self.run_id)?;
        write!(
            f,
            "hub:          {:.2}° at {:.3} N·m",
            self.angle_deg, self.torque_nm
        )?;
        for warning in &self.warnings {
            write!(f, "\nwarning:      {warning}")?;
        }
        Ok(())
    }
}

impl Report for StatusReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
