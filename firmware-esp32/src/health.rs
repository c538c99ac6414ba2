//! What the device knows about its own health since boot, answered by `GetDiagnostics`
//! (protocol 2.6): facts the board reads once at boot ([`BootFacts`]: the last reset's reason,
//! the chip revision, the ADC's calibration, the brown-out detector), what the shared control
//! tick sees of the sensors ([`SenseFacts`]: the current sense asleep and its learnt offset,
//! the encoder's diagnostics), ADC conversions given up, and the motor driver the firmware was
//! built for.
//!
//! The board fills [`BootFacts`] from the chip (`board::boot`); the digital twin sets each of
//! them, so that tests can drive them (a watchdog reset, an uncalibrated ADC).

use kerfmeter_protocol::{
    AdcCalibration, BrownOutDetector, ChipRevision, Diagnostics, EncoderHealth, G2Variant,
    ResetReason, Status,
};

/// The reset reason of the chip's reset-reason code (the ROM's `rtc_get_reset_reason`, esp-hal's
/// `SocResetReason` as a number; the codes are the same on the ESP32-C3 and C6), `None` where
/// esp-hal knew no such code. A watchdog reset after the panic path recorded a panic
/// (`panicked`) is a panic.
pub fn reset_reason_from_code(code: Option<u8>, panicked: bool) -> ResetReason {
    let Some(code) = code else {
        return ResetReason::Unknown;
    };
    let reason = match code {
        0x01 => ResetReason::PowerOn,
        // The digital core or CPU 0 reset by software (RTC_CNTL_SW_SYS_RST, _SW_PROCPU_RST).
        0x03 | 0x0C => ResetReason::Software,
        // Main watchdogs 0 and 1 (TIMG0/TIMG1), the RTC watchdog, the super watchdog.
        0x07 | 0x08 | 0x09 | 0x0B | 0x0D | 0x10 | 0x11 | 0x12 => ResetReason::Watchdog,
        0x0F => ResetReason::BrownOut,
        // USB-Serial-JTAG's UART or JTAG side, and (C6) a JTAG CPU reset.
        0x15 | 0x16 | 0x18 => ResetReason::UsbHost,
        other => ResetReason::Other(other),
    };
    if panicked && reason == ResetReason::Watchdog {
        ResetReason::Panic
    } else {
        reason
    }
}

/// The ADC's calibration from the eFuse calibration scheme's version (esp-hal's
/// `efuse::rtc_calib_version`: 0 when the chip carries none).
pub fn adc_calibration_from_version(version: u8) -> AdcCalibration {
    match version {
        0 => AdcCalibration::Uncalibrated,
        version => AdcCalibration::Efuse { version },
    }
}

/// Facts the board reads once, at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BootFacts {
    /// Why the chip last started.
    pub reset_reason: ResetReason,
    /// The silicon revision, where read.
    pub chip_revision: Option<ChipRevision>,
    /// Whether the ADC is calibrated by eFuses.
    pub adc_calibration: AdcCalibration,
    /// The brown-out detector as found.
    pub brown_out: BrownOutDetector,
}

impl BootFacts {
    /// Nothing read (a bare `Device`, the tests).
    pub const UNKNOWN: Self = Self {
        reset_reason: ResetReason::Unknown,
        chip_revision: None,
        adc_calibration: AdcCalibration::Unknown,
        brown_out: BrownOutDetector::Unknown,
    };

    /// The ADC reads without eFuse calibration: `Conditions::ADC_UNCALIBRATED` stands.
    pub fn adc_uncalibrated(&self) -> bool {
        self.adc_calibration == AdcCalibration::Uncalibrated
    }
}

/// What the control tick saw of the sensors, as of the last tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SenseFacts {
    /// The `CS` pin asleep, settled, mV.
    pub cs_asleep_mv: Option<u16>,
    /// The learnt `CS` offset, mV.
    pub cs_offset_mv: f32,
    /// Whether it was learnt since boot.
    pub cs_offset_learnt: bool,
    /// The encoder's diagnostics as last read.
    pub encoder: Option<EncoderHealth>,
}

impl SenseFacts {
    /// Before the first tick: the nominal offset, nothing read.
    pub const NONE: Self = Self {
        cs_asleep_mv: None,
        cs_offset_mv: crate::board::current::CURRENT_SENSE_OFFSET_MV,
        cs_offset_learnt: false,
        encoder: None,
    };
}

/// Everything `GetDiagnostics` reports but the timing, which the controller keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Health {
    /// Read at boot.
    pub boot: BootFacts,
    /// Seen by the last tick.
    pub sense: SenseFacts,
    /// ADC conversions given up since boot.
    pub adc_restarts: u16,
    /// The motor driver.
    pub driver: G2Variant,
}

impl Health {
    /// Nothing known yet, the reference build's driver.
    pub const fn new() -> Self {
        Self {
            boot: BootFacts::UNKNOWN,
            sense: SenseFacts::NONE,
            adc_restarts: 0,
            driver: G2Variant::V18v17,
        }
    }

    /// The answer to `GetDiagnostics`, with the timing of `status`.
    pub fn diagnostics(&self, status: &Status) -> Diagnostics {
        Diagnostics {
            reset_reason: self.boot.reset_reason,
            chip_revision: self.boot.chip_revision,
            adc_calibration: self.boot.adc_calibration,
            brown_out: self.boot.brown_out,
            cs_asleep_mv: self.sense.cs_asleep_mv,
            cs_offset_mv: self.sense.cs_offset_mv,
            cs_offset_learnt: self.sense.cs_offset_learnt,
            encoder: self.sense.encoder,
            longest_step_us: status.longest_step_us,
            longest_gap_us: status.longest_gap_us,
            adc_restarts: self.adc_restarts,
            driver: self.driver,
        }
    }
}

impl Default for Health {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reset_codes_read_as_their_reasons_and_a_recorded_panic_as_a_panic() {
        let reason = |code| reset_reason_from_code(Some(code), false);
        assert_eq!(reason(0x01), ResetReason::PowerOn);
        assert_eq!(
            reason(0x08),
            ResetReason::Watchdog,
            "TIMG1's MWDT, the board's"
        );
        assert_eq!(reason(0x0F), ResetReason::BrownOut);
        assert_eq!(reason(0x0C), ResetReason::Software);
        assert_eq!(reason(0x15), ResetReason::UsbHost);
        assert_eq!(reason(0x05), ResetReason::Other(0x05), "deep sleep");
        assert_eq!(reset_reason_from_code(None, false), ResetReason::Unknown);
        assert_eq!(reset_reason_from_code(Some(0x08), true), ResetReason::Panic);
        // A mark left over from before a power cycle does not turn a power-on into a panic.
        assert_eq!(
            reset_reason_from_code(Some(0x01), true),
            ResetReason::PowerOn
        );
        assert!(ResetReason::Watchdog.is_abnormal() && ResetReason::BrownOut.is_abnormal());
        assert!(!ResetReason::PowerOn.is_abnormal());
    }

    #[test]
    fn calibration_version_zero_is_uncalibrated() {
        assert_eq!(
            adc_calibration_from_version(0),
            AdcCalibration::Uncalibrated
        );
        assert_eq!(
            adc_calibration_from_version(1),
            AdcCalibration::Efuse { version: 1 }
        );
        let boot = BootFacts {
            adc_calibration: AdcCalibration::Uncalibrated,
            ..BootFacts::UNKNOWN
        };
        assert!(boot.adc_uncalibrated());
        assert!(!BootFacts::UNKNOWN.adc_uncalibrated());
    }
}
