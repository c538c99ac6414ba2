//! Every pin assignment of the board, in one place.
//!
//! [`take_pins!`](crate::take_pins) moves the board's pins out of esp-hal's `Peripherals`;
//! nothing else in the firmware (board binary, on-target tests) names a GPIO number. The numbers
//! themselves are written once, in `board::wiring` (chip-independent, so that `cargo xtask
//! wiring` draws `docs/wiring.svg` from them): change a pin there, keep the table below in step,
//! and run `cargo xtask wiring`.
//!
//! # Wiring
//!
//! | signal                  | part / pin          | dir | ESP32-C3 | ESP32-C6 | notes |
//! |-------------------------|---------------------|-----|----------|----------|-------|
//! | motor PWM               | Pololu G2 `PWM`     | out | GPIO3    | GPIO3    | LEDC, 20 kHz, 11-bit duty; duty 0 = no drive. A panic takes the pin off LEDC and drives it low |
//! | motor direction         | Pololu G2 `DIR`     | out | GPIO10   | GPIO21   | |
//! | motor sleep             | Pololu G2 `SLP`     | out | GPIO1    | GPIO1    | active-low sleep: low = asleep. **Board requirement:** a pull-down resistor (≈10 kΩ to GND) on this net, so the driver sleeps while the MCU is in reset, booting or unpowered (its pins are inputs then); it must win against the G2's own pull-up on `SLP` (measured on the bench with `VIN` on and the MCU held in reset). A panic drives it low on the GPIO registers before anything is printed (`board::emergency`) |
//! | motor fault             | Pololu G2 `FLT`     | in  | GPIO20   | GPIO20   | open-drain, active low (the 18v17 reports under-voltage and a short; it has no over-temperature fault); internal pull-up enabled (an external ≈10 kΩ pull-up to 3V3 is recommended) |
//! | motor current           | Pololu G2 `CS` via an RC low-pass | ain | GPIO0 | GPIO0 | ADC1 channel 0, **0 dB** attenuation (≈0–750 mV), calibrated to millivolts. **Board requirement:** 10 kΩ in series from `CS` to the pin and 100 nF from the pin to GND (τ = 1 ms, [`CS_FILTER_OHM`], [`CS_FILTER_NF`]): the filter averages the G2's pulsed `CS` to duty × current, which the firmware divides by the duty ([`MotorCurrent`]). ≈20 mV/A + ≈50 mV on the G2 18v17 ([`CURRENT_SENSE_MV_PER_A`], [`CURRENT_SENSE_OFFSET_MV`]) |
//! | motor supply            | G2 `VIN` via a 100k/8.2k divider | ain | GPIO4 | GPIO2 | ADC1 channel 4 (C3) / 2 (C6), **11 dB** attenuation (≈0–2.5 V), calibrated; 100 kΩ from `VIN` to the pin, 8.2 kΩ and 100 nF from the pin to GND (`board::supply`): 30 V reads 2.27 V |
//! | encoder clock           | AS5048A `CLK`       | out | GPIO6    | GPIO6    | SPI2 `SCLK`, mode 1, 2 MHz |
//! | encoder data in         | AS5048A `MOSI`      | out | GPIO7    | GPIO7    | SPI2 `MOSI` |
//! | encoder data out        | AS5048A `MISO`      | in  | GPIO5    | GPIO19   | SPI2 `MISO` |
//! | encoder chip select     | AS5048A `CSn`       | out | GPIO2    | GPIO18   | plain GPIO, active low, idles high. **C3 board requirement:** a 10 kΩ pull-up to 3V3 on this net: GPIO2 is a strapping pin that must be high at reset for the chip to boot from flash (or to enter download mode), and the pull-up also keeps the encoder deselected while the pin is an input |
//! | encoder supply          | AS5048A `VDD3V3`, `VDD5V` | pwr | 3V3 | 3V3 | **3.3 V, with `VDD5V` tied to `VDD3V3`**: at 5 V the encoder's `MISO` would drive the MCU's pin beyond its rating |
//! | protocol port           | USB `D-` / `D+`     | —   | GPIO18/19 | GPIO12/13 | USB-Serial-JTAG: protocol frames only |
//! | logs and panics         | UART0 `TX`          | out | GPIO21   | GPIO16   | esp-println, 115200 baud; never on the protocol port |
//!
//! Both analog signals are on ADC1: the C6 has no other ADC, and ESP-IDF no longer supports the
//! C3's ADC2 in oneshot mode (a hardware limitation: its results are not stable). The C3's ADC1
//! has five channels, GPIO0–4: `CS`, `SLP`, `CSn` (GPIO2, with its pull-up), `PWM` and the
//! supply; `DIR` moved from GPIO4 to GPIO10 to make room, and `CSn` from GPIO10 to GPIO2. On the
//! C6, ADC1 is GPIO0–6, of which GPIO4 and GPIO5 are strapping pins (a divider on one would set
//! the boot mode), so `MISO` moved from GPIO2 to GPIO19 and the supply took GPIO2.
//!
//! Pins avoided on purpose:
//!
//! - ESP32-C3: GPIO8 and GPIO9 are boot-strapping pins (so is GPIO2, used for `CSn` with its
//!   pull-up, see above); GPIO18/19 are the USB pins; GPIO11–17 belong to the SPI flash; GPIO21
//!   is the log UART's TX. GPIO20 (UART0 RX) is free because logs are transmit-only: do **not**
//!   connect a USB-UART adapter's TX to it.
//! - ESP32-C6: GPIO4, GPIO5, GPIO8, GPIO9, GPIO15 are strapping pins; GPIO12/13 are the USB pins;
//!   GPIO24–30 belong to the SPI flash; GPIO16/17 are UART0.
//!
//! The SPI signals go through the GPIO matrix; at 2 MHz (the AS5048A allows 10) that is far within
//! its limits.
//!
//! [`CURRENT_SENSE_MV_PER_A`]: super::current::CURRENT_SENSE_MV_PER_A
//! [`CURRENT_SENSE_OFFSET_MV`]: super::current::CURRENT_SENSE_OFFSET_MV
//! [`CS_FILTER_OHM`]: super::current::CS_FILTER_OHM
//! [`CS_FILTER_NF`]: super::current::CS_FILTER_NF
//! [`MotorCurrent`]: super::current::MotorCurrent

use esp_hal::gpio::AnyPin;

/// The pin wired to the G2's current-sense output (ADC1 channel 0 on both chips): a concrete
/// type, because the ADC driver needs to know the ADC channel at compile time.
pub type CurrentSensePin = esp_hal::peripherals::GPIO0<'static>;

/// The pin wired to the supply divider (ADC1 channel 4 on the C3): a concrete type, as above.
#[cfg(feature = "esp32c3")]
pub type SupplySensePin = esp_hal::peripherals::GPIO4<'static>;
/// The pin wired to the supply divider (ADC1 channel 2 on the C6): a concrete type, as above.
#[cfg(feature = "esp32c6")]
pub type SupplySensePin = esp_hal::peripherals::GPIO2<'static>;

/// The board's pins, named by what they are wired to (see the table in the module docs).
pub struct Pins {
    /// The Pololu G2's digital lines.
    pub motor: MotorPins,
    /// Pololu G2 `CS` through its RC filter (analog).
    pub motor_current: CurrentSensePin,
    /// The motor supply's divider (analog).
    pub motor_supply: SupplySensePin,
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
        $crate::__esp32c3_gpios!(__take_board_pins! { $p; })
    };
}

/// Moves the board's [`Pins`](crate::board::pins::Pins) out of a `Peripherals` value named by
/// `$p` (a local variable; the other peripherals stay usable).
#[cfg(feature = "esp32c6")]
#[macro_export]
macro_rules! take_pins {
    ($p:ident) => {
        $crate::__esp32c6_gpios!(__take_board_pins! { $p; })
    };
}

/// [`take_pins!`](crate::take_pins)'s body, given one chip's GPIOs.
#[doc(hidden)]
#[macro_export]
macro_rules! __take_board_pins {
    ($p:ident;
     pwm: $pwm:ident, dir: $dir:ident, sleep: $sleep:ident, fault: $fault:ident,
     current: $current:ident, supply: $supply:ident,
     sclk: $sclk:ident, mosi: $mosi:ident, miso: $miso:ident, cs: $cs:ident) => {
        $crate::board::pins::Pins {
            motor: $crate::board::pins::MotorPins {
                pwm: $p.$pwm.into(),
                dir: $p.$dir.into(),
                sleep: $p.$sleep.into(),
                fault: $p.$fault.into(),
            },
            motor_current: $p.$current,
            motor_supply: $p.$supply,
            encoder: $crate::board::pins::EncoderPins {
                sclk: $p.$sclk.into(),
                mosi: $p.$mosi.into(),
                miso: $p.$miso.into(),
                cs: $p.$cs.into(),
            },
        }
    };
}
