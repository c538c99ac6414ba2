//! Loading a DXF with the `dxf` crate, and why one it could not load cannot be read, when the
//! cause is a value its group code cannot hold (a 90 code of 4294967295, a coordinate of `1,5`)
//! or a group code no DXF has. The crate stops on such a pair, but what it reports is often a
//! pair after it ("the code pair 70/1 was not expected at this time"), which sends the user to
//! the wrong line. Only a file that failed to load is scanned, so a good file costs nothing.
//!
//! The crate can also panic on a damaged file where overflow is checked (a layer colour of
//! −32768, which it negates; a debug or fuzzing build): such a panic is caught and reported as a
//! file that cannot be read, never a crash.

use std::io::Cursor;
use std::panic::{AssertUnwindSafe, catch_unwind};

use dxf::{Drawing, ExpectedType};

/// The drawing in `bytes`, or why it cannot be read (the message, without the crate's panic).
pub(super) fn load(bytes: &[u8]) -> Result<Drawing, String> {
    match catch_unwind(AssertUnwindSafe(|| Drawing::load(&mut Cursor::new(bytes)))) {
        Ok(Ok(drawing)) => Ok(drawing),
        Ok(Err(e)) => Err(load_error(bytes, &e)),
        Err(_) => Err(match first_bad_pair_reading(bytes, Shorts::InRange) {
            Some(b) => bad_pair_message(&b),
            None => "not a readable DXF file: the dxf crate failed on it; the file is damaged or breaks the DXF format: export it again".to_owned(),
        }),
    }
}

/// A code pair whose value its group code cannot hold, or whose code is not a group code.
#[derive(Debug, PartialEq)]
struct BadPair {
    /// The line of the group code (1 is the file's first line, as the crate counts).
    code_line: usize,
    /// What is wrong, to follow "line N: ".
    what: String,
}

/// How strictly shorts are read.
#[derive(Clone, Copy, PartialEq)]
enum Shorts {
    /// As the crate does: any decimal number (it saturates what a short cannot hold).
    AsTheCrate,
    /// Also within a short's range less its lowest value, which the crate negates (the panic
    /// path: [`load`]).
    InRange,
}

/// The first code pair of an ASCII DXF (`bytes`) that the `dxf` crate cannot parse, by the
/// crate's own rules (shorts and booleans as any decimal number, 90–99 codes as 32-bit
/// integers, 160–169 as 64-bit ones), or `None` (a binary DXF or a DXB is not scanned).
fn first_bad_pair(bytes: &[u8]) -> Option<BadPair> {
    first_bad_pair_reading(bytes, Shorts::AsTheCrate)
}

/// [`first_bad_pair`], shorts read as `shorts` says.
fn first_bad_pair_reading(bytes: &[u8], shorts: Shorts) -> Option<BadPair> {
    if bytes.starts_with(b"AutoCAD Binary DXF") || bytes.starts_with(b"AutoCAD DXB") {
        return None;
    }
    let text = String::from_utf8_lossy(bytes);
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut lines = text.lines().map(str::trim).enumerate();
    while let Some((k, code_text)) = lines.next() {
        let code_line = k + 1;
        if code_text.is_empty() {
            return None;
        }
        let Ok(code) = code_text.parse::<i32>() else {
            let what = format!(
                "`{}` stands where a group code (a whole number) should",
                short(code_text)
            );
            return Some(BadPair { code_line, what });
        };
        let Some(wanted) = ExpectedType::new(code) else {
            let what = format!("{code} is not a DXF group code");
            return Some(BadPair { code_line, what });
        };
        let (_, value) = lines.next()?;
        if let Some(needs) = unreadable(&wanted, value, shorts) {
            let what = format!(
                "group code {code} has the value `{}`, which {needs}",
                short(value)
            );
            return Some(BadPair { code_line, what });
        }
    }
    None
}

/// What a value of type `wanted` must be, when `value` is not that.
fn unreadable(wanted: &ExpectedType, value: &str, shorts: Shorts) -> Option<&'static str> {
    match wanted {
        ExpectedType::Integer => value
            .parse::<i32>()
            .err()
            .map(|_| "must be a whole number from -2147483648 to 2147483647"),
        ExpectedType::Long => value
            .parse::<i64>()
            .err()
            .map(|_| "must be a whole number (64 bits)"),
        ExpectedType::Short | ExpectedType::Boolean => match value.parse::<f64>() {
            Err(_) => Some("must be a number (with a point for decimals)"),
            Ok(v) if shorts == Shorts::InRange && !(-32767.0..=32767.0).contains(&v) => {
                Some("must be a whole number from -32767 to 32767")
            }
            Ok(_) => None,
        },
        ExpectedType::Double => value
            .parse::<f64>()
            .err()
            .map(|_| "must be a number (with a point for decimals)"),
        ExpectedType::Str | ExpectedType::Binary => None,
    }
}

/// `text`, cut to 40 characters for a message, control characters escaped (a file whose lines
/// end in a lone CR is one line here).
fn short(text: &str) -> String {
    let cut = match text.char_indices().nth(40) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_owned(),
    };
    cut.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// The line the crate's error names, when it names one.
fn line_of(e: &dxf::DxfError) -> Option<usize> {
    use dxf::DxfError as E;
    match e {
        E::ParseFloatError(_, o)
        | E::ParseIntError(_, o)
        | E::ParseError(o)
        | E::UnexpectedCode(_, o)
        | E::UnexpectedByte(_, o)
        | E::UnexpectedEnumValue(o)
        | E::ExpectedTableType(o)
        | E::WrongValueType(o) => Some(*o),
        E::UnexpectedCodePair(pair, _) => Some(pair.offset),
        _ => None,
    }
}

/// The message for a DXF the crate could not load with `e`: the first bad pair in `bytes`, when
/// there is one at or before the line the crate stopped at; the crate's own words otherwise.
fn load_error(bytes: &[u8], e: &dxf::DxfError) -> String {
    let bad = first_bad_pair(bytes).filter(|b| line_of(e).is_none_or(|stop| b.code_line <= stop));
    match bad {
        Some(b) => bad_pair_message(&b),
        None => format!("not a readable DXF file: {e}"),
    }
}

/// The message for a file that cannot be read because of the code pair `b`.
fn bad_pair_message(b: &BadPair) -> String {
    format!(
        "not a readable DXF file: line {}: {}; the file is damaged or breaks the DXF format: export it again",
        b.code_line, b.what
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entity(pairs: &str) -> String {
        format!("  0\nSECTION\n  2\nENTITIES\n  0\nLWPOLYLINE\n{pairs}  0\nENDSEC\n  0\nEOF\n")
    }

    #[test]
    fn a_value_too_large_for_its_code_is_found_on_its_own_line() {
        let text = entity(" 90\n4294967295\n 70\n1\n");
        let bad = first_bad_pair(text.as_bytes()).expect("a bad pair");
        assert_eq!(bad.code_line, 7);
        assert!(bad.what.contains("group code 90"), "{}", bad.what);
        assert!(bad.what.contains("4294967295"), "{}", bad.what);
    }

    #[test]
    fn a_decimal_comma_and_an_unknown_code_are_found() {
        let comma = entity(" 10\n1,5\n");
        let what = first_bad_pair(comma.as_bytes()).expect("comma").what;
        assert!(what.contains("must be a number"), "{what}");
        let code = entity("1234\nx\n");
        let what = first_bad_pair(code.as_bytes()).expect("code").what;
        assert_eq!(what, "1234 is not a DXF group code");
        let word = entity("ten\nx\n");
        assert!(first_bad_pair(word.as_bytes()).is_some());
    }

    #[test]
    fn good_files_shorts_written_as_decimals_and_binary_files_have_none() {
        let good = entity(" 90\n-4\n 70\n1.0\n 10\n-2.5e3\n  1\n90\n");
        assert_eq!(first_bad_pair(good.as_bytes()), None);
        let bom = format!("\u{feff}{good}");
        assert_eq!(first_bad_pair(bom.as_bytes()), None);
        assert_eq!(first_bad_pair(b"AutoCAD Binary DXF\r\n\x1a\0 90"), None);
    }

    #[test]
    fn a_short_beyond_its_range_is_named_only_where_the_crate_panicked() {
        // A layer colour of −1e308: the crate reads it as −32768 and negates it, which panics
        // where overflow is checked (this test's build); the panic is caught and the value named.
        let text = "  0\nSECTION\n  2\nTABLES\n  0\nTABLE\n  2\nLAYER\n  0\nLAYER\n  2\nCUT\n 62\n-1e308\n  0\nENDTAB\n  0\nENDSEC\n  0\nEOF\n";
        let bad = first_bad_pair_reading(text.as_bytes(), Shorts::InRange).expect("a bad pair");
        assert_eq!(bad.code_line, 13);
        assert!(bad.what.contains("-32767 to 32767"), "{}", bad.what);
        if cfg!(debug_assertions) {
            let message = load(text.as_bytes()).expect_err("the crate panics");
            assert!(
                message.starts_with("not a readable DXF file: line 13"),
                "{message}"
            );
        }
        // Where the crate failed of itself, a short it read (saturated) is not blamed.
        assert_eq!(first_bad_pair(text.as_bytes()), None);
    }

    #[test]
    fn a_file_with_lone_cr_line_ends_is_named_readably() {
        let what = first_bad_pair(b"  0\rSECTION\r")
            .expect("one long line")
            .what;
        assert!(what.contains("\\r") && !what.contains('\r'), "{what}");
        assert_eq!(first_bad_pair(b"AutoCAD DXB 1.0\r\n\x1a\0"), None);
    }

    #[test]
    fn the_crate_stopping_on_a_later_pair_names_the_bad_one() {
        let text = entity(" 90\n4294967295\n 70\n1\n 10\n0\n 20\n0\n");
        let message = load(text.as_bytes()).expect_err("the crate refuses it");
        assert!(
            message.starts_with("not a readable DXF file: line 7: group code 90"),
            "{message}"
        );
    }
}
