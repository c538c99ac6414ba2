//! Every pin assignment of the board, in one place.
//!
//! [`take!`] moves the board's pins out of esp-hal's `Peripherals`; nothing else in the binary
//! names a GPIO number. Change a pin here and only here.
//!
//! # Wiring
//!
//! | signal                  | part / pin          | dir | ESP32-C3 | ESP32-C6 | notes |
//! |-------------------------|---------------------|-----|----------|----------|-------|
//! | motor PWM               | Pololu G2 `PWM`     | out | GPIO3    | GPIO3    | LEDC, 20 kHz, 11-bit duty; duty 0 = no drive |
//! | motor direction         | Pololu G2 `DIR`     | out | GPIO4    | GPIO21   | |
//! | motor sleep             | Pololu G2 `SLP`     | out | GPIO1    | GPIO1    | active-low sleep: low = asleep. **Board requirement:** a pull-down resistor (≈10 kΩ to GND) on this net, so the driver sleeps while the MCU is in reset, booting, halted after a panic, or unpowered |
//! | motor fault             | Pololu G2 `FLT`     | in  | GPIO20   | GPIO20   | open-drain, active low; internal pull-up enabled (an external ≈10 kΩ pull-up to 3V3 is recommended) |
//! | motor current           | Pololu G2 `CS`      | ain | GPIO0    | GPIO0    | ADC1 channel 0, 11 dB attenuation, calibrated to millivolts; ≈20 mV/A + ≈50 mV on the G2 18v17 ([`CURRENT_SENSE_MV_PER_A`], [`CURRENT_SENSE_OFFSET_MV`]); the voltage must stay below the ADC's 11 dB range (≈2.5 V) |
//! | encoder clock           | AS5048A `CLK`       | out | GPIO6    | GPIO6    | SPI2 `SCLK`, mode 1, ≤ 10 MHz |
//! | encoder data in         | AS5048A `MOSI`      | out | GPIO7    | GPIO7    | SPI2 `MOSI` |
//! | encoder data out        | AS5048A `MISO`      | in  | GPIO5    | GPIO2    | SPI2 `MISO` |
//! | encoder chip select     | AS5048A `CSn`       | out | GPIO10   | GPIO18   | plain GPIO, active low, idles high |
//! | protocol port           | USB `D-` / `D+`     | —   | GPIO18/19 | GPIO12/13 | USB-Serial-JTAG: protocol frames only |
//! | logs and panics         | UART0 `TX`          | out | GPIO21   | GPIO16   | esp-println, 115200 baud; never on the protocol port |
//!
//! Pins avoided on purpose:
//!
//! - ESP32-C3: GPIO2, GPIO8, GPIO9 are boot-strapping pins; GPIO18/19 are the USB pins;
//!   GPIO11–17 belong to the SPI flash; GPIO21 is the log UART's TX. GPIO20 (UART0 RX) is free
//!   because logs are transmit-only: do **not** connect a USB-UART adapter's TX to it.
//! - ESP32-C6: GPIO4, GPIO5, GPIO8, GPIO9, GPIO15 are strapping pins; GPIO12/13 are the USB pins;
//!   GPIO24–30 belong to the SPI flash; GPIO16/17 are UART0.
//!
//! The SPI signals go through the GPIO matrix; at ≤ 10 MHz that is well within its limits.

use esp_hal::gpio::AnyPin;

#[cfg(not(any(feature = "esp32c3", feature = "esp32c6")))]
compile_error!("the board binary needs a chip feature: `esp32c3` or `esp32c6`");

#[cfg(all(feature = "esp32c3", feature = "esp32c6"))]
compile_error!("features `esp32c3` and `esp32c6` are mutually exclusive");

/// The pin wired to the G2's current-sense output (ADC1 channel 0 on both chips): a concrete
/// type, because the ADC driver needs to know the ADC channel at compile time.
pub type CurrentSensePin = esp_hal::peripherals::GPIO0<'static>;

/// Current-sense gain of the Pololu G2 18v17 (the reference driver): its `CS` output rises by
/// about 20 mV per amp of motor current. The gain depends on the G2 variant: look it up on
/// Pololu's page for yours and adjust this (and [`CURRENT_SENSE_OFFSET_MV`]) for any other.
pub const CURRENT_SENSE_MV_PER_A: f32 = 20.0;

/// Current-sense offset of the Pololu G2 18v17: its `CS` output sits about 50 mV above ground
/// at zero current. Depends on the G2 variant (and varies a little from board to board): adjust
/// it for another driver.
pub const CURRENT_SENSE_OFFSET_MV: f32 = 50.0;

/// Motor current, A, from the G2's `CS` voltage in millivolts (never negative).
pub fn motor_current_a(cs_mv: u16) -> f32 {
    ((f32::from(cs_mv) - CURRENT_SENSE_OFFSET_MV) / CURRENT_SENSE_MV_PER_A).max(0.0)
}

/// The board's pins, named by what they are wired to (see the table in the module docs).
pub struct Pins {
    /// Pololu G2 `PWM`.
    pub motor_pwm: AnyPin<'static>,
    /// Pololu G2 `DIR`.
    pub motor_dir: AnyPin<'static>,
    /// Pololu G2 `SLP` (low = asleep).
    pub motor_sleep: AnyPin<'static>,
    /// Pololu G2 `FLT` (open-drain, low = fault).
    pub motor_fault: AnyPin<'static>,
    /// Pololu G2 `CS` (analog).
    pub motor_current: CurrentSensePin,
    /// AS5048A `CLK`.
    pub encoder_sclk: AnyPin<'static>,
    /// AS5048A `MOSI`.
    pub encoder_mosi: AnyPin<'static>,
    /// AS5048A `MISO`.
    pub encoder_miso: AnyPin<'static>,
    /// AS5048A `CSn`.
    pub encoder_cs: AnyPin<'static>,
}

/// Moves the board's [`Pins`] out of a `Peripherals` value named by `$p` (a local variable;
/// the other peripherals stay usable).
#[cfg(feature = "esp32c3")]
macro_rules! take {
    ($p:ident) => {
        $crate::pins::Pins {
            motor_pwm: $p.GPIO3.into(),
            motor_dir: $p.GPIO4.into(),
            motor_sleep: $p.GPIO1.into(),
            motor_fault: $p.GPIO20.into(),
            motor_current: $p.GPIO0,
            encoder_sclk: $p.GPIO6.into(),
            encoder_mosi: $p.GPIO7.into(),
            encoder_miso: $p.GPIO5.into(),
            encoder_cs: $p.GPIO10.into(),
        }
    };
}

/// Moves the board's [`Pins`] out of a `Peripherals` value named by `$p` (a local variable;
/// the other peripherals stay usable).
#[cfg(feature = "esp32c6")]
macro_rules! take {
    ($p:ident) => {
        $crate::pins::Pins {
            motor_pwm: $p.GPIO3.into(),
            motor_dir: $p.GPIO21.into(),
            motor_sleep: $p.GPIO1.into(),
            motor_fault: $p.GPIO20.into(),
            motor_current: $p.GPIO0,
            encoder_sclk: $p.GPIO6.into(),
            encoder_mosi: $p.GPIO7.into(),
            encoder_miso: $p.GPIO2.into(),
            encoder_cs: $p.GPIO18.into(),
        }
    };
}

pub(crate) use take;
