//! The `--sim` device: the firmware's digital twin (real firmware, fake peripherals, physics),
//! run in a thread of this process and served on a pseudo-terminal, so that the client talks to
//! it through a real serial port exactly as it talks to hardware.
//!
//! By default simulated time runs in lock-step with the host (far faster than real time, never
//! more than 100 ms ahead of the host's last request); [`SimOptions::realtime`] makes it follow
//! the wall clock instead.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use kerfmeter_twin::{InjectedFault, Pace, Twin, TwinOptions};
use serialport::{SerialPort, TTYPort};

use crate::client::{Kerfmeter, Options};
use crate::error::{Error, Result};

pub use kerfmeter_twin::InjectedFault as SimFault;

/// How the simulated device is set up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimOptions {
    /// True kerf of the gauges the simulated cutter cuts, µm.
    pub kerf_um: f64,
    /// Gauge-to-gauge standard deviation of the simulated cutter's kerf, µm.
    pub kerf_sd_um: f64,
    /// Seed of every random number: the same seed gives the same run.
    pub seed: u64,
    /// A fault to inject.
    pub fault: Option<InjectedFault>,
    /// Follow the wall clock instead of running ahead in lock-step.
    pub realtime: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        Self {
            kerf_um: 150.0,
            kerf_sd_um: 0.0,
            seed: 1,
            fault: None,
            realtime: false,
        }
    }
}

impl SimOptions {
    /// Check the options.
    pub fn validate(&self) -> Result<()> {
        if !(0.0..=2000.0).contains(&self.kerf_um) {
            return Err(Error::InvalidArgument(format!(
                "simulated kerf must be between 0 and 2000 µm, got {}",
                self.kerf_um
            )));
        }
        if !(0.0..=200.0).contains(&self.kerf_sd_um) {
            return Err(Error::InvalidArgument(format!(
                "simulated kerf spread must be between 0 and 200 µm, got {}",
                self.kerf_sd_um
            )));
        }
        Ok(())
    }

    fn twin_options(&self) -> TwinOptions {
        TwinOptions {
            kerf_um: self.kerf_um,
            kerf_sd_um: self.kerf_sd_um,
            seed: self.seed,
            fault: self.fault,
            ..TwinOptions::default()
        }
    }
}

/// A running simulated device. Dropping it stops the twin.
pub struct SimDevice {
    options: SimOptions,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    path: String,
}

impl SimDevice {
    /// Start the twin on a new pseudo-terminal; returns it and the client side of the terminal.
    pub fn start(options: SimOptions) -> Result<(Self, Box<dyn SerialPort>)> {
        options.validate()?;
        let (mut master, slave) = TTYPort::pair().map_err(|e| Error::Sim(e.to_string()))?;
        master
            .set_timeout(Duration::from_millis(1))
            .map_err(|e| Error::Sim(e.to_string()))?;
        let path = slave.name().unwrap_or_else(|| "<pty>".into());
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let stop = stop.clone();
            let pace = if options.realtime {
                Pace::RealTime
            } else {
                Pace::LockStep
            };
            std::thread::Builder::new()
                .name("kerfmeter-twin".into())
                .spawn(move || {
                    let mut twin = Twin::new(options.twin_options());
                    // The twin ends when the client closes its side; an I/O error there has no
                    // one to be reported to but the client, which sees the port vanish.
                    let _ = kerfmeter_twin::serve_twin(&mut master, &mut twin, &stop, pace);
                })
                .map_err(|e| Error::Sim(e.to_string()))?
        };
        Ok((
            Self {
                options,
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

    /// What an ideal device reads on this twin's gauge (with no cutter spread) for a jam at
    /// `torque_nm`: the geometric kerf plus the spiral contact's compression at that torque.
    pub fn ideal_reading_um(&self, torque_nm: f32) -> f64 {
        kerfmeter_twin::plant::Plant::new(
            kerfmeter_twin::plant::PlantParams::default(),
            kerfmeter_protocol::GaugeGeometry::PAPER,
            self.options.kerf_um,
        )
        .kerf_at_torque_um(f64::from(torque_nm))
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
