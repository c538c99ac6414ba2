//! When things happen on the twin's core: the control ticks as the board's ticker and interrupt
//! latency place them, the watchdog they feed, and a host that sends bursts of frames.
//!
//! # The board's loop, as the twin times it
//!
//! The board's control task runs one loop: the control tick, feeding the watchdog, then the
//! link's work on the frames received, at most the firmware's `link::FRAMES_PER_TICK` of them,
//! the rest left queued for the next passes (each frame costs `frame_cost_us` of core time;
//! a `SetConfig` also erases and writes flash, stalling the core for the whole operation). Then
//! it waits for its embassy `Ticker`:
//!
//! - the next tick is due one period after this one was due; a tick due in the past runs at
//!   once (the ticker catches up);
//! - but if this iteration (tick and link work) took longer than a period, the ticker restarts
//!   from the end of the work (`ticker.reset()`): the next tick comes a full period later.
//!
//! Each tick then runs at its due time plus a jitter (Gaussian, SD `tick_jitter_us`) and, at a
//! Poisson rate of `late_ticks_per_s`, `late_tick_ms` late; never before the core is free of the
//! previous iteration's work, and never before the previous tick. These draws come from their
//! own seeded stream, drawn once per tick, so that they shuffle no other draw and a host's
//! timing does not change them.
//!
//! # The watchdog
//!
//! [`SimWatchdog`] is the board's hardware watchdog: the firmware's own
//! [`Watchdog`] implementation for the twin. It runs from
//! boot at [`WATCHDOG_TIMEOUT_MS`], is fed by every control tick, and honours what the firmware
//! asks around flash operations (a [`FLASH_WATCHDOG_TIMEOUT_MS`] window for each erase and write,
//! the normal timeout after it), on the core's clock: flash operations move that clock on as
//! they stall the core. Core work that reaches the deadline (a flash erase longer than its
//! window) resets the chip at that instant: the flash's power is cut there, the operation under
//! way left torn.
//!
//! [`FLASH_WATCHDOG_TIMEOUT_MS`]: kerfmeter_firmware::watchdog::FLASH_WATCHDOG_TIMEOUT_MS

use std::sync::{Arc, Mutex, MutexGuard};

use kerfmeter_firmware::controller::PERIOD_US;
use kerfmeter_firmware::fakes::flash::FlashClock;
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_firmware::watchdog::{WATCHDOG_TIMEOUT_MS, Watchdog};
use kerfmeter_protocol::{Envelope, MAX_REQUEST_FRAME_LEN, Request, encode_frame};

use crate::plant::PlantParams;

/// The control ticks' times of one boot of the core.
#[derive(Debug, Clone)]
pub struct TickClock {
    rng: Rng,
    jitter_sd_us: f64,
    late_per_tick: f64,
    late_us: u64,
    boot_us: u64,
    /// When the last tick was due and when it ran (none before the first).
    last: Option<(u64, u64)>,
    /// The next tick's offset from its due time (jitter plus lateness), drawn in advance.
    offset_us: i64,
}

impl TickClock {
    /// The clock of a core booted at `boot_us`, drawing from `seed`.
    pub fn new(params: &PlantParams, seed: u64, boot_us: u64) -> Self {
        let period_s = PERIOD_US as f64 * 1e-6;
        let mut clock = Self {
            rng: Rng::new(seed),
            jitter_sd_us: params.tick_jitter_us,
            // A Poisson process seen once per period.
            late_per_tick: 1.0 - (-params.late_ticks_per_s * period_s).exp(),
            late_us: (params.late_tick_ms * 1000.0).round() as u64,
            boot_us,
            last: None,
            offset_us: 0,
        };
        clock.offset_us = clock.draw_offset_us();
        clock
    }

    fn draw_offset_us(&mut self) -> i64 {
        let jitter = f64::from(self.rng.normal()) * self.jitter_sd_us;
        let late = if self.rng.uniform() < self.late_per_tick {
            self.late_us
        } else {
            0
        };
        jitter.round() as i64 + late as i64
    }

    /// When the next tick is due by the ticker, the core having worked until `core_us`.
    fn next_due_us(&self, core_us: u64) -> u64 {
        match self.last {
            None => self.boot_us,
            Some((_, ran_us)) if core_us.saturating_sub(ran_us) > PERIOD_US => core_us + PERIOD_US,
            Some((due_us, _)) => due_us + PERIOD_US,
        }
    }

    /// True when the last tick's pass, its link work having run until `core_us`, took longer
    /// than a period: the board has restarted its ticker, and anything the host sends on
    /// hearing from this pass waits for the next one.
    pub fn overran(&self, core_us: u64) -> bool {
        matches!(self.last, Some((_, ran_us)) if core_us.saturating_sub(ran_us) > PERIOD_US)
    }

    /// When the next tick runs, the core having worked until `core_us`.
    pub fn next_tick_us(&self, core_us: u64) -> u64 {
        let due = self.next_due_us(core_us);
        let earliest = match self.last {
            None => core_us,
            Some((_, ran_us)) => core_us.max(ran_us + 1),
        };
        due.saturating_add_signed(self.offset_us).max(earliest)
    }

    /// Run the next tick (the core having worked until `core_us`): its time.
    pub fn start_tick(&mut self, core_us: u64) -> u64 {
        let due = self.next_due_us(core_us);
        let ran = self.next_tick_us(core_us);
        self.last = Some((due, ran));
        self.offset_us = self.draw_offset_us();
        ran
    }
}

/// The board's hardware watchdog on the core's clock (see the module docs). A cheap shared
/// handle: the firmware's guarded flash holds one, the twin another.
#[derive(Debug, Clone)]
pub struct SimWatchdog(Arc<Mutex<WatchdogState>>);

#[derive(Debug)]
struct WatchdogState {
    /// The flash whose operations stall the core (and whose power the reset cuts).
    flash: FlashClock,
    /// Started (the board starts it once booted; feeds before are no-ops).
    running: bool,
    /// Inside [`SimWatchdog::begin`]..[`SimWatchdog::end`]: the firmware has the core.
    working: bool,
    /// The core's clock, as far as the watchdog has seen it.
    now_us: u64,
    fed_us: u64,
    timeout_us: u64,
}

impl WatchdogState {
    /// The core's clock, moved on by the flash time spent since it was last read.
    fn now_us(&mut self) -> u64 {
        self.now_us += self.flash.take_spent_us();
        self.now_us
    }

    fn deadline_us(&self) -> u64 {
        self.fed_us + self.timeout_us
    }

    /// Flash time left before the reset, while the firmware has the core.
    fn arm_flash(&self) {
        if self.working && self.running {
            let left = self.deadline_us().saturating_sub(self.now_us);
            self.flash.set_budget_us(Some(left));
        }
    }
}

impl SimWatchdog {
    /// The watchdog of a core whose flash is timed by `flash`; not running yet.
    pub fn new(flash: FlashClock) -> Self {
        Self(Arc::new(Mutex::new(WatchdogState {
            flash,
            running: false,
            working: false,
            now_us: 0,
            fed_us: 0,
            timeout_us: WATCHDOG_TIMEOUT_MS * 1000,
        })))
    }

    fn state(&self) -> MutexGuard<'_, WatchdogState> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Start it at `now_us` with the normal timeout, as the board does once booted.
    pub fn start(&self, now_us: u64) {
        let mut s = self.state();
        s.flash.take_spent_us();
        s.running = true;
        s.now_us = now_us;
        s.fed_us = now_us;
        s.timeout_us = WATCHDOG_TIMEOUT_MS * 1000;
    }

    /// The firmware gets the core at `now_us`: from here flash operations move the core's clock
    /// on, and the flash's power is cut when the watchdog fires.
    pub fn begin(&self, now_us: u64) {
        let mut s = self.state();
        s.flash.take_spent_us();
        s.now_us = now_us;
        s.working = true;
        s.arm_flash();
    }

    /// The firmware is done: the core's clock then.
    pub fn end(&self) -> u64 {
        let mut s = self.state();
        s.working = false;
        s.flash.set_budget_us(None);
        s.now_us()
    }

    /// When the chip resets unless fed first (`u64::MAX` before it starts).
    pub fn deadline_us(&self) -> u64 {
        let s = self.state();
        if s.running { s.deadline_us() } else { u64::MAX }
    }
}

impl Watchdog for SimWatchdog {
    fn feed_ms(&mut self, timeout_ms: u64) {
        let mut s = self.state();
        if !s.running {
            return;
        }
        s.fed_us = s.now_us();
        s.timeout_us = timeout_ms * 1000;
        s.arm_flash();
    }
}

/// A host that sends, along with its own traffic, a burst of `host_burst_frames` extra status
/// requests every `host_burst_period_ms` (a GUI refreshing, a second tool polling): the burst
/// due goes out with the host's next frames, queued in front of them. A host that sends nothing
/// sends no bursts either (a silent host stays silent), nor while its last burst still waits in
/// the board's queue (back-pressure), and bursts missed meanwhile are not sent late.
#[derive(Debug, Clone)]
pub struct HostBursts {
    frames: u32,
    period_us: u64,
    next_us: u64,
    seq: u16,
}

impl HostBursts {
    /// Bursts as `params` set them, the first one period after `start_us`.
    pub fn new(params: &PlantParams, start_us: u64) -> Self {
        let period_us = (params.host_burst_period_ms * 1000.0).round().max(1.0) as u64;
        Self {
            frames: params.host_burst_frames.round() as u32,
            period_us,
            next_us: start_us + period_us,
            seq: 0,
        }
    }

    /// The framed requests of the burst due by `now_us`, if one is (empty otherwise). Each
    /// request has a new `seq`, so that the link hands every one to the device.
    pub fn take_due(&mut self, now_us: u64) -> Vec<u8> {
        let mut bytes = Vec::new();
        if self.next_us > now_us {
            return bytes;
        }
        let missed = (now_us - self.next_us) / self.period_us;
        self.next_us += (missed + 1) * self.period_us;
        let mut buf = [0u8; MAX_REQUEST_FRAME_LEN];
        for _ in 0..self.frames {
            self.seq = self.seq.wrapping_add(1);
            let request = Envelope {
                seq: self.seq,
                body: Request::GetStatus,
            };
            let frame = encode_frame(&request, &mut buf).expect("a status request fits");
            bytes.extend_from_slice(frame);
        }
        bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(set: &[&str]) -> PlantParams {
        let mut p = PlantParams::default();
        for s in set {
            p.assign(s).unwrap();
        }
        p
    }

    /// Tick times of an idle core (no link work).
    fn tick_times(p: &PlantParams, n: usize) -> Vec<u64> {
        let mut clock = TickClock::new(p, 3, 0);
        let mut core_us = 0;
        (0..n)
            .map(|_| {
                core_us = clock.start_tick(core_us);
                core_us
            })
            .collect()
    }

    #[test]
    fn without_jitter_or_late_ticks_ticks_come_every_period() {
        let p = params(&["tick_jitter_us=0", "late_ticks_per_s=0"]);
        let times = tick_times(&p, 100);
        assert!(
            times
                .iter()
                .enumerate()
                .all(|(i, &t)| t == i as u64 * PERIOD_US)
        );
    }

    #[test]
    fn ticks_jitter_around_their_due_time_with_the_set_spread() {
        let p = params(&["tick_jitter_us=40", "late_ticks_per_s=0"]);
        let times = tick_times(&p, 20_000);
        let offsets: Vec<f64> = times
            .iter()
            .enumerate()
            .map(|(i, &t)| t as f64 - (i as u64 * PERIOD_US) as f64)
            .collect();
        let n = offsets.len() as f64;
        let mean = offsets.iter().sum::<f64>() / n;
        let sd = (offsets.iter().map(|o| (o - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert!(mean.abs() < 2.0, "mean offset {mean} µs");
        assert!((sd - 40.0).abs() < 2.0, "SD {sd} µs");
        assert!(
            times.windows(2).all(|w| w[1] > w[0]),
            "never before the last"
        );
    }

    #[test]
    fn late_ticks_come_at_the_set_rate_and_lateness() {
        let p = params(&["tick_jitter_us=0", "late_ticks_per_s=5", "late_tick_ms=5"]);
        let times = tick_times(&p, 100_000);
        // A late tick shows as a gap of a period plus the lateness; the ticker then catches up.
        let late = times
            .windows(2)
            .filter(|w| w[1] - w[0] == PERIOD_US + 5000)
            .count();
        // 100 s at 5 per second: 500 (Poisson SD 22).
        assert!((420..580).contains(&late), "{late} late ticks");
        let last = *times.last().unwrap();
        assert!(last <= 99_999 * PERIOD_US + 5000, "caught up: {last}");
    }

    #[test]
    fn link_work_longer_than_a_period_restarts_the_ticker_after_it() {
        let p = params(&["tick_jitter_us=0", "late_ticks_per_s=0"]);
        let mut clock = TickClock::new(&p, 3, 0);
        let t0 = clock.start_tick(0);
        // 400 µs of work: the next tick keeps its schedule.
        assert_eq!(clock.next_tick_us(t0 + 400), t0 + PERIOD_US);
        // 1.5 ms of work: the tick that was due waits for the core...
        // ...and the ticker restarts a period after the work.
        assert_eq!(clock.next_tick_us(t0 + 1500), t0 + 1500 + PERIOD_US);
        assert_eq!(clock.start_tick(t0 + 1500), t0 + 2500);
        assert_eq!(clock.start_tick(t0 + 2500), t0 + 3500);
    }

    #[test]
    fn the_watchdog_runs_from_its_start_and_a_feed_restarts_it_at_the_timeout_given() {
        let clock = FlashClock::new(400_000, 0, 1);
        let mut dog = SimWatchdog::new(clock.clone());
        assert_eq!(dog.deadline_us(), u64::MAX, "not started");
        dog.start(7_000);
        assert_eq!(dog.deadline_us(), 7_000 + WATCHDOG_TIMEOUT_MS * 1000);
        dog.begin(9_000);
        dog.feed_ms(WATCHDOG_TIMEOUT_MS);
        assert_eq!(dog.end(), 9_000);
        assert_eq!(dog.deadline_us(), 9_000 + WATCHDOG_TIMEOUT_MS * 1000);
    }

    #[test]
    fn flash_time_moves_the_clock_and_the_flash_is_cut_at_the_deadline() {
        use embedded_storage_async::nor_flash::NorFlash;
        use kerfmeter_firmware::fakes::flash::RamFlash;
        let clock = FlashClock::new(400_000, 0, 1);
        let mut flash = RamFlash::new(2).with_clock(clock.clone());
        let mut dog = SimWatchdog::new(clock.clone());
        dog.start(0);
        // An erase with no longer window: cut at the 50 ms deadline.
        dog.begin(1_000);
        assert!(embassy_futures::block_on(flash.erase(0, RamFlash::PAGE)).is_err());
        assert!(clock.is_cut());
        assert_eq!(dog.end(), WATCHDOG_TIMEOUT_MS * 1000);
        // After a reboot, with the window the firmware asks for: the erase completes.
        clock.power_on();
        dog.start(0);
        dog.begin(1_000);
        dog.feed_ms(1_000);
        embassy_futures::block_on(flash.erase(0, RamFlash::PAGE)).unwrap();
        dog.feed_ms(WATCHDOG_TIMEOUT_MS);
        assert!(!clock.is_cut());
        assert_eq!(dog.end(), 401_000);
        assert_eq!(dog.deadline_us(), 401_000 + WATCHDOG_TIMEOUT_MS * 1000);
    }

    #[test]
    fn bursts_come_every_period_as_framed_status_requests() {
        let p = params(&["host_burst_frames=3", "host_burst_period_ms=200"]);
        let mut bursts = HostBursts::new(&p, 0);
        assert!(bursts.take_due(199_999).is_empty());
        let bytes = bursts.take_due(200_000);
        let mut deframer = kerfmeter_protocol::Deframer::<MAX_REQUEST_FRAME_LEN>::new();
        let mut input = &bytes[..];
        let mut seqs = Vec::new();
        while let kerfmeter_protocol::Feed::Frame { result, rest } =
            deframer.feed::<Envelope<Request>>(input)
        {
            let request = result.unwrap();
            assert_eq!(request.body, Request::GetStatus);
            seqs.push(request.seq);
            input = rest;
        }
        assert_eq!(seqs, [1, 2, 3]);
        assert!(bursts.take_due(399_999).is_empty());
        // A host quiet from 400 to 1000 ms sends one burst at 1000 ms, not four.
        assert_eq!(bursts.take_due(1_000_000).len(), bytes.len());
        assert!(bursts.take_due(1_199_999).is_empty());
        assert!(!bursts.take_due(1_200_000).is_empty());
    }
}
