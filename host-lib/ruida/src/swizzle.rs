//! The swizzle: every byte of a packet's payload (and every reply byte) is scrambled with a
//! per-model magic number. Per byte: swap bits 7 and 0 (three XOR steps), XOR the magic, add 1
//! (mod 256); unswizzling undoes the steps in reverse order.

/// Swap bit 7 and bit 0 of `b` (its own inverse).
fn swap_end_bits(b: u8) -> u8 {
    let mut b = b;
    b ^= b >> 7;
    b ^= b << 7;
    b ^= b >> 7;
    b
}

/// One byte, swizzled with `magic`.
pub fn swizzle_byte(b: u8, magic: u8) -> u8 {
    (swap_end_bits(b) ^ magic).wrapping_add(1)
}

/// One byte, unswizzled with `magic`.
pub fn unswizzle_byte(b: u8, magic: u8) -> u8 {
    swap_end_bits(b.wrapping_sub(1) ^ magic)
}

/// `bytes`, swizzled with `magic`.
pub fn swizzle(bytes: &[u8], magic: u8) -> Vec<u8> {
    bytes.iter().map(|&b| swizzle_byte(b, magic)).collect()
}

/// `bytes`, unswizzled with `magic`.
pub fn unswizzle(bytes: &[u8], magic: u8) -> Vec<u8> {
    bytes.iter().map(|&b| unswizzle_byte(b, magic)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MAGIC;
    use proptest::prelude::*;

    #[test]
    fn swap_end_bits_swaps_bit_7_and_bit_0_only() {
        assert_eq!(swap_end_bits(0x80), 0x01);
        assert_eq!(swap_end_bits(0x01), 0x80);
        assert_eq!(swap_end_bits(0x81), 0x81);
        assert_eq!(swap_end_bits(0x7E), 0x7E);
    }

    /// Zero swizzles to magic + 1 (what MeerK40t's magic guess relies on); the ACK byte 0xCC
    /// with magic 0x88: bits swapped 0x4D, XOR 0x88 = 0xC5, + 1 = 0xC6.
    #[test]
    fn known_bytes_swizzle_as_worked_by_hand() {
        assert_eq!(swizzle_byte(0x00, MAGIC), 0x89);
        assert_eq!(swizzle_byte(0xCC, MAGIC), 0xC6);
        assert_eq!(unswizzle_byte(0xC6, MAGIC), 0xCC);
    }

    #[test]
    fn swizzle_is_a_permutation_for_every_magic() {
        for magic in 0..=255u8 {
            let mut seen = [false; 256];
            for b in 0..=255u8 {
                seen[swizzle_byte(b, magic) as usize] = true;
            }
            assert!(seen.iter().all(|&s| s), "magic {magic:#04x}");
        }
    }

    proptest! {
        #[test]
        fn unswizzle_undoes_swizzle(bytes in proptest::collection::vec(any::<u8>(), 0..300), magic in any::<u8>()) {
            prop_assert_eq!(unswizzle(&swizzle(&bytes, magic), magic), bytes.clone());
            prop_assert_eq!(swizzle(&unswizzle(&bytes, magic), magic), bytes);
        }
    }
}
