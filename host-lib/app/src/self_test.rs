//! The self-test's items in words: their names, and why one that did not pass failed, from its
//! value. `kerfmeter self-test` lists them; the bring-up's self-test step gives the first.

use kerfmeter::protocol::{SelfTestItem, SelfTestReport, TestOutcome};

/// Motion of the direction check below which the hub counts as not having turned, degrees
/// (the device passes it from 1°).
pub const STILL_DEG: f32 = 1.0;
/// A torque-constant estimate below this fraction of the configured one means no current flowed
/// (what is left is the current sense's noise)...
const NO_CURRENT_FRACTION: f32 = 0.15;
/// ...or below this, N·m, when the configured one is not known (the reference build's 0.88 N·m
/// times that fraction).
const NO_CURRENT_NM: f32 = 0.13;

/// The item names, as printed.
pub const ENCODER_READS: &str = "encoder reads ok";
/// See [`ENCODER_READS`].
pub const MAGNET: &str = "magnet magnitude";
/// See [`ENCODER_READS`].
pub const DIRECTION: &str = "direction";
/// See [`ENCODER_READS`].
pub const TORQUE_CONSTANT: &str = "torque constant";

/// Each item with its name and unit, in the order printed.
pub fn items(r: &SelfTestReport) -> [(&'static str, SelfTestItem, &'static str); 4] {
    [
        (ENCODER_READS, r.encoder_ok_fraction, ""),
        (MAGNET, r.magnet_magnitude, ""),
        (DIRECTION, r.direction_deg, "°"),
        (TORQUE_CONSTANT, r.torque_per_duty_nm, " N·m"),
    ]
}

/// Why the item `name` did not pass, from its value (and, for the torque constant, the
/// configured one, `None` when not known).
pub fn explain(name: &str, item: SelfTestItem, torque_per_duty_nm: Option<f32>) -> String {
    let value = item.value;
    let no_current_nm = torque_per_duty_nm.map_or(NO_CURRENT_NM, |c| c * NO_CURRENT_FRACTION);
    match (item.outcome, name) {
        (TestOutcome::Skipped, _) => "not run: the self-test stopped before it".to_owned(),
        (_, ENCODER_READS) => format!(
            "only {:.0} % of the encoder's reads were good (99 % pass): check the AS5048A's \
             wiring, power and SPI lines",
            value * 100.0
        ),
        (_, MAGNET) => format!(
            "the magnet's field ({value:.0}) is missing or at the edge of the encoder's range: \
             check that the magnet is fitted, centred over the chip and at the right distance"
        ),
        (_, DIRECTION) if value <= -STILL_DEG => format!(
            "the hub turned the wrong way ({value:.1}°) under a clockwise torque: set \
             motor_inverted (or encoder_inverted, if the encoder counts the wrong way)"
        ),
        (_, DIRECTION) => format!(
            "the hub did not turn ({value:.2}°) under a clockwise torque: the motor is \
             disconnected, its supply is off, or the hub is jammed"
        ),
        (_, TORQUE_CONSTANT) if value < no_current_nm => format!(
            "no motor current flowed during the test pulse ({value:.3} N·m per duty): the motor \
             is disconnected or its supply is off"
        ),
        _ => format!(
            "the current drawn at standstill gives {value:.3} N·m per duty, more than 30 % off \
             the configured torque_per_duty_nm{}: check the calibration (torque_per_duty_nm, \
             torque_per_amp_nm), the current-sense filter and gain, and the winding's \
             temperature",
            torque_per_duty_nm.map_or(String::new(), |c| format!(" ({c:.3})"))
        ),
    }
}
