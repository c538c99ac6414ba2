//! The Kerfmeter board binary for the ESP32-C3 (feature `esp32c3`) or ESP32-C6 (`esp32c6`).
//!
//! Glue only: this file takes the chip's peripherals, puts the motor in its safe state, sets up
//! the PWM, encoder SPI, current-sense ADC and watchdog, and starts two embassy tasks. All
//! behaviour lives in the `kerfmeter_firmware` library, which is tested on the host.
//!
//! - [`control_task`], every 1 ms: will step the controller; for now it holds the motor in its
//!   safe state and is the only thing that feeds the hardware watchdog, so a stalled control
//!   loop resets the chip.
//! - [`link_task`]: USB-Serial-JTAG bytes in → [`Link`] → response frames out. Nothing else
//!   writes to that port.
//!
//! Logs and panic messages go to UART0 (esp-println's `uart` feature), never to the protocol
//! port.
//!
//! Panic path: esp-backtrace prints the backtrace to UART0, then spins with interrupts off.
//! Nobody feeds the watchdog any more, so it resets the chip within [`WATCHDOG_TIMEOUT`]. From
//! reset on, the pins are high-impedance inputs and the board's pull-down resistor on the G2's
//! `SLP` input (a wiring requirement, see [`pins`]) puts the driver to sleep: the motor is safe
//! without any help from software.

#![no_std]
#![no_main]

mod pins;

use embassy_executor::Spawner;
use embassy_time::{Delay, Duration, Ticker};
use embedded_hal_bus::spi::ExclusiveDevice;
use esp_backtrace as _;
use esp_hal::{
    Async,
    analog::adc::{Adc, AdcConfig, AdcPin, Attenuation},
    clock::CpuClock,
    gpio::{DriveMode, Input, InputConfig, Level, Output, OutputConfig, Pull},
    ledc::{
        LSGlobalClkSource, Ledc, LowSpeed,
        channel::{self, ChannelHW, ChannelIFace},
        timer::{self, TimerIFace},
    },
    peripherals::{ADC1, TIMG1},
    rng::{Rng, Trng, TrngSource},
    spi::{
        Mode,
        master::{Config as SpiConfig, Spi},
    },
    time::Rate,
    timer::timg::{MwdtStage, TimerGroup, Wdt},
    usb::usb_serial_jtag::UsbSerialJtag,
};
use kerfmeter_firmware::{build::CONTROL_RATE_HZ, device::Device, link::Link};
use kerfmeter_protocol::{MAX_RESPONSE_FRAME_LEN, heapless};
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
/// Hardware watchdog timeout: a control loop stalled this long resets the chip.
const WATCHDOG_TIMEOUT: esp_hal::time::Duration = esp_hal::time::Duration::from_millis(500);
/// How long a response may wait for the host to read before it is dropped (the host retries,
/// and the link answers the retry from memory).
const LINK_WRITE_TIMEOUT: Duration = Duration::from_millis(100);

/// The LEDC timer behind the motor PWM channel. A channel borrows its timer, so the timer lives
/// in a static to give a `'static` channel to a task.
static PWM_TIMER: StaticCell<timer::Timer<'static, LowSpeed>> = StaticCell::new();

/// The motor PWM output.
type MotorPwm = channel::Channel<'static, LowSpeed>;
/// The AS5048A on SPI2, with its chip select, as an embedded-hal-async `SpiDevice`.
type EncoderSpi = ExclusiveDevice<Spi<'static, Async>, Output<'static>, Delay>;
/// The G2 current-sense input on ADC1.
type CurrentSense = (
    Adc<'static, ADC1<'static>, esp_hal::Blocking>,
    AdcPin<pins::CurrentSensePin, ADC1<'static>>,
);

/// The Pololu G2 motor driver's pins.
struct MotorDriver {
    pwm: MotorPwm,
    dir: Output<'static>,
    sleep: Output<'static>,
    /// Not read yet: the controller will.
    _fault: Input<'static>,
    /// Not read yet: the controller will.
    _current: CurrentSense,
}

impl MotorDriver {
    /// Duty 0, direction low, driver asleep.
    fn set_safe(&mut self) {
        self.pwm.set_duty_hw(0);
        self.dir.set_low();
        self.sleep.set_low();
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

    let mut adc_config = AdcConfig::new();
    let current_pin = adc_config.enable_pin(pins.motor_current, Attenuation::_11dB);
    let current = (Adc::new(p.ADC1, adc_config), current_pin);

    let mut motor = MotorDriver {
        pwm,
        dir,
        sleep,
        _fault: fault,
        _current: current,
    };
    motor.set_safe();

    // Encoder: SPI2, mode 1, 10 MHz; chip select as a GPIO, idle high.
    let spi = Spi::new(
        p.SPI2,
        SpiConfig::default()
            .with_frequency(ENCODER_SPI_FREQUENCY)
            .with_mode(Mode::_1),
    )
    .expect("SPI2 config")
    .with_sck(pins.encoder_sclk)
    .with_mosi(pins.encoder_mosi)
    .with_miso(pins.encoder_miso)
    .into_async();
    let encoder_cs = Output::new(pins.encoder_cs, Level::High, OutputConfig::default());
    let Ok(encoder) = ExclusiveDevice::new(spi, encoder_cs, Delay);

    esp_rtos::start(TimerGroup::new(p.TIMG0).timer0, p.FROM_CPU_INTR0);

    // Hardware watchdog: TIMG1's MWDT resets the whole system unless `control_task` feeds it.
    let mut watchdog = TimerGroup::new(p.TIMG1).wdt;
    watchdog.set_timeout(MwdtStage::Stage0, WATCHDOG_TIMEOUT);
    watchdog.enable();

    let usb = UsbSerialJtag::new(p.USB_DEVICE).into_async();

    spawner.spawn(
        control_task(
            Board {
                motor,
                _encoder: encoder,
            },
            watchdog,
        )
        .expect("control task"),
    );
    spawner.spawn(link_task(usb, boot_id).expect("link task"));
}

/// What the control task owns.
struct Board {
    motor: MotorDriver,
    /// Not read yet: the encoder driver will.
    _encoder: EncoderSpi,
}

/// The fixed-rate control tick. The only feeder of the watchdog.
#[embassy_executor::task]
async fn control_task(mut board: Board, mut watchdog: Wdt<TIMG1<'static>>) {
    let mut ticker = Ticker::every(Duration::from_hz(CONTROL_RATE_HZ.into()));
    loop {
        // No controller yet: hold the motor in its safe state.
        board.motor.set_safe();
        watchdog.feed();
        ticker.next().await;
    }
}

/// The protocol port: bytes from the host go through the sans-IO [`Link`]; its response frames
/// go back. The device only answers, so this task is the only writer.
///
/// The [`Device`] is built here rather than passed in: a large async-fn argument would be
/// stored twice in the task's static future.
#[embassy_executor::task]
async fn link_task(mut usb: UsbSerialJtag<'static, Async>, boot_id: u32) {
    let mut device = Device::new(BOARD_NAME, boot_id);
    let mut link = Link::new();
    let mut rx = [0u8; 64];
    let mut tx = heapless::Vec::<u8, MAX_RESPONSE_FRAME_LEN>::new();
    loop {
        let n = match embedded_io_async::Read::read(&mut usb, &mut rx).await {
            Ok(n) => n,
            Err(_) => continue,
        };
        // Feed the link up to one frame delimiter at a time: each piece completes at most one
        // request, so its response always fits `tx`.
        for piece in rx[..n].split_inclusive(|&b| b == 0) {
            tx.clear();
            link.receive(piece, &mut device, |frame| {
                // Cannot fail: one response frame is at most `MAX_RESPONSE_FRAME_LEN` bytes.
                let _ = tx.extend_from_slice(frame);
            });
            if tx.is_empty() {
                continue;
            }
            let write = async {
                embedded_io_async::Write::write_all(&mut usb, &tx).await?;
                embedded_io_async::Write::flush(&mut usb).await
            };
            // A host that stopped reading must not stall the link: drop the response.
            let _ = embassy_time::with_timeout(LINK_WRITE_TIMEOUT, write).await;
        }
    }
}
