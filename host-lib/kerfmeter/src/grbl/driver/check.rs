//! The check pass before a job (GRBL's check mode, `$C`: every line parsed and answered, nothing
//! moving), and the confirmation after it that the laser is off.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use super::super::error::CutterError;
use super::super::protocol::{ProgramLine, Reply, Streamer, parse_reply};
use super::{CLOSING_LINE, Cutter, StreamProgress};
use kerfmeter_grbl::commands;

impl Cutter {
    /// The check pass: the program through check mode (`$C`), where GRBL parses and answers
    /// every line and moves nothing; the first refused line is
    /// [`CutterError::CheckRejected`]. Check mode is left (`$C` again: a soft reset) whatever
    /// happened.
    pub(super) fn check_program(
        &mut self,
        lines: &[ProgramLine],
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<(), CutterError> {
        self.command(commands::CHECK_MODE)?;
        let refused = self.check_lines(lines, cancel, progress);
        let left = self.leave_check_mode();
        match (refused?, left) {
            (Some((line, text, code)), _) => Err(CutterError::CheckRejected { line, text, code }),
            (None, left) => left,
        }
    }

    /// Stream `lines` in check mode by character counting; the first refused line, if any.
    fn check_lines(
        &mut self,
        lines: &[ProgramLine],
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<Option<(usize, String, u8)>, CutterError> {
        let mut streamer = Streamer::with_window(lines.to_vec(), self.window);
        let mut refused = None;
        let mut last_heard = Instant::now();
        while !streamer.done() {
            if cancel.load(Ordering::Relaxed) {
                let total = streamer.total().saturating_sub(1);
                return Err(CutterError::Cancelled { answered: 0, total });
            }
            while let Some(bytes) = streamer.next_to_send() {
                self.write(&bytes)?;
            }
            let replies = self.read_available()?;
            if !replies.is_empty() {
                last_heard = Instant::now();
            }
            for reply in replies {
                let unexpected = || CutterError::Protocol(format!("`{reply}` answered no line"));
                match parse_reply(&reply) {
                    Reply::Ok => {
                        streamer.answer().map_err(|_| unexpected())?;
                    }
                    Reply::Error(code) => {
                        let line = streamer.answer().map_err(|_| unexpected())?;
                        refused.get_or_insert((line.number, line.written.clone(), code));
                    }
                    Reply::Alarm(code) => {
                        return Err(CutterError::Alarm {
                            code,
                            after: None,
                            last_position_mm: None,
                        });
                    }
                    Reply::Banner(_) => return Err(CutterError::Restarted),
                    _ => {}
                }
            }
            progress(&StreamProgress::of(&streamer, None, true));
            if last_heard.elapsed() > self.options.silence_timeout {
                return Err(self.silent_for("checking the program", self.options.silence_timeout));
            }
        }
        Ok(refused)
    }

    /// `$C` again: GRBL answers `ok`, then resets (its banner).
    fn leave_check_mode(&mut self) -> Result<(), CutterError> {
        self.command(commands::CHECK_MODE)?;
        let mut seen = Vec::new();
        if self.await_banner(self.options.reply_timeout, &mut seen)? {
            Ok(())
        } else {
            Err(self.silent("waiting for the reset that leaves check mode"))
        }
    }

    /// After the closing `M5`: the parser state must say M5 and the status spindle 0.
    pub(super) fn confirm_laser_off(&mut self) -> Result<(), CutterError> {
        let said = self.command(commands::PARSER_STATE)?;
        let parser_state = said.iter().find(|l| l.starts_with("[GC:"));
        let m5 = parser_state.is_some_and(|gc| {
            gc.trim_end_matches(']')
                .split([' ', ':'])
                .any(|word| word == CLOSING_LINE)
        });
        if !m5 {
            return Err(CutterError::LaserNotOff {
                said: parser_state.map_or_else(
                    || "no `[GC:...]` parser state came for `$G`".into(),
                    |gc| format!("its parser state is {gc}"),
                ),
            });
        }
        let status = self.status()?;
        match status.spindle_s {
            Some(s) if s > 0.0 => Err(CutterError::LaserNotOff {
                said: format!("its status reports the spindle at S{s}"),
            }),
            _ => Ok(()),
        }
    }
}
