//! Board bring-up: the chip's peripherals set up for the Kerfmeter board, shared by the board
//! binary (`src/bin/board`) and the on-target tests (`tests/on_target.rs`), so that both run
//! exactly the same set-up on the same pins.
//!
//! Chip code, behind the chip features (`esp32c3` or `esp32c6`, which enable `board`; so not
//! linked from these docs when they are built for the host):
//!
//! - `pins`: every pin assignment, with the wiring table and the pins avoided, and why.
//! - `motor`: the Pololu G2's `SLP`, `DIR`, `FLT` lines and its PWM on LEDC (20 kHz, 11-bit
//!   duty), including the ESP32-C6 LEDC divider workaround; then the [`G2Motor`] driver. The
//!   motor lines are driven low before anything else is set up.
//! - `encoder`: the AS5048A on SPI2 (mode 1, 2 MHz, chip select as a GPIO, its timing kept); then the
//!   [`As5048a`] driver.
//! - `adc`: the G2's RC-filtered current-sense output (0 dB) and the supply divider (11 dB) on
//!   ADC1, eFuse-calibrated, its driver built on borrowed parts so that it can be built again
//!   when a conversion stalls.
//! - `flash`: the SPI flash and the partition table's `nvs` partition, which holds the
//!   configuration, its erases and writes guarded by the watchdog.
//! - `watchdog`: TIMG1's MWDT, fed by the control tick and lengthened around flash operations.
//! - `boot`: what the chip says about itself at boot (the last reset's reason, its revision,
//!   the ADC's calibration, the brown-out detector) for `GetDiagnostics`.
//! - `emergency`: the panic path's register writes (GPIO, LEDC) that put the bridge safe before
//!   anything is printed; the motor set-up arms it with the bridge's lines.
//!
//! Chip-independent, and tested on the host:
//!
//! - [`conversion`]: which ADC1 conversion each tick starts and collects, one conversion behind
//!   so that the control tick never waits, and a conversion that never finishes given up.
//! - [`current`]: the motor current from the RC-filtered current sense divided by the duty
//!   filtered alike, and when the current counts as unknown (used by `Hardware::tick`).
//! - [`supply`]: the motor supply's sense divider, its scaling and its reading between
//!   conversions.
//! - [`partition`]: what is done at boot with the configuration partition: use a valid record,
//!   erase foreign data, or run without persistence.
//! - [`wiring`]: the pin numbers of each chip's board, written once (`pins` takes them), and the
//!   wiring as data: each wire's part, pin and fitted components, for `cargo xtask wiring`.
//!
//! The USB-Serial-JTAG port and the tasks stay in the board binary: they are the binary's
//! run-time structure, not set-up that the tests share.
//!
//! [`G2Motor`]: crate::motor::G2Motor
//! [`As5048a`]: crate::as5048a::As5048a

pub mod conversion;
pub mod current;
pub mod partition;
pub mod supply;
pub mod wiring;

#[cfg(feature = "board")]
pub mod adc;
#[cfg(feature = "board")]
pub mod boot;
#[cfg(feature = "board")]
pub mod emergency;
#[cfg(feature = "board")]
pub mod encoder;
#[cfg(feature = "board")]
pub mod flash;
#[cfg(feature = "board")]
pub mod motor;
#[cfg(feature = "board")]
pub mod pins;
#[cfg(feature = "board")]
pub mod watchdog;

#[cfg(all(feature = "board", not(any(feature = "esp32c3", feature = "esp32c6"))))]
compile_error!("the board needs a chip feature: `esp32c3` or `esp32c6`");

#[cfg(all(feature = "esp32c3", feature = "esp32c6"))]
compile_error!("features `esp32c3` and `esp32c6` are mutually exclusive");

/// The chip's name, as `GetInfo` reports it.
#[cfg(feature = "esp32c3")]
pub const BOARD_NAME: &str = "esp32c3";
/// The chip's name, as `GetInfo` reports it.
#[cfg(feature = "esp32c6")]
pub const BOARD_NAME: &str = "esp32c6";

/// The motor driver the board is built with: its current-sense gain and safe supply
/// (`G2Variant`, with Pololu's figures cited). Change it here for another G2 and rebuild; the
/// device reports it in `GetDiagnostics`. (`DeviceConfig` cannot carry it without a major
/// protocol change: it is a postcard struct that `GetConfig` and `SetConfig` send whole.)
pub const DRIVER: kerfmeter_protocol::G2Variant = kerfmeter_protocol::G2Variant::V18v17;

/// The encoder and motor drivers on the board, as the control tick uses them.
#[cfg(feature = "board")]
pub type BoardHardware = crate::hardware::Hardware<
    encoder::EncoderSpi,
    motor::MotorPwm,
    esp_hal::gpio::Output<'static>,
    esp_hal::gpio::Output<'static>,
    esp_hal::gpio::Input<'static>,
>;
