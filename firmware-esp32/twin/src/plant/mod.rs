//! The physics the twin's firmware acts on: one degree of freedom (the hub, through the gearbox)
//! with the gauge's inset dragged through a backlash. Every parameter has a realistic default
//! with its source and plausible range ([`PlantParams`], listed in [`PARAMS`]): a plant kinder
//! than hardware would pass firmware that a real board fails.
//!
//! - `motor`: the supply, the G2 bridge and the motor, electrically (bus sag,
//!   under-voltage lockout, current limiting, winding temperature); the torque they give.
//! - `gauge`: the hole play, the spiral's gap and contact, the truth.
//! - [`cut`]: a gauge as a real cutter cuts it ([`GaugeCut`], drawn by a [`Cutter`]):
//!   the kerf's location bias and spread, its taper, displaced holes, off-centre prongs and the
//!   contact's spread.
//! - Here: the hub's motion with Karnopp stick–slip friction on the gearbox and the inset (the
//!   table, plus contact friction once the gap is closed): stuck while the net torque stays
//!   within the static level, kinetic friction while moving. Integrated in sub-steps of at most
//!   [`SUBSTEP_US`] over whatever time passes between two control ticks ([`Plant::run_us`]).
//!
//! Angles are in the jam frame (positive in the gauge's jam direction), radians, from the zero
//! position: the hub where the device's zero is, the inset as the gauge was cut (with a perfect
//! cut, the prongs centred in their holes).

pub mod cut;
mod gauge;
mod motor;
mod params;

pub use cut::{Cutter, CutterKerf, GaugeCut};
pub use gauge::tapered_contact_force_n;
pub use motor::{COPPER_TEMPCO_PER_C, Electrical, UVLO_HYSTERESIS_V};
pub use params::{
    FRICTION_PAIRS, Material, PARAMS, ParamSpec, PlantParamError, PlantParams, param, param_list,
    param_table,
};

use kerfmeter_protocol::spiral::force_for_torque_n;
use kerfmeter_protocol::{GaugeGeometry, JamDirection, RunParams};

use gauge::Gauge;
use motor::Motor;

/// Longest integration sub-step, µs.
pub const SUBSTEP_US: u64 = 100;
/// Below this hub speed (rad/s) the hub counts as stopped for friction.
const STICK_SPEED: f64 = 1e-3;

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
    motor: Motor,
    gauge: Gauge,
    hub_rad: f64,
    hub_rad_per_s: f64,
}

impl Plant {
    /// A plant with a freshly cut nominal gauge ([`GaugeCut::nominal`]: as drawn, with the
    /// plant's taper and mean contact) of `gauge` geometry and mid-sheet kerf `kerf_um` under the
    /// prongs, hub at zero.
    pub fn new(params: PlantParams, gauge: GaugeGeometry, kerf_um: f64) -> Self {
        Self::with_cut(params, gauge, GaugeCut::nominal(&params, kerf_um))
    }

    /// A plant with the gauge `cut` of `gauge` geometry under the prongs, hub at zero.
    pub fn with_cut(params: PlantParams, gauge: GaugeGeometry, cut: GaugeCut) -> Self {
        Self {
            motor: Motor::new(&params),
            params,
            gauge: Gauge::new(gauge, cut),
            hub_rad: 0.0,
            hub_rad_per_s: 0.0,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// A new gauge, cut as `cut` says, under the prongs: its holes are cut at the zero position
    /// (displaced as the cut says). The prongs go into them with the hub anywhere within the
    /// play; further off (a hub that is not where the device believes its zero is) they rest on
    /// the gauge's face until the hub turns them over the holes, where they drop in.
    pub fn place_gauge(&mut self, cut: GaugeCut) {
        self.place_gauge_of(self.gauge.geometry, cut);
    }

    /// A new gauge of physical `geometry` (a gauge cut from other G-code than the device was
    /// told of: [`crate::gauge_trace`]), cut as `cut` says, under the prongs, as
    /// [`Plant::place_gauge`] places one.
    pub fn place_gauge_of(&mut self, geometry: GaugeGeometry, cut: GaugeCut) {
        self.gauge = Gauge::new(geometry, cut);
        self.gauge.land(self.hub_rad);
    }

    /// Someone turns the hub by hand to `cw_deg` (clockwise-positive seen from above) with the
    /// prongs lifted (they are lifted first) and the motor at rest.
    pub fn turn_hub_by_hand(&mut self, cw_deg: f64) {
        self.lift_prongs();
        let cw_rad = cw_deg.to_radians();
        self.hub_rad = match self.gauge.geometry.jam_direction {
            JamDirection::Clockwise => cw_rad,
            JamDirection::CounterClockwise => -cw_rad,
        };
        self.hub_rad_per_s = 0.0;
    }

    /// The physical geometry of the gauge in place.
    pub fn geometry(&self) -> &GaugeGeometry {
        &self.gauge.geometry
    }

    /// How the gauge in place was cut.
    pub fn cut(&self) -> &GaugeCut {
        &self.gauge.cut
    }

    /// The hub's free play beyond the inset at its current angle, degrees: (forward, backward).
    pub fn play_deg(&self) -> (f64, f64) {
        let (forward, backward) = self.gauge.play_rad();
        (forward.to_degrees(), backward.to_degrees())
    }

    /// Lift the prongs out of the gauge (the head moves away after a measurement).
    pub fn lift_prongs(&mut self) {
        self.gauge.inset_present = false;
    }

    /// The true (geometric) kerf of the gauge in place, at mid-sheet, µm.
    pub fn kerf_um(&self) -> f64 {
        self.gauge.cut.kerf_um
    }

    /// Remove the inset (or put it back): the prongs then turn freely.
    pub fn set_inset_present(&mut self, present: bool) {
        self.gauge.inset_present = present;
    }

    /// A prong slips out of its hole: from now on the hub no longer drags the inset.
    pub fn slip_prong(&mut self) {
        self.gauge.coupled = false;
    }

    /// Disconnect (or reconnect) the motor leads.
    pub fn set_motor_connected(&mut self, connected: bool) {
        self.motor.connected = connected;
    }

    /// Hub angle in the jam frame, degrees.
    pub fn hub_deg(&self) -> f64 {
        self.hub_rad.to_degrees()
    }

    /// Hub angle clockwise-positive seen from above, degrees (what the encoder sees).
    pub fn hub_cw_deg(&self) -> f64 {
        match self.gauge.geometry.jam_direction {
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
        self.gauge.inset_rad.to_degrees()
    }

    /// Motor current of the last sub-step, A (signed).
    pub fn current_a(&self) -> f64 {
        self.motor.state.current_a
    }

    /// The supply, bridge and winding after the last sub-step: bus voltage, drive fraction,
    /// what the current sense reads in the drive phase, chopping, under-voltage lockout, winding
    /// temperature.
    pub fn electrical(&self) -> Electrical {
        self.motor.state
    }

    /// The driver pulls FLT low: locked out by under-voltage.
    pub fn driver_fault(&self) -> bool {
        self.motor.state.under_voltage
    }

    /// Normal force in the spiral contact, N.
    pub fn contact_force_n(&self) -> f64 {
        self.gauge.contact_force_n()
    }

    /// The truth: the kerf an ideal device reads on the gauge in place at the force `run` asks
    /// for, µm — the closure c·θs at which this gauge's contact (its taper, stiffness and μ)
    /// carries the ramp's target torque for that force. Computed from the plant alone, never
    /// from anything the device reports; the holes' and prongs' misplacement and the encoder's
    /// errors are errors of the device, not part of the truth.
    pub fn truth_um(&self, run: &RunParams) -> f64 {
        self.gauge.truth_um(run)
    }

    /// The kerf this plant's gauge shows when jammed moving forward under `torque_nm` at the hub:
    /// the closure c·θs at which its contact carries that torque. This is what an ideal device
    /// reports for a jam at that torque ([`Plant::truth_um`] is this at the run's target).
    pub fn kerf_at_torque_um(&self, torque_nm: f64) -> f64 {
        self.gauge.kerf_at_torque_um(torque_nm)
    }

    /// Joint force the device reports for `torque_nm` at the current inset angle (for checks).
    pub fn equivalent_force_n(&self, run: &RunParams, torque_nm: f32) -> f32 {
        force_for_torque_n(run, torque_nm, self.inset_deg() as f32)
    }

    /// Advance one 1 ms control tick with the bridge held at `bridge` (the unit tests' step; the
    /// twin runs the plant by the core's clock, [`Plant::run_us`]).
    #[cfg(test)]
    fn tick(&mut self, bridge: &Bridge) {
        self.run_us(bridge, 1000);
    }

    /// Advance `duration_us` with the bridge held at `bridge`, in sub-steps of at most
    /// [`SUBSTEP_US`].
    pub fn run_us(&mut self, bridge: &Bridge, duration_us: u64) {
        let mut left_us = duration_us;
        while left_us > 0 {
            let step_us = left_us.min(SUBSTEP_US);
            self.substep(bridge, step_us as f64 * 1e-6);
            left_us -= step_us;
        }
    }

    fn substep(&mut self, bridge: &Bridge, dt_s: f64) {
        let p = self.params;
        let motor_torque = self.motor.step(&p, bridge, self.hub_rad_per_s, dt_s);
        let (fwd, back) = self.gauge.resistance(&p, self.hub_rad);
        let inertia = p.rotor_inertia_kgm2 * p.gear_ratio * p.gear_ratio + p.hub_inertia_kgm2;

        // Karnopp friction: stuck while the motor torque is within the static level of the
        // direction it pushes; kinetic friction against the motion otherwise.
        let omega = self.hub_rad_per_s;
        let forward_nm = motor_torque - p.gear_kinetic_nm - fwd.kinetic_nm;
        let backward_nm = motor_torque + p.gear_kinetic_nm + back.kinetic_nm;
        let accel = if omega.abs() < STICK_SPEED {
            if motor_torque > p.gear_static_nm + fwd.static_nm {
                forward_nm / inertia
            } else if motor_torque < -(p.gear_static_nm + back.static_nm) {
                backward_nm / inertia
            } else {
                0.0
            }
        } else if omega > 0.0 {
            forward_nm / inertia
        } else {
            backward_nm / inertia
        };
        let mut next = omega + accel * dt_s;
        if omega.abs() >= STICK_SPEED && next.signum() != omega.signum() {
            // Friction can stop the hub, never reverse it.
            next = 0.0;
        }
        if omega.abs() < STICK_SPEED && accel == 0.0 {
            next = 0.0;
        }
        self.hub_rad_per_s = next;
        self.hub_rad += next * dt_s;
        self.gauge.drag(self.hub_rad);
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

    /// Drive the hub forward at a constant duty until it stands still.
    fn jam(mut pl: Plant) -> Plant {
        let bridge = Bridge {
            duty: 0.3,
            direction: 1.0,
            awake: true,
        };
        let mut ticks = 0;
        while pl.hub_deg_per_s().abs() > 0.0 || ticks < 10 {
            pl.tick(&bridge);
            ticks += 1;
            assert!(ticks < 10_000, "never jammed");
        }
        pl
    }

    #[test]
    fn prongs_let_down_off_the_holes_ride_the_gauge_until_they_drop_in() {
        // The hub a motor turn (17°, gear ratio 21) behind the gauge's holes when the prongs
        // come down: they rest on the face and the inset does not follow until they are over
        // the holes; from there the hub drags it as usual.
        let mut pl = plant(150.0);
        pl.turn_hub_by_hand(-360.0 / 21.0);
        pl.place_gauge(GaugeCut::nominal(&PlantParams::default(), 150.0));
        let (play, _) = pl.play_deg();
        let bridge = Bridge {
            duty: 0.3,
            direction: 1.0,
            awake: true,
        };
        while pl.hub_deg() < play / 2.0 {
            pl.tick(&bridge);
            assert_eq!(pl.inset_deg(), 0.0, "hub at {}°", pl.hub_deg());
        }
        let jammed = jam(pl);
        assert!(jammed.inset_deg() > 10.0, "{}", jammed.inset_deg());
        // A hub ahead of the holes never finds them going forward: nothing to drag.
        let mut ahead = plant(150.0);
        ahead.turn_hub_by_hand(360.0 / 21.0);
        ahead.place_gauge(GaugeCut::nominal(&PlantParams::default(), 150.0));
        for _ in 0..300 {
            ahead.tick(&bridge);
        }
        assert!(ahead.hub_deg() > 40.0, "{}", ahead.hub_deg());
        assert_eq!(ahead.inset_deg(), 0.0);
    }

    #[test]
    fn the_hub_turns_freely_through_the_play_then_drags_the_inset_until_the_gap_closes() {
        let mut pl = plant(150.0);
        let bridge = Bridge {
            duty: 0.3,
            direction: 1.0,
            awake: true,
        };
        let (play, _) = pl.play_deg();
        for _ in 0..10_000 {
            pl.tick(&bridge);
            if pl.hub_deg() < play {
                assert_eq!(
                    pl.inset_deg(),
                    0.0,
                    "the inset waits while the prong crosses the play"
                );
            }
        }
        // Jammed: the gap is closed at the bottom of the sheet, where the tapered kerf is
        // narrowest, and compressed by a few tens of µm (at duty 0.3 the motor presses far
        // harder than a run does).
        let taper = PlantParams::default().kerf_taper_um;
        let closed_at = (150.0 - taper / 2.0) / f64::from(GaugeGeometry::PAPER.pitch_um_per_deg);
        assert!(
            pl.inset_deg() > closed_at && pl.inset_deg() < closed_at + 12.0,
            "{}",
            pl.inset_deg()
        );
        assert!(
            (pl.hub_deg() - pl.inset_deg() - pl.play_deg().0).abs() < 1e-6,
            "{} {} {:?}",
            pl.hub_deg(),
            pl.inset_deg(),
            pl.play_deg()
        );
    }

    #[test]
    fn a_prong_offset_shifts_the_jam_angle_by_its_tangential_share_at_the_jam() {
        let p = PlantParams::default();
        let centred = GaugeCut::nominal(&p, 150.0);
        let offset = GaugeCut {
            hub_offset_um: [0.0, 10.0],
            ..centred
        };
        let a = jam(Plant::with_cut(p, GaugeGeometry::PAPER, centred));
        let b = jam(Plant::with_cut(p, GaugeGeometry::PAPER, offset));
        // The contact stops the inset at the same angle either way (to within 0.01 µm of
        // closure: the hub comes in a little faster through the other play) ...
        assert!(
            (a.inset_deg() - b.inset_deg()).abs() < 0.01,
            "{} vs {}",
            a.inset_deg(),
            b.inset_deg()
        );
        // ... and the hub earlier: the 10 µm offset on the table is 10·cos θs tangential and
        // 10·sin θs radial at the holes, forward for prong 0 and backward for prong 1, which
        // touches first (first order: (w_r·tan(θplay/2) − w_t)/R for each prong).
        let theta_s = b.inset_deg().to_radians();
        let (w_r, w_t) = (10e-6 * theta_s.sin(), 10e-6 * theta_s.cos());
        let tan_half = (a.play_deg().0.to_radians() / 2.0).tan();
        let r = f64::from(GaugeGeometry::PAPER.hole_distance_mm) * 1e-3;
        let predicted_deg = ((w_r * tan_half - w_t) / r)
            .min((-w_r * tan_half + w_t) / r)
            .to_degrees();
        assert!(predicted_deg < -0.05, "{predicted_deg}");
        let play_shift_deg = (b.hub_deg() - b.inset_deg()) - (a.hub_deg() - a.inset_deg());
        assert!(
            (play_shift_deg - predicted_deg).abs() < 0.03 * predicted_deg.abs(),
            "play shifted {play_shift_deg}°, predicted {predicted_deg}°"
        );
        let shift_deg = b.hub_deg() - a.hub_deg();
        assert!(
            (shift_deg - predicted_deg).abs() < 0.15 * predicted_deg.abs(),
            "jam shifted {shift_deg}°, predicted {predicted_deg}°"
        );
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
    fn the_truth_adds_a_few_micrometres_of_compression() {
        let pl = plant(150.0);
        let k = pl.truth_um(&RunParams::DEFAULT);
        assert!(k > 152.0 && k < 170.0, "{k}");
    }
}
