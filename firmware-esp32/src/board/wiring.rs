//! The board's wiring as data: which GPIO each signal takes on each chip, which part and pin it
//! goes to, and what must be fitted on the wire. Chip-independent and `no_std`, so that host
//! tools read the same table the firmware is built from: `cargo xtask wiring` draws
//! `docs/wiring.svg` from it, and `cargo xtask wiring --check` fails when that drawing is stale.
//!
//! **One home for the pin numbers.** Each chip's assignment is written once, as GPIO names, in a
//! macro ([`__esp32c3_gpios!`](crate::__esp32c3_gpios), [`__esp32c6_gpios!`](crate::__esp32c6_gpios)).
//! `take_pins!` (chip features) moves exactly those peripherals out of
//! esp-hal's `Peripherals`, and [`ESP32C3`] and [`ESP32C6`] are the same names turned into
//! numbers at compile time; neither can change without the other. `board::pins` (chip features)
//! has the prose table: why each pin, and the pins avoided.
//!
//! [`WIRES`] are the signal wires between the MCU and the parts, with the components each needs
//! on the board; [`POWER`] the power and ground connections, which no GPIO names. Two facts from
//! a review of the hardware (issue 34) live here because a wrong build damages a part:
//!
//! - The AS5048A is powered at **3.3 V, with `VDD5V` tied to `VDD3V3`**, both from the MCU
//!   board's 3V3 (the datasheet's 3.3 V operation). Powered at 5 V, its `MISO` would drive the
//!   C3's `GPIO5` to 5 V, beyond the C3's pin rating (its I/O is 3.3 V, not 5 V tolerant).
//! - `SLP`'s pull-down fights the G2's own pull-up on `SLP` (the G2 pulls `SLP` high, enabling the
//!   driver by default): the 10 kΩ must hold the line well below the G2's logic-high threshold
//!   while the MCU's pin floats. Measure it on the bench (docs/hardware.md, first bench checks),
//!   with `VIN` on and the C3 held in reset.

use super::current::{CS_FILTER_NF, CS_FILTER_OHM};
use super::supply::{SUPPLY_DIVIDER_BOTTOM_OHM, SUPPLY_DIVIDER_TOP_OHM};

/// The GPIO numbers of one chip's board, by signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Gpios {
    /// The chip's name as `GetInfo` reports it (`esp32c3`).
    pub chip: &'static str,
    /// Pololu G2 `PWM`.
    pub pwm: u8,
    /// Pololu G2 `DIR`.
    pub dir: u8,
    /// Pololu G2 `SLP`.
    pub sleep: u8,
    /// Pololu G2 `FLT`.
    pub fault: u8,
    /// Pololu G2 `CS`, through its RC filter (an ADC1 channel).
    pub current: u8,
    /// The motor supply's divider (an ADC1 channel).
    pub supply: u8,
    /// AS5048A `CLK`.
    pub sclk: u8,
    /// AS5048A `MOSI`.
    pub mosi: u8,
    /// AS5048A `MISO`.
    pub miso: u8,
    /// AS5048A `CSn`.
    pub cs: u8,
}

impl Gpios {
    /// The GPIO that `signal` takes.
    pub const fn gpio(&self, signal: Signal) -> u8 {
        match signal {
            Signal::Pwm => self.pwm,
            Signal::Dir => self.dir,
            Signal::Sleep => self.sleep,
            Signal::Fault => self.fault,
            Signal::Current => self.current,
            Signal::Supply => self.supply,
            Signal::Sclk => self.sclk,
            Signal::Mosi => self.mosi,
            Signal::Miso => self.miso,
            Signal::Cs => self.cs,
        }
    }
}

/// The ESP32-C3 board's pins, written once as esp-hal's peripheral names; `$then!` receives
/// `$($args)*` followed by the list. Used by `take_pins!` and [`ESP32C3`].
#[doc(hidden)]
#[macro_export]
macro_rules! __esp32c3_gpios {
    ($then:ident! { $($args:tt)* }) => {
        $crate::$then! { $($args)*
            pwm: GPIO3, dir: GPIO10, sleep: GPIO1, fault: GPIO20, current: GPIO0,
            supply: GPIO4, sclk: GPIO6, mosi: GPIO7, miso: GPIO5, cs: GPIO2 }
    };
}

/// The ESP32-C6 board's pins, as [`__esp32c3_gpios!`](crate::__esp32c3_gpios) for the C3.
#[doc(hidden)]
#[macro_export]
macro_rules! __esp32c6_gpios {
    ($then:ident! { $($args:tt)* }) => {
        $crate::$then! { $($args)*
            pwm: GPIO3, dir: GPIO21, sleep: GPIO1, fault: GPIO20, current: GPIO0,
            supply: GPIO2, sclk: GPIO6, mosi: GPIO7, miso: GPIO19, cs: GPIO18 }
    };
}

/// A [`Gpios`] value from a chip's list of peripheral names.
#[doc(hidden)]
#[macro_export]
macro_rules! __gpio_numbers {
    ($chip:literal;
     pwm: $pwm:ident, dir: $dir:ident, sleep: $sleep:ident, fault: $fault:ident,
     current: $current:ident, supply: $supply:ident,
     sclk: $sclk:ident, mosi: $mosi:ident, miso: $miso:ident, cs: $cs:ident) => {
        $crate::board::wiring::Gpios {
            chip: $chip,
            pwm: $crate::board::wiring::gpio_number(stringify!($pwm)),
            dir: $crate::board::wiring::gpio_number(stringify!($dir)),
            sleep: $crate::board::wiring::gpio_number(stringify!($sleep)),
            fault: $crate::board::wiring::gpio_number(stringify!($fault)),
            current: $crate::board::wiring::gpio_number(stringify!($current)),
            supply: $crate::board::wiring::gpio_number(stringify!($supply)),
            sclk: $crate::board::wiring::gpio_number(stringify!($sclk)),
            mosi: $crate::board::wiring::gpio_number(stringify!($mosi)),
            miso: $crate::board::wiring::gpio_number(stringify!($miso)),
            cs: $crate::board::wiring::gpio_number(stringify!($cs)),
        }
    };
}

/// The ESP32-C3 board's GPIOs (the pins `take_pins!` takes on the C3).
pub const ESP32C3: Gpios = __esp32c3_gpios!(__gpio_numbers! { "esp32c3"; });
/// The ESP32-C6 board's GPIOs (the pins `take_pins!` takes on the C6).
pub const ESP32C6: Gpios = __esp32c6_gpios!(__gpio_numbers! { "esp32c6"; });

/// The number in an esp-hal GPIO peripheral's name (`"GPIO10"` is 10); a name of another shape
/// fails the build where it is evaluated as a constant.
#[doc(hidden)]
pub const fn gpio_number(name: &str) -> u8 {
    let bytes = name.as_bytes();
    assert!(
        bytes.len() > 4
            && bytes[0] == b'G'
            && bytes[1] == b'P'
            && bytes[2] == b'I'
            && bytes[3] == b'O',
        "not a GPIO peripheral name"
    );
    let mut n: u32 = 0;
    let mut i = 4;
    while i < bytes.len() {
        assert!(bytes[i].is_ascii_digit(), "not a GPIO peripheral name");
        n = n * 10 + (bytes[i] - b'0') as u32;
        i += 1;
    }
    assert!(n <= 30, "no such GPIO on the C3 or C6");
    n as u8
}

/// A signal between the MCU and a part, named by what it carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Signal {
    /// Motor PWM.
    Pwm,
    /// Motor direction.
    Dir,
    /// Motor driver sleep (low = asleep).
    Sleep,
    /// Motor driver fault (low = fault).
    Fault,
    /// Motor current sense.
    Current,
    /// Motor supply sense.
    Supply,
    /// Encoder SPI clock.
    Sclk,
    /// Encoder SPI data to the encoder.
    Mosi,
    /// Encoder SPI data from the encoder.
    Miso,
    /// Encoder chip select.
    Cs,
}

/// A part of the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// The ESP32-C3 (or C6) board.
    Mcu,
    /// The Pololu G2 motor driver.
    G2,
    /// The AMS AS5048A magnetic encoder.
    As5048a,
    /// The motor supply (9–26 V DC; a 12 V or 24 V supply).
    Supply,
    /// The DC motor.
    Motor,
}

impl Part {
    /// The part's name in a drawing or table.
    pub const fn name(self) -> &'static str {
        match self {
            Part::Mcu => "ESP32-C3 board",
            Part::G2 => "Pololu G2 18v17",
            Part::As5048a => "AS5048A",
            Part::Supply => "Motor supply",
            Part::Motor => "DC motor",
        }
    }
}

/// Which way a signal goes, seen from the MCU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// A digital output of the MCU.
    Out,
    /// A digital input of the MCU.
    In,
    /// An analog input of the MCU (ADC1).
    Analog,
}

/// What the board carries on a wire besides the wire.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fitted {
    /// Nothing: a plain wire.
    Wire,
    /// A resistor from the wire to GND, Ω: required.
    PullDown {
        /// The resistor, Ω.
        ohm: f32,
    },
    /// A resistor from the wire to 3V3, Ω.
    PullUp {
        /// The resistor, Ω.
        ohm: f32,
        /// Whether the board needs it (otherwise recommended).
        required: bool,
    },
    /// A resistor in series from the part to the pin and a capacitor from the pin to GND.
    LowPass {
        /// The series resistor, Ω.
        ohm: f32,
        /// The capacitor, nF.
        nf: f32,
    },
    /// A divider: a resistor from the part to the pin, one from the pin to GND, with a
    /// capacitor across the bottom one.
    Divider {
        /// From the part to the pin, Ω.
        top_ohm: f32,
        /// From the pin to GND, Ω.
        bottom_ohm: f32,
        /// Across the bottom resistor, nF.
        nf: f32,
    },
}

/// One signal wire from an MCU pin to a part's pin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wire {
    /// What it carries (its GPIO comes from the chip's [`Gpios`]).
    pub signal: Signal,
    /// The part at the other end.
    pub part: Part,
    /// The part's pin, as printed on the part's board.
    pub part_pin: &'static str,
    /// Which way it goes, seen from the MCU.
    pub direction: Direction,
    /// What the board must carry on it.
    pub fitted: Fitted,
    /// One line on what it does.
    pub note: &'static str,
}

/// The SLP pull-down, Ω: keeps the G2 asleep while the MCU's pin is an input.
pub const SLEEP_PULL_DOWN_OHM: f32 = 10_000.0;
/// The `CSn` pull-up, Ω: GPIO2 is a strapping pin that must be high at reset on the C3.
pub const CS_PULL_UP_OHM: f32 = 10_000.0;
/// The recommended external `FLT` pull-up, Ω (the MCU's internal pull-up is enabled too).
pub const FAULT_PULL_UP_OHM: f32 = 10_000.0;
/// The capacitor across the supply divider's bottom resistor, nF.
pub const SUPPLY_FILTER_NF: f32 = 100.0;

/// Every signal wire, the G2's first, then the encoder's.
pub const WIRES: [Wire; 10] = [
    Wire {
        signal: Signal::Pwm,
        part: Part::G2,
        part_pin: "PWM",
        direction: Direction::Out,
        fitted: Fitted::Wire,
        note: "LEDC 20 kHz, 11-bit duty",
    },
    Wire {
        signal: Signal::Dir,
        part: Part::G2,
        part_pin: "DIR",
        direction: Direction::Out,
        fitted: Fitted::Wire,
        note: "high turns the hub clockwise",
    },
    Wire {
        signal: Signal::Sleep,
        part: Part::G2,
        part_pin: "SLP",
        direction: Direction::Out,
        fitted: Fitted::PullDown {
            ohm: SLEEP_PULL_DOWN_OHM,
        },
        note: "low = asleep; asleep through reset and boot",
    },
    Wire {
        signal: Signal::Fault,
        part: Part::G2,
        part_pin: "FLT",
        direction: Direction::In,
        fitted: Fitted::PullUp {
            ohm: FAULT_PULL_UP_OHM,
            required: false,
        },
        note: "open drain, low = under-voltage or short",
    },
    Wire {
        signal: Signal::Current,
        part: Part::G2,
        part_pin: "CS",
        direction: Direction::Analog,
        fitted: Fitted::LowPass {
            ohm: CS_FILTER_OHM,
            nf: CS_FILTER_NF,
        },
        note: "ADC1, 0 dB; about 20 mV/A + 50 mV",
    },
    Wire {
        signal: Signal::Supply,
        part: Part::G2,
        part_pin: "VIN",
        direction: Direction::Analog,
        fitted: Fitted::Divider {
            top_ohm: SUPPLY_DIVIDER_TOP_OHM,
            bottom_ohm: SUPPLY_DIVIDER_BOTTOM_OHM,
            nf: SUPPLY_FILTER_NF,
        },
        note: "ADC1, 11 dB; 30 V reads 2.27 V",
    },
    Wire {
        signal: Signal::Sclk,
        part: Part::As5048a,
        part_pin: "CLK",
        direction: Direction::Out,
        fitted: Fitted::Wire,
        note: "SPI2 mode 1, 2 MHz",
    },
    Wire {
        signal: Signal::Mosi,
        part: Part::As5048a,
        part_pin: "MOSI",
        direction: Direction::Out,
        fitted: Fitted::Wire,
        note: "SPI2",
    },
    Wire {
        signal: Signal::Miso,
        part: Part::As5048a,
        part_pin: "MISO",
        direction: Direction::In,
        fitted: Fitted::Wire,
        note: "SPI2; 3.3 V only (the AS5048A on 3V3)",
    },
    Wire {
        signal: Signal::Cs,
        part: Part::As5048a,
        part_pin: "CSn",
        direction: Direction::Out,
        fitted: Fitted::PullUp {
            ohm: CS_PULL_UP_OHM,
            required: true,
        },
        note: "active low; GPIO2 must be high at reset (C3)",
    },
];

/// A power or ground connection: no GPIO names it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerWire {
    /// One end: a part and its pin.
    pub from: (Part, &'static str),
    /// The other end.
    pub to: (Part, &'static str),
    /// One line on it.
    pub note: &'static str,
}

/// The power and ground connections.
pub const POWER: [PowerWire; 8] = [
    PowerWire {
        from: (Part::Mcu, "3V3"),
        to: (Part::As5048a, "VDD3V3"),
        note: "the encoder runs at 3.3 V",
    },
    PowerWire {
        from: (Part::Mcu, "3V3"),
        to: (Part::As5048a, "VDD5V"),
        note: "tied to VDD3V3: never 5 V (MISO would exceed the C3's pin rating)",
    },
    PowerWire {
        from: (Part::Mcu, "GND"),
        to: (Part::As5048a, "GND"),
        note: "",
    },
    PowerWire {
        from: (Part::Mcu, "GND"),
        to: (Part::G2, "GND"),
        note: "logic ground, beside the control pins",
    },
    PowerWire {
        from: (Part::Supply, "+"),
        to: (Part::G2, "VIN"),
        note: "9–26 V; the G2 18v17's safe maximum is about 24 V",
    },
    PowerWire {
        from: (Part::Supply, "−"),
        to: (Part::G2, "GND"),
        note: "the power ground, by the VIN terminal",
    },
    PowerWire {
        from: (Part::Motor, "+"),
        to: (Part::G2, "OUTA"),
        note: "",
    },
    PowerWire {
        from: (Part::Motor, "−"),
        to: (Part::G2, "OUTB"),
        note: "swap, or set motor_inverted, if it turns the wrong way",
    },
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gpio_names_become_their_numbers() {
        assert_eq!(gpio_number("GPIO0"), 0);
        assert_eq!(gpio_number("GPIO21"), 21);
        assert_eq!(ESP32C3.pwm, 3);
        assert_eq!(ESP32C3.cs, 2);
        assert_eq!(ESP32C6.miso, 19);
    }

    #[test]
    fn no_gpio_is_taken_twice() {
        for gpios in [ESP32C3, ESP32C6] {
            let mut taken: Vec<u8> = WIRES.iter().map(|w| gpios.gpio(w.signal)).collect();
            taken.sort_unstable();
            taken.dedup();
            assert_eq!(taken.len(), WIRES.len(), "{}", gpios.chip);
        }
    }

    #[test]
    fn the_analog_signals_are_on_adc1() {
        // ADC1 is GPIO0–4 on the C3 and GPIO0–6 on the C6.
        for (gpios, last) in [(ESP32C3, 4), (ESP32C6, 6)] {
            for w in WIRES.iter().filter(|w| w.direction == Direction::Analog) {
                assert!(
                    gpios.gpio(w.signal) <= last,
                    "{:?} on {}",
                    w.signal,
                    gpios.chip
                );
            }
        }
    }
}
