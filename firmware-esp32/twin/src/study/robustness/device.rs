//! The configuration a draw's device is given: what its owner would set from the motor's and
//! gearbox's datasheets (see the module docs, "How the device is set up").

use kerfmeter_protocol::{DeviceConfig, ParamField};

use crate::plant::PlantParams;

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
