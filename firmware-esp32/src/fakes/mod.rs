//! Fake peripherals (feature `fakes`, std) that speak the real chips' protocols, for the drivers'
//! tests and for the digital twin (`kerfmeter-twin`).
//!
//! - [`as5048a`]: the AS5048A encoder as an embedded-hal `SpiDevice`, with injectable faults.
//! - [`pins`]: PWM and GPIO pins as embedded-hal handles shared with whoever reads them.
//! - [`flash`]: a NOR flash in RAM with the ESP32's geometry, for the configuration store.
//! - [`rng`]: the seeded generator behind the fakes' noise, so a run is reproducible.
//!
//! They need std, so the feature is never switched on with a chip feature: the pins are shared
//! handles (`Arc` of an atomic, one clone for the driver, one for whoever reads the level), the
//! flash is a heap buffer of any size, and the noise uses std's floating-point functions.

pub mod as5048a;
pub mod flash;
pub mod pins;
pub mod rng;
