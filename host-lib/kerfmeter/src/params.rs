//! Run parameters from what a user knows: the sheet's thickness, the joint (how many fingers, how
//! long), the assembly force wanted, and the gauge that was cut.
//!
//! The force defaults to the centre of the paper's fit window: users assembled every three-finger
//! box joint needing at most 97.7 N and 8 N was the least that held, so 55 N for three fingers,
//! i.e. [`DEFAULT_FORCE_PER_FINGER_N`] per finger. The joint's contact area is
//! fingers × 2 faces × thickness × finger length (each finger presses on both of its sides).

use kerfmeter_protocol::advice::{Advice, Advised};
use kerfmeter_protocol::{GaugeGeometry, ParamField, RunParams};

use crate::error::{Error, Result};

/// The paper's fit-window centre, per finger: 55 N / 3.
pub const DEFAULT_FORCE_PER_FINGER_N: f64 = 55.0 / 3.0;
/// Default number of fingers of the joint.
pub const DEFAULT_FINGERS: u32 = 3;
/// Default finger length (depth of each finger's pressed face), mm: with 4 mm stock and three
/// fingers this gives the paper's ≈ 152 mm² contact area.
pub const DEFAULT_FINGER_LENGTH_MM: f64 = 6.3;
/// Default sheet thickness, mm.
pub const DEFAULT_THICKNESS_MM: f64 = 4.0;

/// The joint and material a measurement is for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointSpec {
    /// Sheet thickness, mm.
    pub thickness_mm: f64,
    /// Fingers in the joint.
    pub fingers: u32,
    /// Length of each finger's pressed face, mm.
    pub finger_length_mm: f64,
    /// Assembly force; `None` for the default (18.3 N per finger).
    pub force_n: Option<f64>,
}

impl Default for JointSpec {
    fn default() -> Self {
        Self {
            thickness_mm: DEFAULT_THICKNESS_MM,
            fingers: DEFAULT_FINGERS,
            finger_length_mm: DEFAULT_FINGER_LENGTH_MM,
            force_n: None,
        }
    }
}

impl JointSpec {
    /// The assembly force, N.
    pub fn force_n(&self) -> f64 {
        self.force_n
            .unwrap_or(DEFAULT_FORCE_PER_FINGER_N * f64::from(self.fingers))
    }

    /// Total pressed contact area, mm².
    pub fn contact_area_mm2(&self) -> f64 {
        f64::from(self.fingers) * 2.0 * self.thickness_mm * self.finger_length_mm
    }

    /// The device's run parameters for this joint on `gauge`, checked.
    pub fn run_params(&self, gauge: GaugeGeometry) -> Result<RunParams> {
        if self.fingers == 0 || self.fingers > MAX_FINGERS {
            return Err(fingers_out_of_range(self.fingers));
        }
        // Said as itself: out of range it would be said only as the contact area it makes.
        if !(self.finger_length_mm > 0.0 && self.finger_length_mm.is_finite()) {
            return Err(Error::invalid(format!(
                "the finger length (finger_length_mm) must be more than 0 mm, got {} mm",
                kerfmeter_protocol::Shown(self.finger_length_mm)
            )));
        }
        let params = RunParams {
            gauge,
            thickness_mm: self.thickness_mm as f32,
            target_force_n: self.force_n() as f32,
            contact_area_mm2: self.contact_area_mm2() as f32,
            ..RunParams::DEFAULT
        };
        check(&params)?;
        Ok(params)
    }
}

/// The most fingers a joint may have.
pub const MAX_FINGERS: u32 = 100;

/// The refusal of a finger count (any integer a caller was given) outside 1 to [`MAX_FINGERS`].
pub fn fingers_out_of_range(fingers: impl std::fmt::Display) -> Error {
    Error::invalid(format!(
        "fingers must be between 1 and {MAX_FINGERS}, got {fingers}"
    ))
}

/// Check run parameters with the device's own ranges, with a message that names the value.
pub fn check(params: &RunParams) -> Result<()> {
    params
        .validate()
        .map_err(|field| Error::invalid(describe_invalid(params, field)))
}

/// A sentence saying which value is refused and why (out of its range, or against a rule that
/// ties it to another field); the contact area says what it is made of.
pub fn describe_invalid(params: &RunParams, field: ParamField) -> Advised {
    let mut message = params.why_invalid(field).to_string();
    if field == ParamField::ContactAreaMm2 {
        message.push_str("; it is fingers × 2 × thickness × finger length");
    }
    // The force is named as each front end takes it (`--force-n`, `force_n`), not by its name
    // on the wire.
    match message.split_once("(target_force_n)") {
        Some((before, after)) if field == ParamField::TargetForceN => Advised::text(before)
            .then("(")
            .advise(Advice::ForceParam)
            .then(")")
            .then(after),
        _ => message.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_reproduce_the_papers_joint() {
        let j = JointSpec::default();
        assert!((j.force_n() - 55.0).abs() < 1e-9);
        assert!((j.contact_area_mm2() - 151.2).abs() < 1e-9);
        let p = j.run_params(GaugeGeometry::PAPER).unwrap();
        assert_eq!(p.target_force_n, 55.0);
    }

    #[test]
    fn a_finger_length_of_nothing_is_said_as_itself() {
        let j = JointSpec {
            finger_length_mm: -1.0,
            ..JointSpec::default()
        };
        let e = j.run_params(GaugeGeometry::PAPER).unwrap_err().to_string();
        assert!(e.contains("finger length (finger_length_mm)"), "{e}");
    }

    #[test]
    fn force_scales_with_fingers_unless_given() {
        let j = JointSpec {
            fingers: 6,
            ..JointSpec::default()
        };
        assert!((j.force_n() - 110.0).abs() < 1e-9);
        let j = JointSpec {
            force_n: Some(30.0),
            ..j
        };
        assert_eq!(j.force_n(), 30.0);
    }

    #[test]
    fn bad_values_get_messages_that_name_them() {
        let j = JointSpec {
            thickness_mm: 80.0,
            ..JointSpec::default()
        };
        let e = j.run_params(GaugeGeometry::PAPER).unwrap_err().to_string();
        assert_eq!(
            e,
            "the sheet thickness (thickness_mm) = 80 mm is out of range (allowed 0.5 to 25 mm)"
        );
        let j = JointSpec {
            force_n: Some(0.0),
            ..JointSpec::default()
        };
        let e = j.run_params(GaugeGeometry::PAPER).unwrap_err().to_string();
        assert!(
            e.contains("the joint's assembly force (target_force_n) = 0 N")
                && e.contains("1 to 500 N"),
            "{e}"
        );
        let j = JointSpec {
            fingers: 0,
            ..JointSpec::default()
        };
        assert!(
            j.run_params(GaugeGeometry::PAPER)
                .unwrap_err()
                .to_string()
                .contains("fingers")
        );
    }
}
