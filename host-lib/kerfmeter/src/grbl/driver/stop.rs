//! Stopping the cutter: feed hold, waited for as long as the machine's rates and accelerations
//! say, then soft reset, sent again until the banner comes; and the error that says whether it
//! worked.

use std::time::{Duration, Instant};

use super::super::error::CutterError;
use super::super::protocol::{MachineState, Reply, parse_reply};
use super::super::transport::READ_SLICE;
use super::{Cutter, SOFT_RESET};
use kerfmeter_grbl::codes::ALARM_ABORT_CYCLE;
use kerfmeter_grbl::realtime;
use kerfmeter_grbl::settings::{ACCELERATION_MM_PER_S2, MAX_RATE_MM_PER_MIN};

/// `$110`, `$111`: the X and Y maximum rates, mm/min.
const MAX_RATE_SETTINGS: [u16; 2] = [MAX_RATE_MM_PER_MIN[0], MAX_RATE_MM_PER_MIN[1]];
/// `$120`, `$121`: the X and Y accelerations, mm/s².
const ACCELERATION_SETTINGS: [u16; 2] = [ACCELERATION_MM_PER_S2[0], ACCELERATION_MM_PER_S2[1]];
/// The longest a feed hold is waited for, whatever the settings say.
const HOLD_WAIT_MAX: Duration = Duration::from_secs(60);
/// How long one soft reset is given to bring the banner before it is sent again.
const RESET_RETRY: Duration = Duration::from_millis(500);

impl Cutter {
    /// Stop the cutter: feed hold (`!`) so that the machine decelerates and keeps its position,
    /// wait (bounded by its fastest rate over its slowest acceleration) for the hold to
    /// complete, then soft reset (ctrl-X), which empties its queue and turns the laser off.
    /// Waits for the reset's banner. A failed write of the hold or a status request does not
    /// keep the reset from being tried; the reset is sent again until its banner comes.
    pub fn stop(&mut self) -> Result<(), CutterError> {
        self.halt().map(|_| ())
    }

    /// [`Cutter::stop`]; true when the reset raised `ALARM:3` (the machine still moved).
    fn halt(&mut self) -> Result<bool, CutterError> {
        let _ = self.write(&[realtime::FEED_HOLD]);
        let deadline = Instant::now() + self.hold_wait();
        // A status request that cannot be written goes straight to the reset, which is tried
        // again until the reply timeout.
        while Instant::now() < deadline && self.poll_stopped(deadline) == Some(false) {}
        self.reset_checked()
    }

    /// One status request while holding: true once the machine reports it has stopped; `None`
    /// when the request cannot be written.
    fn poll_stopped(&mut self, deadline: Instant) -> Option<bool> {
        self.write(&[realtime::STATUS_REPORT]).ok()?;
        let poll_end = (Instant::now() + Duration::from_millis(50)).min(deadline);
        let mut stopped = false;
        while let Ok(Some(line)) = self.read_line(poll_end) {
            if let Reply::Status(s) = parse_reply(&line) {
                stopped = matches!(
                    s.state,
                    MachineState::Hold(0)
                        | MachineState::Door(0 | 1)
                        | MachineState::Idle
                        | MachineState::Alarm
                        | MachineState::Sleep
                );
            }
        }
        Some(stopped)
    }

    /// How long a feed hold may take: the fastest rate over the slowest acceleration of X and Y
    /// (`$110`, `$111`, `$120`, `$121`), with margin, plus a reply's time.
    fn hold_wait(&self) -> Duration {
        let setting = |numbers: [u16; 2], pick: fn(f64, f64) -> f64| {
            numbers
                .iter()
                .filter_map(|n| self.settings.get(n).copied())
                .filter(|v| v.is_finite() && *v > 0.0)
                .reduce(pick)
        };
        let stopping_s = match (
            setting(MAX_RATE_SETTINGS, f64::max),
            setting(ACCELERATION_SETTINGS, f64::min),
        ) {
            (Some(rate_mm_per_min), Some(accel)) => 1.5 * rate_mm_per_min / 60.0 / accel,
            _ => 0.0,
        };
        let stopping = Duration::try_from_secs_f64(stopping_s).unwrap_or(HOLD_WAIT_MAX);
        (self.options.reply_timeout + stopping).min(HOLD_WAIT_MAX)
    }

    /// Soft reset (ctrl-X) and wait for the banner: the queue is emptied, the laser off. A
    /// machine in motion raises `ALARM:3` (its position may be lost); [`Cutter::stop`] holds
    /// first to avoid that.
    pub fn reset(&mut self) -> Result<(), CutterError> {
        self.reset_checked().map(|_| ())
    }

    /// [`Cutter::reset`], sent again until its banner comes within the reply timeout; true when
    /// `ALARM:3` came with it.
    fn reset_checked(&mut self) -> Result<bool, CutterError> {
        let deadline = Instant::now() + self.options.reply_timeout;
        let mut seen = Vec::new();
        loop {
            let write_error = self.write(&[SOFT_RESET]).err();
            let wait = RESET_RETRY.min(deadline.saturating_duration_since(Instant::now()));
            if write_error.is_none() && self.await_banner(wait, &mut seen)? {
                return Ok(self.alarm_before_banner == Some(ALARM_ABORT_CYCLE));
            }
            if Instant::now() >= deadline {
                return Err(write_error
                    .unwrap_or_else(|| self.silent("waiting for the banner after a soft reset")));
            }
            if write_error.is_some() {
                std::thread::sleep(READ_SLICE);
            }
        }
    }

    /// `cause`, after stopping the cutter: [`CutterError::Stopped`] around it, or
    /// [`CutterError::NotStopped`] when it cannot be stopped. After an alarm the machine has
    /// stopped already and may hear nothing but a reset.
    pub(crate) fn stop_after(&mut self, cause: CutterError) -> CutterError {
        let stopped = match cause {
            CutterError::Alarm { .. } => self.reset_checked(),
            _ => self.halt(),
        };
        match stopped {
            Ok(position_lost) => CutterError::Stopped {
                cause: Box::new(cause),
                position_lost,
            },
            Err(stop) => CutterError::NotStopped {
                cause: Box::new(cause),
                stop: Box::new(stop),
            },
        }
    }
}
