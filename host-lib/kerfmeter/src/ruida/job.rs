//! The Ruida driver as the job loop's cutter.

use std::sync::atomic::AtomicBool;

use super::RuidaCutter;
use crate::grbl::travel::Travel;
use crate::grbl::{CutterError, StreamProgress, StreamReport};
use crate::job::{HeadState, HeadStatus, JobCutter};

/// A Ruida controller, through its driver.
impl JobCutter for RuidaCutter {
    fn travel(&self) -> Option<Travel> {
        Some(RuidaCutter::travel(self))
    }

    fn status(&mut self) -> Result<HeadStatus, CutterError> {
        let status = self.machine_status("reading its status")?;
        let state = if status.is_busy() {
            HeadState::Busy(format!("busy (status {:#x})", status.0))
        } else {
            HeadState::Idle
        };
        Ok(HeadStatus {
            state,
            machine_mm: Some(self.head_mm()?),
            work_mm: None,
        })
    }

    fn stream(
        &mut self,
        program: &str,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError> {
        RuidaCutter::stream(self, program, cancel, progress)
    }

    fn stop(&mut self) -> Result<(), CutterError> {
        RuidaCutter::stop(self)
    }

    fn stop_after(&mut self, cause: CutterError) -> CutterError {
        RuidaCutter::stop_after(self, cause)
    }

    #[cfg(feature = "sim")]
    fn traced_segments(&self) -> Option<Vec<kerfmeter_twin::traced::Segment>> {
        RuidaCutter::traced_segments(self)
    }
}
