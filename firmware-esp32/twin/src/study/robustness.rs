//! The robustness sweep (`cargo xtask robustness --draws N --seed S`): many twins, each with every
//! plant parameter drawn from its documented range ([`PARAMS`]), a kerf and a gauge-to-gauge
//! spread, each running one measurement with `RunParams::DEFAULT` (55 N over three fingers of
//! 4 mm stock) from a reset. A [`Sweep`] may hold some plant parameters at one value in every
//! draw (`--set supply_v=24`: the sweep on a 24 V rail) and run at another force (`--force-n`).
//!
//! # How a draw is made
//!
//! - Each parameter is drawn uniformly between its `min` and `max`, or log-uniformly when its
//!   range spans more than [`LOG_UNIFORM_SPAN`]× with a positive minimum (contact stiffness
//!   1–500 N/µm, hub inertia, inset friction, the host's burst period, …): there each decade is
//!   as likely as the next, which is how such parameters vary between builds. A range starting
//!   at 0 (a filter that may be absent, a stall that may not happen) is drawn uniformly.
//!   [`scale`] decides it from the [`ParamSpec`] alone, so a parameter added to the registry is
//!   drawn with no change here.
//! - A draw whose parameters contradict each other (kinetic friction above static,
//!   [`PlantParams::validate`]) is drawn again, up to [`MAX_ATTEMPTS`] times.
//! - The winding's temperature at boot is held to what the drawn build can reach
//!   ([`reachable_winding_temp_c`]): between the enclosure's temperature and that plus the
//!   steady rise of the winding stalled at the run's torque cap for good. Only this device
//!   drives the motor, so a winding is hotter than its enclosure by what the device's own
//!   current dissipates (a device restarted mid-job, the case the warm boot is for), and not
//!   colder than it. Drawn independently, a build whose cap draws 0.5 A (a 78:1 gearbox: under
//!   4 °C of rise at 15 °C/W) booted at 118 °C, 30 % less torque than its duty gives, at a duty
//!   too low (0.05) for its current to be measured: a combination no bench shows, which gave
//!   the sweep's largest errors before. Set with `--sim-plant`, a twin still takes any
//!   temperature in the range.
//! - The kerf is uniform in [`KERF_RANGE_UM`], the gauge-to-gauge spread in
//!   [`KERF_SD_RANGE_UM`], the twin's own seed from the draw's stream.
//! - Every value comes from its own stream ([`super::stream`], keyed by the sweep's seed, the
//!   draw's index and the parameter's name): the same seed gives the same draws whatever the
//!   threads, and a parameter added later does not move the others.
//!
//! # How the device is set up
//!
//! Before its run each twin's device is given the configuration its owner would give that build
//! from the motor's and gearbox's datasheets at the reference 12 V and 25 °C ([`device_config`]:
//! gear ratio, torque per duty and per amp, breakaway duty, over-current threshold), as
//! `kerfmeter config` does once per build. A 95:1 gearbox read as the reference 21:1 would only
//! show a misconfigured device. What the configuration cannot know (the supply, the winding's
//! temperature, timing, the encoder's errors, the gauge as cut) is what the sweep tests.
//!
//! # How an ending is classified ([`Class`])
//!
//! A reading is *correct* when its device-added error (reading − truth, the truth from the
//! twin's log for that run id) is within the tolerance; *flagged* when a quality flag that
//! distrusts the number is set ([`distrusted`]: any but the advisory `decimated`, which only
//! says the curve is coarse, and `play-modelled`); otherwise it is an *unflagged wrong
//! reading*, the one ending the issue forbids ("never a wrong number without a flag"). The
//! default tolerance, [`TOLERANCE_UM`], is the device's own accuracy target for this sweep
//! (issue 12: max |error| ≤ 5 µm); in a 4 mm MDF
//! box joint 5 µm of interference is some 8 N of assembly force per finger, a quarter of the
//! fit window. Any other ending is a typed fault or refusal (allowed), or a failure of the sweep
//! itself: no end within the limit, an answer that does not belong, a panic.

use std::collections::BTreeMap;

use kerfmeter_protocol::{DeviceConfig, ErrorCode, ParamField, QualityFlags, RunParams};

use super::{Outcome, configure, mean_sd, measure, quantile, stream};
use crate::plant::{
    COPPER_TEMPCO_PER_C, FRICTION_PAIRS, PARAMS, ParamSpec, PlantParamError, PlantParams, param,
};
use crate::{Twin, TwinOptions};

/// A range spanning more than this ratio (with a positive minimum) is drawn log-uniformly.
pub const LOG_UNIFORM_SPAN: f64 = 10.0;
/// The kerfs drawn, µm (a CO2 cutter in 3–6 mm stock).
pub const KERF_RANGE_UM: (f64, f64) = (50.0, 400.0);
/// The gauge-to-gauge kerf spreads drawn, µm.
pub const KERF_SD_RANGE_UM: (f64, f64) = (0.0, 20.0);
/// Redraws allowed for parameters that contradict each other.
pub const MAX_ATTEMPTS: u32 = 1000;
/// Default tolerance on the device-added error, µm (see the module docs).
pub const TOLERANCE_UM: f64 = 5.0;
/// Ticks the twin runs after booting, before the host's first request.
const SETTLE_TICKS: u64 = 5;

/// How a parameter is drawn from its range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Every value equally likely.
    Uniform,
    /// Every decade equally likely.
    LogUniform,
}

/// How `spec` is drawn: log-uniformly when its range spans more than [`LOG_UNIFORM_SPAN`]× from
/// a positive minimum, uniformly otherwise.
pub fn scale(spec: &ParamSpec) -> Scale {
    if spec.min > 0.0 && spec.max / spec.min > LOG_UNIFORM_SPAN {
        Scale::LogUniform
    } else {
        Scale::Uniform
    }
}

/// The value of `spec` at the fraction `u` (0..1) of its range, on its [`scale`].
pub fn value_at(spec: &ParamSpec, u: f64) -> f64 {
    let value = match scale(spec) {
        Scale::Uniform => spec.min + u * (spec.max - spec.min),
        Scale::LogUniform => (spec.min.ln() + u * (spec.max / spec.min).ln()).exp(),
    };
    value.clamp(spec.min, spec.max)
}

/// Where `value` lies in `spec`'s range on its [`scale`], 0..=1 (for "how unusual is this").
pub fn fraction_of(spec: &ParamSpec, value: f64) -> f64 {
    match scale(spec) {
        Scale::Uniform => (value - spec.min) / (spec.max - spec.min),
        Scale::LogUniform => (value / spec.min).ln() / (spec.max / spec.min).ln(),
    }
}

/// What every draw of a sweep shares: its seed, the plant parameters held at one value, the run.
#[derive(Clone)]
pub struct Sweep {
    /// The sweep's seed.
    pub seed: u64,
    /// Plant parameters held at one value in every draw instead of drawn (a sweep at one
    /// supply voltage, say), each within its range.
    pub fixed: Vec<(&'static ParamSpec, f64)>,
    /// The run each draw measures with.
    pub run: RunParams,
}

impl Sweep {
    /// The sweep with `seed`: every parameter drawn, `RunParams::DEFAULT`.
    pub fn new(seed: u64) -> Self {
        Self {
            seed,
            fixed: Vec::new(),
            run: RunParams::DEFAULT,
        }
    }

    /// Hold the parameter `name` at `value` in every draw: within its range, and leaving a
    /// consistent friction pair possible (a held kinetic friction not above its static partner's
    /// range or held value), or an error and nothing held.
    pub fn fix(&mut self, name: &str, value: f64) -> Result<(), PlantParamError> {
        PlantParams::default().set(name, value)?;
        let spec = param(name)?;
        let mut fixed = self.fixed.clone();
        fixed.retain(|(held, _)| held.name != spec.name);
        fixed.push((spec, value));
        for (kinetic, stat) in FRICTION_PAIRS {
            let lowest_kinetic = held_value(&fixed, kinetic).unwrap_or(param(kinetic)?.min);
            let highest_static = held_value(&fixed, stat).unwrap_or(param(stat)?.max);
            if lowest_kinetic > highest_static {
                return Err(PlantParamError::Inconsistent(format!(
                    "{kinetic} ({lowest_kinetic}) must not exceed {stat} (at most {highest_static})"
                )));
            }
        }
        self.fixed = fixed;
        Ok(())
    }

    /// Draw number `index`.
    pub fn draw(&self, index: u32) -> Draw {
        let seed = self.seed;
        let uniform =
            |key: &str, (lo, hi): (f64, f64)| lo + stream(seed, index, key).uniform() * (hi - lo);
        Draw {
            seed,
            index,
            twin_seed: stream(seed, index, "twin_seed").next_u64(),
            kerf_um: uniform("kerf_um", KERF_RANGE_UM),
            kerf_sd_um: uniform("kerf_sd_um", KERF_SD_RANGE_UM),
            plant: draw_plant(seed, index, &self.fixed),
            run: self.run,
        }
    }
}

/// One draw: a twin's kerf, spread, seed and every plant parameter, and the run it measures.
#[derive(Debug, Clone, PartialEq)]
pub struct Draw {
    /// The sweep's seed.
    pub seed: u64,
    /// The draw's index in the sweep.
    pub index: u32,
    /// The twin's own seed (its noise and its gauges).
    pub twin_seed: u64,
    /// The cutter's kerf, µm.
    pub kerf_um: f64,
    /// Its gauge-to-gauge spread (SD), µm.
    pub kerf_sd_um: f64,
    /// Every plant parameter.
    pub plant: PlantParams,
    /// The run it measures with.
    pub run: RunParams,
}

impl Draw {
    /// Draw number `index` of the sweep with `seed`, nothing held, the default run.
    pub fn new(seed: u64, index: u32) -> Self {
        Sweep::new(seed).draw(index)
    }

    /// The twin this draw builds.
    pub fn options(&self) -> TwinOptions {
        TwinOptions {
            kerf_um: self.kerf_um,
            kerf_sd_um: self.kerf_sd_um,
            seed: self.twin_seed,
            plant: self.plant,
            ..TwinOptions::default()
        }
    }

    /// The parameters furthest from their defaults (as a fraction of their range, on its
    /// scale), most unusual first: what to look at first in a bad draw.
    pub fn most_unusual(&self, n: usize) -> Vec<(&'static ParamSpec, f64)> {
        let mut by_distance: Vec<(&'static ParamSpec, f64, f64)> = PARAMS
            .iter()
            .map(|spec| {
                let value = spec.get(&self.plant);
                let distance =
                    (fraction_of(spec, value) - fraction_of(spec, spec.default_value())).abs();
                (spec, value, distance)
            })
            .collect();
        by_distance.sort_by(|a, b| b.2.total_cmp(&a.2));
        by_distance
            .into_iter()
            .take(n)
            .map(|(spec, value, _)| (spec, value))
            .collect()
    }
}

/// The value `name` is held at, if it is.
fn held_value(fixed: &[(&'static ParamSpec, f64)], name: &str) -> Option<f64> {
    fixed
        .iter()
        .find(|(held, _)| held.name == name)
        .map(|&(_, value)| value)
}

/// Every plant parameter of draw `index`, those `fixed` at their values, redrawn until
/// consistent. Where one side of a friction pair is held, the other is brought to it instead
/// (kinetic no higher, static no lower: [`Sweep::fix`] made sure it can be), since a held value
/// near its partner's limit would leave few draws consistent. A held winding temperature is
/// taken as it is, not held to what the build can reach. Other parameters' draws do not move.
fn draw_plant(seed: u64, index: u32, fixed: &[(&'static ParamSpec, f64)]) -> PlantParams {
    for attempt in 0..MAX_ATTEMPTS {
        let mut plant = PlantParams::default();
        for spec in PARAMS {
            let key = format!("{}#{attempt}", spec.name);
            let drawn = value_at(spec, stream(seed, index, &key).uniform());
            let value = held_value(fixed, spec.name).unwrap_or(drawn);
            plant
                .set(spec.name, value)
                .expect("a value drawn or held within the range is accepted");
        }
        meet_held_frictions(&mut plant, fixed);
        if plant.validate().is_ok() {
            if held_value(fixed, "winding_temp_c").is_none() {
                plant.winding_temp_c = reachable_winding_temp_c(&plant);
            }
            return plant;
        }
    }
    panic!(
        "no consistent plant parameters in {MAX_ATTEMPTS} draws: check the ranges and the values held"
    );
}

/// Bring the drawn side of each friction pair with one side held to the held one.
fn meet_held_frictions(plant: &mut PlantParams, fixed: &[(&'static ParamSpec, f64)]) {
    for (kinetic, stat) in FRICTION_PAIRS {
        let value = |name| param(name).expect("a known name").get(plant);
        let (kinetic_nm, static_nm) = (value(kinetic), value(stat));
        let met = match (held_value(fixed, kinetic), held_value(fixed, stat)) {
            (Some(_), None) if static_nm < kinetic_nm => plant.set(stat, kinetic_nm),
            (None, Some(_)) if kinetic_nm > static_nm => plant.set(kinetic, static_nm),
            _ => Ok(()),
        };
        met.expect("Sweep::fix left the partner's range room for the held value");
    }
}

/// The drawn boot temperature of the winding, held to what the build can reach (module docs):
/// no colder than the enclosure, no hotter than the enclosure plus the steady rise of the
/// winding stalled at the run's torque cap (or at full duty, if that draws less) for good,
/// `I²·R(120 °C)·R_th`: more than any sequence of runs heats it.
pub fn reachable_winding_temp_c(plant: &PlantParams) -> f64 {
    let per_amp_nm = plant.gear_ratio * plant.gear_efficiency * plant.kt_nm_per_a;
    let cap_a = (f64::from(RunParams::DEFAULT.max_torque_nm) / per_amp_nm)
        .min(plant.supply_v / plant.resistance_ohm);
    let hot_ohm = plant.resistance_ohm * (1.0 + COPPER_TEMPCO_PER_C * (HOTTEST_WINDING_C - 25.0));
    let rise_c = cap_a * cap_a * hot_ohm * plant.winding_thermal_res_c_per_w;
    plant
        .winding_temp_c
        .clamp(plant.ambient_temp_c, plant.ambient_temp_c + rise_c)
}

/// The hottest winding the sweep draws, °C (the top of `winding_temp_c`'s range).
const HOTTEST_WINDING_C: f64 = 120.0;

/// Supply voltage the datasheet figures of a build are given at, V.
pub const REFERENCE_SUPPLY_V: f64 = 12.0;

/// The configuration the owner of a build with `plant`'s motor and gearbox gives the device:
/// their datasheet figures at [`REFERENCE_SUPPLY_V`] and 25 °C, each within the device's range.
/// For the default plant this is the device's default configuration.
pub fn device_config(plant: &PlantParams) -> DeviceConfig {
    let per_amp_nm = plant.gear_ratio * plant.gear_efficiency * plant.kt_nm_per_a;
    let stall_a = REFERENCE_SUPPLY_V / plant.resistance_ohm;
    let per_duty_nm = per_amp_nm * stall_a;
    let defaults = DeviceConfig::DEFAULT;
    // The default threshold's margin over the reference motor's stall current.
    let margin = f64::from(defaults.max_current_a) / 5.6;
    let within = |value: f64, field: ParamField| {
        let (lo, hi) = field.range();
        (value as f32).clamp(lo, hi)
    };
    DeviceConfig {
        torque_per_duty_nm: within(per_duty_nm, ParamField::TorquePerDutyNm),
        breakaway_duty: within(
            plant.gear_static_nm / per_duty_nm,
            ParamField::BreakawayDuty,
        ),
        gear_ratio: within(plant.gear_ratio, ParamField::GearRatio),
        max_current_a: within(stall_a * margin, ParamField::MaxCurrentA),
        torque_per_amp_nm: within(per_amp_nm, ParamField::TorquePerAmpNm),
        ..defaults
    }
}

/// What a draw ended in.
#[derive(Debug, Clone, PartialEq)]
pub struct DrawReport {
    /// The draw.
    pub draw: Draw,
    /// How its measurement ended.
    pub outcome: Outcome,
    /// Whether the motor was in its safe state when it ended (`None` after a panic).
    pub motor_safe: Option<bool>,
    /// Simulated time the twin ran, ms.
    pub sim_ms: u64,
}

/// Build the draw's twin and run its one measurement, catching a panic.
pub fn run_draw(draw: &Draw) -> DrawReport {
    let options = draw.options();
    let run = draw.run;
    let ran = std::panic::catch_unwind(move || {
        let mut twin = Twin::new(options);
        twin.advance_ticks(SETTLE_TICKS);
        let outcome = match configure(&mut twin, &device_config(&options.plant)) {
            Ok(()) => measure(&mut twin, &run),
            Err(ending) => ending,
        };
        (outcome, twin.motor_safe(), twin.now_us() / 1000)
    });
    let (outcome, motor_safe, sim_ms) = match ran {
        Ok((outcome, safe, sim_ms)) => (outcome, Some(safe), sim_ms),
        Err(payload) => (Outcome::Panic(panic_text(payload.as_ref())), None, 0),
    };
    DrawReport {
        draw: draw.clone(),
        outcome,
        motor_safe,
        sim_ms,
    }
}

fn panic_text(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_owned())
}

/// Whether `flags` distrust the number: any flag but the advisory ones
/// ([`QualityFlags::ADVISORY`]: `decimated`, `play-modelled`).
pub fn distrusted(flags: QualityFlags) -> bool {
    !flags.distrusting().is_empty()
}

/// What an ending counts as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Class {
    /// A reading within the tolerance, not distrusted.
    Correct,
    /// A reading with a flag that distrusts it (right or wrong).
    Flagged,
    /// A reading off by more than the tolerance with no flag: what must never happen.
    UnflaggedWrong,
    /// A typed fault (allowed: the device said why).
    Fault,
    /// A typed refusal (allowed).
    Refused,
    /// No result and no fault within the limit.
    NoEnd,
    /// An answer that does not belong to the request.
    Unexpected,
    /// A panic.
    Panic,
}

impl Class {
    /// Its name in reports.
    pub const fn name(self) -> &'static str {
        match self {
            Class::Correct => "correct",
            Class::Flagged => "flagged",
            Class::UnflaggedWrong => "unflagged_wrong",
            Class::Fault => "fault",
            Class::Refused => "refused",
            Class::NoEnd => "no_end",
            Class::Unexpected => "unexpected",
            Class::Panic => "panic",
        }
    }

    /// Whether this ending is allowed by the sweep's rules (a reading or a typed fault or
    /// refusal), leaving aside whether an unflagged reading is right.
    pub fn ends_properly(self) -> bool {
        !matches!(self, Class::NoEnd | Class::Unexpected | Class::Panic)
    }
}

/// The class of `outcome` with the tolerance `tolerance_um` on the device-added error.
pub fn classify(outcome: &Outcome, tolerance_um: f64) -> Class {
    match outcome {
        Outcome::Reading { result, .. } => {
            let error = outcome.error_um().unwrap_or(f64::NAN);
            if distrusted(result.flags) {
                Class::Flagged
            } else if error.abs() <= tolerance_um {
                Class::Correct
            } else {
                Class::UnflaggedWrong
            }
        }
        Outcome::Fault { .. } => Class::Fault,
        Outcome::Refused { .. } => Class::Refused,
        Outcome::NoEnd { .. } => Class::NoEnd,
        Outcome::Unexpected { .. } => Class::Unexpected,
        Outcome::Panic(_) => Class::Panic,
    }
}

/// The name of an ending that is not a reading, by its type: `fault OverCurrent (run)`,
/// `refused NotAtZero (run)`, `no end (reset, Resetting)`, ...
pub fn failure_name(outcome: &Outcome) -> Option<String> {
    Some(match outcome {
        Outcome::Reading { .. } => return None,
        Outcome::Fault { phase, fault } => format!("fault {fault:?} ({})", phase.name()),
        // The figures of a supply refusal differ from draw to draw: counted by kind.
        Outcome::Refused {
            phase,
            code: ErrorCode::SupplyTooLow { .. },
        } => format!("refused SupplyTooLow ({})", phase.name()),
        Outcome::Refused { phase, code } => format!("refused {code:?} ({})", phase.name()),
        Outcome::NoEnd { phase, state } => format!("no end ({}, {state:?})", phase.name()),
        Outcome::Unexpected { phase, .. } => format!("unexpected answer ({})", phase.name()),
        Outcome::Panic(_) => "panic".to_owned(),
    })
}

/// Device-added error statistics, µm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    /// Readings.
    pub n: usize,
    /// Mean error.
    pub mean_um: f64,
    /// Its standard deviation.
    pub sd_um: f64,
    /// 95th percentile of |error|.
    pub p95_abs_um: f64,
    /// Largest |error|.
    pub max_abs_um: f64,
}

impl ErrorStats {
    /// Statistics of `errors`.
    pub fn of(errors: &[f64]) -> Self {
        let (mean_um, sd_um) = mean_sd(errors);
        let abs: Vec<f64> = errors.iter().map(|e| e.abs()).collect();
        Self {
            n: errors.len(),
            mean_um,
            sd_um,
            p95_abs_um: quantile(&abs, 0.95),
            max_abs_um: abs.iter().copied().fold(f64::NAN, f64::max),
        }
    }
}

/// A sweep's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Draws run.
    pub draws: usize,
    /// Draw indices by class.
    pub by_class: BTreeMap<Class, Vec<u32>>,
    /// Draw indices of every ending that is not a reading, by [`failure_name`].
    pub failures: BTreeMap<String, Vec<u32>>,
    /// Error of every reading.
    pub all_readings: ErrorStats,
    /// Error of the readings no flag distrusts.
    pub unflagged_readings: ErrorStats,
    /// Draw indices of the readings, largest |error| first.
    pub worst: Vec<u32>,
    /// Draws that ended with the motor not in its safe state (or panicked).
    pub motor_unsafe: Vec<u32>,
}

impl Summary {
    /// The figures of `reports` with `tolerance_um`.
    pub fn of(reports: &[DrawReport], tolerance_um: f64) -> Self {
        let mut by_class: BTreeMap<Class, Vec<u32>> = BTreeMap::new();
        let mut failures: BTreeMap<String, Vec<u32>> = BTreeMap::new();
        let (mut all, mut unflagged, mut readings) = (Vec::new(), Vec::new(), Vec::new());
        for report in reports {
            let index = report.draw.index;
            let class = classify(&report.outcome, tolerance_um);
            by_class.entry(class).or_default().push(index);
            if let Some(name) = failure_name(&report.outcome) {
                failures.entry(name).or_default().push(index);
            }
            if let Some(error) = report.outcome.error_um() {
                all.push(error);
                readings.push((index, error.abs()));
                if class != Class::Flagged {
                    unflagged.push(error);
                }
            }
        }
        readings.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        Self {
            draws: reports.len(),
            by_class,
            failures,
            all_readings: ErrorStats::of(&all),
            unflagged_readings: ErrorStats::of(&unflagged),
            worst: readings.into_iter().map(|(index, _)| index).collect(),
            motor_unsafe: reports
                .iter()
                .filter(|r| r.motor_safe != Some(true))
                .map(|r| r.draw.index)
                .collect(),
        }
    }

    /// Draw indices of `class`.
    pub fn of_class(&self, class: Class) -> &[u32] {
        self.by_class.get(&class).map_or(&[], Vec::as_slice)
    }

    /// Draws that ended in a reading.
    pub fn readings(&self) -> usize {
        self.all_readings.n
    }

    /// Whether every draw ended properly (a reading or a typed fault or refusal) with the motor
    /// safe: what the short sweep in `cargo xtask test` asserts.
    pub fn all_ended_safely(&self) -> bool {
        self.motor_unsafe.is_empty()
            && self
                .by_class
                .iter()
                .all(|(class, draws)| class.ends_properly() || draws.is_empty())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::Phase;
    use kerfmeter_protocol::{Fault, KerfResult};

    #[test]
    fn every_drawn_parameter_is_within_its_range_and_consistent() {
        for index in 0..50 {
            let draw = Draw::new(7, index);
            assert_eq!(draw.plant.validate(), Ok(()));
            assert_eq!(draw.options().validate(), Ok(()));
            assert!((KERF_RANGE_UM.0..=KERF_RANGE_UM.1).contains(&draw.kerf_um));
            assert!((KERF_SD_RANGE_UM.0..=KERF_SD_RANGE_UM.1).contains(&draw.kerf_sd_um));
        }
    }

    #[test]
    fn draws_are_deterministic_for_a_seed_and_differ_between_draws_and_seeds() {
        assert_eq!(Draw::new(3, 4), Draw::new(3, 4));
        assert_ne!(Draw::new(3, 4).plant, Draw::new(3, 5).plant);
        assert_ne!(Draw::new(3, 4).plant, Draw::new(4, 4).plant);
        assert_ne!(Draw::new(3, 4).twin_seed, Draw::new(3, 5).twin_seed);
    }

    #[test]
    fn a_held_parameter_is_the_same_in_every_draw_and_moves_no_other() {
        let mut sweep = Sweep::new(3);
        sweep.fix("supply_v", 24.0).unwrap();
        for index in 0..20 {
            let (held, free) = (sweep.draw(index), Draw::new(3, index));
            assert_eq!(held.plant.supply_v, 24.0);
            assert_eq!(held.kerf_um, free.kerf_um);
            assert_eq!(held.plant.gear_ratio, free.plant.gear_ratio);
            assert_eq!(held.plant.validate(), Ok(()));
        }
        // The last value given wins; a value out of range or an unknown name is refused.
        sweep.fix("supply_v", 9.0).unwrap();
        assert_eq!(sweep.draw(0).plant.supply_v, 9.0);
        assert_eq!(sweep.fixed.len(), 1);
        assert!(matches!(
            sweep.fix("supply_v", 40.0),
            Err(PlantParamError::OutOfRange { .. })
        ));
        assert!(matches!(
            sweep.fix("supply_volts", 12.0),
            Err(PlantParamError::Unknown(_))
        ));
    }

    #[test]
    fn a_held_friction_brings_its_partner_and_a_held_winding_temperature_stays() {
        let mut sweep = Sweep::new(5);
        // Above most static frictions drawn: each is raised to it, none is drawn in vain.
        sweep.fix("gear_kinetic_nm", 0.079).unwrap();
        sweep.fix("inset_static_nm", 0.0011).unwrap();
        sweep.fix("winding_temp_c", 120.0).unwrap();
        for index in 0..30 {
            let plant = sweep.draw(index).plant;
            assert_eq!(plant.validate(), Ok(()));
            assert!(plant.gear_static_nm >= 0.079, "{}", plant.gear_static_nm);
            assert!(
                plant.inset_kinetic_nm <= 0.0011,
                "{}",
                plant.inset_kinetic_nm
            );
            assert_eq!(plant.winding_temp_c, 120.0);
        }
        // A pair that cannot agree is refused, and the earlier holds stand.
        assert!(matches!(
            sweep.fix("gear_static_nm", 0.05),
            Err(PlantParamError::Inconsistent(_))
        ));
        assert!(matches!(
            sweep.fix("inset_kinetic_nm", 0.02),
            Err(PlantParamError::Inconsistent(_))
        ));
        assert_eq!(sweep.fixed.len(), 3);
    }

    #[test]
    fn wide_positive_ranges_are_log_uniform_and_the_rest_uniform() {
        let stiffness = param("contact_stiffness_n_per_um").unwrap();
        assert_eq!(scale(stiffness), Scale::LogUniform);
        assert_eq!(scale(param("supply_v").unwrap()), Scale::Uniform);
        // A range from 0 cannot be log-uniform.
        assert_eq!(scale(param("cs_filter_tau_us").unwrap()), Scale::Uniform);
        // Log-uniform: the geometric middle at the middle of the fraction.
        let middle = value_at(stiffness, 0.5);
        assert!((middle - (1.0f64 * 500.0).sqrt()).abs() < 1e-9, "{middle}");
        assert_eq!(value_at(stiffness, 0.0), 1.0);
        assert!((fraction_of(stiffness, middle) - 0.5).abs() < 1e-12);
        // Over many draws each decade of 1–500 N/µm is about equally likely.
        let below_10 = (0..400)
            .filter(|&i| Draw::new(11, i).plant.contact_stiffness_n_per_um < 10.0)
            .count();
        let expected = 400.0 * 10f64.ln() / 500f64.ln();
        assert!(
            (below_10 as f64 - expected).abs() < 40.0,
            "{below_10} of 400 below 10 N/µm, expected about {expected:.0}"
        );
        let supply_below_17 = (0..400)
            .filter(|&i| Draw::new(11, i).plant.supply_v < 17.0)
            .count();
        assert!(
            (160..=240).contains(&supply_below_17),
            "{supply_below_17} of 400 supplies below the middle of 6–28 V"
        );
    }

    fn reading(kerf_um: f32, truth_um: f64, flags: QualityFlags) -> Outcome {
        Outcome::Reading {
            result: KerfResult {
                run_id: 1,
                kerf_um,
                angle_deg: 60.0,
                play_deg: 4.5,
                torque_at_jam_nm: 0.5,
                force_at_jam_n: 55.0,
                flags,
            },
            truth_um,
        }
    }

    #[test]
    fn the_boot_temperature_is_held_to_what_the_build_can_reach() {
        // The reference build stalled at 0.8 N·m draws 5 A: hundreds of degrees of rise, so
        // any drawn temperature above the enclosure's stands, and one below it is raised to it.
        let hot = PlantParams {
            winding_temp_c: 110.0,
            ambient_temp_c: 20.0,
            ..PlantParams::default()
        };
        assert_eq!(reachable_winding_temp_c(&hot), 110.0);
        let cold = PlantParams {
            winding_temp_c: 5.0,
            ..hot
        };
        assert_eq!(reachable_winding_temp_c(&cold), 20.0);
        // A 95:1 gearbox draws 1.1 A at the cap, 3.7 W in the hot winding: 11 °C above the
        // enclosure at 3 °C/W.
        let geared = PlantParams {
            gear_ratio: 95.0,
            winding_thermal_res_c_per_w: 3.0,
            ..hot
        };
        let t = reachable_winding_temp_c(&geared);
        assert!((30.0..32.0).contains(&t), "{t}");
        // Every draw is within its range and the rule.
        for index in 0..50 {
            let plant = Draw::new(5, index).plant;
            assert_eq!(reachable_winding_temp_c(&plant), plant.winding_temp_c);
        }
    }

    #[test]
    fn the_default_build_is_configured_as_the_device_defaults() {
        let config = device_config(&PlantParams::default());
        let defaults = DeviceConfig::DEFAULT;
        let close = |a: f32, b: f32| (a - b).abs() <= 0.002 * b.abs().max(1.0);
        assert!(
            close(config.torque_per_duty_nm, defaults.torque_per_duty_nm),
            "{config:?}"
        );
        assert!(
            close(config.breakaway_duty, defaults.breakaway_duty),
            "{config:?}"
        );
        assert!(close(config.gear_ratio, defaults.gear_ratio), "{config:?}");
        assert!(
            close(config.max_current_a, defaults.max_current_a),
            "{config:?}"
        );
        assert!(
            close(config.torque_per_amp_nm, defaults.torque_per_amp_nm),
            "{config:?}"
        );
        for index in 0..50 {
            assert_eq!(device_config(&Draw::new(5, index).plant).validate(), Ok(()));
        }
        let geared = PlantParams {
            gear_ratio: 42.0,
            ..PlantParams::default()
        };
        assert!(close(device_config(&geared).torque_per_duty_nm, 1.76));
    }

    #[test]
    fn endings_are_classified_by_error_flag_and_type() {
        let none = QualityFlags::empty();
        assert_eq!(classify(&reading(152.0, 150.0, none), 5.0), Class::Correct);
        assert_eq!(
            classify(&reading(157.0, 150.0, none), 5.0),
            Class::UnflaggedWrong
        );
        assert_eq!(
            classify(&reading(143.0, 150.0, none), 5.0),
            Class::UnflaggedWrong
        );
        let limited = QualityFlags::TORQUE_LIMITED;
        assert_eq!(
            classify(&reading(170.0, 150.0, limited), 5.0),
            Class::Flagged
        );
        // A decimated curve does not excuse a wrong number.
        assert_eq!(
            classify(&reading(170.0, 150.0, QualityFlags::DECIMATED), 5.0),
            Class::UnflaggedWrong
        );
        let fault = Outcome::Fault {
            phase: Phase::Run,
            fault: Fault::OverCurrent,
        };
        assert_eq!(classify(&fault, 5.0), Class::Fault);
        assert_eq!(
            failure_name(&fault).as_deref(),
            Some("fault OverCurrent (run)")
        );
        assert_eq!(classify(&Outcome::Panic("x".into()), 5.0), Class::Panic);
        assert!(!Class::Panic.ends_properly());
        assert!(Class::UnflaggedWrong.ends_properly());
    }

    #[test]
    fn a_summary_counts_classes_errors_and_the_worst_first() {
        let report = |index, outcome, safe| DrawReport {
            draw: Draw::new(1, index),
            outcome,
            motor_safe: Some(safe),
            sim_ms: 0,
        };
        let none = QualityFlags::empty();
        let reports = [
            report(0, reading(151.0, 150.0, none), true),
            report(1, reading(140.0, 150.0, none), true),
            report(
                2,
                Outcome::Refused {
                    phase: Phase::Run,
                    code: kerfmeter_protocol::ErrorCode::NotAtZero,
                },
                true,
            ),
            report(3, reading(153.0, 150.0, QualityFlags::NOISY_HOLD), true),
        ];
        let summary = Summary::of(&reports, 5.0);
        assert_eq!(summary.readings(), 3);
        assert_eq!(summary.of_class(Class::UnflaggedWrong), &[1]);
        assert_eq!(summary.of_class(Class::Correct), &[0]);
        assert_eq!(summary.worst, vec![1, 3, 0]);
        assert_eq!(summary.unflagged_readings.n, 2);
        assert_eq!(summary.all_readings.max_abs_um, 10.0);
        assert_eq!(
            summary.failures.keys().collect::<Vec<_>>(),
            ["refused NotAtZero (run)"]
        );
        assert!(summary.all_ended_safely());
        let unsafe_motor = Summary::of(&[report(0, reading(151.0, 150.0, none), false)], 5.0);
        assert!(!unsafe_motor.all_ended_safely());
    }

    #[test]
    fn a_draw_runs_to_an_ending_with_the_motor_safe() {
        let report = run_draw(&Draw::new(1, 0));
        assert!(
            classify(&report.outcome, TOLERANCE_UM).ends_properly(),
            "{report:?}"
        );
        assert_eq!(report.motor_safe, Some(true));
        assert_eq!(report, run_draw(&Draw::new(1, 0)), "deterministic");
    }
}
