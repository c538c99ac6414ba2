//! The numbers of GRBL 1.1's `$N` settings that this project reads or sets, and the values a
//! stock GRBL 1.1 reports for every setting ([`STOCK`]). Per-axis settings are X, Y, Z arrays.

/// `$12`: the arc tolerance, mm (how far the segments GRBL cuts an arc into may stray).
pub const ARC_TOLERANCE_MM: u16 = 12;
/// `$13`: report inches (1) or mm (0).
pub const REPORT_INCHES: u16 = 13;
/// `$20`: soft limits (1 on).
pub const SOFT_LIMITS: u16 = 20;
/// `$21`: hard limits (1 on).
pub const HARD_LIMITS: u16 = 21;
/// `$22`: homing (1 enabled).
pub const HOMING: u16 = 22;
/// `$23`: the axes that home toward negative (a mask: 1 X, 2 Y, 4 Z).
pub const HOMING_DIR_MASK: u16 = 23;
/// `$27`: the homing pull-off, mm.
pub const HOMING_PULLOFF_MM: u16 = 27;
/// `$30`: the `S` value of full power (the spindle's maximum).
pub const MAX_POWER_S: u16 = 30;
/// `$32`: laser mode (1 on).
pub const LASER_MODE: u16 = 32;
/// `$110`–`$112`: the X, Y and Z maximum rates, mm/min.
pub const MAX_RATE_MM_PER_MIN: [u16; 3] = [110, 111, 112];
/// `$120`–`$122`: the X, Y and Z accelerations, mm/s².
pub const ACCELERATION_MM_PER_S2: [u16; 3] = [120, 121, 122];
/// `$130`–`$132`: the X, Y and Z travel, mm.
pub const MAX_TRAVEL_MM: [u16; 3] = [130, 131, 132];

/// GRBL's default `$30`: the `S` of full power when not told otherwise.
pub const DEFAULT_MAX_POWER_S: f64 = 1000.0;

/// Every setting of GRBL 1.1 and the value a stock build reports (laser mode off).
pub const STOCK: [(u16, f64); 34] = [
    (0, 10.0),
    (1, 25.0),
    (2, 0.0),
    (3, 0.0),
    (4, 0.0),
    (5, 0.0),
    (6, 0.0),
    (10, 1.0),
    (11, 0.010),
    (ARC_TOLERANCE_MM, 0.002),
    (REPORT_INCHES, 0.0),
    (SOFT_LIMITS, 0.0),
    (HARD_LIMITS, 0.0),
    (HOMING, 0.0),
    (HOMING_DIR_MASK, 0.0),
    (24, 25.0),
    (25, 500.0),
    (26, 250.0),
    (HOMING_PULLOFF_MM, 1.0),
    (MAX_POWER_S, DEFAULT_MAX_POWER_S),
    (31, 0.0),
    (LASER_MODE, 0.0),
    (100, 80.0),
    (101, 80.0),
    (102, 250.0),
    (MAX_RATE_MM_PER_MIN[0], 6000.0),
    (MAX_RATE_MM_PER_MIN[1], 6000.0),
    (MAX_RATE_MM_PER_MIN[2], 500.0),
    (ACCELERATION_MM_PER_S2[0], 1000.0),
    (ACCELERATION_MM_PER_S2[1], 1000.0),
    (ACCELERATION_MM_PER_S2[2], 10.0),
    (MAX_TRAVEL_MM[0], 400.0),
    (MAX_TRAVEL_MM[1], 400.0),
    (MAX_TRAVEL_MM[2], 50.0),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stock_table_is_in_order_and_names_each_setting_once() {
        assert!(STOCK.windows(2).all(|w| w[0].0 < w[1].0));
    }
}
