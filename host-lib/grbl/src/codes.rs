//! GRBL 1.1's numbered replies: `error:N` (a line refused) and `ALARM:N` (the machine stopped),
//! each code by name (the names follow GRBL's own `STATUS_*` and `EXEC_ALARM_*`), with a sentence
//! for the person at the cutter, in this project's words ([`describe_error`],
//! [`describe_alarm`]).
//!
//! grblHAL and FluidNC speak the same protocol, but some of their numbers mean other things
//! (grblHAL's `ALARM:10` is its E-stop): the driver says that the meaning given is GRBL 1.1's.

/// A word without its letter.
pub const EXPECTED_COMMAND_LETTER: u8 = 1;
/// A letter without a valid number.
pub const BAD_NUMBER_FORMAT: u8 = 2;
/// A `$` command GRBL does not know.
pub const INVALID_STATEMENT: u8 = 3;
/// A negative value where only positive ones make sense.
pub const NEGATIVE_VALUE: u8 = 4;
/// Homing (`$H`) is disabled.
pub const SETTING_DISABLED: u8 = 5;
/// A step pulse under 3 µs.
pub const SETTING_STEP_PULSE_MIN: u8 = 6;
/// The EEPROM could not be read; defaults restored.
pub const SETTING_READ_FAIL: u8 = 7;
/// A `$` command that needs the machine idle.
pub const NOT_IDLE: u8 = 8;
/// G-code refused in the alarm or jog state.
pub const GCODE_LOCK: u8 = 9;
/// Soft limits (`$20=1`) without homing enabled.
pub const SOFT_LIMIT_ERROR: u8 = 10;
/// A line longer than the line buffer ([`crate::LINE_MAX_LEN`]).
pub const LINE_OVERFLOW: u8 = 11;
/// A setting that would make the step rate too high.
pub const MAX_STEP_RATE_EXCEEDED: u8 = 12;
/// The safety door is open.
pub const CHECK_DOOR: u8 = 13;
/// A startup line too long to store.
pub const LINE_LENGTH_EXCEEDED: u8 = 14;
/// A jog target outside the travel.
pub const TRAVEL_EXCEEDED: u8 = 15;
/// A malformed jog command.
pub const INVALID_JOG_COMMAND: u8 = 16;
/// Laser mode without the spindle's PWM output.
pub const SETTING_DISABLED_LASER: u8 = 17;
/// A command GRBL does not support.
pub const UNSUPPORTED_COMMAND: u8 = 20;
/// Two commands of one modal group in a block.
pub const MODAL_GROUP_VIOLATION: u8 = 21;
/// A feed move before any feed rate.
pub const UNDEFINED_FEED_RATE: u8 = 22;
/// A command that needs an integer got a fraction.
pub const NOT_AN_INTEGER: u8 = 23;
/// Two commands that both need axis words in one block.
pub const AXIS_COMMAND_CONFLICT: u8 = 24;
/// A word repeated in one block.
pub const REPEATED_WORD: u8 = 25;
/// A motion without axis words.
pub const NO_AXIS_WORDS: u8 = 26;
/// An invalid line number.
pub const INVALID_LINE_NUMBER: u8 = 27;
/// A command missing a value it needs (G4 without P).
pub const MISSING_VALUE: u8 = 28;
/// A work coordinate system GRBL does not support.
pub const UNSUPPORTED_COORD_SYS: u8 = 29;
/// G53 with a motion mode other than G0 or G1.
pub const G53_INVALID_MOTION_MODE: u8 = 30;
/// Axis words no command uses.
pub const UNUSED_AXIS_WORDS: u8 = 31;
/// An arc without an axis word in its plane.
pub const NO_AXIS_WORDS_IN_PLANE: u8 = 32;
/// An invalid target (an arc whose end does not lie on its circle).
pub const INVALID_TARGET: u8 = 33;
/// An invalid arc radius.
pub const ARC_RADIUS_ERROR: u8 = 34;
/// An arc without I or J.
pub const NO_OFFSET_WORDS: u8 = 35;
/// Value words nothing uses.
pub const UNUSED_VALUE_WORDS: u8 = 36;
/// A tool length offset not on the configured axis.
pub const G43_DYNAMIC_AXIS_ERROR: u8 = 37;
/// A tool number too large.
pub const MAX_VALUE_EXCEEDED: u8 = 38;

/// A hard limit tripped.
pub const ALARM_HARD_LIMIT: u8 = 1;
/// A target beyond the machine's travel (soft limits).
pub const ALARM_SOFT_LIMIT: u8 = 2;
/// A reset during motion: the position may be lost.
pub const ALARM_ABORT_CYCLE: u8 = 3;
/// Probing: the probe was not in its expected initial state.
pub const ALARM_PROBE_FAIL_INITIAL: u8 = 4;
/// Probing: no contact within the travel.
pub const ALARM_PROBE_FAIL_CONTACT: u8 = 5;
/// Homing: reset during the cycle.
pub const ALARM_HOMING_FAIL_RESET: u8 = 6;
/// Homing: the safety door opened.
pub const ALARM_HOMING_FAIL_DOOR: u8 = 7;
/// Homing: the pull-off did not clear the switch.
pub const ALARM_HOMING_FAIL_PULLOFF: u8 = 8;
/// Homing: no switch found within the search distance.
pub const ALARM_HOMING_FAIL_APPROACH: u8 = 9;
/// Homing: a dual-axis machine's second switch not found.
pub const ALARM_HOMING_FAIL_DUAL_APPROACH: u8 = 10;

/// A sentence for `error:N`.
pub fn describe_error(code: u8) -> &'static str {
    match code {
        EXPECTED_COMMAND_LETTER => "a word has no letter (G-code words are a letter and a number)",
        BAD_NUMBER_FORMAT => "a number is missing or malformed",
        INVALID_STATEMENT => "the controller does not know this `$` command",
        NEGATIVE_VALUE => "a value that must not be negative is negative",
        SETTING_DISABLED => "homing is not enabled on this controller",
        SETTING_STEP_PULSE_MIN => "the step pulse must be at least 3 µs",
        SETTING_READ_FAIL => {
            "the controller's stored settings could not be read; it restored its defaults"
        }
        NOT_IDLE => "this `$` command needs the machine idle",
        GCODE_LOCK => "G-code is locked while the machine is in alarm or jogging",
        SOFT_LIMIT_ERROR => "soft limits need homing enabled",
        LINE_OVERFLOW => "the line is longer than the controller's line buffer",
        MAX_STEP_RATE_EXCEEDED => "this setting would make the step rate too high",
        CHECK_DOOR => "the safety door is open",
        LINE_LENGTH_EXCEEDED => "the line is too long to be stored",
        TRAVEL_EXCEEDED => "the jog target is outside the machine's travel",
        INVALID_JOG_COMMAND => "the jog command is malformed or uses forbidden G-code",
        SETTING_DISABLED_LASER => "laser mode needs the spindle's PWM output",
        UNSUPPORTED_COMMAND => "the controller does not support this command",
        MODAL_GROUP_VIOLATION => "two commands of the same group are on one line",
        UNDEFINED_FEED_RATE => "no feed rate has been set for this feed move",
        NOT_AN_INTEGER => "this command needs a whole number",
        AXIS_COMMAND_CONFLICT => "two commands that both need axis words are on one line",
        REPEATED_WORD => "a word is repeated on the line",
        NO_AXIS_WORDS => "the command needs axis words and has none",
        INVALID_LINE_NUMBER => "the line number is invalid",
        MISSING_VALUE => "the command is missing a value it needs",
        UNSUPPORTED_COORD_SYS => "this work coordinate system is not supported",
        G53_INVALID_MOTION_MODE => "G53 is allowed only with G0 and G1",
        UNUSED_AXIS_WORDS => "there are axis words that no command on the line uses",
        NO_AXIS_WORDS_IN_PLANE => "an arc needs at least one axis word in its plane",
        INVALID_TARGET => {
            "the motion's target is invalid (for an arc: its end is not on its circle)"
        }
        ARC_RADIUS_ERROR => "the arc's radius is invalid",
        NO_OFFSET_WORDS => "an arc needs at least one of its offsets (I, J)",
        UNUSED_VALUE_WORDS => "there are value words that nothing on the line uses",
        G43_DYNAMIC_AXIS_ERROR => "the tool length offset is not on the configured axis",
        MAX_VALUE_EXCEEDED => "the tool number is too large",
        _ => "an error this program does not know (see the controller's documentation)",
    }
}

/// A sentence for `ALARM:N`.
pub fn describe_alarm(code: u8) -> &'static str {
    match code {
        ALARM_HARD_LIMIT => {
            "a hard limit switch tripped: the machine stopped at once and its position may be lost; home it again"
        }
        ALARM_SOFT_LIMIT => "a motion would leave the machine's travel (soft limit); nothing moved",
        ALARM_ABORT_CYCLE => {
            "the controller was reset while moving: its position may be lost; home it again"
        }
        ALARM_PROBE_FAIL_INITIAL | ALARM_PROBE_FAIL_CONTACT => "a probing cycle failed",
        ALARM_HOMING_FAIL_RESET..=ALARM_HOMING_FAIL_DUAL_APPROACH => "homing failed",
        _ => "an alarm this program does not know (see the controller's documentation)",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_grbl_sends_has_its_own_sentence() {
        let unknown = describe_error(0);
        for code in (1..=17).chain(20..=38) {
            assert_ne!(describe_error(code), unknown, "error:{code}");
        }
        assert_eq!(describe_error(18), unknown);
        let unknown = describe_alarm(0);
        for code in 1..=10 {
            assert_ne!(describe_alarm(code), unknown, "ALARM:{code}");
        }
        assert_eq!(describe_alarm(11), unknown);
    }
}
