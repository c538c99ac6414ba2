//! Kerfmeter's digital twin (std): the device's real firmware on the host, driving a physics
//! model of what it drives, for tests, for the host's `--sim` and for the `kerfmeter-twin`
//! binary.
//!
//! - [`sim`]: the [`Twin`] — the firmware's own link, request handler, controller, AS5048A and G2
//!   drivers and control tick, wired to the firmware's fake peripherals (`kerfmeter_firmware::fakes`)
//!   and lock-stepped with the [`plant`]; named fault injection.
//! - [`options`]: [`TwinOptions`], the one description of a twin, validated here.
//! - [`serve`](mod@serve): one serve loop for a twin or a bare link on any `Read + Write` port.
//! - [`truth`]: [`TruthLog`], the truth of each run (what an ideal device reads on its gauge).
//! - [`pty`]: [`PtyTwin`], a twin served on a pseudo-terminal by a thread, whose client side is an
//!   ordinary serial port.
//!
//! # What the twin models
//!
//! A twin must be as unkind as hardware: one that hands the firmware a perfect world passes
//! firmware a real board fails. So every physical parameter has a realistic default, with its
//! source and plausible range ([`plant::PlantParams`]), and can be set from outside.
//!
//! - The motor and G2 bridge: back-EMF, winding resistance, the driver's current limit, braking
//!   at duty 0, coasting asleep; gearbox ratio, efficiency and stick–slip (Karnopp) friction.
//! - The gauge: the hole play, the inset's friction on the table, the spiral's gap and a linear
//!   contact stiffness, self-locking; a prong slipping out of its hole.
//! - The encoder: the AS5048A's SPI protocol (parity, error flag and register, pipelined
//!   replies), 14-bit quantisation and a few LSB of noise.
//! - The current sense: the motor current plus Gaussian noise.
//! - The configuration flash: NOR rules (erase to 0xFF, writes only clear bits), kept across a
//!   reboot.
//! - The cutter: a gauge-to-gauge Gaussian spread of the kerf.
//! - Faults, by name ([`InjectedFault`]): encoder parity errors, magnet lost, MISO stuck, no inset,
//!   motor disconnected, driver FLT, over-current, host silent, prong slip.
//!
//! Time is simulated in 1 ms control ticks (the physics in [`plant::SUBSTEPS`] sub-steps each),
//! deterministic for a seed; served, it runs ahead of the host in lock-step or follows the wall
//! clock ([`Pace`]).
//!
//! # What it does not model
//!
//! The motor's inductance (its L/R is far below a tick); the G2's current-sense output existing
//! only in the drive phase of each PWM period, and its current chopping; supply sag, under-voltage
//! and winding heating; tick jitter and late ticks; flash erase and write times; the encoder's
//! non-linearity, magnet eccentricity and register writes; the inset's inertia; a non-linear
//! contact; holes displaced by the cutter's repeatability, off-centre prongs and kerf taper.

pub mod encoder;
pub mod options;
pub mod plant;
pub mod pty;
pub mod serve;
pub mod sim;
pub mod truth;

pub use options::{InjectedFault, InvalidOptions, TwinOptions, UnknownFault};
pub use pty::{PtyTwin, StartError};
pub use serve::{LinkServer, Pace, Served, serve};
pub use sim::Twin;
pub use truth::TruthLog;
