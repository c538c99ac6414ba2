//! What GRBL 1.1's numbered replies mean: `error:N` (a line refused) and `ALARM:N` (the machine
//! stopped), each as a sentence for the person at the cutter, in this project's words.

/// A sentence for `error:N`.
pub fn describe_error(code: u8) -> &'static str {
    match code {
        1 => "a word has no letter (G-code words are a letter and a number)",
        2 => "a number is missing or malformed",
        3 => "the controller does not know this `$` command",
        4 => "a value that must not be negative is negative",
        5 => "homing is not enabled on this controller",
        6 => "the step pulse must be at least 3 µs",
        7 => "the controller's stored settings could not be read; it restored its defaults",
        8 => "this `$` command needs the machine idle",
        9 => "G-code is locked while the machine is in alarm or jogging",
        10 => "soft limits need homing enabled",
        11 => "the line is longer than the controller's line buffer",
        12 => "this setting would make the step rate too high",
        13 => "the safety door is open",
        14 => "the line is too long to be stored",
        15 => "the jog target is outside the machine's travel",
        16 => "the jog command is malformed or uses forbidden G-code",
        17 => "laser mode needs the spindle's PWM output",
        20 => "the controller does not support this command",
        21 => "two commands of the same group are on one line",
        22 => "no feed rate has been set for this feed move",
        23 => "this command needs a whole number",
        24 => "two commands that both need axis words are on one line",
        25 => "a word is repeated on the line",
        26 => "the command needs axis words and has none",
        27 => "the line number is invalid",
        28 => "the command is missing a value it needs",
        29 => "this work coordinate system is not supported",
        30 => "G53 is allowed only with G0 and G1",
        31 => "there are axis words that no command on the line uses",
        32 => "an arc needs at least one axis word in its plane",
        33 => "the motion's target is invalid (for an arc: its end is not on its circle)",
        34 => "the arc's radius is invalid",
        35 => "an arc needs at least one of its offsets (I, J)",
        36 => "there are value words that nothing on the line uses",
        37 => "the tool length offset is not on the configured axis",
        38 => "the tool number is too large",
        _ => "an error this program does not know (see the controller's documentation)",
    }
}

/// A sentence for `ALARM:N`.
pub fn describe_alarm(code: u8) -> &'static str {
    match code {
        1 => {
            "a hard limit switch tripped: the machine stopped at once and its position may be lost; home it again"
        }
        2 => "a motion would leave the machine's travel (soft limit); nothing moved",
        3 => "the controller was reset while moving: its position may be lost; home it again",
        4 | 5 => "a probing cycle failed",
        6..=10 => "homing failed",
        _ => "an alarm this program does not know (see the controller's documentation)",
    }
}
