//! The gauge under the prongs: the inset's angle, the hole play it is dragged through, the
//! spiral's gap and its contact, and the truth an ideal device would read on it.
//!
//! - **Hole play**: the hub turns freely by θplay(k) = 2·asin((r_h − r_p + k/2)/(2R)) either way
//!   before a prong drags the inset (the inset's inertia is neglected beside the gearbox's).
//! - **Spiral**: the gap k − c·θs closes at θs = k/c; beyond, a linear contact stiffness gives
//!   F_n = K·δ with δ = c·θs − k, and the inset resists a prong pressing forward with
//!   F_n·(c + μ·r) (elastic c·F_n, friction μ·r·F_n). The spiral is self-locking (c < μ·r): the
//!   compressed inset never springs back by itself; pulled back, it resists with F_n·(μ·r − c).
//! - **Prongs** only push: a prong pressing one side of its hole drags the inset that way; the
//!   hub leaves the inset behind as soon as it turns the other way.
//!
//! The truth ([`Gauge::truth_um`]) is the kerf an ideal device reads at the force a run asks
//! for: the gap plus the contact's compression at that force, as a real joint's fit includes it.
//! It is computed from this gauge, never from anything the device reports.

use kerfmeter_protocol::spiral::{pitch_mm_per_rad, play_deg, torque_for_force_nm};
use kerfmeter_protocol::{GaugeGeometry, RunParams};

use super::PlantParams;

/// Slack in the prong–hole coupling test, rad.
const COUPLING_EPS: f64 = 1e-9;

/// Friction torques, N·m: the level that holds the inset still, and the one while it slides.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Resistance {
    pub(super) static_nm: f64,
    pub(super) kinetic_nm: f64,
}

/// The gauge in place and the inset's state.
#[derive(Debug, Clone)]
pub(super) struct Gauge {
    pub(super) geometry: GaugeGeometry,
    pub(super) kerf_um: f64,
    pub(super) inset_present: bool,
    pub(super) coupled: bool,
    pub(super) inset_rad: f64,
}

impl Gauge {
    /// A freshly cut gauge of `geometry` with kerf `kerf_um`, inset at zero.
    pub(super) fn new(geometry: GaugeGeometry, kerf_um: f64) -> Self {
        Self {
            geometry,
            kerf_um,
            inset_present: true,
            coupled: true,
            inset_rad: 0.0,
        }
    }

    /// The spiral's pitch c, m/rad: the gauge drawer's and the device's, from one place.
    pub(super) fn pitch_m_per_rad(&self) -> f64 {
        pitch_mm_per_rad(&self.geometry) * 1e-3
    }

    /// The hole play either way, rad.
    pub(super) fn play_rad(&self) -> f64 {
        f64::from(play_deg(&self.geometry, self.kerf_um as f32)).to_radians()
    }

    /// μ·r of the spiral contact, m.
    fn mu_r_m(&self, p: &PlantParams) -> f64 {
        p.contact_mu * f64::from(self.geometry.radius_mm) * 1e-3
    }

    /// Spiral closure δ (m) at the current inset angle; negative while the gap is open.
    fn closure_m(&self) -> f64 {
        self.pitch_m_per_rad() * self.inset_rad - self.kerf_um * 1e-6
    }

    /// Normal force in the spiral contact, N.
    pub(super) fn contact_force_n(&self, p: &PlantParams) -> f64 {
        let closure = self.closure_m();
        if self.inset_present && closure > 0.0 {
            p.contact_stiffness_n_per_um * 1e6 * closure
        } else {
            0.0
        }
    }

    /// Whether a prong presses the inset forward (jam direction) and backward with the hub at
    /// `hub_rad`.
    fn pressing(&self, hub_rad: f64) -> (bool, bool) {
        let play = self.play_rad();
        let rel = hub_rad - self.inset_rad;
        let dragging = self.inset_present && self.coupled;
        (
            dragging && rel >= play - COUPLING_EPS,
            dragging && rel <= -play + COUPLING_EPS,
        )
    }

    /// The inset's resistance seen at the hub at `hub_rad`, forward and backward. The spiral is
    /// self-locking: its elastic push c·F_n never drives the inset back, so pressing forward meets
    /// F_n·(c + μ·r), pulling back meets F_n·(μ·r − c).
    pub(super) fn resistance(&self, p: &PlantParams, hub_rad: f64) -> (Resistance, Resistance) {
        let (forward, backward) = self.pressing(hub_rad);
        let force = self.contact_force_n(p);
        let c = self.pitch_m_per_rad();
        let mu_r = self.mu_r_m(p);
        let side = |pressing: bool, contact_nm: f64| {
            if pressing {
                Resistance {
                    static_nm: p.inset_static_nm + contact_nm,
                    kinetic_nm: p.inset_kinetic_nm + contact_nm,
                }
            } else {
                Resistance::default()
            }
        };
        (
            side(forward, force * (c + mu_r)),
            side(backward, force * (mu_r - c).max(0.0)),
        )
    }

    /// The hub has moved to `hub_rad`: a prong at a side of its hole drags the inset along.
    pub(super) fn drag(&mut self, hub_rad: f64) {
        if !(self.inset_present && self.coupled) {
            return;
        }
        let play = self.play_rad();
        let rel = hub_rad - self.inset_rad;
        if rel > play {
            self.inset_rad = hub_rad - play;
        } else if rel < -play {
            self.inset_rad = hub_rad + play;
        }
    }

    /// Compression of the contact, m, under `torque_nm` pressing forward at the hub:
    /// F_n = τ / (c + μ·r), δ = F_n / K.
    fn compression_m(&self, p: &PlantParams, torque_nm: f64) -> f64 {
        let lever = self.pitch_m_per_rad() + self.mu_r_m(p);
        torque_nm.max(0.0) / lever / (p.contact_stiffness_n_per_um * 1e6)
    }

    /// The truth: the kerf an ideal device reads on this gauge at the force `run` asks for, µm.
    /// At the jam, τ = F_n·(c + μ·r) and τ is the ramp's target at the jam angle; the (weak)
    /// dependence of the target on the angle is iterated.
    pub(super) fn truth_um(&self, p: &PlantParams, run: &RunParams) -> f64 {
        let c = self.pitch_m_per_rad();
        let mut compression_m = 0.0;
        for _ in 0..20 {
            let inset_deg = ((self.kerf_um * 1e-6 + compression_m) / c).to_degrees() as f32;
            let torque =
                torque_for_force_nm(run, run.target_force_n, inset_deg).min(run.max_torque_nm);
            compression_m = self.compression_m(p, f64::from(torque));
        }
        self.kerf_um + compression_m * 1e6
    }

    /// What an ideal device reports for a jam under `torque_nm` at the hub, µm.
    pub(super) fn kerf_at_torque_um(&self, p: &PlantParams, torque_nm: f64) -> f64 {
        self.kerf_um + self.compression_m(p, torque_nm) * 1e6
    }
}
