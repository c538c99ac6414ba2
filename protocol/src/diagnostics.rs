//! What the device knows about its own health since boot (protocol 2.6): the answer to
//! [`Request::GetDiagnostics`](crate::Request::GetDiagnostics).
//!
//! `GetInfo` is frozen, so the facts a guided bring-up and a bug report need, and that `Info`
//! cannot carry, travel here: why the chip last reset, its revision, whether its ADC is
//! calibrated, whether the brown-out detector is on, what the current sense reads asleep and
//! the offset learnt braking, the encoder's own diagnostics, and the worst timing since boot.
//! An older device answers the request `ErrorCode::UnknownRequest`; a host then has none of
//! this (and says so), and everything else works as before.

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::params::G2Variant;

/// Why the chip last started, as its reset-reason register tells it (ESP32-C3/C6: the ROM's
/// `rtc_get_reset_reason`, which esp-hal reads as `SocResetReason`).
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetReason {
    /// The board could not tell (a code the firmware does not know, or none read).
    Unknown,
    /// Power was applied (or the `EN` pin released). On the ESP32-C3 a brown-out that resets
    /// the whole chip also reads as power-on: the chip gives both the same code.
    PowerOn,
    /// A watchdog reset the chip: the control loop stopped feeding the main watchdog (50 ms),
    /// or the RTC or super watchdog fired. A panic ends this way too unless the firmware
    /// recorded it ([`ResetReason::Panic`]).
    Watchdog,
    /// The supply of the chip dipped below the brown-out detector's threshold.
    BrownOut,
    /// The firmware panicked (it recorded so before the watchdog reset the chip).
    Panic,
    /// The firmware, or a debugger, reset the chip on purpose.
    Software,
    /// The host reset the chip through its USB port (the line-state sequence espflash and
    /// esptool use: RTS asserted with DTR released), or over JTAG.
    UsbHost,
    /// Another reason, with the chip's own code (deep sleep, a clock or power glitch, an eFuse
    /// CRC error).
    Other(u8),
}

impl ResetReason {
    /// The reason in a few words, for `info` and bug reports.
    pub const fn words(self) -> &'static str {
        match self {
            Self::Unknown => "unknown",
            Self::PowerOn => "power-on",
            Self::Watchdog => "watchdog",
            Self::BrownOut => "brown-out",
            Self::Panic => "panic",
            Self::Software => "software",
            Self::UsbHost => "reset by the host over USB",
            Self::Other(_) => "other",
        }
    }

    /// True for a reset that means something went wrong: a watchdog, a brown-out or a panic.
    pub const fn is_abnormal(self) -> bool {
        matches!(self, Self::Watchdog | Self::BrownOut | Self::Panic)
    }
}

/// The chip's silicon revision (eFuse `WAFER_VERSION_MAJOR`/`MINOR`).
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ChipRevision {
    /// Major revision.
    pub major: u8,
    /// Minor revision.
    pub minor: u8,
}

/// Whether the ADC's readings are calibrated by the chip's eFuses.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AdcCalibration {
    /// The chip carries ADC calibration eFuses of this version (ESP32-C3: version 1, in eFuse
    /// block 2 of version 1.x), and esp-hal calibrates each reading with them.
    Efuse {
        /// The calibration scheme's version.
        version: u8,
    },
    /// No calibration eFuses (early ESP32-C3 chips): esp-hal calibrates against an assumed
    /// reference, and the current sense reads some 30–40 % high. A measurement is still
    /// possible, but the torque-constant check and the winding estimate see the error; see
    /// `Conditions::ADC_UNCALIBRATED`.
    Uncalibrated,
    /// The board does not say (it has no ADC, or does not read the eFuses).
    Unknown,
}

/// The chip's brown-out detector as the firmware found it at boot. esp-hal leaves it as the
/// second-stage bootloader set it, which enables it only on some chip revisions and builds; the
/// firmware reports what it finds rather than assume.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BrownOutDetector {
    /// On, and a brown-out resets the chip (reported as [`ResetReason::BrownOut`]).
    Resets,
    /// On, but set to interrupt only: a brown-out does not reset the chip.
    InterruptOnly,
    /// Off: a sagging supply can corrupt the chip's state without a reset.
    Off,
    /// Not read (the digital twin unless set, or a board that does not read it).
    Unknown,
}

/// The encoder's own diagnostics, as last read (AS5048A: the DIAG/AGC register and the CORDIC
/// magnitude).
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EncoderHealth {
    /// The CORDIC magnitude (0..16383): the magnet's field strength.
    pub magnitude: u16,
    /// The automatic gain control (0..255): near 0 a magnet too strong (too close), near 255
    /// one too weak (too far).
    pub agc: u8,
    /// Offset compensation finished (OCF): must be set.
    pub ocf: bool,
    /// CORDIC overflow (COF): must be clear.
    pub cof: bool,
    /// Field too strong (COMP low).
    pub comp_low: bool,
    /// Field too weak (COMP high).
    pub comp_high: bool,
}

/// The answer to [`Request::GetDiagnostics`](crate::Request::GetDiagnostics) (protocol 2.6).
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Diagnostics {
    /// Why the chip last started.
    pub reset_reason: ResetReason,
    /// The silicon revision, where the board reads it.
    pub chip_revision: Option<ChipRevision>,
    /// Whether the ADC (current and supply sense) is calibrated.
    pub adc_calibration: AdcCalibration,
    /// The brown-out detector as found at boot.
    pub brown_out: BrownOutDetector,
    /// The filtered `CS` pin's last reading with the driver asleep for long enough that its
    /// filter holds the sleep level, mV (`None` before one was taken). The G2 does not document
    /// it; the firmware never learns its offset from it.
    pub cs_asleep_mv: Option<u16>,
    /// The `CS` offset the firmware learnt awake and braking, mV (50 mV nominal before the first
    /// run or self-test).
    pub cs_offset_mv: f32,
    /// Whether that offset was learnt since boot (false: still the nominal one).
    pub cs_offset_learnt: bool,
    /// The encoder's diagnostics as last read (`None` before the first good read).
    pub encoder: Option<EncoderHealth>,
    /// The longest control step since boot, µs (as `Status`).
    pub longest_step_us: u32,
    /// The longest gap between two control steps since boot, µs (as `Status`).
    pub longest_gap_us: u32,
    /// ADC conversions given up since boot (one that never finished; the driver was opened
    /// again).
    pub adc_restarts: u16,
    /// The motor driver the firmware was built for: its current-sense gain and supply limits.
    pub driver: G2Variant,
}
