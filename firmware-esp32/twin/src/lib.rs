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
//! - [`sense`]: what the firmware's ADC channels read: the G2's current sense as the chip produces
//!   it, and the motor supply through its divider.
//! - [`pty`]: [`PtyTwin`], a twin served on a pseudo-terminal by a thread, whose client side is an
//!   ordinary serial port.
//!
//! # What the twin models
//!
//! A twin must be as unkind as hardware: one that hands the firmware a perfect world passes
//! firmware a real board fails. So every physical parameter has a realistic default, with its
//! source and plausible range ([`plant::PlantParams`]), and can be set from outside.
//!
//! - The supply: its source resistance, so the bus sags by the average supply current (the duty
//!   times the motor current); the G2's under-voltage lockout (outputs off, FLT low, released
//!   0.3 V above the threshold), which the firmware sees as `DriverFault`.
//! - The motor and G2 bridge: back-EMF, winding resistance, braking at duty 0, coasting asleep;
//!   the driver's current limiting (chopping: the current held at the limit, a shorter drive
//!   phase); gearbox ratio, efficiency and stick–slip (Karnopp) friction.
//! - The winding's temperature: I²R heating against a thermal resistance to ambient, and the
//!   copper's resistance rising 0.39 %/°C with it (less current, so less torque, per duty).
//! - The gauge: the hole play, the inset's friction on the table, the spiral's gap and a linear
//!   contact stiffness, self-locking; a prong slipping out of its hole.
//! - The encoder: the AS5048A's SPI protocol (parity, error flag and register, pipelined
//!   replies), 14-bit quantisation and a few LSB of noise.
//! - The current sense as the G2 produces it: the current only in the drive phase of each 20 kHz
//!   PWM period (about zero while braking or chopping), sampled once per tick at an instant that
//!   drifts through the period; an optional RC filter on the pin; gain error, noise, the 1 mV
//!   steps of the calibrated ADC and the firmware's own mV→A conversion.
//! - The supply sense: the bus through a divider into the ADC, with gain error, noise and 1 mV
//!   steps (handed to the firmware, which does not use it yet).
//! - The configuration flash: NOR rules (erase to 0xFF, writes only clear bits), kept across a
//!   reboot.
//! - The cutter: a gauge-to-gauge Gaussian spread of the kerf.
//! - Faults, by name ([`InjectedFault`]): encoder parity errors, magnet lost, MISO stuck, no inset,
//!   motor disconnected, driver FLT, over-current, host silent, prong slip.
//!
//! Time is simulated in 1 ms control ticks (the physics in sub-steps of at most
//! [`plant::SUBSTEP_US`] µs), deterministic for a seed; served, it runs ahead of the host in
//! lock-step or follows the wall clock ([`Pace`]).
//!
//! # What it does not model
//!
//! The motor's inductance (its L/R is far below a tick, though above a PWM period: the current is
//! taken as continuous, with no ripple); the bus capacitance (the bus follows the load at once, so
//! a supply that sags into the lockout stays locked while the load is asked for, rather than
//! hiccuping); the current-sense waveform between two samples (the bridge's state at the end of
//! the last tick stands for the whole tick); the CS offset's spread and the G2's other faults
//! (short circuit, over-temperature); tick jitter and late ticks; flash erase and write times;
//! the encoder's non-linearity, magnet eccentricity and register writes; the inset's inertia; a
//! non-linear contact; holes displaced by the cutter's repeatability, off-centre prongs and kerf
//! taper.

pub mod options;
pub mod plant;
pub mod pty;
pub mod sense;
pub mod serve;
pub mod sim;
pub mod truth;

pub use options::{InjectedFault, InvalidOptions, TwinOptions, UnknownFault};
pub use pty::{PtyTwin, StartError};
pub use serve::{LinkServer, Pace, Served, serve};
pub use sim::Twin;
pub use truth::TruthLog;
