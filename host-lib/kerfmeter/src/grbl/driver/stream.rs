//! Streaming a program: refused before sending when it cannot be streamed or leaves the travel,
//! checked first (`$C`), then sent with character counting, the state polled, a hold watched,
//! and every failure stopped.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use kerfmeter_grbl::realtime;

use super::super::error::CutterError;
use super::super::protocol::{
    MachineState, ProgramLine, Reply, Status, Streamer, parse_reply, prepare,
};
use super::{CLOSING_LINE, Cutter, StreamProgress, StreamReport};

impl Cutter {
    /// Stream a G-code program: at most 128 bytes unanswered, the state polled, until every line
    /// is accepted and the machine is idle again. `progress` hears of each batch of replies.
    ///
    /// The program is always closed with an `M5` of the driver's own (numbered one past the
    /// program's last line), and the stream succeeds only once the controller confirms the laser
    /// off (`M5` in its `$G` parser state, spindle 0 in its status): under M3 GRBL keeps the beam
    /// on at rest after a cut until M5.
    ///
    /// On any failure (a refused line, an alarm, silence, `cancel` set, the laser not confirmed
    /// off) the cutter is stopped ([`Cutter::stop`]: feed hold, then soft reset, which turns the
    /// laser off) and the error is [`CutterError::Stopped`] around the failure, or
    /// [`CutterError::NotStopped`] when even stopping failed. A program with a line that cannot
    /// be streamed is refused before anything is sent.
    pub fn stream(
        &mut self,
        program: &str,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError> {
        self.check_s_max(program)?;
        let lines = prepare(program).map_err(|bad| CutterError::BadProgram {
            line: bad.number,
            reason: bad.reason,
        })?;
        self.stream_prepared(lines, cancel, progress)
    }

    /// [`Cutter::stream`] for a program already cleaned by [`prepare`] (a caller that checked
    /// it before connecting need not clean it twice); the caller checks the raw program with
    /// [`Cutter::check_s_max`] first, since cleaning drops its header. The closing `M5` is numbered one past the
    /// last line.
    pub fn stream_prepared(
        &mut self,
        mut lines: Vec<ProgramLine>,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError> {
        self.check_travel(&lines)?;
        let program_lines = lines.len();
        lines.push(ProgramLine {
            number: lines.last().map_or(1, |l| l.number + 1),
            text: CLOSING_LINE.into(),
            written: CLOSING_LINE.into(),
        });
        self.in_job = true;
        let checked = match self.options.check_first {
            true => self.check_program(&lines, cancel, progress),
            false => Ok(()),
        };
        let mut streamer = Streamer::with_window(lines, self.window);
        let result = checked
            .and_then(|()| self.stream_lines(&mut streamer, cancel, progress))
            .and_then(|report| self.confirm_laser_off().map(|()| report));
        let result = result
            .map(|report| StreamReport {
                lines: program_lines,
                ..report
            })
            .map_err(|e| match e {
                CutterError::Cancelled { answered, .. } => CutterError::Cancelled {
                    answered: answered.min(program_lines),
                    total: program_lines,
                },
                other => other,
            })
            .map_err(|e| self.tagged(e))
            .map_err(|e| self.stop_after(e));
        self.in_job = false;
        result
    }

    pub(super) fn stream_lines(
        &mut self,
        streamer: &mut Streamer,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError> {
        let started = Instant::now();
        let mut last_poll: Option<Instant> = None;
        let mut last_heard = Instant::now();
        let mut max_unanswered_bytes = 0;
        let mut idle_reports_after_done = 0;
        let mut status = None;
        let mut held_since = None;
        loop {
            if cancel.load(Ordering::Relaxed) {
                return Err(CutterError::Cancelled {
                    answered: streamer.answered(),
                    total: streamer.total(),
                });
            }
            let unanswered_bytes = self.send_ready(streamer, &mut last_poll)?;
            max_unanswered_bytes = max_unanswered_bytes.max(unanswered_bytes);
            let lines = self.read_available()?;
            if !lines.is_empty() {
                last_heard = Instant::now();
            }
            for line in lines {
                let reply = self.stream_reply(streamer, &line);
                let Some(s) = reply.map_err(|e| located(e, status.as_ref()))? else {
                    continue;
                };
                // Idle twice after the last `ok`: the first report may predate the last block's
                // start by a moment.
                let idle = s.state == MachineState::Idle;
                idle_reports_after_done = if streamer.done() && idle {
                    idle_reports_after_done + 1
                } else {
                    0
                };
                if matches!(s.state, MachineState::Alarm | MachineState::Sleep) {
                    return Err(CutterError::StoppedItself {
                        state: s.state.to_string(),
                        after: streamer
                            .last_answered()
                            .map(|l| (l.number, l.written.clone())),
                    });
                }
                status = Some(s);
            }
            progress(&StreamProgress::of(streamer, status.clone(), false));
            if idle_reports_after_done >= 2 {
                return Ok(StreamReport {
                    lines: streamer.total(),
                    elapsed: started.elapsed(),
                    max_unanswered_bytes,
                    position_mm: status.and_then(|s| s.position_mm),
                });
            }
            if last_heard.elapsed() > self.options.silence_timeout {
                return Err(self.silent_for("streaming", self.options.silence_timeout));
            }
            self.check_hold(status.as_ref(), &mut held_since)?;
        }
    }

    /// A machine held (feed hold, door) for longer than [`ConnectOptions::hold_timeout`] is
    /// [`CutterError::HeldTooLong`]; `held_since` tracks when the hold began.
    pub(super) fn check_hold(
        &self,
        status: Option<&Status>,
        held_since: &mut Option<Instant>,
    ) -> Result<(), CutterError> {
        let held = status
            .map(|s| &s.state)
            .filter(|state| matches!(state, MachineState::Hold(_) | MachineState::Door(_)));
        let (Some(state), Some(limit)) = (held, self.options.hold_timeout) else {
            *held_since = None;
            return Ok(());
        };
        let since = *held_since.get_or_insert_with(Instant::now);
        if since.elapsed() > limit {
            return Err(CutterError::HeldTooLong {
                state: state.to_string(),
                waited_ms: limit.as_millis() as u64,
            });
        }
        Ok(())
    }

    /// Send every line that fits, and a status request when one is due; the bytes unanswered.
    pub(super) fn send_ready(
        &mut self,
        streamer: &mut Streamer,
        last_poll: &mut Option<Instant>,
    ) -> Result<usize, CutterError> {
        while let Some(bytes) = streamer.next_to_send() {
            self.write(&bytes)?;
        }
        if last_poll.is_none_or(|t| t.elapsed() >= self.options.poll_interval) {
            self.write(&[realtime::STATUS_REPORT])?;
            *last_poll = Some(Instant::now());
        }
        Ok(streamer.unanswered_bytes())
    }

    /// Act on one reply while streaming; a status report is returned.
    pub(super) fn stream_reply(
        &mut self,
        streamer: &mut Streamer,
        line: &str,
    ) -> Result<Option<Status>, CutterError> {
        let unexpected = |what: &str| CutterError::Protocol(format!("{what} answered no line"));
        match parse_reply(line) {
            Reply::Ok => {
                streamer.answer().map_err(|_| unexpected("an `ok`"))?;
            }
            Reply::Error(code) => {
                let refused = streamer.answer().map_err(|_| unexpected("an `error`"))?;
                return Err(CutterError::Rejected {
                    line: refused.number,
                    text: refused.written.clone(),
                    code,
                });
            }
            Reply::Alarm(code) => {
                let after = streamer
                    .last_answered()
                    .map(|l| (l.number, l.written.clone()));
                return Err(CutterError::Alarm {
                    code,
                    after,
                    last_position_mm: None,
                });
            }
            Reply::Banner(_) => return Err(CutterError::Restarted),
            Reply::Status(status) => return Ok(Some(self.in_mm(status))),
            Reply::Message(_) | Reply::Setting(..) | Reply::Other(_) => {}
        }
        Ok(None)
    }
}

/// An alarm with the head's position from the last status report before it.
fn located(error: CutterError, status: Option<&Status>) -> CutterError {
    match error {
        CutterError::Alarm { code, after, .. } => CutterError::Alarm {
            code,
            after,
            last_position_mm: status.and_then(|s| s.position_mm),
        },
        other => other,
    }
}
