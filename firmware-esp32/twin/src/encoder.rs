//! The AS5048A's angle errors as a real build shows them, added to the magnet's angle before the
//! fake chip quantises it and adds its noise: the chip's integral non-linearity and the magnet's
//! eccentricity. Drawn once per twin (one chip, one magnet) from the seed.
//!
//! - **Integral non-linearity**: the 1st, 2nd and 3rd harmonics of the angle over a turn, with
//!   relative weights (0.5–1) and phases drawn per twin, scaled so that the curve's INL — half
//!   its peak-to-peak over the turn, the datasheet's definition — is `encoder_inl_deg` (AS5048A
//!   datasheet: ±0.05° for a centred magnet after linearisation).
//! - **Magnet eccentricity**: a magnet `magnet_offset_mm` off the sensor's axis gives a
//!   once-per-turn error of [`ECCENTRICITY_DEG_PER_MM`] per mm, at a phase drawn per twin. No
//!   AS5048A curve of error against displacement was at hand; ams's sister parts give the
//!   order: the AS5050's worst-case error rises from about 0.5° with a centred magnet to about
//!   1.0° within 0.5 mm of displacement, and the AS5046 stays within ±1° over about 0.7 mm, i.e.
//!   1–1.5° per mm of offset. This model takes the lower end, as a pure first harmonic.
//!
//! The user sets the device's zero (`encoder_zero_raw`) with the hub at its zero position, so
//! the stored zero absorbs the error there: the chip is handed θ + e(θ) − e(0), and what the
//! errors do to a reading is e(θ) − e(0), growing with the angle a run turns. Not cancelled
//! anywhere else.

use kerfmeter_firmware::fakes::rng::Rng;

use crate::plant::PlantParams;

/// Mixed into the seed of the stream that draws the encoder's error curve, so that it depends on
/// the seed alone.
pub const ENCODER_STREAM: u64 = 0x656e_636f_6465_7200;

/// Once-per-turn angle error per mm of magnet offset, degrees (see the module docs).
pub const ECCENTRICITY_DEG_PER_MM: f64 = 1.0;

/// Harmonics of the integral non-linearity: 1st to 3rd over the turn.
const HARMONICS: usize = 3;
/// Points over the turn at which the INL is scaled to its amplitude.
const INL_GRID: usize = 3600;

/// One chip's and magnet's angle errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderErrors {
    /// Amplitude of each INL harmonic, degrees.
    inl_amplitude_deg: [f64; HARMONICS],
    /// Phase of each INL harmonic, rad.
    inl_phase_rad: [f64; HARMONICS],
    /// Amplitude of the eccentricity's once-per-turn error, degrees.
    eccentricity_deg: f64,
    /// Its phase, rad.
    eccentricity_phase_rad: f64,
}

impl EncoderErrors {
    /// No errors: an ideal chip and magnet.
    pub const NONE: Self = Self {
        inl_amplitude_deg: [0.0; HARMONICS],
        inl_phase_rad: [0.0; HARMONICS],
        eccentricity_deg: 0.0,
        eccentricity_phase_rad: 0.0,
    };

    /// Draw one chip's and magnet's errors for `params` from `rng`.
    pub fn draw(params: &PlantParams, rng: &mut Rng) -> Self {
        let tau = core::f64::consts::TAU;
        let mut errors = Self::NONE;
        for h in 0..HARMONICS {
            errors.inl_amplitude_deg[h] = 0.5 + 0.5 * rng.uniform();
            errors.inl_phase_rad[h] = tau * rng.uniform();
        }
        errors.eccentricity_phase_rad = tau * rng.uniform();
        let drawn_inl = errors.inl_amplitude();
        let scale = if drawn_inl > 0.0 {
            params.encoder_inl_deg / drawn_inl
        } else {
            0.0
        };
        for amplitude in &mut errors.inl_amplitude_deg {
            *amplitude *= scale;
        }
        errors.eccentricity_deg = params.magnet_offset_mm * ECCENTRICITY_DEG_PER_MM;
        errors
    }

    /// The errors of the twin seeded with `seed` (see [`ENCODER_STREAM`]).
    pub fn for_twin(params: &PlantParams, seed: u64) -> Self {
        Self::draw(params, &mut Rng::new(seed ^ ENCODER_STREAM))
    }

    /// The integral non-linearity at magnet angle `angle_deg`, degrees.
    pub fn inl_deg(&self, angle_deg: f64) -> f64 {
        let angle = angle_deg.to_radians();
        (0..HARMONICS)
            .map(|h| {
                let order = (h + 1) as f64;
                self.inl_amplitude_deg[h] * (order * angle + self.inl_phase_rad[h]).sin()
            })
            .sum()
    }

    /// The magnet eccentricity's error at magnet angle `angle_deg`, degrees.
    pub fn eccentricity_error_deg(&self, angle_deg: f64) -> f64 {
        self.eccentricity_deg * (angle_deg.to_radians() + self.eccentricity_phase_rad).sin()
    }

    /// The whole error at magnet angle `angle_deg`, degrees.
    pub fn error_deg(&self, angle_deg: f64) -> f64 {
        self.inl_deg(angle_deg) + self.eccentricity_error_deg(angle_deg)
    }

    /// The angle the chip measures at magnet angle `angle_deg`, degrees, with the device's zero
    /// set at 0 (which absorbs the error there).
    pub fn measured_deg(&self, angle_deg: f64) -> f64 {
        angle_deg + self.error_deg(angle_deg) - self.error_deg(0.0)
    }

    /// The INL of the curve: half its peak-to-peak over a turn, degrees.
    pub fn inl_amplitude(&self) -> f64 {
        let (lo, hi) = (0..INL_GRID)
            .map(|i| self.inl_deg(360.0 * i as f64 / INL_GRID as f64))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| {
                (lo.min(e), hi.max(e))
            });
        (hi - lo) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inl_has_the_configured_amplitude_and_harmonics() {
        let params = PlantParams::default();
        for seed in 0..20 {
            let e = EncoderErrors::for_twin(&params, seed);
            // Sampled on another grid than the one it was scaled on.
            let samples: Vec<f64> = (0..7919)
                .map(|i| e.inl_deg(i as f64 * 360.0 / 7919.0))
                .collect();
            let hi = samples.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let lo = samples.iter().cloned().fold(f64::INFINITY, f64::min);
            assert!(
                ((hi - lo) / 2.0 - params.encoder_inl_deg).abs() < 1e-4,
                "seed {seed}: ±{}",
                (hi - lo) / 2.0
            );
            // Periodic over the turn, with every harmonic in it.
            assert!((e.inl_deg(10.0) - e.inl_deg(370.0)).abs() < 1e-12);
            assert!(e.inl_amplitude_deg.iter().all(|a| *a > 0.0));
        }
        let twice = PlantParams {
            encoder_inl_deg: 0.1,
            ..params
        };
        assert!((EncoderErrors::for_twin(&twice, 3).inl_amplitude() - 0.1).abs() < 1e-9);
    }

    #[test]
    fn eccentricity_is_a_once_per_turn_error_of_its_documented_size() {
        let params = PlantParams {
            encoder_inl_deg: 0.0,
            magnet_offset_mm: 0.2,
            ..PlantParams::default()
        };
        let e = EncoderErrors::for_twin(&params, 9);
        let peak = (0..3600)
            .map(|i| e.error_deg(f64::from(i) / 10.0).abs())
            .fold(0.0, f64::max);
        assert!(
            (peak - 0.2 * ECCENTRICITY_DEG_PER_MM).abs() < 1e-4,
            "{peak}"
        );
        // Once per turn: half a turn on, the error is reversed.
        assert!((e.error_deg(40.0) + e.error_deg(220.0)).abs() < 1e-12);
    }

    #[test]
    fn the_zero_absorbs_the_error_there_and_the_rest_shows() {
        let e = EncoderErrors::for_twin(&PlantParams::default(), 4);
        assert_eq!(e.measured_deg(0.0), 0.0);
        let at_60 = e.measured_deg(60.0) - 60.0;
        assert!((at_60 - (e.error_deg(60.0) - e.error_deg(0.0))).abs() < 1e-12);
        let largest = (0..360)
            .map(|d| (e.measured_deg(f64::from(d)) - f64::from(d)).abs())
            .fold(0.0, f64::max);
        assert!(largest > 0.05, "the errors reach a reading: {largest}");
        assert_eq!(EncoderErrors::NONE.measured_deg(33.3), 33.3);
    }

    #[test]
    fn each_twin_draws_its_own_errors_and_keeps_them() {
        let params = PlantParams::default();
        let a = EncoderErrors::for_twin(&params, 1);
        assert_eq!(a, EncoderErrors::for_twin(&params, 1));
        assert_ne!(a, EncoderErrors::for_twin(&params, 2));
    }
}
