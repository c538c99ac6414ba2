//! A fake AS5048A that speaks the chip's SPI protocol as the datasheet describes it, for the twin
//! and the driver's tests.
//!
//! Modelled: 16-bit frames (anything else is a framing error), even parity on commands and
//! responses, the pipelined reply (each frame returns the answer to the previous command), the
//! error flag and the error register cleared by reading `CLEAR ERROR FLAG`, the diagnostics / AGC
//! and magnitude registers, 14-bit quantisation with a few LSB of noise. Faults to inject:
//! corrupted responses (parity errors), corrupted commands (the chip flags them), a lost magnet,
//! MISO stuck low or high.
//!
//! Chip-select timing, as far as a transaction carries it: the time from CSn falling to the first
//! clock (t_L, at least 350 ns) and from the last clock to CSn rising (t_H, at least half
//! a period of [`SPI_FREQUENCY_HZ`]) are the `Operation::DelayNs` before the first and after the
//! last data operation. A frame that falls short is not taken: the chip flags a framing error
//! (counted in [`FakeAs5048a::timing_violations`]), so a driver that drops them fails its reads.
//! The CSn high time between frames (t_CSn) lies outside any transaction and is not checked.
//!
//! Not modelled: writes (the driver never writes; the zero position lives in the device
//! configuration, not in the chip's OTP), clock-level timing, the PWM output.

use core::convert::Infallible;

use embedded_hal::spi::{ErrorType, Operation, SpiDevice};

use super::rng::Rng;
use crate::as5048a::{COUNTS_PER_TURN, SPI_FREQUENCY_HZ, diag, err, parity_ok, reg, with_parity};

/// t_L, the datasheet's minimum, ns (the chip's own figure, not the driver's constant, so that a
/// driver that shortens it is caught).
const MIN_SETUP_NS: u32 = 350;
/// t_H at the bus clock: half a clock period, ns.
const MIN_HOLD_NS: u32 = 1_000_000_000_u32.div_ceil(2 * SPI_FREQUENCY_HZ);

/// A broken MISO line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MisoFault {
    /// Reads 0x0000: valid parity, no error flag, angle 0.
    StuckLow,
    /// Reads 0xFFFF: valid parity, error flag set.
    StuckHigh,
}

/// The fake chip.
pub struct FakeAs5048a {
    angle_deg: f64,
    noise_lsb: f32,
    rng: Rng,
    magnet_lost: bool,
    agc: u8,
    magnitude: u16,
    error_register: u16,
    error_flag: bool,
    /// Data the next frame shifts out.
    out: u16,
    frames: u32,
    timing_violations: u32,
    corrupt_responses: u32,
    corrupt_commands: u32,
    miso_fault: Option<MisoFault>,
}

impl FakeAs5048a {
    /// A healthy chip over a well-placed magnet, with 1 LSB of noise, seeded.
    pub fn new(seed: u64) -> Self {
        Self {
            angle_deg: 0.0,
            noise_lsb: 1.0,
            rng: Rng::new(seed),
            magnet_lost: false,
            agc: 128,
            magnitude: 4000,
            error_register: 0,
            error_flag: false,
            out: 0,
            frames: 0,
            timing_violations: 0,
            corrupt_responses: 0,
            corrupt_commands: 0,
            miso_fault: None,
        }
    }

    /// Set the magnet's angle (the shaft the chip sits on), degrees, any number of turns.
    pub fn set_angle_deg(&mut self, angle_deg: f64) {
        self.angle_deg = angle_deg;
    }

    /// Standard deviation of the angle noise, LSB.
    pub fn set_noise_lsb(&mut self, lsb: f32) {
        self.noise_lsb = lsb;
    }

    /// Remove (or bring back) the magnet: field too weak, AGC at its limit, angle is noise.
    pub fn set_magnet_lost(&mut self, lost: bool) {
        self.magnet_lost = lost;
    }

    /// Set the AGC value a healthy magnet gives (distance of the magnet).
    pub fn set_agc(&mut self, agc: u8) {
        self.agc = agc;
    }

    /// Break (or mend) the MISO line.
    pub fn set_miso_fault(&mut self, fault: Option<MisoFault>) {
        self.miso_fault = fault;
    }

    /// Flip a bit in the next `n` responses (the host sees parity errors).
    pub fn corrupt_next_responses(&mut self, n: u32) {
        self.corrupt_responses += n;
    }

    /// Flip a bit in the next `n` commands (the chip flags parity errors).
    pub fn corrupt_next_commands(&mut self, n: u32) {
        self.corrupt_commands += n;
    }

    /// Frames clocked so far.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Frames whose chip-select setup or hold time was too short (see the module docs).
    pub fn timing_violations(&self) -> u32 {
        self.timing_violations
    }

    fn diag_agc(&self) -> u16 {
        if self.magnet_lost {
            diag::OCF | diag::COMP_HIGH | 0xFF
        } else {
            diag::OCF | u16::from(self.agc)
        }
    }

    fn sample_angle(&mut self) -> u16 {
        let counts = f64::from(COUNTS_PER_TURN);
        let noise = if self.magnet_lost {
            self.rng.uniform() * counts
        } else {
            f64::from(self.rng.normal() * self.noise_lsb)
        };
        let raw = (self.angle_deg / 360.0 * counts + noise).round();
        raw.rem_euclid(counts) as u16
    }

    /// Clock one frame: returns what MISO carried, and takes `command` from MOSI (`timed`: the
    /// chip-select setup and hold times were met).
    fn clock(&mut self, command: u16, bytes: usize, timed: bool) -> u16 {
        self.frames += 1;
        let mut response = with_parity(self.out | if self.error_flag { 0x4000 } else { 0 });
        match self.miso_fault {
            Some(MisoFault::StuckLow) => response = 0x0000,
            Some(MisoFault::StuckHigh) => response = 0xFFFF,
            None => {}
        }
        if self.corrupt_responses > 0 {
            self.corrupt_responses -= 1;
            response ^= 0x0004;
        }

        let mut command = command;
        if self.corrupt_commands > 0 {
            self.corrupt_commands -= 1;
            command ^= 0x0100;
        }
        if !timed {
            self.timing_violations += 1;
            self.flag(err::FRAMING);
        } else if bytes != 2 {
            self.flag(err::FRAMING);
        } else if !parity_ok(command) {
            self.flag(err::PARITY);
        } else if command & 0x4000 == 0 {
            // Writes are not modelled: the driver never writes.
            self.flag(err::COMMAND_INVALID);
        } else {
            self.out = match command & 0x3FFF {
                reg::NOP => 0,
                reg::CLEAR_ERROR_FLAG => {
                    let bits = self.error_register;
                    self.error_register = 0;
                    self.error_flag = false;
                    bits
                }
                reg::DIAG_AGC => self.diag_agc(),
                reg::MAGNITUDE => {
                    if self.magnet_lost {
                        40
                    } else {
                        self.magnitude
                    }
                }
                reg::ANGLE => self.sample_angle(),
                _ => {
                    self.flag(err::COMMAND_INVALID);
                    self.out
                }
            };
        }
        response
    }

    fn flag(&mut self, bit: u16) {
        self.error_register |= bit;
        self.error_flag = true;
    }
}

impl ErrorType for FakeAs5048a {
    type Error = Infallible;
}

impl SpiDevice<u8> for FakeAs5048a {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Infallible> {
        // Chip select is low for the whole transaction: gather MOSI, clock one frame, then hand
        // MISO back to the read buffers in order.
        let mut mosi = [0u8; 8];
        let mut n = 0;
        for op in operations.iter() {
            let bytes: &[u8] = match op {
                Operation::Write(w) => w,
                Operation::Transfer(_, w) => w,
                Operation::TransferInPlace(b) => b,
                Operation::Read(r) => &[0u8; 8][..r.len().min(8)],
                Operation::DelayNs(_) => &[],
            };
            for &b in bytes {
                if n < mosi.len() {
                    mosi[n] = b;
                }
                n += 1;
            }
        }
        let command = u16::from_be_bytes([mosi[0], mosi[1]]);
        let miso = self
            .clock(command, n, cs_timing_met(operations))
            .to_be_bytes();
        let mut i = 0;
        for op in operations.iter_mut() {
            let buf: &mut [u8] = match op {
                Operation::Transfer(r, _) => r,
                Operation::TransferInPlace(b) => b,
                Operation::Read(r) => r,
                Operation::Write(_) | Operation::DelayNs(_) => continue,
            };
            for b in buf.iter_mut() {
                *b = miso.get(i).copied().unwrap_or(0);
                i += 1;
            }
        }
        Ok(())
    }
}

/// True when the delays before the first and after the last data operation of a transaction meet
/// the chip-select setup (t_L) and hold (t_H) times.
fn cs_timing_met(operations: &[Operation<'_, u8>]) -> bool {
    let is_data = |op: &Operation<'_, u8>| !matches!(op, Operation::DelayNs(_));
    let delay_ns = |ops: &[Operation<'_, u8>]| -> u32 {
        ops.iter()
            .map(|op| match op {
                Operation::DelayNs(ns) => *ns,
                _ => 0,
            })
            .sum()
    };
    let (Some(first), Some(last)) = (
        operations.iter().position(is_data),
        operations.iter().rposition(is_data),
    ) else {
        return true; // no clock at all
    };
    delay_ns(&operations[..first]) >= MIN_SETUP_NS
        && delay_ns(&operations[last + 1..]) >= MIN_HOLD_NS
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::as5048a::read_command;

    /// One angle-read frame with `lead_ns` of chip-select setup and `trail_ns` of hold; the
    /// response word.
    fn frame(chip: &mut FakeAs5048a, lead_ns: u32, trail_ns: u32) -> u16 {
        let mut bytes = read_command(reg::ANGLE).to_be_bytes();
        chip.transaction(&mut [
            Operation::DelayNs(lead_ns),
            Operation::TransferInPlace(&mut bytes),
            Operation::DelayNs(trail_ns),
        ])
        .unwrap();
        u16::from_be_bytes(bytes)
    }

    #[test]
    fn frames_without_the_chip_select_setup_or_hold_time_are_flagged() {
        let mut chip = FakeAs5048a::new(1);
        frame(&mut chip, MIN_SETUP_NS, MIN_HOLD_NS);
        assert!(frame(&mut chip, MIN_SETUP_NS, MIN_HOLD_NS) & 0x4000 == 0);
        assert_eq!(chip.timing_violations(), 0);
        // Too short a setup: the command is not taken and the next response carries EF.
        frame(&mut chip, MIN_SETUP_NS - 1, MIN_HOLD_NS);
        assert!(frame(&mut chip, MIN_SETUP_NS, MIN_HOLD_NS) & 0x4000 != 0);
        // Too short a hold, likewise.
        let mut chip = FakeAs5048a::new(2);
        frame(&mut chip, MIN_SETUP_NS, MIN_HOLD_NS - 1);
        assert!(frame(&mut chip, MIN_SETUP_NS, MIN_HOLD_NS) & 0x4000 != 0);
        assert_eq!(chip.timing_violations(), 1);
        // A bare transfer (no delays at all) is a violation too.
        let mut bytes = read_command(reg::ANGLE).to_be_bytes();
        chip.transfer_in_place(&mut bytes).unwrap();
        assert_eq!(chip.timing_violations(), 2);
    }
}
