//! The Pololu G2's lines on the chip: `SLP`, `DIR` and `PWM` driven low first, the PWM on LEDC
//! (low-speed timer 0, channel 0, 20 kHz, 11-bit duty, clocked from APB), `FLT` as an input with
//! its pull-up; then the library's [`G2Motor`] driver over them.
//!
//! The set-up is split in two ([`motor_lines`], then [`MotorLines::into_driver`]) so that the
//! on-target tests can look at the lines between the two and check that the driver puts them
//! safe whatever state they were left in.

use esp_hal::{
    gpio::{DriveMode, Input, InputConfig, Level, Output, OutputConfig, Pin, Pull},
    ledc::{
        LSGlobalClkSource, Ledc, LowSpeed,
        channel::{self, ChannelIFace},
        timer::{self, TimerIFace},
    },
    peripherals::LEDC,
    time::Rate,
};
use static_cell::StaticCell;

use super::pins::MotorPins;
use crate::build::PWM_FREQUENCY_HZ;
use crate::emergency::BridgeLines;
use crate::motor::{G2Motor, MotorError};

/// Motor PWM frequency ([`PWM_FREQUENCY_HZ`], shared with the digital twin).
pub const PWM_FREQUENCY: Rate = Rate::from_hz(PWM_FREQUENCY_HZ);
/// The LEDC channel of the motor PWM.
pub const PWM_CHANNEL: channel::Number = channel::Number::Channel0;

/// What to ask esp-hal's LEDC timer for so that the pin sees [`PWM_FREQUENCY`].
#[cfg(feature = "esp32c3")]
const LEDC_TIMER_REQUEST: Rate = PWM_FREQUENCY;
/// What to ask esp-hal's LEDC timer for so that the pin sees [`PWM_FREQUENCY`]. On the C6,
/// esp-hal 1.2.2 clocks LEDC from PLL_F80M (80 MHz) but computes the divider from APB_CLK
/// (40 MHz), and then refuses 20 kHz with 11 bits (divider below 1). Asking for half gives the
/// right divider and 20 kHz on the pin. Not yet checked on hardware: scope the pin, and drop
/// this once esp-hal computes the C6 divider from the LEDC clock.
#[cfg(feature = "esp32c6")]
const LEDC_TIMER_REQUEST: Rate = Rate::from_hz(PWM_FREQUENCY.as_hz() / 2);

/// The LEDC timer behind the motor PWM channel. A channel borrows its timer, so the timer lives
/// in a static to give a `'static` channel to a task. Set up once per boot.
static PWM_TIMER: StaticCell<timer::Timer<'static, LowSpeed>> = StaticCell::new();

/// The motor PWM output.
pub type MotorPwm = channel::Channel<'static, LowSpeed>;
/// The G2 driver on the board: PWM, `DIR`, `SLP` outputs and the `FLT` input.
pub type BoardMotor = G2Motor<MotorPwm, Output<'static>, Output<'static>, Input<'static>>;

/// How the motor lines are driven until the motor driver takes them. Each is harmless on its
/// own: awake with duty 0 brakes, a duty while asleep is ignored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineLevels {
    /// `SLP` high (driver awake).
    pub sleep_high: bool,
    /// `DIR` high.
    pub dir_high: bool,
    /// The PWM channel's duty, percent.
    pub duty_pct: u8,
}

impl LineLevels {
    /// The motor's safe state, as the board boots: asleep, `DIR` low, duty 0.
    pub const SAFE: Self = Self {
        sleep_high: false,
        dir_high: false,
        duty_pct: 0,
    };
}

/// The G2's lines, set up but not yet owned by the driver.
pub struct MotorLines {
    /// The PWM channel on `PWM`.
    pub pwm: MotorPwm,
    /// `DIR`.
    pub dir: Output<'static>,
    /// `SLP`.
    pub sleep: Output<'static>,
    /// `FLT`, pulled up.
    pub fault: Input<'static>,
}

impl MotorLines {
    /// The motor driver over these lines, and whether it put them safe (it takes them either
    /// way).
    pub fn into_driver(self) -> (BoardMotor, Result<(), MotorError>) {
        G2Motor::new(self.pwm, self.dir, self.sleep, self.fault)
    }
}

/// Set the G2's lines up at `levels`: `SLP`, `DIR` and the PWM pin as outputs first, then the
/// LEDC timer and channel. Call once per boot (the timer lives in a static). From then on a
/// panic puts these lines safe on the registers (`board::emergency`).
///
/// Panics if LEDC refuses the timer or channel configuration (a build for a chip whose clock
/// tree this module does not know).
pub fn motor_lines(ledc: LEDC<'static>, pins: MotorPins, levels: LineLevels) -> MotorLines {
    let level = |high| if high { Level::High } else { Level::Low };
    let lines = BridgeLines {
        sleep_gpio: pins.sleep.number(),
        dir_gpio: pins.dir.number(),
        pwm_gpio: pins.pwm.number(),
        pwm_channel: PWM_CHANNEL as u8,
    };
    let sleep = Output::new(
        pins.sleep,
        level(levels.sleep_high),
        OutputConfig::default(),
    );
    let dir = Output::new(pins.dir, level(levels.dir_high), OutputConfig::default());
    let pwm_pin = Output::new(pins.pwm, Level::Low, OutputConfig::default());
    // The lines are outputs now: a panic from here on (the LEDC set-up below included) drives
    // them safe on the registers.
    super::emergency::arm(lines);

    let mut ledc = Ledc::new(ledc);
    ledc.set_global_slow_clock(LSGlobalClkSource::APBClk);
    let pwm_timer = PWM_TIMER.init(ledc.timer::<LowSpeed>(timer::Number::Timer0));
    pwm_timer
        .configure(timer::config::Config {
            duty: timer::config::Duty::Duty11Bit,
            clock_source: timer::LSClockSource::APBClk,
            frequency: LEDC_TIMER_REQUEST,
        })
        .expect("LEDC timer: 20 kHz with 11-bit duty");
    let mut pwm = ledc.channel(PWM_CHANNEL, pwm_pin);
    pwm.configure(channel::config::Config {
        timer: &*pwm_timer,
        duty_pct: levels.duty_pct,
        drive_mode: DriveMode::PushPull,
    })
    .expect("LEDC channel");

    let fault = Input::new(pins.fault, InputConfig::default().with_pull(Pull::Up));
    MotorLines {
        pwm,
        dir,
        sleep,
        fault,
    }
}
