//! What the loop needs of a laser cutter, whatever its controller: [`JobCutter`]. The loop knows
//! nothing of GRBL; the GRBL driver ([`crate::grbl::Cutter`], below) and the Ruida driver
//! ([`crate::ruida::RuidaCutter`]) implement it. Both take the program as the G-code Kerfmeter
//! writes: GRBL streams it, the Ruida driver reads it into cut programs and direct moves
//! ([`crate::ruida::steps`]), so that the loop and its travel checks read one program text.
//!
//! The contract each implementation keeps, on which the loop's safety rests:
//!
//! - [`JobCutter::stream`] runs a whole program and returns once the machine has finished it,
//!   at rest with its laser confirmed off; on any failure after it began sending, it has stopped
//!   the cutter itself (laser off) and says how that went ([`CutterError::Stopped`],
//!   [`CutterError::NotStopped`]); a refusal before anything was sent stops nothing.
//! - [`JobCutter::stop`] and [`JobCutter::stop_after`] stop the machine now (motion and laser)
//!   and say whether that worked.
//! - [`JobCutter::status`] reads where the head stands and whether the machine is at rest.
//! - [`JobCutter::travel`] is the machine's travel as read at connect, when the controller
//!   reports one; the loop checks every planned move against it before anything moves.
//!
//! Connecting, unlocking and a controller's own settings (laser mode, its `S` of full power) are
//! the driver's, checked before the loop begins.

use std::sync::atomic::AtomicBool;

use crate::grbl::protocol::{MachineState, Status};
use crate::grbl::travel::Travel;
use crate::grbl::{Cutter, CutterError, StreamProgress, StreamReport};

/// What the machine is doing, as far as the loop cares.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum HeadState {
    /// At rest, ready for the next program.
    Idle,
    /// Stopped by an alarm: nothing more moves until someone clears it.
    Alarm,
    /// Anything else (moving, holding, a door open), as the controller names it.
    Busy(String),
}

/// Where the head stands and what the machine is doing.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadStatus {
    /// What the machine is doing.
    pub state: HeadState,
    /// The head's machine position, mm, when the controller reports it.
    pub machine_mm: Option<[f64; 3]>,
    /// The head's work position, mm, when the controller reports it instead.
    pub work_mm: Option<[f64; 3]>,
}

/// A laser cutter as the job loop drives it (see the [module docs](self)).
pub trait JobCutter {
    /// The machine's travel as read at connect (`None` when the controller reports none).
    fn travel(&self) -> Option<Travel>;

    /// Where the head stands and what the machine is doing now.
    fn status(&mut self) -> Result<HeadStatus, CutterError>;

    /// Run `program` to its end, laser off at the end; `cancel` stops it (and the cutter);
    /// `progress` hears how far it got. On a failure after sending began, the cutter has been
    /// stopped and the error says how that went.
    fn stream(
        &mut self,
        program: &str,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError>;

    /// Stop the machine now: motion and laser.
    fn stop(&mut self) -> Result<(), CutterError>;

    /// Stop the machine after `cause`; the error as the user is to be told it, with how the
    /// stop went.
    fn stop_after(&mut self, cause: CutterError) -> CutterError;

    /// With `sim`: what a simulated cutter's laser traced since it started (the device twin
    /// measures the gauge it cut); `None` for a real machine.
    #[cfg(feature = "sim")]
    fn traced_segments(&self) -> Option<Vec<kerfmeter_twin::traced::Segment>> {
        None
    }
}

impl From<Status> for HeadStatus {
    fn from(status: Status) -> Self {
        let state = match status.state {
            MachineState::Idle => HeadState::Idle,
            MachineState::Alarm => HeadState::Alarm,
            other => HeadState::Busy(other.to_string()),
        };
        Self {
            state,
            machine_mm: status.position_mm,
            work_mm: status.work_position_mm,
        }
    }
}

/// GRBL 1.1, through its driver.
impl JobCutter for Cutter {
    fn travel(&self) -> Option<Travel> {
        Cutter::travel(self)
    }

    fn status(&mut self) -> Result<HeadStatus, CutterError> {
        Cutter::status(self).map(HeadStatus::from)
    }

    fn stream(
        &mut self,
        program: &str,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError> {
        Cutter::stream(self, program, cancel, progress)
    }

    fn stop(&mut self) -> Result<(), CutterError> {
        Cutter::stop(self)
    }

    fn stop_after(&mut self, cause: CutterError) -> CutterError {
        Cutter::stop_after(self, cause)
    }

    #[cfg(feature = "sim")]
    fn traced_segments(&self) -> Option<Vec<kerfmeter_twin::traced::Segment>> {
        self.sim_log().map(|log| log.snapshot().segments)
    }
}
