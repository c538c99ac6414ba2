//! Pololu G2 motor driver: PWM (`SetDutyCycle`), DIR and SLP (`OutputPin`), FLT (`InputPin`).
//!
//! No control logic: it applies a [`MotorOutput`] and reports the FLT line. SLP low puts the
//! driver to sleep (outputs off); FLT is open-drain, low on a fault: on the G2 18v17, a short
//! circuit or under-voltage. The 18v17 has no over-temperature fault on FLT (Pololu lists
//! under-voltage shutdown and short-circuit protection only), so a hot bridge is not reported
//! here: the over-current trip on the measured current is what guards the motor and driver.
//!
//! **Safe state** — duty 0, SLP low (asleep), DIR low — is set before anything else when the
//! driver is constructed, whenever the output asks for the driver asleep
//! ([`MotorOutput::SAFE`]; [`MotorOutput::BRAKE`], awake at duty 0, is driven as any output), and
//! when the driver is dropped (the glue losing control of the motor). A pin error while going safe is reported, and the
//! remaining pins are still driven safe.

use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal::pwm::SetDutyCycle;

/// What the controller wants the motor to do this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorOutput {
    /// Duty cycle, 0..=1.
    pub duty: f32,
    /// DIR line level (after the configuration's inversion).
    pub dir_high: bool,
    /// Driver awake (SLP high). When false the duty is ignored and the driver sleeps.
    pub awake: bool,
}

impl MotorOutput {
    /// Duty 0, driver asleep.
    pub const SAFE: Self = Self {
        duty: 0.0,
        dir_high: false,
        awake: false,
    };

    /// Duty 0 with the driver awake: the G2 shorts the motor through its low-side switches,
    /// braking it (back-EMF drives the current). No drive torque.
    pub const BRAKE: Self = Self {
        duty: 0.0,
        dir_high: false,
        awake: true,
    };

    /// True when this output applies no drive torque (asleep, or braking).
    pub fn is_safe(&self) -> bool {
        !self.awake || self.duty <= 0.0
    }
}

/// A pin or PWM error; the motor has been driven to its safe state as far as possible.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MotorError {
    /// Setting the PWM duty failed.
    Pwm,
    /// Driving DIR or SLP, or reading FLT, failed.
    Pin,
}

/// The G2 driver's pins.
pub struct G2Motor<PWM, DIR, SLP, FLT>
where
    PWM: SetDutyCycle,
    DIR: OutputPin,
    SLP: OutputPin,
    FLT: InputPin,
{
    pwm: PWM,
    dir: DIR,
    slp: SLP,
    flt: FLT,
}

impl<PWM, DIR, SLP, FLT> G2Motor<PWM, DIR, SLP, FLT>
where
    PWM: SetDutyCycle,
    DIR: OutputPin,
    SLP: OutputPin,
    FLT: InputPin,
{
    /// Take the pins and put the motor in its safe state at once.
    pub fn new(pwm: PWM, dir: DIR, slp: SLP, flt: FLT) -> (Self, Result<(), MotorError>) {
        let mut motor = Self { pwm, dir, slp, flt };
        let safe = motor.safe();
        (motor, safe)
    }

    /// Duty 0, driver asleep, DIR low. Every pin is driven even if an earlier one fails.
    pub fn safe(&mut self) -> Result<(), MotorError> {
        let pwm = self
            .pwm
            .set_duty_cycle_fully_off()
            .map_err(|_| MotorError::Pwm);
        let slp = self.slp.set_low().map_err(|_| MotorError::Pin);
        let dir = self.dir.set_low().map_err(|_| MotorError::Pin);
        pwm.and(slp).and(dir)
    }

    /// Apply the controller's output. An output with the driver asleep takes the safe path.
    pub fn apply(&mut self, out: &MotorOutput) -> Result<(), MotorError> {
        if !out.awake {
            return self.safe();
        }
        let result = self.drive(out);
        if result.is_err() {
            // Never leave a half-applied output behind.
            let _ = self.safe();
        }
        result
    }

    fn drive(&mut self, out: &MotorOutput) -> Result<(), MotorError> {
        self.dir
            .set_state(out.dir_high.into())
            .map_err(|_| MotorError::Pin)?;
        let max = u32::from(self.pwm.max_duty_cycle());
        let duty = (out.duty.clamp(0.0, 1.0) * max as f32 + 0.5) as u32;
        self.pwm
            .set_duty_cycle(duty.min(max) as u16)
            .map_err(|_| MotorError::Pwm)?;
        self.slp.set_high().map_err(|_| MotorError::Pin)
    }

    /// True when the driver pulls FLT low (a driver fault).
    pub fn fault(&mut self) -> Result<bool, MotorError> {
        self.flt.is_low().map_err(|_| MotorError::Pin)
    }
}

impl<PWM, DIR, SLP, FLT> Drop for G2Motor<PWM, DIR, SLP, FLT>
where
    PWM: SetDutyCycle,
    DIR: OutputPin,
    SLP: OutputPin,
    FLT: InputPin,
{
    fn drop(&mut self) {
        let _ = self.safe();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fakes::pins::{FakeInput, FakeOutput, FakePwm};

    fn motor() -> (
        G2Motor<FakePwm, FakeOutput, FakeOutput, FakeInput>,
        FakePwm,
        FakeOutput,
        FakeOutput,
        FakeInput,
    ) {
        let (pwm, dir, slp, flt) = (
            FakePwm::new(2047),
            FakeOutput::new(true),
            FakeOutput::new(true),
            FakeInput::new(true),
        );
        pwm.set_raw(1234);
        let (m, r) = G2Motor::new(pwm.clone(), dir.clone(), slp.clone(), flt.clone());
        r.unwrap();
        (m, pwm, dir, slp, flt)
    }

    #[test]
    fn construction_sets_the_safe_state_first() {
        let (_m, pwm, dir, slp, _) = motor();
        assert_eq!(pwm.duty(), 0.0);
        assert!(!slp.is_high());
        assert!(!dir.is_high());
    }

    #[test]
    fn apply_drives_duty_direction_and_wakes_the_driver() {
        let (mut m, pwm, dir, slp, _) = motor();
        m.apply(&MotorOutput {
            duty: 0.5,
            dir_high: true,
            awake: true,
        })
        .unwrap();
        assert!((pwm.duty() - 0.5).abs() < 1e-3);
        assert!(dir.is_high() && slp.is_high());
        m.apply(&MotorOutput::SAFE).unwrap();
        assert_eq!(pwm.duty(), 0.0);
        assert!(!slp.is_high());
    }

    #[test]
    fn dropping_the_driver_leaves_the_motor_safe() {
        let (mut m, pwm, _, slp, _) = motor();
        m.apply(&MotorOutput {
            duty: 0.8,
            dir_high: false,
            awake: true,
        })
        .unwrap();
        drop(m);
        assert_eq!(pwm.duty(), 0.0);
        assert!(!slp.is_high());
    }

    #[test]
    fn a_pwm_failure_still_puts_the_driver_to_sleep() {
        let (mut m, pwm, _, slp, _) = motor();
        pwm.fail(true);
        assert_eq!(
            m.apply(&MotorOutput {
                duty: 0.5,
                dir_high: true,
                awake: true
            }),
            Err(MotorError::Pwm)
        );
        assert!(!slp.is_high());
    }

    #[test]
    fn flt_low_is_a_fault() {
        let (mut m, _, _, _, flt) = motor();
        assert_eq!(m.fault(), Ok(false));
        flt.set_high(false);
        assert_eq!(m.fault(), Ok(true));
    }
}
