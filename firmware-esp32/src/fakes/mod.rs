//! Fake peripherals (feature `fakes`, std) that speak the real chips' protocols, for the drivers'
//! tests and for the digital twin (`kerfmeter-twin`).
//!
//! - [`as5048a`]: the AS5048A encoder as an embedded-hal `SpiDevice`, with injectable faults.
//! - [`pins`]: PWM and GPIO pins as embedded-hal handles shared with whoever reads them.
//! - [`flash`]: a NOR flash in RAM with the ESP32's geometry, for the configuration store.
//! - [`rng`]: the seeded generator behind the fakes' noise, so a run is reproducible.

pub mod as5048a;
pub mod flash;
pub mod pins;
pub mod rng;
