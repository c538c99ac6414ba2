//! The emulator itself: GRBL's receive buffer, line execution, planner queue, motion, feed hold,
//! soft reset and alarms, driven by [`Grbl::receive`] and [`Grbl::advance_us`].

use std::collections::VecDeque;

use super::gcode::{self, Block, Motion, Spindle, codes};
use super::motion::Move;
use super::options::CutterOptions;
use super::system::Settings;
use super::trace::{CutterLog, Point, ProtocolViolation, Segment, SegmentKind, TravelFiring};
use super::{PLANNER_BLOCKS, RX_BUFFER_LEN, SOFT_RESET, VERSION};
use kerfmeter_grbl::codes::{ALARM_ABORT_CYCLE, ALARM_HARD_LIMIT, ALARM_SOFT_LIMIT};
use kerfmeter_grbl::realtime::{CYCLE_START, FEED_HOLD, STATUS_REPORT};
use kerfmeter_grbl::status::{BufferFree, MachineState, Status};

/// Longest raw line kept while it is read (GRBL's line buffer overflows well before).
const RAW_LINE_MAX: usize = 256;

/// The parser's modal state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Modal {
    pub motion: Motion,
    pub metric: bool,
    pub absolute: bool,
    pub feed_mm_per_min: f64,
    pub power_s: f64,
    pub spindle: Spindle,
}

impl Default for Modal {
    fn default() -> Self {
        Self {
            motion: Motion::Rapid,
            metric: true,
            absolute: true,
            feed_mm_per_min: 0.0,
            power_s: 0.0,
            spindle: Spindle::Off,
        }
    }
}

/// A feed hold's progress.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Hold {
    None,
    Decelerating { remaining_us: u64 },
    Complete,
}

/// A line's execution, planned but not yet applied.
struct Plan {
    modal: Modal,
    step: Option<Move>,
    sync: bool,
    program_end: bool,
}

/// A simulated GRBL 1.1 laser cutter (see the [module docs](super)).
pub struct Grbl {
    pub(super) options: CutterOptions,
    log: CutterLog,
    now_us: u64,
    pub(super) out: Vec<u8>,
    rx: VecDeque<u8>,
    raw_line: String,
    pending: Option<(String, u32)>,
    pub(super) settings: Settings,
    pub(super) modal: Modal,
    plan_pos: Point,
    queue: VecDeque<Move>,
    current: Option<(Move, u64)>,
    machine_pos: Point,
    pub(super) hold: Hold,
    /// The alarm state: the code raised, or 0 when it booted locked without one.
    pub(super) alarm: Option<u8>,
    critical: bool,
    /// Check mode (`$C`): lines are parsed and answered, nothing moves.
    pub(super) check_mode: bool,
    gcode_lines: u32,
    /// G-code lines run outside check mode since boot.
    lines_run: u32,
    motion_us: u64,
}

impl Grbl {
    /// A cutter that has just booted (its banner is waiting in the output), recording into `log`.
    pub fn new(options: CutterOptions, log: CutterLog) -> Self {
        let mut grbl = Self {
            options,
            log,
            now_us: 0,
            out: Vec::new(),
            rx: VecDeque::with_capacity(RX_BUFFER_LEN),
            raw_line: String::new(),
            pending: None,
            settings: Settings::new(&options),
            modal: Modal::default(),
            plan_pos: [0.0; 3],
            queue: VecDeque::new(),
            current: None,
            machine_pos: [0.0; 3],
            hold: Hold::None,
            alarm: (options.boot_in_alarm || options.homing).then_some(0),
            critical: false,
            check_mode: false,
            gcode_lines: 0,
            lines_run: 0,
            motion_us: 0,
        };
        grbl.banner();
        grbl.publish();
        grbl
    }

    /// Greet a new client with the banner (as a networked controller does on each connection).
    pub fn greet(&mut self) {
        self.banner();
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// Its record (shared).
    pub fn log(&self) -> &CutterLog {
        &self.log
    }

    /// Everything it has said since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// Bytes from the sender: realtime commands act at once, the rest goes to the receive buffer
    /// (lost, and recorded, when it is full); then whatever lines can run, run. Bytes that come
    /// with a soft reset, after it, are lost, realtime ones too: GRBL flushes its receive buffer
    /// and clears pending realtime requests when it re-initialises.
    pub fn receive(&mut self, bytes: &[u8]) {
        let mut lost_bytes = 0;
        for &b in bytes {
            match b {
                // After a hard limit GRBL services nothing but a reset, not even `?`.
                STATUS_REPORT if self.critical => {}
                STATUS_REPORT => self.status_report(),
                FEED_HOLD => self.feed_hold(),
                CYCLE_START => self.resume(),
                SOFT_RESET => {
                    self.soft_reset();
                    break;
                }
                // GRBL's extended realtime commands (overrides): not emulated, never buffered.
                0x80.. => {}
                _ if self.rx.len() >= RX_BUFFER_LEN => lost_bytes += 1,
                _ => self.rx.push_back(b),
            }
        }
        if lost_bytes > 0 {
            let at_us = self.now_us;
            let violation = ProtocolViolation::RxOverflow { at_us, lost_bytes };
            self.log.lock().violations.push(violation);
        }
        self.process_lines();
        self.publish();
    }

    /// Let `dt_us` of simulated time pass: motion runs, and lines waiting for the planner run.
    pub fn advance_us(&mut self, dt_us: u64) {
        let mut left_us = dt_us;
        while left_us > 0 && self.alarm.is_none() {
            let step_us = self.step(left_us);
            if step_us == 0 {
                break;
            }
            left_us -= step_us;
        }
        self.now_us += dt_us;
        self.process_lines();
        self.publish();
    }

    /// Run the current move for at most `max_us`; the time used (0 when nothing can move).
    fn step(&mut self, max_us: u64) -> u64 {
        if self.current.is_none() && !self.start_next() {
            return 0;
        }
        let Some((m, elapsed_us)) = &self.current else {
            return 0;
        };
        let left_in_move_us = m.duration_us - elapsed_us;
        let Some((mut step_us, speed_divisor)) = self.hold_step(max_us, left_in_move_us) else {
            return 0;
        };
        if let Some(left_us) = self.hard_limit_left_us() {
            if left_us == 0 {
                self.hard_limit();
                return max_us;
            }
            step_us = step_us.min(left_us);
        }
        self.advance_move(step_us, (step_us / speed_divisor).min(left_in_move_us));
        step_us.max(1)
    }

    /// Start the next queued move; false when there is none (a hold decelerating through the
    /// last move then has nothing left to stop, and is complete).
    fn start_next(&mut self) -> bool {
        let Some(next) = self.queue.pop_front() else {
            if let Hold::Decelerating { .. } = self.hold {
                self.hold = Hold::Complete;
            }
            return false;
        };
        self.start_move(next);
        true
    }

    /// How much time a step may take, and by how much the head's speed is divided meanwhile
    /// (decelerating to a hold it covers its path at half its speed on average); the hold's
    /// deceleration moves on by the step. `None` once the hold is complete.
    fn hold_step(&mut self, max_us: u64, left_in_move_us: u64) -> Option<(u64, u64)> {
        match &mut self.hold {
            Hold::Complete => None,
            Hold::Decelerating { remaining_us } => {
                let step_us = max_us
                    .min(left_in_move_us.saturating_mul(2))
                    .min(*remaining_us)
                    .max(1);
                *remaining_us = remaining_us.saturating_sub(step_us);
                if *remaining_us == 0 {
                    self.hold = Hold::Complete;
                }
                Some((step_us, 2))
            }
            Hold::None => Some((max_us.min(left_in_move_us), 1)),
        }
    }

    /// Motion time left before the injected hard limit trips, µs (`None`: none injected).
    fn hard_limit_left_us(&self) -> Option<u64> {
        let limit_ms = self.options.hard_limit_after_ms?;
        Some(limit_ms.saturating_mul(1000).saturating_sub(self.motion_us))
    }

    /// Move the current move on by `progress_us` over a step of `step_us`; finish it at its end.
    fn advance_move(&mut self, step_us: u64, progress_us: u64) {
        let Some((m, elapsed_us)) = self.current.as_mut() else {
            return;
        };
        *elapsed_us += progress_us;
        if m.kind != SegmentKind::Dwell {
            self.motion_us += step_us;
        }
        if *elapsed_us >= m.duration_us {
            self.finish_move(true);
        }
    }

    fn start_move(&mut self, m: Move) {
        if let Some(hit) = self.end_stop_hit(&m) {
            self.log.lock().end_stop_hits.push(hit);
        }
        if m.kind == SegmentKind::Travel && m.enabled_s > 0.0 {
            let firing = TravelFiring {
                at_us: self.now_us,
                start: m.start,
                end: m.end,
                power_s: m.enabled_s,
            };
            let mut log = self.log.lock();
            if m.power_s > 0.0 {
                log.travel_firings.push(firing);
            } else {
                log.blanked_travels.push(firing);
            }
        }
        self.current = Some((m, 0));
    }

    /// End the current move (cut short unless `complete`) and record what it traced.
    fn finish_move(&mut self, complete: bool) {
        let Some((m, elapsed_us)) = self.current.take() else {
            return;
        };
        let end = m.position_at(elapsed_us);
        self.machine_pos = end;
        let segment = Segment {
            kind: m.kind,
            start: m.start,
            end,
            power_s: m.power_s,
            feed_mm_per_min: m.feed_mm_per_min,
            complete,
            line: m.line,
        };
        self.log.lock().segments.push(segment);
    }

    /// Where the head is now, mm.
    fn position(&self) -> Point {
        match &self.current {
            Some((m, elapsed_us)) => m.position_at(*elapsed_us),
            None => self.machine_pos,
        }
    }

    fn busy(&self) -> bool {
        self.current.is_some() || !self.queue.is_empty()
    }

    /// The laser's output now (`S`, 0 when off).
    pub fn laser_power_s(&self) -> f64 {
        if self.alarm.is_some() {
            return 0.0;
        }
        let laser_mode = self.settings.laser_mode();
        match (&self.current, self.hold) {
            (_, Hold::Complete) if laser_mode => 0.0,
            (Some((m, _)), _) => m.power_s,
            (None, _) if laser_mode => self.laser_idle_output(),
            (None, _) => self.spindle_output(&self.modal),
        }
    }

    /// The laser's output at rest in laser mode: GRBL turns the beam off when motion stops only
    /// under M4 (dynamic power) or after a travel; under M3 after a G1/G2/G3 its PWM stays at `S`
    /// until M5, a stationary beam burning one spot.
    fn laser_idle_output(&self) -> f64 {
        match (self.modal.spindle, self.modal.motion) {
            (Spindle::Constant, Motion::Linear | Motion::Arc { .. }) => {
                self.spindle_output(&self.modal)
            }
            _ => 0.0,
        }
    }

    /// The state, as a status report names it.
    pub fn state(&self) -> MachineState {
        match (self.alarm, self.hold) {
            (Some(_), _) => MachineState::Alarm,
            (None, _) if self.check_mode => MachineState::Check,
            (None, Hold::Complete) => MachineState::Hold(0),
            (None, Hold::Decelerating { .. }) => MachineState::Hold(1),
            (None, Hold::None) if self.busy() => MachineState::Run,
            (None, Hold::None) => MachineState::Idle,
        }
    }

    /// Copy the state and laser output into the log.
    fn publish(&self) {
        let state = self.state().to_string();
        let power = self.laser_power_s();
        let mut log = self.log.lock();
        if log.state != state {
            log.state = state;
        }
        log.laser_power_s = power;
    }

    fn say(&mut self, text: &str) {
        self.out.extend_from_slice(text.as_bytes());
        self.out.extend_from_slice(b"\r\n");
    }

    fn banner(&mut self) {
        self.say("");
        self.say(&kerfmeter_grbl::banner(VERSION));
        if self.alarm.is_some() {
            self.say("[MSG:'$H'|'$X' to unlock]");
        }
    }

    fn status_report(&mut self) {
        let [x, y, z] = self.position();
        let feed = match (&self.current, self.hold) {
            (Some((m, _)), Hold::None | Hold::Decelerating { .. }) => m.feed_mm_per_min,
            _ => 0.0,
        };
        let report = Status {
            state: self.state(),
            position_mm: Some([x, y, z]),
            work_position_mm: None,
            feed_mm_per_min: Some(feed),
            spindle_s: Some(self.laser_power_s()),
            buffer_free: Some(BufferFree {
                planner_blocks: (PLANNER_BLOCKS - self.queue.len()) as u32,
                rx_bytes: (RX_BUFFER_LEN - self.rx.len()) as u32,
            }),
        };
        self.say(&report.to_string());
    }

    fn feed_hold(&mut self) {
        if self.alarm.is_some() || self.hold != Hold::None {
            return;
        }
        self.hold = match &self.current {
            Some((m, _)) if m.kind != SegmentKind::Dwell => {
                let speed_mm_per_s = m.feed_mm_per_min / 60.0;
                let decel_us = speed_mm_per_s / self.settings.acceleration_mm_per_s2() * 1e6;
                Hold::Decelerating {
                    remaining_us: (decel_us.round() as u64).max(1),
                }
            }
            _ => Hold::Complete,
        };
        self.publish();
    }

    fn resume(&mut self) {
        if self.hold != Hold::None {
            self.hold = Hold::None;
            self.publish();
        }
    }

    /// Ctrl-X: stop everything, laser off; an alarm when it stops motion.
    pub(super) fn soft_reset(&mut self) {
        let moving = matches!(self.hold, Hold::None | Hold::Decelerating { .. }) && self.busy();
        if moving && self.alarm.is_none() {
            self.raise(ALARM_ABORT_CYCLE);
        }
        self.finish_move(false);
        self.queue.clear();
        self.rx.clear();
        self.raw_line.clear();
        self.pending = None;
        self.hold = Hold::None;
        self.critical = false;
        self.check_mode = false;
        self.plan_pos = self.machine_pos;
        self.modal = Modal::default();
        self.log.lock().resets += 1;
        self.banner();
        self.publish();
    }

    /// Motion stops where it is (the move under way ends there) and the queued moves are
    /// dropped: what an alarm does to the planner.
    fn stop_where_it_is(&mut self) {
        self.finish_move(false);
        self.queue.clear();
    }

    /// Record and announce alarm `code`: motion stops, the laser goes off.
    fn raise(&mut self, code: u8) {
        self.enter_alarm(code);
        self.say(&format!("{}{code}", kerfmeter_grbl::ALARM_PREFIX));
    }

    /// Go into alarm `code` (recorded, not announced).
    fn enter_alarm(&mut self, code: u8) {
        self.alarm = Some(code);
        self.log.lock().alarms.push(code);
    }

    /// The soft-limit alarm of [`CutterOptions::unannounced_alarm_on_line`]: motion stops where
    /// it is, the queue is dropped, and no `ALARM:2` line reaches the sender.
    fn unannounced_soft_limit(&mut self) {
        self.stop_where_it_is();
        self.enter_alarm(ALARM_SOFT_LIMIT);
        self.publish();
    }

    /// A limit switch tripped: everything stops, and only a reset is heard.
    fn hard_limit(&mut self) {
        self.critical_alarm(ALARM_HARD_LIMIT);
    }

    /// A critical alarm (a hard or soft limit): everything stops, and only a reset is heard.
    fn critical_alarm(&mut self, code: u8) {
        self.stop_where_it_is();
        self.pending = None;
        self.raw_line.clear();
        self.raise(code);
        self.say("[MSG:Reset to continue]");
        self.critical = true;
    }

    /// Put the head at `at` at once (the homing cycle's end).
    pub(super) fn move_to_home(&mut self, at: Point) {
        self.machine_pos = at;
        self.plan_pos = at;
        self.publish();
    }

    /// Read characters into lines and run them, until one has to wait (or an alarm that only a
    /// reset clears).
    fn process_lines(&mut self) {
        while !self.critical {
            if self.pending.is_none() && !self.read_line() {
                return;
            }
            let Some((line, number)) = self.pending.take() else {
                return;
            };
            match self.execute(&line, number) {
                Some(reply) => self.out.extend_from_slice(reply.as_bytes()),
                None => {
                    self.pending = Some((line, number));
                    return;
                }
            }
        }
    }

    /// Move characters from the receive buffer to the line being read; true once a line ends.
    fn read_line(&mut self) -> bool {
        while let Some(b) = self.rx.pop_front() {
            if b == b'\n' || b == b'\r' {
                let line = std::mem::take(&mut self.raw_line);
                let is_gcode = !line.trim().is_empty() && !line.trim_start().starts_with('$');
                if is_gcode {
                    self.gcode_lines += 1;
                    self.log.lock().gcode_received.push(line.clone());
                }
                self.pending = Some((line, self.gcode_lines));
                return true;
            }
            if self.raw_line.len() < RAW_LINE_MAX {
                self.raw_line.push(char::from(b));
            }
        }
        false
    }

    /// Run one line: its reply, or `None` when it must wait for the planner.
    fn execute(&mut self, line: &str, number: u32) -> Option<String> {
        if line.trim_start().starts_with('$') {
            return Some(self.system_command(line));
        }
        let block = match gcode::parse(line) {
            Ok(block) => block,
            Err(code) => return Some(error(code)),
        };
        if block == Block::default() {
            return Some(ok());
        }
        if self.alarm.is_some() {
            return Some(error(codes::GCODE_LOCK));
        }
        if let Some((n, code)) = self.options.error_on_line
            && n == number
        {
            return Some(error(code));
        }

        let plan = match self.plan(&block, number) {
            Ok(plan) => plan,
            Err(code) => return Some(error(code)),
        };
        if plan
            .step
            .as_ref()
            .is_some_and(|m| self.beyond_soft_limits(m))
        {
            // GRBL's soft limit: checked as the line is planned (in check mode too), before it
            // moves anything; the line gets no answer.
            self.critical_alarm(ALARM_SOFT_LIMIT);
            return Some(String::new());
        }
        if self.check_mode {
            // Checked, and the parser's state moves on; nothing is queued.
            self.modal = plan.modal;
            if let Some(m) = plan.step {
                self.plan_pos = m.end;
            }
            return Some(ok());
        }
        let full = plan.step.is_some() && self.queue.len() >= PLANNER_BLOCKS;
        if full || (plan.sync && self.busy()) {
            return None;
        }
        self.lines_run += 1;
        if self.options.unannounced_alarm_on_line == Some(self.lines_run) {
            self.unannounced_soft_limit();
            return Some(ok());
        }
        self.commit(plan);
        Some(ok())
    }

    fn commit(&mut self, plan: Plan) {
        self.modal = plan.modal;
        if let Some(m) = plan.step {
            self.plan_pos = m.end;
            self.queue.push_back(m);
        }
        if plan.program_end {
            self.say("[MSG:Pgm End]");
            self.modal = Modal {
                motion: Motion::Linear,
                absolute: true,
                spindle: Spindle::Off,
                ..self.modal
            };
        }
    }

    /// What `block` does, checked, without doing it.
    fn plan(&self, block: &Block, number: u32) -> Result<Plan, u8> {
        let mut modal = self.modal;
        if let Some(metric) = block.metric {
            modal.metric = metric;
        }
        let scale = if modal.metric { 1.0 } else { 25.4 };
        if let Some(feed) = block.feed {
            modal.feed_mm_per_min = feed * scale;
        }
        if let Some(power) = block.power {
            modal.power_s = power;
        }
        if let Some(spindle) = block.spindle {
            modal.spindle = spindle;
        }
        if let Some(absolute) = block.absolute {
            modal.absolute = absolute;
        }
        if let Some(motion) = block.motion {
            modal.motion = motion;
        }
        let mut plan = Plan {
            modal,
            step: None,
            sync: block.program_end || self.spindle_sync(block, &modal),
            program_end: block.program_end,
        };
        match (block.dwell, block.p) {
            (true, None) => return Err(codes::MISSING_VALUE),
            (false, Some(_)) => return Err(codes::UNUSED_VALUE_WORDS),
            (true, Some(_)) if block.has_axes() => return Err(codes::UNUSED_AXIS_WORDS),
            (true, Some(seconds)) => {
                let mut dwell = Move::dwell(self.plan_pos, seconds);
                dwell.power_s = self.output(SegmentKind::Dwell, &modal);
                dwell.enabled_s = self.spindle_output(&modal);
                dwell.line = number;
                plan.step = Some(dwell);
                plan.sync = true;
                return Ok(plan);
            }
            (false, None) => {}
        }
        if block.machine_coords && matches!(modal.motion, Motion::Arc { .. }) {
            return Err(codes::G53_INVALID_MOTION_MODE);
        }
        if block.has_axes() {
            plan.step = self.motion(block, &modal, scale, number)?;
        } else if block.offsets.iter().any(Option::is_some) {
            return Err(codes::UNUSED_VALUE_WORDS);
        }
        Ok(plan)
    }

    /// True when `block` changes the spindle the way GRBL synchronises: it waits for the
    /// planner to empty before parsing on (its `spindle_sync`), so the `ok` comes only once
    /// every earlier move has run: a change of M3/M4/M5, or a new `S` with the spindle on and no
    /// motion on the line.
    fn spindle_sync(&self, block: &Block, modal: &Modal) -> bool {
        let state_changed = modal.spindle != self.modal.spindle;
        let power_changed = modal.power_s != self.modal.power_s
            && modal.spindle != Spindle::Off
            && !block.has_axes();
        state_changed || power_changed
    }

    /// The move a block with axis words makes (`None` when it goes nowhere).
    fn motion(
        &self,
        block: &Block,
        modal: &Modal,
        scale: f64,
        number: u32,
    ) -> Result<Option<Move>, u8> {
        let mut target = self.plan_pos;
        let offsets = self.options.work_offset_mm;
        for ((axis, word), offset) in target.iter_mut().zip(block.axes).zip(offsets) {
            if let Some(value) = word {
                *axis = value * scale
                    + match (block.machine_coords, modal.absolute) {
                        (true, _) => 0.0,
                        (false, true) => offset,
                        (false, false) => *axis,
                    };
            }
        }
        let max_rate = self.settings.max_rate_mm_per_min();
        let feed = modal.feed_mm_per_min.min(max_rate);
        let needs_feed = modal.motion != Motion::Rapid;
        if needs_feed && feed <= 0.0 {
            return Err(codes::UNDEFINED_FEED_RATE);
        }
        let mut m = match modal.motion {
            Motion::Rapid => Move::straight(self.plan_pos, target, max_rate, true),
            Motion::Linear => Move::straight(self.plan_pos, target, feed, false),
            Motion::Arc { clockwise } => {
                let [i, j] = block.offsets;
                if i.is_none() && j.is_none() {
                    return Err(codes::NO_OFFSET_WORDS);
                }
                let center = [
                    self.plan_pos[0] + i.unwrap_or(0.0) * scale,
                    self.plan_pos[1] + j.unwrap_or(0.0) * scale,
                ];
                Move::arc(self.plan_pos, target, center, clockwise, feed)?
            }
        };
        if m.duration_us == 0 {
            return Ok(None);
        }
        m.power_s = self.output(m.kind, modal);
        m.enabled_s = self.spindle_output(modal);
        m.line = number;
        Ok(Some(m))
    }

    /// The laser's output during a move of `kind` under `modal`.
    fn output(&self, kind: SegmentKind, modal: &Modal) -> f64 {
        let on = self.spindle_output(modal);
        if !self.settings.laser_mode() {
            return on;
        }
        match (kind, modal.spindle) {
            (SegmentKind::Travel, _) | (SegmentKind::Dwell, Spindle::Dynamic) => 0.0,
            _ => on,
        }
    }

    /// The spindle's output under `modal`, capped at `$30`.
    fn spindle_output(&self, modal: &Modal) -> f64 {
        match modal.spindle {
            Spindle::Off => 0.0,
            Spindle::Constant | Spindle::Dynamic => modal.power_s.min(self.settings.max_power_s()),
        }
    }

    /// True while a move or queued block exists (for `$` commands that need the machine still).
    pub(super) fn is_busy(&self) -> bool {
        self.busy()
    }

    /// Leave the alarm state (`$X`).
    pub(super) fn unlock(&mut self) {
        self.alarm = None;
        self.publish();
    }
}

/// `ok`, with GRBL's line end.
pub(super) fn ok() -> String {
    format!("{}\r\n", kerfmeter_grbl::OK)
}

/// `error:N`, with GRBL's line end.
pub(super) fn error(code: u8) -> String {
    format!("{}{code}\r\n", kerfmeter_grbl::ERROR_PREFIX)
}
