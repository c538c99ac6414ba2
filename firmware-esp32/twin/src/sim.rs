//! The twin itself: the real firmware (link, device, controller, AS5048A and G2 drivers, the
//! shared control tick) wired to fake peripherals that speak the chips' protocols, in lock-step
//! with the [`Plant`], deterministic for a seed.
//!
//! # Time
//!
//! Time is simulated, on the core's clock ([`Twin::now_us`]): [`Twin::tick`] runs the next
//! control tick when the core gets to it ([`crate::timing`]: the board's ticker, jitter, late
//! ticks), and the plant integrates the time in between with the bridge held as the firmware
//! last left it. Link work moves the core's clock on as the board's loop does: each frame from
//! the host costs `frame_cost_us`, and a request that erases or writes flash stalls the core for
//! the whole operation (`flash_erase_ms` a sector, `flash_write_ms` a page): no tick runs
//! meanwhile, the plant keeps moving. As on the board, the link takes at most
//! [`FRAMES_PER_TICK`] frames a pass (the firmware's rule, see its `link` module): each pass is
//! a tick's step, then link work on the frames queued before it, within that budget; the frames
//! after them wait for the next passes, in the order they came (the other host's burst, then the
//! client's frames), and an answer comes only once its frame's turn has come. (The store erases
//! a sector only when its pages are full: on the twin's four sectors, a fresh flash's 319th save
//! is the first to erase.) The device
//! puts the bridge safe before it writes flash (`device::WithMotor`, as on the board), so the
//! plant coasts through a stall rather than being driven. The watchdog ([`SimWatchdog`]) is the
//! firmware's: fed by each tick, given a longer window by the firmware around each flash
//! operation. A stall that reaches its deadline resets the chip in the middle of it, the flash
//! operation under way left torn, and the twin reboots (flash kept, state lost); the host gets no
//! answer. With its own frames, the host sends a burst of
//! `host_burst_frames` status requests every `host_burst_period_ms`, through a link of their own,
//! so that their answers never reach the real client and its retry memory is not disturbed; they
//! cost core time and budget like any frame. While a burst still waits in the board's queue, the
//! host sends no new one (the full queue holds its writes back).
//!
//! Served on a serial port ([`crate::serve()`]), simulated time runs ahead of the host by at most
//! [`MAX_LEAD_MS`] past its last answer — much faster than real time, yet a host that keeps
//! polling never looks silent to the device's watchdog — or follows the wall clock in real-time
//! mode.

use kerfmeter_protocol::{DeviceConfig, EncoderPlacement, Request, Response, RunState};

use crate::encoder::EncoderErrors;
use crate::gauge_trace::{GaugeTraceError, TracedGaugeSlot};
use crate::options::{InjectedFault, TwinOptions};
use crate::plant::{Bridge, Cutter, GaugeCut, Plant};
use crate::sense::{Sense, Sensed};
use crate::timing::{HostBursts, SimWatchdog, TickClock};
use crate::traced::Segment;
use crate::truth::TruthLog;
use kerfmeter_firmware::as5048a::{As5048a, EncoderSettings};
use kerfmeter_firmware::board::partition::{ConfigStorage, OpenedConfig, open_config_partition};
use kerfmeter_firmware::config_store::{ConfigSource, FlashConfigStore};
use kerfmeter_firmware::controller::PERIOD_US;
use kerfmeter_firmware::device::{Device, WithMotor};
use kerfmeter_firmware::fakes::as5048a::{FakeAs5048a, MisoFault};
use kerfmeter_firmware::fakes::flash::{FlashClock, RamFlash};
use kerfmeter_firmware::fakes::pins::{FakeInput, FakeOutput, FakePwm};
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_firmware::hardware::Hardware;
use kerfmeter_firmware::link::{FRAMES_PER_TICK, Handler, Link};
use kerfmeter_firmware::motor::G2Motor;
use kerfmeter_firmware::watchdog::{WATCHDOG_TIMEOUT_MS, Watchdog, WatchdogFlash};

/// How far simulated time may run past the host's last answered request, ms.
pub const MAX_LEAD_MS: u64 = 100;
/// When a mid-run fault strikes, ms after the run started.
pub const FAULT_AT_MS: u64 = 200;
/// Every this many encoder frames, one response is corrupted (`parity` fault).
pub const PARITY_ERROR_EVERY_FRAMES: u32 = 40;

/// Mixed into the seed of the random stream that draws each gauge's cut, so that the gauges a
/// seed gives do not depend on how many ticks (each drawing current noise from the main stream)
/// passed before each run: host timing decides that, and must not decide the gauges.
const GAUGE_STREAM: u64 = 0x6761_7567_6573_0000;
/// Mixed into the seed of the stream that draws tick jitter and late ticks (see
/// [`GAUGE_STREAM`]).
const TIMING_STREAM: u64 = 0x7469_6d69_6e67_0000;
/// Mixed into the seed of the stream that draws a torn flash operation's bytes.
const FLASH_STREAM: u64 = 0x666c_6173_6800_0000;

/// Flash reserved for the configuration store (four 4 KiB sectors).
const FLASH_PAGES: usize = 4;
/// The configuration store's range of the flash.
const FLASH_RANGE: core::ops::Range<u32> = 0..FLASH_PAGES as u32 * RamFlash::PAGE;

type TwinHardware = Hardware<FakeAs5048a, FakePwm, FakeOutput, FakeOutput, FakeInput>;
type TwinMotor = G2Motor<FakePwm, FakeOutput, FakeOutput, FakeInput>;
/// The configuration's flash, its operations guarded by the watchdog as on the board.
pub type TwinFlash = WatchdogFlash<RamFlash, SimWatchdog>;
/// The device, with its configuration kept as the board keeps it.
pub type TwinDevice = Device<ConfigStorage<TwinFlash>>;

/// The bridge at rest: what the driver's constructor leaves.
const SAFE_BRIDGE: Bridge = Bridge {
    duty: 0.0,
    direction: 1.0,
    awake: false,
};

/// The twin: firmware, fake peripherals and plant.
pub struct Twin {
    options: TwinOptions,
    rng: Rng,
    /// Draws each gauge's cut (see [`GAUGE_STREAM`]).
    gauge_rng: Rng,
    /// Cuts each gauge, at this twin's place on the bed.
    cutter: Cutter,
    /// The gauge a traced cut left under the prongs, placed for every run instead of a fresh
    /// one ([`Twin::place_traced_gauge`]): its physical geometry and cut.
    traced_gauge: TracedGaugeSlot,
    /// This twin's encoder chip's and magnet's angle errors.
    encoder_errors: EncoderErrors,
    /// The magnet sits on the motor shaft (it turns `gear_ratio` times per hub turn) instead of
    /// the output shaft.
    magnet_on_motor_shaft: bool,
    plant: Plant,
    hardware: TwinHardware,
    pwm: FakePwm,
    dir: FakeOutput,
    slp: FakeOutput,
    flt: FakeInput,
    /// The injected `driver-fault` holds FLT low (besides the driver's own under-voltage).
    flt_injected: bool,
    /// The ADC's current-sense and supply-sense channels.
    sense: Sense,
    /// Their readings taken at the end of the last tick, for the next one (the board reads them
    /// one conversion behind); `None` before the first tick.
    sensed: Option<Sensed>,
    device: TwinDevice,
    link: Link,
    /// The link the bursts of the other host go through.
    burst_link: Link,
    /// The other host's bytes the link has not taken yet (the board's receive queue).
    burst_backlog: Vec<u8>,
    /// Frames the links took in this pass, since the last step.
    pass_frames: u32,
    bursts: HostBursts,
    ticks: TickClock,
    /// The board's watchdog, fed by each tick and by the firmware around flash operations.
    watchdog: SimWatchdog,
    flash: FlashClock,
    /// The bridge as the firmware last left it: the plant runs with it until the next tick.
    bridge: Bridge,
    /// The core's clock; the plant has run until it.
    now_us: u64,
    last_request_us: u64,
    run_started_us: Option<u64>,
    fault_struck: bool,
    over_current: bool,
    boots: u32,
    truths: TruthLog,
}

impl Twin {
    /// Boot a twin.
    pub fn new(options: TwinOptions) -> Self {
        let p = &options.plant;
        let flash = RamFlash::new(FLASH_PAGES).with_clock(FlashClock::new(
            (p.flash_erase_ms * 1000.0).round() as u64,
            (p.flash_write_ms * 1000.0).round() as u64,
            options.seed ^ FLASH_STREAM,
        ));
        let flash = if options.encoder_on_motor_shaft {
            with_motor_shaft_config(flash)
        } else {
            flash
        };
        let mut twin = Self::boot(options, flash, 0, 0);
        twin.magnet_on_motor_shaft = options.encoder_on_motor_shaft;
        twin
    }

    /// Boot a twin that records its runs' truths in `truths` (shared with the caller).
    pub fn with_truth_log(options: TwinOptions, truths: TruthLog) -> Self {
        Self {
            truths,
            ..Self::new(options)
        }
    }

    /// Boot the firmware at `now_us` on `flash` (its `boots`-th boot), as the board boots: the
    /// configuration opened under the board's partition policy. Boot time is not simulated.
    fn boot(options: TwinOptions, flash: RamFlash, boots: u32, now_us: u64) -> Self {
        let stream = |mix: u64| options.seed ^ mix ^ (u64::from(boots) << 32);
        let mut rng = Rng::new(stream(0));
        let boot_id = rng.next_u64() as u32;
        // Safe state first: the driver's constructor drives the pins safe.
        let (pwm, dir, slp, flt) = (
            FakePwm::new((1 << kerfmeter_firmware::build::PWM_BITS) - 1),
            FakeOutput::new(false),
            FakeOutput::new(false),
            FakeInput::new(true),
        );
        let (motor, _) = G2Motor::new(pwm.clone(), dir.clone(), slp.clone(), flt.clone());
        let mut chip = FakeAs5048a::new(rng.next_u64());
        chip.set_noise_lsb(options.plant.encoder_noise_lsb as f32);
        chip.set_agc(options.plant.magnet_agc.round() as u8);
        let watchdog = SimWatchdog::new(flash.clock().clone());
        let (opened, flash_clock) = open_config(WatchdogFlash::new(flash, watchdog.clone()));
        // The board starts its watchdog once booted.
        watchdog.start(now_us);
        let encoder = As5048a::new(chip, EncoderSettings::from_config(&opened.config));
        let device = Device::with_config(
            "twin",
            boot_id,
            opened.config,
            opened.source,
            opened.storage,
        );
        let mut plant = Plant::new(options.plant, options.gauge, options.kerf_um);
        match options.fault {
            Some(InjectedFault::NoInset) => plant.set_inset_present(false),
            Some(InjectedFault::MotorDisconnected) => plant.set_motor_connected(false),
            _ => {}
        }
        Self {
            gauge_rng: Rng::new(stream(GAUGE_STREAM)),
            ticks: TickClock::new(&options.plant, stream(TIMING_STREAM), now_us),
            watchdog,
            bursts: HostBursts::new(&options.plant, now_us),
            cutter: Cutter::for_twin(
                options.plant,
                options.kerf_um,
                options.kerf_sd_um,
                options.seed,
            ),
            traced_gauge: TracedGaugeSlot::default(),
            encoder_errors: EncoderErrors::for_twin(&options.plant, options.seed),
            magnet_on_motor_shaft: false,
            sense: Sense::new(&options.plant, stream(0)),
            sensed: None,
            flt_injected: false,
            options,
            rng,
            plant,
            hardware: Hardware::new(encoder, motor),
            pwm,
            dir,
            slp,
            flt,
            device,
            link: Link::new(),
            burst_link: Link::new(),
            burst_backlog: Vec::new(),
            pass_frames: 0,
            flash: flash_clock,
            bridge: SAFE_BRIDGE,
            now_us,
            last_request_us: now_us,
            run_started_us: None,
            fault_struck: false,
            over_current: false,
            boots,
            truths: TruthLog::default(),
        }
    }

    /// Power-cycle the device: new boot id, state lost, flash (configuration) kept, hub where it
    /// stands; the other host keeps its rhythm.
    pub fn reboot(&mut self) {
        let storage = core::mem::replace(
            &mut self.device,
            Device::with_config(
                "twin",
                0,
                DeviceConfig::DEFAULT,
                ConfigSource::Missing,
                ConfigStorage::RamOnly,
            ),
        )
        .into_store();
        // The RAM flash reads and erases at boot unless its power is cut, and it is on then:
        // every twin keeps its flash.
        let flash = storage
            .into_flash()
            .expect("the twin's flash always opens")
            .into_inner();
        let plant = self.plant.clone();
        let bursts = self.bursts.clone();
        let truths = self.truths.clone();
        truths.clear();
        let magnet_on_motor_shaft = self.magnet_on_motor_shaft;
        let traced_gauge = self.traced_gauge.clone();
        *self = Self::boot(self.options, flash, self.boots + 1, self.now_us);
        self.magnet_on_motor_shaft = magnet_on_motor_shaft;
        self.traced_gauge = traced_gauge;
        self.plant = plant;
        self.bursts = bursts;
        self.truths = truths;
    }

    /// The gauge a cutter cut around `at_mm` on its bed, as the laser traced it (`segments`, a
    /// cutter twin's record of its segments, `kerfmeter::grbl::twin::CutterRecord`), goes under the
    /// prongs, which come down over `at_mm`: every run from now on measures it (its physical
    /// pitch, sense, holes and centre, from the trace; its kerf, contact and the machine's
    /// repeatability from this twin's [`Cutter`]), while the device keeps the nominal geometry
    /// its `RunParams` give it. The cut drawn for it, or why no gauge the device can measure was
    /// cut there ([`crate::gauge_trace`]); a refused trace leaves the gauges as they were.
    pub fn place_traced_gauge(
        &mut self,
        segments: &[Segment],
        at_mm: [f64; 2],
    ) -> Result<GaugeCut, GaugeTraceError> {
        let cutter = self.cutter;
        self.place_traced_gauge_cut_by(segments, at_mm, &cutter)
    }

    /// [`place_traced_gauge`](Self::place_traced_gauge), the gauge cut by `cutter` (a cutter
    /// twin's, from its options' kerf, `kerfmeter::grbl::twin::CutterOptions::kerf`) instead of this
    /// twin's own.
    pub fn place_traced_gauge_cut_by(
        &mut self,
        segments: &[Segment],
        at_mm: [f64; 2],
        cutter: &Cutter,
    ) -> Result<GaugeCut, GaugeTraceError> {
        self.traced_gauge.place(
            segments,
            &self.options.gauge,
            at_mm,
            cutter,
            &mut self.gauge_rng,
        )
    }

    /// This twin's traced-gauge slot (see [`place_traced_gauge`](Self::place_traced_gauge)).
    pub fn traced_gauges(&self) -> &TracedGaugeSlot {
        &self.traced_gauge
    }

    /// This twin, its runs measuring whatever gauge `slot` holds (shared with its caller).
    pub fn with_traced_gauges(self, slot: TracedGaugeSlot) -> Self {
        Self {
            traced_gauge: slot,
            ..self
        }
    }

    /// How many times the device rebooted ([`reboot`](Self::reboot) or its watchdog).
    pub fn reboots(&self) -> u32 {
        self.boots
    }

    /// The flash's clock: its erases and writes so far (for checks).
    pub fn flash(&self) -> &FlashClock {
        &self.flash
    }

    /// Simulated time on the core's clock, µs: the last tick, or the end of the link work
    /// (frames, flash stalls) after it. The plant has run until it.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// When the next control tick will run, µs (later if more link work comes first).
    pub fn next_tick_us(&self) -> u64 {
        self.ticks.next_tick_us(self.now_us)
    }

    /// The plant (for checks).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The device (for checks).
    pub fn device(&self) -> &TwinDevice {
        &self.device
    }

    /// The truth of each run started (shared: a clone follows this twin).
    pub fn truths(&self) -> &TruthLog {
        &self.truths
    }

    /// The options it was built with.
    pub fn options(&self) -> &TwinOptions {
        &self.options
    }

    /// Move the encoder's magnet to the motor shaft (`true`: it turns `gear_ratio` times per hub
    /// turn) or back to the output shaft. The device's configuration must say so too
    /// (`encoder_placement`): this is the mechanics, not the firmware.
    pub fn set_magnet_on_motor_shaft(&mut self, on_motor: bool) {
        self.magnet_on_motor_shaft = on_motor;
    }

    /// Someone turns the hub by hand to `cw_deg` (clockwise-positive seen from above), prongs
    /// lifted ([`Plant::turn_hub_by_hand`]); between requests, with the motor at rest.
    pub fn turn_hub_by_hand(&mut self, cw_deg: f64) {
        self.plant.turn_hub_by_hand(cw_deg);
    }

    /// True when the motor bridge is in its safe state: duty 0 and the driver asleep (either
    /// alone leaves the bridge able to brake or to drive on the next write).
    pub fn motor_safe(&self) -> bool {
        self.pwm.duty() == 0.0 && !self.slp.is_high()
    }

    /// True when the bridge drives the motor: the driver awake at a duty above 0 (what a test
    /// that a run drives it asks; a bridge braking awake at duty 0 is neither this nor safe).
    pub fn motor_driven(&self) -> bool {
        self.pwm.duty() > 0.0 && self.slp.is_high()
    }

    /// True when the bridge applies no drive torque: duty 0 (braking) or the driver asleep, as
    /// the controller's [`MotorOutput::is_safe`](kerfmeter_firmware::motor::MotorOutput::is_safe)
    /// says of its output.
    fn motor_torque_free(&self) -> bool {
        self.pwm.duty() == 0.0 || !self.slp.is_high()
    }

    /// True while the injected `host-silent` fault swallows the host's bytes.
    fn host_muted(&self) -> bool {
        self.options.fault == Some(InjectedFault::HostSilent)
            && self.fault_struck
            && !matches!(self.device.controller().run_state(), RunState::Fault(_))
    }

    /// Bytes from the host: handled by the firmware's link, [`FRAMES_PER_TICK`] frames a pass
    /// (the twin runs the ticks until the last frame's turn comes); responses go to `transmit` —
    /// none if the device reset before it could send them (its watchdog, during a flash stall).
    pub fn receive(&mut self, bytes: &[u8], mut transmit: impl FnMut(&[u8])) {
        if self.host_muted() {
            return;
        }
        self.queue_burst();
        let mut rest = bytes;
        loop {
            let budget = self.client_turn();
            let mut out = Vec::new();
            let Some(done) = self.serve_host(Sender::Client, |handler, link| {
                link.receive_frames(rest, budget, handler, |frame| out.push(frame.to_vec()))
            }) else {
                return;
            };
            self.pass_frames += done.frames;
            out.iter().for_each(|frame| transmit(frame));
            rest = &rest[done.consumed..];
            if rest.is_empty() {
                return;
            }
        }
    }

    /// A request without framing (in-process tests), costing one frame's link work.
    ///
    /// # Panics
    ///
    /// If the device resets before answering (see [`try_request`](Self::try_request)).
    pub fn request(&mut self, request: &Request) -> Response {
        self.try_request(request)
            .expect("the device's watchdog reset it before it answered")
    }

    /// A request without framing, handled when its turn comes (a frame of the pass's budget);
    /// `None` when the device reset before answering (its watchdog fired during a flash stall)
    /// and rebooted.
    pub fn try_request(&mut self, request: &Request) -> Option<Response> {
        self.queue_burst();
        self.client_turn();
        // Heard, then handled, as the link does with every request it receives.
        let response = self.serve_host(Sender::Client, |handler, _| {
            handler.host_activity();
            handler.handle(request)
        })?;
        self.pass_frames += 1;
        Some(response)
    }

    /// The client's frames arrive: with them the other host's burst due, if its last one is
    /// gone, queued in front of them (and served at once if this pass has budget left).
    fn queue_burst(&mut self) {
        if self.burst_backlog.is_empty() {
            self.burst_backlog = self.bursts.take_due(self.now_us);
            self.serve_backlog();
        }
    }

    /// Runs passes (ticks, each serving the queue) until the other host's queued frames are
    /// through and a pass has budget left for the client's next frames; that budget.
    ///
    /// A pass whose link work ran longer than a period (a flash stall) takes no more frames:
    /// on the board its answers leave only once it has ended, and the board's ticker then
    /// restarts, so whatever the host sends on hearing them is served after the next pass's
    /// step, a period later (a run started then does not take the stall for an overrun of its
    /// own steps).
    fn client_turn(&mut self) -> u32 {
        while !self.burst_backlog.is_empty()
            || self.pass_frames >= FRAMES_PER_TICK
            || self.ticks.overran(self.now_us)
        {
            self.tick();
        }
        FRAMES_PER_TICK - self.pass_frames
    }

    /// The other host's queued frames, within what is left of this pass's budget.
    fn serve_backlog(&mut self) {
        if self.burst_backlog.is_empty() || self.pass_frames >= FRAMES_PER_TICK {
            return;
        }
        let budget = FRAMES_PER_TICK - self.pass_frames;
        let bytes = core::mem::take(&mut self.burst_backlog);
        // `None`: the device reset (and rebooted, its queue lost).
        if let Some(done) = self.serve_host(Sender::Burst, |handler, link| {
            link.receive_frames(&bytes, budget, handler, |_| {})
        }) {
            self.pass_frames += done.frames;
            self.burst_backlog = bytes[done.consumed..].to_vec();
        }
    }

    /// Host traffic goes through the twin's handler (which acts out how the device is used) on
    /// the sender's link, on the core's clock: each frame costs link work, flash operations
    /// stall the core, and a stall that reaches the watchdog resets the device (`None`: no
    /// answer). A `ClearFault` among it repairs the injected fault afterwards.
    fn serve_host<R>(
        &mut self,
        sender: Sender,
        serve: impl FnOnce(&mut TwinHandler<'_>, &mut Link) -> R,
    ) -> Option<R> {
        let link = match sender {
            Sender::Client => &mut self.link,
            Sender::Burst => &mut self.burst_link,
        };
        let frames_before = frames_seen(link);
        let mut core = CoreWork {
            now_us: self.now_us,
            frame_cost_us: self.options.plant.frame_cost_us.round() as u64,
            handled: 0,
            reset: false,
            bridge_safe_at_us: None,
        };
        let mut repair = false;
        let result = serve(
            &mut TwinHandler {
                device: &mut self.device,
                motor: &mut self.hardware.motor,
                pwm: &self.pwm,
                slp: &self.slp,
                watchdog: &self.watchdog,
                plant: &mut self.plant,
                gauge_rng: &mut self.gauge_rng,
                cutter: &self.cutter,
                traced_gauge: &self.traced_gauge,
                options: &self.options,
                run_started: &mut self.run_started_us,
                truths: &self.truths,
                repair: &mut repair,
                flash: &self.flash,
                core: &mut core,
            },
            link,
        );
        // Frames that never reached the handler (retries answered from memory, broken frames)
        // cost link work too.
        let unhandled = (frames_seen(link) - frames_before).saturating_sub(core.handled);
        core.now_us += u64::from(unhandled) * core.frame_cost_us;
        let deadline_us = self.watchdog.deadline_us();
        // The device put the bridge safe before a flash operation: from then on the plant runs
        // with it so.
        if let Some(at_us) = core.bridge_safe_at_us {
            self.advance_to(at_us.min(deadline_us));
            self.bridge = self.bridge_inputs();
        }
        if core.reset || core.now_us >= deadline_us {
            self.advance_to(deadline_us);
            self.reboot();
            return None;
        }
        self.advance_to(core.now_us);
        if sender == Sender::Client {
            self.last_request_us = self.now_us;
        }
        if repair {
            self.repair();
        }
        Some(result)
    }

    /// Ticks the twin may run before it must wait for the host (lock-step mode): those that
    /// start before [`MAX_LEAD_MS`] past the host's last answer.
    pub fn lead_ticks(&self) -> u64 {
        let limit = self.last_request_us + MAX_LEAD_MS * 1000;
        let host_silent =
            self.options.fault == Some(InjectedFault::HostSilent) && self.fault_struck;
        if host_silent {
            return u64::MAX;
        }
        match limit.checked_sub(self.next_tick_us()) {
            Some(lead_us) if lead_us > 0 => (lead_us - 1) / PERIOD_US + 1,
            _ => 0,
        }
    }

    /// Run the plant until `t_us` with the bridge held; the core's clock moves there.
    fn advance_to(&mut self, t_us: u64) {
        if t_us > self.now_us {
            self.plant.run_us(&self.bridge, t_us - self.now_us);
            self.now_us = t_us;
        }
    }

    /// The next pass of the board's control loop, when the core gets to it: the plant runs
    /// until then, then sensors → firmware tick (feeding the watchdog) → bridge, then the link's
    /// work on the other host's queued frames, within the pass's budget. (The client's frames
    /// are served when it sends them: [`receive`](Self::receive).)
    pub fn tick(&mut self) {
        let tick_us = self.ticks.start_tick(self.now_us);
        self.step_at(tick_us);
        self.pass_frames = 0;
        self.serve_backlog();
    }

    /// The control step of a pass, at `tick_us`: the plant runs until then, then sensors →
    /// firmware tick (feeding the watchdog) → bridge.
    fn step_at(&mut self, tick_us: u64) {
        self.advance_to(tick_us);
        self.strike_faults();
        let hub_cw_deg = self.plant.hub_cw_deg();
        let magnet_cw_deg = if self.magnet_on_motor_shaft {
            hub_cw_deg * self.plant.params().gear_ratio
        } else {
            hub_cw_deg
        };
        let cw = self.encoder_errors.measured_deg(magnet_cw_deg);
        self.hardware.encoder.bus_mut().set_angle_deg(cw);
        self.flt
            .set_high(!self.flt_injected && !self.plant.driver_fault());
        // The first tick after boot has no conversion yet, as on the board.
        let out = self.hardware.tick(
            self.now_us,
            self.sensed.map(|s| s.cs_mv),
            self.sensed.map(|s| s.supply_v),
            &mut self.device,
        );
        // The next conversions, started just after the output was applied: they see the bridge
        // as it was until now.
        self.sensed = Some(self.sense.sample(
            &self.plant.electrical(),
            self.now_us,
            self.over_current,
            &mut self.rng,
        ));
        // The control tick, and only it, feeds the watchdog at the normal timeout.
        self.watchdog.begin(self.now_us);
        self.watchdog.feed_ms(WATCHDOG_TIMEOUT_MS);
        self.watchdog.end();
        // The board reports when each step's work ended; the twin does not model the step's own
        // execution time (crate docs), so its steps end as they start and `Status` shows a
        // longest step of 0 µs here.
        self.device.step_finished(self.now_us);
        debug_assert_eq!(out.is_safe(), self.motor_torque_free());
        self.bridge = self.bridge_inputs();
    }

    /// The bridge's inputs as the pins hold them, in the jam frame.
    fn bridge_inputs(&self) -> Bridge {
        let cw_sign = if self.dir.is_high() { 1.0 } else { -1.0 };
        let jam_sign = match self.options.gauge.jam_direction {
            kerfmeter_protocol::JamDirection::Clockwise => 1.0,
            kerfmeter_protocol::JamDirection::CounterClockwise => -1.0,
        };
        Bridge {
            duty: f64::from(self.pwm.duty()),
            direction: cw_sign * jam_sign,
            awake: self.slp.is_high(),
        }
    }

    /// Run `n` ticks.
    pub fn advance_ticks(&mut self, n: u64) {
        for _ in 0..n {
            self.tick();
        }
    }

    /// Run every tick that starts by `t_us` (real-time pacing).
    pub fn advance_until(&mut self, t_us: u64) {
        while self.next_tick_us() <= t_us {
            self.tick();
        }
    }

    fn strike_faults(&mut self) {
        let Some(fault) = self.options.fault else {
            return;
        };
        let chip = self.hardware.encoder.bus_mut();
        if fault == InjectedFault::Parity && chip.frames().is_multiple_of(PARITY_ERROR_EVERY_FRAMES)
        {
            chip.corrupt_next_responses(1);
        }
        let Some(start) = self.run_started_us else {
            return;
        };
        if self.fault_struck || self.now_us < start + FAULT_AT_MS * 1000 {
            return;
        }
        self.fault_struck = true;
        match fault {
            InjectedFault::MagnetLost => chip.set_magnet_lost(true),
            InjectedFault::MisoStuck => chip.set_miso_fault(Some(MisoFault::StuckLow)),
            InjectedFault::DriverFault => self.flt_injected = true,
            InjectedFault::OverCurrent => self.over_current = true,
            InjectedFault::ProngSlip => self.plant.slip_prong(),
            InjectedFault::HostSilent
            | InjectedFault::Parity
            | InjectedFault::NoInset
            | InjectedFault::MotorDisconnected => {}
        }
    }

    /// Clear the injected fault's cause (the magnet is put back, the short removed, ...), as a
    /// person would before `ClearFault`. A `ClearFault` request does this by itself.
    pub fn repair(&mut self) {
        let chip = self.hardware.encoder.bus_mut();
        chip.set_magnet_lost(false);
        chip.set_miso_fault(None);
        self.flt_injected = false;
        self.over_current = false;
        self.plant.set_inset_present(true);
        self.plant.set_motor_connected(true);
        self.options.fault = None;
        self.fault_struck = false;
    }
}

/// `flash` (blank) holding the record of a configuration with the encoder on the motor shaft,
/// as a user's `kerfmeter config set --encoder-placement motor` leaves it before a power cycle.
fn with_motor_shaft_config(flash: RamFlash) -> RamFlash {
    let config = DeviceConfig {
        encoder_placement: EncoderPlacement::MotorShaft,
        ..DeviceConfig::DEFAULT
    };
    let mut store = FlashConfigStore::new(flash, FLASH_RANGE);
    embassy_futures::block_on(store.save(&config)).expect("a blank RAM flash takes one record");
    store.release()
}

/// The configuration, opened on `flash` as the board opens it at boot, the flash powered on
/// again; and the flash's clock. The time the flash takes here is not counted: boot time is not
/// simulated, and the watchdog is not running yet.
fn open_config(flash: TwinFlash) -> (OpenedConfig<TwinFlash>, FlashClock) {
    let clock = flash.inner().clock().clone();
    clock.power_on();
    let opened = embassy_futures::block_on(open_config_partition(flash, FLASH_RANGE));
    clock.take_spent_us();
    (opened, clock)
}

/// Who sends host traffic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sender {
    /// The real client (a test, or the host on the serial port).
    Client,
    /// The other host's bursts.
    Burst,
}

/// Frames a link has taken so far, intact or not.
fn frames_seen(link: &Link) -> u32 {
    let frames = link.stats().frames;
    frames.frames_ok + frames.frames_dropped
}

/// The core's clock during one pass of link work.
struct CoreWork {
    now_us: u64,
    frame_cost_us: u64,
    /// Requests handed to the handler.
    handled: u32,
    /// The watchdog fired: nothing after it happens.
    reset: bool,
    /// When the device first put a driven bridge safe in this pass (before a flash operation).
    bridge_safe_at_us: Option<u64>,
}

/// The device as the link sees it inside the twin, acting out how the device is used: a freshly
/// cut gauge is under the prongs when a run starts; the prongs are out of it (the head has moved
/// on) for a reset or a self-test. Each request costs a frame's link work and stalls the core
/// for the flash operations it does.
struct TwinHandler<'a> {
    device: &'a mut TwinDevice,
    /// The motor driver, which the device puts safe before writing flash.
    motor: &'a mut TwinMotor,
    pwm: &'a FakePwm,
    slp: &'a FakeOutput,
    watchdog: &'a SimWatchdog,
    plant: &'a mut Plant,
    gauge_rng: &'a mut Rng,
    cutter: &'a Cutter,
    traced_gauge: &'a TracedGaugeSlot,
    options: &'a TwinOptions,
    run_started: &'a mut Option<u64>,
    truths: &'a TruthLog,
    repair: &'a mut bool,
    flash: &'a FlashClock,
    core: &'a mut CoreWork,
}

impl TwinHandler<'_> {
    /// The device handles `request` on the core's clock; `None` if its watchdog reset it first.
    fn timed(&mut self, request: &Request) -> Option<Response> {
        let core = &mut *self.core;
        if core.reset {
            return None;
        }
        core.handled += 1;
        core.now_us += core.frame_cost_us;
        let driven = self.pwm.duty() > 0.0 && self.slp.is_high();
        self.watchdog.begin(core.now_us);
        let response = WithMotor {
            device: &mut *self.device,
            motor: &mut *self.motor,
        }
        .handle(request);
        let handled_at_us = core.now_us;
        core.now_us = self.watchdog.end();
        if driven && !(self.pwm.duty() > 0.0 && self.slp.is_high()) {
            // Before any flash operation of this request.
            core.bridge_safe_at_us.get_or_insert(handled_at_us);
        }
        core.reset = self.flash.is_cut() || core.now_us >= self.watchdog.deadline_us();
        (!core.reset).then_some(response)
    }
}

impl Handler for TwinHandler<'_> {
    fn host_activity(&mut self) {
        if !self.core.reset {
            self.device.host_activity();
        }
    }

    fn handle(&mut self, request: &Request) -> Response {
        // After a watchdog reset the answer is never sent: any will do.
        let Some(response) = self.timed(request) else {
            return Response::Ok;
        };
        if response != Response::Ok {
            return response;
        }
        match request {
            Request::Run(params) => {
                match self.traced_gauge.get() {
                    Some((geometry, cut)) => self.plant.place_gauge_of(geometry, cut),
                    None => self.plant.place_gauge(self.cutter.cut(self.gauge_rng)),
                }
                let run_id = self.device.controller().run_id();
                self.truths.record(run_id, self.plant.truth_um(params));
                if self.options.fault == Some(InjectedFault::NoInset) {
                    self.plant.lift_prongs();
                }
                *self.run_started = Some(self.core.now_us);
            }
            // The head has moved away from the last gauge: the prongs turn freely back to zero.
            Request::Reset | Request::SelfTest => self.plant.lift_prongs(),
            // Whoever clears a fault is taken to have fixed its cause (put the magnet back,
            // removed the short, ...): the injected fault is gone from now on.
            Request::ClearFault => *self.repair = true,
            _ => {}
        }
        response
    }
}
