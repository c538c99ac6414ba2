//! The gauge under the prongs, as its [`GaugeCut`] says it was cut: the inset's angle, the hole
//! play it is dragged through, the spiral's gap and its contact, and the truth an ideal device
//! would read on it. Prongs let down with the hub further from the holes than the play (a hub a
//! motor turn off its zero) rest on the gauge's face and turn freely until the hub brings them
//! over the holes, where they drop in ([`Gauge::land`]); the model takes the hub within a
//! fraction of a turn of the holes (a hub half a turn round, where the two prongs would swap
//! holes, is not modelled).
//!
//! # Hole play
//!
//! Hole i sits at radius R, at φ_i = 0 and π on the inset, displaced by δ_i from where it was
//! drawn; its radius is r_h + k_b/2, where k_b is the kerf at the bottom of the sheet (the prongs
//! pass through it, and a tapered hole is narrowest there), so a prong of radius r_p moves freely
//! within ρ = r_h − r_p + k_b/2 of the hole's centre. The inset turns about the gauge's centre
//! (the spiral centres it); the hub turns about its own axis, which stands off that centre by d
//! (the head returned over the gauge with its repeatability). With the inset at θs and the hub
//! turned by α beyond it, prong i's centre is off its hole's centre by
//!
//! ```text
//!   w_i + R·((cos α − 1)·e_r + sin α·e_t),   w_i = (d·e_r − δ_r, d·e_t − δ_t)
//! ```
//!
//! in the hole's radial/tangential frame (e_r, e_t at φ_i + θs on the table, e_t in the jam
//! direction): d is fixed on the table, so its share in each hole's frame turns with the inset.
//! The prong touches the hole's face where that offset's length is ρ, which gives
//!
//! ```text
//!   a·(1 − cos α) + b·sin α = C,   a = R − w_r,  b = w_t,  C = (ρ² − |w|²) / (2R)
//!   α = ψ + asin((C − a)/√(a² + b²)),  ψ = atan2(a, b)          (forward, α > 0)
//!   α = ψ + π − asin((C − a)/√(a² + b²)) − 2π                   (backward, α < 0)
//! ```
//!
//! With w = 0 this is the nominal θplay = 2·asin(ρ/(2R)) either way; to first order, a prong
//! offset moves its forward play by (w_r·tan(θplay/2) − w_t)/R and its backward play by
//! (w_r·tan(θplay/2) + w_t)/R. The hub is rigid: the first prong to touch its face drags the
//! inset, so the hub's play is the smaller of the two prongs' either way. A translation d of the
//! prong pair moves prong 0 forward by d·e_t and prong 1 (whose e_t is the opposite vector)
//! backward by as much: both sides' plays shrink by |d·e_t|/R, with e_t taken at the inset's
//! angle, i.e. at the jam. The device's correction assumes the nominal play: what differs is its
//! error, not part of the truth.
//!
//! # The spiral's contact, with a tapered kerf
//!
//! The gap k − c·θs closes where the kerf is narrowest, the bottom of the sheet, at
//! c·θs = k − τ/2 (k the mid-sheet kerf, τ = top − bottom, never more than 2k). Through the
//! sheet's thickness the kerf rises linearly by τ, so beyond that closure e = c·θs − (k − τ/2)
//! a share min(e/τ, 1) of the face is in contact, compressed by e − u at the depth whose kerf is
//! u above the narrowest. Integrating the full-face stiffness K over that share:
//!
//! ```text
//!   F = K/τ · ∫₀^min(e,τ) (e − u) du  =  K/τ · e²/2     for 0 ≤ e ≤ τ
//!                                     =  K·(e − τ/2)    for e > τ
//! ```
//!
//! quadratic while the contact spreads down the face, then linear; at τ = 0 it is F = K·(c·θs − k).
//! Past the contact's yield F_y (`contact_yield_n`: cardboard crushes at some 250 N, MDF at
//! some 1500 N) the face crushes: each further µm of closure costs a tenth of K
//! ([`YIELD_STIFFNESS_SHARE`]), so a torque a little past the yield turns the inset on by many
//! µm. The law has no memory: the self-locking spiral only ever closes it further under a run.
//! The inset resists a prong pressing forward with F·(c + μ·r) (elastic c·F, friction μ·r·F).
//! The spiral is self-locking (c < μ·r): the compressed inset never springs back by itself;
//! pulled back, it resists with F·(μ·r − c).
//!
//! # Prongs
//!
//! Prongs only push: a prong pressing one side of its hole drags the inset that way; the hub
//! leaves the inset behind as soon as it turns the other way.
//!
//! # The truth
//!
//! [`Gauge::truth_um`] is the kerf an ideal device reads at the force a run asks for: the closure
//! c·θs at which this gauge's contact (its taper, stiffness and μ) carries the ramp's target
//! torque for that force at that angle, as a real joint's fit includes the compression. Computed
//! from this gauge alone; the hole displacements and prong offsets (errors the device's play
//! correction makes) and the encoder's errors are not part of it.

use core::cell::Cell;
use core::f64::consts::PI;

use kerfmeter_protocol::spiral::{pitch_mm_per_rad, torque_for_force_nm};
use kerfmeter_protocol::{GaugeGeometry, RunParams};

use super::PlantParams;
use super::cut::GaugeCut;

/// Slack in the prong–hole coupling test, rad.
const COUPLING_EPS: f64 = 1e-9;
/// Bisection steps of the truth's solve: the closure to well under a nanometre.
const TRUTH_ITERATIONS: usize = 60;

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
    pub(super) cut: GaugeCut,
    pub(super) inset_present: bool,
    pub(super) coupled: bool,
    /// The prongs came down off their holes (the hub further from them than its play): they
    /// rest on the gauge's face and turn freely until the hub brings them over the holes, where
    /// they drop in ([`Gauge::land`]).
    on_face: bool,
    pub(super) inset_rad: f64,
    /// The last play computed each way (forward, backward), and the inset's angle it was
    /// computed at.
    play_cache: Cell<[Option<(f64, f64)>; 2]>,
}

impl Gauge {
    /// A gauge of `geometry` cut as `cut` says, inset at zero.
    pub(super) fn new(geometry: GaugeGeometry, cut: GaugeCut) -> Self {
        Self {
            geometry,
            cut,
            inset_present: true,
            coupled: true,
            on_face: false,
            inset_rad: 0.0,
            play_cache: Cell::new([None; 2]),
        }
    }

    /// The spiral's pitch c, m/rad: the gauge drawer's and the device's, from one place.
    pub(super) fn pitch_m_per_rad(&self) -> f64 {
        pitch_mm_per_rad(&self.geometry) * 1e-3
    }

    /// The kerf's taper through the sheet, m: the cut narrows at most to nothing.
    fn taper_m(&self) -> f64 {
        self.cut.taper_um.clamp(0.0, 2.0 * self.cut.kerf_um) * 1e-6
    }

    /// The kerf at the bottom of the sheet, where it is narrowest, m.
    fn bottom_kerf_m(&self) -> f64 {
        self.cut.kerf_um * 1e-6 - self.taper_m() / 2.0
    }

    /// How far a prong's centre moves within its hole before it touches, ρ, m.
    fn hole_clearance_m(&self) -> f64 {
        let g = &self.geometry;
        f64::from(g.hole_radius_mm - g.prong_radius_mm) * 1e-3 + self.bottom_kerf_m() / 2.0
    }

    /// Prong `i`'s offset from its hole's centre with the hub in line with the inset, m:
    /// (radial, tangential) in the hole's frame at the inset's current angle.
    fn prong_offset_m(&self, i: usize) -> (f64, f64) {
        let hole_at = PI * i as f64 + self.inset_rad;
        let [dx, dy] = self.cut.hub_offset_um;
        let [delta_r, delta_t] = self.cut.hole_offset_um[i];
        let (sin, cos) = hole_at.sin_cos();
        let d_r = dx * cos + dy * sin;
        let d_t = -dx * sin + dy * cos;
        ((d_r - delta_r) * 1e-6, (d_t - delta_t) * 1e-6)
    }

    /// Hub rotation beyond the inset before prong `i` touches its hole, (forward, backward), rad.
    fn prong_play_rad(&self, i: usize) -> (f64, f64) {
        let radius = f64::from(self.geometry.hole_distance_mm) * 1e-3;
        let rho = self.hole_clearance_m();
        let (w_r, w_t) = self.prong_offset_m(i);
        let a = radius - w_r;
        let b = w_t;
        let c = (rho * rho - w_r * w_r - w_t * w_t) / (2.0 * radius);
        let psi = a.atan2(b);
        let s = ((c - a) / a.hypot(b)).clamp(-1.0, 1.0).asin();
        let forward = psi + s;
        let backward = PI - psi + s;
        (forward, backward)
    }

    /// The hub's play beyond the inset, (forward, backward), rad.
    pub(super) fn play_rad(&self) -> (f64, f64) {
        (self.side_play_rad(true), self.side_play_rad(false))
    }

    /// The hub's play beyond the inset forward or backward, rad: the first prong to touch its
    /// hole's face that way decides. Kept for the inset's angle it was computed at: the plant
    /// asks for it several times per sub-step, and the inset stands still for most of them.
    fn side_play_rad(&self, forward: bool) -> f64 {
        let side = usize::from(!forward);
        let mut cache = self.play_cache.get();
        if let Some((at_rad, play)) = cache[side]
            && at_rad == self.inset_rad
        {
            return play;
        }
        let pick = |(f, b): (f64, f64)| if forward { f } else { b };
        let play = pick(self.prong_play_rad(0)).min(pick(self.prong_play_rad(1)));
        cache[side] = Some((self.inset_rad, play));
        self.play_cache.set(cache);
        play
    }

    /// The inset's angle at which prong `i`, with the hub at `hub_rad`, touches its hole's
    /// forward face (`forward`) or its backward one, rad. On the table, the hole's centre turns
    /// with the inset on a circle of radius R' about the gauge's centre, and the prong's centre p
    /// is fixed by the hub: |p − R'·u(β + θs)| = ρ gives cos(β + θs − ∠p) = (|p|² + R'² − ρ²) /
    /// (2·R'·|p|), the hole behind the prong when it pushes forward, ahead of it backward.
    fn inset_touching_rad(&self, i: usize, hub_rad: f64, forward: bool) -> f64 {
        let radius = f64::from(self.geometry.hole_distance_mm) * 1e-3;
        let rho = self.hole_clearance_m();
        let prong_at = PI * i as f64;
        let [delta_r, delta_t] = self.cut.hole_offset_um[i];
        let (hole_r, hole_t) = (radius + delta_r * 1e-6, delta_t * 1e-6);
        let hole_radius = (hole_r * hole_r + hole_t * hole_t).sqrt();
        let hole_at = prong_at + hole_t.atan2(hole_r);
        let [dx, dy] = self.cut.hub_offset_um;
        let (sin, cos) = (prong_at + hub_rad).sin_cos();
        let (px, py) = (dx * 1e-6 + radius * cos, dy * 1e-6 + radius * sin);
        let prong_radius = (px * px + py * py).sqrt();
        let q = (prong_radius * prong_radius + hole_radius * hole_radius - rho * rho)
            / (2.0 * hole_radius * prong_radius);
        let centre_rad = wrap_pi(py.atan2(px) - hole_at - hub_rad) + hub_rad;
        let apart_rad = q.clamp(-1.0, 1.0).acos();
        if forward {
            centre_rad - apart_rad
        } else {
            centre_rad + apart_rad
        }
    }

    /// μ·r of the spiral contact, m.
    fn mu_r_m(&self) -> f64 {
        self.cut.mu * f64::from(self.geometry.radius_mm) * 1e-3
    }

    /// Full-face contact stiffness K, N/m.
    fn stiffness_n_per_m(&self) -> f64 {
        self.cut.stiffness_n_per_um * 1e6
    }

    /// Normal force of the contact at closure `e_m` beyond the narrowest kerf, N: the tapered
    /// elastic law ([`tapered_contact_force_n`]) up to the yield, then the crushing face's
    /// ([`YIELD_STIFFNESS_SHARE`] of the stiffness) beyond it.
    pub(super) fn force_at_closure_n(&self, e_m: f64) -> f64 {
        let elastic_n =
            tapered_contact_force_n(self.cut.stiffness_n_per_um, self.taper_m() * 1e6, e_m * 1e6);
        let yield_n = self.cut.yield_n;
        if elastic_n <= yield_n {
            return elastic_n;
        }
        let crushed_m = e_m - self.elastic_closure_m(yield_n);
        yield_n + YIELD_STIFFNESS_SHARE * self.stiffness_n_per_m() * crushed_m
    }

    /// The closure beyond the narrowest kerf at which the contact carries `force_n`, m (the
    /// inverse of [`Gauge::force_at_closure_n`]).
    fn closure_for_force_m(&self, force_n: f64) -> f64 {
        let force_n = force_n.max(0.0);
        let yield_n = self.cut.yield_n;
        if force_n <= yield_n {
            return self.elastic_closure_m(force_n);
        }
        let crush_stiffness = YIELD_STIFFNESS_SHARE * self.stiffness_n_per_m();
        self.elastic_closure_m(yield_n) + (force_n - yield_n) / crush_stiffness
    }

    /// The closure at which the elastic law alone carries `force_n`, m.
    fn elastic_closure_m(&self, force_n: f64) -> f64 {
        let k = self.stiffness_n_per_m();
        let taper = self.taper_m();
        if force_n <= k * taper / 2.0 {
            (2.0 * force_n * taper / k).sqrt()
        } else {
            force_n / k + taper / 2.0
        }
    }

    /// Normal force in the spiral contact, N.
    pub(super) fn contact_force_n(&self) -> f64 {
        if self.inset_present {
            self.force_at_closure_n(self.pitch_m_per_rad() * self.inset_rad - self.bottom_kerf_m())
        } else {
            0.0
        }
    }

    /// Whether a prong presses the inset forward (jam direction) and backward with the hub at
    /// `hub_rad` (only the side the hub stands on can be pressed).
    fn pressing(&self, hub_rad: f64) -> (bool, bool) {
        if !(self.inset_present && self.coupled) || self.on_face {
            return (false, false);
        }
        let rel = hub_rad - self.inset_rad;
        if rel >= 0.0 {
            (rel >= self.side_play_rad(true) - COUPLING_EPS, false)
        } else {
            (false, rel <= -self.side_play_rad(false) + COUPLING_EPS)
        }
    }

    /// The inset's resistance seen at the hub at `hub_rad`, forward and backward. The spiral is
    /// self-locking: its elastic push c·F_n never drives the inset back, so pressing forward meets
    /// F_n·(c + μ·r), pulling back meets F_n·(μ·r − c).
    pub(super) fn resistance(&self, p: &PlantParams, hub_rad: f64) -> (Resistance, Resistance) {
        let (forward, backward) = self.pressing(hub_rad);
        let force = self.contact_force_n();
        let c = self.pitch_m_per_rad();
        let mu_r = self.mu_r_m();
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

    /// The prongs come down with the hub at `hub_rad`: into the holes when it stands within its
    /// play of them, else onto the gauge's face (a hub a motor turn off its zero; see
    /// [`Gauge::drag`] for when they drop in).
    pub(super) fn land(&mut self, hub_rad: f64) {
        self.on_face = !self.within_play(hub_rad);
    }

    /// True when the prongs, with the hub at `hub_rad`, stand over the holes (within the play).
    fn within_play(&self, hub_rad: f64) -> bool {
        let rel = hub_rad - self.inset_rad;
        rel <= self.side_play_rad(true) && rel >= -self.side_play_rad(false)
    }

    /// The hub has moved to `hub_rad`: prongs resting on the gauge's face drop into the holes
    /// once over them; a prong at a side of its hole drags the inset along, to
    /// where the prong touches its face (the first prong to touch decides: pushed forward, the
    /// inset ends up as far as the further-ahead of the two places; pulled back, the other way).
    pub(super) fn drag(&mut self, hub_rad: f64) {
        if self.on_face {
            self.on_face = !self.within_play(hub_rad);
        }
        if !(self.inset_present && self.coupled) || self.on_face {
            return;
        }
        let rel = hub_rad - self.inset_rad;
        let forward = rel >= 0.0;
        if rel.abs() <= self.side_play_rad(forward) {
            return;
        }
        let (at_0, at_1) = (
            self.inset_touching_rad(0, hub_rad, forward),
            self.inset_touching_rad(1, hub_rad, forward),
        );
        self.inset_rad = if forward {
            at_0.max(at_1)
        } else {
            at_0.min(at_1)
        };
        // The prong that decided now touches its face: that side's play is known.
        let mut cache = self.play_cache.get();
        cache[usize::from(!forward)] = Some((self.inset_rad, (hub_rad - self.inset_rad).abs()));
        self.play_cache.set(cache);
    }

    /// The closure c·θs, m, at which the inset holds still under `torque_nm` pressing forward at
    /// the hub: F_n = τ / (c + μ·r), carried by the tapered contact.
    fn closure_at_torque_m(&self, torque_nm: f64) -> f64 {
        let lever = self.pitch_m_per_rad() + self.mu_r_m();
        self.bottom_kerf_m() + self.closure_for_force_m(torque_nm / lever)
    }

    /// The truth: the kerf an ideal device reads on this gauge at the force `run` asks for, µm.
    /// At the jam, τ = F_n·(c + μ·r) and τ is the ramp's target at the jam angle, which falls as
    /// the angle grows: the closure e solves e = closure(τ(e)), whose right side falls as e
    /// grows, so it has one root, found by bisection (a fixed-point iteration oscillates where
    /// the contact is soft, a crushing one above all).
    pub(super) fn truth_um(&self, run: &RunParams) -> f64 {
        let c = self.pitch_m_per_rad();
        let closure_at = |closure_m: f64| {
            let inset_deg = (closure_m / c).to_degrees() as f32;
            let torque =
                torque_for_force_nm(run, run.target_force_n, inset_deg).min(run.max_torque_nm);
            self.closure_at_torque_m(f64::from(torque))
        };
        // At zero closure the target's closure is above it; at half a turn the target is zero.
        let (mut lo_m, mut hi_m) = (0.0, c * PI);
        for _ in 0..TRUTH_ITERATIONS {
            let mid_m = (lo_m + hi_m) / 2.0;
            if closure_at(mid_m) > mid_m {
                lo_m = mid_m;
            } else {
                hi_m = mid_m;
            }
        }
        (lo_m + hi_m) / 2.0 * 1e6
    }

    /// What an ideal device reports for a jam under `torque_nm` at the hub, µm.
    pub(super) fn kerf_at_torque_um(&self, torque_nm: f64) -> f64 {
        self.closure_at_torque_m(torque_nm) * 1e6
    }
}

/// The stiffness of a crushing contact, past its yield, as a share of its elastic stiffness: a
/// fibreboard face densifying as it crushes.
pub const YIELD_STIFFNESS_SHARE: f64 = 0.1;

/// Normal force of a tapered cut face pressed `closure_um` beyond its narrowest kerf, N: with the
/// full face's stiffness K and a taper τ through the sheet, the contact spreads down the face as
/// it closes, K/τ·e²/2 while e ≤ τ, then carries the whole face, K·(e − τ/2). The gauge's spiral
/// and a joint's faces (the fit study) are the same kind of cut and share this law.
pub fn tapered_contact_force_n(stiffness_n_per_um: f64, taper_um: f64, closure_um: f64) -> f64 {
    let (k, taper, e) = (stiffness_n_per_um, taper_um.max(0.0), closure_um);
    if e <= 0.0 {
        0.0
    } else if e <= taper {
        k / taper * e * e / 2.0
    } else {
        k * (e - taper / 2.0)
    }
}

/// `angle_rad` brought into (−π, π].
fn wrap_pi(angle_rad: f64) -> f64 {
    PI - (PI - angle_rad).rem_euclid(2.0 * PI)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerfmeter_protocol::spiral::play_deg;

    const R_M: f64 = 5.3e-3;

    fn gauge(cut: GaugeCut) -> Gauge {
        Gauge::new(GaugeGeometry::PAPER, cut)
    }

    fn straight(kerf_um: f64) -> GaugeCut {
        GaugeCut {
            taper_um: 0.0,
            ..GaugeCut::nominal(&PlantParams::default(), kerf_um)
        }
    }

    #[test]
    fn a_perfect_cut_has_the_nominal_play_either_way() {
        let (forward, backward) = gauge(straight(150.0)).play_rad();
        let nominal = f64::from(play_deg(&GaugeGeometry::PAPER, 150.0)).to_radians();
        assert!((forward - nominal).abs() < 1e-6, "{forward} vs {nominal}");
        assert!((backward - nominal).abs() < 1e-6, "{backward} vs {nominal}");
    }

    #[test]
    fn a_displaced_hole_shortens_one_sides_play() {
        let perfect = gauge(straight(150.0)).play_rad();
        // Hole 0 cut 10 µm backward: prong 0 stands 10 µm forward in it.
        let mut cut = straight(150.0);
        cut.hole_offset_um[0] = [0.0, -10.0];
        let (forward, backward) = gauge(cut).play_rad();
        let expected = perfect.0 - 10e-6 / R_M;
        assert!(
            (forward - expected).abs() < 0.01 * 10e-6 / R_M,
            "{forward} vs {expected}"
        );
        // Backward, prong 0 has more room: prong 1 still touches at the nominal play.
        assert!((backward - perfect.1).abs() < 1e-12, "{backward}");
    }

    /// The linear prediction of the hub's forward play for a prong offset (see the module docs).
    fn predicted_forward_rad(g: &Gauge) -> f64 {
        let nominal = gauge(straight(g.cut.kerf_um)).play_rad().0;
        (0..2)
            .map(|i| {
                let (w_r, w_t) = g.prong_offset_m(i);
                nominal + (w_r * (nominal / 2.0).tan() - w_t) / R_M
            })
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn a_prong_offset_moves_one_prong_forward_and_the_other_backward() {
        let mut cut = straight(150.0);
        cut.hub_offset_um = [0.0, 8.0];
        let mut g = gauge(cut);
        let nominal = gauge(straight(150.0)).play_rad();
        // At zero the offset is purely tangential: both sides lose 8 µm / R.
        let (forward, backward) = g.play_rad();
        for play in [forward, backward] {
            assert!((nominal.0 - play - 8e-6 / R_M).abs() < 1e-3 * 8e-6 / R_M);
        }
        // With the inset turned 60°, only cos 60° of it is tangential at the holes.
        g.inset_rad = 60f64.to_radians();
        let (forward, _) = g.play_rad();
        let predicted = predicted_forward_rad(&g);
        assert!(
            (forward - predicted).abs() < 0.02 * 4e-6 / R_M,
            "{forward} vs {predicted}"
        );
        // That is 4 µm tangentially, less a little: the 6.9 µm now radial tilts the chord.
        let shift_um = (nominal.0 - forward) * R_M * 1e6;
        assert!(shift_um > 3.5 && shift_um < 4.0, "{shift_um}");
    }

    #[test]
    fn a_dragged_inset_is_left_with_the_prong_at_its_face_either_way() {
        let mut cut = straight(150.0);
        cut.hole_offset_um = [[6.0, -9.0], [-4.0, 3.0]];
        cut.hub_offset_um = [7.0, -5.0];
        let mut g = gauge(cut);
        for hub_deg in [10.0f64, 20.0, 47.5, 90.0, 140.0] {
            g.drag(hub_deg.to_radians());
            let rel = hub_deg.to_radians() - g.inset_rad;
            assert!((rel - g.play_rad().0).abs() < 1e-12, "{hub_deg}°: {rel}");
            assert!(g.pressing(hub_deg.to_radians()).0);
        }
        for hub_deg in [120.0f64, 60.0, 0.0] {
            g.drag(hub_deg.to_radians());
            let rel = hub_deg.to_radians() - g.inset_rad;
            assert!((rel + g.play_rad().1).abs() < 1e-12, "{hub_deg}°: {rel}");
            assert!(g.pressing(hub_deg.to_radians()).1);
        }
    }

    #[test]
    fn taper_makes_the_contact_quadratic_then_linear() {
        let mut cut = straight(150.0);
        cut.taper_um = 40.0;
        let g = gauge(cut);
        let k = cut.stiffness_n_per_um * 1e6;
        let f = |e_um: f64| g.force_at_closure_n(e_um * 1e-6);
        assert_eq!(f(-1.0), 0.0);
        // Quadratic while the contact spreads down the face: twice the closure, four times the
        // force.
        assert!((f(20.0) - 4.0 * f(10.0)).abs() < 1e-9 * f(20.0));
        assert!((f(40.0) - k * 40e-6 / 2.0).abs() < 1e-9);
        // Linear beyond, at the full face's stiffness, offset by half the taper.
        assert!((f(60.0) - f(50.0) - k * 10e-6).abs() < 1e-9);
        assert!((f(60.0) - k * (60e-6 - 20e-6)).abs() < 1e-9);
        // Continuous slope at e = τ: K·e/τ = K.
        let slope = (f(40.001) - f(39.999)) / 0.002e-6;
        assert!((slope / k - 1.0).abs() < 1e-3);
        // And the closure for a force inverts it on both branches.
        for e_um in [5.0, 30.0, 80.0] {
            assert!((g.closure_for_force_m(f(e_um)) * 1e6 - e_um).abs() < 1e-9);
        }
    }

    #[test]
    fn taper_moves_where_the_gap_closes_and_the_truth_with_it() {
        let straight_gauge = gauge(straight(150.0));
        let mut cut = straight(150.0);
        cut.taper_um = 40.0;
        let mut tapered = gauge(cut);
        // The narrowest (bottom) kerf closes first: 20 µm before the mid-sheet kerf.
        tapered.inset_rad = 131e-6 / tapered.pitch_m_per_rad();
        assert!(tapered.contact_force_n() > 0.0);
        tapered.inset_rad = 129e-6 / tapered.pitch_m_per_rad();
        assert_eq!(tapered.contact_force_n(), 0.0);
        // At the run's force the tapered contact is still within the quadratic branch here:
        // it reads less than the straight one, but more than its bottom kerf.
        let run = RunParams::DEFAULT;
        let (t_straight, t_tapered) = (straight_gauge.truth_um(&run), tapered.truth_um(&run));
        assert!(
            t_tapered < t_straight && t_tapered > 130.0,
            "{t_tapered} {t_straight}"
        );
    }

    #[test]
    fn the_truth_is_the_reading_at_the_targets_torque_and_ignores_holes_and_prongs() {
        let run = RunParams::DEFAULT;
        let g = gauge(GaugeCut::nominal(&PlantParams::default(), 150.0));
        let truth = g.truth_um(&run);
        let inset_deg = (truth * 1e-6 / g.pitch_m_per_rad()).to_degrees() as f32;
        let torque = torque_for_force_nm(&run, run.target_force_n, inset_deg);
        assert!((g.kerf_at_torque_um(f64::from(torque)) - truth).abs() < 1e-6);
        let mut cut = g.cut;
        cut.hole_offset_um = [[5.0, -7.0], [3.0, 9.0]];
        cut.hub_offset_um = [-4.0, 6.0];
        assert_eq!(gauge(cut).truth_um(&run), truth);
        // A softer gauge reads wider at the same force.
        cut.stiffness_n_per_um *= 0.8;
        assert!(gauge(cut).truth_um(&run) > truth);
    }
}
