//! The device's health in the CLI's words (protocol 2.6's `Diagnostics`): the last reset's
//! reason, an uncalibrated ADC, the brown-out detector, for `kerfmeter info` and `status` (and
//! a bring-up report). A watchdog, brown-out or panic reset is said as such, with what it means.

use kerfmeter::protocol::{AdcCalibration, BrownOutDetector, Diagnostics, ResetReason};

/// A sentence for the last reset, with what an abnormal one means.
pub fn describe_reset(reason: ResetReason) -> String {
    match reason {
        ResetReason::Watchdog => "the watchdog reset the device: its control loop stopped for \
            50 ms or more (a hang, or a panic it could not record), and the motor was made safe \
            by the reset; if it happens again, capture the log on UART0 (GPIO21, 115200 baud) \
            and report it"
            .to_owned(),
        ResetReason::BrownOut => "a brown-out reset the device: the chip's 3.3 V supply dipped \
            (a weak USB port or cable, or the motor's current pulling the logic supply down); \
            power the board from a stiffer supply, and keep the motor's ground return off the \
            logic ground's wire"
            .to_owned(),
        ResetReason::Panic => "the firmware panicked and the watchdog reset the device (the \
            motor was made safe first); capture the panic message on UART0 (GPIO21, 115200 baud) \
            and report it"
            .to_owned(),
        ResetReason::PowerOn => "power-on".to_owned(),
        ResetReason::Software => "reset by the firmware or a debugger".to_owned(),
        ResetReason::UsbHost => "reset by the host over USB (a flasher, or a program that \
            toggled the port's RTS line)"
            .to_owned(),
        ResetReason::Other(code) => format!("another reason (chip code {code:#04x})"),
        ResetReason::Unknown => "unknown".to_owned(),
    }
}

/// A sentence for the ADC's calibration.
pub fn describe_adc(calibration: AdcCalibration) -> String {
    match calibration {
        AdcCalibration::Efuse { version } => format!("calibrated (eFuse scheme {version})"),
        AdcCalibration::Uncalibrated => "uncalibrated: this chip has no ADC calibration eFuses, \
            so the current sense reads some 30–40 % high (the self-test's torque constant and \
            the winding estimate with it); the torque of a measurement is set from the duty and \
            is not affected"
            .to_owned(),
        AdcCalibration::Unknown => "not reported".to_owned(),
    }
}

/// A sentence for the brown-out detector.
pub fn describe_brown_out(detector: BrownOutDetector) -> &'static str {
    match detector {
        BrownOutDetector::Resets => "on (a sag resets the chip)",
        BrownOutDetector::InterruptOnly => "on, interrupt only (a sag does not reset the chip)",
        BrownOutDetector::Off => {
            "off (the bootloader did not enable it): a sagging logic supply can corrupt the \
             chip's state without a reset"
        }
        BrownOutDetector::Unknown => "not reported",
    }
}

/// The warnings a host should show about `d`: an abnormal last reset, an uncalibrated ADC, a
/// brown-out detector that is off, ADC conversions given up.
pub fn health_warnings(d: &Diagnostics) -> Vec<String> {
    let mut warnings = Vec::new();
    if d.reset_reason.is_abnormal() {
        warnings.push(describe_reset(d.reset_reason));
    }
    if d.adc_calibration == AdcCalibration::Uncalibrated {
        warnings.push(format!("the ADC is {}", describe_adc(d.adc_calibration)));
    }
    if d.brown_out == BrownOutDetector::Off {
        warnings.push(format!(
            "the brown-out detector is {}",
            describe_brown_out(d.brown_out)
        ));
    }
    if d.adc_restarts > 0 {
        warnings.push(format!(
            "{} ADC conversion(s) never finished since boot and the ADC was restarted: check \
             the current-sense and supply-sense wiring",
            d.adc_restarts
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerfmeter::protocol::G2Variant;

    fn healthy() -> Diagnostics {
        Diagnostics {
            reset_reason: ResetReason::PowerOn,
            chip_revision: None,
            adc_calibration: AdcCalibration::Efuse { version: 1 },
            brown_out: BrownOutDetector::Resets,
            cs_asleep_mv: None,
            cs_offset_mv: 50.0,
            cs_offset_learnt: false,
            encoder: None,
            longest_step_us: 0,
            longest_gap_us: 1000,
            adc_restarts: 0,
            driver: G2Variant::V18v17,
        }
    }

    #[test]
    fn a_watchdog_or_brown_out_reset_is_said_in_words_and_a_power_on_is_not_a_warning() {
        assert!(health_warnings(&healthy()).is_empty());
        let watchdog = Diagnostics {
            reset_reason: ResetReason::Watchdog,
            ..healthy()
        };
        let warnings = health_warnings(&watchdog);
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].starts_with("the watchdog reset the device"),
            "{warnings:?}"
        );
        let brown_out = Diagnostics {
            reset_reason: ResetReason::BrownOut,
            adc_calibration: AdcCalibration::Uncalibrated,
            ..healthy()
        };
        let warnings = health_warnings(&brown_out);
        assert!(warnings[0].contains("brown-out"), "{warnings:?}");
        assert!(warnings[1].contains("30–40 % high"), "{warnings:?}");
    }
}
