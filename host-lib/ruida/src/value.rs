//! Ruida's numbers: big-endian groups of 7 bits, one group a byte, so that no data byte has its
//! top bit set (a byte ≥ 0x80 starts a command).
//!
//! - A 5-byte value carries 35 bits; coordinates are µm, signed 32-bit two's complement in the
//!   low 32 bits ([`encode_coord_um`]); speeds are µm/s ([`encode_speed`]).
//! - A 2-byte value carries 14 bits; power is a share of 2^14 = 100 % ([`encode_power`]), so
//!   10 % is sent as 1638 and reads back as 9.998 %.

use crate::RuidaError;

/// The full-scale power value: 100 % is 2^14 (and the largest value 2^14 − 1 is sent for it).
pub const POWER_FULL_SCALE: f64 = 16384.0;

/// The 35 bits a 5-byte value carries.
const U35_MASK: u64 = (1 << 35) - 1;

/// The largest 14-bit value.
const MAX_14: u16 = 0x3FFF;

/// `value`'s low 35 bits as five 7-bit bytes, most significant first.
pub fn encode_u35(value: u64) -> [u8; 5] {
    std::array::from_fn(|i| ((value >> (7 * (4 - i))) & 0x7F) as u8)
}

/// Five 7-bit bytes as a number; `None` when one has its top bit set.
pub fn decode_u35(bytes: [u8; 5]) -> Option<u64> {
    bytes.iter().try_fold(0u64, |acc, &b| {
        (b < 0x80).then_some(acc << 7 | u64::from(b))
    })
}

/// `value` (≤ 2^14 − 1) as two 7-bit bytes.
pub fn encode_u14(value: u16) -> [u8; 2] {
    [((value >> 7) & 0x7F) as u8, (value & 0x7F) as u8]
}

/// Two 7-bit bytes as a number; `None` when one has its top bit set.
pub fn decode_u14(bytes: [u8; 2]) -> Option<u16> {
    (bytes[0] < 0x80 && bytes[1] < 0x80).then(|| u16::from(bytes[0]) << 7 | u16::from(bytes[1]))
}

/// A coordinate, µm, as 5 bytes: the value sign-extended to 35 bits (−1 µm is `7F 7F 7F 7F 7F`),
/// as MeerK40t writes it, which a reader of 32 bits and a reader of 35 bits both read alike.
pub fn encode_coord_um(um: i32) -> [u8; 5] {
    encode_u35(i64::from(um) as u64 & U35_MASK)
}

/// A 5-byte coordinate, µm: a signed 35-bit value within 32 bits, or 32-bit two's complement
/// (top byte ≤ 0x0F); `None` for anything else.
pub fn decode_coord_um(bytes: [u8; 5]) -> Option<i32> {
    let raw = decode_u35(bytes)?;
    let signed = if raw & (1 << 34) != 0 {
        raw as i64 - (1 << 35)
    } else {
        raw as i64
    };
    i32::try_from(signed)
        .ok()
        .or_else(|| (raw <= u64::from(u32::MAX)).then_some(raw as u32 as i32))
}

/// A length in mm, rounded to whole µm, checked to fit a coordinate.
pub fn mm_to_um(what: &'static str, mm: f64) -> Result<i32, RuidaError> {
    let um = (mm * 1000.0).round();
    if um.is_finite() && um >= f64::from(i32::MIN) && um <= f64::from(i32::MAX) {
        Ok(um as i32)
    } else {
        Err(RuidaError::OutOfRange {
            what,
            value: mm,
            allowed: "a finite length within ±2147 m",
        })
    }
}

/// A speed, mm/s, in whole µm/s; it must be at least 0.001 mm/s and finite.
pub fn speed_um_per_s(speed_mm_per_s: f64) -> Result<u32, RuidaError> {
    let um_per_s = (speed_mm_per_s * 1000.0).round();
    if !(um_per_s >= 1.0 && um_per_s <= f64::from(u32::MAX >> 1)) {
        return Err(RuidaError::OutOfRange {
            what: "speed_mm_per_s",
            value: speed_mm_per_s,
            allowed: "at least 0.001 mm/s and finite",
        });
    }
    Ok(um_per_s as u32)
}

/// A speed, mm/s, as 5 bytes of whole µm/s.
pub fn encode_speed(speed_mm_per_s: f64) -> Result<[u8; 5], RuidaError> {
    Ok(encode_u35(speed_um_per_s(speed_mm_per_s)?.into()))
}

/// A 5-byte speed, mm/s.
pub fn decode_speed(bytes: [u8; 5]) -> Option<f64> {
    Some(decode_u35(bytes)? as f64 / 1000.0)
}

/// A power, percent (0–100), as a share of 2^14 rounded to the nearest step, 100 % capped at
/// the largest 14-bit value.
pub fn power_steps(power_percent: f64) -> Result<u16, RuidaError> {
    if !(0.0..=100.0).contains(&power_percent) {
        return Err(RuidaError::OutOfRange {
            what: "power_percent",
            value: power_percent,
            allowed: "0 to 100",
        });
    }
    let steps = (power_percent / 100.0 * POWER_FULL_SCALE).round() as u16;
    Ok(steps.min(MAX_14))
}

/// A power, percent, as 2 bytes ([`power_steps`]).
pub fn encode_power(power_percent: f64) -> Result<[u8; 2], RuidaError> {
    Ok(encode_u14(power_steps(power_percent)?))
}

/// A 2-byte power, percent.
pub fn decode_power(bytes: [u8; 2]) -> Option<f64> {
    Some(f64::from(decode_u14(bytes)?) * 100.0 / POWER_FULL_SCALE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn ten_percent_reads_back_as_9_998() {
        let bytes = encode_power(10.0).unwrap();
        assert_eq!(decode_u14(bytes), Some(1638));
        assert!((decode_power(bytes).unwrap() - 9.998).abs() < 0.001);
        assert_eq!(decode_u14(encode_power(100.0).unwrap()), Some(MAX_14));
        assert!(encode_power(100.5).is_err());
        assert!(encode_power(f64::NAN).is_err());
    }

    #[test]
    fn a_negative_coordinate_is_sign_extended_and_read_either_way() {
        assert_eq!(encode_coord_um(-1), [0x7F; 5]);
        assert_eq!(encode_coord_um(1000), [0, 0, 0, 0x07, 0x68]);
        assert_eq!(decode_coord_um([0x0F, 0x7F, 0x7F, 0x7F, 0x7F]), Some(-1));
        // 2^32: neither a 32-bit value nor a 35-bit one within 32 bits.
        assert_eq!(decode_coord_um([0x10, 0, 0, 0, 0]), None);
        assert_eq!(decode_coord_um([0x40, 0, 0, 0, 0]), None);
        assert_eq!(decode_coord_um([0, 0, 0, 0x80, 0]), None);
    }

    #[test]
    fn speeds_are_whole_um_per_s_above_zero() {
        assert_eq!(decode_u35(encode_speed(100.0).unwrap()), Some(100_000));
        assert!(encode_speed(0.0).is_err());
        assert!(encode_speed(-5.0).is_err());
        assert!(encode_speed(f64::INFINITY).is_err());
        assert!(mm_to_um("x_mm", 3e6).is_err());
        assert_eq!(mm_to_um("x_mm", -12.3456), Ok(-12346));
    }

    proptest! {
        #[test]
        fn coordinates_round_trip(um in any::<i32>()) {
            let bytes = encode_coord_um(um);
            prop_assert!(bytes.iter().all(|&b| b < 0x80));
            prop_assert_eq!(decode_coord_um(bytes), Some(um));
        }

        #[test]
        fn powers_round_trip_within_a_step(percent in 0.0f64..=100.0) {
            let back = decode_power(encode_power(percent).unwrap()).unwrap();
            prop_assert!((back - percent).abs() <= 100.0 / POWER_FULL_SCALE);
        }
    }
}
