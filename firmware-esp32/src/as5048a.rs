//! AS5048A magnetic angle encoder over SPI (`embedded_hal::spi::SpiDevice<u8>`), checked the way
//! the datasheet asks.
//!
//! Bus: SPI mode 1 (CPOL 0, CPHA 1), one 16-bit frame per chip-select, MSB first, at
//! [`SPI_FREQUENCY_HZ`] (the part allows 10 MHz; 2 MHz leaves margin for the GPIO matrix and
//! the long, noisy wires of a laser head, and a frame still takes only 8 µs).
//!
//! - **Chip-select timing** (datasheet, SPI timing): t_L ≥ 350 ns from CSn falling to the first
//!   clock edge, t_H ≥ half a clock period from the last clock edge to CSn rising, and
//!   t_CSn ≥ 350 ns of CSn high between two frames. Every frame is one transaction that carries
//!   the first two as `Operation::DelayNs` ([`CS_SETUP_NS`], [`CS_HOLD_NS`]), so any
//!   `SpiDevice` that honours its operations meets them; t_CSn lies between transactions, so the
//!   bus's `SpiDevice` keeps CSn high for [`CS_HIGH_NS`] after each one (the board's does).
//!
//! ```text
//!   command  │ 15: even parity │ 14: 1 = read, 0 = write │ 13..0: address │
//!   response │ 15: even parity │ 14: EF (error flag)     │ 13..0: data    │
//! ```
//!
//! - **Pipelined replies.** The answer to a command comes in the *next* frame. The driver tracks
//!   what it sent last; reading the angle continuously costs one frame per sample, and the sample
//!   is one frame old (1 ms at 1 kHz).
//! - **Parity** (even, over all 16 bits) is checked on every response; a bad one is an error.
//! - **Error flag.** When EF is set, the driver reads the error register (`CLEAR ERROR FLAG`,
//!   0x0001, which also clears it) and reports framing / invalid-command / parity errors.
//! - **Diagnostics** (0x3FFD + magnitude 0x3FFE), read at start and periodically: offset
//!   compensation finished (OCF = 1), no CORDIC overflow (COF = 0), field neither too weak
//!   (COMP_H) nor too strong (COMP_L), AGC and magnitude inside a band. A MISO line stuck low reads
//!   as 0x0000 with *valid* parity: angle 0 forever. Only the diagnostics catch it (OCF = 0).
//! - **Impossible jumps** (more than [`EncoderSettings::max_step_deg`] of encoder angle between two
//!   samples) are rejected, not unwrapped.
//! - **Multi-turn unwrap**, gear ratio and placement (motor or output shaft), counting sense and
//!   zero come from [`EncoderSettings`]; the driver reports the *hub* angle.
//! - **Turn counting** starts at the first reading (boot) and restarts only when the settings
//!   change or the user confirms the hub at its mark ([`As5048a::set_settings`]; the control
//!   tick calls it only when [`EncoderSettings::from_config`] or the controller's encoder epoch
//!   differs, never for other configuration fields). On the output shaft the first reading is
//!   the hub angle itself. On the motor shaft it fixes the hub only modulo one motor turn
//!   (360°/gear ratio of hub angle): the count takes the motor turn nearest the zero, so a
//!   motor-shaft encoder must (re)start with the hub at zero. At boot, and after a change onto
//!   the motor shaft, the controller refuses runs until the user has confirmed the hub at its
//!   mark (`Conditions::HUB_TURN_UNKNOWN`, `ConfirmHubAtZero`); a change of its settings it takes
//!   only at zero (`NotAtZero` away from it).

use embedded_hal::spi::{Operation, SpiDevice};
use kerfmeter_protocol::{DeviceConfig, EncoderPlacement};

/// SPI clock, Hz (see the module docs for the choice).
pub const SPI_FREQUENCY_HZ: u32 = 2_000_000;
/// t_L: CSn falling edge to the first clock edge, at least, ns (datasheet: 350 ns).
pub const CS_SETUP_NS: u32 = 350;
/// t_H: last clock edge to CSn rising edge, at least, ns (datasheet: half a clock period; this
/// covers any clock from 1 MHz up).
pub const CS_HOLD_NS: u32 = 500;
/// t_CSn: CSn high between two frames, at least, ns (datasheet: 350 ns). Kept by the bus's
/// `SpiDevice` after each transaction, not by the driver.
pub const CS_HIGH_NS: u32 = 350;

/// Counts per turn (14 bit).
pub const COUNTS_PER_TURN: u16 = 1 << 14;
const DATA_MASK: u16 = COUNTS_PER_TURN - 1;

/// Register addresses.
pub mod reg {
    /// No operation; reading it returns 0.
    pub const NOP: u16 = 0x0000;
    /// Clear error flag: reading returns the error register and clears it.
    pub const CLEAR_ERROR_FLAG: u16 = 0x0001;
    /// Diagnostics (bits 11..8) and AGC (bits 7..0).
    pub const DIAG_AGC: u16 = 0x3FFD;
    /// CORDIC magnitude.
    pub const MAGNITUDE: u16 = 0x3FFE;
    /// Angle.
    pub const ANGLE: u16 = 0x3FFF;
}

/// Diagnostics bits of [`reg::DIAG_AGC`].
pub mod diag {
    /// Offset compensation finished (must be 1).
    pub const OCF: u16 = 1 << 8;
    /// CORDIC overflow (must be 0).
    pub const COF: u16 = 1 << 9;
    /// Field too strong.
    pub const COMP_LOW: u16 = 1 << 10;
    /// Field too weak.
    pub const COMP_HIGH: u16 = 1 << 11;
}

/// Error register bits (read through [`reg::CLEAR_ERROR_FLAG`]).
pub mod err {
    /// Framing error (frame not 16 bits).
    pub const FRAMING: u16 = 1 << 0;
    /// Invalid command.
    pub const COMMAND_INVALID: u16 = 1 << 1;
    /// Parity error in a command.
    pub const PARITY: u16 = 1 << 2;
}

/// Lowest AGC accepted: below it the field is too strong to trust.
pub const AGC_MIN: u8 = 5;
/// Highest AGC accepted: above it the field is too weak to trust (magnet far or lost).
pub const AGC_MAX: u8 = 250;
/// AGC band edges that still work but flag the result as [`kerfmeter_protocol::QualityFlags::WEAK_MAGNET`].
pub const AGC_WARN: (u8, u8) = (20, 220);
/// Magnitude band accepted (CORDIC magnitude; the AGC holds it near mid-scale).
pub const MAGNITUDE_RANGE: (u16, u16) = (500, 16_000);

/// Consecutive rejected jumps after which an output-shaft encoder re-acquires its position (the
/// last accepted reading is stale: the magnet was lost and is back, the bus glitched for a
/// while). The hub never leaves ±180° of zero, so the turn nearest zero is the right one. A
/// motor-shaft encoder cannot do this (a motor turn is 360°/gear ratio of hub angle): it keeps
/// rejecting, the controller faults on encoder errors, and the device must restart at zero.
pub const RESYNC_AFTER_JUMPS: u32 = 3;

/// Largest believable hub motion between two samples, degrees.
pub const MAX_HUB_STEP_DEG: f32 = 10.0;

/// Even parity bit for the 15 low bits, in bit 15.
pub const fn with_parity(word: u16) -> u16 {
    let low = word & 0x7FFF;
    if low.count_ones() % 2 == 1 {
        low | 0x8000
    } else {
        low
    }
}

/// True when the 16-bit word has even parity.
pub const fn parity_ok(word: u16) -> bool {
    word.count_ones().is_multiple_of(2)
}

/// A read command for `address`.
pub const fn read_command(address: u16) -> u16 {
    with_parity(0x4000 | (address & DATA_MASK))
}

/// How the encoder is mounted, from the device configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderSettings {
    /// Where the magnet sits.
    pub placement: EncoderPlacement,
    /// Motor turns per hub turn.
    pub gear_ratio: f32,
    /// Count the other way round.
    pub inverted: bool,
    /// Raw reading at the hub's zero position.
    pub zero_raw: u16,
    /// Largest believable change of *encoder* angle between two samples, degrees.
    pub max_step_deg: f32,
}

impl EncoderSettings {
    /// Settings from the stored device configuration.
    pub fn from_config(config: &DeviceConfig) -> Self {
        let mut settings = Self {
            placement: config.encoder_placement,
            gear_ratio: config.gear_ratio,
            inverted: config.encoder_inverted,
            zero_raw: config.encoder_zero_raw,
            max_step_deg: 0.0,
        };
        // The hub never turns 10° in one 1 ms tick (the reference motor's no-load output speed
        // is about 3°/ms); on the motor shaft that is 10° × gear ratio, kept under half a turn
        // so that the unwrap stays unambiguous.
        settings.max_step_deg = (MAX_HUB_STEP_DEG * settings.turns_per_hub_turn()).min(170.0);
        settings
    }

    /// Encoder turns per hub turn.
    fn turns_per_hub_turn(&self) -> f32 {
        match self.placement {
            EncoderPlacement::OutputShaft => 1.0,
            EncoderPlacement::MotorShaft => self.gear_ratio,
        }
    }
}

/// The diagnostics registers, decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Diagnostics {
    /// Automatic gain control: 0 = strong field, 255 = weak field.
    pub agc: u8,
    /// Offset compensation finished.
    pub ocf: bool,
    /// CORDIC overflow.
    pub cof: bool,
    /// Field too strong.
    pub comp_low: bool,
    /// Field too weak.
    pub comp_high: bool,
    /// CORDIC magnitude.
    pub magnitude: u16,
}

/// What the diagnostics found wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DiagnosticFault {
    /// OCF clear or COF set: the chip is not measuring (or the bus is stuck).
    Chip,
    /// Field too weak or too strong, or AGC / magnitude out of band: the magnet.
    Magnet,
}

impl Diagnostics {
    /// Decode the two registers.
    pub fn from_registers(diag_agc: u16, magnitude: u16) -> Self {
        Self {
            agc: (diag_agc & 0xFF) as u8,
            ocf: diag_agc & diag::OCF != 0,
            cof: diag_agc & diag::COF != 0,
            comp_low: diag_agc & diag::COMP_LOW != 0,
            comp_high: diag_agc & diag::COMP_HIGH != 0,
            magnitude: magnitude & DATA_MASK,
        }
    }

    /// Check against the datasheet's rules and the bands.
    pub fn check(&self) -> Result<(), DiagnosticFault> {
        if !self.ocf || self.cof {
            return Err(DiagnosticFault::Chip);
        }
        if self.comp_low
            || self.comp_high
            || !(AGC_MIN..=AGC_MAX).contains(&self.agc)
            || !(MAGNITUDE_RANGE.0..=MAGNITUDE_RANGE.1).contains(&self.magnitude)
        {
            return Err(DiagnosticFault::Magnet);
        }
        Ok(())
    }

    /// Working, but near the edge of the AGC band.
    pub fn marginal(&self) -> bool {
        self.agc < AGC_WARN.0 || self.agc > AGC_WARN.1
    }
}

/// Why a read failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncoderError<E> {
    /// The SPI transfer itself failed.
    Bus(E),
    /// A response had odd parity.
    Parity,
    /// The chip flagged an error; the error register's bits (see [`err`]).
    ErrorFlag(u16),
    /// The angle moved more than is physically possible since the last sample (angle reads
    /// only).
    Jump,
}

/// Why [`As5048a::diagnostics`] failed: the registers could not be read, or they were read and
/// report a fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DiagnosticsError<E> {
    /// Reading the registers failed.
    Read(EncoderError<E>),
    /// The registers report a fault.
    Failed(DiagnosticFault),
}

impl<E> From<EncoderError<E>> for DiagnosticsError<E> {
    fn from(e: EncoderError<E>) -> Self {
        Self::Read(e)
    }
}

/// Counters since construction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EncoderStats {
    /// Successful angle samples.
    pub samples: u32,
    /// Responses with bad parity.
    pub parity_errors: u32,
    /// Responses with the error flag set.
    pub error_flags: u32,
    /// Rejected jumps.
    pub jumps: u32,
}

/// The AS5048A driver.
pub struct As5048a<SPI> {
    spi: SPI,
    settings: EncoderSettings,
    /// The command whose answer the next frame carries.
    pending: u16,
    /// Last accepted raw reading and the whole turns counted so far.
    last_raw: Option<u16>,
    turns: i32,
    consecutive_jumps: u32,
    stats: EncoderStats,
}

impl<SPI: SpiDevice<u8>> As5048a<SPI> {
    /// A driver for the chip on `spi`. Does no I/O; call [`As5048a::diagnostics`] before use.
    pub fn new(spi: SPI, settings: EncoderSettings) -> Self {
        Self {
            spi,
            settings,
            pending: reg::NOP,
            last_raw: None,
            turns: 0,
            consecutive_jumps: 0,
            stats: EncoderStats::default(),
        }
    }

    /// Counters since construction.
    pub fn stats(&self) -> EncoderStats {
        self.stats
    }

    /// Change the mounting settings (after a change of them in the configuration). Restarts the
    /// unwrap: the next reading is taken as a first one (see the module docs for what that means
    /// on the motor shaft).
    pub fn set_settings(&mut self, settings: EncoderSettings) {
        self.settings = settings;
        self.last_raw = None;
        self.turns = 0;
    }

    /// Give the bus back.
    pub fn release(self) -> SPI {
        self.spi
    }

    /// The bus (a test harness sets the fake chip's angle through it).
    pub fn bus_mut(&mut self) -> &mut SPI {
        &mut self.spi
    }

    /// One 16-bit frame: send `command`, return what the chip shifted out (the answer to the
    /// previous command), parity- and EF-checked.
    fn frame(&mut self, command: u16) -> Result<u16, EncoderError<SPI::Error>> {
        let word = self.clock_frame(command)?;
        if !parity_ok(word) {
            self.stats.parity_errors += 1;
            return Err(EncoderError::Parity);
        }
        if word & 0x4000 != 0 {
            self.stats.error_flags += 1;
            return Err(EncoderError::ErrorFlag(self.read_error_register()?));
        }
        Ok(word & DATA_MASK)
    }

    /// Read and clear the error register (two frames); returns its bits.
    fn read_error_register(&mut self) -> Result<u16, EncoderError<SPI::Error>> {
        for command in [read_command(reg::CLEAR_ERROR_FLAG), read_command(reg::NOP)] {
            let word = self.clock_frame(command)?;
            if command == read_command(reg::NOP) {
                if !parity_ok(word) {
                    self.stats.parity_errors += 1;
                    return Err(EncoderError::Parity);
                }
                return Ok(word & 0x0007);
            }
        }
        unreachable!("the loop returns on its second frame")
    }

    /// Clock one 16-bit frame out and in, in one transaction with the chip-select setup and hold
    /// times; returns the raw response (unchecked).
    fn clock_frame(&mut self, command: u16) -> Result<u16, EncoderError<SPI::Error>> {
        let mut bytes = command.to_be_bytes();
        self.spi
            .transaction(&mut [
                Operation::DelayNs(CS_SETUP_NS),
                Operation::TransferInPlace(&mut bytes),
                Operation::DelayNs(CS_HOLD_NS),
            ])
            .map_err(EncoderError::Bus)?;
        self.pending = command & 0x3FFF;
        Ok(u16::from_be_bytes(bytes))
    }

    /// Read a register (two frames unless its read is already pending).
    pub fn read_register(&mut self, address: u16) -> Result<u16, EncoderError<SPI::Error>> {
        if self.pending != address {
            self.frame(read_command(address))?;
        }
        // Ask for the same register again, so that a following read of it costs one frame.
        self.frame(read_command(address))
    }

    /// Read and check the diagnostics and magnitude registers.
    pub fn diagnostics(&mut self) -> Result<Diagnostics, DiagnosticsError<SPI::Error>> {
        let diag_agc = self.read_register(reg::DIAG_AGC)?;
        let magnitude = self.read_register(reg::MAGNITUDE)?;
        let d = Diagnostics::from_registers(diag_agc, magnitude);
        d.check().map_err(DiagnosticsError::Failed)?;
        Ok(d)
    }

    /// Read the raw 14-bit angle.
    pub fn read_raw(&mut self) -> Result<u16, EncoderError<SPI::Error>> {
        self.read_register(reg::ANGLE)
    }

    /// Read the hub angle from its zero position, degrees, unwrapped over turns.
    pub fn read_hub_deg(&mut self) -> Result<f32, EncoderError<SPI::Error>> {
        let raw = self.read_raw()?;
        self.unwrap(raw)
    }

    /// Fold a new raw reading into the multi-turn count; rejects impossible jumps.
    fn unwrap(&mut self, raw: u16) -> Result<f32, EncoderError<SPI::Error>> {
        let counts = i32::from(COUNTS_PER_TURN);
        let half = counts / 2;
        let raw_counts = i32::from(raw);
        match self.last_raw {
            Some(last) => {
                // The shortest way round: a step of more than half a turn crossed the wrap.
                let step = raw_counts - i32::from(last);
                let wrap = if step > half {
                    -1
                } else if step < -half {
                    1
                } else {
                    0
                };
                let step_deg = (step + wrap * counts) as f32 * 360.0 / counts as f32;
                if step_deg.abs() > self.settings.max_step_deg {
                    self.stats.jumps += 1;
                    self.consecutive_jumps += 1;
                    if self.consecutive_jumps < RESYNC_AFTER_JUMPS
                        || self.settings.placement != EncoderPlacement::OutputShaft
                    {
                        return Err(EncoderError::Jump);
                    }
                    // Stale reference: re-acquire as at boot.
                    self.last_raw = None;
                    return self.unwrap(raw);
                }
                self.turns += wrap;
            }
            None => {
                // First reading: the turn that puts the hub nearest its zero. (On the motor
                // shaft that assumes the hub stands within ±180°/gear ratio of zero: a motor-shaft
                // encoder cannot tell hub positions a motor turn apart. After a boot the controller
                // refuses runs until the user has confirmed it, `Conditions::HUB_TURN_UNKNOWN`.)
                let offset = raw_counts - i32::from(self.settings.zero_raw);
                self.turns = if offset > half {
                    -1
                } else if offset < -half {
                    1
                } else {
                    0
                };
            }
        }
        self.last_raw = Some(raw);
        self.consecutive_jumps = 0;
        self.stats.samples += 1;
        let total = self.turns * counts + i32::from(raw) - i32::from(self.settings.zero_raw);
        let encoder_deg = total as f32 * 360.0 / counts as f32;
        let hub_deg = encoder_deg / self.settings.turns_per_hub_turn();
        Ok(if self.settings.inverted {
            -hub_deg
        } else {
            hub_deg
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fakes::as5048a::{FakeAs5048a, MisoFault};

    fn settings() -> EncoderSettings {
        EncoderSettings::from_config(&DeviceConfig::DEFAULT)
    }

    fn driver(fake: FakeAs5048a) -> As5048a<FakeAs5048a> {
        As5048a::new(fake, settings())
    }

    #[test]
    fn parity_is_even_over_sixteen_bits() {
        assert_eq!(read_command(reg::ANGLE), 0xFFFF);
        assert_eq!(read_command(reg::NOP), 0xC000);
        assert_eq!(read_command(reg::CLEAR_ERROR_FLAG), 0x4001);
        assert_eq!(read_command(reg::DIAG_AGC), 0x7FFD);
        assert!(parity_ok(0x0000) && parity_ok(0xFFFF) && !parity_ok(0x0001));
    }

    #[test]
    fn reads_the_angle_through_the_pipeline() {
        let mut fake = FakeAs5048a::new(1);
        fake.set_angle_deg(90.0);
        let mut enc = driver(fake);
        let a = enc.read_hub_deg().unwrap();
        assert!((a - 90.0).abs() < 0.05, "{a}");
        // After the first read, each sample costs one frame.
        let frames = enc.spi.frames();
        enc.read_hub_deg().unwrap();
        assert_eq!(enc.spi.frames(), frames + 1);
        // Every frame met the chip-select setup and hold times.
        enc.diagnostics().unwrap();
        assert_eq!(enc.spi.timing_violations(), 0);
    }

    #[test]
    fn unwraps_across_turns_and_applies_gear_ratio_and_sense() {
        let mut fake = FakeAs5048a::new(2);
        fake.set_angle_deg(350.0);
        let mut enc = As5048a::new(
            fake,
            EncoderSettings {
                placement: EncoderPlacement::MotorShaft,
                gear_ratio: 21.0,
                inverted: true,
                zero_raw: 0,
                max_step_deg: 90.0,
            },
        );
        let a0 = enc.read_hub_deg().unwrap();
        let mut motor_deg = 350.0;
        for _ in 0..100 {
            motor_deg += 37.0;
            enc.spi.set_angle_deg(motor_deg);
            enc.read_hub_deg().unwrap();
        }
        let a1 = enc.read_hub_deg().unwrap();
        let hub_turned = -(a1 - a0);
        assert!((hub_turned - 3700.0 / 21.0).abs() < 0.05, "{hub_turned}");
    }

    #[test]
    fn a_parity_error_is_reported_and_the_next_read_works() {
        let mut fake = FakeAs5048a::new(3);
        fake.set_angle_deg(10.0);
        let mut enc = driver(fake);
        enc.read_hub_deg().unwrap();
        enc.spi.corrupt_next_responses(1);
        assert_eq!(enc.read_hub_deg(), Err(EncoderError::Parity));
        assert!((enc.read_hub_deg().unwrap() - 10.0).abs() < 0.05);
        assert_eq!(enc.stats().parity_errors, 1);
    }

    #[test]
    fn a_command_error_sets_ef_and_the_error_register_is_read_and_cleared() {
        let mut fake = FakeAs5048a::new(4);
        fake.set_angle_deg(20.0);
        let mut enc = driver(fake);
        enc.read_hub_deg().unwrap();
        // A glitch on MOSI: the chip receives a command with bad parity.
        enc.spi.corrupt_next_commands(1);
        enc.read_hub_deg().unwrap(); // this frame's command is corrupted; its answer is still fine
        assert_eq!(
            enc.read_hub_deg(),
            Err(EncoderError::ErrorFlag(err::PARITY))
        );
        // Cleared: reads work again.
        enc.read_hub_deg().unwrap();
        enc.read_hub_deg().unwrap();
        assert_eq!(enc.stats().error_flags, 1);
    }

    #[test]
    fn healthy_diagnostics_pass() {
        let mut enc = driver(FakeAs5048a::new(5));
        let d = enc.diagnostics().unwrap();
        assert!(d.ocf && !d.cof && !d.comp_high && !d.comp_low);
        assert!(!d.marginal());
    }

    #[test]
    fn a_weak_magnet_fails_the_diagnostics() {
        let mut fake = FakeAs5048a::new(6);
        fake.set_magnet_lost(true);
        let mut enc = driver(fake);
        assert_eq!(
            enc.diagnostics(),
            Err(DiagnosticsError::Failed(DiagnosticFault::Magnet))
        );
    }

    #[test]
    fn miso_stuck_low_reads_zero_with_valid_parity_and_only_diagnostics_catch_it() {
        let mut fake = FakeAs5048a::new(7);
        fake.set_angle_deg(45.0);
        fake.set_miso_fault(Some(MisoFault::StuckLow));
        let mut enc = driver(fake);
        // Angle reads "succeed": zero, forever.
        assert_eq!(enc.read_hub_deg(), Ok(0.0));
        assert_eq!(enc.read_hub_deg(), Ok(0.0));
        assert_eq!(
            enc.diagnostics(),
            Err(DiagnosticsError::Failed(DiagnosticFault::Chip))
        );
    }

    #[test]
    fn miso_stuck_high_reads_as_error_flags() {
        let mut fake = FakeAs5048a::new(8);
        fake.set_miso_fault(Some(MisoFault::StuckHigh));
        let mut enc = driver(fake);
        assert!(matches!(
            enc.read_hub_deg(),
            Err(EncoderError::ErrorFlag(_))
        ));
        assert!(enc.diagnostics().is_err());
    }

    #[test]
    fn impossible_jumps_are_rejected() {
        let mut fake = FakeAs5048a::new(9);
        fake.set_angle_deg(0.0);
        let mut enc = driver(fake);
        enc.read_hub_deg().unwrap();
        enc.spi.set_angle_deg(150.0);
        // The pipeline: this frame still carries the sample taken one frame ago.
        assert!(enc.read_hub_deg().unwrap().abs() < 0.05);
        assert_eq!(enc.read_hub_deg(), Err(EncoderError::Jump));
        enc.spi.set_angle_deg(1.0);
        assert_eq!(enc.read_hub_deg(), Err(EncoderError::Jump));
        assert!((enc.read_hub_deg().unwrap() - 1.0).abs() < 0.05);
        assert_eq!(enc.stats().jumps, 2);
    }

    #[test]
    fn an_output_shaft_encoder_resyncs_after_a_stale_reference() {
        let mut fake = FakeAs5048a::new(11);
        fake.set_angle_deg(60.0);
        let mut enc = driver(fake);
        enc.read_hub_deg().unwrap();
        // The magnet goes away: noise is rejected or accepted at random...
        enc.spi.set_magnet_lost(true);
        for _ in 0..50 {
            let _ = enc.read_hub_deg();
        }
        // ...and comes back: within a few reads the true angle is reported again.
        enc.spi.set_magnet_lost(false);
        let mut reads = Vec::new();
        for _ in 0..(RESYNC_AFTER_JUMPS + 2) {
            reads.push(enc.read_hub_deg());
        }
        let last = reads.last().unwrap().as_ref().expect("resynced");
        assert!((last - 60.0).abs() < 0.1, "{reads:?}");
    }

    #[test]
    fn a_motor_shaft_encoder_never_guesses_after_a_stale_reference() {
        let mut fake = FakeAs5048a::new(12);
        fake.set_angle_deg(100.0);
        let mut s = settings();
        s.placement = EncoderPlacement::MotorShaft;
        let mut enc = As5048a::new(fake, s);
        enc.read_hub_deg().unwrap();
        // Half a motor turn away: ambiguous by a motor turn, so never accepted.
        enc.spi.set_angle_deg(280.0);
        enc.read_hub_deg().unwrap(); // the pipeline's older sample
        for _ in 0..10 {
            assert_eq!(enc.read_hub_deg().map(|_| ()), Err(EncoderError::Jump));
        }
    }

    #[test]
    fn the_zero_offset_is_applied() {
        let mut fake = FakeAs5048a::new(10);
        fake.set_angle_deg(100.0);
        let mut s = settings();
        s.zero_raw = (100.0 / 360.0 * 16384.0) as u16;
        let mut enc = As5048a::new(fake, s);
        assert!(enc.read_hub_deg().unwrap().abs() < 0.05);
    }
}
