//! The robustness sweep (`cargo xtask robustness --draws N --seed S`): many twins, each with every
//! plant parameter drawn from its documented range ([`PARAMS`](crate::plant::PARAMS)), a kerf and a
//! gauge-to-gauge spread, each running one measurement with `RunParams::DEFAULT` (55 N over three
//! fingers of 4 mm stock) from a reset. A [`Sweep`] may hold some plant parameters at one value in
//! every draw (`--set supply_v=24`: the sweep on a 24 V rail) and run at another force
//! (`--force-n`).
//!
//! # How a draw is made
//!
//! - Each parameter is drawn uniformly between its `min` and `max`, or log-uniformly when its
//!   range spans more than [`LOG_UNIFORM_SPAN`]× with a positive minimum (contact stiffness
//!   1–500 N/µm, hub inertia, inset friction, the host's burst period, …): there each decade is
//!   as likely as the next, which is how such parameters vary between builds. A range starting
//!   at 0 (a filter that may be absent, a stall that may not happen) is drawn uniformly.
//!   [`scale`](fn@scale) decides it from the [`ParamSpec`](crate::plant::ParamSpec) alone, so a
//!   parameter added to the registry is drawn with no change here.
//! - A draw whose parameters contradict each other (kinetic friction above static,
//!   [`PlantParams::validate`](crate::plant::PlantParams::validate)) is drawn again, up to
//!   [`MAX_ATTEMPTS`] times.
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
//!
//! # Where it lives
//!
//! One module each: `scale` (a parameter's draw from its range), `draw` (the sweep and its
//! draws), `device` (the device's configuration), `run` (one draw run), `classify` (its ending
//! classified) and `summary` (the sweep summed up); their public items are re-exported here;
//! tests in `tests`.

mod classify;
mod device;
mod draw;
mod run;
mod scale;
mod summary;

#[cfg(test)]
mod tests;

pub use classify::{Class, classify, distrusted, failure_name};
pub use device::{REFERENCE_SUPPLY_V, device_config};
pub use draw::{Draw, Sweep, reachable_winding_temp_c};
pub use run::{DrawReport, run_draw};
pub use scale::{Scale, fraction_of, scale, value_at};
pub use summary::{ErrorStats, Summary};

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
