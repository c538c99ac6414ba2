//! The draws: what a sweep's draws share ([`Sweep`]), and each draw's plant, kerf, spread and
//! seed from its own streams ([`Draw`]), parameters that contradict each other drawn again, the
//! winding's boot temperature held to what the build can reach.

use kerfmeter_protocol::RunParams;

use super::scale::{fraction_of, value_at};
use super::{KERF_RANGE_UM, KERF_SD_RANGE_UM, MAX_ATTEMPTS};
use crate::TwinOptions;
use crate::plant::{
    COPPER_TEMPCO_PER_C, FRICTION_PAIRS, PARAMS, ParamSpec, PlantParamError, PlantParams, param,
};
use crate::study::stream;

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
