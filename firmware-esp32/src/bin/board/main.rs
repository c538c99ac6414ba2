//! The Kerfmeter board binary for the ESP32-C3 (feature `esp32c3`) or ESP32-C6 (`esp32c6`).
//!
//! Glue only: this file takes the chip's peripherals, puts the motor in its safe state, sets up
//! the PWM, encoder SPI, current-sense and supply ADC and configuration flash through the library's
//! [`board`] module (the same set-up the on-target tests use), starts the watchdog
//! ([`BoardWatchdog`]), and starts three embassy tasks. All behaviour lives in the `kerfmeter_firmware` library, which is tested
//! on the host; the per-tick sequence is the library's [`Hardware::tick`], the same one the
//! digital twin runs.
//!
//! # Tasks
//!
//! ```text
//!  USB-Serial-JTAG rx ─▶ usb_rx_task ─▶ REQUEST_CHUNKS ─┐ try_receive
//!                                      (Channel)        ▼
//!                                     control_task, every 1 ms: ADC1 ─▶ Hardware::tick(Device)
//!                                                                     ─▶ feed the watchdog
//!                                                                     ─▶ Inbox ─▶ Link ─▶ Device
//!                                                                      (FRAMES_PER_TICK at most)
//!                                      (Pipe)           │ try_write
//!  USB-Serial-JTAG tx ◀─ usb_tx_task ◀─ RESPONSE_BYTES ◀┘
//! ```
//!
//! - [`control_task`], every [`PERIOD_US`] µs: owns the [`Device`] (controller, configuration,
//!   request handler), the [`Link`] (protocol server), the [`Hardware`] (encoder and motor
//!   drivers), the analog inputs on ADC1 (`board::adc`) and the watchdog. Each tick it takes the
//!   current-sense reading and the motor supply (conversions started at the end of the previous
//!   tick, so the ADC never holds the tick up; the supply every tenth tick in place of the current
//!   sense; a conversion that never finishes is given up and the ADC driver opened again,
//!   `board::conversion`), runs [`Hardware::tick`] (encoder, diagnostics, FLT, the motor current
//!   from the filtered current sense, controller step, motor output), starts the next
//!   conversion, feeds the
//!   watchdog, then hands received bytes to the link, which answers each complete request from
//!   the same `Device`: at most
//!   [`FRAMES_PER_TICK`](kerfmeter_firmware::link::FRAMES_PER_TICK) frames a pass, so that no
//!   burst from the host can delay the next step (the link's module docs say why a budget and
//!   not an interrupt executor). The bytes after the last frame taken wait in the [`Inbox`], and
//!   the chunks not taken in [`REQUEST_CHUNKS`], for the next pass. It never awaits anything but
//!   its ticker: received bytes are taken with `try_receive`, responses are queued with
//!   `try_write`, and a response that does not fit the queue is dropped (the host retries the same `seq`, and the link
//!   answers the retry from memory without carrying the request out twice). It feeds the
//!   hardware watchdog ([`WATCHDOG_TIMEOUT_MS`], 50 ms), so a stalled control loop resets the
//!   chip; the only other feeder is the configuration flash, which lengthens it around each of its
//!   operations (always with the motor asleep) and restores it after.
//! - [`usb_rx_task`]: USB-Serial-JTAG bytes in, forwarded in chunks of up to [`CHUNK_LEN`] bytes.
//!   It waits for room in the queue when the host sends faster than the control task takes
//!   frames; the USB FIFO then fills and the host's writes wait: back-pressure, nothing dropped.
//! - [`usb_tx_task`]: response bytes out. The device only answers, so nothing else writes to
//!   that port. A host that stops reading makes a write time out after [`LINK_WRITE_TIMEOUT`];
//!   the pending responses are then dropped.
//!
//! # Configuration flash
//!
//! The device configuration is kept in the `nvs` data partition of the partition table, found at
//! boot; the library's `board::partition` says what is done with it (use a valid record, erase
//! foreign data, or run without persistence) and is tested on the host. A `SetConfig` writes it
//! synchronously from the control task, stalling the ticks for the duration of the write; the
//! ticker then restarts instead of bursting through the missed ticks. The device refuses it while
//! the motor runs, and the link hands requests to it with the motor driver at hand
//! ([`WithMotor`]), so that the bridge is put to sleep before the first flash operation even when
//! the last tick left it driven (an `Abort` in the same pass). Each erase and write runs in its
//! own [`FLASH_WATCHDOG_TIMEOUT_MS`](kerfmeter_firmware::watchdog::FLASH_WATCHDOG_TIMEOUT_MS)
//! watchdog window (the library's `WatchdogFlash`), and the
//! 50 ms timeout is back as soon as it returns.
//!
//! Logs and panic messages go to UART0 (esp-println's `uart` feature), never to the protocol
//! port. The control loop itself does not log (a UART write would stall the tick).
//!
//! Panic path: esp-backtrace's handler first calls [`custom_pre_backtrace`], which puts the
//! bridge in its safe state on the GPIO and LEDC registers (`SLP` low, the PWM pin low and its
//! LEDC channel stopped, `DIR` low: `board::emergency`), without the motor driver, which the
//! panic may have struck mid-use. Only then does it print the message and backtrace to UART0
//! (milliseconds at 115200 baud) and spin with interrupts off. Nobody feeds the watchdog any
//! more, so it resets the chip within [`WATCHDOG_TIMEOUT_MS`] (within the flash's longer window
//! when the panic strikes in a flash operation). A panic during boot, before the watchdog is
//! started (esp-hal's init stops the chip's watchdogs), halts the chip with the bridge safe until
//! it is reset or power-cycled. From reset on, the pins are
//! high-impedance inputs and the board's pull-down resistor on the G2's `SLP` input (a wiring
//! requirement, see `board::pins`) keeps the driver asleep.

#![no_std]
#![no_main]

use embassy_executor::Spawner;
use embassy_sync::{blocking_mutex::raw::CriticalSectionRawMutex, channel::Channel, pipe::Pipe};
use embassy_time::{Duration, Instant, Ticker};
use esp_backtrace as _;
use esp_hal::{
    Async,
    clock::CpuClock,
    rng::{Rng, Trng, TrngSource},
    timer::timg::TimerGroup,
    usb::usb_serial_jtag::{UsbSerialJtag, UsbSerialJtagRx, UsbSerialJtagTx},
};
use kerfmeter_firmware::{
    board::{
        self, BOARD_NAME, BoardHardware,
        adc::AnalogParts,
        conversion::Conversions,
        flash::{ConfigFlash, config_partition},
        motor::{LineLevels, motor_lines},
        partition::{OpenedConfig, open_config_partition},
        watchdog::BoardWatchdog,
    },
    config_store::ConfigSource,
    controller::PERIOD_US,
    device::{Device, WithMotor},
    hardware::Hardware,
    health::BootFacts,
    link::{Inbox, Link},
    watchdog::{WATCHDOG_TIMEOUT_MS, Watchdog},
};
use kerfmeter_protocol::{MAX_RESPONSE_FRAME_LEN, heapless};

esp_bootloader_esp_idf::esp_app_desc!();

/// esp-backtrace's pre-backtrace hook (its `custom-pre-backtrace` feature), the first thing its
/// panic handler does: the motor bridge safe on the registers before anything is printed.
#[unsafe(no_mangle)]
pub fn custom_pre_backtrace() {
    board::emergency::force_safe();
    // Then the mark that makes the watchdog reset to come read as a panic at the next boot.
    board::emergency::mark_panic();
}
/// How long response bytes may wait for the host to read before they are dropped (the host
/// retries, and the link answers the retry from memory).
const LINK_WRITE_TIMEOUT: Duration = Duration::from_millis(100);
/// The control period.
const CONTROL_PERIOD: Duration = Duration::from_micros(PERIOD_US);

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

#[esp_rtos::main]
async fn main(spawner: Spawner) {
    let mut p = esp_hal::init(esp_hal::Config::default().with_cpu_clock(CpuClock::max()));
    let pins = kerfmeter_firmware::take_pins!(p);

    // Motor safe state first (driver asleep, DIR low, PWM duty 0), then the motor driver, which
    // takes the lines and drives them safe again.
    let (motor, safe) = motor_lines(p.LEDC, pins.motor, LineLevels::SAFE).into_driver();
    if let Err(e) = safe {
        esp_println::println!("motor driver: safe state failed: {e:?}");
    }

    // Why the chip started, its revision, its ADC's calibration and the brown-out detector.
    let boot = board::boot::boot_facts();
    esp_println::println!("boot: {boot:?}");

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

    let analog = AnalogParts::new(p.ADC1, pins.motor_current, pins.motor_supply);

    // The stored configuration (defaults if there is none).
    let opened = open_config(p.FLASH);
    esp_println::println!(
        "configuration: {}",
        match opened.source {
            ConfigSource::Stored => "stored",
            ConfigSource::Migrated { .. } => "stored (older record version, migrated)",
            ConfigSource::Missing => "defaults (none stored)",
            ConfigSource::Newer { .. } => "defaults (record of a newer firmware, kept)",
            ConfigSource::Corrupt => "defaults (stored record unusable)",
        }
    );

    let encoder = board::encoder::encoder(p.SPI2, pins.encoder, &opened.config);
    let hardware = Hardware::new(encoder, motor);

    esp_rtos::start(TimerGroup::new(p.TIMG0).timer0, p.FROM_CPU_INTR0);

    // Hardware watchdog: TIMG1's MWDT resets the whole system unless `control_task` feeds it.
    let watchdog = BoardWatchdog::start(p.TIMG1);

    let (usb_rx, usb_tx) = UsbSerialJtag::new(p.USB_DEVICE).into_async().split();

    spawner.spawn(
        control_task(hardware, analog, watchdog, boot_id, boot, opened).expect("control task"),
    );
    spawner.spawn(usb_rx_task(usb_rx).expect("usb rx task"));
    spawner.spawn(usb_tx_task(usb_tx).expect("usb tx task"));
}

/// The configuration from the `nvs` partition, under the library's partition policy, with what
/// happened logged to UART0.
fn open_config(flash: esp_hal::peripherals::FLASH<'static>) -> OpenedConfig<ConfigFlash> {
    let opened = match config_partition(flash) {
        Ok((flash, range)) => {
            esp_println::println!(
                "configuration flash: nvs partition {:#x}..{:#x}",
                range.start,
                range.end
            );
            embassy_futures::block_on(open_config_partition(flash, range))
        }
        Err(why) => OpenedConfig::without_partition(why),
    };
    esp_println::println!("configuration flash: {}", opened.outcome);
    opened
}

/// The fixed-rate control tick; owns the device, the link and the drivers. It feeds the
/// watchdog (the configuration flash only opens and closes its windows around its operations).
///
/// The [`Device`] (its controller holds the run's sample log, ≈24 KiB) and the [`Link`] are built
/// here from the opened configuration rather than passed in: a large async-fn argument would be stored twice in the task's
/// static future.
#[embassy_executor::task]
async fn control_task(
    mut hardware: BoardHardware,
    mut analog: AnalogParts,
    mut watchdog: BoardWatchdog,
    boot_id: u32,
    boot: BootFacts,
    opened: OpenedConfig<ConfigFlash>,
) {
    let mut device = Device::with_config(
        BOARD_NAME,
        boot_id,
        opened.config,
        opened.source,
        opened.storage,
    );
    device.set_boot_facts(boot);
    device.set_driver(board::DRIVER);
    let mut link = Link::new();
    let mut inbox = Inbox::<CHUNK_LEN>::new();
    let mut ticker = Ticker::every(CONTROL_PERIOD);
    let mut conversions = Conversions::new();
    let mut adc = analog.open();
    loop {
        let started = Instant::now();
        // A tick without a current-sense reading keeps the last current; too many in a row make it
        // unknown, and the controller faults with `OverCurrent` rather than drive blind.
        let readings = conversions.read(&mut adc);
        hardware.tick(
            started.as_micros(),
            readings.cs_mv,
            readings.supply_v,
            &mut device,
        );
        // The longest step since boot, reported in `Status`.
        device.step_finished(Instant::now().as_micros());
        if readings.restart {
            // A conversion that never finished: a new driver (`board::conversion`).
            esp_println::println!("adc: a conversion stalled, driver restarted");
            device.note_adc_restart();
            drop(adc);
            adc = analog.open();
        }
        // Just after the output was applied: the reading the next tick pairs with it.
        conversions.start_next(&mut adc);
        watchdog.feed_ms(WATCHDOG_TIMEOUT_MS);

        // Requests, answered at the state of this tick; a save puts the motor safe first. At
        // most `FRAMES_PER_TICK` frames a pass: the rest waits in the inbox and the queue, and
        // a host that keeps sending is held back by the full queue (`usb_rx_task` waits).
        inbox.serve(
            &mut link,
            || REQUEST_CHUNKS.try_receive().ok(),
            &mut WithMotor {
                device: &mut device,
                motor: &mut hardware.motor,
            },
            |frame| {
                // Whole frames only; one that does not fit is dropped, and the host's retry of
                // the same seq is answered from the link's memory.
                if RESPONSE_BYTES.free_capacity() >= frame.len() {
                    let _ = RESPONSE_BYTES.try_write(frame);
                }
            },
        );

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
