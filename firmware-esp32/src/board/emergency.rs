//! The panic path's register writes on the chip: the library's [`emergency`](crate::emergency)
//! logic over the GPIO and LEDC registers, with the board's lines armed by `board::motor` as
//! soon as it has set them up.
//!
//! [`force_safe`] is what the board binary's pre-backtrace hook and the on-target tests' panic
//! handler call before they print anything. It never takes a lock and never touches a driver.
//!
//! This module is the library's only `unsafe` code: raw register writes, each of which changes
//! only the bits of the bridge's own lines, and the panic mark in RTC memory ([`mark_panic`])
//! that tells the next boot a panic caused its watchdog reset.

#![allow(unsafe_code)]

use esp_hal::gpio::OutputSignal;
use esp_hal::peripherals::{GPIO, LEDC};

use crate::emergency::{ArmedBridge, BridgeLines, BridgeRegisters};

/// The board's bridge lines, once `board::motor` has set them up.
pub static ARMED: ArmedBridge = ArmedBridge::new();

/// From now on a panic puts `lines` safe.
pub fn arm(lines: BridgeLines) {
    ARMED.arm(lines);
}

/// Put the bridge safe on the registers now, if its lines are armed: the panic path's first
/// step (see [`crate::emergency`]).
pub fn force_safe() {
    ARMED.force_safe(&mut ChipRegisters);
}

/// What the panic path writes to [`PANIC_MARK`]: "PANC".
const PANIC_MAGIC: u32 = 0x5041_4e43;

/// Set by the panic path, read and cleared at the next boot (`board::boot`): the watchdog reset
/// that follows a panic is then reported as a panic. In RTC fast memory, kept across the
/// watchdog's core reset and zeroed by esp-hal's start-up after a power-on.
#[esp_hal::ram(unstable(rtc_fast, persistent))]
static mut PANIC_MARK: u32 = 0;

/// Record that the firmware panicked (the panic path, after [`force_safe`]).
pub fn mark_panic() {
    // SAFETY: a volatile write of a word through a raw pointer, no reference to the static is
    // made; the panic path runs with nothing else touching it.
    unsafe { (&raw mut PANIC_MARK).write_volatile(PANIC_MAGIC) }
}

/// Whether the firmware panicked before this boot's reset; clears the mark.
pub fn take_panic_mark() -> bool {
    // SAFETY: volatile accesses through a raw pointer, once at boot before any task runs.
    let mark = unsafe { (&raw mut PANIC_MARK).read_volatile() };
    unsafe { (&raw mut PANIC_MARK).write_volatile(0) }
    mark == PANIC_MAGIC
}

/// The chip's GPIO and LEDC registers.
pub struct ChipRegisters;

impl BridgeRegisters for ChipRegisters {
    fn drive_gpio_low(&mut self, gpio: u8) {
        if gpio >= 32 {
            return;
        }
        let gpio_regs = GPIO::regs();
        let bit = 1u32 << gpio;
        // SAFETY: write-1-to-clear / write-1-to-set of this pin's bit only; the pin's output
        // routed to the GPIO output register (a plain GPIO output), its enable from that
        // register.
        unsafe {
            gpio_regs.out_w1tc().write(|w| w.bits(bit));
            gpio_regs.func_out_sel_cfg(usize::from(gpio)).write(|w| {
                w.out_sel()
                    .bits(OutputSignal::GPIO as _)
                    .oen_sel()
                    .set_bit()
            });
            gpio_regs.enable_w1ts().write(|w| w.bits(bit));
        }
    }

    fn stop_pwm(&mut self, channel: u8) {
        // Output disabled at its idle level, low; `para_up` latches the change.
        LEDC::regs()
            .ch(usize::from(channel))
            .conf0()
            .modify(|_, w| {
                w.sig_out_en().clear_bit();
                w.idle_lv().clear_bit();
                w.para_up().set_bit()
            });
    }
}
