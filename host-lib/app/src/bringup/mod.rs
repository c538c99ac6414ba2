//! A guided first power-on (`kerfmeter bringup`): the bench checks of docs/build.md's "The
//! first power-on", in order, each passed or failed in words with what a failure means and
//! what to check, gathered in a report a user can attach to a bug report.
//!
//! What the device measures itself comes from its health (`GetDiagnostics`, protocol 2.6), its
//! status and its self-test: the reset reason, the ADC's calibration, the supply within the G2
//! variant's limits and the supply sense's tolerance, `CS` asleep, the encoder's diagnostics,
//! the self-test, the direction of its short bounded turn, `CS` braking, one run on a cut
//! gauge and the worst timing since boot. What only a person can see (a meter's reading of the
//! supply, which way the hub turned, that a cut gauge is under the prongs) is answered by the
//! request ([`AnsweredBy::Flag`]), else by the twin's physics when the device is the twin
//! ([`TwinTruth`], [`AnsweredBy::Twin`]), else by a [`Witness`] (a person at a prompt). Nobody
//! answering leaves the step [`Outcome::NotChecked`], said so: a real device's answer is never
//! made up.
//!
//! The motor moves twice, both bounded by the device's own limits: the self-test's short turn
//! each way and the run on the gauge. The caller's `stop` is polled between status polls of
//! both, and a stop aborts the device and waits for its motor to be at rest before the call
//! returns [`kerfmeter::Error::Cancelled`]. A step whose precondition failed is
//! [`Outcome::Skipped`] (no self-test without a supply or an encoder; no run after any failure).

mod judge;
mod report;
mod save;
#[cfg(test)]
mod tests;

pub use judge::supply_tolerance_v;
pub use report::{
    AnsweredBy, BringupReport, DeviceSeen, Outcome, REPORT_FORMAT, Step, StepId, TEXT_MARKER,
};
pub use save::{ReportFiles, today};

use std::ops::ControlFlow;
use std::str::FromStr;

use kerfmeter::protocol::{Conditions, Diagnostics, GaugeGeometry, KerfResult, Status};
use kerfmeter::{Category, Error, JointSpec, Kerfmeter, Progress};
use serde::{Deserialize, Serialize};

/// Which way the hub turned, seen from above (the prongs facing down).
#[derive(Serialize, Deserialize, Debug, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum HubTurn {
    /// Clockwise: the way the device turns the gauge's inset to close its spiral (the default
    /// gauge; docs/plans.md).
    Cw,
    /// Counter-clockwise.
    Ccw,
    /// It did not turn.
    Still,
}

impl HubTurn {
    /// In words.
    pub const fn words(self) -> &'static str {
        match self {
            Self::Cw => "clockwise",
            Self::Ccw => "counter-clockwise",
            Self::Still => "did not turn",
        }
    }
}

impl FromStr for HubTurn {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "cw" | "clockwise" => Ok(Self::Cw),
            "ccw" | "counter-clockwise" | "anticlockwise" => Ok(Self::Ccw),
            "still" | "none" | "no" => Ok(Self::Still),
            other => Err(format!("`{other}`: say cw, ccw or still")),
        }
    }
}

/// A bring-up asked for: the answers a person gave beforehand (each `None`: ask, or let the
/// twin answer).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BringupRequest {
    /// The motor supply a meter reads at the G2's `VIN`, V.
    pub meter_v: Option<f32>,
    /// Which way the hub turned first in the self-test, seen from above.
    pub hub_turned: Option<HubTurn>,
    /// A cut gauge lies under the prongs, lowered into it (`false`: no run on a gauge).
    pub gauge_placed: Option<bool>,
}

/// The highest meter reading taken for a motor supply, V (the device is rated to 26 V).
pub const METER_MAX_V: f32 = 100.0;

impl BringupRequest {
    /// Refuse a meter reading that no meter shows on a motor supply (negative, not a number,
    /// above [`METER_MAX_V`]).
    pub fn check(&self) -> Result<(), Error> {
        match self.meter_v {
            Some(v) if !(0.0..=METER_MAX_V).contains(&v) => Err(Error::invalid(format!(
                "meter_v {v}: a meter's reading of the motor supply is 0–{METER_MAX_V} V"
            ))),
            _ => Ok(()),
        }
    }
}

/// The twin's physics, answering the person's questions on the simulated device.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwinTruth {
    /// The supply at its source, V: what a meter at `VIN` reads with the motor at rest.
    pub supply_v: f32,
    /// Which way its hub turns under the self-test's clockwise torque.
    pub hub_turned: HubTurn,
}

#[cfg(any(test, feature = "sim"))]
impl TwinTruth {
    /// The truth of a twin started with `options`.
    pub fn of(options: &kerfmeter::sim::SimOptions) -> Self {
        let hub_turned = if options.fault == Some(kerfmeter::sim::SimFault::MotorDisconnected) {
            HubTurn::Still
        } else if options.motor_leads_swapped {
            HubTurn::Ccw
        } else {
            HubTurn::Cw
        };
        Self {
            supply_v: options.plant.supply_v as f32,
            hub_turned,
        }
    }
}

/// The person at the bench: asked what only they can see. Each answer is `None` when they
/// cannot be asked (no terminal) or gave none.
pub trait Witness {
    /// The device reads `device_v`: what does the meter read at the G2's `VIN`?
    fn meter_v(&mut self, device_v: f32) -> Option<f32>;
    /// The hub is about to turn a little each way: watch it (the call returns when they are).
    fn watch_hub(&mut self);
    /// Which way did the hub turn first?
    fn hub_turned(&mut self) -> Option<HubTurn>;
    /// Is a cut gauge under the prongs, lowered into it? (`None`: no answer.)
    fn gauge_placed(&mut self) -> Option<bool>;
}

/// Nobody to ask: every question a person answers is left not checked.
pub struct NoWitness;

impl Witness for NoWitness {
    fn meter_v(&mut self, _: f32) -> Option<f32> {
        None
    }
    fn watch_hub(&mut self) {}
    fn hub_turned(&mut self) -> Option<HubTurn> {
        None
    }
    fn gauge_placed(&mut self) -> Option<bool> {
        None
    }
}

/// Where the person's answers come from: the request, the twin, then the witness.
struct Answers<'a> {
    request: &'a BringupRequest,
    twin: Option<TwinTruth>,
    witness: &'a mut dyn Witness,
}

impl Answers<'_> {
    fn meter_v(&mut self, device_v: f32) -> Option<(f32, AnsweredBy)> {
        if let Some(v) = self.request.meter_v {
            return Some((v, AnsweredBy::Flag));
        }
        if let Some(t) = self.twin {
            return Some((t.supply_v, AnsweredBy::Twin));
        }
        self.witness
            .meter_v(device_v)
            .map(|v| (v, AnsweredBy::Person))
    }

    /// Whether a person must watch the hub turn (nobody else will say which way it went).
    fn person_watches(&self) -> bool {
        self.request.hub_turned.is_none() && self.twin.is_none()
    }

    fn hub_turned(&mut self) -> Option<(HubTurn, AnsweredBy)> {
        if let Some(t) = self.request.hub_turned {
            return Some((t, AnsweredBy::Flag));
        }
        if let Some(t) = self.twin {
            return Some((t.hub_turned, AnsweredBy::Twin));
        }
        self.witness.hub_turned().map(|t| (t, AnsweredBy::Person))
    }

    fn gauge_placed(&mut self) -> Option<(bool, AnsweredBy)> {
        if let Some(p) = self.request.gauge_placed {
            return Some((p, AnsweredBy::Flag));
        }
        if self.twin.is_some() {
            // The twin places a gauge under its prongs for every run.
            return Some((true, AnsweredBy::Twin));
        }
        self.witness.gauge_placed().map(|p| (p, AnsweredBy::Person))
    }
}

/// Walk the bench checks on `meter` in order. `twin` is the simulated device's truth (`None`
/// on hardware), `witness` the person to ask, `stop` polled during motion (see the module
/// docs). A device error that is not a communication one fails its step; a lost link, a
/// restarted device or a stop ends the bring-up with the error.
pub fn bring_up(
    meter: &mut Kerfmeter,
    request: &BringupRequest,
    twin: Option<TwinTruth>,
    witness: &mut dyn Witness,
    mut stop: impl FnMut(&Progress) -> ControlFlow<()>,
) -> Result<BringupReport, Error> {
    request.check()?;
    let info = meter.info()?;
    let status = meter.status()?;
    let diagnostics = meter.diagnostics()?;
    let device = DeviceSeen {
        port: meter.path().to_owned(),
        board: info.hardware.board.to_string(),
        firmware: format!(
            "{}.{}.{}",
            info.firmware.major, info.firmware.minor, info.firmware.patch
        ),
        protocol: format!("{}.{}", info.protocol.major, info.protocol.minor),
        boot_id: format!("{:08x}", info.boot_id),
        driver: diagnostics.map(|d| d.driver.name().to_owned()),
        simulated: twin.is_some(),
    };
    let mut answers = Answers {
        request,
        twin,
        witness,
    };
    let steps = match diagnostics {
        Some(d) => checks(meter, &status, &d, &mut answers, &mut stop)?,
        None => vec![Step::fail(
            StepId::Health,
            format!("protocol {}: no GetDiagnostics", device.protocol),
            "this firmware predates protocol 2.6 and cannot report its health (reset reason, \
             ADC calibration, current sense, encoder): flash the current firmware \
             (`cargo xtask flash`) and run the bring-up again",
        )],
    };
    Ok(BringupReport::new(now_rfc3339(), device, steps))
}

/// The checks of a device that reports its health `d`, in order.
fn checks(
    meter: &mut Kerfmeter,
    status: &Status,
    d: &Diagnostics,
    answers: &mut Answers<'_>,
    stop: &mut impl FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Vec<Step>, Error> {
    let mut steps = vec![
        judge::reset_reason(d),
        judge::adc_calibration(d),
        judge::supply(status, d.driver),
    ];
    steps.push(match status.supply_v {
        Some(v) => judge::supply_meter(v, answers.meter_v(v)),
        None => Step::skipped(
            StepId::SupplyMeter,
            "the device does not measure its supply",
        ),
    });
    steps.push(judge::cs_asleep(d));
    steps.push(judge::encoder(d, status.conditions));
    match motion_refused(&steps, status.conditions) {
        Some(Refusal::Failed(why)) => {
            for id in [StepId::SelfTest, StepId::Direction, StepId::CsBraking] {
                steps.push(Step::skipped(id, why.clone()));
            }
        }
        Some(Refusal::Blocked(why)) => {
            steps.push(Step::fail(StepId::SelfTest, "refused by the device", why));
            for id in [StepId::Direction, StepId::CsBraking] {
                steps.push(Step::skipped(
                    id,
                    "not run: the device refused the self-test",
                ));
            }
        }
        None => motion_checks(meter, &mut steps, answers, stop)?,
    }
    steps.push(gauge_run(meter, &steps, answers, stop)?);
    steps.push(judge::timing(&meter.status()?, answers.twin.is_some()));
    Ok(steps)
}

/// Why the self-test is not run.
enum Refusal {
    /// An earlier step failed (the self-test is skipped).
    Failed(String),
    /// The device would refuse it (the self-test fails, saying why).
    Blocked(String),
}

/// Why the self-test must not run: a failed supply or encoder step, or a condition that
/// would refuse it.
fn motion_refused(steps: &[Step], conditions: Conditions) -> Option<Refusal> {
    let failed: Vec<&str> = steps
        .iter()
        .filter(|s| {
            s.outcome == Outcome::Fail && matches!(s.step, StepId::Supply | StepId::Encoder)
        })
        .map(|s| s.step.title())
        .collect();
    if !failed.is_empty() {
        return Some(Refusal::Failed(format!(
            "not run because the {} step failed: fix it first",
            failed.join(" and ")
        )));
    }
    let blocking = conditions.intersection(Conditions::BLOCKING);
    (!blocking.is_empty()).then(|| {
        Refusal::Blocked(format!(
            "the device refuses to move ({:?}): {}",
            blocking,
            kerfmeter::describe_conditions(blocking)
        ))
    })
}

/// The self-test, the direction of its turn, and the `CS` offset it learnt braking.
fn motion_checks(
    meter: &mut Kerfmeter,
    steps: &mut Vec<Step>,
    answers: &mut Answers<'_>,
    stop: &mut impl FnMut(&Progress) -> ControlFlow<()>,
) -> Result<(), Error> {
    if answers.person_watches() {
        answers.witness.watch_hub();
    }
    let report = match meter.self_test_until(&mut *stop) {
        Ok(report) => report,
        Err(e) if is_step_failure(&e) => {
            steps.push(Step::fail(
                StepId::SelfTest,
                "did not finish",
                e.to_string(),
            ));
            for id in [StepId::Direction, StepId::CsBraking] {
                steps.push(Step::skipped(id, "not run: the self-test did not finish"));
            }
            return Ok(());
        }
        Err(e) => return Err(e),
    };
    let configured = meter.config().ok().map(|c| c.config.torque_per_duty_nm);
    steps.push(judge::self_test(&report, configured));
    steps.push(judge::direction(report.direction_deg, answers.hub_turned()));
    steps.push(match meter.diagnostics()? {
        Some(d) => judge::cs_braking(&d),
        None => Step::not_checked(
            StepId::CsBraking,
            "no reading",
            "the device stopped answering",
        ),
    });
    Ok(())
}

/// A device error that fails a step rather than the bring-up: the device refused or faulted
/// (a stop, a lost link or a restarted device end it).
fn is_step_failure(e: &Error) -> bool {
    e.category() == Category::Device && !matches!(e, Error::Cancelled)
}

/// One run on a cut gauge, when every step before passed and a gauge is under the prongs.
fn gauge_run(
    meter: &mut Kerfmeter,
    steps: &[Step],
    answers: &mut Answers<'_>,
    stop: &mut impl FnMut(&Progress) -> ControlFlow<()>,
) -> Result<Step, Error> {
    let failed: Vec<&str> = steps
        .iter()
        .filter(|s| s.outcome == Outcome::Fail)
        .map(|s| s.step.title())
        .collect();
    if !failed.is_empty() {
        return Ok(Step::skipped(
            StepId::GaugeRun,
            format!(
                "not run: a measurement is not trusted on a device that failed {}",
                failed.join(", ")
            ),
        ));
    }
    let answer = answers.gauge_placed();
    let Some((true, by)) = answer else {
        let by = answer.map(|(_, by)| by);
        return Ok(Step::not_checked(
            StepId::GaugeRun,
            "no gauge under the prongs",
            judge::with_param(
                "cut one (docs/plans.md), lower the prongs into it and say so (",
                "gauge_placed",
                ", or when asked)",
            ),
        )
        .answered_by(by));
    };
    let params = JointSpec::default().run_params(GaugeGeometry::PAPER)?;
    let outcome = meter
        .prepare_for_run_until(&mut *stop)
        .and_then(|()| meter.run_kerfmeter_until(&params, &mut *stop));
    let step = match outcome {
        Ok(result) => judge_run(&result),
        Err(e) if is_step_failure(&e) => Step::fail(
            StepId::GaugeRun,
            "the run did not finish",
            format!(
                "{e}. The self-test passed, so this is what only a run shows: the gauge (no \
                 inset, a prong out of its hole), the magnet or the encoder's bus under load, \
                 the driver under current"
            ),
        ),
        Err(e) => return Err(e),
    };
    Ok(step.answered_by(Some(by)))
}

/// A run's result: passed when no flag distrusts it.
fn judge_run(r: &KerfResult) -> Step {
    let names: Vec<&str> = r.flags.names().collect();
    let seen = format!(
        "kerf {:.1} µm at {:.1}° and {:.3} N·m ({:.1} N), flags: {}",
        r.kerf_um,
        r.angle_deg,
        r.torque_at_jam_nm,
        r.force_at_jam_n,
        if names.is_empty() {
            "none".to_owned()
        } else {
            names.join(", ")
        }
    );
    if r.flags.distrusting().is_empty() {
        return Step::pass(StepId::GaugeRun, seen);
    }
    Step::fail(
        StepId::GaugeRun,
        seen,
        "the device distrusts its reading (its flags are explained in docs/measurement.md): \
         check the gauge's cut and its seat under the prongs, then the flag's own cause",
    )
}

/// Now, in RFC 3339 (UTC, whole seconds).
fn now_rfc3339() -> String {
    let now = jiff::Timestamp::now();
    now.round(jiff::Unit::Second).unwrap_or(now).to_string()
}
