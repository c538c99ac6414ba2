//! The motor bridge put in its safe state from a panic, on the chip's registers, before anything
//! is printed.
//!
//! A panic can strike anywhere, including in the middle of a control tick, with the motor driver
//! borrowed or half-way through an update; printing the message takes milliseconds over UART,
//! and the watchdog resets the chip only after that. So the panic path does not go through the
//! driver: it writes the registers that drive the bridge's lines, in this order:
//!
//! 1. `SLP` low, on the GPIO output register: the G2 sleeps, its outputs off, whatever the PWM
//!    does. This alone makes the motor safe.
//! 2. The `PWM` pin low, taken from the PWM peripheral back to the GPIO output register: duty 0
//!    on the pin at once.
//! 3. The PWM channel's output stopped at its low idle level (LEDC), in case the pin is routed
//!    to it again.
//! 4. `DIR` low.
//!
//! The board records its lines ([`ArmedBridge::arm`]) as soon as it has set them up; before
//! that the pins are still in their reset state, inputs, and the pull-down on `SLP` (a wiring
//! requirement) holds the driver asleep. [`on_panic`] is the panic path's order: the bridge
//! safe, then the report. The on-target tests' panic handler calls it with the chip's registers
//! (`board::emergency`), the host tests with fake ones; in the board binary esp-backtrace's
//! handler is the report, and its pre-backtrace hook does the first half
//! ([`ArmedBridge::force_safe`] on the same registers) before it prints anything.

use core::sync::atomic::{AtomicU32, Ordering};

/// The bridge's lines as the registers know them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BridgeLines {
    /// GPIO number of the G2's `SLP`.
    pub sleep_gpio: u8,
    /// GPIO number of the G2's `DIR`.
    pub dir_gpio: u8,
    /// GPIO number of the G2's `PWM`.
    pub pwm_gpio: u8,
    /// The PWM peripheral's channel driving `pwm_gpio`.
    pub pwm_channel: u8,
}

/// Register access for the panic path: plain writes, no driver, no lock.
pub trait BridgeRegisters {
    /// Drive GPIO `gpio` low from the GPIO output register, whatever peripheral drove it.
    fn drive_gpio_low(&mut self, gpio: u8);
    /// Stop PWM channel `channel`'s output at its low idle level.
    fn stop_pwm(&mut self, channel: u8);
}

/// Put the bridge whose lines are `lines` in its safe state through `regs` (see the module docs
/// for the order).
pub fn force_safe(lines: &BridgeLines, regs: &mut impl BridgeRegisters) {
    regs.drive_gpio_low(lines.sleep_gpio);
    regs.drive_gpio_low(lines.pwm_gpio);
    regs.stop_pwm(lines.pwm_channel);
    regs.drive_gpio_low(lines.dir_gpio);
}

/// The panic path: the bridge safe first (if its lines are armed), then `report` (print the
/// message, the backtrace, tell a test runner).
pub fn on_panic(armed: &ArmedBridge, regs: &mut impl BridgeRegisters, report: impl FnOnce()) {
    armed.force_safe(regs);
    report();
}

/// "Not armed": no line has this number.
const UNARMED: u32 = u32::MAX;

/// The bridge's lines once the board has set them up, readable from a panic without a lock
/// (one atomic word).
#[derive(Debug)]
pub struct ArmedBridge(AtomicU32);

impl ArmedBridge {
    /// Nothing armed yet.
    pub const fn new() -> Self {
        Self(AtomicU32::new(UNARMED))
    }

    /// From now on a panic puts `lines` safe.
    pub fn arm(&self, lines: BridgeLines) {
        let word = u32::from_le_bytes([
            lines.sleep_gpio,
            lines.dir_gpio,
            lines.pwm_gpio,
            lines.pwm_channel,
        ]);
        self.0.store(word, Ordering::SeqCst);
    }

    /// The armed lines, if any.
    pub fn lines(&self) -> Option<BridgeLines> {
        let word = self.0.load(Ordering::SeqCst);
        let [sleep_gpio, dir_gpio, pwm_gpio, pwm_channel] = word.to_le_bytes();
        (word != UNARMED).then_some(BridgeLines {
            sleep_gpio,
            dir_gpio,
            pwm_gpio,
            pwm_channel,
        })
    }

    /// Put the armed lines safe through `regs`; false (nothing written) when none are armed.
    pub fn force_safe(&self, regs: &mut impl BridgeRegisters) -> bool {
        match self.lines() {
            Some(lines) => {
                force_safe(&lines, regs);
                true
            }
            None => false,
        }
    }
}

impl Default for ArmedBridge {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests;
