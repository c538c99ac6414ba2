//! Kerfmeter device firmware, as a `no_std` library that builds and is tested on the host.
//!
//! The behaviour is sans-IO: nothing here touches a peripheral or awaits. The board binary
//! (`src/bin/board`, features `esp32c3` / `esp32c6`) is glue that moves bytes and samples between
//! the chip and these modules; the digital twin wires the same modules to simulated peripherals.
//! The one exception is [`board`], whose chip part (behind those features) sets the chip's
//! peripherals up for the binary and the on-target tests alike.
//!
//! - [`link`]: the protocol server. Bytes in, requests out to a [`link::Handler`], responses back
//!   out as bytes; retried requests are answered from memory, never executed twice.
//! - [`as5048a`]: the magnetic encoder's driver, checked as the datasheet asks.
//! - [`build`]: what this build is (firmware version, board name, hardware constants) for
//!   `GetInfo`.
//! - [`motor`]: the Pololu G2 motor driver; safe state on construction, on drop, on request.
//! - [`config_store`]: the device configuration in flash, versioned, CRC-checked and migrated.
//! - [`controller`]: the measuring state machine, stepped at 1 kHz: ramp, jam, kerf, faults. Its
//!   kerf and torque math is the gauge's model in `kerfmeter_protocol::spiral`, shared with the host.
//!   Torque is set from the duty, scaled by the measured supply and by the winding's resistance,
//!   which it measures from the motor current where the hub stands still at each jam.
//! - [`hardware`]: one control tick on the real drivers (shared by the board and the twin).
//! - [`health`]: what `GetDiagnostics` reports: the last reset, the chip, the ADC's
//!   calibration, the brown-out detector, the sensors' health, the motor driver.
//! - [`jam`]: jam detection: windowed slope, hold median.
//! - [`samples`]: the run's (time, torque, angle) log, decimated rather than truncated.
//! - [`device`]: the request handler behind the link: the whole request table.
//! - [`watchdog`]: the hardware watchdog's timeouts, and the flash operations that lengthen it.
//! - [`emergency`]: the motor bridge put safe on the registers from a panic, before any print.
//! - [`board`]: board bring-up: pins, PWM, encoder SPI, the current and supply sense on ADC1
//!   (chip features), and the chip-independent current-sense conversion (the RC-filtered `CS`
//!   over the filtered duty, used by [`hardware`]), supply scaling and configuration-partition
//!   policy.
//! - `fakes` (feature `fakes`, std): fake peripherals for the drivers' tests and the digital twin
//!   (the `kerfmeter-twin` crate).

#![cfg_attr(not(any(test, feature = "fakes")), no_std)]
// Unsafe code only in `board::emergency` (the panic path's register writes), which allows it.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod as5048a;
pub mod board;
pub mod build;
pub mod config_store;
pub mod controller;
pub mod device;
pub mod emergency;
#[cfg(any(test, feature = "fakes"))]
pub mod fakes;
pub mod hardware;
pub mod health;
pub mod jam;
pub mod link;
pub mod motor;
pub mod samples;
pub mod watchdog;
