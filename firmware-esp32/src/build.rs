//! Facts about this firmware build: those `GetInfo` reports, and the board's watchdog timeouts,
//! which the digital twin models too.

use kerfmeter_protocol::{
    DeviceInfo, FirmwareVersion, HardwareInfo, MAX_REQUEST_FRAME_LEN, PROTOCOL_VERSION,
};

/// The firmware version, from the crate version in `Cargo.toml`.
pub const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: parse_u16(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: parse_u16(env!("CARGO_PKG_VERSION_MINOR")),
    patch: parse_u16(env!("CARGO_PKG_VERSION_PATCH")),
};

/// Control loop rate of every build, Hz.
pub const CONTROL_RATE_HZ: u16 = 1000;
/// AS5048A resolution, bits per turn.
pub const ENCODER_BITS: u8 = 14;
/// Motor PWM frequency, Hz: above hearing, within the G2's 100 kHz limit. The board's LEDC timer
/// runs at it; the digital twin's current sense, which is valid only in the drive phase of each
/// PWM period, uses it too.
pub const PWM_FREQUENCY_HZ: u32 = 20_000;
/// LEDC duty resolution at [`PWM_FREQUENCY_HZ`] from the 80 MHz APB clock (the maximum there).
pub const PWM_BITS: u8 = 11;
/// Capacity of the run's sample log.
pub const MAX_SAMPLES: u16 = 2048;
/// Hardware watchdog timeout of the board in normal running, ms: a control loop stalled this long
/// resets the chip. The control tick feeds it; the configuration flash gives each of its
/// operations a longer window (see [`crate::watchdog`]).
///
/// Why 50 ms: the tick comes every 1 ms; the worst step costs 13.4k instructions (under 0.13 ms
/// at 160 MHz; `cargo xtask bench-step`), link work a few ms at most, and a late tick 1–5 ms. The controller itself faults a
/// run (`StepOverrun`) once 8 ms pass between steps (or late steps come often), so nothing
/// healthy comes near 50 ms — ten times the latest tick the twin draws — while a hung loop with the motor driven is reset within
/// 50 ms rather than half a second. The digital twin resets its device after the same time.
pub const WATCHDOG_TIMEOUT_MS: u64 = 50;
/// Hardware watchdog timeout around each flash erase or write, ms (see [`crate::watchdog`]): a
/// 4 KiB sector erase stalls the core for 45 ms typically and 300–400 ms at worst on a C3
/// module's flash (the twin's range goes to 1000 ms). 2 s is five times the datasheet worst
/// case. It costs nothing in safety: flash is written only with the motor asleep.
pub const FLASH_WATCHDOG_TIMEOUT_MS: u64 = 2000;

/// The `GetInfo` answer of a device named `board` (`"esp32c3"`, `"esp32c6"`, `"twin"`) that
/// booted with `boot_id`.
pub fn device_info(board: &str, boot_id: u32) -> DeviceInfo {
    let mut name = kerfmeter_protocol::heapless::String::new();
    // Board names are compile-time constants shorter than the bound; truncate rather than fail.
    for c in board.chars() {
        if name.push(c).is_err() {
            break;
        }
    }
    DeviceInfo {
        protocol: PROTOCOL_VERSION,
        firmware: FIRMWARE_VERSION,
        boot_id,
        hardware: HardwareInfo {
            board: name,
            control_rate_hz: CONTROL_RATE_HZ,
            encoder_bits: ENCODER_BITS,
            pwm_bits: PWM_BITS,
            max_samples: MAX_SAMPLES,
            max_request_frame_len: MAX_REQUEST_FRAME_LEN as u16,
        },
    }
}

const fn parse_u16(s: &str) -> u16 {
    let bytes = s.as_bytes();
    let mut value: u16 = 0;
    let mut i = 0;
    while i < bytes.len() {
        assert!(
            bytes[i].is_ascii_digit(),
            "version component is not a number"
        );
        value = value * 10 + (bytes[i] - b'0') as u16;
        i += 1;
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn version_matches_the_crate() {
        let v = FIRMWARE_VERSION;
        assert_eq!(
            std::format!("{}.{}.{}", v.major, v.minor, v.patch),
            env!("CARGO_PKG_VERSION")
        );
    }

    #[test]
    fn long_board_names_are_truncated_not_rejected() {
        let info = device_info("a-board-name-much-longer-than-the-limit", 1);
        assert_eq!(
            info.hardware.board.len(),
            kerfmeter_protocol::BOARD_NAME_LEN
        );
    }
}
