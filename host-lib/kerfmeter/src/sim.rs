//! The `--sim` device: the firmware's digital twin (real firmware, fake peripherals, physics),
//! run in a thread of this process and served on a pseudo-terminal, so that the client talks to
//! it through a real serial port exactly as it talks to hardware.
//!
//! By default simulated time runs in lock-step with the host (far faster than real time, never
//! more than 100 ms ahead of the host's last request); [`SimOptions::realtime`] makes it follow
//! the wall clock instead.

use kerfmeter_twin::plant::CutterKerf;
use kerfmeter_twin::traced::Segment;
use kerfmeter_twin::{PtyTwin, StartError};
use serialport::SerialPort;

use crate::client::{Kerfmeter, Options};
use crate::error::{Error, Result};

pub use kerfmeter_twin::InjectedFault as SimFault;
/// How the simulated device is set up: the twin's own options.
pub use kerfmeter_twin::TwinOptions as SimOptions;
/// The twin's physics: every parameter, its range and source ([`kerfmeter_twin::plant::PARAMS`]).
pub use kerfmeter_twin::plant::{Material as SimMaterial, PlantParamError, PlantParams};

/// A running simulated device. Dropping it stops the twin.
pub struct SimDevice {
    /// Boxed: a device is moved around more often than it is asked for its options.
    options: Box<SimOptions>,
    twin: PtyTwin,
}

impl SimDevice {
    /// Start the twin on a new pseudo-terminal; returns it and the client side of the terminal.
    pub fn start(options: SimOptions) -> Result<(Self, Box<dyn SerialPort>)> {
        let (twin, port) = PtyTwin::start(options).map_err(|e| match e {
            StartError::Options(e) => Error::invalid(e.to_string()),
            e => Error::Sim(e.to_string()),
        })?;
        let options = Box::new(options);
        Ok((Self { options, twin }, Box::new(port)))
    }

    /// Start the twin and connect a client to it.
    pub fn connect(options: SimOptions, client: Options) -> Result<(Self, Kerfmeter)> {
        let (sim, port) = Self::start(options)?;
        let meter = Kerfmeter::from_port(port, client)?;
        Ok((sim, meter))
    }

    /// The truth of run `run_id`: what an ideal device reads on the gauge the twin placed for it,
    /// at the force the run asked for, µm (computed from the twin's physics, not from the
    /// device's report). `None` for a run this twin did not start since its last reboot.
    pub fn truth_um(&self, run_id: u32) -> Option<f64> {
        self.twin.truths().truth_um(run_id)
    }

    /// The options the twin was started with.
    pub fn options(&self) -> &SimOptions {
        &self.options
    }

    /// The gauge a simulated cutter's laser traced around `at_mm` (`segments`, from
    /// [`Cutter::sim_log`](crate::grbl::Cutter::sim_log)) goes under the prongs, which came down
    /// over `at_mm`: the following runs measure it, cut with `kerf` (the cutter twin's kerf
    /// model; `None`: this twin's own). The gauge's kerf, or why no measurable gauge was cut
    /// there.
    pub fn place_traced_gauge(
        &self,
        segments: &[Segment],
        at_mm: [f64; 2],
        kerf: Option<CutterKerf>,
    ) -> Result<f64> {
        let cutter = kerf
            .map(|k| k.cutter(self.options.plant, self.options.seed))
            .transpose()
            .map_err(|e| Error::invalid(e.to_string()))?;
        let cut = self
            .twin
            .place_traced_gauge(segments, at_mm, cutter.as_ref())
            .map_err(|e| Error::Sim(format!("the traced gauge cannot be measured: {e}")))?;
        Ok(cut.kerf_um)
    }

    /// Path of the pseudo-terminal's client side.
    pub fn path(&self) -> &str {
        self.twin.path()
    }
}
