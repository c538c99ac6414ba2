//! The panic path's register writes on the chip: the library's [`emergency`](crate::emergency)
//! logic over the GPIO and LEDC registers, with the board's lines armed by `board::motor` as
//! soon as it has set them up.
//!
//! [`force_safe`] is what the board binary's pre-backtrace hook and the on-target tests' panic
//! handler call before they print anything. It never takes a lock and never touches a driver.
//!
//! This module is the library's only `unsafe` code: raw register writes, each of which changes
//! only the bits of the bridge's own lines.

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
