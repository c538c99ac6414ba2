//! The blocking GRBL driver: connect (banner, alarm, laser mode), stream a program with
//! character counting, wait for the motion to end, and stop the cutter on every failure.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::error::CutterError;
use super::protocol::{
    MachineState, ProgramLine, Reply, Status, Streamer, declared_s_max, parse_reply, prepare,
    rx_buffer_from_build_info, window_for,
};
use super::transport::{CutterAddress, Link, open_serial, open_tcp};
use super::travel::Travel;

mod check;
mod stop;
mod travel;

/// The realtime soft reset (ctrl-X): stops everything, laser off.
use kerfmeter_grbl::realtime::SOFT_RESET;
use kerfmeter_grbl::settings::{LASER_MODE, MAX_POWER_S, REPORT_INCHES};
use kerfmeter_grbl::{commands, realtime};
/// While a controller talks without its banner yet (a boot log), the banner is waited for
/// until it has been quiet this long...
const BOOT_LOG_QUIET: Duration = Duration::from_millis(500);
/// ...but no longer than this past the usual wait.
const BOOT_LOG_MAX: Duration = Duration::from_secs(15);
/// A command's answer is waited for while it comes, up to this many reply timeouts.
const COMMAND_WAIT_MAX_REPLIES: u32 = 10;
/// Alarm and message lines kept for a later error.
const NOTES_KEPT: usize = 32;
/// The most bytes kept without a line end (GRBL's longest line is far shorter).
const INCOMING_MAX: usize = 4096;
/// How many unrecognised lines a failed connection reports.
const SEEN_KEPT: usize = 8;
/// The line every program is closed with: laser off. Under M3 GRBL keeps the beam on at rest
/// after a cut, so a program that does not end with M5 would leave it burning one spot.
const CLOSING_LINE: &str = "M5";

/// How the driver connects and streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ConnectOptions {
    /// Unlock (`$X`) a controller that is in alarm, instead of refusing it.
    pub unlock: bool,
    /// Accept a controller without laser mode (`$32=0`): only for a spindle machine, since GRBL
    /// then keeps the beam on during travel moves.
    pub allow_without_laser_mode: bool,
    /// How long to wait for the banner before waking the controller with a soft reset (a board
    /// that resets when its port opens needs about 2 s to boot).
    pub banner_wait: Duration,
    /// How long to wait for an answer to a command, a status request or a reset.
    pub reply_timeout: Duration,
    /// How often the state is polled (`?`) while streaming.
    pub poll_interval: Duration,
    /// How long the controller may say nothing at all while streaming before it is given up.
    pub silence_timeout: Duration,
    /// Run the whole program through GRBL's check mode (`$C`) before cutting it, so that a line
    /// it refuses is found before anything moves (see [`Cutter::stream`]).
    pub check_first: bool,
    /// Give up a job (stopping the cutter) once the machine has been held (feed hold, door
    /// open) this long; `None`: wait for cycle start or a cancel, however long.
    pub hold_timeout: Option<Duration>,
}

impl Default for ConnectOptions {
    fn default() -> Self {
        Self {
            unlock: false,
            allow_without_laser_mode: false,
            banner_wait: Duration::from_millis(2500),
            reply_timeout: Duration::from_secs(2),
            poll_interval: Duration::from_millis(200),
            silence_timeout: Duration::from_secs(5),
            check_first: true,
            hold_timeout: None,
        }
    }
}

/// Where a stream is, for a progress display.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamProgress {
    /// Lines the controller has answered.
    pub answered: usize,
    /// Lines in the program.
    pub total: usize,
    /// Bytes sent and not yet answered (never more than 128).
    pub unanswered_bytes: usize,
    /// The last status report.
    pub status: Option<Status>,
    /// True during the check pass (`$C`: answered, nothing moves), false while cutting.
    pub checking: bool,
}

impl StreamProgress {
    fn of(streamer: &Streamer, status: Option<Status>, checking: bool) -> Self {
        Self {
            answered: streamer.answered(),
            total: streamer.total(),
            unanswered_bytes: streamer.unanswered_bytes(),
            status,
            checking,
        }
    }
}

/// How a stream went.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamReport {
    /// Lines streamed.
    pub lines: usize,
    /// From the first line sent until the machine was idle again.
    pub elapsed: Duration,
    /// The most bytes that were unanswered at once.
    pub max_unanswered_bytes: usize,
    /// Where the machine ended, mm (when it reports its machine position).
    pub position_mm: Option<[f64; 3]>,
}

/// A connected GRBL 1.1 controller.
pub struct Cutter {
    link: Box<dyn Link>,
    address: String,
    incoming: Vec<u8>,
    options: ConnectOptions,
    version: String,
    settings: BTreeMap<u16, f64>,
    notes: Vec<String>,
    in_job: bool,
    /// Bytes that may be unanswered at once (GRBL's 128, or less for a smaller buffer).
    window: usize,
    /// The firmware, when its banner names one other than GRBL (`grblHAL`, `FluidNC`).
    flavour: Option<&'static str>,
    /// The alarm that came just before the last banner (`ALARM:3` after a reset in motion).
    alarm_before_banner: Option<u8>,
    /// The machine's travel, when the controller reports one (`$130`–`$132`).
    travel: Option<Travel>,
    /// Set from outside (Ctrl-C): ends a connect early.
    cancel: Arc<AtomicBool>,
    /// True while connecting: `cancel` is heard.
    connecting: bool,
    #[cfg(feature = "sim")]
    pub(super) sim: Option<super::twin::CutterServer>,
}

impl std::fmt::Debug for Cutter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Cutter")
            .field("address", &self.address)
            .field("version", &self.version)
            .finish_non_exhaustive()
    }
}

impl Cutter {
    /// Connect to the cutter at `address` (see [`CutterAddress`]).
    pub fn open(address: &CutterAddress, options: ConnectOptions) -> Result<Self, CutterError> {
        Self::open_cancellable(address, options, Arc::new(AtomicBool::new(false)))
    }

    /// [`Cutter::open`], given up with [`CutterError::ConnectCancelled`] as soon as `cancel` is
    /// set (Ctrl-C while a name resolves or a controller boots).
    pub fn open_cancellable(
        address: &CutterAddress,
        options: ConnectOptions,
        cancel: Arc<AtomicBool>,
    ) -> Result<Self, CutterError> {
        let link = match address {
            CutterAddress::Serial { path, baud } => open_serial(path, *baud)?,
            CutterAddress::Tcp { host_port } => open_tcp(host_port, &cancel)?,
            #[cfg(feature = "sim")]
            CutterAddress::Sim => {
                return Self::sim_cancellable(Default::default(), options, cancel);
            }
            #[cfg(not(feature = "sim"))]
            CutterAddress::Sim => {
                return Err(CutterError::Sim(
                    "this program was built without the `sim` feature".into(),
                ));
            }
        };
        Self::connect_cancellable(link, address.to_string(), options, cancel)
    }

    /// Talk to a controller on an open byte stream (reads must time out within milliseconds):
    /// wait for its banner (or wake it with a soft reset), refuse or unlock an alarm, and check
    /// laser mode, as [`ConnectOptions`] say.
    pub fn connect(
        link: Box<dyn Link>,
        address: String,
        options: ConnectOptions,
    ) -> Result<Self, CutterError> {
        Self::connect_cancellable(link, address, options, Arc::new(AtomicBool::new(false)))
    }

    /// [`Cutter::connect`], given up as soon as `cancel` is set.
    pub fn connect_cancellable(
        link: Box<dyn Link>,
        address: String,
        options: ConnectOptions,
        cancel: Arc<AtomicBool>,
    ) -> Result<Self, CutterError> {
        let mut cutter = Self {
            link,
            address,
            incoming: Vec::new(),
            options,
            version: String::new(),
            settings: BTreeMap::new(),
            notes: Vec::new(),
            in_job: false,
            alarm_before_banner: None,
            flavour: None,
            window: super::protocol::RX_BUFFER_LEN,
            travel: None,
            cancel,
            connecting: true,
            #[cfg(feature = "sim")]
            sim: None,
        };
        cutter.handshake()?;
        cutter.connecting = false;
        Ok(cutter)
    }

    /// The address it was opened at.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// GRBL's version from the banner (`1.1h`).
    pub fn version(&self) -> &str {
        &self.version
    }

    /// The controller's settings (`$$`) as read at connect.
    pub fn settings(&self) -> &BTreeMap<u16, f64> {
        &self.settings
    }

    fn handshake(&mut self) -> Result<(), CutterError> {
        // The wait for a banner is extended while a controller prints its boot log: the error
        // says how long it really was.
        let started = Instant::now();
        let mut seen = Vec::new();
        if !self.await_banner(self.options.banner_wait, &mut seen)? {
            // A networked controller need not greet, and may be running another client's job:
            // a reset would abort it, so ask first.
            self.refuse_if_busy(&mut seen)?;
            self.write(&[SOFT_RESET])?;
            if !self.await_banner(self.options.reply_timeout, &mut seen)? {
                return Err(CutterError::NoBanner {
                    address: self.address.clone(),
                    waited_ms: started.elapsed().as_millis() as u64,
                    seen,
                });
            }
        }
        self.check_version()?;
        let mut status = self.status()?;
        if status.state == MachineState::Alarm {
            if !self.options.unlock {
                return Err(self.tagged(self.alarm_at_connect()));
            }
            self.command(commands::UNLOCK)?;
            status = self.status()?;
        }
        if status.state != MachineState::Idle {
            return Err(CutterError::NotIdle {
                state: status.state.to_string(),
            });
        }
        self.read_settings()?;
        self.read_build_info();
        self.check_laser_mode()?;
        self.read_travel()
    }

    /// The character-counting window from `$I`'s receive-buffer size; GRBL's 128 when it does
    /// not say (or refuses `$I`).
    fn read_build_info(&mut self) {
        let rx_buffer = self
            .command(commands::BUILD_INFO)
            .ok()
            .and_then(|lines| lines.iter().find_map(|l| rx_buffer_from_build_info(l)));
        self.window = window_for(rx_buffer);
    }

    /// Before waking a silent controller with a reset: refuse one that reports it is busy (a
    /// job, a hold, homing), without resetting it.
    fn refuse_if_busy(&mut self, seen: &mut Vec<String>) -> Result<(), CutterError> {
        self.write(&[realtime::STATUS_REPORT])?;
        let deadline = Instant::now() + self.options.reply_timeout;
        while let Some(line) = self.read_line(deadline)? {
            if let Reply::Status(status) = parse_reply(&line) {
                return match status.state {
                    MachineState::Idle | MachineState::Alarm | MachineState::Sleep => Ok(()),
                    state => Err(CutterError::NotIdle {
                        state: state.to_string(),
                    }),
                };
            }
            if seen.len() < SEEN_KEPT {
                seen.push(line);
            }
        }
        Ok(())
    }

    /// Why the controller is in alarm, from what it said since the banner.
    fn alarm_at_connect(&self) -> CutterError {
        let code = self.notes.iter().rev().find_map(|n| match parse_reply(n) {
            Reply::Alarm(code) => Some(code),
            _ => None,
        });
        let reason = match code {
            Some(code) => super::codes::describe_alarm(code).to_owned(),
            None => "it starts locked (homing is enabled, or it was stopped abruptly)".to_owned(),
        };
        CutterError::AlarmAtConnect { code, reason }
    }

    /// `error`, marked as read with GRBL 1.1's meanings when the controller is another
    /// firmware and the error gives a code's meaning.
    fn tagged(&self, error: CutterError) -> CutterError {
        match self.flavour {
            Some(flavour) if error.has_code() => CutterError::OtherFlavour {
                flavour,
                error: Box::new(error),
            },
            _ => error,
        }
    }

    /// The firmware named in the banner: `GRBL` unless it is another (`grblHAL`, `FluidNC`).
    pub fn flavour(&self) -> &'static str {
        self.flavour.unwrap_or("GRBL")
    }

    /// Refuse a GRBL older than 1.1 (grblHAL and FluidNC, 1.1 and later, pass).
    fn check_version(&self) -> Result<(), CutterError> {
        let mut numbers = self.version.split(|c: char| !c.is_ascii_digit());
        let mut next = || numbers.next().and_then(|n| n.parse::<u32>().ok());
        match (next(), next()) {
            (Some(major), Some(minor)) if (major, minor) >= (1, 1) => Ok(()),
            _ => Err(CutterError::OldVersion {
                version: self.version.clone(),
            }),
        }
    }

    fn read_settings(&mut self) -> Result<(), CutterError> {
        for line in self.command(commands::SETTINGS)? {
            if let Reply::Setting(number, value) = parse_reply(&line) {
                self.settings.insert(number, value);
            }
        }
        Ok(())
    }

    /// Refuse a program that declares ([`declared_s_max`]) another `S` of full power than this
    /// controller's `$30` (as read at connect): every power in it would be scaled wrong. A
    /// program that declares none is not checked.
    pub fn check_s_max(&self, program: &str) -> Result<(), CutterError> {
        let declared = declared_s_max(program).map_err(|bad| CutterError::BadProgram {
            line: bad.number,
            reason: bad.reason,
        })?;
        let Some(program_s_max) = declared else {
            return Ok(());
        };
        let controller = self.settings.get(&MAX_POWER_S).copied();
        if controller.is_some_and(|c| (c - program_s_max).abs() <= 1e-6 * c.abs().max(1.0)) {
            return Ok(());
        }
        Err(CutterError::SMaxMismatch {
            program: program_s_max,
            controller: controller.map_or("?".into(), |v| v.to_string()),
        })
    }

    fn check_laser_mode(&self) -> Result<(), CutterError> {
        let laser_mode = self.settings.get(&LASER_MODE);
        if laser_mode == Some(&1.0) || self.options.allow_without_laser_mode {
            return Ok(());
        }
        Err(CutterError::LaserModeOff {
            value: laser_mode.map_or("?".into(), |v| v.to_string()),
        })
    }

    /// Read until the banner comes (true) or `wait` passes with nothing said for
    /// [`BOOT_LOG_QUIET`] (false): an ESP32 controller prints seconds of boot log before its
    /// banner, so each line extends the wait (by at most [`BOOT_LOG_MAX`] in all). Other lines go
    /// to `seen`.
    fn await_banner(
        &mut self,
        wait: Duration,
        seen: &mut Vec<String>,
    ) -> Result<bool, CutterError> {
        let started = Instant::now();
        let latest = started + wait + BOOT_LOG_MAX;
        let mut deadline = started + wait;
        let mut alarm = None;
        while let Some(line) = self.read_line(deadline)? {
            deadline = deadline.max((Instant::now() + BOOT_LOG_QUIET).min(latest));
            match parse_reply(&line) {
                Reply::Banner(version) => {
                    self.version = version;
                    self.flavour = flavour_of(&line);
                    self.notes.clear();
                    self.alarm_before_banner = alarm;
                    return Ok(true);
                }
                Reply::Alarm(code) => {
                    alarm = Some(code);
                    self.note(line.clone());
                }
                Reply::Message(_) => self.note(line.clone()),
                _ => {}
            }
            if seen.len() < SEEN_KEPT {
                seen.push(line);
            }
        }
        Ok(false)
    }

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
    fn in_mm(&self, mut status: Status) -> Status {
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
    fn command(&mut self, line: &str) -> Result<Vec<String>, CutterError> {
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
                        super::codes::describe_error(code)
                    )));
                }
                Reply::Alarm(code) if !self.in_job => {
                    return Err(CutterError::AlarmAtConnect {
                        code: Some(code),
                        reason: super::codes::describe_alarm(code).to_owned(),
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

    fn stream_lines(
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
    fn check_hold(
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
    fn send_ready(
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
    fn stream_reply(
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

    /// The controller said nothing for the reply timeout while the driver was `doing`.
    fn silent(&self, doing: &'static str) -> CutterError {
        self.silent_for(doing, self.options.reply_timeout)
    }

    fn silent_for(&self, doing: &'static str, waited: Duration) -> CutterError {
        CutterError::Silent {
            address: self.address.clone(),
            waited_ms: waited.as_millis() as u64,
            doing,
        }
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), CutterError> {
        self.link
            .write_all(bytes)
            .and_then(|()| self.link.flush())
            .map_err(|source| CutterError::Io {
                address: self.address.clone(),
                source,
            })
    }

    /// Keep an alarm or message line for a later error (the last [`NOTES_KEPT`]).
    fn note(&mut self, line: String) {
        if self.notes.len() >= NOTES_KEPT {
            self.notes.remove(0);
        }
        self.notes.push(line);
    }

    /// One read slice into the incoming bytes. Bytes without a line end beyond
    /// [`INCOMING_MAX`] are an error (a wrong baud rate reads as noise without newlines).
    fn fill(&mut self) -> Result<(), CutterError> {
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
    fn take_line(&mut self) -> Option<String> {
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
    fn read_available(&mut self) -> Result<Vec<String>, CutterError> {
        self.fill()?;
        Ok(std::iter::from_fn(|| self.take_line()).collect())
    }

    /// The next complete line, or `None` once `deadline` passes. While connecting, a cancel
    /// ends it with [`CutterError::ConnectCancelled`].
    fn read_line(&mut self, deadline: Instant) -> Result<Option<String>, CutterError> {
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

impl Drop for Cutter {
    /// Dropped in the middle of a job (a panic unwinding): stop the cutter, best effort.
    fn drop(&mut self) {
        if self.in_job {
            let _ = self.link.write_all(&[realtime::FEED_HOLD, SOFT_RESET]);
            let _ = self.link.flush();
        }
    }
}

/// The firmware a banner names, when it is not GRBL itself.
fn flavour_of(banner: &str) -> Option<&'static str> {
    if banner.starts_with("GrblHAL") {
        Some("grblHAL")
    } else if banner.contains("FluidNC") {
        Some("FluidNC")
    } else {
        None
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

fn is_timeout(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::TimedOut
            | std::io::ErrorKind::WouldBlock
            | std::io::ErrorKind::Interrupted
    )
}
