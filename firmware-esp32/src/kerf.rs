//! The measurement's math (DESIGN.md §3): hole play, kerf from the jam angle, and the torque that
//! represents a joint's assembly force. Pure functions, `f32`, no FPU needed (`libm`).
//!
//! Symbols: pitch c (µm per degree), kerf k (µm), hub (encoder) angle θm and inset angle θs
//! (degrees from the zero position), prong radius r_p, hole radius r_h, hole distance R.
//!
//! - The laser enlarges each prong hole's radius by k/2, so the hub turns freely by
//!   θplay(k) = 2·asin((r_h − r_p + k/2) / (2R)) before the prongs drag the inset.
//! - The spiral's gap k − c·θs closes at θs = k / c. Hence θm = θplay(k) + k / c, solved for k by
//!   the fixed point k ← c·(θm − θplay(k)). It contracts with factor ≈ c / (4R) ≈ 0.008 (c in
//!   mm/rad): three iterations reach 0.001 µm.
//! - A box joint held by friction needs force F = μ·P·A_j; the inset sees the same μ·P over a
//!   contact arc that shrinks as it turns, so the torque equivalent to F is
//!   τ(θs) = (2π − 2θs)·r²·L·F / A_j.

use core::f32::consts::PI;

use kerfmeter_protocol::{GaugeGeometry, RunParams, Sample};

/// Stop iterating when an iterate moves less than this, µm.
pub const KERF_TOLERANCE_UM: f32 = 0.001;
/// Give up (and flag it) after this many iterations.
pub const KERF_MAX_ITERATIONS: u32 = 20;

const DEG_PER_RAD: f32 = 180.0 / PI;
const UM_PER_MM: f32 = 1000.0;

/// Hub rotation before the prongs drag the inset, degrees, for a gauge cut with kerf `kerf_um`.
pub fn play_deg(gauge: &GaugeGeometry, kerf_um: f32) -> f32 {
    let clearance_mm = gauge.hole_radius_mm - gauge.prong_radius_mm + kerf_um / UM_PER_MM / 2.0;
    let ratio = (clearance_mm / (2.0 * gauge.hole_distance_mm)).clamp(-1.0, 1.0);
    2.0 * libm::asinf(ratio) * DEG_PER_RAD
}

/// The kerf read without the hole-play correction, µm: c·θm. Off by 10–20 µm on the paper's
/// gauge; kept for comparison.
pub fn uncorrected_kerf_um(gauge: &GaugeGeometry, angle_deg: f32) -> f32 {
    gauge.pitch_um_per_deg * angle_deg
}

/// A kerf solved from a hub angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KerfSolution {
    /// Kerf, µm (negative when the angle is smaller than the play of a zero kerf: no jam).
    pub kerf_um: f32,
    /// The hole play included in the angle, degrees.
    pub play_deg: f32,
    /// Inset rotation θs = θm − θplay, degrees.
    pub inset_deg: f32,
    /// False when the fixed point did not settle within [`KERF_MAX_ITERATIONS`].
    pub converged: bool,
}

/// Solve θm = θplay(k) + k / c for k by fixed-point iteration.
pub fn kerf_from_angle(gauge: &GaugeGeometry, angle_deg: f32) -> KerfSolution {
    let c = gauge.pitch_um_per_deg;
    let mut kerf_um = uncorrected_kerf_um(gauge, angle_deg);
    let mut converged = false;
    for _ in 0..KERF_MAX_ITERATIONS {
        let next = c * (angle_deg - play_deg(gauge, kerf_um));
        let step = (next - kerf_um).abs();
        kerf_um = next;
        if step < KERF_TOLERANCE_UM {
            converged = true;
            break;
        }
    }
    let play = play_deg(gauge, kerf_um);
    KerfSolution {
        kerf_um,
        play_deg: play,
        inset_deg: angle_deg - play,
        converged,
    }
}

/// The output torque that presses the inset as hard as the joint of `params` is pressed by its
/// assembly force `force_n`, with the inset turned by `inset_deg`: τ = (2π − 2θs)·r²·L·F / A_j.
pub fn torque_for_force_nm(params: &RunParams, force_n: f32, inset_deg: f32) -> f32 {
    torque_per_newton_nm(params, inset_deg) * force_n
}

/// The joint assembly force that `torque_nm` represents at inset angle `inset_deg`.
pub fn force_for_torque_n(params: &RunParams, torque_nm: f32, inset_deg: f32) -> f32 {
    let per_newton = torque_per_newton_nm(params, inset_deg);
    if per_newton > 0.0 {
        torque_nm / per_newton
    } else {
        f32::INFINITY
    }
}

/// dτ/dF at `inset_deg`, N·m per N (zero once the contact arc has vanished at θs = π).
fn torque_per_newton_nm(params: &RunParams, inset_deg: f32) -> f32 {
    let arc_rad = (2.0 * PI - 2.0 * inset_deg.max(0.0) / DEG_PER_RAD).max(0.0);
    let r_mm = params.gauge.radius_mm;
    // mm² · mm / mm² = mm; × 1e-3 → m.
    arc_rad * r_mm * r_mm * params.thickness_mm / params.contact_area_mm2 / UM_PER_MM
}

/// The kerf at another assembly force, read off a run's (torque, angle) sweep: the angle where
/// the torque first represents `force_n` (interpolated between samples, looking only at the
/// loading part of the sweep, up to its highest torque), solved for kerf. `None` when the sweep
/// never reached that force (ask for at most the force the run reached).
///
/// The design's point: the kerf that matters depends on how hard the joint is pressed; one run
/// answers for every force up to its own.
pub fn kerf_at_force_um(params: &RunParams, samples: &[Sample], force_n: f32) -> Option<f32> {
    let peak = samples
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.torque_nm.total_cmp(&b.1.torque_nm))?
        .0;
    let gauge = &params.gauge;
    let force_at = |s: &Sample| {
        let inset = kerf_from_angle(gauge, s.angle_deg).inset_deg.max(0.0);
        force_for_torque_n(params, s.torque_nm, inset)
    };
    let loading = &samples[..=peak];
    let mut previous: Option<(f32, f32)> = None;
    for s in loading {
        let force = force_at(s);
        if force >= force_n {
            let angle = match previous {
                Some((f0, a0)) if force > f0 => {
                    a0 + (s.angle_deg - a0) * (force_n - f0) / (force - f0)
                }
                _ => s.angle_deg,
            };
            return Some(kerf_from_angle(gauge, angle).kerf_um);
        }
        previous = Some((force, s.angle_deg));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> GaugeGeometry {
        GaugeGeometry::PAPER
    }

    /// θm for a true kerf, straight from the model (the forward direction).
    fn angle_for(gauge: &GaugeGeometry, kerf_um: f32) -> f32 {
        play_deg(gauge, kerf_um) + kerf_um / gauge.pitch_um_per_deg
    }

    #[test]
    fn the_fixed_point_inverts_the_model_across_the_gauge_range() {
        let g = paper();
        for k in (0..=430).step_by(5) {
            let k = k as f32;
            let s = kerf_from_angle(&g, angle_for(&g, k));
            assert!(s.converged);
            assert!(
                (s.kerf_um - k).abs() < 0.01,
                "kerf {k}: solved {}",
                s.kerf_um
            );
            assert!((s.inset_deg - k / g.pitch_um_per_deg).abs() < 0.001);
        }
    }

    #[test]
    fn the_play_is_what_the_closed_form_says() {
        // Computed in f64: 2·asin((2.42 − 2.0 + 0.05) / 10.6) = 5.08261°.
        let p = play_deg(&paper(), 100.0);
        assert!((p - 5.08261).abs() < 0.0005, "{p}");
    }

    #[test]
    fn uncorrected_error_matches_the_paper_14_and_17_um() {
        // The paper reports 14–17 µm error for kerf 100–300 µm without the correction.
        let g = paper();
        let e100 = uncorrected_kerf_um(&g, angle_for(&g, 100.0)) - 100.0;
        let e300 = uncorrected_kerf_um(&g, angle_for(&g, 300.0)) - 300.0;
        assert!((13.5..14.5).contains(&e100), "{e100}");
        assert!((16.5..17.5).contains(&e300), "{e300}");
    }

    #[test]
    fn torque_matches_the_papers_worked_numbers() {
        // Three fingers of 4 mm stock at 50 N: ≈ 0.62 N·m at 45°, ≈ 0.41 N·m at 90°
        // (r = 10 mm, L = 4 mm, A_j ≈ 152 mm²).
        let p = RunParams {
            thickness_mm: 4.0,
            contact_area_mm2: 152.0,
            ..RunParams::DEFAULT
        };
        let t45 = torque_for_force_nm(&p, 50.0, 45.0);
        let t90 = torque_for_force_nm(&p, 50.0, 90.0);
        assert!((t45 - 0.62).abs() < 0.005, "{t45}");
        assert!((t90 - 0.41).abs() < 0.005, "{t90}");
        // And back.
        assert!((force_for_torque_n(&p, t45, 45.0) - 50.0).abs() < 1e-3);
    }

    #[test]
    fn no_contact_arc_left_means_no_force_can_be_represented() {
        let p = RunParams::DEFAULT;
        assert_eq!(torque_for_force_nm(&p, 50.0, 180.0), 0.0);
        assert_eq!(force_for_torque_n(&p, 0.1, 180.0), f32::INFINITY);
    }

    #[test]
    fn an_angle_below_the_zero_kerf_play_gives_a_negative_kerf() {
        let s = kerf_from_angle(&paper(), 1.0);
        assert!(s.kerf_um < 0.0);
    }
}
