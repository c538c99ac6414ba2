//! A binary DXF as ASCII DXF text, pair for pair: the same group codes in the same order, each
//! value written as ASCII DXF writes it, so that a binary drawing is read by the `dxf` crate and
//! written back by the splice like any ASCII one. A dilated binary DXF comes back as ASCII.
//!
//! This is no reader of the drawing: it turns each binary pair into its two text lines and
//! nothing more, the value's type taken from the `dxf` crate's own table of group codes
//! ([`dxf::ExpectedType`]), as the crate's binary reader takes it. Binary DXF (from AutoCAD's
//! `DXFOUT` binary option; ezdxf's `saveas(fmt="bin")`): the 22-byte sentinel, then pairs of a
//! group code (two bytes, little-endian, from R13; one byte before, 255 escaping a two-byte code)
//! and a value: strings end with a zero byte, numbers are little-endian (doubles 8 bytes, 16-,
//! 32- and 64-bit integers, booleans one byte from R13 and two before), binary chunks are a length
//! byte and that many bytes (written as hex).

use std::io::Write as _;

use dxf::ExpectedType;

use super::text::number;

/// What a binary DXF starts with.
const SENTINEL: &[u8] = b"AutoCAD Binary DXF\r\n\x1a\0";

/// The line end of the text made.
const EOL: &str = "\r\n";

/// Whether `bytes` are a binary DXF.
pub(super) fn is_binary(bytes: &[u8]) -> bool {
    bytes.starts_with(SENTINEL)
}

/// The binary DXF `bytes` as ASCII DXF text, up to its `0 EOF` pair; why not, when a pair is cut
/// short or its group code is none.
pub(super) fn to_ascii(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let mut reader = Reader {
        bytes,
        at: SENTINEL.len(),
        // The first pair is 0/SECTION: a zero byte after the first code's is its high byte.
        two_byte_codes: bytes.get(SENTINEL.len()..SENTINEL.len() + 2) == Some(&[0, 0][..]),
    };
    let mut out = Vec::with_capacity(bytes.len() * 2);
    while reader.at < bytes.len() {
        let at = reader.at;
        let code = reader.code().ok_or_else(|| cut_short(at))?;
        write_code(code, &mut out);
        let end = reader.value(code, &mut out)?;
        out.extend_from_slice(EOL.as_bytes());
        if end {
            break;
        }
    }
    Ok(out)
}

fn cut_short(at: usize) -> String {
    format!("not a readable DXF file: the binary DXF ends in the middle of a pair (byte {at})")
}

/// A group code line, right-aligned in three columns.
fn write_code(code: i32, out: &mut Vec<u8>) {
    let _ = write!(out, "{code:>3}{EOL}");
}

/// Where a binary DXF is read.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    two_byte_codes: bool,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let taken = self.bytes.get(self.at..self.at + N)?.try_into().ok()?;
        self.at += N;
        Some(taken)
    }

    fn code(&mut self) -> Option<i32> {
        if self.two_byte_codes {
            return Some(i32::from(u16::from_le_bytes(self.take()?)));
        }
        match self.take::<1>()?[0] {
            255 => Some(i32::from(i16::from_le_bytes(self.take()?))),
            c => Some(i32::from(c)),
        }
    }

    /// Write the value of a pair with `code` as its text line (without the line end); whether it
    /// ends the file (`0 EOF`).
    fn value(&mut self, code: i32, out: &mut Vec<u8>) -> Result<bool, String> {
        let at = self.at;
        let short = || cut_short(at);
        let kind = ExpectedType::new(code).ok_or_else(|| {
            format!("not a readable DXF file: {code} (byte {at} of the binary DXF) is not a DXF group code")
        })?;
        match kind {
            ExpectedType::Str => return self.string(code, out).ok_or_else(short),
            ExpectedType::Double => number(f64::from_le_bytes(self.take().ok_or_else(short)?), out),
            ExpectedType::Short => integer(i16::from_le_bytes(self.take().ok_or_else(short)?), out),
            ExpectedType::Integer => {
                integer(i32::from_le_bytes(self.take().ok_or_else(short)?), out)
            }
            ExpectedType::Long => integer(i64::from_le_bytes(self.take().ok_or_else(short)?), out),
            ExpectedType::Boolean if self.two_byte_codes => {
                integer(self.take::<1>().ok_or_else(short)?[0], out)
            }
            ExpectedType::Boolean => {
                integer(i16::from_le_bytes(self.take().ok_or_else(short)?), out)
            }
            ExpectedType::Binary => {
                let n = usize::from(self.take::<1>().ok_or_else(short)?[0]);
                let chunk = self.bytes.get(self.at..self.at + n).ok_or_else(short)?;
                self.at += n;
                for b in chunk {
                    let _ = write!(out, "{b:02X}");
                }
            }
        }
        Ok(false)
    }

    /// A string value (control characters in the caret notation ASCII DXF uses, `^J` for a line
    /// feed); whether it is the `0 EOF` pair. `None` when it has no end.
    fn string(&mut self, code: i32, out: &mut Vec<u8>) -> Option<bool> {
        let rest = self.bytes.get(self.at..)?;
        let n = rest.iter().position(|&b| b == 0)?;
        self.at += n + 1;
        let value = &rest[..n];
        for &b in value {
            match b {
                0..=31 => out.extend_from_slice(&[b'^', b + 64]),
                _ => out.push(b),
            }
        }
        Some(code == 0 && value == b"EOF")
    }
}

fn integer(v: impl itoa::Integer, out: &mut Vec<u8>) {
    out.extend_from_slice(itoa::Buffer::new().format(v).as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A binary DXF of `pairs` (two-byte codes), each value as its bytes.
    fn binary(pairs: &[(u16, Vec<u8>)]) -> Vec<u8> {
        let mut out = SENTINEL.to_vec();
        for (code, value) in pairs {
            out.extend_from_slice(&code.to_le_bytes());
            out.extend_from_slice(value);
        }
        out
    }

    fn text(s: &str) -> Vec<u8> {
        let mut v = s.as_bytes().to_vec();
        v.push(0);
        v
    }

    #[test]
    fn every_value_type_becomes_its_text_line() {
        let bytes = binary(&[
            (0, text("SECTION")),
            (2, text("ENTITIES")),
            (0, text("LWPOLYLINE")),
            (5, text("2F")),
            (10, 12.5f64.to_le_bytes().to_vec()),
            (20, (-0.1f64).to_le_bytes().to_vec()),
            (70, 1i16.to_le_bytes().to_vec()),
            (90, 4i32.to_le_bytes().to_vec()),
            (160, 7i64.to_le_bytes().to_vec()),
            (290, vec![1]),
            (310, vec![3, 0xAB, 0x01, 0xFF]),
            (1000, text("a\nb")),
            (0, text("ENDSEC")),
            (0, text("EOF")),
            (0, text("after the end")),
        ]);
        let out = String::from_utf8(to_ascii(&bytes).unwrap()).unwrap();
        let lines: Vec<&str> = out.split("\r\n").collect();
        assert_eq!(
            lines,
            [
                "  0",
                "SECTION",
                "  2",
                "ENTITIES",
                "  0",
                "LWPOLYLINE",
                "  5",
                "2F",
                " 10",
                "12.5",
                " 20",
                "-0.1",
                " 70",
                "1",
                " 90",
                "4",
                "160",
                "7",
                "290",
                "1",
                "310",
                "AB01FF",
                "1000",
                "a^Jb",
                "  0",
                "ENDSEC",
                "  0",
                "EOF",
                ""
            ]
        );
    }

    #[test]
    fn r12_codes_are_one_byte_with_an_escape_and_booleans_two() {
        let mut bytes = SENTINEL.to_vec();
        bytes.extend_from_slice(b"\0SECTION\0\x02ENTITIES\0");
        bytes.extend_from_slice(b"\xff\x22\x01");
        bytes.extend_from_slice(&1i16.to_le_bytes());
        let out = String::from_utf8(to_ascii(&bytes).unwrap()).unwrap();
        assert_eq!(out, "  0\r\nSECTION\r\n  2\r\nENTITIES\r\n290\r\n1\r\n");
    }

    #[test]
    fn a_pair_cut_short_or_an_unknown_code_is_refused() {
        let mut bytes = binary(&[(0, text("SECTION")), (10, vec![0, 0, 0])]);
        assert!(
            to_ascii(&bytes)
                .unwrap_err()
                .contains("in the middle of a pair")
        );
        bytes = binary(&[(0, text("SECTION")), (1234, text("x"))]);
        assert!(to_ascii(&bytes).unwrap_err().contains("1234"));
        bytes = binary(&[(0, b"SECTION".to_vec())]);
        assert!(to_ascii(&bytes).is_err());
    }
}
