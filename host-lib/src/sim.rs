//! The `--sim` device: the firmware's digital twin, run in a thread of this process and served on
//! a pseudo-terminal, so that the client talks to it through a real serial port exactly as it
//! talks to hardware.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use kerfmeter_firmware::device::Device;
use serialport::{SerialPort, TTYPort};

use crate::client::{Kerfmeter, Options};
use crate::error::{Error, Result};

/// How the simulated device is set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimOptions {
    /// Seed of the twin's random numbers (its boot id, and later its noise).
    pub seed: u64,
}

/// A running simulated device. Dropping it stops the twin.
pub struct SimDevice {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    path: String,
}

impl SimDevice {
    /// Start the twin on a new pseudo-terminal; returns it and the client side of the terminal.
    pub fn start(options: SimOptions) -> Result<(Self, Box<dyn SerialPort>)> {
        let (mut master, slave) = TTYPort::pair().map_err(|e| Error::Sim(e.to_string()))?;
        master
            .set_timeout(Duration::from_millis(20))
            .map_err(|e| Error::Sim(e.to_string()))?;
        let path = slave.name().unwrap_or_else(|| "<pty>".into());
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            let boot_id = boot_id(options.seed);
            std::thread::Builder::new()
                .name("kerfmeter-twin".into())
                .spawn(move || {
                    let mut device = Device::new("twin", boot_id);
                    // The twin ends when the client closes its side; an I/O error there has no
                    // one to be reported to but the client, which sees the port vanish.
                    let _ = kerfmeter_firmware::twin::serve(&mut master, &mut device, &stop);
                })
                .map_err(|e| Error::Sim(e.to_string()))?
        };
        Ok((
            Self {
                stop,
                thread: Some(thread),
                path,
            },
            Box::new(slave),
        ))
    }

    /// Start the twin and connect a client to it.
    pub fn connect(options: SimOptions, client: Options) -> Result<(Self, Kerfmeter)> {
        let (sim, port) = Self::start(options)?;
        let meter = Kerfmeter::from_port(port, client)?;
        Ok((sim, meter))
    }

    /// Path of the pseudo-terminal's client side.
    pub fn path(&self) -> &str {
        &self.path
    }
}

impl Drop for SimDevice {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A boot id derived from the seed (splitmix64), so a seeded twin is reproducible.
fn boot_id(seed: u64) -> u32 {
    let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as u32
}
