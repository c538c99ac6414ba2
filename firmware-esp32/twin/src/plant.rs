//! The physics the twin's firmware acts on: motor and gearbox, hole play, the gauge's inset and
//! the spiral's contact. One degree of freedom (the hub) with the inset dragged through a
//! backlash, integrated at [`SUBSTEPS`] sub-steps per 1 ms control tick. Every parameter has a
//! realistic default with its source and plausible range ([`PlantParams`]): a plant kinder than
//! hardware would pass firmware that a real board fails.
//!
//! - **Motor** (G2 driver, locked-antiphase-free sign/magnitude PWM): asleep → coasts (no
//!   current); awake → i = clamp((D·Vs·dir − ke·N·ω)/R, ±I_max), output torque N·η·kt·i. At
//!   duty 0 while awake the bridge brakes (i = −ke·N·ω/R). The electrical time constant (L/R,
//!   well under the 1 ms tick) is neglected.
//! - **Friction**: Karnopp stick–slip on the hub (gearbox) and on the inset (table, plus contact
//!   friction μ·r·F_n once the spiral's gap is closed): stuck while the net torque stays within
//!   the static level, kinetic friction while moving.
//! - **Hole play**: the hub turns freely by θplay(k) = 2·asin((r_h − r_p + k/2)/(2R)) either way
//!   before a prong drags the inset (the inset's inertia is neglected beside the gearbox's).
//! - **Spiral**: the gap k − c·θs closes at θs = k/c; beyond, a linear contact stiffness gives
//!   F_n = K·δ with δ = c·θs − k, and the inset resists a prong pressing forward with
//!   F_n·(c + μ·r) (elastic c·F_n, friction μ·r·F_n). The spiral is self-locking (c < μ·r): the
//!   compressed inset never springs back by itself; pulled back, it resists with F_n·(μ·r − c).
//!   The measured kerf at a force includes the contact's compression δ(F), as a real joint's fit
//!   does; [`Plant::effective_kerf_um`] gives it.
//! - **Prongs** only push: a prong pressing one side of its hole drags the inset that way; the
//!   hub leaves the inset behind as soon as it turns the other way.
//!
//! Angles are in the jam frame (positive in the gauge's jam direction), radians, from the zero
//! position with the prongs centred in their holes.

use kerfmeter_protocol::{GaugeGeometry, JamDirection, RunParams};

use kerfmeter_protocol::spiral::{
    force_for_torque_n, pitch_mm_per_rad, play_deg, torque_for_force_nm,
};

/// Integration sub-steps per 1 ms control tick.
pub const SUBSTEPS: u32 = 10;
const DT_S: f64 = 1e-3 / SUBSTEPS as f64;
/// Slack in the prong–hole coupling test, rad.
const COUPLING_EPS: f64 = 1e-9;
/// Below this hub speed (rad/s) the hub counts as stopped for friction.
const STICK_SPEED: f64 = 1e-3;

/// Every parameter of the plant, with its source and plausible range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantParams {
    /// Supply voltage, V. Reference build: 12 V (range 6–24).
    pub supply_v: f64,
    /// Winding resistance, Ω. 12 V / 5.6 A stall current of a Pololu 25D HP 12 V motor (1–5).
    pub resistance_ohm: f64,
    /// Motor torque constant, N·m/A (= back-EMF constant, V·s/rad). Chosen so the stall torque at
    /// the output is the reference 0.88 N·m (0.005–0.03).
    pub kt_nm_per_a: f64,
    /// Driver current limit, A (G2 18v17: far above stall; 5–40).
    pub max_current_a: f64,
    /// Gear ratio (reference 21:1; 10–100).
    pub gear_ratio: f64,
    /// Gearbox efficiency (spur gearbox: 0.6–0.9).
    pub gear_efficiency: f64,
    /// Rotor inertia, kg·m² (25 mm motor: 2e-7–2e-6).
    pub rotor_inertia_kgm2: f64,
    /// Hub and prongs inertia at the output, kg·m² (1e-6–1e-4).
    pub hub_inertia_kgm2: f64,
    /// Gearbox static friction at the output, N·m (0.01–0.08).
    pub gear_static_nm: f64,
    /// Gearbox kinetic friction at the output, N·m (0.8 × static).
    pub gear_kinetic_nm: f64,
    /// Inset on the cutting table: static friction, N·m (a 20 mm plywood disc: 0.002–0.03).
    pub inset_static_nm: f64,
    /// Inset on the cutting table: kinetic friction, N·m.
    pub inset_kinetic_nm: f64,
    /// Spiral contact stiffness, N per µm of closure (stiff wood edge: 20–500).
    pub contact_stiffness_n_per_um: f64,
    /// Friction coefficient in the spiral contact (wood on wood: 0.2–0.5).
    pub contact_mu: f64,
    /// Encoder noise, LSB (AS5048A datasheet: ±1–2 LSB).
    pub encoder_noise_lsb: f32,
    /// Current-sense noise, A.
    pub current_noise_a: f64,
}

impl Default for PlantParams {
    fn default() -> Self {
        Self {
            supply_v: 12.0,
            resistance_ohm: 12.0 / 5.6,
            kt_nm_per_a: 0.88 / (21.0 * 0.7 * 5.6),
            max_current_a: 20.0,
            gear_ratio: 21.0,
            gear_efficiency: 0.7,
            rotor_inertia_kgm2: 5e-7,
            hub_inertia_kgm2: 2e-5,
            gear_static_nm: 0.035,
            gear_kinetic_nm: 0.028,
            inset_static_nm: 0.010,
            inset_kinetic_nm: 0.008,
            contact_stiffness_n_per_um: 80.0,
            contact_mu: 0.3,
            encoder_noise_lsb: 1.0,
            current_noise_a: 0.02,
        }
    }
}

/// The motor bridge's inputs, as the fake pins hold them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bridge {
    /// PWM duty, 0..=1.
    pub duty: f64,
    /// Hub torque direction in the jam frame: +1 or −1.
    pub direction: f64,
    /// SLP high.
    pub awake: bool,
}

/// The plant's state.
#[derive(Debug, Clone)]
pub struct Plant {
    params: PlantParams,
    gauge: GaugeGeometry,
    kerf_um: f64,
    inset_present: bool,
    coupled: bool,
    motor_connected: bool,
    hub_rad: f64,
    hub_rad_per_s: f64,
    inset_rad: f64,
    current_a: f64,
}

impl Plant {
    /// A plant with a freshly cut gauge of `gauge` geometry and true kerf `kerf_um` under the
    /// prongs, hub at zero.
    pub fn new(params: PlantParams, gauge: GaugeGeometry, kerf_um: f64) -> Self {
        Self {
            params,
            gauge,
            kerf_um,
            inset_present: true,
            coupled: true,
            motor_connected: true,
            hub_rad: 0.0,
            hub_rad_per_s: 0.0,
            inset_rad: 0.0,
            current_a: 0.0,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// A new gauge cut with `kerf_um` under the prongs: its holes are cut at the zero position,
    /// wherever the hub stands within the play.
    pub fn place_gauge(&mut self, kerf_um: f64) {
        self.kerf_um = kerf_um;
        self.inset_rad = 0.0;
        self.inset_present = true;
        self.coupled = true;
    }

    /// Lift the prongs out of the gauge (the head moves away after a measurement).
    pub fn lift_prongs(&mut self) {
        self.inset_present = false;
    }

    /// The true (geometric) kerf of the gauge in place.
    pub fn kerf_um(&self) -> f64 {
        self.kerf_um
    }

    /// Remove the inset (or put it back): the prongs then turn freely.
    pub fn set_inset_present(&mut self, present: bool) {
        self.inset_present = present;
    }

    /// A prong slips out of its hole: from now on the hub no longer drags the inset.
    pub fn slip_prong(&mut self) {
        self.coupled = false;
    }

    /// Disconnect (or reconnect) the motor leads.
    pub fn set_motor_connected(&mut self, connected: bool) {
        self.motor_connected = connected;
    }

    /// Hub angle in the jam frame, degrees.
    pub fn hub_deg(&self) -> f64 {
        self.hub_rad.to_degrees()
    }

    /// Hub angle clockwise-positive seen from above, degrees (what the encoder sees).
    pub fn hub_cw_deg(&self) -> f64 {
        match self.gauge.jam_direction {
            JamDirection::Clockwise => self.hub_deg(),
            JamDirection::CounterClockwise => -self.hub_deg(),
        }
    }

    /// Hub speed, degrees per second (jam frame).
    pub fn hub_deg_per_s(&self) -> f64 {
        self.hub_rad_per_s.to_degrees()
    }

    /// Inset angle in the jam frame, degrees.
    pub fn inset_deg(&self) -> f64 {
        self.inset_rad.to_degrees()
    }

    /// Motor current of the last sub-step, A (signed).
    pub fn current_a(&self) -> f64 {
        self.current_a
    }

    /// The spiral's pitch c, m/rad: the gauge drawer's and the device's, from one place.
    fn pitch_m_per_rad(&self) -> f64 {
        pitch_mm_per_rad(&self.gauge) * 1e-3
    }

    fn play_rad(&self) -> f64 {
        f64::from(play_deg(&self.gauge, self.kerf_um as f32)).to_radians()
    }

    /// Spiral closure δ (m) at the current inset angle; negative while the gap is open.
    fn closure_m(&self) -> f64 {
        self.pitch_m_per_rad() * self.inset_rad - self.kerf_um * 1e-6
    }

    /// Normal force in the spiral contact, N.
    pub fn contact_force_n(&self) -> f64 {
        let closure = self.closure_m();
        if self.inset_present && closure > 0.0 {
            self.params.contact_stiffness_n_per_um * 1e6 * closure
        } else {
            0.0
        }
    }

    /// The kerf this plant's gauge shows at the force of `params` when jammed moving forward:
    /// the geometric kerf plus the contact's compression at that force, µm. This is what an ideal
    /// device measures.
    pub fn effective_kerf_um(&self, run: &RunParams) -> f64 {
        // At the jam, τ = F_n·(c + μ·r) and τ is the ramp's target at the jam angle; iterate the
        // (weak) dependence of the target on the angle.
        let c = self.pitch_m_per_rad();
        let lever = c + self.params.contact_mu * f64::from(self.gauge.radius_mm) * 1e-3;
        let k = self.params.contact_stiffness_n_per_um * 1e6;
        let mut compression_m = 0.0;
        for _ in 0..20 {
            let inset_deg = ((self.kerf_um * 1e-6 + compression_m) / c).to_degrees() as f32;
            let torque =
                torque_for_force_nm(run, run.target_force_n, inset_deg).min(run.max_torque_nm);
            compression_m = f64::from(torque) / lever / k;
        }
        self.kerf_um + compression_m * 1e6
    }

    /// The kerf this plant's gauge shows when jammed moving forward under `torque_nm` at the hub:
    /// the geometric kerf plus the contact's compression, F_n = τ / (c + μ·r), δ = F_n / K. This
    /// is what an ideal device reports for a jam at that torque.
    pub fn kerf_at_torque_um(&self, torque_nm: f64) -> f64 {
        let lever = self.pitch_m_per_rad()
            + self.params.contact_mu * f64::from(self.gauge.radius_mm) * 1e-3;
        let stiffness = self.params.contact_stiffness_n_per_um * 1e6;
        self.kerf_um + torque_nm.max(0.0) / lever / stiffness * 1e6
    }

    /// Joint force the device reports for `torque_nm` at the current inset angle (for checks).
    pub fn equivalent_force_n(&self, run: &RunParams, torque_nm: f32) -> f32 {
        force_for_torque_n(run, torque_nm, self.inset_deg() as f32)
    }

    /// Advance one 1 ms control tick with the bridge held at `bridge`.
    pub fn tick(&mut self, bridge: &Bridge) {
        for _ in 0..SUBSTEPS {
            self.substep(bridge);
        }
    }

    fn substep(&mut self, bridge: &Bridge) {
        let p = self.params;
        let n = p.gear_ratio;
        let motor_speed = n * self.hub_rad_per_s;
        self.current_a = if !self.motor_connected || !bridge.awake {
            0.0
        } else {
            let applied_v = bridge.duty.clamp(0.0, 1.0) * p.supply_v * bridge.direction.signum();
            ((applied_v - p.kt_nm_per_a * motor_speed) / p.resistance_ohm)
                .clamp(-p.max_current_a, p.max_current_a)
        };
        let motor_torque = n * p.gear_efficiency * p.kt_nm_per_a * self.current_a;

        // Which prong face touches its hole: pressing forward (jam direction) or backward.
        let play = self.play_rad();
        let rel = self.hub_rad - self.inset_rad;
        let dragging = self.inset_present && self.coupled;
        let forward = dragging && rel >= play - COUPLING_EPS;
        let backward = dragging && rel <= -play + COUPLING_EPS;

        // The inset's resistance, seen at the hub, in the direction the prong presses. The spiral
        // is self-locking (c < μ·r): its elastic push c·F_n never drives the inset back, so
        // pressing forward meets F_n·(c + μ·r), pulling back meets F_n·(μ·r − c).
        let force = self.contact_force_n();
        let c = self.pitch_m_per_rad();
        let mu_r = p.contact_mu * f64::from(self.gauge.radius_mm) * 1e-3;
        let (fwd_static, fwd_kinetic) = if forward {
            let contact = force * (c + mu_r);
            (p.inset_static_nm + contact, p.inset_kinetic_nm + contact)
        } else {
            (0.0, 0.0)
        };
        let (back_static, back_kinetic) = if backward {
            let contact = force * (mu_r - c).max(0.0);
            (p.inset_static_nm + contact, p.inset_kinetic_nm + contact)
        } else {
            (0.0, 0.0)
        };
        let inertia = p.rotor_inertia_kgm2 * n * n + p.hub_inertia_kgm2;

        // Karnopp friction: stuck while the motor torque is within the static level of the
        // direction it pushes; kinetic friction against the motion otherwise.
        let omega = self.hub_rad_per_s;
        let accel = if omega.abs() < STICK_SPEED {
            if motor_torque > p.gear_static_nm + fwd_static {
                (motor_torque - p.gear_kinetic_nm - fwd_kinetic) / inertia
            } else if motor_torque < -(p.gear_static_nm + back_static) {
                (motor_torque + p.gear_kinetic_nm + back_kinetic) / inertia
            } else {
                0.0
            }
        } else if omega > 0.0 {
            (motor_torque - p.gear_kinetic_nm - fwd_kinetic) / inertia
        } else {
            (motor_torque + p.gear_kinetic_nm + back_kinetic) / inertia
        };
        let mut next = omega + accel * DT_S;
        if omega.abs() >= STICK_SPEED && next.signum() != omega.signum() {
            // Friction can stop the hub, never reverse it.
            next = 0.0;
        }
        if omega.abs() < STICK_SPEED && accel == 0.0 {
            next = 0.0;
        }
        self.hub_rad_per_s = next;
        self.hub_rad += next * DT_S;

        if self.inset_present && self.coupled {
            let rel = self.hub_rad - self.inset_rad;
            if rel > play {
                self.inset_rad = self.hub_rad - play;
            } else if rel < -play {
                self.inset_rad = self.hub_rad + play;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plant(kerf_um: f64) -> Plant {
        Plant::new(PlantParams::default(), GaugeGeometry::PAPER, kerf_um)
    }

    #[test]
    fn stall_torque_at_full_duty_is_the_reference() {
        let p = PlantParams::default();
        let stall =
            p.gear_ratio * p.gear_efficiency * p.kt_nm_per_a * p.supply_v / p.resistance_ohm;
        assert!((stall - 0.88).abs() < 1e-9);
    }

    #[test]
    fn below_breakaway_the_hub_does_not_move() {
        let mut pl = plant(150.0);
        let bridge = Bridge {
            duty: 0.03,
            direction: 1.0,
            awake: true,
        };
        for _ in 0..500 {
            pl.tick(&bridge);
        }
        assert_eq!(pl.hub_deg(), 0.0);
    }

    #[test]
    fn the_hub_turns_freely_through_the_play_then_drags_the_inset_until_the_gap_closes() {
        let mut pl = plant(150.0);
        let bridge = Bridge {
            duty: 0.3,
            direction: 1.0,
            awake: true,
        };
        let play = f64::from(play_deg(&GaugeGeometry::PAPER, 150.0));
        let mut ticks = 0;
        while pl.hub_rad_per_s.abs() > 0.0 || ticks < 10 {
            pl.tick(&bridge);
            ticks += 1;
            if pl.hub_deg() < play {
                assert_eq!(
                    pl.inset_deg(),
                    0.0,
                    "the inset waits while the prong crosses the play"
                );
            }
            assert!(ticks < 10_000, "never jammed");
        }
        // Jammed: the gap is closed (and a little compressed).
        let closed_at = 150.0 / f64::from(GaugeGeometry::PAPER.pitch_um_per_deg);
        assert!(
            pl.inset_deg() > closed_at && pl.inset_deg() < closed_at + 3.0,
            "{}",
            pl.inset_deg()
        );
        assert!((pl.hub_deg() - pl.inset_deg() - play).abs() < 1e-6);
    }

    #[test]
    fn without_an_inset_the_hub_never_jams() {
        let mut pl = plant(150.0);
        pl.set_inset_present(false);
        let bridge = Bridge {
            duty: 0.2,
            direction: 1.0,
            awake: true,
        };
        for _ in 0..2000 {
            pl.tick(&bridge);
        }
        assert!(pl.hub_deg() > 360.0);
    }

    #[test]
    fn a_disconnected_motor_draws_no_current_and_does_not_move() {
        let mut pl = plant(150.0);
        pl.set_motor_connected(false);
        pl.tick(&Bridge {
            duty: 1.0,
            direction: 1.0,
            awake: true,
        });
        assert_eq!(pl.current_a(), 0.0);
        assert_eq!(pl.hub_deg(), 0.0);
    }

    #[test]
    fn effective_kerf_adds_a_few_micrometres_of_compression() {
        let pl = plant(150.0);
        let k = pl.effective_kerf_um(&RunParams::DEFAULT);
        assert!(k > 150.5 && k < 155.0, "{k}");
    }
}
