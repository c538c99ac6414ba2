//! The gauge a cutter cut, recovered from what its laser traced: the link between the cutter twin
//! (`kerfmeter::grbl::twin`, whose record lists every segment the laser cut, [`crate::traced`])
//! and the device twin's plant ([`crate::plant`]), so that the gauge the device
//! twin measures is the gauge the G-code cut ([`crate::Twin::place_traced_gauge`]). A gauge whose
//! G-code is wrong is measured wrong, as on a real machine.
//!
//! # What is recovered
//!
//! The trace is read in bed coordinates, mm, seen from above with X to the right and Y up (the
//! drawing's own y-up frame): G-code that flips Y (a machine whose Y grows towards the
//! operator, fed the drawing unflipped) cuts the gauge mirrored. The device comes down with its
//! prongs' axis along X, centred on where the gauge was meant to be. Only the cutting moves
//! count (G1/G2/G3 with the laser at `S` > 0), and only within the nominal gauge's outer radius
//! plus [`SEARCH_MARGIN_MM`] of where the gauge was meant to be (engraving or parts farther away
//! are ignored).
//!
//! - **Holes**: full circles, i.e. G2/G3 arcs about one centre and radius (within
//!   [`CIRCLE_MATCH_UM`]) that together sweep a whole turn, or a closed chain of straight cuts
//!   whose corners lie on one circle within it (a hole a Ruida controller cut from the arcs
//!   flattened into chords: `polygon`; a coarse polygon, whose sides' middles stray from the
//!   circle by more than that, is not recognised). Hole 0 is the circle whose centre is
//!   nearest where prong 0 comes down (the hole distance along +X from where the gauge was meant to be), hole 1 the one nearest prong 1
//!   (along −X), each within the drawn hole radius of it.
//! - **The spiral**: every other cut, sampled every [`SAMPLE_STEP_MM`], fitted by least squares
//!   to r(φ) = a + c·φ about an unknown centre, φ counted from the radial step, with a signed
//!   pitch c: c > 0 means φ grows counter-clockwise (a clockwise jam, as drawn by default), c < 0
//!   the mirror image. Gauss–Newton on the centre, a and c from the holes' midpoint; the step's
//!   direction is where the samples' radius jumps (elsewhere a rotation of the spiral is the same
//!   as a change of a), and samples within [`STEP_EXCLUSION_RAD`] of it are left out. Every
//!   other sample must lie within [`SPIRAL_TOLERANCE_UM`] of the fitted spiral (G-code rounds to
//!   1 µm; the drawing's biarcs are within 0.05 µm), and the cut must go round at least
//!   [`MIN_SPIRAL_COVERAGE`] of a turn. Where the step points does not matter to the device.
//!
//! # What the device then meets ([`TracedGauge::gauge_cut`])
//!
//! The physical [`GaugeGeometry`] is the nominal one with the traced pitch, mean radius, sense
//! and hole radius (the smaller of the two: the plant models one, and the tighter hole stops its
//! prong first); the prongs keep the device's hole distance. The [`GaugeCut`] is drawn by the
//! one kerf model, [`Cutter::cut`] (kerf with its location bias and spread, taper, contact,
//! and the machine's repeatability on the holes and on the head's return), plus what the trace
//! says: each hole's displacement from where the traced spiral's centre puts it, and the
//! traced centre's distance from where the prongs come down (where the gauge was meant to be).
//!
//! It is refused, with a [`GaugeTraceError`] that says what and where, when:
//! - no spiral was cut there, or what was cut is not one;
//! - the spiral turns the other way than the device expects. A real device would turn the inset
//!   against the spiral, where the gap opens and the radial step's faces close after about
//!   k / (a + 2π·c) (under a degree): it would read a few µm. The plant does not model the step,
//!   so the twin refuses rather than invent that reading;
//! - a hole is missing;
//! - a prong cannot enter its hole: the hole as cut (traced radius + half the bottom kerf) is no
//!   wider than the prong, or the prong comes down farther from the hole's centre than that
//!   clearance.
//!
//! A pitch that is wrong is not refused: the device reads k·c/c′ on a spiral of pitch c′ when it
//! was told c (a spiral 4 % too steep reads 3.8 % low).

use core::f64::consts::{PI, TAU};
use std::sync::{Arc, Mutex, PoisonError};

use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_protocol::spiral::{pitch_mm_per_rad, start_radius_mm};
use kerfmeter_protocol::{GaugeGeometry, JamDirection};

use crate::plant::{Cutter, GaugeCut};
use crate::traced::{Segment, SegmentKind, sweep_rad};

/// How far beyond the nominal gauge's outer radius cuts still count as the gauge's, mm.
pub const SEARCH_MARGIN_MM: f64 = 1.0;
/// Spacing of the samples taken along the traced cuts, mm.
pub const SAMPLE_STEP_MM: f64 = 0.05;
/// Arcs belong to one circle when their centres and radii agree within this, µm.
pub const CIRCLE_MATCH_UM: f64 = 2.0;
/// The largest distance of a spiral sample from the fitted spiral, µm.
pub const SPIRAL_TOLERANCE_UM: f64 = 10.0;
/// Samples this close in angle to the radial step are left out of the spiral's fit, rad.
pub const STEP_EXCLUSION_RAD: f64 = 0.05;
/// The share of a turn the spiral's samples must cover (in 64 sectors about the centre).
pub const MIN_SPIRAL_COVERAGE: f64 = 0.9;

/// Sectors of the coverage check.
const SECTORS: usize = 64;
/// Gauss–Newton iterations at most.
const FIT_ITERATIONS: usize = 40;
/// The fit has converged when no parameter moves more than this (mm or rad).
const FIT_CONVERGED: f64 = 1e-10;

/// One prong hole as traced (its centre line: the cut is wider by the kerf).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracedHole {
    /// Centre on the bed, mm.
    pub center_mm: [f64; 2],
    /// Traced radius, mm.
    pub radius_mm: f64,
}

/// A gauge as its trace shows it (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracedGauge {
    /// The spiral's centre on the bed, mm.
    pub center_mm: [f64; 2],
    /// Its pitch c, µm per degree.
    pub pitch_um_per_deg: f64,
    /// Its mean radius over the turn, mm.
    pub radius_mm: f64,
    /// The sense the inset jams in.
    pub jam_direction: JamDirection,
    /// Direction of the radial step from the centre, rad, counter-clockwise from +X.
    pub step_rad: f64,
    /// Largest distance of a spiral sample from the fitted spiral, µm.
    pub max_residual_um: f64,
    /// Hole 0 (prong 0's, along +X) and hole 1.
    pub holes: [TracedHole; 2],
}

/// Why no gauge could be recovered from a trace, or a recovered one cannot be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GaugeTraceError {
    /// No spiral, or not one, within the search radius of where the gauge was meant to be.
    #[error(
        "no gauge spiral was cut within {radius_mm:.2} mm of ({:.3}, {:.3}) mm: {reason}",
        at_mm[0], at_mm[1]
    )]
    NoSpiral {
        /// Where the gauge was meant to be, mm.
        at_mm: [f64; 2],
        /// The search radius, mm.
        radius_mm: f64,
        /// What was found instead.
        reason: String,
    },
    /// The spiral turns the other way than the device expects.
    #[error(
        "the spiral cut at ({:.3}, {:.3}) mm is mirrored: it jams {found:?}, the device turns {expected:?} (a mirrored drawing or a flipped axis in the G-code)",
        center_mm[0], center_mm[1]
    )]
    SenseReversed {
        /// The spiral's centre, mm.
        center_mm: [f64; 2],
        /// The traced spiral's jam direction.
        found: JamDirection,
        /// The device's.
        expected: JamDirection,
    },
    /// No full circle where a prong comes down.
    #[error(
        "hole {hole} is missing: no full circle was cut within {search_mm:.2} mm of ({:.3}, {:.3}) mm, where prong {hole} comes down",
        expected_mm[0], expected_mm[1]
    )]
    HoleMissing {
        /// The hole (0 along +X from the centre, 1 along −X).
        hole: usize,
        /// Where its prong comes down, mm.
        expected_mm: [f64; 2],
        /// How far from there a circle's centre was looked for, mm.
        search_mm: f64,
    },
    /// The hole as cut is no wider than the prong.
    #[error(
        "hole {hole} at ({:.3}, {:.3}) mm is too small: traced at r = {traced_radius_mm:.3} mm, cut {cut_radius_mm:.3} mm with the kerf, the prong is {prong_radius_mm:.3} mm",
        center_mm[0], center_mm[1]
    )]
    HoleTooSmall {
        /// The hole.
        hole: usize,
        /// Its centre, mm.
        center_mm: [f64; 2],
        /// Its traced radius, mm.
        traced_radius_mm: f64,
        /// Its radius as cut (at the bottom of the sheet), mm.
        cut_radius_mm: f64,
        /// The prong's radius, mm.
        prong_radius_mm: f64,
    },
    /// The prong comes down outside the room its hole leaves it.
    #[error(
        "prong {hole} cannot enter hole {hole} at ({:.3}, {:.3}) mm: it comes down {offset_um:.0} µm from the hole's centre, which leaves it {clearance_um:.0} µm",
        center_mm[0], center_mm[1]
    )]
    ProngOffHole {
        /// The hole.
        hole: usize,
        /// Its centre, mm.
        center_mm: [f64; 2],
        /// The prong's distance from the hole's centre, µm.
        offset_um: f64,
        /// Hole radius as cut minus prong radius, µm.
        clearance_um: f64,
    },
}

/// The traced gauge a twin places for its runs (its physical geometry and cut), shared with
/// whoever serves it (a [`crate::PtyTwin`]'s caller places one while the twin runs in its
/// thread). Cloning shares the slot.
#[derive(Debug, Clone, Default)]
pub struct TracedGaugeSlot(Arc<Mutex<Option<(GaugeGeometry, GaugeCut)>>>);

impl TracedGaugeSlot {
    /// The gauge in the slot, if any.
    pub fn get(&self) -> Option<(GaugeGeometry, GaugeCut)> {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Put `gauge` in the slot (or empty it).
    pub fn set(&self, gauge: Option<(GaugeGeometry, GaugeCut)>) {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner) = gauge;
    }

    /// Recover the gauge cut around `at_mm` from `segments` for a device that expects
    /// `nominal`, cut by `cutter` (drawing from `rng`), and put it in the slot; the cut, or why
    /// not (the slot is then left as it was).
    pub fn place(
        &self,
        segments: &[Segment],
        nominal: &GaugeGeometry,
        at_mm: [f64; 2],
        cutter: &Cutter,
        rng: &mut Rng,
    ) -> Result<GaugeCut, GaugeTraceError> {
        let traced = TracedGauge::recover(segments, nominal, at_mm)?;
        let (geometry, cut) = traced.gauge_cut(nominal, at_mm, cutter, rng)?;
        self.set(Some((geometry, cut)));
        Ok(cut)
    }
}

/// +1 when φ grows counter-clockwise (a clockwise jam), −1 otherwise.
fn sense(jam: JamDirection) -> f64 {
    match jam {
        JamDirection::Clockwise => 1.0,
        JamDirection::CounterClockwise => -1.0,
    }
}

/// A whole circle traced as arcs.
#[derive(Debug, Clone, Copy)]
struct Circle {
    center: [f64; 2],
    radius: f64,
    sweep: f64,
}

impl TracedGauge {
    /// Recover the gauge cut around `at_mm` (where it was meant to be) from `segments`, for a
    /// device that expects `nominal`.
    pub fn recover(
        segments: &[Segment],
        nominal: &GaugeGeometry,
        at_mm: [f64; 2],
    ) -> Result<Self, GaugeTraceError> {
        let c_nominal = pitch_mm_per_rad(nominal);
        let search_mm = start_radius_mm(nominal) + TAU * c_nominal + SEARCH_MARGIN_MM;
        let near = |p: [f64; 3]| (p[0] - at_mm[0]).hypot(p[1] - at_mm[1]) <= search_mm;
        // An arc wider than the search area leaves it, whatever its ends.
        let small = |s: &Segment| arc_of(s).is_none_or(|arc| arc.radius <= search_mm);
        let cuts: Vec<&Segment> = segments
            .iter()
            .filter(|s| {
                s.power_s > 0.0 && matches!(s.kind, SegmentKind::Line | SegmentKind::Arc { .. })
            })
            .filter(|s| near(s.start) && near(s.end) && small(s))
            .collect();
        let mut circles = full_circles(&cuts);
        let (polygons, on_polygon) = polygon::polygon_circles(&cuts);
        circles.extend(polygons);
        let mut points = Vec::new();
        for (s, on_polygon) in cuts.iter().zip(on_polygon) {
            if !on_polygon && !on_a_circle(s, &circles) {
                sample(s, &mut points);
            }
        }
        let no_spiral = |reason: String| GaugeTraceError::NoSpiral {
            at_mm,
            radius_mm: search_mm,
            reason,
        };
        let coverage = coverage(&points, at_mm);
        if coverage < MIN_SPIRAL_COVERAGE {
            return Err(no_spiral(format!(
                "the cuts there go round {:.0} % of a turn",
                coverage * 100.0
            )));
        }
        let fit = fit_spiral(&points, first_centre(&circles, at_mm, nominal))
            .ok_or_else(|| no_spiral("the cuts there fit no spiral".into()))?;
        let [x0, y0, step_rad, a, c] = fit.params;
        let max_residual_um = fit.max_residual_mm * 1e3;
        // Written so that a NaN (a degenerate fit) is refused too.
        if !(max_residual_um <= SPIRAL_TOLERANCE_UM && c != 0.0) {
            return Err(no_spiral(format!(
                "the cut there is {max_residual_um:.1} µm off the nearest Archimedean spiral (at most {SPIRAL_TOLERANCE_UM} µm)"
            )));
        }
        let holes = [
            find_hole(&circles, at_mm, nominal, 0)?,
            find_hole(&circles, at_mm, nominal, 1)?,
        ];
        Ok(Self {
            center_mm: [x0, y0],
            pitch_um_per_deg: c.abs() * 1e3 * PI / 180.0,
            radius_mm: a + PI * c,
            jam_direction: if c > 0.0 {
                JamDirection::Clockwise
            } else {
                JamDirection::CounterClockwise
            },
            step_rad: step_rad.rem_euclid(TAU),
            max_residual_um,
            holes,
        })
    }

    /// The gauge's physical geometry, for a device that expects `nominal`: the traced pitch,
    /// mean radius, sense and (smaller) hole radius; the prongs' radius and distance, and the
    /// disengage angle, are the device's.
    pub fn geometry(&self, nominal: &GaugeGeometry) -> GaugeGeometry {
        GaugeGeometry {
            pitch_um_per_deg: self.pitch_um_per_deg as f32,
            radius_mm: self.radius_mm as f32,
            hole_radius_mm: self.holes[0].radius_mm.min(self.holes[1].radius_mm) as f32,
            jam_direction: self.jam_direction,
            ..*nominal
        }
    }

    /// The gauge as the device meets it when its prongs come down over `at_mm`: its physical
    /// geometry and its cut, drawn by `cutter` from `rng` (see the [module docs](self)); or why
    /// the device cannot measure it.
    pub fn gauge_cut(
        &self,
        nominal: &GaugeGeometry,
        at_mm: [f64; 2],
        cutter: &Cutter,
        rng: &mut Rng,
    ) -> Result<(GaugeGeometry, GaugeCut), GaugeTraceError> {
        if self.jam_direction != nominal.jam_direction {
            return Err(GaugeTraceError::SenseReversed {
                center_mm: self.center_mm,
                found: self.jam_direction,
                expected: nominal.jam_direction,
            });
        }
        let geometry = self.geometry(nominal);
        let mut cut = cutter.cut(rng);
        // The gauge's frame at zero: x towards hole 0 (+X), y the jam direction at hole 0.
        let s = sense(self.jam_direction);
        let to_gauge_um = |v: [f64; 2]| [v[0] * 1e3, -s * v[1] * 1e3];
        let hub = to_gauge_um([at_mm[0] - self.center_mm[0], at_mm[1] - self.center_mm[1]]);
        cut.hub_offset_um = [cut.hub_offset_um[0] + hub[0], cut.hub_offset_um[1] + hub[1]];
        let distance_mm = f64::from(nominal.hole_distance_mm);
        for (i, hole) in self.holes.iter().enumerate() {
            // Hole 1's radial and tangential directions are hole 0's, reversed.
            let side = if i == 0 { 1.0 } else { -1.0 };
            let drawn = [self.center_mm[0] + side * distance_mm, self.center_mm[1]];
            let moved = to_gauge_um([hole.center_mm[0] - drawn[0], hole.center_mm[1] - drawn[1]]);
            let offset = &mut cut.hole_offset_um[i];
            *offset = [offset[0] + side * moved[0], offset[1] + side * moved[1]];
            let hub_here = [side * cut.hub_offset_um[0], side * cut.hub_offset_um[1]];
            let prong_um = (hub_here[0] - offset[0]).hypot(hub_here[1] - offset[1]);
            check_entry(i, hole, prong_um, &cut, nominal)?;
        }
        Ok((geometry, cut))
    }
}

/// Refuse a hole its prong cannot enter: the hole as cut at the bottom of the sheet (traced
/// radius + half the bottom kerf) against the prong coming down `prong_um` off its centre.
fn check_entry(
    i: usize,
    hole: &TracedHole,
    prong_um: f64,
    cut: &GaugeCut,
    nominal: &GaugeGeometry,
) -> Result<(), GaugeTraceError> {
    let taper_um = cut.taper_um.clamp(0.0, 2.0 * cut.kerf_um);
    let bottom_kerf_um = cut.kerf_um - taper_um / 2.0;
    let cut_radius_mm = hole.radius_mm + bottom_kerf_um * 1e-3 / 2.0;
    let prong_radius_mm = f64::from(nominal.prong_radius_mm);
    let clearance_um = (cut_radius_mm - prong_radius_mm) * 1e3;
    if clearance_um <= 0.0 {
        return Err(GaugeTraceError::HoleTooSmall {
            hole: i,
            center_mm: hole.center_mm,
            traced_radius_mm: hole.radius_mm,
            cut_radius_mm,
            prong_radius_mm,
        });
    }
    if prong_um > clearance_um {
        return Err(GaugeTraceError::ProngOffHole {
            hole: i,
            center_mm: hole.center_mm,
            offset_um: prong_um,
            clearance_um,
        });
    }
    Ok(())
}

/// Where to start looking for the spiral's centre: midway between the holes if both were cut,
/// else where the gauge was meant to be.
fn first_centre(circles: &[Circle], at_mm: [f64; 2], nominal: &GaugeGeometry) -> [f64; 2] {
    match (
        find_hole(circles, at_mm, nominal, 0),
        find_hole(circles, at_mm, nominal, 1),
    ) {
        (Ok(p), Ok(q)) => [
            (p.center_mm[0] + q.center_mm[0]) / 2.0,
            (p.center_mm[1] + q.center_mm[1]) / 2.0,
        ],
        _ => at_mm,
    }
}

/// The circle nearest where prong `i` comes down, within the drawn hole radius of it.
fn find_hole(
    circles: &[Circle],
    at_mm: [f64; 2],
    nominal: &GaugeGeometry,
    i: usize,
) -> Result<TracedHole, GaugeTraceError> {
    let side = if i == 0 { 1.0 } else { -1.0 };
    let expected_mm = [
        at_mm[0] + side * f64::from(nominal.hole_distance_mm),
        at_mm[1],
    ];
    let search_mm = f64::from(nominal.hole_radius_mm);
    let distance = |c: &Circle| (c.center[0] - expected_mm[0]).hypot(c.center[1] - expected_mm[1]);
    circles
        .iter()
        .filter(|c| distance(c) <= search_mm)
        .min_by(|p, q| distance(p).total_cmp(&distance(q)))
        .map(|c| TracedHole {
            center_mm: c.center,
            radius_mm: c.radius,
        })
        .ok_or(GaugeTraceError::HoleMissing {
            hole: i,
            expected_mm,
            search_mm,
        })
}

/// An arc's centre, start radius and sweep (rad, unsigned).
fn arc_of(s: &Segment) -> Option<Circle> {
    let SegmentKind::Arc { center, clockwise } = s.kind else {
        return None;
    };
    Some(Circle {
        center,
        radius: (s.start[0] - center[0]).hypot(s.start[1] - center[1]),
        sweep: sweep_rad(s.start, s.end, center, clockwise),
    })
}

/// Whether two circles agree within [`CIRCLE_MATCH_UM`].
fn same_circle(p: &Circle, q: &Circle) -> bool {
    let tol_mm = CIRCLE_MATCH_UM * 1e-3;
    (p.center[0] - q.center[0]).hypot(p.center[1] - q.center[1]) <= tol_mm
        && (p.radius - q.radius).abs() <= tol_mm
}

/// The circles the arcs among `cuts` trace whole (their sweeps adding up to a turn).
fn full_circles(cuts: &[&Segment]) -> Vec<Circle> {
    let mut groups: Vec<Circle> = Vec::new();
    for arc in cuts.iter().filter_map(|s| arc_of(s)) {
        match groups.iter_mut().find(|g| same_circle(g, &arc)) {
            Some(g) => g.sweep += arc.sweep,
            None => groups.push(arc),
        }
    }
    groups.retain(|g| g.sweep >= TAU * (1.0 - 1e-6));
    groups
}

/// Whether `s` is an arc of one of `circles`.
fn on_a_circle(s: &Segment, circles: &[Circle]) -> bool {
    arc_of(s).is_some_and(|arc| circles.iter().any(|c| same_circle(c, &arc)))
}

/// Points along a cut, every [`SAMPLE_STEP_MM`] at most, both ends included.
fn sample(s: &Segment, out: &mut Vec<[f64; 2]>) {
    let (p, q) = ([s.start[0], s.start[1]], [s.end[0], s.end[1]]);
    match arc_of(s) {
        Some(arc) => {
            let SegmentKind::Arc { clockwise, .. } = s.kind else {
                return;
            };
            let c = arc.center;
            let end_radius = (q[0] - c[0]).hypot(q[1] - c[1]);
            let a0 = (p[1] - c[1]).atan2(p[0] - c[0]);
            let turn = if clockwise { -arc.sweep } else { arc.sweep };
            let n = (arc.radius * arc.sweep / SAMPLE_STEP_MM).ceil().max(1.0) as usize;
            out.extend((0..=n).map(|k| {
                let f = k as f64 / n as f64;
                let r = arc.radius + (end_radius - arc.radius) * f;
                let (sin, cos) = (a0 + turn * f).sin_cos();
                [c[0] + r * cos, c[1] + r * sin]
            }));
        }
        None => {
            let length = (q[0] - p[0]).hypot(q[1] - p[1]);
            let n = (length / SAMPLE_STEP_MM).ceil().max(1.0) as usize;
            out.extend((0..=n).map(|k| {
                let f = k as f64 / n as f64;
                [p[0] + (q[0] - p[0]) * f, p[1] + (q[1] - p[1]) * f]
            }));
        }
    }
}

/// The share of [`SECTORS`] sectors about `center` that hold a point.
fn coverage(points: &[[f64; 2]], center: [f64; 2]) -> f64 {
    let mut hit = [false; SECTORS];
    for p in points {
        let theta = (p[1] - center[1]).atan2(p[0] - center[0]).rem_euclid(TAU);
        hit[((theta / TAU * SECTORS as f64) as usize).min(SECTORS - 1)] = true;
    }
    hit.iter().filter(|h| **h).count() as f64 / SECTORS as f64
}

/// A fitted spiral: `[x0, y0, φ0, a, c]` (mm, rad, c signed, mm/rad) and its largest residual.
struct SpiralFit {
    params: [f64; 5],
    max_residual_mm: f64,
}

/// A point's polar position about the spiral's centre: radius, and φ from the step in [0, 2π).
fn polar(p: &[f64; 5], q: [f64; 2]) -> (f64, f64) {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    (dx.hypot(dy), (dy.atan2(dx) - p[2]).rem_euclid(TAU))
}

/// Whether φ is far enough from the step to take part in the fit.
fn away_from_step(phi: f64) -> bool {
    (STEP_EXCLUSION_RAD..=TAU - STEP_EXCLUSION_RAD).contains(&phi)
}

/// Fit r = a + c·φ about an unknown centre (see the [module docs](self)), starting at
/// `start_mm`: Gauss–Newton on the centre, a and c, the step's direction found again from the
/// samples about each new centre (rotating a spiral is the same as changing its a, so only the
/// step fixes its direction); `None` if the equations are singular.
fn fit_spiral(points: &[[f64; 2]], start_mm: [f64; 2]) -> Option<SpiralFit> {
    let mut params = [start_mm[0], start_mm[1], 0.0, 0.0, 0.0];
    for _ in 0..FIT_ITERATIONS {
        params[2] = step_direction_rad(points, [params[0], params[1]]);
        if !fit_radius_line(points, &mut params).is_finite() {
            return None;
        }
        let step = gauss_newton_step(points, &params)?;
        for (p, d) in [0, 1, 3, 4].into_iter().zip(step) {
            params[p] += d;
        }
        if step.iter().all(|d| d.abs() < FIT_CONVERGED) {
            break;
        }
    }
    params[2] = step_direction_rad(points, [params[0], params[1]]);
    let max_residual_mm = points
        .iter()
        .map(|q| polar(&params, *q))
        .filter(|(_, phi)| away_from_step(*phi))
        .map(|(r, phi)| (r - params[3] - params[4] * phi).abs())
        .fold(0.0, f64::max);
    Some(SpiralFit {
        params,
        max_residual_mm,
    })
}

/// The direction of the spiral's radial step from `centre`, rad: where, going round, the
/// samples' radius jumps the most (along the step it changes by a sample's spacing, along the
/// spiral by c times a sample's tiny angle).
fn step_direction_rad(points: &[[f64; 2]], centre: [f64; 2]) -> f64 {
    let mut polar: Vec<(f64, f64)> = points
        .iter()
        .map(|q| {
            let (dx, dy) = (q[0] - centre[0], q[1] - centre[1]);
            (dy.atan2(dx), dx.hypot(dy))
        })
        .collect();
    polar.sort_by(|p, q| p.0.total_cmp(&q.0));
    polar
        .windows(2)
        .max_by(|p, q| (p[1].1 - p[0].1).abs().total_cmp(&(q[1].1 - q[0].1).abs()))
        .map_or(0.0, |w| w[0].0)
}

/// With the centre and step fixed, the least-squares a and c (written into `p`); the sum of
/// squared residuals (infinite with fewer than two samples).
fn fit_radius_line(points: &[[f64; 2]], p: &mut [f64; 5]) -> f64 {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for q in points {
        let (r, phi) = polar(p, *q);
        if away_from_step(phi) {
            n += 1.0;
            sx += phi;
            sy += r;
            sxx += phi * phi;
            sxy += phi * r;
            syy += r * r;
        }
    }
    let det = n * sxx - sx * sx;
    if n < 2.0 || det <= 0.0 {
        return f64::INFINITY;
    }
    let c = (n * sxy - sx * sy) / det;
    let a = (sy - c * sx) / n;
    p[3] = a;
    p[4] = c;
    syy - a * sy - c * sxy
}

/// One Gauss–Newton step of the residual ρ − a − c·φ over the points away from the step, in
/// the centre, a and c (the step's direction held).
fn gauss_newton_step(points: &[[f64; 2]], p: &[f64; 5]) -> Option<[f64; 4]> {
    let mut jtj = [[0.0; 4]; 4];
    let mut jtr = [0.0; 4];
    for q in points {
        let (r, phi) = polar(p, *q);
        if !away_from_step(phi) || r == 0.0 {
            continue;
        }
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let c = p[4];
        // ∂ρ/∂x0 = −dx/ρ, ∂θ/∂x0 = dy/ρ²; ∂ρ/∂y0 = −dy/ρ, ∂θ/∂y0 = −dx/ρ².
        let jacobian = [
            -dx / r - c * dy / (r * r),
            -dy / r + c * dx / (r * r),
            -1.0,
            -phi,
        ];
        let residual = r - p[3] - c * phi;
        for i in 0..4 {
            jtr[i] += jacobian[i] * residual;
            for j in 0..4 {
                jtj[i][j] += jacobian[i] * jacobian[j];
            }
        }
    }
    solve(jtj, jtr.map(|v| -v))
}

/// Solve `m·x = b` by Gaussian elimination with partial pivoting; `None` if singular.
fn solve<const N: usize>(mut m: [[f64; N]; N], mut b: [f64; N]) -> Option<[f64; N]> {
    for col in 0..N {
        let pivot = (col..N).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[pivot][col].abs() < 1e-300 {
            return None;
        }
        m.swap(col, pivot);
        b.swap(col, pivot);
        for row in col + 1..N {
            let f = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (x, p) in m[row].iter_mut().zip(pivot_row).skip(col) {
                *x -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; N];
    for row in (0..N).rev() {
        let tail: f64 = (row + 1..N).map(|k| m[row][k] * x[k]).sum();
        x[row] = (b[row] - tail) / m[row][row];
    }
    Some(x)
}

mod polygon;
#[cfg(test)]
mod tests;
