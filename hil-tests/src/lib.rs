//! The acceptance suite's target: the digital twin by default, a real board when the environment
//! variable `KERFMETER_PORT` names its serial port.
//!
//! Every case in `tests/` calls [`connect`] and runs unchanged against either; [`Target`] says
//! which one it got, so a case can print what it ran against.

use kerfmeter::sim::{SimDevice, SimOptions};
use kerfmeter::{Kerfmeter, Options};

/// Environment variable naming a real board's serial port.
pub const PORT_ENV: &str = "KERFMETER_PORT";

/// What a case runs against.
pub enum Target {
    /// The digital twin, in-process behind a pseudo-terminal (kept alive here).
    Twin(SimDevice),
    /// A real board on this serial port.
    Board(String),
}

impl Target {
    /// A short description for test output.
    pub fn describe(&self) -> String {
        match self {
            Target::Twin(sim) => format!("twin on {}", sim.path()),
            Target::Board(path) => format!("board on {path}"),
        }
    }
}

/// Connect to the board named by `KERFMETER_PORT`, or start a twin with `seed`.
pub fn connect(seed: u64) -> kerfmeter::Result<(Target, Kerfmeter)> {
    let options = Options::default();
    match std::env::var(PORT_ENV) {
        Ok(path) if !path.is_empty() => {
            let meter = Kerfmeter::open_with(&path, options)?;
            Ok((Target::Board(path), meter))
        }
        _ => {
            let (sim, meter) = SimDevice::connect(
                SimOptions {
                    seed,
                    ..SimOptions::default()
                },
                options,
            )?;
            Ok((Target::Twin(sim), meter))
        }
    }
}
