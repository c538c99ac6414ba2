//! The twin itself: the real firmware (link, device, controller, AS5048A and G2 drivers, the
//! shared control tick) wired to fake peripherals that speak the chips' protocols, stepped in
//! lock-step with the [`Plant`], deterministic for a seed.
//!
//! Time is simulated: [`Twin::tick`] advances one 1 ms control period. Served on a serial port
//! ([`crate::serve()`]), simulated time runs ahead of the host by at most [`MAX_LEAD_MS`] past
//! its last request — much faster than real time, yet a host that keeps polling never looks
//! silent to the device's watchdog — or follows the wall clock in real-time mode.

use kerfmeter_protocol::{DeviceConfig, Request, Response, RunState};

use crate::options::{InjectedFault, TwinOptions};
use crate::plant::{Bridge, Plant};
use crate::sense::Sense;
use crate::truth::TruthLog;
use kerfmeter_firmware::as5048a::{As5048a, EncoderSettings};
use kerfmeter_firmware::config_store::FlashConfigStore;
use kerfmeter_firmware::controller::PERIOD_US;
use kerfmeter_firmware::device::Device;
use kerfmeter_firmware::fakes::as5048a::{FakeAs5048a, MisoFault};
use kerfmeter_firmware::fakes::flash::RamFlash;
use kerfmeter_firmware::fakes::pins::{FakeInput, FakeOutput, FakePwm};
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_firmware::hardware::Hardware;
use kerfmeter_firmware::link::{Handler, Link};
use kerfmeter_firmware::motor::G2Motor;

/// How far simulated time may run past the host's last request, ms.
pub const MAX_LEAD_MS: u64 = 100;
/// When a mid-run fault strikes, ms after the run started.
pub const FAULT_AT_MS: u64 = 200;
/// Every this many encoder frames, one response is corrupted (`parity` fault).
pub const PARITY_ERROR_EVERY_FRAMES: u32 = 40;

/// Mixed into the seed of the random stream that draws each gauge's kerf, so that the gauges a
/// seed gives do not depend on how many ticks (each drawing current noise from the main stream)
/// passed before each run: host timing decides that, and must not decide the gauges.
const GAUGE_STREAM: u64 = 0x6761_7567_6573_0000;

/// Flash reserved for the configuration store (four 4 KiB sectors).
const FLASH_PAGES: usize = 4;

type TwinHardware = Hardware<FakeAs5048a, FakePwm, FakeOutput, FakeOutput, FakeInput>;

/// The twin: firmware, fake peripherals and plant.
pub struct Twin {
    options: TwinOptions,
    rng: Rng,
    /// Draws each gauge's kerf (see [`GAUGE_STREAM`]).
    gauge_rng: Rng,
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
    device: Device<FlashConfigStore<RamFlash>>,
    link: Link,
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
        Self::boot(options, RamFlash::new(FLASH_PAGES), 0)
    }

    /// Boot a twin that records its runs' truths in `truths` (shared with the caller).
    pub fn with_truth_log(options: TwinOptions, truths: TruthLog) -> Self {
        Self {
            truths,
            ..Self::new(options)
        }
    }

    fn boot(options: TwinOptions, flash: RamFlash, boots: u32) -> Self {
        let mut rng = Rng::new(options.seed ^ (u64::from(boots) << 32));
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
        let mut store = FlashConfigStore::new(flash, 0..FLASH_PAGES as u32 * RamFlash::PAGE);
        let (config, source) = embassy_futures::block_on(store.load());
        let encoder = As5048a::new(chip, EncoderSettings::from_config(&config));
        let device = Device::with_config("twin", boot_id, config, source, store);
        let mut plant = Plant::new(options.plant, options.gauge, options.kerf_um);
        match options.fault {
            Some(InjectedFault::NoInset) => plant.set_inset_present(false),
            Some(InjectedFault::MotorDisconnected) => plant.set_motor_connected(false),
            _ => {}
        }
        Self {
            gauge_rng: Rng::new(options.seed ^ GAUGE_STREAM ^ (u64::from(boots) << 32)),
            sense: Sense::new(&options.plant, options.seed ^ (u64::from(boots) << 32)),
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
            now_us: 0,
            last_request_us: 0,
            run_started_us: None,
            fault_struck: false,
            over_current: false,
            boots,
            truths: TruthLog::default(),
        }
    }

    /// Power-cycle the device: new boot id, state lost, flash (configuration) kept, hub where it
    /// stands.
    pub fn reboot(&mut self) {
        let flash = core::mem::replace(
            &mut self.device,
            Device::with_config(
                "twin",
                0,
                DeviceConfig::DEFAULT,
                kerfmeter_firmware::config_store::ConfigSource::Missing,
                FlashConfigStore::new(
                    RamFlash::new(FLASH_PAGES),
                    0..FLASH_PAGES as u32 * RamFlash::PAGE,
                ),
            ),
        )
        .into_store()
        .release();
        let plant = self.plant.clone();
        let now = self.now_us;
        let truths = self.truths.clone();
        truths.clear();
        *self = Self::boot(self.options, flash, self.boots + 1);
        self.plant = plant;
        self.truths = truths;
        self.now_us = now;
        self.last_request_us = now;
    }

    /// Simulated time, µs.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// The plant (for checks).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The device (for checks).
    pub fn device(&self) -> &Device<FlashConfigStore<RamFlash>> {
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

    /// True when the motor bridge is in its safe state (duty 0 or driver asleep).
    pub fn motor_safe(&self) -> bool {
        self.pwm.duty() == 0.0 || !self.slp.is_high()
    }

    /// True while the injected `host-silent` fault swallows the host's bytes.
    fn host_muted(&self) -> bool {
        self.options.fault == Some(InjectedFault::HostSilent)
            && self.fault_struck
            && !matches!(self.device.controller().run_state(), RunState::Fault(_))
    }

    /// Bytes from the host: handled by the firmware's link; responses go to `transmit`.
    pub fn receive(&mut self, bytes: &[u8], transmit: impl FnMut(&[u8])) {
        if self.host_muted() {
            return;
        }
        self.with_handler(|handler, link| {
            link.receive(bytes, handler, transmit);
        });
    }

    /// A request without framing (in-process tests).
    pub fn request(&mut self, request: &Request) -> Response {
        self.with_handler(|handler, _| handler.handle(request))
    }

    /// Host traffic goes through the twin's handler (which acts out how the device is used);
    /// a `ClearFault` among it repairs the injected fault afterwards.
    fn with_handler<R>(&mut self, serve: impl FnOnce(&mut TwinHandler<'_>, &mut Link) -> R) -> R {
        self.last_request_us = self.now_us;
        let mut repair = false;
        let result = serve(
            &mut TwinHandler {
                device: &mut self.device,
                plant: &mut self.plant,
                gauge_rng: &mut self.gauge_rng,
                options: &self.options,
                run_started: &mut self.run_started_us,
                truths: &self.truths,
                repair: &mut repair,
                now_us: self.now_us,
            },
            &mut self.link,
        );
        if repair {
            self.repair();
        }
        result
    }

    /// Ticks the twin may run before it must wait for the host (lock-step mode).
    pub fn lead_ticks(&self) -> u64 {
        let limit = self.last_request_us + MAX_LEAD_MS * 1000;
        let host_silent =
            self.options.fault == Some(InjectedFault::HostSilent) && self.fault_struck;
        if host_silent {
            return u64::MAX;
        }
        limit.saturating_sub(self.now_us) / PERIOD_US
    }

    /// One 1 ms control period: sensors → firmware tick → motor → physics.
    pub fn tick(&mut self) {
        self.strike_faults();
        let cw = self.plant.hub_cw_deg();
        self.hardware.encoder.bus_mut().set_angle_deg(cw);
        let sensed = self.sense.sample(
            &self.plant.electrical(),
            self.now_us,
            self.over_current,
            &mut self.rng,
        );
        self.flt
            .set_high(!self.flt_injected && !self.plant.driver_fault());
        let out = self.hardware.tick(
            self.now_us,
            Some(sensed.current_a),
            Some(sensed.supply_v),
            &mut self.device,
        );
        debug_assert_eq!(out.is_safe(), self.motor_safe());
        let clockwise = self.dir.is_high();
        let cw_sign = if clockwise { 1.0 } else { -1.0 };
        let jam_sign = match self.options.gauge.jam_direction {
            kerfmeter_protocol::JamDirection::Clockwise => 1.0,
            kerfmeter_protocol::JamDirection::CounterClockwise => -1.0,
        };
        let bridge = Bridge {
            duty: f64::from(self.pwm.duty()),
            direction: cw_sign * jam_sign,
            awake: self.slp.is_high(),
        };
        self.plant.tick(&bridge);
        self.now_us += PERIOD_US;
    }

    /// Run `n` ticks.
    pub fn advance_ticks(&mut self, n: u64) {
        for _ in 0..n {
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

/// The device as the link sees it inside the twin, acting out how the device is used: a freshly
/// cut gauge is under the prongs when a run starts; the prongs are out of it (the head has moved
/// on) for a reset or a self-test.
struct TwinHandler<'a> {
    device: &'a mut Device<FlashConfigStore<RamFlash>>,
    plant: &'a mut Plant,
    gauge_rng: &'a mut Rng,
    options: &'a TwinOptions,
    run_started: &'a mut Option<u64>,
    truths: &'a TruthLog,
    repair: &'a mut bool,
    now_us: u64,
}

impl Handler for TwinHandler<'_> {
    fn handle(&mut self, request: &Request) -> Response {
        let response = self.device.handle(request);
        if response != Response::Ok {
            return response;
        }
        match request {
            Request::Run(params) => {
                let kerf = self.options.kerf_um
                    + f64::from(self.gauge_rng.normal()) * self.options.kerf_sd_um;
                self.plant.place_gauge(kerf.max(0.0));
                let run_id = self.device.controller().run_id();
                self.truths.record(run_id, self.plant.truth_um(params));
                if self.options.fault == Some(InjectedFault::NoInset) {
                    self.plant.lift_prongs();
                }
                *self.run_started = Some(self.now_us);
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
