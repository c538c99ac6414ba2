//! Every pin assignment of the board, in one place.
//!
//! [`take_pins!`](crate::take_pins) moves the board's pins out of esp-hal's `Peripherals`;
//! nothing else in the firmware (board binary, on-target tests) names a GPIO number. Change a pin
//! here and only here.
//!
//! # Wiring
//!
//! | signal                  | part / pin          | dir | ESP32-C3 | ESP32-C6 | notes |
//! |-------------------------|---------------------|-----|----------|----------|-------|
//! | motor PWM               | Pololu G2 `PWM`     | out | GPIO3    | GPIO3    | LEDC, 20 kHz, 11-bit duty; duty 0 = no drive. A panic takes the pin off LEDC and drives it low |
//! | motor direction         | Pololu G2 `DIR`     | out | GPIO4    | GPIO21   | |
//! | motor sleep             | Pololu G2 `SLP`     | out | GPIO1    | GPIO1    | active-low sleep: low = asleep. **Board requirement:** a pull-down resistor (≈10 kΩ to GND) on this net, so the driver sleeps while the MCU is in reset, booting or unpowered (its pins are inputs then). A panic drives it low on the GPIO registers before anything is printed (`board::emergency`) |
//! | motor fault             | Pololu G2 `FLT`     | in  | GPIO20   | GPIO20   | open-drain, active low; internal pull-up enabled (an external ≈10 kΩ pull-up to 3V3 is recommended) |
//! | motor current           | Pololu G2 `CS`      | ain | GPIO0    | GPIO0    | ADC1 channel 0, 11 dB attenuation, calibrated to millivolts; ≈20 mV/A + ≈50 mV on the G2 18v17 ([`CURRENT_SENSE_MV_PER_A`], [`CURRENT_SENSE_OFFSET_MV`]); the voltage must stay below the ADC's 11 dB range (≈2.5 V) |
//! | motor supply            | G2 `VIN` via a 100k/8.2k divider | ain | — | — | **not wired yet** (issue 12): ADC1's channels on the C3 (GPIO0–4) are all taken; the divider and its scaling are in `board::supply` |
//! | encoder clock           | AS5048A `CLK`       | out | GPIO6    | GPIO6    | SPI2 `SCLK`, mode 1, 2 MHz |
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
//! The SPI signals go through the GPIO matrix; at 2 MHz (the AS5048A allows 10) that is far within
//! its limits.
//!
//! [`CURRENT_SENSE_MV_PER_A`]: super::current::CURRENT_SENSE_MV_PER_A
//! [`CURRENT_SENSE_OFFSET_MV`]: super::current::CURRENT_SENSE_OFFSET_MV

use esp_hal::gpio::AnyPin;

/// The pin wired to the G2's current-sense output (ADC1 channel 0 on both chips): a concrete
/// type, because the ADC driver needs to know the ADC channel at compile time.
pub type CurrentSensePin = esp_hal::peripherals::GPIO0<'static>;

/// The board's pins, named by what they are wired to (see the table in the module docs).
pub struct Pins {
    /// The Pololu G2's digital lines.
    pub motor: MotorPins,
    /// Pololu G2 `CS` (analog).
    pub motor_current: CurrentSensePin,
    /// The AS5048A's SPI lines.
    pub encoder: EncoderPins,
}

/// The Pololu G2's digital lines.
pub struct MotorPins {
    /// Pololu G2 `PWM`.
    pub pwm: AnyPin<'static>,
    /// Pololu G2 `DIR`.
    pub dir: AnyPin<'static>,
    /// Pololu G2 `SLP` (low = asleep).
    pub sleep: AnyPin<'static>,
    /// Pololu G2 `FLT` (open-drain, low = fault).
    pub fault: AnyPin<'static>,
}

/// The AS5048A's SPI lines.
pub struct EncoderPins {
    /// AS5048A `CLK`.
    pub sclk: AnyPin<'static>,
    /// AS5048A `MOSI`.
    pub mosi: AnyPin<'static>,
    /// AS5048A `MISO`.
    pub miso: AnyPin<'static>,
    /// AS5048A `CSn`.
    pub cs: AnyPin<'static>,
}

/// Moves the board's [`Pins`](crate::board::pins::Pins) out of a `Peripherals` value named by
/// `$p` (a local variable; the other peripherals stay usable).
#[cfg(feature = "esp32c3")]
#[macro_export]
macro_rules! take_pins {
    ($p:ident) => {
        $crate::__take_board_pins!($p;
            pwm: GPIO3, dir: GPIO4, sleep: GPIO1, fault: GPIO20, current: GPIO0,
            sclk: GPIO6, mosi: GPIO7, miso: GPIO5, cs: GPIO10)
    };
}

/// Moves the board's [`Pins`](crate::board::pins::Pins) out of a `Peripherals` value named by
/// `$p` (a local variable; the other peripherals stay usable).
#[cfg(feature = "esp32c6")]
#[macro_export]
macro_rules! take_pins {
    ($p:ident) => {
        $crate::__take_board_pins!($p;
            pwm: GPIO3, dir: GPIO21, sleep: GPIO1, fault: GPIO20, current: GPIO0,
            sclk: GPIO6, mosi: GPIO7, miso: GPIO2, cs: GPIO18)
    };
}

/// [`take_pins!`](crate::take_pins)'s body, given one chip's GPIOs.
#[doc(hidden)]
#[macro_export]
macro_rules! __take_board_pins {
    ($p:ident;
     pwm: $pwm:ident, dir: $dir:ident, sleep: $sleep:ident, fault: $fault:ident,
     current: $current:ident,
     sclk: $sclk:ident, mosi: $mosi:ident, miso: $miso:ident, cs: $cs:ident) => {
        $crate::board::pins::Pins {
            motor: $crate::board::pins::MotorPins {
                pwm: $p.$pwm.into(),
                dir: $p.$dir.into(),
                sleep: $p.$sleep.into(),
                fault: $p.$fault.into(),
            },
            motor_current: $p.$current,
            encoder: $crate::board::pins::EncoderPins {
                sclk: $p.$sclk.into(),
                mosi: $p.$mosi.into(),
                miso: $p.$miso.into(),
                cs: $p.$cs.into(),
            },
        }
    };
}
