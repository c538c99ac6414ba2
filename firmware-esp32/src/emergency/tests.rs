//! The panic path on the host: a panic in the middle of a control tick, with the motor driven
//! and its driver borrowed, caught by a panic hook that runs [`on_panic`] on fake registers
//! wired to the fake bridge, and reports only after it.

use std::cell::RefCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use embedded_hal::digital::OutputPin;
use embedded_hal::pwm::SetDutyCycle;
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
use kerfmeter_protocol::{DeviceConfig, Request, Response, RunParams};

use super::*;
use crate::as5048a::{As5048a, EncoderSettings};
use crate::controller::PERIOD_US;
use crate::device::Device;
use crate::fakes::as5048a::FakeAs5048a;
use crate::fakes::pins::{FakeInput, FakeOutput, FakePwm};
use crate::hardware::Hardware;
use crate::link::Handler;
use crate::motor::G2Motor;

const LINES: BridgeLines = BridgeLines {
    sleep_gpio: 1,
    dir_gpio: 4,
    pwm_gpio: 3,
    pwm_channel: 0,
};

/// The fake bridge's pins.
#[derive(Clone)]
struct Bridge {
    pwm: FakePwm,
    dir: FakeOutput,
    slp: FakeOutput,
}

impl Bridge {
    fn new() -> Self {
        Self {
            pwm: FakePwm::new(2047),
            dir: FakeOutput::new(false),
            slp: FakeOutput::new(false),
        }
    }

    /// The safe state: duty 0 and the driver asleep.
    fn is_safe(&self) -> bool {
        self.pwm.duty() == 0.0 && !self.slp.is_high()
    }

    /// The driver awake at a duty above 0: the motor driven.
    fn is_driven(&self) -> bool {
        self.pwm.duty() > 0.0 && self.slp.is_high()
    }
}

/// Registers wired to the fake bridge as [`LINES`] says; they log what was written.
struct FakeRegisters {
    bridge: Bridge,
    writes: Vec<&'static str>,
}

impl BridgeRegisters for FakeRegisters {
    fn drive_gpio_low(&mut self, gpio: u8) {
        let b = &mut self.bridge;
        let written = match gpio {
            g if g == LINES.sleep_gpio => b.slp.set_low().map(|_| "SLP low"),
            g if g == LINES.dir_gpio => b.dir.set_low().map(|_| "DIR low"),
            g if g == LINES.pwm_gpio => b
                .pwm
                .set_duty_cycle(0)
                .map(|_| "PWM pin low")
                .or(Ok("PWM pin low (fake refused)")),
            _ => Ok("another GPIO low"),
        };
        self.writes.push(written.unwrap());
    }

    fn stop_pwm(&mut self, channel: u8) {
        assert_eq!(channel, LINES.pwm_channel);
        self.bridge.pwm.set_raw(0);
        self.writes.push("PWM channel stopped");
    }
}

/// What the panic hook saw when it reported.
#[derive(Debug, Clone, PartialEq)]
struct Report {
    message: String,
    bridge_safe: bool,
}

/// This thread's panic path: the armed lines, the registers and what was reported.
struct PanicPath {
    armed: ArmedBridge,
    regs: FakeRegisters,
    report: Option<Report>,
}

thread_local! {
    static PANIC_PATH: RefCell<Option<PanicPath>> = const { RefCell::new(None) };
}

/// A process-wide panic hook that runs this thread's panic path, if it has one (other threads'
/// panics go to the default hook).
fn install_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let handled = PANIC_PATH.with(|p| {
                let mut p = p.borrow_mut();
                let Some(path) = p.as_mut() else {
                    return false;
                };
                let (armed, regs, report) = (&path.armed, &mut path.regs, &mut path.report);
                let bridge = regs.bridge.clone();
                on_panic(armed, regs, || {
                    *report = Some(Report {
                        message: info.to_string(),
                        bridge_safe: bridge.is_safe(),
                    });
                });
                true
            });
            if !handled {
                default(info);
            }
        }));
    });
}

/// An encoder bus that panics once told to (a bug in the control path).
struct PanicOnCue {
    chip: FakeAs5048a,
    cue: Arc<AtomicBool>,
}

impl ErrorType for PanicOnCue {
    type Error = core::convert::Infallible;
}

impl SpiDevice<u8> for PanicOnCue {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        assert!(
            !self.cue.load(Ordering::Relaxed),
            "a bug in the control path"
        );
        self.chip.transaction(ops)
    }
}

/// Run a measurement until the motor is driven, then make the next tick panic; what the panic
/// hook reported, and the registers' writes.
fn panic_mid_tick(arm: bool) -> (Report, Vec<&'static str>, Bridge) {
    install_hook();
    let bridge = Bridge::new();
    let armed = ArmedBridge::new();
    if arm {
        armed.arm(LINES);
    }
    PANIC_PATH.with(|p| {
        *p.borrow_mut() = Some(PanicPath {
            armed,
            regs: FakeRegisters {
                bridge: bridge.clone(),
                writes: Vec::new(),
            },
            report: None,
        })
    });
    let cue = Arc::new(AtomicBool::new(false));
    let bus = PanicOnCue {
        chip: FakeAs5048a::new(7),
        cue: cue.clone(),
    };
    let (motor, _) = G2Motor::new(
        bridge.pwm.clone(),
        bridge.dir.clone(),
        bridge.slp.clone(),
        FakeInput::new(true),
    );
    let encoder = As5048a::new(bus, EncoderSettings::from_config(&DeviceConfig::DEFAULT));
    let mut hardware = Hardware::new(encoder, motor);
    let mut device = Device::new("test", 1);
    let mut now_us = PERIOD_US;
    hardware.tick(now_us, Some(54), None, &mut device);
    assert_eq!(
        device.handle(&Request::Run(RunParams::DEFAULT)),
        Response::Ok
    );
    for _ in 0..200 {
        now_us += PERIOD_US;
        hardware.tick(now_us, Some(54), None, &mut device);
        if bridge.is_driven() {
            break;
        }
    }
    assert!(bridge.is_driven(), "the run drives the motor");

    cue.store(true, Ordering::Relaxed);
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        hardware.tick(now_us + PERIOD_US, Some(54), None, &mut device)
    }));
    assert!(result.is_err(), "the tick panicked");
    let path = PANIC_PATH.with(|p| p.borrow_mut().take()).unwrap();
    (
        path.report.expect("the hook reported"),
        path.regs.writes,
        bridge,
    )
}

#[test]
fn a_panic_mid_tick_leaves_the_bridge_safe_before_the_message_is_reported() {
    let (report, writes, bridge) = panic_mid_tick(true);
    assert!(
        report.message.contains("a bug in the control path"),
        "{report:?}"
    );
    assert!(report.bridge_safe, "driven while the message was reported");
    assert_eq!(
        writes,
        ["SLP low", "PWM pin low", "PWM channel stopped", "DIR low"],
        "SLP first: it alone puts the bridge off"
    );
    assert!(bridge.is_safe() && !bridge.dir.is_high());
}

#[test]
fn before_the_lines_are_armed_the_panic_path_writes_nothing() {
    // The pins are in their reset state then (the pull-down holds SLP low); here the fake bridge
    // was driven without arming, and nothing touched it.
    let (report, writes, _) = panic_mid_tick(false);
    assert!(writes.is_empty());
    assert!(!report.bridge_safe);
}

#[test]
fn armed_lines_round_trip_through_the_atomic_word() {
    let armed = ArmedBridge::new();
    assert_eq!(armed.lines(), None);
    let lines = BridgeLines {
        sleep_gpio: 30,
        dir_gpio: 21,
        pwm_gpio: 0,
        pwm_channel: 5,
    };
    armed.arm(lines);
    assert_eq!(armed.lines(), Some(lines));
}
