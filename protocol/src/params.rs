//! What the host asks for: the gauge geometry and run parameters sent with every run, and the
//! device's stored configuration.
//!
//! The gauge geometry travels with every [`RunParams`] so that the device and the gauge generator
//! can never disagree on the spiral's pitch, the prong holes or the sense in which the gap closes.
//! Ranges are checked in one place, [`RunParams::validate`], which both the host (before sending)
//! and the device (on receipt) call.

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::messages::ParamField;

/// The sense in which the hub turns the inset to close the spiral's gap, seen from above (from the
/// laser head looking down at the gauge, i.e. looking at the top face of the cut sheet).
///
/// The gauge generator draws the spiral so that turning the inset this way moves it towards
/// decreasing spiral angle φ, which narrows the gap everywhere at once.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum JamDirection {
    /// Clockwise seen from above.
    #[default]
    Clockwise,
    /// Counter-clockwise seen from above.
    CounterClockwise,
}

/// Geometry of the laser-cut spiral gauge (the paper's defaults in [`GaugeGeometry::PAPER`]).
///
/// The cut line is r(φ) = a + c·φ for one turn (φ in radians), closed by a radial step of height
/// 2π·c, with `a = radius_mm − π·c` so that `radius_mm` is the spiral's mean radius. Two prong
/// holes sit diametrically opposite at `hole_distance_mm` from the centre. What the device and the
/// host compute from it (hole play, kerf, torque, the pitch in mm per radian) is in
/// [`crate::spiral`].
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GaugeGeometry {
    /// Spiral pitch c, in µm of radius per degree of turn (paper: 2.774 = 430 µm / 155°).
    pub pitch_um_per_deg: f32,
    /// Mean radius r of the spiral cut, mm (paper: ≈ 10, a 2 cm gauge).
    pub radius_mm: f32,
    /// Radius of each prong r_p, mm.
    pub prong_radius_mm: f32,
    /// Nominal (as drawn) radius of each prong hole r_h, mm. The laser adds k/2.
    pub hole_radius_mm: f32,
    /// Distance R of each hole's centre from the gauge centre, mm.
    pub hole_distance_mm: f32,
    /// Sense of rotation that closes the gap.
    pub jam_direction: JamDirection,
    /// Inset rotation past which the spiral disengages; reaching it is a fault, not a reading.
    pub disengage_deg: f32,
}

impl GaugeGeometry {
    /// The paper's gauge. c = 2.774 µm/deg; R = 5.3 mm and a radial clearance r_h − r_p = 0.42 mm
    /// reproduce the paper's 14 µm / 17 µm uncorrected hole-play error at 100 µm / 300 µm kerf.
    pub const PAPER: Self = Self {
        pitch_um_per_deg: 2.774,
        radius_mm: 10.0,
        prong_radius_mm: 2.0,
        hole_radius_mm: 2.42,
        hole_distance_mm: 5.3,
        jam_direction: JamDirection::Clockwise,
        disengage_deg: 155.0,
    };

    /// Largest kerf this gauge can measure, µm: the gap closes at `disengage_deg`.
    pub fn max_kerf_um(&self) -> f32 {
        self.pitch_um_per_deg * self.disengage_deg
    }
}

impl Default for GaugeGeometry {
    fn default() -> Self {
        Self::PAPER
    }
}

/// Parameters of one measurement, sent with [`crate::Request::Run`].
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RunParams {
    /// The gauge that was cut for this run.
    pub gauge: GaugeGeometry,
    /// Sheet thickness L, mm.
    pub thickness_mm: f32,
    /// Assembly force F of the joint the kerf is measured for, N (paper's default: 55 N).
    pub target_force_n: f32,
    /// Total finger contact area A_j of that joint, mm².
    pub contact_area_mm2: f32,
    /// Never command more output torque than this, N·m.
    pub max_torque_nm: f32,
    /// Torque ramp rate while ramping, N·m per second.
    pub ramp_rate_nm_per_s: f32,
    /// The run faults if it has not finished after this long, ms.
    pub max_time_ms: u32,
    /// Communication watchdog during the run: the device stops the motor and faults when the host
    /// has sent nothing for this long, ms.
    pub host_timeout_ms: u32,
}

impl RunParams {
    /// The paper's defaults: its gauge, 4 mm stock, 55 N over three 6.3 mm fingers.
    pub const DEFAULT: Self = Self {
        gauge: GaugeGeometry::PAPER,
        thickness_mm: 4.0,
        target_force_n: 55.0,
        contact_area_mm2: 151.2,
        max_torque_nm: 0.8,
        ramp_rate_nm_per_s: 1.0,
        max_time_ms: 10_000,
        host_timeout_ms: 1_000,
    };

    /// The value of `field` in these parameters (`None` for a configuration field).
    pub fn value_of(&self, field: ParamField) -> Option<f32> {
        let g = &self.gauge;
        Some(match field {
            ParamField::PitchUmPerDeg => g.pitch_um_per_deg,
            ParamField::RadiusMm => g.radius_mm,
            ParamField::ProngRadiusMm => g.prong_radius_mm,
            ParamField::HoleRadiusMm => g.hole_radius_mm,
            ParamField::HoleDistanceMm => g.hole_distance_mm,
            ParamField::DisengageDeg => g.disengage_deg,
            ParamField::ThicknessMm => self.thickness_mm,
            ParamField::TargetForceN => self.target_force_n,
            ParamField::ContactAreaMm2 => self.contact_area_mm2,
            ParamField::MaxTorqueNm => self.max_torque_nm,
            ParamField::RampRateNmPerS => self.ramp_rate_nm_per_s,
            ParamField::MaxTimeMs => self.max_time_ms as f32,
            ParamField::HostTimeoutMs => self.host_timeout_ms as f32,
            _ => return None,
        })
    }

    /// Why `field` (as [`validate`](Self::validate) returned it) is refused, as a message: out
    /// of its range, or within it but against the rule that ties it to another field (a hole
    /// smaller than its prong, holes outside the spiral).
    pub fn why_invalid(&self, field: ParamField) -> WhyInvalid<'_> {
        WhyInvalid {
            params: self,
            field,
        }
    }

    /// Check every field against its physically sensible range.
    ///
    /// Returns the first offending field. Ranges are deliberately generous (they reject nonsense and
    /// NaN, not unusual setups); the host turns the field into a message that names the range.
    pub fn validate(&self) -> Result<(), ParamField> {
        let g = &self.gauge;
        check(g.pitch_um_per_deg, ParamField::PitchUmPerDeg)?;
        check(g.radius_mm, ParamField::RadiusMm)?;
        check(g.prong_radius_mm, ParamField::ProngRadiusMm)?;
        check(g.hole_radius_mm, ParamField::HoleRadiusMm)?;
        if g.hole_radius_mm < g.prong_radius_mm {
            return Err(ParamField::HoleRadiusMm);
        }
        check(g.hole_distance_mm, ParamField::HoleDistanceMm)?;
        // The prong hole must lie inside the spiral, and the play formula
        // (`spiral::play_deg`) needs (r_h − r_p + k/2) < 2R.
        if g.hole_distance_mm + g.hole_radius_mm >= g.radius_mm
            || g.hole_radius_mm - g.prong_radius_mm >= g.hole_distance_mm
        {
            return Err(ParamField::HoleDistanceMm);
        }
        check(g.disengage_deg, ParamField::DisengageDeg)?;
        check(self.thickness_mm, ParamField::ThicknessMm)?;
        check(self.target_force_n, ParamField::TargetForceN)?;
        check(self.contact_area_mm2, ParamField::ContactAreaMm2)?;
        check(self.max_torque_nm, ParamField::MaxTorqueNm)?;
        check(self.ramp_rate_nm_per_s, ParamField::RampRateNmPerS)?;
        check(self.max_time_ms as f32, ParamField::MaxTimeMs)?;
        check(self.host_timeout_ms as f32, ParamField::HostTimeoutMs)?;
        Ok(())
    }
}

/// Why a field of [`RunParams`] is refused ([`RunParams::why_invalid`]); `Display` says it.
#[derive(Debug, Clone, Copy)]
pub struct WhyInvalid<'a> {
    params: &'a RunParams,
    field: ParamField,
}

impl core::fmt::Display for WhyInvalid<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let value = self.params.value_of(self.field);
        let g = &self.params.gauge;
        match self.field {
            _ if value.is_none_or(|v| check(v, self.field).is_err()) => {
                write!(f, "{}", self.field.out_of_range(value))
            }
            ParamField::HoleRadiusMm => write!(
                f,
                "the gauge's prong-hole radius (hole_radius_mm = {} mm) is smaller than the prong \
                 radius (prong_radius_mm = {} mm): the prong would not enter its hole",
                g.hole_radius_mm, g.prong_radius_mm
            ),
            ParamField::HoleDistanceMm => write!(
                f,
                "the prong holes (hole_distance_mm = {} mm from the centre, hole_radius_mm = {} mm) \
                 must lie inside the spiral (radius_mm = {} mm) and farther from the centre than \
                 a hole's play (hole − prong radius)",
                g.hole_distance_mm, g.hole_radius_mm, g.radius_mm
            ),
            _ => write!(f, "{}", self.field.out_of_range(value)),
        }
    }
}

impl Default for RunParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

fn check(value: f32, field: ParamField) -> Result<(), ParamField> {
    let (lo, hi) = field.range();
    // `contains` is false for NaN, which is what we want.
    if (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(field)
    }
}

/// Where the AS5048A's magnet sits.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncoderPlacement {
    /// On the gearbox output shaft (the hub): one encoder turn is one hub turn.
    #[default]
    OutputShaft,
    /// On the motor shaft: one hub turn is `gear_ratio` encoder turns.
    MotorShaft,
}

/// The motor supply at which [`DeviceConfig::torque_per_duty_nm`] and
/// [`DeviceConfig::breakaway_duty`] are given, V: the reference build's 12 V. Where the device
/// measures its supply it scales the duty by `REFERENCE_SUPPLY_V / supply` so that a torque is
/// the same from [`SUPPLY_MIN_V`] to [`SUPPLY_MAX_V`]; where it does not, it assumes this supply.
pub const REFERENCE_SUPPLY_V: f32 = 12.0;
/// The lowest motor supply the device is rated for, V: below it the device reports
/// `Conditions::SUPPLY_OUT_OF_RANGE` and refuses to drive the motor.
pub const SUPPLY_MIN_V: f32 = 9.0;
/// The highest motor supply the device is rated for with any driver, V: above it (or above its
/// driver's own safe maximum, [`G2Variant::supply_max_v`], whichever is lower) the device
/// reports `Conditions::SUPPLY_OUT_OF_RANGE` and refuses to drive the motor. The supply sense
/// reads 30 V as 2.27 V at its pin, inside the ADC's 11 dB range with room for the tolerance.
pub const SUPPLY_MAX_V: f32 = 26.0;

/// The Pololu G2 High-Power Motor Driver the device is built with (protocol 2.6, reported in
/// `Diagnostics`): its current-sense gain and the supply it is safe on. The figures are
/// Pololu's:
///
/// - **18v17** (Pololu item #2991, the reference build's): 6.5–30 V absolute maximum, "a safe
///   maximum voltage is approximately 24 V" for the ripple on the supply line (its product
///   page, Overview); current sense about 20 mV/A plus about 50 mV of offset (Pololu's G2
///   documentation, as the firmware used it before this table; the 20 mV/A and 50 mV for the
///   G2 family's "other versions" are also in Pololu's Dual G2 user's guide, §4.b).
/// - **24v13** (#2992): 6.5–40 V absolute maximum, safe maximum approximately 34 V; current
///   sense "approx. 40 mV/A; only active while H-bridge is driving", 0.04 V/A in its
///   specifications (its product page).
/// - **24v21** (#2995): 40 V absolute maximum and a safe maximum of approximately 34 V as the
///   24v13 (the same 40 V MOSFET class: an assumption from the 24v13's page, the 24v21's own
///   page was not at hand); current sense about 20 mV/A with a 50–60 mV offset, as a Pololu
///   engineer confirmed on a 24v21 in Pololu's forum ("G2 24v21 cs offset"). Check it on the
///   bench (bring-up step 6's torque constant) before trusting it.
/// - The **18v25** is not listed: its current-sense gain was not found in Pololu's
///   documentation at hand, and the firmware will not guess a gain that scales every current
///   and the over-current trip.
///
/// The device's own range, [`SUPPLY_MIN_V`]–[`SUPPLY_MAX_V`], bounds every variant's: a 24 V
/// driver is accepted up to 26 V, not 34 V.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum G2Variant {
    /// G2 18v17: 20 mV/A, safe up to about 24 V (the reference build).
    #[default]
    V18v17,
    /// G2 24v13: 40 mV/A, safe up to about 34 V.
    V24v13,
    /// G2 24v21: about 20 mV/A, safe up to about 34 V.
    V24v21,
}

impl G2Variant {
    /// Every variant, in wire order.
    pub const ALL: [Self; 3] = [Self::V18v17, Self::V24v13, Self::V24v21];

    /// The variant's name as Pololu writes it: `"18v17"`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::V18v17 => "18v17",
            Self::V24v13 => "24v13",
            Self::V24v21 => "24v21",
        }
    }

    /// The variant named `name` (`"18v17"`, `"24v13"`, `"24v21"`).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|v| v.name() == name)
    }

    /// The current-sense gain in the drive phase, mV per amp of motor current.
    pub const fn cs_mv_per_a(self) -> f32 {
        match self {
            Self::V18v17 | Self::V24v21 => 20.0,
            Self::V24v13 => 40.0,
        }
    }

    /// Pololu's safe maximum supply for the driver, V (its absolute maximum less the supply
    /// line's ripple).
    pub const fn safe_max_v(self) -> f32 {
        match self {
            Self::V18v17 => 24.0,
            Self::V24v13 | Self::V24v21 => 34.0,
        }
    }

    /// The highest supply the device accepts with this driver, V: its safe maximum, at most
    /// [`SUPPLY_MAX_V`].
    pub const fn supply_max_v(self) -> f32 {
        let safe = self.safe_max_v();
        if safe < SUPPLY_MAX_V {
            safe
        } else {
            SUPPLY_MAX_V
        }
    }
}

/// A name that is no [`G2Variant`]'s; `Display` lists the known ones.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownG2Variant;

impl core::fmt::Display for UnknownG2Variant {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("unknown Pololu G2 variant; known:")?;
        for v in G2Variant::ALL {
            write!(f, " {}", v.name())?;
        }
        Ok(())
    }
}

impl core::error::Error for UnknownG2Variant {}

impl core::str::FromStr for G2Variant {
    type Err = UnknownG2Variant;
    /// By Pololu's name: `"24v13".parse()`.
    fn from_str(name: &str) -> Result<Self, UnknownG2Variant> {
        Self::from_name(name).ok_or(UnknownG2Variant)
    }
}

/// Calibration and wiring constants of one device, stored in its flash.
///
/// The torque calibration (`torque_per_duty_nm`, `breakaway_duty`) is given at the reference
/// supply, [`REFERENCE_SUPPLY_V`] (12 V), whatever the supply the device runs on: the device
/// scales the duty by the supply it measures. Calibrate at 12 V, or convert: a figure measured
/// at V volts is `torque_per_duty_nm × 12 / V` and `breakaway_duty × V / 12`.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceConfig {
    /// Output torque at 100 % duty and standstill on a [`REFERENCE_SUPPLY_V`] (12 V) supply,
    /// N·m (reference motor: ≈ 0.88).
    pub torque_per_duty_nm: f32,
    /// Duty (0..1) below which the gearbox does not move at all (static friction), as a
    /// fraction, on a [`REFERENCE_SUPPLY_V`] (12 V) supply.
    pub breakaway_duty: f32,
    /// Raw encoder reading (0..16383) at the hub's zero position (prongs aligned with the gauge).
    pub encoder_zero_raw: u16,
    /// Where the encoder magnet sits.
    pub encoder_placement: EncoderPlacement,
    /// Gearbox reduction (motor turns per hub turn).
    pub gear_ratio: f32,
    /// Swap the motor's DIR sense (motor wired the other way round).
    pub motor_inverted: bool,
    /// Swap the encoder's counting sense (magnet or chip mounted the other way round).
    pub encoder_inverted: bool,
    /// Motor current that trips the over-current fault, A.
    pub max_current_a: f32,
    /// Output torque per amp of motor current, N·m/A (gear ratio × efficiency × motor kt); the
    /// self-test estimates the torque constant from it and the current at standstill.
    pub torque_per_amp_nm: f32,
}

impl DeviceConfig {
    /// The reference build: 12 V, 21:1 gearbox, encoder on the output shaft, 0.88 N·m and 5.6 A
    /// at full duty and standstill.
    pub const DEFAULT: Self = Self {
        torque_per_duty_nm: 0.88,
        breakaway_duty: 0.04,
        encoder_zero_raw: 0,
        encoder_placement: EncoderPlacement::OutputShaft,
        gear_ratio: 21.0,
        motor_inverted: false,
        encoder_inverted: false,
        max_current_a: 6.5,
        torque_per_amp_nm: 0.157,
    };

    /// Check every field against its range; returns the first offending field.
    pub fn validate(&self) -> Result<(), ParamField> {
        check(self.torque_per_duty_nm, ParamField::TorquePerDutyNm)?;
        check(self.breakaway_duty, ParamField::BreakawayDuty)?;
        check(f32::from(self.encoder_zero_raw), ParamField::EncoderZeroRaw)?;
        check(self.gear_ratio, ParamField::GearRatio)?;
        check(self.max_current_a, ParamField::MaxCurrentA)?;
        check(self.torque_per_amp_nm, ParamField::TorquePerAmpNm)?;
        Ok(())
    }
}

impl Default for DeviceConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_g2_variant_is_named_as_pololu_names_it_and_bounded_by_the_device() {
        for v in G2Variant::ALL {
            assert_eq!(v.name().parse(), Ok(v));
            assert!(v.supply_max_v() <= SUPPLY_MAX_V);
        }
        assert_eq!("18v25".parse::<G2Variant>(), Err(UnknownG2Variant));
        assert_eq!(G2Variant::V18v17.supply_max_v(), 24.0);
        assert_eq!(G2Variant::V24v13.supply_max_v(), SUPPLY_MAX_V);
        assert_eq!(G2Variant::V24v13.cs_mv_per_a(), 40.0);
        assert_eq!(G2Variant::default(), G2Variant::V18v17);
    }
}
