//! A bring-up's report: each step's outcome in words, the device it was run on, and whether the
//! device may be trusted with a measurement. Its text is what `kerfmeter bringup` prints and
//! saves beside its JSON; a user attaches either to a bug report.

use std::fmt;

use serde::{Deserialize, Serialize};

/// The report's format, in its JSON (`kerfmeter_bringup`) and its text's first line: what says
/// a file is a bring-up report kerfmeter wrote.
pub const REPORT_FORMAT: u32 = 1;

/// The first words of a report's text (and so of its file).
pub const TEXT_MARKER: &str = "kerfmeter bring-up report";

/// One bench check, in the order a bring-up runs them.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum StepId {
    /// The device answers with its health (protocol 2.6).
    Health,
    /// Why the chip last started.
    ResetReason,
    /// Whether the ADC is calibrated by the chip's eFuses.
    AdcCalibration,
    /// The motor supply the device reads, within its G2's limits.
    Supply,
    /// The supply against a meter at the G2's `VIN`.
    SupplyMeter,
    /// The current sense with the driver asleep.
    CsAsleep,
    /// The encoder's magnitude, AGC and diagnostic flags.
    Encoder,
    /// The device's self-test (encoder reads, magnet, torque constant).
    SelfTest,
    /// The self-test's short, bounded turn: which way the hub went.
    Direction,
    /// The current-sense offset learnt awake and braking.
    CsBraking,
    /// One measurement on a cut gauge.
    GaugeRun,
    /// The longest control step and gap between steps since boot.
    Timing,
}

impl StepId {
    /// The step's name as the text prints it.
    pub const fn title(self) -> &'static str {
        match self {
            Self::Health => "health",
            Self::ResetReason => "reset reason",
            Self::AdcCalibration => "adc calibration",
            Self::Supply => "supply",
            Self::SupplyMeter => "supply vs meter",
            Self::CsAsleep => "cs asleep",
            Self::Encoder => "encoder",
            Self::SelfTest => "self-test",
            Self::Direction => "direction",
            Self::CsBraking => "cs braking",
            Self::GaugeRun => "gauge run",
            Self::Timing => "timing",
        }
    }
}

/// How a step ended.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Outcome {
    /// Checked, and right.
    Pass,
    /// Checked, and wrong: `means` says what that means and what to check.
    Fail,
    /// Not checked: nobody answered (no terminal, no flag), or the device has no reading.
    NotChecked,
    /// Not run, because an earlier step failed (`means` names it).
    Skipped,
}

impl Outcome {
    /// The outcome as the text prints it.
    pub const fn word(self) -> &'static str {
        match self {
            Self::Pass => "PASS",
            Self::Fail => "FAIL",
            Self::NotChecked => "NOT CHECKED",
            Self::Skipped => "SKIPPED",
        }
    }
}

/// Who answered a question only a person can: what the report must say of every such answer.
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum AnsweredBy {
    /// A flag (or request parameter): `--meter-v`, `--hub-turned`, `--gauge-placed`.
    Flag,
    /// The person at the bench, at a prompt.
    Person,
    /// The simulated device's own physics: no person looked.
    Twin,
}

/// One step's outcome, in words.
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct Step {
    /// Which step.
    pub step: StepId,
    /// How it ended.
    pub outcome: Outcome,
    /// What was measured or answered, with its unit.
    pub seen: String,
    /// For a failure, what it means and what to check; for a skipped or unchecked step, why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub means: Option<String>,
    /// Who answered the person's question of this step (absent for what the device measured).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub answered_by: Option<AnsweredBy>,
    /// Where the documentation explains this check.
    pub see: &'static str,
}

impl Step {
    /// A step that passed, having seen `seen`.
    pub fn pass(step: StepId, seen: impl Into<String>) -> Self {
        Self::new(step, Outcome::Pass, seen, None)
    }

    /// A step that failed: `seen`, which `means` this.
    pub fn fail(step: StepId, seen: impl Into<String>, means: impl Into<String>) -> Self {
        Self::new(step, Outcome::Fail, seen, Some(means.into()))
    }

    /// A step not checked, for `why`.
    pub fn not_checked(step: StepId, seen: impl Into<String>, why: impl Into<String>) -> Self {
        Self::new(step, Outcome::NotChecked, seen, Some(why.into()))
    }

    /// A step not run because `earlier` failed.
    pub fn skipped(step: StepId, why: impl Into<String>) -> Self {
        Self::new(step, Outcome::Skipped, "not run", Some(why.into()))
    }

    fn new(step: StepId, outcome: Outcome, seen: impl Into<String>, means: Option<String>) -> Self {
        Self {
            step,
            outcome,
            seen: seen.into(),
            means,
            answered_by: None,
            see: see(step),
        }
    }

    /// The same step, its question answered by `by`.
    pub fn answered_by(mut self, by: Option<AnsweredBy>) -> Self {
        self.answered_by = by;
        self
    }
}

/// The documentation section of each step.
const fn see(step: StepId) -> &'static str {
    match step {
        StepId::Health | StepId::ResetReason | StepId::AdcCalibration => {
            "docs/hardware.md#resets-and-the-chips-health"
        }
        StepId::Supply | StepId::SupplyMeter => "docs/build.md#which-pololu-g2",
        StepId::CsAsleep | StepId::CsBraking => "docs/hardware.md#which-g2",
        StepId::Encoder | StepId::SelfTest | StepId::Direction | StepId::GaugeRun => {
            "docs/hardware.md#first-bench-checks"
        }
        StepId::Timing => "docs/hardware.md#first-bench-checks",
    }
}

/// The device a bring-up ran on.
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct DeviceSeen {
    /// The port it answered on.
    pub port: String,
    /// The board (`esp32c3`, `twin`).
    pub board: String,
    /// Firmware version, `major.minor.patch`.
    pub firmware: String,
    /// Protocol version, `major.minor`.
    pub protocol: String,
    /// The per-boot id, hex.
    pub boot_id: String,
    /// The G2 variant it is built for (`null` from a device before protocol 2.6).
    pub driver: Option<String>,
    /// The device is the simulated one.
    pub simulated: bool,
}

/// A bring-up: the device, every step in order, and the verdict.
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct BringupReport {
    /// [`REPORT_FORMAT`]: marks a file as a bring-up report kerfmeter wrote.
    pub kerfmeter_bringup: u32,
    /// When it ran (RFC 3339, UTC).
    pub date: String,
    /// The device.
    pub device: DeviceSeen,
    /// Every step, in order.
    pub steps: Vec<Step>,
    /// True when no step failed (steps not checked are named in `not_checked`).
    pub passed: bool,
    /// The steps that failed.
    pub failed: Vec<StepId>,
    /// The steps nobody could check (no answer, no reading).
    pub not_checked: Vec<StepId>,
}

impl BringupReport {
    /// The report of `steps` on `device`, run at `date`.
    pub fn new(date: String, device: DeviceSeen, steps: Vec<Step>) -> Self {
        let with = |o: Outcome| -> Vec<StepId> {
            steps
                .iter()
                .filter(|s| s.outcome == o)
                .map(|s| s.step)
                .collect()
        };
        let failed = with(Outcome::Fail);
        let not_checked = with(Outcome::NotChecked);
        Self {
            kerfmeter_bringup: REPORT_FORMAT,
            date,
            device,
            passed: failed.is_empty(),
            failed,
            not_checked,
            steps,
        }
    }

    /// The step `id`, if it was reported.
    pub fn step(&self, id: StepId) -> Option<&Step> {
        self.steps.iter().find(|s| s.step == id)
    }
}

impl fmt::Display for BringupReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = &self.device;
        writeln!(f, "{TEXT_MARKER} {REPORT_FORMAT}, {}", self.date)?;
        writeln!(
            f,
            "device: {} on {}{}, firmware {}, protocol {}, boot id {}, G2 {}",
            d.board,
            d.port,
            if d.simulated { " (simulated)" } else { "" },
            d.firmware,
            d.protocol,
            d.boot_id,
            d.driver.as_deref().unwrap_or("not reported")
        )?;
        for step in &self.steps {
            write_step(f, step)?;
        }
        writeln!(f)?;
        write_verdict(f, self)
    }
}

/// One step: its name, outcome and what was seen; then what it means, and where to read more.
fn write_step(f: &mut fmt::Formatter<'_>, s: &Step) -> fmt::Result {
    writeln!(f)?;
    let by = match s.answered_by {
        Some(AnsweredBy::Flag) => " (answered by a flag)",
        Some(AnsweredBy::Person) => " (answered at the prompt)",
        Some(AnsweredBy::Twin) => " (the twin answered: no person looked)",
        None => "",
    };
    write!(
        f,
        "{:<16} {:<11} {}{by}",
        s.step.title(),
        s.outcome.word(),
        s.seen
    )?;
    if let Some(means) = &s.means {
        write!(f, "\n    {means}")?;
    }
    if s.outcome == Outcome::Fail {
        write!(f, "\n    see {}", s.see)?;
    }
    Ok(())
}

/// The last line: passed, or which steps failed; and which nobody checked.
fn write_verdict(f: &mut fmt::Formatter<'_>, r: &BringupReport) -> fmt::Result {
    let names =
        |ids: &[StepId]| -> String { ids.iter().map(|s| s.title()).collect::<Vec<_>>().join(", ") };
    if r.passed {
        write!(f, "bring-up passed")?;
    } else {
        write!(f, "bring-up FAILED at: {}", names(&r.failed))?;
    }
    if !r.not_checked.is_empty() {
        write!(
            f,
            "; not checked: {} (answer them to complete the bring-up)",
            names(&r.not_checked)
        )?;
    }
    Ok(())
}
