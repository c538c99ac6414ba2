//! The cutter twin's G-code parser: one received line (already stripped of its terminator) into
//! the words it carries, checked the way GRBL 1.1 checks them, with GRBL's `error:N` code for
//! what it refuses. It knows the subset the twin executes (see the [module docs](super)); any
//! other command is refused with `error:20` rather than ignored.

/// The longest line GRBL 1.1 takes (without spaces and comments): 79 characters; longer lines
/// are `error:11`.
use kerfmeter_grbl::LINE_MAX_LEN;
/// GRBL's error codes the twin sends (the numbers of GRBL 1.1's `error:N`), from the one table.
pub use kerfmeter_grbl::codes;

/// A motion command (modal group 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Motion {
    /// G0: travel at the maximum rate.
    Rapid,
    /// G1: a straight feed move.
    Linear,
    /// G2 (`true`) or G3 (`false`): an arc in the XY plane about I/J.
    Arc {
        /// G2.
        clockwise: bool,
    },
}

/// The spindle (laser) command (modal group 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spindle {
    /// M3: constant power.
    Constant,
    /// M4: dynamic power (in laser mode).
    Dynamic,
    /// M5: off.
    Off,
}

/// What one line asks for, as parsed (values in the line's units).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Block {
    /// G0/G1/G2/G3, when the line names one.
    pub motion: Option<Motion>,
    /// G4.
    pub dwell: bool,
    /// G53: this block's axis words are machine coordinates (absolute, whatever G90/G91 say).
    pub machine_coords: bool,
    /// P (G4's pause, seconds).
    pub p: Option<f64>,
    /// G20 (`false`) or G21 (`true`).
    pub metric: Option<bool>,
    /// G90 (`true`) or G91 (`false`).
    pub absolute: Option<bool>,
    /// M3/M4/M5.
    pub spindle: Option<Spindle>,
    /// M2 or M30.
    pub program_end: bool,
    /// F.
    pub feed: Option<f64>,
    /// S.
    pub power: Option<f64>,
    /// X, Y, Z.
    pub axes: [Option<f64>; 3],
    /// I, J.
    pub offsets: [Option<f64>; 2],
}

impl Block {
    /// True when the line names an axis.
    pub fn has_axes(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }
}

/// Parse one line (upper-cased, spaces and comments removed here) into a [`Block`], or the
/// `error:N` code GRBL would answer. A line of nothing but spaces and comments is an empty block.
pub fn parse(line: &str) -> Result<Block, u8> {
    let text = normalise(line)?;
    let mut block = Block::default();
    let mut rest = text.as_str();
    while let Some(letter) = rest.chars().next() {
        if !letter.is_ascii_alphabetic() {
            return Err(codes::EXPECTED_COMMAND_LETTER);
        }
        let digits = &rest[1..];
        let end = digits
            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+'))
            .unwrap_or(digits.len());
        let value: f64 = digits[..end]
            .parse()
            .map_err(|_| codes::BAD_NUMBER_FORMAT)?;
        if !value.is_finite() {
            return Err(codes::BAD_NUMBER_FORMAT);
        }
        word(&mut block, letter, value)?;
        rest = &digits[end..];
    }
    Ok(block)
}

/// The line without spaces and comments, upper-cased (what GRBL keeps in its line buffer);
/// `error:11` when that overflows.
fn normalise(line: &str) -> Result<String, u8> {
    let mut out = String::with_capacity(line.len());
    let mut in_comment = false;
    for c in line.chars() {
        match c {
            '(' => in_comment = true,
            ')' => in_comment = false,
            ';' if !in_comment => break,
            c if in_comment || c.is_whitespace() => {}
            c => out.push(c.to_ascii_uppercase()),
        }
    }
    if out.len() > LINE_MAX_LEN {
        return Err(codes::LINE_OVERFLOW);
    }
    Ok(out)
}

/// Apply one word to the block.
fn word(block: &mut Block, letter: char, value: f64) -> Result<(), u8> {
    fn set(slot: &mut Option<f64>, value: f64) -> Result<(), u8> {
        if slot.replace(value).is_some() {
            return Err(codes::REPEATED_WORD);
        }
        Ok(())
    }
    match letter {
        'G' => g_word(block, integer(value)?),
        'M' => m_word(block, integer(value)?),
        'F' | 'S' if value < 0.0 => Err(codes::NEGATIVE_VALUE),
        'F' => set(&mut block.feed, value),
        'S' => set(&mut block.power, value),
        'X' => set(&mut block.axes[0], value),
        'Y' => set(&mut block.axes[1], value),
        'Z' => set(&mut block.axes[2], value),
        'I' => set(&mut block.offsets[0], value),
        'J' => set(&mut block.offsets[1], value),
        'P' if value < 0.0 => Err(codes::NEGATIVE_VALUE),
        'P' => set(&mut block.p, value),
        // A line number: accepted and not used.
        'N' => Ok(()),
        _ => Err(codes::UNSUPPORTED_COMMAND),
    }
}

/// A G or M number, which must be whole.
fn integer(value: f64) -> Result<u16, u8> {
    if value.fract() != 0.0 {
        return Err(codes::NOT_AN_INTEGER);
    }
    if !(0.0..=999.0).contains(&value) {
        return Err(codes::UNSUPPORTED_COMMAND);
    }
    Ok(value as u16)
}

/// Apply a G word.
fn g_word(block: &mut Block, number: u16) -> Result<(), u8> {
    fn modal<T>(slot: &mut Option<T>, value: T) -> Result<(), u8> {
        if slot.replace(value).is_some() {
            return Err(codes::MODAL_GROUP_VIOLATION);
        }
        Ok(())
    }
    match number {
        0 => modal(&mut block.motion, Motion::Rapid),
        1 => modal(&mut block.motion, Motion::Linear),
        2 => modal(&mut block.motion, Motion::Arc { clockwise: true }),
        3 => modal(&mut block.motion, Motion::Arc { clockwise: false }),
        // G4 and G53 share GRBL's non-modal group: one of them a block.
        4 | 53 if block.dwell || block.machine_coords => Err(codes::MODAL_GROUP_VIOLATION),
        53 => {
            block.machine_coords = true;
            Ok(())
        }
        4 => {
            block.dwell = true;
            Ok(())
        }
        20 => modal(&mut block.metric, false),
        21 => modal(&mut block.metric, true),
        90 => modal(&mut block.absolute, true),
        91 => modal(&mut block.absolute, false),
        // The XY plane, the first work system, units per minute: the only ones the twin has.
        17 | 54 | 94 => Ok(()),
        _ => Err(codes::UNSUPPORTED_COMMAND),
    }
}

/// Apply an M word.
fn m_word(block: &mut Block, number: u16) -> Result<(), u8> {
    let spindle = match number {
        2 | 30 => {
            block.program_end = true;
            return Ok(());
        }
        3 => Spindle::Constant,
        4 => Spindle::Dynamic,
        5 => Spindle::Off,
        // Coolant (air assist) on and off: accepted, nothing to simulate.
        7..=9 => return Ok(()),
        _ => return Err(codes::UNSUPPORTED_COMMAND),
    };
    if block.spindle.replace(spindle).is_some() {
        return Err(codes::MODAL_GROUP_VIOLATION);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_comments_and_case_are_read_as_grbl_reads_them() {
        let block = parse("g1 x10.5 (a comment) Y-2 f600 s1000 ; trailing").unwrap();
        assert_eq!(block.motion, Some(Motion::Linear));
        assert_eq!(block.axes, [Some(10.5), Some(-2.0), None]);
        assert_eq!(block.feed, Some(600.0));
        assert_eq!(block.power, Some(1000.0));
    }

    #[test]
    fn what_grbl_refuses_gets_its_code() {
        assert_eq!(parse("G1 X"), Err(codes::BAD_NUMBER_FORMAT));
        assert_eq!(parse("10"), Err(codes::EXPECTED_COMMAND_LETTER));
        assert_eq!(parse("G28"), Err(codes::UNSUPPORTED_COMMAND));
        assert_eq!(parse("G0 G1 X1"), Err(codes::MODAL_GROUP_VIOLATION));
        assert_eq!(parse("G53 G4 P1"), Err(codes::MODAL_GROUP_VIOLATION));
        assert!(parse("G53 G0 Z5").unwrap().machine_coords);
        assert_eq!(parse("G1 X1 X2"), Err(codes::REPEATED_WORD));
        assert_eq!(parse("S-1"), Err(codes::NEGATIVE_VALUE));
        assert_eq!(parse(&"G1X1".repeat(30)), Err(codes::LINE_OVERFLOW));
        let longest = format!("G1X{}", "1".repeat(LINE_MAX_LEN - 3));
        assert_eq!(longest.len(), 79);
        assert!(parse(&longest).is_ok(), "79 characters fit");
        assert_eq!(parse(&format!("{longest}1")), Err(codes::LINE_OVERFLOW));
    }
}
