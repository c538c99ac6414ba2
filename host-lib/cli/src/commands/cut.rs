//! `kerfmeter cut`: stream a G-code file to a laser cutter's GRBL controller (or the simulated
//! cutter) with a progress bar, or send it to a Ruida controller (`ruida:HOST`, `ruida-sim`),
//! whose driver reads the G-code Kerfmeter writes into its programs. Ctrl-C, SIGTERM and SIGHUP
//! stop the cutter (GRBL: feed hold, then soft reset; Ruida: `D8 01`: the laser goes off) and the
//! command fails, also while it connects; so does any refused line or alarm, with its meaning.
//! SIGKILL and a power loss of the computer cannot be caught: then only the machine's own safety
//! (its E-stop, its interlock) stops the laser.

use std::fmt;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kerfmeter::grbl::protocol::{MachineState, constant_power_line, prepare};
use kerfmeter::grbl::{ConnectOptions, Cutter, CutterAddress, CutterError, StreamProgress};
use kerfmeter_lightburn::project::is_project_path;
use kerfmeter_plan::PlanFormat;
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

/// `kerfmeter cut`: stream a G-code program to a cutter.
#[derive(Debug, Clone, clap::Args)]
pub struct CutArgs {
    /// The G-code program to stream.
    #[arg(value_name = "FILE.gcode")]
    pub input: PathBuf,
    /// The cutter: `sim`, `grbl:/dev/ttyUSB0[?baud=N]`, `grbl+tcp://HOST:PORT`,
    /// `ruida:HOST?z-mm=MIN,MAX[&bed-mm=W,H][&axis=z|u]` or `ruida-sim` (a Ruida controller is
    /// sent the G-code Kerfmeter writes, converted). Also from KERFMETER_CUTTER.
    #[arg(long, env = "KERFMETER_CUTTER", value_name = "ADDRESS")]
    pub cutter: CutterAddress,
    /// Unlock a cutter that is in alarm (`$X`) instead of refusing it. Check the machine first:
    /// an alarm after a hard limit or a reset means its position may be lost.
    #[arg(long)]
    pub unlock: bool,
    /// Accept a controller without laser mode (`$32=0`). Only for a spindle machine: GRBL then
    /// keeps a laser on through every travel move.
    #[arg(long)]
    pub allow_without_laser_mode: bool,
    /// Skip the check pass: by default the whole program first runs through GRBL's check mode
    /// (`$C`: parsed and answered, nothing moves), because a line GRBL refuses mid-job is
    /// followed by lines it has already read, which can cut from the wrong point.
    #[arg(long)]
    pub no_check: bool,
    /// Give the job up (and stop the cutter) once the machine has been held (feed hold, door
    /// open) this long, s. By default a held job waits for cycle start or Ctrl-C.
    #[arg(long, value_name = "SECONDS")]
    pub hold_timeout_s: Option<f64>,
}

/// What `cut` did.
#[derive(Debug, Clone, Serialize)]
pub struct CutReport {
    /// The cutter's address.
    pub cutter: String,
    /// GRBL's version (`null` for a Ruida controller).
    pub grbl_version: Option<String>,
    /// Lines streamed.
    pub lines: usize,
    /// From the first line until the machine was idle, s.
    pub elapsed_s: f64,
    /// The most bytes that were unanswered at once (at most 128).
    pub max_unanswered_bytes: usize,
    /// The first line that switched the laser on at constant power (`M3`), if any (see
    /// `constant_power_warning`).
    pub constant_power_line: Option<usize>,
}

impl fmt::Display for CutReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let controller = match &self.grbl_version {
            Some(version) => format!("GRBL {version}"),
            None => "Ruida".into(),
        };
        write!(
            f,
            "cut {} lines on {} ({controller}) in {:.1} s; the machine is idle",
            self.lines, self.cutter, self.elapsed_s
        )
    }
}

impl Report for CutReport {
    const JSON: JsonLayout = JsonLayout::CompactSorted;
}

/// A drawing given where a G-code program is expected: said as such, with the commands that
/// make the program (its first line would otherwise be refused as too long for GRBL).
fn refuse_a_plan_file(input: &std::path::Path) -> Result<(), CliError> {
    if PlanFormat::of(input).is_err() && !is_project_path(input) {
        return Ok(());
    }
    let ext = input.extension().unwrap_or_default().to_string_lossy();
    Err(CliError::Usage(format!(
        "{} is a drawing (.{ext}), not a G-code program: make one with `kerfmeter gcode {} \
         --kerf-um K -o plan.gcode`, or measure and cut in one go with `kerfmeter job`",
        input.display(),
        input.display()
    )))
}

/// Stream the file; Ctrl-C stops the cutter.
pub fn run(g: &Global, args: &CutArgs) -> Result<CutReport, CliError> {
    refuse_a_plan_file(&args.input)?;
    let program = std::fs::read_to_string(&args.input).map_err(|e| kerfmeter::Error::File {
        path: args.input.clone(),
        message: format!("cannot read the G-code program: {e}"),
    })?;
    // A line that cannot be streamed is refused before the cutter is touched.
    let lines = prepare(&program).map_err(|bad| CutterError::BadProgram {
        line: bad.number,
        reason: bad.reason,
    })?;
    if lines.is_empty() {
        return Err(kerfmeter::Error::File {
            path: args.input.clone(),
            message: "has no G-code line to cut (it is empty, or only comments); nothing was sent"
                .into(),
        }
        .into());
    }
    let constant_power_line = constant_power_line(&lines);
    if let Some(line) = constant_power_line.filter(|_| !g.json) {
        eprintln!("{}", constant_power_warning(line));
    }
    // Raised by Ctrl-C, SIGTERM and SIGHUP (`main` installs the handler for `cut`).
    let cancel = crate::interrupt::flag();
    if args.cutter.is_ruida() {
        return cut_on_ruida(g, args, &program, &cancel, constant_power_line);
    }
    let options = connect_options(args)?;
    let mut cutter = Cutter::open_cancellable(&args.cutter, options, cancel.clone())?;
    if !g.json {
        eprintln!(
            "streaming {} to {} (GRBL {}); Ctrl-C stops the cutter",
            args.input.display(),
            cutter.address(),
            cutter.version()
        );
    }
    cutter.check_s_max(&program)?;
    let bar = stream_bar(g.json);
    let report = cutter.stream_prepared(lines, &cancel, &mut |p| show(&bar, p));
    bar.finish_and_clear();
    let report = report?;
    Ok(CutReport {
        cutter: cutter.address().to_owned(),
        grbl_version: Some(cutter.version().to_owned()),
        lines: report.lines,
        elapsed_s: report.elapsed.as_secs_f64(),
        max_unanswered_bytes: report.max_unanswered_bytes,
        constant_power_line,
    })
}

/// Send `program` to the Ruida controller `args` names (the driver reads it into programs and
/// direct moves, and stops the controller on any failure and on `cancel`).
fn cut_on_ruida(
    g: &Global,
    args: &CutArgs,
    program: &str,
    cancel: &AtomicBool,
    constant_power_line: Option<usize>,
) -> Result<CutReport, CliError> {
    let mut cutter = kerfmeter::ruida::open(&args.cutter, None)?;
    if !g.json {
        eprintln!(
            "sending {} to {} (Ruida); Ctrl-C stops the cutter",
            args.input.display(),
            cutter.address()
        );
    }
    let bar = stream_bar(g.json);
    let report = cutter.stream(program, cancel, &mut |p| show(&bar, p));
    bar.finish_and_clear();
    let report = report?;
    Ok(CutReport {
        cutter: cutter.address().to_owned(),
        grbl_version: None,
        lines: report.lines,
        elapsed_s: report.elapsed.as_secs_f64(),
        max_unanswered_bytes: report.max_unanswered_bytes,
        constant_power_line,
    })
}

/// The warning for a program that switches the laser on with `M3` on `line`: the stream is
/// stopped with the laser off on every failure the host sees, but not where the host cannot
/// send (see [`kerfmeter::grbl::protocol::constant_power_line`]).
fn constant_power_warning(line: usize) -> String {
    format!(
        "warning: line {line} switches the laser on with M3 (constant power), which GRBL keeps on \
         at rest: if the stream stops where this computer cannot stop the cutter (asleep, the \
         cable pulled), the beam stays on over one spot. Prefer M4 (dynamic power, off at rest in \
         laser mode; in LightBurn the GRBL device rather than GRBL-M3)"
    )
}

/// The driver's options from the flags.
fn connect_options(args: &CutArgs) -> Result<ConnectOptions, CliError> {
    let hold_timeout = args
        .hold_timeout_s
        .map(|s| {
            Duration::try_from_secs_f64(s).map_err(|_| {
                CliError::Usage(format!(
                    "--hold-timeout-s {s}: give a number of seconds ≥ 0"
                ))
            })
        })
        .transpose()?;
    Ok(ConnectOptions {
        hold_timeout,
        unlock: args.unlock,
        allow_without_laser_mode: args.allow_without_laser_mode,
        check_first: !args.no_check,
        ..ConnectOptions::default()
    })
}

/// A bar of lines accepted, on stderr when it is a terminal and `json` is off.
fn stream_bar(json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} lines  {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

fn show(bar: &ProgressBar, p: &StreamProgress) {
    bar.set_length(p.total as u64);
    bar.set_position(p.answered as u64);
    if p.checking {
        bar.set_message("checking ($C): nothing moves");
        return;
    }
    if let Some(status) = &p.status {
        let at = status
            .position_mm
            .map(|[x, y, _]| format!(" at X{x:.1} Y{y:.1}"))
            .unwrap_or_default();
        let state = match status.state {
            MachineState::Hold(_) | MachineState::Door(_) => {
                format!(
                    "{}: held, press cycle start at the machine or Ctrl-C",
                    status.state
                )
            }
            ref other => other.to_string(),
        };
        bar.set_message(format!("{state}{at}"));
    }
}
