//! Every parameter of the plant in one table: its name, unit, default, plausible range and where
//! the figures come from. The struct, its defaults and the table a user sets them through
//! (`--sim-plant NAME=VALUE`, `--sim-plant-file FILE.json`, `--sim-material NAME`) are generated
//! from the one list in this file, so a parameter cannot exist in one and be missing in another.
//!
//! Defaults are realistic, not ideal: a plant kinder than a bench passes firmware that a real
//! board fails. Ranges are what a real build could plausibly show; `cargo xtask robustness` draws
//! from them.

use core::fmt;
use core::str::FromStr;

/// One parameter of [`PlantParams`]: name, unit, range, description, and how to reach it.
#[derive(Clone, Copy)]
pub struct ParamSpec {
    /// The parameter's name, as the field and on the command line.
    pub name: &'static str,
    /// Its unit ("" for a ratio or a count).
    pub unit: &'static str,
    /// The smallest value it may take.
    pub min: f64,
    /// The largest value it may take.
    pub max: f64,
    /// What it is, and the source of its default and range.
    pub doc: &'static str,
    get: fn(&PlantParams) -> f64,
    set: fn(&mut PlantParams, f64),
}

impl ParamSpec {
    /// Its value in `params`.
    pub fn get(&self, params: &PlantParams) -> f64 {
        (self.get)(params)
    }

    /// Its default.
    pub fn default_value(&self) -> f64 {
        self.get(&PlantParams::default())
    }

    /// Whether `value` is within the range.
    pub fn accepts(&self, value: f64) -> bool {
        (self.min..=self.max).contains(&value)
    }

    /// The first line of its description.
    pub fn summary(&self) -> &'static str {
        self.doc.lines().next().unwrap_or("").trim()
    }
}

impl fmt::Debug for ParamSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ParamSpec")
            .field("name", &self.name)
            .field("unit", &self.unit)
            .field("min", &self.min)
            .field("max", &self.max)
            .finish()
    }
}

/// Generates [`PlantParams`], its `Default` and [`PARAMS`] from one list.
macro_rules! plant_params {
    ($( $(#[doc = $doc:literal])+ $name:ident [$unit:literal] = $default:expr, $min:literal ..= $max:literal; )+) => {
        /// Every parameter of the plant. See [`PARAMS`] for names, units, ranges and sources.
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct PlantParams {
            $( $(#[doc = $doc])+ pub $name: f64, )+
        }

        impl Default for PlantParams {
            fn default() -> Self {
                Self { $( $name: $default, )+ }
            }
        }

        /// Every parameter, in a fixed order.
        pub const PARAMS: &[ParamSpec] = &[
            $( ParamSpec {
                name: stringify!($name),
                unit: $unit,
                min: $min,
                max: $max,
                doc: concat!($($doc, "\n"),+),
                get: |p| p.$name,
                set: |p, v| p.$name = v,
            }, )+
        ];
    };
}

plant_params! {
    // ---- Supply and driver ----
    /// Supply voltage at its source, V.
    /// Reference build 12 V; a laser cutter's usual rail is 24 V. The G2 18v17 runs on 6.5–30 V.
    supply_v ["V"] = 12.0, 6.0..=28.0;
    /// Resistance of the supply and its wiring, Ω: the driver's bus sags by I·R under load.
    /// A wall adapter and a metre of cable: 0.1–0.5 Ω; a stiff bench supply: near 0.
    supply_source_ohm ["Ω"] = 0.2, 0.0..=2.0;
    /// Bus voltage below which the G2 turns its outputs off and pulls FLT low, V.
    /// Its under-voltage lockout sits a little under the 6.5 V minimum operating voltage;
    /// it recovers 0.3 V above this.
    driver_uvlo_v ["V"] = 5.8, 4.5..=6.5;
    /// Relative gain error of the supply-sense divider and ADC.
    /// 1 % divider resistors and the ESP32-C3 ADC's calibration error: ±3 %.
    supply_sense_gain_error [""] = 0.01, -0.05..=0.05;
    /// Noise on the supply-sense reading, V (SD).
    supply_sense_noise_v ["V"] = 0.05, 0.0..=0.5;
    /// Driver current limit, A: above it the G2 chops the bridge at its VREF threshold.
    /// G2 18v17: set by VREF, far above this motor's stall current by default (2–40). While it
    /// chops, the current sense reads nothing in the brake part (Pololu's G2 user's guide).
    max_current_a ["A"] = 20.0, 2.0..=40.0;

    // ---- Motor and gearbox ----
    /// Winding resistance at 25 °C, Ω.
    /// 12 V / 5.6 A stall current of a Pololu 25D HP 12 V motor (1–5).
    resistance_ohm ["Ω"] = 12.0 / 5.6, 1.0..=5.0;
    /// Motor torque constant, N·m/A (= back-EMF constant, V·s/rad).
    /// Chosen so that the stall torque at the output is the reference 0.88 N·m at 12 V (0.005–0.03).
    kt_nm_per_a ["N·m/A"] = 0.88 / (21.0 * 0.7 * 5.6), 0.005..=0.03;
    /// Gear ratio (reference 21:1).
    gear_ratio [""] = 21.0, 10.0..=100.0;
    /// Gearbox efficiency (spur gearbox: 0.6–0.9).
    gear_efficiency [""] = 0.7, 0.6..=0.9;
    /// Rotor inertia, kg·m² (25 mm motor: 2e-7–2e-6).
    rotor_inertia_kgm2 ["kg·m²"] = 5e-7, 2e-7..=2e-6;
    /// Hub and prongs inertia at the output, kg·m² (1e-6–1e-4).
    hub_inertia_kgm2 ["kg·m²"] = 2e-5, 1e-6..=1e-4;
    /// Gearbox static friction at the output, N·m (0.01–0.08).
    gear_static_nm ["N·m"] = 0.035, 0.01..=0.08;
    /// Gearbox kinetic friction at the output, N·m (about 0.8 × static; never above it).
    gear_kinetic_nm ["N·m"] = 0.028, 0.005..=0.08;

    // ---- Winding temperature ----
    /// Winding temperature when the twin starts, °C (after a long job: 60–100).
    /// Copper's resistance rises about 0.39 %/°C: at 102 °C the winding has 30 % more.
    winding_temp_c ["°C"] = 25.0, 0.0..=120.0;
    /// Ambient temperature the winding cools towards, °C (a laser cutter's enclosure: 15–45).
    ambient_temp_c ["°C"] = 25.0, 0.0..=45.0;
    /// Heat capacity of the winding, J/°C (about 10 g of copper at 0.385 J/(g·°C): 1–20).
    winding_heat_capacity_j_per_c ["J/°C"] = 4.0, 1.0..=20.0;
    /// Thermal resistance from the winding to ambient, °C/W (25 mm gearmotors: 5–40).
    winding_thermal_res_c_per_w ["°C/W"] = 15.0, 3.0..=40.0;

    // ---- Current sense (G2 CS pin into the ESP32-C3's ADC) ----
    /// Noise of the G2's current-sense output, A (SD), independent from one PWM period to the
    /// next: switching spikes and the sense amplifier's noise. The RC filter on the pin leaves
    /// 16 % of it at 1 ms.
    current_noise_a ["A"] = 0.02, 0.0..=0.5;
    /// The ADC's own noise on the current-sense pin, mV (SD), after the filter: the C3's SAR
    /// at 0 dB, a few of its raw steps of 0.2 mV (0–3).
    adc_noise_mv ["mV"] = 1.0, 0.0..=3.0;
    /// Relative gain error of the G2's current sense against the firmware's 20 mV/A.
    /// Pololu gives "about 20 mV/A" and "approximately 50 mV" offset, with no tolerance: ±10 %.
    cs_gain_error [""] = 0.05, -0.1..=0.1;
    /// The G2's current-sense offset at zero current, mV ("approximately 50 mV"; boards read
    /// 40–65: one reported 60 mV). The firmware learns it awake, braking, before each run and
    /// each self-test.
    cs_offset_mv ["mV"] = 50.0, 40.0..=65.0;
    /// What the G2's current-sense output reads while the driver sleeps (`SLP` low), minus its
    /// offset awake, mV. Pololu documents the offset only awake; the sleep level is not
    /// documented. From 0 V (−40 to −65: an output that
    /// switches off with the driver) to 40 mV above the offset. The default, +10 mV, sits inside
    /// the 30–80 mV band a firmware taking every idle reading for the offset would accept, and
    /// is 2.5 A at the firmware's duty floor of 0.2 (`board::current`).
    cs_sleep_delta_mv ["mV"] = 10.0, -65.0..=40.0;
    /// Time constant of the RC filter on the CS pin, µs: the board's 10 kΩ in series and 100 nF
    /// to ground, 1 ms (firmware `board::current`), which the firmware's duty filter assumes.
    /// 1 % resistors and an X7R capacitor (±10 %, and some 20 % lost to DC bias and
    /// temperature): 0.7–1.2 ms. (No filter at all, as the Pololu board ships, is not a build
    /// the firmware supports; the sense's own tests still model it, at 0.)
    cs_filter_tau_us ["µs"] = kerfmeter_firmware::board::current::CS_FILTER_TAU_US as f64, 700.0..=1200.0;
    /// How far the ADC's sampling instant moves against the 20 kHz PWM each tick, in PWM periods.
    /// The control tick and the PWM run from independent timers: the instant drifts through
    /// the period, and the CS output is valid only in its drive phase (Pololu's G2 user's guide:
    /// not while the bridge brakes, nor while it limits current).
    cs_sample_drift [""] = 0.013, 0.0..=0.5;

    // ---- Timing on the core ----
    /// Spread (SD) of when each control tick actually runs, µs.
    /// Interrupt latency, link work and flash cache misses on a C3 under embassy: tens of µs.
    tick_jitter_us ["µs"] = 25.0, 0.0..=200.0;
    /// How often a tick comes late, per second of running (a healthy loop: well under 1/s; a
    /// busy USB link or cache-missing code: a few per second).
    late_ticks_per_s [""] = 0.5, 0.0..=5.0;
    /// How late a late tick comes, ms (an interrupt storm or a long link pass: 1–5 ms).
    late_tick_ms ["ms"] = 1.5, 0.0..=5.0;
    /// Time a 4 KiB flash sector erase stalls the core, ms.
    /// A typical ESP32-C3 module's flash (GD25Q32, XM25QH32): 45 ms typical, 300–400 ms worst.
    flash_erase_ms ["ms"] = 400.0, 0.0..=1000.0;
    /// Time a flash page write stalls the core, ms (worst case 3 ms per 256 bytes).
    flash_write_ms ["ms"] = 3.0, 0.0..=10.0;
    /// Frames the host sends in each burst (status polls, a GUI refreshing; 0: none).
    host_burst_frames [""] = 6.0, 0.0..=32.0;
    /// Time between the host's bursts, ms.
    host_burst_period_ms ["ms"] = 200.0, 10.0..=5000.0;
    /// Core time the link spends on one frame, µs (COBS, CRC, postcard and the USB FIFO on a
    /// 160 MHz RISC-V core: 20–300 µs for frames of this protocol's sizes).
    frame_cost_us ["µs"] = 60.0, 0.0..=300.0;

    // ---- Encoder (AS5048A) ----
    /// Encoder noise, LSB (AS5048A datasheet: ±1–2 LSB; a weak or distant magnet: up to 4).
    encoder_noise_lsb ["LSB"] = 1.0, 0.0..=4.0;
    /// Amplitude of the encoder's integral non-linearity, degrees, over its 1st–3rd harmonics.
    /// AS5048A datasheet: INL ±0.05° with an ideally placed magnet.
    encoder_inl_deg ["°"] = 0.05, 0.0..=0.5;
    /// Magnet off the sensor's axis, mm: a once-per-turn angle error (this model: 1° per mm).
    /// A press-fitted diametric magnet: 0.05–0.25 mm.
    magnet_offset_mm ["mm"] = 0.1, 0.0..=0.5;
    /// The encoder's AGC with the magnet in place: the gain the AS5048A needs for the field it
    /// sees, set by the magnet's air gap (datasheet: 0.5–2.5 mm; at the design gap it sits
    /// mid-scale). Above 220 the field is weak and every run is flagged `weak-magnet` (a magnet
    /// glued a little too far); the device refuses one beyond 250 (a fault, not a build).
    magnet_agc [""] = 128.0, 60.0..=230.0;

    // ---- The gauge, as a real cutter cuts it ----
    /// SD of each hole centre's position, µm: the cutter's repeatability.
    /// Trotec Speedy 360: ±15 µm at 95 % (ISO 230-2), an SD of 7.5 µm.
    hole_position_sd_um ["µm"] = 7.5, 0.0..=30.0;
    /// SD of the prongs' offset from their holes' centres at zero, µm.
    /// The head returns over the gauge with the cutter's repeatability.
    prong_offset_sd_um ["µm"] = 7.5, 0.0..=50.0;
    /// Kerf at the top of the sheet minus at the bottom, µm (CO2 in 3–6 mm wood: 20–80).
    kerf_taper_um ["µm"] = 40.0, 0.0..=150.0;
    /// SD of the kerf's bias at the place on the bed where the gauges are cut, µm.
    /// The paper's §6.3 and bed maps show a few µm to ±10 µm across a bed.
    kerf_location_sd_um ["µm"] = 5.0, 0.0..=50.0;
    /// Spiral contact stiffness, N per µm of closure, for the full face (see the materials).
    contact_stiffness_n_per_um ["N/µm"] = 15.0, 1.0..=500.0;
    /// Gauge-to-gauge spread of the contact stiffness, as a fraction (SD).
    contact_stiffness_sd_frac [""] = 0.1, 0.0..=0.5;
    /// Normal force at which the spiral contact starts to crush, N: beyond it the face yields,
    /// each further µm costing a tenth of the elastic stiffness, and stays crushed (see the
    /// materials). The contact arc at the jam is some 170 mm² of cut face (4 mm stock): MDF
    /// crushes at some 10 MPa there, cardboard at 1–2 MPa, plywood and acrylic far above. For
    /// scale: the normal force is τ / (c + μ·r), some 150 N at the default 55 N and 220 N at the
    /// 0.8 N·m cap.
    contact_yield_n ["N"] = 1500.0, 100.0..=5000.0;
    /// Friction coefficient in the spiral contact (wood on wood: 0.2–0.5; acrylic: up to 0.6).
    contact_mu [""] = 0.35, 0.1..=0.6;
    /// Gauge-to-gauge spread of the contact's friction coefficient (SD).
    contact_mu_sd [""] = 0.03, 0.0..=0.1;
    /// Inset on the cutting table: static friction, N·m (a 20 mm disc: 0.002–0.03).
    inset_static_nm ["N·m"] = 0.012, 0.001..=0.03;
    /// Inset on the cutting table: kinetic friction, N·m (never above the static).
    inset_kinetic_nm ["N·m"] = 0.010, 0.001..=0.03;
}

/// The materials a gauge may be cut from: each sets the contact's stiffness and friction, their
/// gauge-to-gauge spread, and the inset's friction on the table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Material {
    /// 3–6 mm MDF (the paper's): a soft, even edge. The defaults.
    Mdf,
    /// Birch or poplar plywood: stiffer, with grain and voids spreading it gauge to gauge.
    Plywood,
    /// Cast acrylic: stiff, smooth, little spread.
    Acrylic,
    /// Corrugated or grey board: very soft, very uneven.
    Cardboard,
}

impl Material {
    /// Every material, in a fixed order.
    pub const ALL: [Material; 4] = [
        Material::Mdf,
        Material::Plywood,
        Material::Acrylic,
        Material::Cardboard,
    ];

    /// Its name on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Material::Mdf => "mdf",
            Material::Plywood => "plywood",
            Material::Acrylic => "acrylic",
            Material::Cardboard => "cardboard",
        }
    }

    /// (stiffness N/µm, stiffness SD fraction, μ, μ SD, inset static N·m, inset kinetic N·m,
    /// contact yield N).
    const fn figures(self) -> [f64; 7] {
        match self {
            Material::Mdf => [15.0, 0.1, 0.35, 0.03, 0.012, 0.010, 1500.0],
            Material::Plywood => [40.0, 0.25, 0.4, 0.05, 0.015, 0.012, 4000.0],
            Material::Acrylic => [120.0, 0.05, 0.5, 0.04, 0.006, 0.005, 5000.0],
            Material::Cardboard => [3.0, 0.3, 0.45, 0.06, 0.004, 0.003, 250.0],
        }
    }

    /// Set the material's figures in `params`.
    pub fn apply(self, params: &mut PlantParams) {
        let [k, k_sd, mu, mu_sd, inset_static, inset_kinetic, yield_n] = self.figures();
        params.contact_yield_n = yield_n;
        params.contact_stiffness_n_per_um = k;
        params.contact_stiffness_sd_frac = k_sd;
        params.contact_mu = mu;
        params.contact_mu_sd = mu_sd;
        params.inset_static_nm = inset_static;
        params.inset_kinetic_nm = inset_kinetic;
    }
}

impl fmt::Display for Material {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Material {
    type Err = PlantParamError;
    fn from_str(s: &str) -> Result<Self, PlantParamError> {
        Material::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| PlantParamError::UnknownMaterial(s.to_owned()))
    }
}

/// A parameter that cannot be set.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlantParamError {
    /// No parameter has this name.
    #[error("unknown plant parameter `{0}`; the parameters and their ranges are:\n{table}", table = param_table())]
    Unknown(String),
    /// The value is outside the parameter's range.
    #[error("plant parameter {name} must be between {min} and {max} {unit}, got {value}")]
    OutOfRange {
        /// The parameter.
        name: &'static str,
        /// The value given.
        value: f64,
        /// Its smallest value.
        min: f64,
        /// Its largest value.
        max: f64,
        /// Its unit.
        unit: &'static str,
    },
    /// Two parameters contradict each other.
    #[error("plant parameter {0}")]
    Inconsistent(String),
    /// Not `NAME=VALUE` with a number.
    #[error("`{0}` is not NAME=VALUE with a number (e.g. supply_v=24)")]
    Malformed(String),
    /// A parameter file that cannot be read or is not a flat JSON object of numbers.
    #[error("plant parameter file {path}: {reason}")]
    File {
        /// The file.
        path: String,
        /// What is wrong with it.
        reason: String,
    },
    /// No material has this name.
    #[error("unknown material `{0}`; known materials: mdf, plywood, acrylic, cardboard")]
    UnknownMaterial(String),
}

/// Every parameter with its range and unit, one per line, for error messages and `--help`.
pub fn param_table() -> String {
    PARAMS
        .iter()
        .map(|p| format!("{}  {}\n", param_head(p), p.summary()))
        .collect()
}

/// Every parameter with its range, unit and default, and its whole description (what it is,
/// then where its default and range come from): what `kerfmeter-twin --list-plant` prints.
pub fn param_list() -> String {
    let mut list = String::new();
    for p in PARAMS {
        list.push_str(&param_head(p));
        list.push('\n');
        for line in p.doc.lines().map(str::trim).filter(|l| !l.is_empty()) {
            list.push_str("      ");
            list.push_str(line);
            list.push('\n');
        }
    }
    list
}

/// A parameter's name, range, unit and default on one line.
fn param_head(p: &ParamSpec) -> String {
    format!(
        "  {:<30} {} ..= {} {}  (default {})",
        p.name,
        p.min,
        p.max,
        p.unit,
        six_figures(p.default_value())
    )
}

/// `v` to six significant figures, without trailing zeros (a default worked out from others,
/// such as a resistance from a stall current, prints as 2.14286, not 2.142857142857143).
fn six_figures(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return v.to_string();
    }
    let decimals = (5 - v.abs().log10().floor() as i32).max(0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        text
    }
}

/// The (kinetic, static) friction pairs: kinetic never above static ([`PlantParams::validate`]).
pub const FRICTION_PAIRS: [(&str, &str); 2] = [
    ("gear_kinetic_nm", "gear_static_nm"),
    ("inset_kinetic_nm", "inset_static_nm"),
];

/// The parameter called `name`.
pub fn param(name: &str) -> Result<&'static ParamSpec, PlantParamError> {
    PARAMS
        .iter()
        .find(|p| p.name == name)
        .ok_or_else(|| PlantParamError::Unknown(name.to_owned()))
}

impl PlantParams {
    /// Set the parameter `name` to `value`, within its range.
    pub fn set(&mut self, name: &str, value: f64) -> Result<(), PlantParamError> {
        let spec = param(name)?;
        if !spec.accepts(value) {
            return Err(PlantParamError::OutOfRange {
                name: spec.name,
                value,
                min: spec.min,
                max: spec.max,
                unit: spec.unit,
            });
        }
        (spec.set)(self, value);
        Ok(())
    }

    /// The parameters as a user gives them: the defaults, then a material's figures, then a
    /// parameter file, then `NAME=VALUE` assignments (each later one wins); validated.
    pub fn build(
        material: Option<Material>,
        file: Option<&std::path::Path>,
        assignments: &[String],
    ) -> Result<Self, PlantParamError> {
        let mut params = Self::default();
        if let Some(material) = material {
            material.apply(&mut params);
        }
        if let Some(file) = file {
            params.apply_file(file)?;
        }
        for assignment in assignments {
            params.assign(assignment)?;
        }
        params.validate()?;
        Ok(params)
    }

    /// Apply one `NAME=VALUE` assignment.
    pub fn assign(&mut self, assignment: &str) -> Result<(), PlantParamError> {
        let malformed = || PlantParamError::Malformed(assignment.to_owned());
        let (name, value) = assignment.split_once('=').ok_or_else(malformed)?;
        let value: f64 = value.trim().parse().map_err(|_| malformed())?;
        self.set(name.trim(), value)
    }

    /// Apply every parameter of a JSON object of numbers (`{"supply_v": 24, ...}`), read from
    /// `path`.
    pub fn apply_file(&mut self, path: &std::path::Path) -> Result<(), PlantParamError> {
        let file_error = |reason: String| PlantParamError::File {
            path: path.display().to_string(),
            reason,
        };
        let text = std::fs::read_to_string(path).map_err(|e| file_error(e.to_string()))?;
        let object: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(&text).map_err(|e| file_error(e.to_string()))?;
        for (name, value) in &object {
            let value = value
                .as_f64()
                .ok_or_else(|| file_error(format!("{name}: {value} is not a number")))?;
            // Named with the file, as what is wrong is in it.
            self.set(name, value)
                .map_err(|e| file_error(e.to_string()))?;
        }
        Ok(())
    }

    /// Check every parameter against its range, and the pairs that must agree (kinetic friction
    /// never above static).
    pub fn validate(&self) -> Result<(), PlantParamError> {
        for spec in PARAMS {
            let value = spec.get(self);
            if !spec.accepts(value) {
                return Err(PlantParamError::OutOfRange {
                    name: spec.name,
                    value,
                    min: spec.min,
                    max: spec.max,
                    unit: spec.unit,
                });
            }
        }
        for (kinetic, stat) in FRICTION_PAIRS {
            let (kinetic_nm, static_nm) = (param(kinetic)?.get(self), param(stat)?.get(self));
            if kinetic_nm > static_nm {
                return Err(PlantParamError::Inconsistent(format!(
                    "{kinetic} ({kinetic_nm}) must not exceed {stat} ({static_nm})"
                )));
            }
        }
        Ok(())
    }

    /// The parameters as a JSON object of numbers, in [`PARAMS`] order (what
    /// [`PlantParams::apply_file`] reads back).
    pub fn to_json(&self) -> serde_json::Value {
        PARAMS
            .iter()
            .map(|p| (p.name.to_owned(), serde_json::Value::from(p.get(self))))
            .collect::<serde_json::Map<_, _>>()
            .into()
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn defaults_are_listed_to_six_figures() {
        assert_eq!(six_figures(2.142857142857143), "2.14286");
        assert_eq!(six_figures(0.010689990281827018), "0.01069");
        assert_eq!(six_figures(12.0), "12");
        assert_eq!(six_figures(0.0), "0");
        assert_eq!(six_figures(-0.05), "-0.05");
        assert_eq!(six_figures(2.5e-7), "0.00000025");
        assert_eq!(six_figures(123456789.0), "123456789");
    }

    use super::*;

    #[test]
    fn defaults_are_within_their_ranges_and_names_are_unique() {
        assert_eq!(PlantParams::default().validate(), Ok(()));
        for (i, p) in PARAMS.iter().enumerate() {
            assert!(p.min < p.max, "{}", p.name);
            assert!(!p.summary().is_empty(), "{} has no description", p.name);
            assert!(
                PARAMS[i + 1..].iter().all(|q| q.name != p.name),
                "{}",
                p.name
            );
        }
    }

    #[test]
    fn assignments_set_the_named_field_and_refuse_what_is_out_of_range() {
        let mut p = PlantParams::default();
        p.assign("supply_v=24").unwrap();
        assert_eq!(p.supply_v, 24.0);
        p.assign(" tick_jitter_us = 80 ").unwrap();
        assert_eq!(p.tick_jitter_us, 80.0);
        let err = p.assign("supply_v=40").unwrap_err();
        assert_eq!(
            err.to_string(),
            "plant parameter supply_v must be between 6 and 28 V, got 40"
        );
        assert_eq!(p.supply_v, 24.0, "a refused value changes nothing");
        let unknown = p.assign("supply=12").unwrap_err().to_string();
        assert!(unknown.starts_with("unknown plant parameter `supply`"));
        assert!(
            unknown.contains("supply_v"),
            "lists the valid names: {unknown}"
        );
        assert!(
            unknown.contains("6 ..= 28 V"),
            "with their ranges: {unknown}"
        );
        assert!(matches!(
            p.assign("supply_v"),
            Err(PlantParamError::Malformed(_))
        ));
        assert!(matches!(
            p.assign("supply_v=twelve"),
            Err(PlantParamError::Malformed(_))
        ));
        assert!(p.assign("supply_v=NaN").is_err());
    }

    #[test]
    fn assignments_win_over_the_file_which_wins_over_the_material() {
        let dir = std::env::temp_dir().join(format!("plant-build-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plant.json");
        std::fs::write(&path, r#"{"contact_mu": 0.2, "supply_v": 9}"#).unwrap();
        let p = PlantParams::build(
            Some(Material::Acrylic),
            Some(&path),
            &["supply_v=24".to_owned()],
        )
        .unwrap();
        assert_eq!(p.contact_stiffness_n_per_um, 120.0, "from the material");
        assert_eq!(p.contact_mu, 0.2, "the file over the material");
        assert_eq!(p.supply_v, 24.0, "the assignment over the file");
        let clash = PlantParams::build(None, None, &["gear_kinetic_nm=0.06".to_owned()]);
        assert!(matches!(clash, Err(PlantParamError::Inconsistent(_))));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn kinetic_friction_above_static_is_inconsistent() {
        let mut p = PlantParams::default();
        p.set("gear_kinetic_nm", 0.05).unwrap();
        assert!(matches!(
            p.validate(),
            Err(PlantParamError::Inconsistent(_))
        ));
    }

    #[test]
    fn materials_set_stiffness_friction_and_spread() {
        for material in Material::ALL {
            assert_eq!(material.name().parse::<Material>(), Ok(material));
            let mut p = PlantParams::default();
            material.apply(&mut p);
            assert_eq!(p.validate(), Ok(()), "{material}");
        }
        let mut p = PlantParams::default();
        Material::Cardboard.apply(&mut p);
        assert!(p.contact_stiffness_n_per_um < PlantParams::default().contact_stiffness_n_per_um);
        assert!("glass".parse::<Material>().is_err());
    }

    #[test]
    fn a_file_round_trips_and_a_bad_one_is_named() {
        let dir = std::env::temp_dir().join(format!("plant-params-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("plant.json");
        let p = PlantParams {
            supply_v: 24.0,
            ..PlantParams::default()
        };
        std::fs::write(&path, p.to_json().to_string()).unwrap();
        let mut q = PlantParams::default();
        q.apply_file(&path).unwrap();
        assert_eq!(p, q);
        std::fs::write(&path, r#"{"supply_v": "24"}"#).unwrap();
        let err = q.apply_file(&path).unwrap_err().to_string();
        assert!(err.contains("supply_v: \"24\" is not a number"), "{err}");
        std::fs::write(&path, "[1, 2]").unwrap();
        assert!(q.apply_file(&path).is_err());
        // A name or value the twin refuses is said with the file it is in.
        std::fs::write(&path, r#"{"voltage": 24}"#).unwrap();
        let err = q.apply_file(&path).unwrap_err();
        assert!(matches!(err, PlantParamError::File { .. }), "{err:?}");
        assert!(
            err.to_string()
                .contains("plant.json: unknown plant parameter `voltage`")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
