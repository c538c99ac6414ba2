//! Fake PWM and GPIO peripherals implementing the embedded-hal traits, shared between the
//! driver under test (or the twin's firmware side) and the plant that reads them.
//!
//! Each fake is a cheap handle (`Arc` of an atomic): clone it, give one clone to the driver, keep
//! one to read or set the level. The twin runs in lock-step on one thread, but can be moved to
//! another.

use core::convert::Infallible;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU16, Ordering::Relaxed};

use embedded_hal::digital::{self, InputPin, OutputPin};
use embedded_hal::pwm::{self, SetDutyCycle};

/// An error a fake can be told to return.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FakeError;

impl pwm::Error for FakeError {
    fn kind(&self) -> pwm::ErrorKind {
        pwm::ErrorKind::Other
    }
}

/// A PWM channel: records the duty the driver set.
#[derive(Debug, Clone)]
pub struct FakePwm {
    max: u16,
    raw: Arc<AtomicU16>,
    failing: Arc<AtomicBool>,
}

impl FakePwm {
    /// A channel whose full scale is `max` (2047 for 11 bits).
    pub fn new(max: u16) -> Self {
        Self {
            max,
            raw: Arc::new(AtomicU16::new(0)),
            failing: Arc::new(AtomicBool::new(false)),
        }
    }
    /// Duty as a fraction, 0..=1.
    pub fn duty(&self) -> f32 {
        f32::from(self.raw.load(Relaxed)) / f32::from(self.max)
    }
    /// Force the raw duty (to check that the driver overwrites it).
    pub fn set_raw(&self, raw: u16) {
        self.raw.store(raw, Relaxed);
    }
    /// Make every later call fail (and leave the duty as it is).
    pub fn fail(&self, failing: bool) {
        self.failing.store(failing, Relaxed);
    }
}

impl pwm::ErrorType for FakePwm {
    type Error = FakeError;
}

impl SetDutyCycle for FakePwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), FakeError> {
        if self.failing.load(Relaxed) {
            return Err(FakeError);
        }
        self.raw.store(duty.min(self.max), Relaxed);
        Ok(())
    }
}

/// An output pin: records its level.
#[derive(Debug, Clone)]
pub struct FakeOutput(Arc<AtomicBool>);

impl FakeOutput {
    /// A pin at `high`.
    pub fn new(high: bool) -> Self {
        Self(Arc::new(AtomicBool::new(high)))
    }
    /// The level the driver set.
    pub fn is_high(&self) -> bool {
        self.0.load(Relaxed)
    }
}

impl digital::ErrorType for FakeOutput {
    type Error = Infallible;
}

impl OutputPin for FakeOutput {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0.store(false, Relaxed);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0.store(true, Relaxed);
        Ok(())
    }
}

/// An input pin whose level the test or plant sets.
#[derive(Debug, Clone)]
pub struct FakeInput(Arc<AtomicBool>);

impl FakeInput {
    /// A pin at `high`.
    pub fn new(high: bool) -> Self {
        Self(Arc::new(AtomicBool::new(high)))
    }
    /// Set the level the driver will read.
    pub fn set_high(&self, high: bool) {
        self.0.store(high, Relaxed);
    }
}

impl digital::ErrorType for FakeInput {
    type Error = Infallible;
}

impl InputPin for FakeInput {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0.load(Relaxed))
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.load(Relaxed))
    }
}
