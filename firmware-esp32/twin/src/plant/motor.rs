//! The motor, its G2 bridge and the supply, electrically: what current flows for the bridge's
//! inputs and the hub's speed, what the bus sags to, whether the driver locks out, how warm the
//! winding gets, and the torque at the output.
//!
//! # The bridge
//!
//! Sign/magnitude PWM as the G2 does it: in the drive phase of each period (a fraction D, the
//! duty) the bridge applies the bus voltage V_bus in the direction `dir`; in the rest both
//! low-side switches are on (brake), so the current goes on flowing through the winding. The
//! winding's L/R (about a millisecond) is far longer than the 50 µs PWM period, so the current
//! is continuous, at the level the average applied voltage D·V_bus·dir gives; L/R is also short
//! against anything the firmware does, so it is neglected: i = (D·V_bus·dir − E)/R(T), with
//! E = ke·N·ω the back-EMF. Asleep, the bridge's outputs float and the motor coasts (no current).
//! At duty 0, awake, the bridge brakes: i = −E/R.
//!
//! # The supply
//!
//! The supply `supply_v` feeds the bus through `supply_source_ohm` (R_s). The supply current
//! flows only in the drive phase, so its average is D·i_d, where i_d = i·dir is the current in
//! the driven direction: V_bus = V_s − R_s·D·i_d. Put into the motor's equation,
//! i_d·R = D·(V_s − R_s·D·i_d) − E·dir, whose solution in closed form is
//!
//! ```text
//! i_d = (D·V_s − E·dir) / (R + D²·R_s)
//! ```
//!
//! A motor braking against the drive (i_d < 0) pushes the bus up by the same law (the G2's bulk
//! capacitors take the charge).
//!
//! # Current limiting (chopping)
//!
//! When i_d would exceed `max_current_a` (I_max, the G2's VREF threshold), the G2 ends each drive
//! phase as the current reaches the threshold and brakes for the rest of the period: the current
//! is held at I_max and the drive phase shrinks to the fraction D' that sustains it,
//! I_max·R = D'·(V_s − R_s·D'·I_max) − E·dir, the smaller root of that quadratic. The current
//! sense reads the threshold in the (shortened) drive phase and nothing while braking.
//!
//! # Under-voltage lockout
//!
//! Below `driver_uvlo_v` on the bus the G2 turns its outputs off (the motor coasts) and pulls FLT
//! low; it drives again, and releases FLT, once the bus is [`UVLO_HYSTERESIS_V`] above it. As the
//! supply came up from 0 V, a supply below that release level leaves the driver locked out from
//! the start. A supply that sags below the threshold only under load keeps the driver off while
//! the bridge is asked for that load (the model has no bus capacitance, so the bus would sag again
//! at once), and FLT is released when the bridge is asked for less or sleeps.
//!
//! # Winding temperature
//!
//! Copper's resistance rises with temperature, R(T) = R₂₅·(1 + α·(T − 25 °C)), α =
//! [`COPPER_TEMPCO_PER_C`]; the winding heats by i²·R(T) (the current flows in both PWM phases)
//! and cools through `winding_thermal_res_c_per_w` to `ambient_temp_c`, with the heat capacity
//! `winding_heat_capacity_j_per_c`: dT/dt = (i²·R(T) − (T − T_a)/R_th)/C, integrated per sub-step
//! (the thermal time constant, R_th·C, is a minute; a sub-step is 100 µs).

use super::{Bridge, PlantParams};

/// Copper's temperature coefficient of resistance, per °C (at 20–25 °C).
pub const COPPER_TEMPCO_PER_C: f64 = 0.00393;
/// How far above `driver_uvlo_v` the bus must rise before a locked-out G2 drives again, V.
pub const UVLO_HYSTERESIS_V: f64 = 0.3;

/// The electrical state after a sub-step: what the bridge did and what it measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Electrical {
    /// Motor current, A (signed, in the jam frame).
    pub current_a: f64,
    /// Bus voltage at the driver, V (the supply minus its source resistance's drop).
    pub bus_v: f64,
    /// Fraction of each PWM period the bridge drives (the duty; less while it chops; 0 asleep,
    /// locked out or braking).
    pub drive_fraction: f64,
    /// What the current sense reads in the drive phase, A (|i|; the threshold while chopping).
    pub cs_drive_a: f64,
    /// The driver is limiting the current (chopping).
    pub chopping: bool,
    /// The driver is locked out by under-voltage (outputs off, FLT low).
    pub under_voltage: bool,
    /// Winding temperature, °C.
    pub winding_temp_c: f64,
    /// The G2 sleeps (`SLP` low): its `CS` output sits at its sleep level, not its offset
    /// (`cs_sleep_delta_mv`, [`crate::sense`]).
    pub asleep: bool,
}

/// The motor's electrical and thermal state.
#[derive(Debug, Clone)]
pub(super) struct Motor {
    /// The leads are connected.
    pub(super) connected: bool,
    /// The state after the last sub-step.
    pub(super) state: Electrical,
}

impl Motor {
    /// A connected motor at rest, its winding at `winding_temp_c`, the supply just switched on.
    pub(super) fn new(p: &PlantParams) -> Self {
        Self {
            connected: true,
            state: Electrical {
                current_a: 0.0,
                bus_v: p.supply_v,
                drive_fraction: 0.0,
                cs_drive_a: 0.0,
                chopping: false,
                under_voltage: p.supply_v < p.driver_uvlo_v + UVLO_HYSTERESIS_V,
                winding_temp_c: p.winding_temp_c,
                asleep: true,
            },
        }
    }

    /// Winding resistance at temperature `temp_c`, Ω.
    pub(super) fn resistance_ohm(p: &PlantParams, temp_c: f64) -> f64 {
        p.resistance_ohm * (1.0 + COPPER_TEMPCO_PER_C * (temp_c - 25.0))
    }

    /// One sub-step of `dt_s` with the bridge at `bridge` and the hub turning at `hub_rad_per_s`:
    /// the output torque, N·m (jam frame).
    pub(super) fn step(
        &mut self,
        p: &PlantParams,
        bridge: &Bridge,
        hub_rad_per_s: f64,
        dt_s: f64,
    ) -> f64 {
        let temp_c = self.state.winding_temp_c;
        // Locked out, the bridge draws nothing and the bus stands at the supply: it releases
        // once that is above the release level.
        let released =
            !self.state.under_voltage || p.supply_v >= p.driver_uvlo_v + UVLO_HYSTERESIS_V;
        let mut next = if self.connected && bridge.awake && released {
            drive(p, bridge, p.gear_ratio * hub_rad_per_s, temp_c)
        } else {
            idle(p, temp_c)
        };
        if !released || next.bus_v < p.driver_uvlo_v {
            // Outputs off: the motor coasts and the bus recovers at once.
            next = Electrical {
                under_voltage: true,
                ..idle(p, temp_c)
            };
        }
        let heat_w = next.current_a * next.current_a * Self::resistance_ohm(p, temp_c);
        let cooling_w = (temp_c - p.ambient_temp_c) / p.winding_thermal_res_c_per_w;
        next.winding_temp_c =
            temp_c + (heat_w - cooling_w) / p.winding_heat_capacity_j_per_c * dt_s;
        next.asleep = !bridge.awake;
        self.state = next;
        p.gear_ratio * p.gear_efficiency * p.kt_nm_per_a * next.current_a
    }
}

/// No current: asleep, disconnected or locked out, the winding at `temp_c`. The bus stands at
/// the supply.
fn idle(p: &PlantParams, temp_c: f64) -> Electrical {
    Electrical {
        current_a: 0.0,
        bus_v: p.supply_v,
        drive_fraction: 0.0,
        cs_drive_a: 0.0,
        chopping: false,
        under_voltage: false,
        winding_temp_c: temp_c,
        asleep: false,
    }
}

/// The bridge awake and driving at `bridge`'s duty, the motor turning at `motor_rad_per_s`, the
/// winding at `temp_c` (see the module docs for the equations).
fn drive(p: &PlantParams, bridge: &Bridge, motor_rad_per_s: f64, temp_c: f64) -> Electrical {
    let r = Motor::resistance_ohm(p, temp_c);
    let rs = p.supply_source_ohm;
    let dir = if bridge.direction < 0.0 { -1.0 } else { 1.0 };
    let duty = bridge.duty.clamp(0.0, 1.0);
    // Back-EMF along the driven direction.
    let emf_v = p.kt_nm_per_a * motor_rad_per_s * dir;
    let mut i_d = (duty * p.supply_v - emf_v) / (r + duty * duty * rs);
    let mut drive_fraction = duty;
    let chopping = i_d > p.max_current_a;
    if chopping {
        i_d = p.max_current_a;
        drive_fraction = chopped_fraction(p, r, emf_v).min(duty);
    } else if i_d < -p.max_current_a {
        // Braking harder than the limit: the G2 does not chop its brake phase; the clamp only
        // keeps a motor spun far beyond its no-load speed bounded.
        i_d = -p.max_current_a;
    }
    Electrical {
        current_a: i_d * dir,
        bus_v: p.supply_v - rs * drive_fraction * i_d,
        drive_fraction,
        cs_drive_a: i_d.abs(),
        chopping,
        under_voltage: false,
        winding_temp_c: temp_c,
        asleep: false,
    }
}

/// The drive fraction D' that holds the current at the limit while chopping: the smaller root of
/// R_s·I·D'² − V_s·D' + (I·R + E) = 0, in the form that stays finite for R_s = 0.
fn chopped_fraction(p: &PlantParams, r: f64, emf_v: f64) -> f64 {
    let i = p.max_current_a;
    let c = i * r + emf_v;
    let disc = (p.supply_v * p.supply_v - 4.0 * p.supply_source_ohm * i * c).max(0.0);
    (2.0 * c / (p.supply_v + disc.sqrt())).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stall(p: &PlantParams, duty: f64) -> Electrical {
        let mut m = Motor::new(p);
        let bridge = Bridge {
            duty,
            direction: 1.0,
            awake: true,
        };
        m.step(p, &bridge, 0.0, 1e-6);
        m.state
    }

    #[test]
    fn the_bus_sags_by_the_supply_current_through_the_source_resistance() {
        let p = PlantParams::default();
        let e = stall(&p, 0.6);
        let r = p.resistance_ohm;
        let i = 0.6 * p.supply_v / (r + 0.36 * p.supply_source_ohm);
        assert!((e.current_a - i).abs() < 1e-9, "{e:?}");
        // The supply current is D·i; the bus sags by it times R_s.
        assert!((e.bus_v - (p.supply_v - p.supply_source_ohm * 0.6 * i)).abs() < 1e-9);
        assert!(e.bus_v < p.supply_v - 0.3, "sags visibly under load: {e:?}");
        // The motor sees D·V_bus: the closed form solves the implicit equation.
        assert!((e.current_a * r - 0.6 * e.bus_v).abs() < 1e-9);
        // A stiffer supply sags less; an idle bridge not at all.
        let stiff = PlantParams {
            supply_source_ohm: 0.0,
            ..p
        };
        assert_eq!(stall(&stiff, 0.6).bus_v, p.supply_v);
        assert_eq!(stall(&p, 0.0).bus_v, p.supply_v);
    }

    #[test]
    fn a_winding_thirty_percent_more_resistive_when_warm_draws_1_over_1_3_of_the_current() {
        let cold = PlantParams {
            supply_source_ohm: 0.0,
            ..PlantParams::default()
        };
        let warm = PlantParams {
            winding_temp_c: 25.0 + 0.3 / COPPER_TEMPCO_PER_C,
            ..cold
        };
        let ratio = stall(&warm, 0.5).current_a / stall(&cold, 0.5).current_a;
        assert!((ratio - 1.0 / 1.3).abs() < 1e-6, "{ratio}");
    }

    #[test]
    fn a_long_stall_heats_the_winding_and_its_resistance_cuts_the_current() {
        let p = PlantParams::default();
        let mut m = Motor::new(&p);
        let bridge = Bridge {
            duty: 0.5,
            direction: 1.0,
            awake: true,
        };
        m.step(&p, &bridge, 0.0, 1e-4);
        let first = m.state;
        // Ten seconds at stall.
        for _ in 0..100_000 {
            m.step(&p, &bridge, 0.0, 1e-4);
        }
        let after = m.state;
        let power_w = first.current_a * first.current_a * p.resistance_ohm;
        let adiabatic_c = power_w * 10.0 / p.winding_heat_capacity_j_per_c;
        let rise_c = after.winding_temp_c - p.winding_temp_c;
        assert!(
            rise_c > 20.0 && rise_c < adiabatic_c,
            "{rise_c} °C (adiabatic bound {adiabatic_c})"
        );
        let expected = Motor::resistance_ohm(&p, p.winding_temp_c)
            / Motor::resistance_ohm(&p, after.winding_temp_c);
        assert!(
            (after.current_a / first.current_a - expected).abs() < 0.01,
            "{first:?} {after:?}"
        );
        // And it cools towards ambient once the bridge stops.
        let off = Bridge {
            awake: false,
            ..bridge
        };
        for _ in 0..100_000 {
            m.step(&p, &off, 0.0, 1e-4);
        }
        assert!(m.state.winding_temp_c < after.winding_temp_c);
        assert!(m.state.winding_temp_c > p.ambient_temp_c);
    }

    #[test]
    fn chopping_holds_the_current_at_the_limit_with_a_shorter_drive_phase() {
        let p = PlantParams {
            max_current_a: 3.0,
            ..PlantParams::default()
        };
        let e = stall(&p, 0.8);
        assert!(e.chopping);
        assert_eq!(e.current_a, 3.0);
        assert_eq!(e.cs_drive_a, 3.0);
        assert!(e.drive_fraction < 0.8, "{e:?}");
        // The shortened drive phase sustains exactly the limit.
        let r = p.resistance_ohm;
        assert!((e.drive_fraction * e.bus_v - 3.0 * r).abs() < 1e-9, "{e:?}");
        // Below the limit nothing chops.
        let e = stall(&p, 0.2);
        assert!(!e.chopping && e.current_a < 3.0 && e.drive_fraction == 0.2);
    }

    #[test]
    fn under_voltage_locks_the_outputs_off_and_releases_above_the_hysteresis() {
        // A weak 6.5 V supply: fine idle, below the lockout at stall.
        let p = PlantParams {
            supply_v: 6.5,
            supply_source_ohm: 1.0,
            ..PlantParams::default()
        };
        let mut m = Motor::new(&p);
        assert!(!m.state.under_voltage);
        let bridge = Bridge {
            duty: 1.0,
            direction: 1.0,
            awake: true,
        };
        m.step(&p, &bridge, 0.0, 1e-4);
        assert!(m.state.under_voltage, "{:?}", m.state);
        assert_eq!(m.state.current_a, 0.0);
        assert_eq!(m.state.bus_v, 6.5);
        // It stays off while the bridge is asked to drive that hard (the bus would sag again at
        // once)...
        m.step(&p, &bridge, 0.0, 1e-4);
        assert!(m.state.under_voltage && m.state.current_a == 0.0);
        // ...and releases FLT once it is not: asleep, the bus stands at 6.5 V, above threshold
        // plus hysteresis; then a lighter duty drives.
        m.step(
            &p,
            &Bridge {
                awake: false,
                ..bridge
            },
            0.0,
            1e-4,
        );
        assert!(!m.state.under_voltage);
        m.step(
            &p,
            &Bridge {
                duty: 0.3,
                ..bridge
            },
            0.0,
            1e-4,
        );
        assert!(
            !m.state.under_voltage && m.state.current_a > 0.0,
            "{:?}",
            m.state
        );
        // A supply below the release level stays locked out from power-up, even asleep.
        let low = PlantParams { supply_v: 6.0, ..p };
        let mut m = Motor::new(&low);
        m.step(
            &low,
            &Bridge {
                awake: false,
                ..bridge
            },
            0.0,
            1e-4,
        );
        assert!(m.state.under_voltage);
        m.step(&low, &bridge, 0.0, 1e-4);
        assert!(m.state.under_voltage);
        assert_eq!(m.state.current_a, 0.0);
    }
}
