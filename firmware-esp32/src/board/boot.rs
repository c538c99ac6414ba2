//! What the chip says about itself at boot, for `GetDiagnostics` (`crate::health`): the last
//! reset's reason (esp-hal's `system::reset_reason`, and the panic path's mark in RTC memory,
//! `board::emergency`), the silicon revision and the ADC's calibration version (esp-hal's
//! `efuse`), and the brown-out detector's register as the bootloader left it.
//!
//! esp-hal does not configure the brown-out detector; the second-stage bootloader enables it
//! only on some builds, so the firmware reads it and reports it rather than assume it is on. It
//! does not turn it on itself: its threshold and timing are the bootloader's (ESP-IDF's
//! `CONFIG_ESP_BROWNOUT_DET_LVL`), and a reset on a sag is better chosen there, once, than
//! written to a register the firmware cannot test without a supply that sags on purpose.

use kerfmeter_protocol::{BrownOutDetector, ChipRevision};

use crate::health::{BootFacts, adc_calibration_from_version, reset_reason_from_code};

/// Read the boot facts; call once, early (it clears the panic mark).
pub fn boot_facts() -> BootFacts {
    let panicked = super::emergency::take_panic_mark();
    let code = esp_hal::system::reset_reason().map(|reason| reason as u8);
    let revision = esp_hal::efuse::chip_revision();
    BootFacts {
        reset_reason: reset_reason_from_code(code, panicked),
        chip_revision: Some(ChipRevision {
            major: revision.major,
            minor: revision.minor,
        }),
        adc_calibration: adc_calibration_from_version(esp_hal::efuse::rtc_calib_version()),
        brown_out: brown_out(),
    }
}

/// The ESP32-C3's detector: RTC_CNTL's `BROWN_OUT` register.
#[cfg(feature = "esp32c3")]
fn brown_out() -> BrownOutDetector {
    let reg = esp_hal::peripherals::LPWR::regs().brown_out().read();
    if reg.brown_out_ena().bit_is_clear() {
        BrownOutDetector::Off
    } else if reg.brown_out_rst_ena().bit_is_set() {
        BrownOutDetector::Resets
    } else {
        BrownOutDetector::InterruptOnly
    }
}

/// The ESP32-C6's detector: LP_ANA's `BOD_MODE0_CNTL` register.
#[cfg(feature = "esp32c6")]
fn brown_out() -> BrownOutDetector {
    let reg = esp_hal::peripherals::LP_ANA::regs().bod_mode0_cntl().read();
    if reg.bod_mode0_reset_ena().bit_is_set() {
        BrownOutDetector::Resets
    } else if reg.bod_mode0_intr_ena().bit_is_set() {
        BrownOutDetector::InterruptOnly
    } else {
        BrownOutDetector::Off
    }
}
