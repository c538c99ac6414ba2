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
//! [`FRAMES_PER_TICK`](kerfmeter_firmware::link::FRAMES_PER_TICK) frames a pass (the firmware's
//! rule, see its `link` module): each pass is
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
//!
//! The twin is built and booted here; its other concerns are one module each: `ticks`
//! (simulated time), `link` (the host's frames and the other host's bursts), `faults` (injected
//! faults) and `inspect` (its state read, and acted on by hand).

use kerfmeter_firmware::as5048a::{As5048a, EncoderSettings};
use kerfmeter_firmware::board::conversion::Conversions;
use kerfmeter_firmware::board::partition::{ConfigStorage, OpenedConfig, open_config_partition};
use kerfmeter_firmware::config_store::{ConfigSource, FlashConfigStore};
use kerfmeter_firmware::device::Device;
use kerfmeter_firmware::fakes::as5048a::FakeAs5048a;
use kerfmeter_firmware::fakes::flash::{FlashClock, RamFlash};
use kerfmeter_firmware::fakes::pins::{FakeInput, FakeOutput, FakePwm};
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_firmware::hardware::Hardware;
use kerfmeter_firmware::health::BootFacts;
use kerfmeter_firmware::link::Link;
use kerfmeter_firmware::motor::G2Motor;
use kerfmeter_firmware::watchdog::WatchdogFlash;
use kerfmeter_protocol::{
    AdcCalibration, BrownOutDetector, ChipRevision, DeviceConfig, EncoderPlacement, ResetReason,
};

use crate::adc::TwinAdc;
use crate::encoder::EncoderErrors;
use crate::gauge_trace::TracedGaugeSlot;
use crate::options::{InjectedFault, TwinOptions};
use crate::plant::{Bridge, Cutter, Plant};
use crate::sense::Sense;
use crate::timing::{HostBursts, SimWatchdog, TickClock};
use crate::truth::TruthLog;

mod faults;
mod inspect;
mod link;
mod ticks;

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
    /// The current-sense and supply-sense pins as the ADC sees them.
    sense: Sense,
    /// The board's ADC1, one conversion at a time, started at the end of a tick and collected
    /// at the next (the board reads one conversion behind).
    adc: TwinAdc,
    /// The firmware's conversion schedule over it (the supply every tenth tick, a stalled
    /// conversion given up), as the board binary runs it.
    conversions: Conversions,
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
    /// What the twin's chip says about itself at boot (`GetDiagnostics`), kept across reboots
    /// but for the reset's reason ([`Twin::set_boot_facts`]).
    boot_facts: BootFacts,
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
        let mut device = Device::with_config(
            "twin",
            boot_id,
            opened.config,
            opened.source,
            opened.storage,
        );
        let boot_facts = twin_boot_facts(&options);
        device.set_boot_facts(boot_facts);
        device.set_driver(options.driver);
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
            sense: Sense::new(&options.plant, stream(0))
                .for_board(options.driver, options.adc_uncalibrated),
            adc: TwinAdc::new(),
            conversions: Conversions::new(),
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
            boot_facts,
        }
    }

    /// Set what the twin's chip says about itself at boot (the last reset's reason, its
    /// revision, the ADC's calibration, the brown-out detector), as a board reads them: from
    /// now on and after each reboot, whose own reason replaces `reset_reason`. The `CS` reading
    /// follows [`TwinOptions::adc_uncalibrated`], not this.
    pub fn set_boot_facts(&mut self, facts: BootFacts) {
        self.boot_facts = facts;
        self.device.set_boot_facts(facts);
    }

    /// Power-cycle the device: new boot id, state lost, flash (configuration) kept, hub where it
    /// stands; the other host keeps its rhythm. It reports a power-on reset.
    pub fn reboot(&mut self) {
        self.reset_by(ResetReason::PowerOn);
    }

    /// Reset the device for `reason` (its watchdog: [`ResetReason::Watchdog`]), as
    /// [`Twin::reboot`] does; `GetDiagnostics` then reports `reason`.
    pub fn reset_by(&mut self, reason: ResetReason) {
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
        let boot_facts = BootFacts {
            reset_reason: reason,
            ..self.boot_facts
        };
        *self = Self::boot(self.options, flash, self.boots + 1, self.now_us);
        self.set_boot_facts(boot_facts);
        self.magnet_on_motor_shaft = magnet_on_motor_shaft;
        self.traced_gauge = traced_gauge;
        self.plant = plant;
        self.bursts = bursts;
        self.truths = truths;
    }
}

/// What a twin's chip says at its first boot: a power-on, an ESP32-C3 of revision 0.4 with ADC
/// calibration eFuses of version 1 (unless [`TwinOptions::adc_uncalibrated`]) and a brown-out
/// detector that resets it.
fn twin_boot_facts(options: &TwinOptions) -> BootFacts {
    BootFacts {
        reset_reason: ResetReason::PowerOn,
        chip_revision: Some(ChipRevision { major: 0, minor: 4 }),
        adc_calibration: if options.adc_uncalibrated {
            AdcCalibration::Uncalibrated
        } else {
            AdcCalibration::Efuse { version: 1 }
        },
        brown_out: BrownOutDetector::Resets,
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
