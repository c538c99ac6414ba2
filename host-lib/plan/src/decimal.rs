//! Numbers as text in the files written: a value already rounded to a number of decimals, held
//! as the integer count of its last decimal, printed without a float formatter (formatting floats
//! exactly was most of the time spent writing a large plan). The SVG and DXF writers each decide
//! how they round and sign a number; the digits are written here.

/// `v` rounded to `decimals` places and written without trailing zeros (nor a bare point), `-0`
/// as `0`: how the gauge, G-code comments and LightBurn's values are written. (The plan writers'
/// hot path uses `write_scaled` on values already rounded.)
pub fn trimmed(v: f64, decimals: usize) -> String {
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        let kept = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(kept);
    }
    if s == "-0" { "0".into() } else { s }
}

/// The decimals (0 to 12) that write a value to a step of `step` or finer: `step` 0.001 gives 3
/// (a step a hair under a power of ten, from a scale that is 1 but for rounding, does not cost a
/// decimal more).
pub(crate) fn decimals_for_step(step: f64) -> usize {
    (-step.log10() - 1e-6).ceil().clamp(0.0, 12.0) as usize
}

/// Every power of ten a float holds exactly, 10⁰ to 10²².
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// 10^`exponent`: from a table where the float is exact (the same value `powi` gives there, for
/// a look-up instead of a call per number written), by `powi` elsewhere.
pub(crate) fn pow10(exponent: i32) -> f64 {
    usize::try_from(exponent)
        .ok()
        .and_then(|k| POW10.get(k).copied())
        .unwrap_or_else(|| 10f64.powi(exponent))
}

/// Write `n / 10^digits` (`digits` at most 19) as decimal text through `push`: the integer part
/// (at least one digit), then a point and the fraction without its trailing zeros, or no point
/// when the fraction is zero; whether a point was written. No sign: that is the caller's.
///
/// The trailing zeros of `n` are dropped (a division by the constant 10 is a multiplication), its
/// digits written by `itoa`, and the point put in, straight into the caller's text: dividing by
/// `10^digits` computed at run time took two hardware divisions a number, and going through a
/// buffer of its own cost as much again.
pub(crate) fn write_scaled(mut n: u64, digits: usize, mut push: impl FnMut(&str)) -> bool {
    const ZEROS: &str = "0000000000000000000";
    let mut places = digits.min(19);
    while places > 0 && n.is_multiple_of(10) {
        n /= 10;
        places -= 1;
    }
    let mut ints = itoa::Buffer::new();
    let all = ints.format(n);
    if places == 0 {
        push(all);
    } else if all.len() > places {
        let (int, frac) = all.split_at(all.len() - places);
        push(int);
        push(".");
        push(frac);
    } else {
        push("0.");
        push(&ZEROS[..places - all.len()]);
        push(all);
    }
    places > 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trimmed_drops_trailing_zeros_and_the_sign_of_zero() {
        assert_eq!(trimmed(1.5, 6), "1.5");
        assert_eq!(trimmed(2.0, 6), "2");
        assert_eq!(trimmed(-0.0000001, 6), "0");
        assert_eq!(trimmed(100.0, 0), "100");
        assert_eq!(trimmed(-12.3456789, 4), "-12.3457");
    }

    #[test]
    fn powers_of_ten_are_powi_s() {
        for e in -30..=30 {
            assert_eq!(pow10(e).to_bits(), 10f64.powi(e).to_bits(), "10^{e}");
        }
    }

    #[test]
    fn scaled_integers_print_as_decimals_without_trailing_zeros() {
        let cases = [
            (0, 0, "0"),
            (0, 5, "0"),
            (7, 0, "7"),
            (1_234_500, 5, "12.345"),
            (1_200_000, 5, "12"),
            (5, 5, "0.00005"),
            (10, 1, "1"),
            (123_456_789_012_345, 10, "12345.6789012345"),
            (u64::MAX, 0, "18446744073709551615"),
            (u64::MAX, 19, "1.8446744073709551615"),
            (1, 19, "0.0000000000000000001"),
            (10_000_000_000_000_000_000, 19, "1"),
            (123, 3, "0.123"),
        ];
        for (n, digits, text) in cases {
            let mut written = String::new();
            let point = write_scaled(n, digits, |s| written.push_str(s));
            assert_eq!(written, text, "{n} / 10^{digits}");
            assert_eq!(point, text.contains('.'), "{n} / 10^{digits}");
        }
    }
}
