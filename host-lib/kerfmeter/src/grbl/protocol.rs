//! The GRBL 1.1 protocol without I/O: a program cleaned into lines fit to stream, the replies
//! classified, status reports parsed, and the character-counting streamer that never lets more
//! than the controller's 128-byte receive buffer go unacknowledged.
//!
//! Character counting: the controller answers every line (`ok` or `error:N`) in order, so the
//! bytes of the lines not yet answered are exactly what may still sit in its receive buffer. A
//! line is sent only when it fits beside them. Realtime commands (`?`, `!`, `~`, ctrl-X) never
//! enter the buffer and are not counted, which is also why a program line may not contain them.

use std::collections::VecDeque;

use kerfmeter_grbl::realtime;
/// GRBL's receive buffer and line limit, and its status report, from the one table of GRBL's
/// facts (`kerfmeter-grbl`).
pub use kerfmeter_grbl::status::{BufferFree, MachineState, Status};
pub use kerfmeter_grbl::{LINE_MAX_LEN, RX_BUFFER_LEN};

/// One line of a program, ready to stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProgramLine {
    /// Its line number in the file (1 = the first).
    pub number: usize,
    /// What is sent: the line without comments and spaces.
    pub text: String,
    /// The line as written in the file (without its line end and the blanks around it), as
    /// messages quote it.
    pub written: String,
}

/// A program line that cannot be streamed, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadLine {
    /// Its line number in the file.
    pub number: usize,
    /// Why.
    pub reason: String,
}

/// The `S` of full power a program declares in a comment that opens with
/// [`kerfmeter_grbl::S_MAX_TAG`] (`(S_MAX=1000 must equal GRBL setting 30)`, as `kerfmeter
/// gcode` and `kerfmeter gauge` write it), if it declares one. A declaration without a positive
/// number, or two that disagree, make a bad line.
pub fn declared_s_max(program: &str) -> Result<Option<f64>, BadLine> {
    let mut found: Option<f64> = None;
    for (index, raw) in program_lines(program).enumerate() {
        let tagged = raw.trim().strip_prefix('(');
        let Some(rest) = tagged.and_then(|r| r.strip_prefix(kerfmeter_grbl::S_MAX_TAG)) else {
            continue;
        };
        let number = index + 1;
        let end = rest
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(rest.len());
        let value = rest[..end]
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| BadLine {
                number,
                reason: format!("`{}` declares no readable S max", raw.trim()),
            })?;
        if let Some(before) = found.filter(|&before| before != value) {
            return Err(BadLine {
                number,
                reason: format!("declares S max {value} after declaring {before}"),
            });
        }
        found = Some(value);
    }
    Ok(found)
}

/// The lines of a program as GRBL reads them: a line ends at `\n`, `\r\n` or a lone `\r`
/// (GRBL ends a line at either character, so a file saved with old Mac line ends is as many
/// lines as it looks, not one).
fn program_lines(program: &str) -> impl Iterator<Item = &str> {
    program.split('\n').flat_map(|line| {
        let line = line.strip_suffix('\r').unwrap_or(line);
        line.split('\r')
    })
}

/// Clean a G-code program into the lines to stream: comments (`;...`, `(...)`), spaces, `%`
/// delimiters and empty lines go. Refused: characters GRBL would take as realtime commands or
/// cannot read, `$` system commands (run them on their own, not inside a job), and lines longer
/// than GRBL's line buffer.
pub fn prepare(program: &str) -> Result<Vec<ProgramLine>, BadLine> {
    let mut lines = Vec::new();
    for (index, raw) in program_lines(program).enumerate() {
        let number = index + 1;
        let bad = |reason: String| BadLine { number, reason };
        let text = clean(raw).map_err(bad)?;
        if text.is_empty() || text == "%" {
            continue;
        }
        let written = raw.trim().to_owned();
        if text.starts_with('$') {
            return Err(bad(format!(
                "`{written}` is a GRBL system command; run it on its own, not inside a job"
            )));
        }
        if text.len() > LINE_MAX_LEN {
            return Err(bad(format!(
                "{} characters without spaces and comments; GRBL takes at most {LINE_MAX_LEN}",
                text.len()
            )));
        }
        if let Some(pause) = program_pause(&text) {
            return Err(bad(format!(
                "`{pause}` pauses the program until cycle start is pressed at the machine, with the job half done; remove it"
            )));
        }
        lines.push(ProgramLine {
            number,
            text,
            written,
        });
    }
    Ok(lines)
}

/// The program pause (`M0`, `M1`) on a cleaned line, if any.
fn program_pause(text: &str) -> Option<String> {
    m_words(text)
        .find(|&(_, command)| command == 0 || command == 1)
        .map(|(word, _)| format!("M{word}"))
}

/// The first line of `lines` that switches the laser on at constant power (`M3`), if any.
/// Under `M3` GRBL keeps the beam on at rest: should the stream stop mid-program where the host
/// cannot send a stop (the computer asleep, the cable pulled, the process killed), the beam
/// stays on over one spot until the controller is reset. `M4` (dynamic power, what Kerfmeter's
/// programs use) scales it with the speed, to nothing at rest.
pub fn constant_power_line(lines: &[ProgramLine]) -> Option<usize> {
    lines
        .iter()
        .find(|l| m_words(&l.text).any(|(_, command)| command == 3))
        .map(|l| l.number)
}

/// The `M` commands of a cleaned line: each word as written after the `M`, and the command GRBL
/// runs for it. GRBL reads a signed number (`M+3` is `M3`, `M-0` is `M0`), takes its whole part
/// when its hundredths round to nothing (`M3.004` is `M3`) and refuses the line otherwise
/// (`M3.5`, a negative command), which leaves nothing to find.
fn m_words(text: &str) -> impl Iterator<Item = (&str, u32)> {
    text.split('M').skip(1).filter_map(|after| {
        let sign = usize::from(after.starts_with(['+', '-']));
        let end = after[sign..]
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .map_or(after.len(), |at| sign + at);
        let word = &after[..end];
        let number = word.parse::<f64>().ok()?;
        let whole = number.trunc();
        let integer = (100.0 * (number - whole)).round() == 0.0;
        (integer && (0.0..=f64::from(u32::MAX)).contains(&whole)).then_some((word, whole as u32))
    })
}

/// One line without comments and spaces, or why it cannot be sent.
fn clean(raw: &str) -> Result<String, String> {
    let mut text = String::with_capacity(raw.len());
    let mut in_comment = false;
    for c in raw.chars() {
        match c {
            '(' => in_comment = true,
            ')' if in_comment => in_comment = false,
            ';' if !in_comment => break,
            _ if in_comment => {}
            c if realtime::PRINTABLE.contains(&c) => {
                return Err(format!(
                    "`{c}` outside a comment would be taken by GRBL as a realtime command"
                ));
            }
            c if c.is_ascii_whitespace() => {}
            c if c.is_ascii_graphic() => text.push(c.to_ascii_uppercase()),
            c => return Err(format!("character {c:?} is not printable ASCII")),
        }
    }
    Ok(text)
}

/// The receive buffer a `$I` build-info line reports (`[OPT:V,15,128]`: options, planner
/// blocks, receive-buffer bytes); `None` for any other line.
pub fn rx_buffer_from_build_info(line: &str) -> Option<usize> {
    let options = line
        .strip_prefix(kerfmeter_grbl::BUILD_OPTIONS_PREFIX)?
        .strip_suffix(']')?;
    options.split(',').nth(2)?.trim().parse().ok()
}

/// The character-counting window for a controller whose `$I` reports `rx_buffer` bytes: GRBL's
/// 128 at most (a larger buffer is not needed to keep a laser's planner fed), less when its
/// buffer is smaller, but never below the longest line plus its newline (or no line could be
/// sent).
pub fn window_for(rx_buffer: Option<usize>) -> usize {
    rx_buffer.map_or(RX_BUFFER_LEN, |rx| {
        rx.clamp(LINE_MAX_LEN + 1, RX_BUFFER_LEN)
    })
}

/// What a line from the controller is.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// `ok`: the oldest unanswered line was accepted.
    Ok,
    /// `error:N`: the oldest unanswered line was refused.
    Error(u8),
    /// `ALARM:N`: the machine stopped.
    Alarm(u8),
    /// The welcome banner (`Grbl 1.1h ['$' for help]`), with its version: the controller
    /// (re)started.
    Banner(String),
    /// A `[MSG:...]` message, without its brackets.
    Message(String),
    /// A status report.
    Status(Status),
    /// A setting from `$$` (`$N=V`).
    Setting(u16, f64),
    /// Anything else (other `[...]` feedback, echoes, noise).
    Other(String),
}

/// Classify one line (without its line ending).
pub fn parse_reply(line: &str) -> Reply {
    let line = line.trim();
    if line == kerfmeter_grbl::OK {
        return Reply::Ok;
    }
    let code = |rest: &str| rest.trim().parse::<u8>().ok();
    if let Some(n) = line
        .strip_prefix(kerfmeter_grbl::ERROR_PREFIX)
        .and_then(code)
    {
        return Reply::Error(n);
    }
    if let Some(n) = line
        .strip_prefix(kerfmeter_grbl::ALARM_PREFIX)
        .and_then(code)
    {
        return Reply::Alarm(n);
    }
    // GRBL's banner; grblHAL names itself `GrblHAL`, FluidNC says `Grbl 3.x [FluidNC ...]`.
    if let Some(rest) = line
        .strip_prefix(kerfmeter_grbl::BANNER_PREFIX)
        .or_else(|| line.strip_prefix(kerfmeter_grbl::GRBLHAL_BANNER_PREFIX))
    {
        let version = rest.split_whitespace().next().unwrap_or_default();
        return Reply::Banner(version.to_owned());
    }
    if let Some(message) = line
        .strip_prefix(kerfmeter_grbl::MESSAGE_PREFIX)
        .and_then(|m| m.strip_suffix(']'))
    {
        return Reply::Message(message.to_owned());
    }
    if let Some(status) = Status::parse(line) {
        return Reply::Status(status);
    }
    if let Some((n, v)) = line.strip_prefix('$').and_then(|s| s.split_once('='))
        && let (Ok(n), Ok(v)) = (n.parse(), v.parse())
    {
        return Reply::Setting(n, v);
    }
    Reply::Other(line.to_owned())
}

/// A reply the streamer did not expect.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnexpectedReply;

/// The character-counting streamer: which line goes next, and which line a reply answers.
#[derive(Debug, Clone)]
pub struct Streamer {
    lines: Vec<ProgramLine>,
    next: usize,
    in_flight: VecDeque<usize>,
    in_flight_bytes: usize,
    answered: usize,
    window: usize,
}

impl Streamer {
    /// Stream `lines` with at most [`RX_BUFFER_LEN`] bytes unanswered.
    pub fn new(lines: Vec<ProgramLine>) -> Self {
        Self::with_window(lines, RX_BUFFER_LEN)
    }

    /// Stream with another window (a controller with a larger buffer; tests).
    pub fn with_window(lines: Vec<ProgramLine>, window: usize) -> Self {
        Self {
            lines,
            next: 0,
            in_flight: VecDeque::new(),
            in_flight_bytes: 0,
            answered: 0,
            window,
        }
    }

    /// The next line to send, with its newline, when it fits beside the unanswered ones.
    pub fn next_to_send(&mut self) -> Option<Vec<u8>> {
        let line = self.lines.get(self.next)?;
        let len = line.text.len() + 1;
        if self.in_flight_bytes + len > self.window {
            return None;
        }
        self.in_flight.push_back(self.next);
        self.in_flight_bytes += len;
        self.next += 1;
        let mut bytes = line.text.clone().into_bytes();
        bytes.push(b'\n');
        Some(bytes)
    }

    /// An `ok` or `error:N` arrived: the oldest unanswered line it answers.
    pub fn answer(&mut self) -> Result<&ProgramLine, UnexpectedReply> {
        let index = self.in_flight.pop_front().ok_or(UnexpectedReply)?;
        let line = &self.lines[index];
        self.in_flight_bytes -= line.text.len() + 1;
        self.answered += 1;
        Ok(line)
    }

    /// Bytes sent and not yet answered.
    pub fn unanswered_bytes(&self) -> usize {
        self.in_flight_bytes
    }

    /// Lines answered so far.
    pub fn answered(&self) -> usize {
        self.answered
    }

    /// Lines in the program.
    pub fn total(&self) -> usize {
        self.lines.len()
    }

    /// The last line the controller accepted, if any.
    pub fn last_answered(&self) -> Option<&ProgramLine> {
        let last = self.in_flight.front().copied().unwrap_or(self.next);
        last.checked_sub(1).map(|i| &self.lines[i])
    }

    /// True once every line is answered.
    pub fn done(&self) -> bool {
        self.answered == self.lines.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_program_is_cleaned_and_what_cannot_be_streamed_is_named() {
        assert_eq!(declared_s_max("G1X1\n"), Ok(None));
        let header = "(kerfmeter)\n(S_MAX=255 must equal GRBL setting 30)\nG1X1\n";
        assert_eq!(declared_s_max(header), Ok(Some(255.0)));
        let twice = format!("{header}(S_MAX=1000)\n");
        assert_eq!(declared_s_max(&twice).unwrap_err().number, 4);
        assert_eq!(declared_s_max("(S_MAX=x)").unwrap_err().number, 1);
        let lines = prepare("%\n; header\nG21 G90 (mm)\n\ng1 x1 f600 ; cut\n").unwrap();
        let texts: Vec<_> = lines.iter().map(|l| (l.number, l.text.as_str())).collect();
        assert_eq!(texts, [(3, "G21G90"), (5, "G1X1F600")]);
        assert_eq!(prepare("G0X1\nG1X2?\n").unwrap_err().number, 2);
        assert!(
            prepare("$X\n")
                .unwrap_err()
                .reason
                .contains("system command")
        );
        let longest = format!("G1X{}", "1".repeat(LINE_MAX_LEN - 3));
        assert_eq!(longest.len(), 79);
        assert!(prepare(&longest).is_ok(), "79 characters fit");
        let error = prepare(&format!("{longest}1")).unwrap_err();
        assert!(error.reason.contains("at most 79"), "{}", error.reason);
        for pause in ["M0", "G0X1M1", "M00", "m1 (pause)"] {
            let error = prepare(pause).unwrap_err();
            assert!(
                error.reason.contains("cycle start"),
                "{pause}: {}",
                error.reason
            );
        }
        assert!(prepare("M3S100\nM5\nM2\nM30\nM4\nM100\n").is_ok());
        let lines = |program| prepare(program).unwrap();
        assert_eq!(
            constant_power_line(&lines("G0X1\nM4S100\nM03 S100\n")),
            Some(3)
        );
        assert_eq!(constant_power_line(&lines("M4S100\nM30\nM5\n")), None);
        // As GRBL reads them: hundredths that round to nothing are the whole command.
        assert_eq!(constant_power_line(&lines("M3.004\n")), Some(1));
        assert_eq!(constant_power_line(&lines("M3.5\nM300\n")), None);
        assert!(prepare("M0.001\n").is_err(), "a pause");
        assert!(prepare("M-0\n").is_err(), "a signed pause");
        assert_eq!(constant_power_line(&lines("M+3\n")), Some(1));
        assert_eq!(
            constant_power_line(&lines("M-3\n")),
            None,
            "refused by GRBL"
        );
        assert!(prepare("G1 X1 (a ! in a comment is fine)\n").is_ok());
    }

    /// GRBL ends a line at `\r` as at `\n`: a file with old Mac line ends is not one line (it
    /// was: `X30` then `Y30` became one diagonal move).
    #[test]
    fn a_lone_carriage_return_ends_a_line_as_in_grbl() {
        let texts = |program: &str| -> Vec<(usize, String)> {
            let lines = prepare(program).unwrap();
            lines.into_iter().map(|l| (l.number, l.text)).collect()
        };
        let expected = [
            (1, "G21G90".to_owned()),
            (2, "G1X30F600".into()),
            (3, "Y30".into()),
        ];
        assert_eq!(texts("G21 G90\rG1 X30 F600\rY30\r"), expected);
        assert_eq!(texts("G21 G90\r\nG1 X30 F600\r\nY30\r\n"), expected);
        assert_eq!(texts("G21 G90\nG1 X30 F600\nY30"), expected);
        assert_eq!(declared_s_max("G1X1\r(S_MAX=255)\r"), Ok(Some(255.0)));
    }

    #[test]
    fn the_window_follows_a_smaller_receive_buffer_from_build_info() {
        assert_eq!(rx_buffer_from_build_info("[OPT:V,15,128]"), Some(128));
        assert_eq!(rx_buffer_from_build_info("[OPT:VL,35,1024]"), Some(1024));
        assert_eq!(rx_buffer_from_build_info("[VER:1.1h.20190825:]"), None);
        assert_eq!(window_for(None), 128);
        assert_eq!(window_for(Some(1024)), 128);
        assert_eq!(window_for(Some(96)), 96);
        assert_eq!(window_for(Some(16)), 80);
    }

    #[test]
    fn replies_and_status_reports_are_read() {
        assert_eq!(parse_reply("ok\r"), Reply::Ok);
        assert_eq!(parse_reply("error:22"), Reply::Error(22));
        assert_eq!(parse_reply("ALARM:1"), Reply::Alarm(1));
        assert_eq!(
            parse_reply("Grbl 1.1h ['$' for help]"),
            Reply::Banner("1.1h".into())
        );
        let fluidnc = "Grbl 3.7 [FluidNC v3.7.8 (wifi) '$' for help]";
        assert_eq!(parse_reply(fluidnc), Reply::Banner("3.7".into()));
        let grblhal = "GrblHAL 1.1f ['$' or '$HELP' for help]";
        assert_eq!(parse_reply(grblhal), Reply::Banner("1.1f".into()));
        assert_eq!(parse_reply("$32=1"), Reply::Setting(32, 1.0));
        let Reply::Status(s) = parse_reply("<Hold:0|MPos:1.000,2.500,0.000|Bf:15,128|FS:0,0>")
        else {
            panic!("not a status");
        };
        assert_eq!(s.state, MachineState::Hold(0));
        assert_eq!(s.position_mm, Some([1.0, 2.5, 0.0]));
        assert_eq!(
            s.buffer_free,
            Some(BufferFree {
                planner_blocks: 15,
                rx_bytes: 128
            })
        );
        let Reply::Status(s) = parse_reply("<Idle|WPos:1.000,2.000,-3.500|FS:0,0>") else {
            panic!("not a status");
        };
        assert_eq!(
            (s.position_mm, s.work_position_mm),
            (None, Some([1.0, 2.0, -3.5]))
        );
    }

    #[test]
    fn the_streamer_keeps_the_unanswered_bytes_within_the_window() {
        let lines = prepare(&"G1X10F600\n".repeat(40)).unwrap();
        let mut streamer = Streamer::new(lines);
        let mut sent = 0;
        while let Some(bytes) = streamer.next_to_send() {
            sent += bytes.len();
        }
        assert_eq!(sent, 120, "12 lines of 10 bytes; the 13th would pass 128");
        assert_eq!(streamer.answer().unwrap().number, 1);
        assert!(streamer.next_to_send().is_some());
        assert_eq!(streamer.unanswered_bytes(), 120);
        let mut fresh = Streamer::new(Vec::new());
        assert_eq!(fresh.answer(), Err(UnexpectedReply));
    }

    proptest::proptest! {
        /// Any text: what is sent is short, printable and free of realtime characters; any
        /// order of sends and answers keeps the window; any reply line is classified.
        #[test]
        fn any_program_streams_within_the_window(
            program in "[ -~\n\t]{0,2000}",
            answers in proptest::collection::vec(proptest::bool::ANY, 0..200),
        ) {
            let _ = parse_reply(&program);
            let Ok(lines) = prepare(&program) else { return Ok(()) };
            for line in &lines {
                proptest::prop_assert!(line.text.len() <= LINE_MAX_LEN);
                proptest::prop_assert!(!line.text.contains(['?', '!', '~']));
                proptest::prop_assert!(line.text.bytes().all(|b| b.is_ascii_graphic()));
            }
            let mut streamer = Streamer::new(lines);
            for answer in answers {
                if answer {
                    let _ = streamer.answer();
                } else {
                    let _ = streamer.next_to_send();
                }
                proptest::prop_assert!(streamer.unanswered_bytes() <= RX_BUFFER_LEN);
            }
        }
    }
}
