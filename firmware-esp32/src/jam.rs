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
//! angles while torque is held at a jam and gives their median (robust to a stray sample) and
//! spread (a noisy hold is flagged).

/// Regression window, control ticks (20 ms at 1 kHz).
pub const JAM_WINDOW_TICKS: usize = 20;
/// Hold window, control ticks (80 ms at 1 kHz, inside the 50–100 ms hold of the rule above).
pub const HOLD_TICKS: usize = 80;

/// The last angles, with a least-squares slope.
pub struct SlopeWindow {
    angles: [f32; JAM_WINDOW_TICKS],
    next: usize,
    len: usize,
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
            angles: [0.0; JAM_WINDOW_TICKS],
            next: 0,
            len: 0,
        }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    /// Add this tick's angle.
    pub fn push(&mut self, angle_deg: f32) {
        self.angles[self.next] = angle_deg;
        self.next = (self.next + 1) % JAM_WINDOW_TICKS;
        self.len = (self.len + 1).min(JAM_WINDOW_TICKS);
    }

    /// True once the window is full.
    pub fn is_full(&self) -> bool {
        self.len == JAM_WINDOW_TICKS
    }

    /// Least-squares slope, degrees per tick (0 with fewer than two samples).
    pub fn slope_deg_per_tick(&self) -> f32 {
        let n = self.len;
        if n < 2 {
            return 0.0;
        }
        // Oldest sample first; x = 0..n, centred. Subtract the first angle to keep f32 precise.
        let start = (self.next + JAM_WINDOW_TICKS - n) % JAM_WINDOW_TICKS;
        let origin = self.angles[start];
        let x_mean = (n - 1) as f32 / 2.0;
        let mut y_mean = 0.0;
        for i in 0..n {
            y_mean += self.angles[(start + i) % JAM_WINDOW_TICKS] - origin;
        }
        y_mean /= n as f32;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for i in 0..n {
            let dx = i as f32 - x_mean;
            let dy = self.angles[(start + i) % JAM_WINDOW_TICKS] - origin - y_mean;
            sxy += dx * dy;
            sxx += dx * dx;
        }
        sxy / sxx
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
        }
    }

    /// Forget everything.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Add an angle; ignored once full.
    pub fn push(&mut self, angle_deg: f32) {
        if self.len < HOLD_TICKS {
            self.angles[self.len] = angle_deg;
            self.len += 1;
        }
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

    /// Median and spread (max − min) of the collected angles; `None` when empty.
    pub fn median_and_spread(&self) -> Option<(f32, f32)> {
        if self.len == 0 {
            return None;
        }
        let mut sorted = self.angles;
        let s = &mut sorted[..self.len];
        s.sort_unstable_by(f32::total_cmp);
        let n = s.len();
        let median = if n % 2 == 1 {
            s[n / 2]
        } else {
            (s[n / 2 - 1] + s[n / 2]) / 2.0
        };
        Some((median, s[n - 1] - s[0]))
    }
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
}
