//! The Kerfmeter board binary for the ESP32-C3 (feature `esp32c3`) or ESP32-C6 (`esp32c6`).
//!
//! Glue only: this file takes the chip's peripherals, puts the motor in its safe state, sets up
//! the PWM, encoder SPI, current-sense ADC, configuration flash and watchdog, and starts three
//! embassy tasks. All behaviour lives in the `kerfmeter_firmware` library, which is tested on the
//! host; the per-tick sequence is the library's [`Hardware::tick`], the same one the digital twin
//! runs.
//!
//! # Tasks
//!
//! ```text
//!  USB-Serial-JTAG rx ─▶ usb_rx_task ─▶ REQUEST_CHUNKS ─┐ try_receive
//!                                      (Channel)        ▼
//!                                     control_task, every 1 ms: ADC ─▶ Hardware::tick(Device)
//!                                                                     ─▶ feed the watchdog
//!                                                                     ─▶ Link ─▶ Device
//!                                      (Pipe)           │ try_write
//!  USB-Serial-JTAG tx ◀─ usb_tx_task ◀─ RESPONSE_BYTES ◀┘
//! ```
//!
//! - [`control_task`], every [`PERIOD_US`] µs: owns the [`Device`] (controller, configuration,
//!   request handler), the [`Link`] (protocol server), the [`Hardware`] (encoder and motor
//!   drivers), the current-sense ADC and the watchdog. Each tick it reads the motor current (the
//!   conversion started at the end of the previous tick, so the ADC never holds the tick up), runs
//!   [`Hardware::tick`] (encoder, diagnostics, FLT, controller step, motor output), feeds the
//!   watchdog, then hands the bytes received since the last tick to the link, which answers each
//!   complete request from the same `Device`. It never awaits anything but its ticker: received
//!   bytes are taken with `try_receive`, responses are queued with `try_write`, and a response
//!   that does not fit the queue is dropped (the host retries the same `seq`, and the link
//!   answers the retry from memory without carrying the request out twice). It is the only
//!   feeder of the hardware watchdog, so a stalled control loop resets the chip.
//! - [`usb_rx_task`]: USB-Serial-JTAG bytes in, forwarded in chunks of up to [`CHUNK_LEN`] bytes.
//!   It may wait for room in the queue (that only slows the host down).
//! - [`usb_tx_task`]: response bytes out. The device only answers, so nothing else writes to
//!   that port. A host that stops reading makes a write time out after [`LINK_WRITE_TIMEOUT`];
//!   the pending responses are then dropped.
//!
//! # Configuration flash
//!
//! The device configuration is kept in the `nvs` data partition of the partition table that
//! espflash writes by default (ESP-IDF's single-app table: `nvs` at 0x9000, 24 KiB), found at
//! boot by reading the partition table. Without such a partition (or with an unreadable table)
//! the device runs without persistence: a new configuration lasts until reboot, and UART0 says
//! so at boot. The app itself never uses ESP-IDF's NVS: the partition holds the library's
//! [`FlashConfigStore`] and nothing else, so when it holds no valid record but is not blank
//! (typically ESP-IDF NVS pages left by a factory firmware, which the store would take for free
//! space), it is erased at boot. A `SetConfig` writes it synchronously from the control
//! task (the device refuses it while the motor runs), stalling the ticks for the duration of the
//! write; the ticker then restarts instead of bursting through the missed ticks.
//!
//! Logs and panic messages go to UART0 (esp-println's `uart` feature), never to the protocol
//! port. The control loop itself does not log (a UART write would stall the tick).
//!
//! Panic path: esp-backtrace prints the backtrace to UART0, then spins with interrupts off.
//! Nobody feeds the watchdog any more, so it resets the chip within [`WATCHDOG_TIMEOUT`]. From
//! reset on, the pins are high-impedance inputs and the board's pull-down resistor on the G2's
//! `SLP` input (a wiring requirement, see [`pins`]) puts the driver to sleep: the motor is safe
//! without any help from software.

#![no_std]
#![no_main]

mod pins;

use core::ops::Range;

use embassy_embedded_hal::adapter::BlockingAsync;
use embassy_executor::Spawner;
use embassy_sync::{blocking_mutex::raw::CriticalSectionRawMutex, channel::Channel, pipe::Pipe};
use embassy_time::{Duration, Instant, Ticker};
use embedded_hal_bus::spi::ExclusiveDevice;
use embedded_storage_async::nor_flash::{NorFlash, ReadNorFlash};
use esp_backtrace as _;
use esp_bootloader_esp_idf::partitions;
use esp_hal::{
    Async, Blocking,
    analog::adc::{Adc, AdcCalCurve, AdcConfig, AdcPin, Attenuation},
    clock::CpuClock,
    delay::Delay,
    gpio::{DriveMode, Input, InputConfig, Level, Output, OutputConfig, Pull},
    ledc::{
        LSGlobalClkSource, Ledc, LowSpeed,
        channel::{self, ChannelIFace},
        timer::{self, TimerIFace},
    },
    peripherals::{ADC1, FLASH, TIMG1},
    rng::{Rng, Trng, TrngSource},
    spi::{
        Mode,
        master::{Config as SpiConfig, Spi},
    },
    time::Rate,
    timer::timg::{MwdtStage, TimerGroup, Wdt},
    usb::usb_serial_jtag::{UsbSerialJtag, UsbSerialJtagRx, UsbSerialJtagTx},
};
use esp_storage::FlashStorage;
use kerfmeter_firmware::{
    as5048a::{As5048a, EncoderSettings},
    config_store::{ConfigPersist, ConfigSource, FlashConfigStore, StoreError},
    controller::PERIOD_US,
    device::Device,
    hardware::Hardware,
    link::Link,
    motor::G2Motor,
};
use kerfmeter_protocol::{DeviceConfig, MAX_RESPONSE_FRAME_LEN, heapless};
use static_cell::StaticCell;

esp_bootloader_esp_idf::esp_app_desc!();

/// The name `GetInfo` reports.
#[cfg(feature = "esp32c3")]
const BOARD_NAME: &str = "esp32c3";
/// The name `GetInfo` reports.
#[cfg(feature = "esp32c6")]
const BOARD_NAME: &str = "esp32c6";

/// Motor PWM frequency: above hearing, within the G2's limit.
const PWM_FREQUENCY: Rate = Rate::from_khz(20);
/// What to ask esp-hal's LEDC timer for so that the pin sees [`PWM_FREQUENCY`].
#[cfg(feature = "esp32c3")]
const LEDC_TIMER_REQUEST: Rate = PWM_FREQUENCY;
/// What to ask esp-hal's LEDC timer for so that the pin sees [`PWM_FREQUENCY`]. On the C6,
/// esp-hal 1.2.2 clocks LEDC from PLL_F80M (80 MHz) but computes the divider from APB_CLK
/// (40 MHz), and then refuses 20 kHz with 11 bits (divider below 1). Asking for half gives the
/// right divider and 20 kHz on the pin. Not yet checked on hardware: scope the pin, and drop
/// this once esp-hal computes the C6 divider from the LEDC clock.
#[cfg(feature = "esp32c6")]
const LEDC_TIMER_REQUEST: Rate = Rate::from_hz(PWM_FREQUENCY.as_hz() / 2);
/// AS5048A SPI clock: the part allows 10 MHz.
const ENCODER_SPI_FREQUENCY: Rate = Rate::from_mhz(10);
/// Hardware watchdog timeout: a control loop stalled this long resets the chip. It also bounds
/// a configuration write (a flash sector erase takes tens of ms, a few hundred at worst).
const WATCHDOG_TIMEOUT: esp_hal::time::Duration = esp_hal::time::Duration::from_millis(500);
/// How long response bytes may wait for the host to read before they are dropped (the host
/// retries, and the link answers the retry from memory).
const LINK_WRITE_TIMEOUT: Duration = Duration::from_millis(100);
/// The control period.
const CONTROL_PERIOD: Duration = Duration::from_micros(PERIOD_US);
/// Ticks without a finished current-sense conversion after which the current counts as unknown.
const CURRENT_STALE_TICKS: u32 = 10;

/// Received bytes travel to the control task in chunks of at most this many bytes (the
/// USB-Serial-JTAG FIFO size).
const CHUNK_LEN: usize = 64;
/// Received chunks the control task has not taken yet.
const REQUEST_QUEUE_CHUNKS: usize = 8;
/// Response bytes not yet written to USB: room for two of the largest response frames.
const RESPONSE_QUEUE_BYTES: usize = 2 * MAX_RESPONSE_FRAME_LEN;

/// A piece of the byte stream from the host.
type Chunk = heapless::Vec<u8, CHUNK_LEN>;

/// Host bytes, from [`usb_rx_task`] to [`control_task`].
static REQUEST_CHUNKS: Channel<CriticalSectionRawMutex, Chunk, REQUEST_QUEUE_CHUNKS> =
    Channel::new();
/// Whole response frames, from [`control_task`] to [`usb_tx_task`].
static RESPONSE_BYTES: Pipe<CriticalSectionRawMutex, RESPONSE_QUEUE_BYTES> = Pipe::new();

/// The LEDC timer behind the motor PWM channel. A channel borrows its timer, so the timer lives
/// in a static to give a `'static` channel to a task.
static PWM_TIMER: StaticCell<timer::Timer<'static, LowSpeed>> = StaticCell::new();

/// The motor PWM output.
type MotorPwm = channel::Channel<'static, LowSpeed>;
/// The AS5048A on SPI2, with its chip select, as a blocking embedded-hal `SpiDevice`.
type EncoderSpi = ExclusiveDevice<Spi<'static, Blocking>, Output<'static>, Delay>;
/// The encoder and motor drivers: PWM, `DIR`, `SLP` outputs and the `FLT` input.
type BoardHardware =
    Hardware<EncoderSpi, MotorPwm, Output<'static>, Output<'static>, Input<'static>>;
/// The flash behind the configuration store.
type ConfigFlash = BlockingAsync<FlashStorage<'static>>;

/// Where a new configuration is persisted.
enum BoardStore {
    /// In the `nvs` partition.
    Flash(FlashConfigStore<ConfigFlash>),
    /// Nowhere: no usable flash region was found, the configuration lasts until reboot.
    RamOnly,
}

impl ConfigPersist for BoardStore {
    fn save(&mut self, config: &DeviceConfig) -> Result<(), StoreError> {
        match self {
            // The flash completes every operation at once (blocking flash behind an async
            // adapter), as `FlashConfigStore`'s synchronous `save` requires.
            BoardStore::Flash(store) => ConfigPersist::save(store, config),
            BoardStore::RamOnly => ConfigPersist::save(&mut (), config),
        }
    }
}

/// The G2 current-sense input on ADC1, read one conversion behind: each tick collects the
/// conversion started at the end of the previous tick and starts the next one, so that the tick
/// never waits for the ADC.
struct CurrentSense {
    adc: Adc<'static, ADC1<'static>, Blocking>,
    pin: AdcPin<pins::CurrentSensePin, ADC1<'static>, AdcCalCurve<ADC1<'static>>>,
    last_a: f32,
    stale_ticks: u32,
}

impl CurrentSense {
    /// The motor current for this tick, A: the last finished conversion. After
    /// [`CURRENT_STALE_TICKS`] ticks without one the current is unknown (`None`), and the
    /// controller faults with `OverCurrent`.
    fn read_a(&mut self) -> Option<f32> {
        if !self.poll() {
            self.stale_ticks = self.stale_ticks.saturating_add(1);
        }
        (self.stale_ticks <= CURRENT_STALE_TICKS).then_some(self.last_a)
    }

    /// Start the next conversion (late in the tick, well after the last one was read out, as
    /// the ADC needs a few of its clock cycles between the two).
    fn start_next(&mut self) {
        self.poll();
    }

    /// Start a conversion if none is running, or take the running one's result if it has
    /// finished. True when a result was taken.
    fn poll(&mut self) -> bool {
        match self.adc.read_oneshot(&mut self.pin) {
            Ok(millivolts) => {
                self.last_a = pins::motor_current_a(millivolts);
                self.stale_ticks = 0;
                true
            }
            Err(_) => false,
        }
    }
}

#[esp_rtos::main]
async fn main(spawner: Spawner) {
    let mut p = esp_hal::init(esp_hal::Config::default().with_cpu_clock(CpuClock::max()));
    let pins = pins::take!(p);

    // Motor safe state first: driver asleep, direction low, PWM pin low.
    let sleep = Output::new(pins.motor_sleep, Level::Low, OutputConfig::default());
    let dir = Output::new(pins.motor_dir, Level::Low, OutputConfig::default());
    let pwm_pin = Output::new(pins.motor_pwm, Level::Low, OutputConfig::default());

    // Motor PWM: 20 kHz, 11-bit duty, starting at duty 0.
    let mut ledc = Ledc::new(p.LEDC);
    ledc.set_global_slow_clock(LSGlobalClkSource::APBClk);
    let pwm_timer = PWM_TIMER.init(ledc.timer::<LowSpeed>(timer::Number::Timer0));
    pwm_timer
        .configure(timer::config::Config {
            duty: timer::config::Duty::Duty11Bit,
            clock_source: timer::LSClockSource::APBClk,
            frequency: LEDC_TIMER_REQUEST,
        })
        .expect("LEDC timer: 20 kHz with 11-bit duty");
    let mut pwm = ledc.channel(channel::Number::Channel0, pwm_pin);
    pwm.configure(channel::config::Config {
        timer: &*pwm_timer,
        duty_pct: 0,
        drive_mode: DriveMode::PushPull,
    })
    .expect("LEDC channel");

    let fault = Input::new(pins.motor_fault, InputConfig::default().with_pull(Pull::Up));

    // The motor driver: takes the pins and drives them safe again (duty 0, asleep, DIR low).
    let (motor, safe) = G2Motor::new(pwm, dir, sleep, fault);
    if let Err(e) = safe {
        esp_println::println!("motor driver: safe state failed: {e:?}");
    }

    // A per-boot id from the TRNG (the SAR ADC as entropy source), before the ADC is used for
    // current sensing.
    let boot_id = {
        let _entropy = TrngSource::new(p.RNG, p.ADC1.reborrow());
        Trng::try_new().map_or_else(|_| Rng::new().random(), |trng| trng.random())
    };

    esp_println::println!(
        "kerfmeter-firmware {} on {BOARD_NAME}, boot id {boot_id:08x}",
        env!("CARGO_PKG_VERSION")
    );

    // Current sense: ADC1, 11 dB, calibrated to millivolts by the chip's eFuse curve.
    let mut adc_config = AdcConfig::new();
    let current_pin = adc_config
        .enable_pin_with_cal::<_, AdcCalCurve<ADC1>>(pins.motor_current, Attenuation::_11dB);
    let current = CurrentSense {
        adc: Adc::new(p.ADC1, adc_config),
        pin: current_pin,
        last_a: 0.0,
        stale_ticks: 0,
    };

    // The stored configuration (defaults if there is none).
    let (config, source, store) = open_config_store(p.FLASH);
    esp_println::println!(
        "configuration: {}",
        match source {
            ConfigSource::Stored => "stored",
            ConfigSource::Missing => "defaults (none stored)",
            ConfigSource::Corrupt => "defaults (stored record unusable)",
        }
    );

    // Encoder: SPI2, mode 1, 10 MHz, blocking (a transfer of two bytes takes a few µs); chip
    // select as a GPIO, idle high.
    let spi = Spi::new(
        p.SPI2,
        SpiConfig::default()
            .with_frequency(ENCODER_SPI_FREQUENCY)
            .with_mode(Mode::_1),
    )
    .expect("SPI2 config")
    .with_sck(pins.encoder_sclk)
    .with_mosi(pins.encoder_mosi)
    .with_miso(pins.encoder_miso);
    let encoder_cs = Output::new(pins.encoder_cs, Level::High, OutputConfig::default());
    let Ok(encoder_spi) = ExclusiveDevice::new(spi, encoder_cs, Delay::new());
    let encoder = As5048a::new(encoder_spi, EncoderSettings::from_config(&config));

    let hardware = Hardware::new(encoder, motor);

    esp_rtos::start(TimerGroup::new(p.TIMG0).timer0, p.FROM_CPU_INTR0);

    // Hardware watchdog: TIMG1's MWDT resets the whole system unless `control_task` feeds it.
    let mut watchdog = TimerGroup::new(p.TIMG1).wdt;
    watchdog.set_timeout(MwdtStage::Stage0, WATCHDOG_TIMEOUT);
    watchdog.enable();

    let (usb_rx, usb_tx) = UsbSerialJtag::new(p.USB_DEVICE).into_async().split();

    spawner.spawn(
        control_task(
            hardware,
            current,
            watchdog,
            Boot {
                boot_id,
                config,
                source,
                store,
            },
        )
        .expect("control task"),
    );
    spawner.spawn(usb_rx_task(usb_rx).expect("usb rx task"));
    spawner.spawn(usb_tx_task(usb_tx).expect("usb tx task"));
}

/// What the [`Device`] is built from.
struct Boot {
    boot_id: u32,
    config: DeviceConfig,
    source: ConfigSource,
    store: BoardStore,
}

/// The fixed-rate control tick; owns the device, the link and the drivers. The only feeder of
/// the watchdog.
///
/// The [`Device`] (its controller holds the run's sample log, ≈24 KiB) and the [`Link`] are built
/// here rather than passed in: a large async-fn argument would be stored twice in the task's
/// static future.
#[embassy_executor::task]
async fn control_task(
    mut hardware: BoardHardware,
    mut current: CurrentSense,
    mut watchdog: Wdt<TIMG1<'static>>,
    boot: Boot,
) {
    let mut device = Device::with_config(
        BOARD_NAME,
        boot.boot_id,
        boot.config,
        boot.source,
        boot.store,
    );
    let mut link = Link::new();
    let mut ticker = Ticker::every(CONTROL_PERIOD);
    loop {
        let started = Instant::now();
        let current_a = current.read_a();
        hardware.tick(started.as_micros(), current_a, &mut device);
        current.start_next();
        watchdog.feed();

        // Requests, answered at the state of this tick.
        while let Ok(chunk) = REQUEST_CHUNKS.try_receive() {
            link.receive(&chunk, &mut device, |frame| {
                // Whole frames only; one that does not fit is dropped, and the host's retry of
                // the same seq is answered from the link's memory.
                if RESPONSE_BYTES.free_capacity() >= frame.len() {
                    let _ = RESPONSE_BYTES.try_write(frame);
                }
            });
        }

        // A tick that overran (a configuration written to flash) restarts the ticker rather than
        // bursting through the missed ticks; the controller sees the gap.
        if started.elapsed() > CONTROL_PERIOD {
            ticker.reset();
        }
        ticker.next().await;
    }
}

/// Host bytes in, to the control task.
#[embassy_executor::task]
async fn usb_rx_task(mut rx: UsbSerialJtagRx<'static, Async>) {
    let mut buf = [0u8; CHUNK_LEN];
    loop {
        let n = match embedded_io_async::Read::read(&mut rx, &mut buf).await {
            Ok(n) => n,
            Err(_) => continue,
        };
        // Cannot fail: `n` is at most `CHUNK_LEN`.
        if let Ok(chunk) = Chunk::from_slice(&buf[..n])
            && !chunk.is_empty()
        {
            REQUEST_CHUNKS.send(chunk).await;
        }
    }
}

/// Response bytes out, to the host.
#[embassy_executor::task]
async fn usb_tx_task(mut tx: UsbSerialJtagTx<'static, Async>) {
    let mut buf = [0u8; CHUNK_LEN];
    loop {
        let n = RESPONSE_BYTES.read(&mut buf).await;
        let write = async {
            embedded_io_async::Write::write_all(&mut tx, &buf[..n]).await?;
            embedded_io_async::Write::flush(&mut tx).await
        };
        // A host that stopped reading must not stall the link: drop what is pending (the host
        // resynchronises at the next frame delimiter and retries).
        if embassy_time::with_timeout(LINK_WRITE_TIMEOUT, write)
            .await
            .is_err()
        {
            RESPONSE_BYTES.clear();
        }
    }
}

/// The configuration store in the `nvs` partition, and the configuration loaded from it.
///
/// Falls back to the defaults and no persistence (logged) when no usable partition is found.
/// When no valid record is found and the partition is not blank, it holds data this firmware
/// did not write (typically ESP-IDF NVS pages left by a board's factory firmware, which the
/// store would misread as free space): it is erased, so that the next `SetConfig` persists.
fn open_config_store(flash: FLASH<'static>) -> (DeviceConfig, ConfigSource, BoardStore) {
    let mut flash = FlashStorage::new(flash);
    let range = match nvs_partition(&mut flash) {
        Ok(range) => range,
        Err(why) => {
            esp_println::println!("configuration flash: {why}; configuration lasts until reboot");
            return (
                DeviceConfig::DEFAULT,
                ConfigSource::Missing,
                BoardStore::RamOnly,
            );
        }
    };
    esp_println::println!(
        "configuration flash: nvs partition {:#x}..{:#x}",
        range.start,
        range.end
    );
    let mut store = FlashConfigStore::new(BlockingAsync::new(flash), range.clone());
    let (config, source) = embassy_futures::block_on(store.load());
    if !source.defaults_in_use() {
        return (config, source, BoardStore::Flash(store));
    }
    let mut flash = store.release();
    match embassy_futures::block_on(erase_if_not_blank(&mut flash, range.clone())) {
        Ok(false) => {}
        Ok(true) => {
            esp_println::println!("configuration flash: no valid record, foreign data erased")
        }
        Err(()) => {
            esp_println::println!(
                "configuration flash: unreadable or not erasable; configuration lasts until reboot"
            );
            return (config, source, BoardStore::RamOnly);
        }
    }
    (
        config,
        source,
        BoardStore::Flash(FlashConfigStore::new(flash, range)),
    )
}

/// The flash range of the partition table's `nvs` data partition.
///
/// Matched by raw type and subtype (data, nvs) and label rather than with the crate's typed
/// lookup, which panics on a subtype it does not know.
fn nvs_partition(flash: &mut FlashStorage<'static>) -> Result<Range<u32>, &'static str> {
    /// Partition type "data", subtype "nvs" (ESP-IDF's numbering).
    const DATA: u8 = 0x01;
    const NVS: u8 = 0x02;
    let mut table = [0u8; partitions::PARTITION_TABLE_MAX_LEN];
    let table = partitions::read_partition_table(flash, &mut table)
        .map_err(|_| "partition table unreadable")?;
    let nvs = table
        .iter()
        .find(|e| e.raw_type() == DATA && e.raw_subtype() == NVS && e.label_as_str() == "nvs")
        .ok_or("no `nvs` partition in the partition table")?;
    if nvs.is_read_only() || nvs.is_encrypted() {
        return Err("the `nvs` partition is read-only or encrypted");
    }
    let page = FlashStorage::SECTOR_SIZE;
    let range = nvs.offset()..nvs.offset().saturating_add(nvs.len());
    if range.start % page != 0 || range.end % page != 0 || range.len() < 2 * page as usize {
        return Err("the `nvs` partition is not at least two whole flash sectors");
    }
    Ok(range)
}

/// Erase `range` unless it is blank (all 0xFF). True when it was erased.
async fn erase_if_not_blank(flash: &mut ConfigFlash, range: Range<u32>) -> Result<bool, ()> {
    /// Word-aligned, so that esp-storage reads straight into it.
    #[repr(align(4))]
    struct Block([u8; 256]);
    let mut block = Block([0; 256]);
    let mut blank = true;
    for offset in range.clone().step_by(block.0.len()) {
        flash.read(offset, &mut block.0).await.map_err(|_| ())?;
        if block.0.iter().any(|&b| b != 0xFF) {
            blank = false;
            break;
        }
    }
    if blank {
        return Ok(false);
    }
    flash.erase(range.start, range.end).await.map_err(|_| ())?;
    Ok(true)
}
