//! Numbers as text in the files written: a value already rounded to a number of decimals, held
//! as the integer count of its last decimal, printed without a float formatter (formatting floats
//! exactly was most of the time spent writing a large plan). The SVG and DXF writers each decide
//! how they round and sign a number; the digits are written here.

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

/// `n / 10^digits` as decimal text: the integer part (at least one digit), then a point and the
/// fraction without its trailing zeros, or no point when the fraction is zero. No sign: that is
/// the caller's.
pub(crate) struct Scaled {
    buf: [u8; 40],
    start: usize,
}

impl Scaled {
    /// The text of `n / 10^digits` (`digits` at most 19).
    pub fn new(n: u64, digits: usize) -> Scaled {
        let digits = digits.min(19);
        let unit = 10u64.pow(digits as u32);
        let (int, mut frac, mut places) = (n / unit, n % unit, digits);
        while places > 0 && frac % 10 == 0 {
            frac /= 10;
            places -= 1;
        }
        let mut s = Scaled {
            buf: [b'0'; 40],
            start: 40,
        };
        if places > 0 {
            s.push_digits(frac, places);
            s.start -= 1;
            s.buf[s.start] = b'.';
        }
        s.push_digits(int, 1);
        s
    }

    /// The decimal digits of `v`, at least `width` of them (zeros in front), before the text
    /// so far.
    fn push_digits(&mut self, mut v: u64, width: usize) {
        let end = self.start;
        while v > 0 || end - self.start < width {
            self.start -= 1;
            self.buf[self.start] = b'0' + (v % 10) as u8;
            v /= 10;
        }
    }

    /// The text.
    pub fn as_str(&self) -> &str {
        // Only ASCII digits and a point were written.
        std::str::from_utf8(&self.buf[self.start..]).unwrap_or("0")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        ];
        for (n, digits, text) in cases {
            assert_eq!(Scaled::new(n, digits).as_str(), text, "{n} / 10^{digits}");
        }
    }
}
