//! The simulated cutter (`sim`): the cutter twin ([`super::twin`]) served on a pseudo-terminal by
//! a thread of this process, driven through the same serial path as a real controller.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use super::twin::{CutterLog, CutterServer};
use kerfmeter_twin::Pace;

use super::driver::{ConnectOptions, Cutter};
use super::error::CutterError;
use super::transport::READ_SLICE;

/// How the simulated cutter is set up, and the faults injected into it.
pub use super::twin::CutterOptions as SimCutterOptions;

impl Cutter {
    /// Start a simulated cutter (lock-stepped: faster than real time) and connect to it.
    pub fn sim(twin: SimCutterOptions, options: ConnectOptions) -> Result<Self, CutterError> {
        Self::sim_cancellable(twin, options, Arc::new(AtomicBool::new(false)))
    }

    /// [`Cutter::sim`], its connect given up as soon as `cancel` is set (as
    /// [`Cutter::open_cancellable`]'s).
    pub fn sim_cancellable(
        twin: SimCutterOptions,
        options: ConnectOptions,
        cancel: Arc<AtomicBool>,
    ) -> Result<Self, CutterError> {
        let (server, mut port) =
            CutterServer::pty(twin, Pace::LockStep).map_err(|e| CutterError::Sim(e.to_string()))?;
        serialport::SerialPort::set_timeout(&mut port, READ_SLICE)
            .map_err(|e| CutterError::Sim(e.to_string()))?;
        let address = format!("sim ({})", server.address());
        let mut cutter = Self::connect_cancellable(Box::new(port), address, options, cancel)?;
        cutter.sim = Some(server);
        Ok(cutter)
    }

    /// The simulated cutter's record (what its laser traced, protocol violations); `None` for a
    /// real controller.
    pub fn sim_log(&self) -> Option<&CutterLog> {
        self.sim.as_ref().map(CutterServer::log)
    }
}
