//! Jam detection: the angle's slope over a short window, and the median angle over the hold
//! window.
//!
//! The rule: the hub counts as jammed when the angle's change over a short regression window
//! (about 20 ms) stays within a few encoder LSB, with the commanded torque above breakaway and
//! the inset turned past a minimum; the torque is then held for 50–100 ms, the jam angle θm is the
//! median over that hold, and the gauge is unloaded. (The controller applies the rule; this
//! module holds the two windows it needs.)
//!
//! [`SlopeWindow`] keeps the last [`JAM_WINDOW_TICKS`] angles and fits a least-squares line: its
//! slope is the hub speed, and slope × window length is the angle change "over the window" that
//! must stay within a few encoder LSB for the hub to count as still. [`HoldWindow`] collects the
//! angles while torque is held at a jam and gives their median (robust to a stray sample), their
//! spread, and the drift between the means of the hold's halves (a hold that drifts is flagged:
//! the jam was still moving).
//!
//! # The regression in O(1) per tick, in integers
//!
//! The slope is needed every tick the motor may be driven, and the ESP32-C3 has no FPU: a fit
//! that loops over the window in `f32` costs some 14.6k instructions a tick. So the window keeps
//! its angles as integers of [`SLOPE_UNIT_DEG`] (2⁻²⁴ turn, 1/1024 of an AS5048A count on the
//! output shaft, about f32's own resolution at 180°) together with two running sums, Σy and Σx·y
//! with x = 0 for the oldest angle. Sliding the window by one angle updates both exactly:
//!
//! ```text
//!   Σx·y ← Σx·y − (Σy − y_oldest) + (n − 1)·y_new,      Σy ← Σy − y_oldest + y_new
//! ```
//!
//! Σx and Σx² depend on n alone, so the least-squares slope (n·Σx·y − Σx·Σy) / (n·Σx² − (Σx)²)
//! has an exact integer numerator and a constant denominator: no drift however long the window
//! slides, a handful of integer operations and one conversion to `f32` a tick. Rounding an angle
//! to the unit moves it by at most 1e-5°, three orders of magnitude below an encoder count, so
//! the fit agrees with a floating-point one to within rounding (the tests compare them). The
//! units cover ±128 turns of the hub; beyond that the conversion saturates.

use core::num::NonZeroU32;

/// Regression window, control ticks (20 ms at 1 kHz).
pub const JAM_WINDOW_TICKS: usize = 20;
/// Hold window, control ticks (80 ms at 1 kHz, inside the 50–100 ms hold of the rule above).
pub const HOLD_TICKS: usize = 80;

/// The regression's angle unit, degrees: 2⁻²⁴ of a turn.
pub const SLOPE_UNIT_DEG: f32 = 360.0 / (1u32 << 24) as f32;
/// [`SLOPE_UNIT_DEG`]s per degree.
const SLOPE_UNITS_PER_DEG: f32 = (1u32 << 24) as f32 / 360.0;

/// An angle in [`SLOPE_UNIT_DEG`]s, rounded to the nearest (saturating past ±128 turns).
fn to_units(angle_deg: f32) -> i32 {
    let units = angle_deg * SLOPE_UNITS_PER_DEG;
    // `as` truncates towards zero (and saturates): add half a unit away from zero to round.
    (units + if units >= 0.0 { 0.5 } else { -0.5 }) as i32
}

/// n·Σx² − (Σx)² for x = 0..n: n²·(n² − 1) / 12.
const fn slope_denominator(n: u32) -> u32 {
    n * n * (n * n - 1) / 12
}

/// The denominator of a full window.
const FULL_DENOMINATOR: u32 = slope_denominator(JAM_WINDOW_TICKS as u32);

/// The last angles, with a least-squares slope kept up to date in O(1) per angle.
pub struct SlopeWindow {
    /// Angles in [`SLOPE_UNIT_DEG`]s, a ring: `next` is the oldest once the window is full.
    units: [i32; JAM_WINDOW_TICKS],
    next: usize,
    len: usize,
    /// Σy over the window.
    sum_y: i64,
    /// Σx·y over the window, x = 0 for the oldest angle.
    sum_xy: i64,
}

impl Default for SlopeWindow {
    fn default() -> Self {
        Self::new()
    }
}

impl SlopeWindow {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            units: [0; JAM_WINDOW_TICKS],
            next: 0,
            len: 0,
            sum_y: 0,
            sum_xy: 0,
        }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// Add this tick's angle (the oldest leaves once the window is full).
    pub fn push(&mut self, angle_deg: f32) {
        let y = i64::from(to_units(angle_deg));
        if self.len < JAM_WINDOW_TICKS {
            self.sum_xy += self.len as i64 * y;
            self.sum_y += y;
            self.len += 1;
        } else {
            let oldest = i64::from(self.units[self.next]);
            // Every remaining angle's x drops by one, the new one comes in at x = n − 1.
            self.sum_xy += (JAM_WINDOW_TICKS as i64 - 1) * y - (self.sum_y - oldest);
            self.sum_y += y - oldest;
        }
        self.units[self.next] = y as i32;
        self.next = (self.next + 1) % JAM_WINDOW_TICKS;
    }

    /// True once the window is full.
    pub fn is_full(&self) -> bool {
        self.len == JAM_WINDOW_TICKS
    }

    /// Least-squares slope, degrees per tick (0 with fewer than two samples).
    pub fn slope_deg_per_tick(&self) -> f32 {
        let n = self.len as u32;
        let Some(denominator) = NonZeroU32::new(if self.is_full() {
            FULL_DENOMINATOR
        } else if n >= 2 {
            slope_denominator(n)
        } else {
            0
        }) else {
            return 0.0;
        };
        let sum_x = i64::from(n * (n - 1) / 2);
        let numerator = i64::from(n) * self.sum_xy - sum_x * self.sum_y;
        numerator as f32 * (SLOPE_UNIT_DEG / denominator.get() as f32)
    }

    /// The fitted angle change across the whole window, degrees.
    pub fn change_over_window_deg(&self) -> f32 {
        self.slope_deg_per_tick() * (JAM_WINDOW_TICKS - 1) as f32
    }
}

/// Angles collected while a jam is held.
pub struct HoldWindow {
    angles: [f32; HOLD_TICKS],
    len: usize,
    /// Σ(angle − first angle) over the first and the second half of the window, degrees: the
    /// drift between the halves' means ([`HoldWindow::drift_deg`]) with one addition a tick,
    /// taken from the first angle so that the sums stay small and keep f32's precision.
    half_sums_deg: [f32; 2],
}

impl Default for HoldWindow {
    fn default() -> Self {
        Self::new()
    }
}

impl HoldWindow {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            angles: [0.0; HOLD_TICKS],
            len: 0,
            half_sums_deg: [0.0; 2],
        }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.len = 0;
        self.half_sums_deg = [0.0; 2];
    }

    /// Add an angle; ignored once full.
    pub fn push(&mut self, angle_deg: f32) {
        if self.len < HOLD_TICKS {
            self.angles[self.len] = angle_deg;
            self.half_sums_deg[usize::from(self.len >= HOLD_TICKS / 2)] +=
                angle_deg - self.angles[0];
            self.len += 1;
        }
    }

    /// How far the hold's angle moved between its halves, degrees: the mean of the second half
    /// of a full window minus the mean of the first (0 until the window is full). White noise of
    /// SD σ gives this an SD of σ·√(4 / [`HOLD_TICKS`]) (0.22σ over 80 ticks), so unlike the
    /// spread, which grows with the noise and the window's length, it shows a jam that still
    /// moves (a creeping contact) and hardly the encoder's noise.
    pub fn drift_deg(&self) -> f32 {
        if !self.is_full() {
            return 0.0;
        }
        let [first, second] = self.half_sums_deg;
        (second - first) * (2.0 / HOLD_TICKS as f32)
    }

    /// True once [`HOLD_TICKS`] angles are in.
    pub fn is_full(&self) -> bool {
        self.len == HOLD_TICKS
    }

    /// Angles collected.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is collected.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Median and spread (max − min) of the collected angles; `None` when empty. In O(n): a
    /// selection of the middle angle (no full sort), then one pass over each half.
    pub fn median_and_spread(&self) -> Option<(f32, f32)> {
        let n = self.len;
        if n == 0 {
            return None;
        }
        let mut angles = self.angles;
        let (lower, middle, upper) = angles[..n].select_nth_unstable_by(n / 2, f32::total_cmp);
        let middle = *middle;
        // `total_cmp` is integer work on the bits: no soft-float comparison per angle.
        let min = lower.iter().copied().fold(middle, least);
        let max = upper.iter().copied().fold(middle, greatest);
        let median = if n % 2 == 1 {
            middle
        } else {
            // The lower middle is the largest of the lower half.
            let below = lower.iter().copied().fold(min, greatest);
            (below + middle) / 2.0
        };
        Some((median, max - min))
    }
}

/// The smaller of two angles by [`f32::total_cmp`].
fn least(a: f32, b: f32) -> f32 {
    if b.total_cmp(&a).is_lt() { b } else { a }
}

/// The larger of two angles by [`f32::total_cmp`].
fn greatest(a: f32, b: f32) -> f32 {
    if b.total_cmp(&a).is_gt() { b } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_ramp_is_exact() {
        let mut w = SlopeWindow::new();
        for i in 0..50 {
            w.push(100.0 + 0.25 * i as f32);
        }
        assert!((w.slope_deg_per_tick() - 0.25).abs() < 1e-4);
        assert!((w.change_over_window_deg() - 0.25 * 19.0).abs() < 1e-3);
    }

    #[test]
    fn a_still_noisy_angle_has_a_small_change_over_the_window() {
        let mut w = SlopeWindow::new();
        let lsb = 360.0 / 16384.0;
        for i in 0..20 {
            // ±1 LSB alternating noise around a constant.
            w.push(72.0 + if i % 2 == 0 { lsb } else { -lsb });
        }
        assert!(w.change_over_window_deg().abs() < 3.0 * lsb);
    }

    /// One encoder count on the output shaft, degrees.
    const LSB_DEG: f32 = 360.0 / 16384.0;

    /// The fit as it was before the running sums: f32, over the window, angles relative to the
    /// oldest. The reference the integer fit must agree with.
    fn reference_slope(angles: &[f32]) -> f32 {
        let n = angles.len();
        if n < 2 {
            return 0.0;
        }
        let origin = angles[0];
        let x_mean = (n - 1) as f32 / 2.0;
        let y_mean = angles.iter().map(|a| a - origin).sum::<f32>() / n as f32;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (i, a) in angles.iter().enumerate() {
            let dx = i as f32 - x_mean;
            sxy += dx * (a - origin - y_mean);
            sxx += dx * dx;
        }
        sxy / sxx
    }

    /// A small deterministic generator (xorshift32) for the synthetic sequences.
    struct Noise(u32);

    impl Noise {
        fn next(&mut self) -> u32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 17;
            self.0 ^= self.0 << 5;
            self.0
        }
        /// A whole number of counts in −`k`..=`k`.
        fn counts(&mut self, k: i32) -> i32 {
            (self.next() % (2 * k as u32 + 1)) as i32 - k
        }
    }

    /// Encoder readings of a hub turning at `speed_deg_per_tick` from `start_deg`, with up to
    /// `noise` counts of noise, on the count grid as the driver reports them.
    fn encoder_sequence(
        start_deg: f32,
        speed_deg_per_tick: f32,
        noise: i32,
        seed: u32,
    ) -> Vec<f32> {
        let mut rng = Noise(seed);
        (0..400)
            .map(|tick| {
                let hub_deg = start_deg + speed_deg_per_tick * tick as f32;
                let counts = (hub_deg / LSB_DEG).round() as i32 + rng.counts(noise);
                counts as f32 * LSB_DEG
            })
            .collect()
    }

    /// The still test of the controller: the fitted change within 4 counts.
    fn still(change_deg: f32) -> bool {
        change_deg.abs() <= 4.0 * LSB_DEG
    }

    /// Pushes `angles` one by one and checks every tick's slope and stillness decision against
    /// the floating-point fit over the same window; the number of decisions compared.
    fn compare_with_reference(angles: &[f32]) -> usize {
        let mut w = SlopeWindow::new();
        let mut decisions = 0;
        for (i, &a) in angles.iter().enumerate() {
            w.push(a);
            let window = &angles[(i + 1).saturating_sub(JAM_WINDOW_TICKS)..=i];
            let reference = reference_slope(window);
            let slope = w.slope_deg_per_tick();
            // Rounding to the unit moves an angle by 1e-5° at most; f32 sums lose about as much.
            assert!(
                (slope - reference).abs() <= 2e-6 + 1e-5 * reference.abs(),
                "tick {i}: {slope} vs {reference} deg/tick"
            );
            let change = reference * (JAM_WINDOW_TICKS - 1) as f32;
            // A decision only differs when the reference sits on the band's edge, to rounding.
            if (change.abs() - 4.0 * LSB_DEG).abs() > 1e-4 {
                assert_eq!(still(w.change_over_window_deg()), still(change), "tick {i}");
                decisions += 1;
            }
        }
        decisions
    }

    #[test]
    fn the_running_fit_agrees_with_the_floating_point_fit() {
        let mut decisions = 0;
        for (seed, start_deg) in [(1u32, 0.0f32), (2, 5.1), (3, 44.9), (4, 130.0), (5, -170.0)] {
            // Still, creeping (at the band's edge), ramping, at the speed limit and backwards.
            for speed in [0.0, 0.001, 0.0046, 0.01, 0.05, 0.09, -0.06] {
                for noise in [0, 1, 2] {
                    let angles = encoder_sequence(start_deg, speed, noise, seed);
                    decisions += compare_with_reference(&angles);
                }
            }
        }
        assert!(decisions > 40_000, "{decisions}");
    }

    #[test]
    fn the_running_sums_do_not_drift() {
        // A long random walk, then the window's slope against a fresh window of the same angles.
        let mut rng = Noise(7);
        let mut w = SlopeWindow::new();
        let mut counts = 0i32;
        let mut last = [0.0f32; JAM_WINDOW_TICKS];
        for i in 0..200_000 {
            counts += rng.counts(3);
            let a = counts as f32 * LSB_DEG;
            w.push(a);
            last[i % JAM_WINDOW_TICKS] = a;
        }
        let mut fresh = SlopeWindow::new();
        for i in 0..JAM_WINDOW_TICKS {
            fresh.push(last[(200_000 + i) % JAM_WINDOW_TICKS]);
        }
        assert_eq!(w.slope_deg_per_tick(), fresh.slope_deg_per_tick());
        assert_ne!(w.slope_deg_per_tick(), 0.0);
    }

    #[test]
    fn a_filling_window_fits_what_it_has_and_clear_forgets() {
        let mut w = SlopeWindow::new();
        assert_eq!(w.slope_deg_per_tick(), 0.0);
        w.push(10.0);
        assert_eq!(w.slope_deg_per_tick(), 0.0);
        w.push(10.5);
        assert!((w.slope_deg_per_tick() - 0.5).abs() < 5e-5);
        assert!(!w.is_full());
        w.clear();
        w.push(3.0);
        assert_eq!(w.slope_deg_per_tick(), 0.0);
    }

    #[test]
    fn the_median_and_spread_match_a_full_sort() {
        let mut rng = Noise(11);
        for n in 1..=HOLD_TICKS {
            let mut h = HoldWindow::new();
            let mut angles = Vec::new();
            for _ in 0..n {
                let a = 45.0 + rng.counts(6) as f32 * LSB_DEG;
                h.push(a);
                angles.push(a);
            }
            angles.sort_by(f32::total_cmp);
            let median = if n % 2 == 1 {
                angles[n / 2]
            } else {
                (angles[n / 2 - 1] + angles[n / 2]) / 2.0
            };
            let spread = angles[n - 1] - angles[0];
            assert_eq!(h.median_and_spread(), Some((median, spread)), "n = {n}");
        }
        assert_eq!(HoldWindow::new().median_and_spread(), None);
    }

    #[test]
    fn median_ignores_a_stray_sample() {
        let mut h = HoldWindow::new();
        for _ in 0..79 {
            h.push(50.0);
        }
        h.push(90.0);
        let (m, spread) = h.median_and_spread().unwrap();
        assert_eq!(m, 50.0);
        assert_eq!(spread, 40.0);
        assert!(h.is_full());
    }

    #[test]
    fn the_drift_shows_a_creeping_hold_and_hardly_the_noise() {
        // A still jam under noise of ±6 counts: the spread is large, the drift is not.
        let mut rng = Noise(5);
        let mut h = HoldWindow::new();
        assert_eq!(h.drift_deg(), 0.0);
        for _ in 0..HOLD_TICKS {
            h.push(60.0 + rng.counts(6) as f32 * LSB_DEG);
        }
        let (_, spread) = h.median_and_spread().unwrap();
        assert!(spread >= 6.0 * LSB_DEG, "{spread}");
        assert!(h.drift_deg().abs() < 3.0 * LSB_DEG, "{}", h.drift_deg());
        // A jam creeping 0.01° a tick: the halves' means lie 40 ticks, 0.4°, apart.
        h.clear();
        for i in 0..HOLD_TICKS {
            h.push(60.0 + 0.01 * i as f32);
        }
        assert!((h.drift_deg() - 0.4).abs() < 1e-4, "{}", h.drift_deg());
        h.clear();
        assert_eq!(h.drift_deg(), 0.0, "cleared");
    }
}
