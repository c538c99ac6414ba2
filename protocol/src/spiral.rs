//! The spiral gauge's model: the one place where an angle becomes a kerf and a force becomes a
//! torque. The device solves its jam angle here, the digital twin's plant builds its physics on
//! it, the host reads a run's sweep at other forces with it, and the gauge drawer takes the
//! spiral's pitch and start radius from it, so the gauge that is cut and the device that measures
//! it cannot disagree. Pure `f32` functions (`f64` for the drawer's conversions), `no_std`, no FPU
//! needed (`libm`).
//!
//! Symbols: pitch c, kerf k (the full cut width, µm), hub (encoder) angle θm and inset angle θs
//! (both from the zero position, prongs centred in their holes), prong radius r_p, nominal hole
//! radius r_h, hole distance R from the gauge centre, gauge mean radius r, sheet thickness L,
//! joint force F, total finger contact area A_j ([`GaugeGeometry`] and [`RunParams`] hold them).
//! Angles are degrees and c is µm per degree unless a name says otherwise.
//!
//! # The spiral
//!
//! The cut line is r(φ) = a + c·φ for one turn, closed by a radial step of height 2π·c, with
//! a = r − π·c ([`start_radius_mm`]; c in mm per radian: [`pitch_mm_per_rad`]). The cut removes
//! k/2 on both sides of the line. Turning the inset by θs towards *decreasing* φ narrows the gap
//! everywhere at once, because the spiral is self-similar:
//!
//! ```text
//!   gap = k − c·θs,   so the inset jams at θs = k / c.
//! ```
//!
//! Past the gauge's disengage angle the inset leaves the spiral: a fault, not a reading.
//!
//! # Hole play
//!
//! The laser enlarges each prong hole's radius by k/2 as well, so the hub turns freely by
//!
//! ```text
//!   θplay(k) = 2·asin((r_h − r_p + k/2) / (2R))
//! ```
//!
//! before the prongs drag the inset ([`play_deg`]). The encoder therefore reads
//! θm = θplay(k) + k / c, which [`kerf_from_angle`] solves for k by the fixed point
//!
//! ```text
//!   k ← c·(θm − θplay(k)),   starting from the uncorrected reading k = c·θm.
//! ```
//!
//! It contracts because its slope is c·dθplay/dk = c / (2R·cos(θplay/2)) (c in mm per radian),
//! about 0.015 on the paper's gauge (c = 0.159 mm/rad, R = 5.3 mm): each iteration shrinks the
//! error some 65-fold, so from the uncorrected reading (10–20 µm off, [`uncorrected_kerf_um`])
//! three iterations reach 0.001 µm and a fourth confirms it ([`KERF_TOLERANCE_UM`]).
//!
//! # Force and torque
//!
//! A box joint held by friction needs the assembly force F = μ·P·A_j. The inset sees the same
//! material, strain and μ·P over a contact arc that shrinks as it turns, so the hub torque that
//! presses it as hard as the joint is pressed by F is ([`torque_for_force_nm`])
//!
//! ```text
//!   τ(θs) = (2π − 2θs)·r²·L·F / A_j      (SI units, θs in radians)
//! ```
//!
//! e.g. three fingers of 4 mm stock at 50 N (A_j ≈ 152 mm², r = 10 mm): ≈ 0.62 N·m at 45° and
//! ≈ 0.41 N·m at 90°. A run records (torque, angle) all along its ramp, so one run answers for
//! every force up to its own ([`kerf_at_force_um`]).

use core::f32::consts::PI;

use crate::{GaugeGeometry, RunParams, Sample};

/// Stop iterating when an iterate moves less than this, µm.
pub const KERF_TOLERANCE_UM: f32 = 0.001;
/// Give up (and flag it) after this many iterations.
pub const KERF_MAX_ITERATIONS: u32 = 20;

const DEG_PER_RAD: f32 = 180.0 / PI;
const UM_PER_MM: f32 = 1000.0;

/// The spiral's pitch c in mm of radius per radian of turn (the gauge stores µm per degree).
pub fn pitch_mm_per_rad(gauge: &GaugeGeometry) -> f64 {
    f64::from(gauge.pitch_um_per_deg) * 1e-3 * 180.0 / core::f64::consts::PI
}

/// The spiral's radius a at φ = 0, mm: a = r − π·c, so that the gauge's `radius_mm` is the mean
/// radius over the turn.
pub fn start_radius_mm(gauge: &GaugeGeometry) -> f64 {
    f64::from(gauge.radius_mm) - core::f64::consts::PI * pitch_mm_per_rad(gauge)
}

/// Hub rotation before the prongs drag the inset, degrees, for a gauge cut with kerf `kerf_um`.
pub fn play_deg(gauge: &GaugeGeometry, kerf_um: f32) -> f32 {
    let clearance_mm = gauge.hole_radius_mm - gauge.prong_radius_mm + kerf_um / UM_PER_MM / 2.0;
    let ratio = (clearance_mm / (2.0 * gauge.hole_distance_mm)).clamp(-1.0, 1.0);
    2.0 * libm::asinf(ratio) * DEG_PER_RAD
}

/// The kerf whose gap closes with the inset turned by `inset_deg`, µm: k = c·θs.
pub fn kerf_for_inset_um(gauge: &GaugeGeometry, inset_deg: f32) -> f32 {
    gauge.pitch_um_per_deg * inset_deg
}

/// The kerf read without the hole-play correction, µm: c·θm. Off by 10–20 µm on the paper's
/// gauge; kept for comparison.
pub fn uncorrected_kerf_um(gauge: &GaugeGeometry, angle_deg: f32) -> f32 {
    kerf_for_inset_um(gauge, angle_deg)
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
    let mut kerf_um = uncorrected_kerf_um(gauge, angle_deg);
    let mut converged = false;
    for _ in 0..KERF_MAX_ITERATIONS {
        let next = kerf_step(gauge, angle_deg, kerf_um);
        kerf_um = next.kerf_um;
        if next.converged {
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

/// One iteration of [`kerf_from_angle`]'s fixed point from the estimate `kerf_um`: the next
/// estimate k = c·(θm − θplay(kerf_um)), the play and inset angle it rests on, and whether it
/// moved less than [`KERF_TOLERANCE_UM`]. One `asinf`.
///
/// A hub that turns slowly can be followed with one iteration per reading, each starting from
/// the last one's kerf: the iteration contracts some 65-fold (see the module's doc), so errors do
/// not build up, and the estimate lags the solved kerf by about one reading's change of it. On
/// the paper's gauge at 0.09° a reading that is 0.25 µm of kerf, and 0.0014° of play.
pub fn kerf_step(gauge: &GaugeGeometry, angle_deg: f32, kerf_um: f32) -> KerfSolution {
    let play = play_deg(gauge, kerf_um);
    let inset_deg = angle_deg - play;
    let next_um = kerf_for_inset_um(gauge, inset_deg);
    KerfSolution {
        kerf_um: next_um,
        play_deg: play,
        inset_deg,
        converged: (next_um - kerf_um).abs() < KERF_TOLERANCE_UM,
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
/// loading part of the sweep, up to its highest torque), less the hole play. `None` when the
/// sweep never reached that force (ask for at most the force the run reached).
///
/// `play_deg` is the run's hole play as its result reports it (`KerfResult::play_deg`: measured
/// by backing off where the device could, else the model's): the holes' play is the gauge's, the
/// same at every force, so every angle of the sweep is read with it. With `None` (a sweep
/// without its result) each angle is solved with the model's play ([`kerf_from_angle`]).
///
/// The kerf that matters depends on how hard the joint is pressed; one run answers for every
/// force up to its own. The log's samples are decimated (one kept per 2, 4, … ticks on a long
/// run), so its highest torque can sit a little under the torque the jam was held at: a force up
/// to [`SWEEP_PEAK_TOLERANCE`] above the sweep's peak is read at the peak.
pub fn kerf_at_force_um(
    params: &RunParams,
    samples: &[Sample],
    play_deg: Option<f32>,
    force_n: f32,
) -> Option<f32> {
    let peak = samples
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.torque_nm.total_cmp(&b.1.torque_nm))?
        .0;
    let gauge = &params.gauge;
    let inset_at = |angle_deg: f32| match play_deg {
        Some(play) => angle_deg - play,
        None => kerf_from_angle(gauge, angle_deg).inset_deg,
    };
    let kerf_at = |angle_deg: f32| kerf_for_inset_um(gauge, inset_at(angle_deg));
    let force_at =
        |s: &Sample| force_for_torque_n(params, s.torque_nm, inset_at(s.angle_deg).max(0.0));
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
            return Some(kerf_at(angle));
        }
        previous = Some((force, s.angle_deg));
    }
    match previous {
        Some((peak_force, peak_deg)) if force_n <= peak_force * (1.0 + SWEEP_PEAK_TOLERANCE) => {
            Some(kerf_at(peak_deg))
        }
        _ => None,
    }
}

/// How far above a sweep's highest force [`kerf_at_force_um`] still answers, as a fraction: the
/// run's own force, a fraction of a percent above its decimated log's peak, is in the sweep.
pub const SWEEP_PEAK_TOLERANCE: f32 = 0.01;

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
    fn one_step_per_reading_follows_a_turning_hub() {
        // A hub turning at the ramp's speed limit (0.09° a tick) from the zero-kerf play past the
        // disengage angle, followed with one iteration per reading from the last reading's kerf.
        let g = paper();
        let start_deg = play_deg(&g, 0.0);
        let mut kerf_um = 0.0;
        let mut worst_deg = 0.0f32;
        for tick in 0..2000 {
            let angle = start_deg + tick as f32 * 0.09;
            let step = kerf_step(&g, angle, kerf_um);
            kerf_um = step.kerf_um;
            let solved = kerf_from_angle(&g, angle);
            worst_deg = worst_deg.max((step.inset_deg - solved.inset_deg).abs());
        }
        // One reading moves the kerf 0.25 µm: the play lags by 0.0014°, and no more.
        assert!(worst_deg < 2e-3, "{worst_deg}");
        // The same iteration as the solver's: from the solution it stays put.
        let solved = kerf_from_angle(&g, 60.0);
        let again = kerf_step(&g, 60.0, solved.kerf_um);
        assert!(again.converged && (again.kerf_um - solved.kerf_um).abs() < KERF_TOLERANCE_UM);
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
    fn the_papers_pitch_is_about_a_millimetre_a_turn() {
        // 2.774 µm/° = 0.158938 mm/rad; the spiral starts at 10 − π·c and steps out by 2π·c.
        let c = pitch_mm_per_rad(&paper());
        assert!((c - 0.158938).abs() < 1e-6, "{c}");
        let a = start_radius_mm(&paper());
        assert!((a - 9.500680).abs() < 1e-6, "{a}");
    }

    /// A loading sweep whose jam angle grows 1 µm of kerf per 2 N, up to 80 N, then an unloading
    /// tail: the hub slips on at nine tenths of the peak torque.
    fn sweep(p: &RunParams) -> [Sample; 42] {
        let c = p.gauge.pitch_um_per_deg;
        let mut samples = [Sample {
            t_ms: 0,
            torque_nm: 0.0,
            angle_deg: 0.0,
        }; 42];
        for (i, s) in samples.iter_mut().enumerate().take(41) {
            let kerf_um = 150.0 + i as f32;
            *s = Sample {
                t_ms: i as u32,
                torque_nm: torque_for_force_nm(p, 2.0 * i as f32, kerf_um / c),
                angle_deg: angle_for(&p.gauge, kerf_um),
            };
        }
        samples[41] = Sample {
            t_ms: 41,
            torque_nm: 0.9 * samples[40].torque_nm,
            angle_deg: angle_for(&p.gauge, 400.0),
        };
        samples
    }

    #[test]
    fn the_sweep_is_read_where_the_loading_part_first_reaches_the_force() {
        let p = RunParams::DEFAULT;
        let samples = sweep(&p);
        // 55 N lies halfway between the samples at 54 N (177 µm) and 56 N (178 µm).
        let k = kerf_at_force_um(&p, &samples, None, 55.0).unwrap();
        assert!((k - 177.5).abs() < 0.01, "{k}");
        assert!((kerf_at_force_um(&p, &samples, None, 79.0).unwrap() - 189.5).abs() < 0.01);
        // The tail represents far more than 80 N at its large angle, but it is unloading.
        assert_eq!(kerf_at_force_um(&p, &samples, None, 85.0), None);
        assert_eq!(kerf_at_force_um(&p, &[], None, 10.0), None);
    }

    #[test]
    fn a_reported_play_reads_every_angle_of_the_sweep() {
        // The sweep's angles include the model's play; a play measured 0.5° shorter reads every
        // kerf 0.5° of pitch higher (the holes' play is the same at every force), less a little:
        // at a larger inset angle a torque stands for more force, so 55 N is met a shade sooner.
        let p = RunParams::DEFAULT;
        let samples = sweep(&p);
        let model_play = play_deg(&p.gauge, 177.5);
        let k = kerf_at_force_um(&p, &samples, Some(model_play - 0.5), 55.0).unwrap();
        let shift = 0.5 * p.gauge.pitch_um_per_deg;
        assert!(k < 177.5 + shift && k > 177.5 + shift - 0.2, "{k}");
    }

    #[test]
    fn an_angle_below_the_zero_kerf_play_gives_a_negative_kerf() {
        let s = kerf_from_angle(&paper(), 1.0);
        assert!(s.kerf_um < 0.0);
    }
}
