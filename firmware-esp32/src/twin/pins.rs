//! Fake PWM and GPIO peripherals implementing the embedded-hal traits, shared between the
//! driver under test (or the twin's firmware side) and the plant that reads them.
//!
//! Each fake is a cheap handle (`Rc<Cell<…>>`): clone it, give one clone to the driver, keep one
//! to read or set the level. Single-threaded, as the twin runs in lock-step.

use core::cell::Cell;
use core::convert::Infallible;
use std::rc::Rc;

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
    raw: Rc<Cell<u16>>,
    failing: Rc<Cell<bool>>,
}

impl FakePwm {
    /// A channel whose full scale is `max` (2047 for 11 bits).
    pub fn new(max: u16) -> Self {
        Self {
            max,
            raw: Rc::new(Cell::new(0)),
            failing: Rc::new(Cell::new(false)),
        }
    }
    /// Duty as a fraction, 0..=1.
    pub fn duty(&self) -> f32 {
        f32::from(self.raw.get()) / f32::from(self.max)
    }
    /// Force the raw duty (to check that the driver overwrites it).
    pub fn set_raw(&self, raw: u16) {
        self.raw.set(raw);
    }
    /// Make every later call fail (and leave the duty as it is).
    pub fn fail(&self, failing: bool) {
        self.failing.set(failing);
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
        if self.failing.get() {
            return Err(FakeError);
        }
        self.raw.set(duty.min(self.max));
        Ok(())
    }
}

/// An output pin: records its level.
#[derive(Debug, Clone)]
pub struct FakeOutput(Rc<Cell<bool>>);

impl FakeOutput {
    /// A pin at `high`.
    pub fn new(high: bool) -> Self {
        Self(Rc::new(Cell::new(high)))
    }
    /// The level the driver set.
    pub fn is_high(&self) -> bool {
        self.0.get()
    }
}

impl digital::ErrorType for FakeOutput {
    type Error = Infallible;
}

impl OutputPin for FakeOutput {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0.set(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0.set(true);
        Ok(())
    }
}

/// An input pin whose level the test or plant sets.
#[derive(Debug, Clone)]
pub struct FakeInput(Rc<Cell<bool>>);

impl FakeInput {
    /// A pin at `high`.
    pub fn new(high: bool) -> Self {
        Self(Rc::new(Cell::new(high)))
    }
    /// Set the level the driver will read.
    pub fn set_high(&self, high: bool) {
        self.0.set(high);
    }
}

impl digital::ErrorType for FakeInput {
    type Error = Infallible;
}

impl InputPin for FakeInput {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.0.get())
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.0.get())
    }
}
