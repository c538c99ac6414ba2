//! The motor and its G2 bridge, electrically: what current flows for the bridge's inputs and the
//! hub's speed, and the torque it gives at the output.
//!
//! Sign/magnitude PWM: asleep → coasts (no current); awake → i = clamp((D·Vs·dir − ke·N·ω)/R,
//! ±I_max), output torque N·η·kt·i. At duty 0 while awake the bridge brakes (i = −ke·N·ω/R). The
//! electrical time constant (L/R, well under the 1 ms tick) is neglected.

use super::{Bridge, PlantParams};

/// The motor's electrical state.
#[derive(Debug, Clone)]
pub(super) struct Motor {
    /// The leads are connected.
    pub(super) connected: bool,
    /// Current of the last sub-step, A (signed, in the jam frame).
    pub(super) current_a: f64,
}

impl Motor {
    /// A connected motor at rest.
    pub(super) fn new() -> Self {
        Self {
            connected: true,
            current_a: 0.0,
        }
    }

    /// One sub-step of `dt_s` with the bridge at `bridge` and the hub turning at `hub_rad_per_s`:
    /// the output torque, N·m (jam frame).
    pub(super) fn step(
        &mut self,
        p: &PlantParams,
        bridge: &Bridge,
        hub_rad_per_s: f64,
        _dt_s: f64,
    ) -> f64 {
        let n = p.gear_ratio;
        let motor_speed = n * hub_rad_per_s;
        self.current_a = if !self.connected || !bridge.awake {
            0.0
        } else {
            let applied_v = bridge.duty.clamp(0.0, 1.0) * p.supply_v * bridge.direction.signum();
            ((applied_v - p.kt_nm_per_a * motor_speed) / p.resistance_ohm)
                .clamp(-p.max_current_a, p.max_current_a)
        };
        n * p.gear_efficiency * p.kt_nm_per_a * self.current_a
    }
}
