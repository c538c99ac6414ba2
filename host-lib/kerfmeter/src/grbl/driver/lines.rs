//! The byte stream as GRBL's lines: writing, reading lines (notes and noise kept apart),
//! a command and its answer, a status report in mm, and the silence errors.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use kerfmeter_grbl::settings::REPORT_INCHES;
use kerfmeter_grbl::{codes, realtime};

use super::super::error::CutterError;
use super::super::protocol::{Reply, Status, parse_reply};
use super::{COMMAND_WAIT_MAX_REPLIES, Cutter, INCOMING_MAX, NOTES_KEPT};

impl Cutter {
    /// Ask for a status report and wait for it.
    ///
    /// A banner instead (a late one, or a restart: GRBL forgets a pending `?` when it resets)
    /// makes it ask once more; a second banner is [`CutterError::Restarted`].
    pub fn status(&mut self) -> Result<Status, CutterError> {
        for attempt in 0..2 {
            self.write(&[realtime::STATUS_REPORT])?;
            let deadline = Instant::now() + self.options.reply_timeout;
            while let Some(line) = self.read_line(deadline)? {
                match parse_reply(&line) {
                    Reply::Status(status) => return Ok(self.in_mm(status)),
                    Reply::Banner(_) if attempt > 0 => return Err(CutterError::Restarted),
                    Reply::Banner(version) => {
                        self.version = version;
                        break;
                    }
                    Reply::Alarm(_) | Reply::Message(_) => self.note(line),
                    _ => {}
                }
            }
        }
        Err(self.silent("waiting for a status report"))
    }

    /// `status` with its position and feed in mm, when the controller reports inches (`$13=1`).
    pub(super) fn in_mm(&self, mut status: Status) -> Status {
        if self.settings.get(&REPORT_INCHES) == Some(&1.0) {
            const MM_PER_INCH: f64 = 25.4;
            status.position_mm = status.position_mm.map(|p| p.map(|v| v * MM_PER_INCH));
            status.work_position_mm = status.work_position_mm.map(|p| p.map(|v| v * MM_PER_INCH));
            status.feed_mm_per_min = status.feed_mm_per_min.map(|f| f * MM_PER_INCH);
        }
        status
    }

    /// Send one command line of the driver's own (a `$` command: nothing else may be
    /// unanswered) and wait for its `ok`; the lines that came before it. Private: a motion line
    /// would return with the machine still moving, and `?`/`!` in the text would act at once.
    ///
    /// A banner instead (the controller restarted and lost the line) sends it once more: the
    /// driver's commands do the same when repeated.
    pub(super) fn command(&mut self, line: &str) -> Result<Vec<String>, CutterError> {
        self.write(format!("{line}\n").as_bytes())?;
        let mut deadline = Instant::now() + self.options.reply_timeout;
        let latest = Instant::now() + COMMAND_WAIT_MAX_REPLIES * self.options.reply_timeout;
        let mut said = Vec::new();
        let mut resent = false;
        while let Some(reply) = self.read_line(deadline)? {
            match parse_reply(&reply) {
                Reply::Ok => return Ok(said),
                Reply::Banner(_) if resent => return Err(CutterError::Restarted),
                Reply::Banner(_) => {
                    resent = true;
                    said.clear();
                    self.write(format!("{line}\n").as_bytes())?;
                    deadline = Instant::now() + self.options.reply_timeout;
                }
                Reply::Error(code) => {
                    return Err(CutterError::Protocol(format!(
                        "`{line}` was refused with error:{code}: {}",
                        codes::describe_error(code)
                    )));
                }
                Reply::Alarm(code) if !self.in_job => {
                    return Err(CutterError::AlarmAtConnect {
                        code: Some(code),
                        reason: codes::describe_alarm(code).to_owned(),
                    });
                }
                Reply::Alarm(code) => {
                    return Err(CutterError::Alarm {
                        code,
                        after: None,
                        last_position_mm: None,
                    });
                }
                _ => {
                    // A long answer (`$$` on grblHAL is over 150 lines) is waited for while it
                    // comes, within bounds.
                    deadline =
                        deadline.max((Instant::now() + self.options.reply_timeout).min(latest));
                    said.push(reply);
                }
            }
        }
        Err(self.silent("waiting for a command's `ok`"))
    }

    /// The controller said nothing for the reply timeout while the driver was `doing`.
    pub(super) fn silent(&self, doing: &'static str) -> CutterError {
        self.silent_for(doing, self.options.reply_timeout)
    }

    pub(super) fn silent_for(&self, doing: &'static str, waited: Duration) -> CutterError {
        CutterError::Silent {
            address: self.address.clone(),
            waited_ms: waited.as_millis() as u64,
            doing,
        }
    }

    pub(super) fn write(&mut self, bytes: &[u8]) -> Result<(), CutterError> {
        self.link
            .write_all(bytes)
            .and_then(|()| self.link.flush())
            .map_err(|source| CutterError::Io {
                address: self.address.clone(),
                source,
            })
    }

    /// Keep an alarm or message line for a later error (the last [`NOTES_KEPT`]).
    pub(super) fn note(&mut self, line: String) {
        if self.notes.len() >= NOTES_KEPT {
            self.notes.remove(0);
        }
        self.notes.push(line);
    }

    /// One read slice into the incoming bytes. Bytes without a line end beyond
    /// [`INCOMING_MAX`] are an error (a wrong baud rate reads as noise without newlines).
    pub(super) fn fill(&mut self) -> Result<(), CutterError> {
        let mut buf = [0u8; 512];
        let io_error = |source| CutterError::Io {
            address: self.address.clone(),
            source,
        };
        match self.link.read(&mut buf) {
            Ok(0) => Err(io_error(std::io::ErrorKind::UnexpectedEof.into())),
            Ok(n) => {
                self.incoming.extend_from_slice(&buf[..n]);
                if self.incoming.len() > INCOMING_MAX {
                    self.incoming.clear();
                    return Err(CutterError::Protocol(format!(
                        "{INCOMING_MAX} bytes came without a line end: is the baud rate right?"
                    )));
                }
                Ok(())
            }
            Err(e) if is_timeout(&e) => Ok(()),
            Err(source) => Err(io_error(source)),
        }
    }

    /// The next complete, non-empty line already received.
    pub(super) fn take_line(&mut self) -> Option<String> {
        while let Some(end) = self.incoming.iter().position(|&b| b == b'\n') {
            let raw: Vec<u8> = self.incoming.drain(..=end).collect();
            let line = String::from_utf8_lossy(&raw).trim().to_owned();
            if !line.is_empty() {
                return Some(line);
            }
        }
        None
    }

    /// One read slice; every complete line received so far.
    pub(super) fn read_available(&mut self) -> Result<Vec<String>, CutterError> {
        self.fill()?;
        Ok(std::iter::from_fn(|| self.take_line()).collect())
    }

    /// The next complete line, or `None` once `deadline` passes. While connecting, a cancel
    /// ends it with [`CutterError::ConnectCancelled`].
    pub(super) fn read_line(&mut self, deadline: Instant) -> Result<Option<String>, CutterError> {
        loop {
            if let Some(line) = self.take_line() {
                return Ok(Some(line));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            if self.connecting && self.cancel.load(Ordering::Relaxed) {
                return Err(CutterError::ConnectCancelled {
                    address: self.address.clone(),
                });
            }
            self.fill()?;
        }
    }
}

fn is_timeout(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::TimedOut
            | std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::Interrupted
    )
}
