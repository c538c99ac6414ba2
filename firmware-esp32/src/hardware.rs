//! One control tick on the real drivers, shared by the board binary and the digital twin so that
//! both run exactly the same sequence:
//!
//! 1. read the hub angle from the AS5048A;
//! 2. read its diagnostics every [`DIAGNOSTICS_PERIOD_TICKS`] ticks, and at once after any read
//!    error (so that a lost magnet is reported as such, not as a run of bad reads);
//! 3. read the driver's FLT line (an unreadable FLT counts as a fault);
//! 4. convert the current-sense reading to the motor current ([`MotorCurrent`]: the RC-filtered
//!    `CS` divided by the duty filtered alike, or unknown);
//! 5. step the [`Device`] with these inputs, the motor current (or that it is unknown) and the
//!    motor supply (when it is measured);
//! 6. apply its output to the motor driver (a failed apply forces the motor safe and is reported
//!    as a driver fault on the next tick), and tell the current sense which duty the bridge holds
//!    from now on.
//!
//! Changes of the encoder's own settings ([`EncoderSettings`]: zero, placement, gear ratio,
//! sense) reach the encoder driver here, and only those, and a hub turn the user has confirmed
//! (`Controller::encoder_epoch`), restart its turn counting: any other
//! configuration change (current limit, torque constant, ...) leaves the count alone, so that a
//! hub standing away from zero (in `Done`) keeps its true angle. The controller accepts a change of
//! a motor-shaft encoder's settings only with the hub at zero (see `Controller::set_config`),
//! where the restarted count picks the right motor turn.

use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal::pwm::SetDutyCycle;
use embedded_hal::spi::SpiDevice;

use kerfmeter_protocol::EncoderHealth;

use crate::as5048a::{As5048a, Diagnostics, DiagnosticsError, EncoderError, EncoderSettings};
use crate::board::current::MotorCurrent;
use crate::config_store::ConfigPersist;
use crate::controller::{DiagnosticsReading, EncoderFault, Inputs};
use crate::device::Device;
use crate::health::SenseFacts;
use crate::motor::{G2Motor, MotorOutput};

/// Diagnostics are read this often (ticks), and after every read error.
pub const DIAGNOSTICS_PERIOD_TICKS: u32 = 50;

/// When the diagnostics are due: on the first tick, then every [`DIAGNOSTICS_PERIOD_TICKS`]
/// ticks, counted again from any tick they are read on at once.
#[derive(Debug, Default)]
struct DiagnosticsDue {
    /// Ticks until they are due (0: this one).
    ticks_left: u32,
}

impl DiagnosticsDue {
    /// Whether they are read on this tick; `now` reads them whatever the count.
    fn tick(&mut self, now: bool) -> bool {
        if now || self.ticks_left == 0 {
            self.ticks_left = DIAGNOSTICS_PERIOD_TICKS - 1;
            true
        } else {
            self.ticks_left -= 1;
            false
        }
    }
}

/// The encoder and motor drivers of one device.
pub struct Hardware<SPI, PWM, DIR, SLP, FLT>
where
    SPI: SpiDevice<u8>,
    PWM: SetDutyCycle,
    DIR: OutputPin,
    SLP: OutputPin,
    FLT: InputPin,
{
    /// The encoder driver.
    pub encoder: As5048a<SPI>,
    /// The motor driver.
    pub motor: G2Motor<PWM, DIR, SLP, FLT>,
    diagnostics_due: DiagnosticsDue,
    motor_error: bool,
    /// The encoder settings last given to the driver, and the controller's encoder epoch then
    /// (a confirmed hub turn restarts the count too).
    applied: Option<(EncoderSettings, u16)>,
    /// The motor current from the current-sense readings and the duties applied.
    current: MotorCurrent,
    /// The encoder's diagnostics as last read.
    encoder_health: Option<EncoderHealth>,
}

impl<SPI, PWM, DIR, SLP, FLT> Hardware<SPI, PWM, DIR, SLP, FLT>
where
    SPI: SpiDevice<u8>,
    PWM: SetDutyCycle,
    DIR: OutputPin,
    SLP: OutputPin,
    FLT: InputPin,
{
    /// Wrap the drivers; diagnostics are read on the first tick.
    pub fn new(encoder: As5048a<SPI>, motor: G2Motor<PWM, DIR, SLP, FLT>) -> Self {
        Self {
            encoder,
            motor,
            diagnostics_due: DiagnosticsDue::default(),
            motor_error: false,
            applied: None,
            current: MotorCurrent::new(),
            encoder_health: None,
        }
    }

    /// One control tick at `now_us`, with the current-sense reading for it, the ADC's calibrated
    /// millivolts on the filtered `CS` pin, taken as the last tick's output was applied (`None`
    /// when the ADC has no fresh reading: the last current stands, and after
    /// [`CURRENT_STALE_TICKS`](crate::board::current::CURRENT_STALE_TICKS) such ticks the current
    /// is unknown and the controller faults with `OverCurrent`), and the motor supply measured
    /// for it, V (`None` where it is not measured).
    pub fn tick<S: ConfigPersist>(
        &mut self,
        now_us: u64,
        cs_mv: Option<u16>,
        supply_v: Option<f32>,
        device: &mut Device<S>,
    ) -> MotorOutput {
        let controller = device.controller();
        let settings = (
            EncoderSettings::from_config(controller.config()),
            controller.encoder_epoch(),
        );
        if self.applied != Some(settings) {
            self.encoder.set_settings(settings.0);
            self.applied = Some(settings);
        }
        let angle_deg = self.encoder.read_hub_deg().map_err(|e| match e {
            EncoderError::Bus(_) => EncoderFault::Bus,
            EncoderError::Parity => EncoderFault::Parity,
            EncoderError::ErrorFlag(_) => EncoderFault::ErrorFlag,
            EncoderError::Jump => EncoderFault::Jump,
        });
        let diagnostics = if self.diagnostics_due.tick(angle_deg.is_err()) {
            match self.encoder.diagnostics() {
                Ok(d) => {
                    self.encoder_health = Some(encoder_health(&d));
                    Some(Ok(DiagnosticsReading {
                        magnitude: d.magnitude,
                        marginal: d.marginal(),
                    }))
                }
                Err(DiagnosticsError::Failed(f)) => Some(Err(f)),
                // A bus-level error while reading them: the angle reads show it too.
                Err(DiagnosticsError::Read(_)) => None,
            }
        } else {
            None
        };
        let driver_fault = self.motor_error || self.motor.fault().unwrap_or(true);
        self.current.set_mv_per_a(device.driver().cs_mv_per_a());
        let inputs = Inputs {
            angle_deg,
            diagnostics,
            current_a: self.current.current_a(cs_mv),
            driver_fault,
            supply_v,
        };
        let out = device.step(now_us, &inputs);
        self.motor_error = self.motor.apply(&out).is_err();
        let held = if self.motor_error {
            MotorOutput::SAFE
        } else {
            out
        };
        self.current.applied(&held, now_us);
        device.note_sense(SenseFacts {
            cs_asleep_mv: self.current.asleep_mv(),
            cs_offset_mv: self.current.offset_mv(),
            cs_offset_learnt: self.current.offset_learnt(),
            encoder: self.encoder_health,
        });
        out
    }

    /// The motor current's conversion (for checks).
    pub fn current(&self) -> &MotorCurrent {
        &self.current
    }
}

/// The encoder's diagnostics as `GetDiagnostics` reports them.
fn encoder_health(d: &Diagnostics) -> EncoderHealth {
    EncoderHealth {
        magnitude: d.magnitude,
        agc: d.agc,
        ocf: d.ocf,
        cof: d.cof,
        comp_low: d.comp_low,
        comp_high: d.comp_high,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagnostics_are_due_on_the_first_tick_then_every_period_and_after_a_read_error() {
        let mut due = DiagnosticsDue::default();
        let read_on: Vec<u32> = (0..160).filter(|_| due.tick(false)).collect();
        let period = DIAGNOSTICS_PERIOD_TICKS;
        assert_eq!(read_on, [0, period, 2 * period, 3 * period]);
        // A read error at once, and the period counted again from it.
        let mut due = DiagnosticsDue::default();
        let read_on: Vec<u32> = (0..80).filter(|&t| due.tick(t == 7)).collect();
        assert_eq!(read_on, [0, 7, 7 + period]);
    }
}
