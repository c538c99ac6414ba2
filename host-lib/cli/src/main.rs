//! `kerfmeter-cli`: the `kerfmeter` command-line tool. Drive a Kerfmeter (or its simulated twin)
//! from a terminal or a script, draw the gauge, dilate plans, write G-code. `kerfmeter --help` lists the
//! commands; `--json` makes every command print one JSON object on stdout for scripts.
//!
//! This package holds what only a terminal needs: the arguments (clap), progress bars
//! ([`progress`]), plots ([`plot`]) and the reports; the work is done by the `kerfmeter` library
//! (device, statistics, bed map, twin) and `kerfmeter-plan` (gauge drawing, dilation). The
//! package's other binary, `kerfmeter-twin`, serves the digital twin on a real serial port.
//!
//! Each command lives in its own module under [`commands`] and returns a typed report that is
//! both its text (`Display`) and its JSON (`Serialize`); [`output::emit`] prints it either way.
//! Exit codes follow the error's category ([`error::exit_code`]): 0 success; 2 bad arguments;
//! 3 communication error (port, timeout, protocol, device restarted); 4 the device refused,
//! faulted, failed its self-test or could not finish, or a file could not be read or written;
//! 5 a cutter failed and could not be stopped (its laser may still be on).
//!
//! Every measurement `run` and `job` make is recorded in the history ([`record`]; `--db`),
//! which `kerfmeter history` lists.

use std::process::ExitCode;

use clap::error::ErrorKind;
use clap::parser::ValueSource;
use clap::{ArgMatches, CommandFactory, FromArgMatches, Parser, Subcommand};

mod commands;
mod connection;
mod error;
mod health;
mod interrupt;
mod output;
mod plot;
mod progress;
mod serve;
#[cfg(test)]
mod tests;
mod words;

use commands::config::ConfigCommand;
use commands::map::MapArgs;
use commands::run::RunArgs;
use commands::{cut, dilate, gauge, gcode, history, job, lightburn};
use connection::Global;
use error::{CliError, exit_code};
use output::{ErrorReport, JsonLayout, emit, print_line, to_json};

#[derive(Parser)]
#[command(
    name = "kerfmeter",
    version,
    about = "Measure a laser cutter's kerf with a Kerfmeter, and use it",
    after_help = "Without --port or --sim, the device is found by its USB ids (303a:1001).\nExamples:\n  kerfmeter --sim run --samples 3\n  kerfmeter --port /dev/ttyACM0 run --thickness-mm 3 --plot curve.png"
)]
struct Cli {
    #[command(flatten)]
    global: Global,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the device's protocol and firmware versions, boot id and hardware constants.
    Info,
    /// Print what the device is doing: state, latched fault, idle conditions (no magnet, driver
    /// FLT, ...), motor supply, and the longest control step and gap since boot.
    Status,
    /// Measure the kerf (resets the hub to zero first). With --samples N, N gauges are measured
    /// and the mean with its 95 % confidence interval is reported.
    Run(RunArgs),
    /// Print the last result kept by the device.
    Kerf,
    /// Turn the hub back to zero and clear the last result (and a latched fault).
    Reset,
    /// Stop the motor and end whatever the device is doing.
    Abort,
    /// Leave a latched fault (fix its cause first).
    ClearFault,
    /// Say the hub stands at its zero mark (turned there by hand, prongs lifted): with the
    /// encoder on the motor shaft the device refuses runs after every power-up until told so.
    ConfirmZero,
    /// Check the encoder, magnet, drive direction and torque constant (no gauge under the prongs).
    SelfTest,
    /// A guided first power-on: the bench checks in order (health, supply against a meter, the
    /// current sense, the encoder, the self-test and which way the hub turned, one run on a
    /// cut gauge, timing), each passed or failed in words; saves a text and JSON report.
    Bringup(commands::bringup::BringupArgs),
    /// Read or change the device configuration (stored in its flash).
    #[command(subcommand)]
    Config(ConfigCommand),
    /// Measure a grid of gauges across the bed and save a location-compensation map (JSON).
    Map(MapArgs),
    /// Draw the spiral gauge to cut before a measurement (SVG, DXF or G-code by extension).
    Gauge(gauge::GaugeArgs),
    /// Dilate a cutting plan (SVG or DXF) by the measured kerf: cuts grow by half the kerf on
    /// each side, so parts come out at their drawn size. A LightBurn project (.lbrn2) gets the
    /// Kerf Offset of its Line layers set to half the kerf instead.
    Dilate(dilate::DilateArgs),
    /// Stream a G-code file to a laser cutter's GRBL controller (--cutter sim for the simulated
    /// one). Refuses a cutter in alarm (--unlock) or without laser mode; Ctrl-C stops the cutter.
    Cut(cut::CutArgs),
    /// Dilate a cutting plan by the kerf and write it as G-code for a GRBL 1.1 laser (laser
    /// mode, M4 dynamic power), with speed, power and passes per colour or layer.
    Gcode(gcode::GcodeArgs),
    /// A running LightBurn over its local REST API (one with its `project_write` capability):
    /// pair with it, and write the kerf into the Kerf Offset of its Line layers.
    #[command(subcommand)]
    Lightburn(lightburn::LightBurnCommand),
    /// The whole job: cut the gauge beside the plan, lower the prongs into it, measure, lift,
    /// dilate the plan by the kerf measured and cut it (--sim --cutter sim: all simulated).
    Job(job::JobArgs),
    /// List the measurements recorded by run and job (the real ones; with --sim the simulated
    /// ones), newest first, with a warning for each label whose kerf left its usual spread.
    History(history::HistoryArgs),
    /// Serve the device to other programs and browsers: JSON-RPC over a WebSocket (/rpc), HTTP
    /// JSON (/api/...) and a page (/), on loopback by default (see docs/server.md).
    Serve(commands::serve::ServeArgs),
}

/// Keep glibc's allocator to one arena. By default every thread that allocates while another
/// does gets an arena of its own (up to 8 a core), and what the dilation's worker threads free
/// stays in theirs: on a 10,000-contour plan the peak resident set was 71 MB (SVG, 2.8 MB file)
/// and 183 MB (DXF, 12.8 MB), 60 MB and 171 MB with one arena, for no more CPU time (two
/// cores; the threads allocate little beside their offsets).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn one_malloc_arena() {
    // SAFETY: mallopt only sets a parameter of the allocator, before any other thread exists.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn one_malloc_arena() {}

/// The command line, parsed. A negative number is a value wherever one is taken (`--kerf-um
/// -150` gets the option's own range message, not "unexpected argument '-1'"), and with
/// `--json` a usage error is printed as `{"error": …}` on stdout, like every other error.
fn parse_cli() -> Result<Cli, ExitCode> {
    let command = negative_numbers_are_values(Cli::command());
    let parsed = command.try_get_matches().and_then(|matches| {
        let cli = Cli::from_arg_matches(&matches)?;
        refuse_unused_device_flags(&cli.command, &matches)?;
        Ok(cli)
    });
    let e = match parsed {
        Ok(cli) => return Ok(cli),
        Err(e) => e,
    };
    let is_usage_error = e.use_stderr();
    if is_usage_error && std::env::args_os().any(|a| a == "--json") {
        let rendered = e.to_string();
        let message = rendered.lines().next().unwrap_or_default();
        let report = ErrorReport {
            error: message.trim_start_matches("error: ").to_owned(),
            fault: None,
            conditions: Vec::new(),
            compensation_found: None,
            job_so_far: None,
        };
        print_line(&to_json(&report, JsonLayout::CompactSorted));
        return Err(ExitCode::from(2));
    }
    e.exit()
}

/// The global flags that reach the device or set up its twin (by their ids).
const DEVICE_FLAGS: [&str; 15] = [
    // First, so that the rest are `DEVICE_FLAGS[1..]`: what `lightburn` and `history` refuse.
    "sim",
    "port",
    "sim_kerf_um",
    "sim_kerf_sd_um",
    "sim_seed",
    "sim_fault",
    "sim_encoder_on_motor_shaft",
    "sim_adc_uncalibrated",
    "sim_driver",
    "sim_motor_leads_swapped",
    "sim_realtime",
    "sim_material",
    "sim_plant_file",
    "sim_plant",
    "timeout_ms",
];

/// Of [`DEVICE_FLAGS`], those `command` has no use for: it does not talk to the device
/// (`lightburn` and `history` take `--sim` for a LightBurn twin and the simulated records).
fn unused_device_flags(command: &Command) -> &'static [&'static str] {
    match command {
        Command::Gauge(_) | Command::Dilate(_) | Command::Gcode(_) | Command::Cut(_) => {
            &DEVICE_FLAGS
        }
        Command::Lightburn(_) | Command::History(_) => &DEVICE_FLAGS[1..],
        _ => &[],
    }
}

/// A device flag typed for a command that does not use the device is refused, not ignored: a
/// `--sim-fault` on `dilate` would let the user believe something was tested. (A port from
/// `KERFMETER_PORT` is the environment's, not the user's word for this command.)
fn refuse_unused_device_flags(command: &Command, matches: &ArgMatches) -> Result<(), clap::Error> {
    let typed = unused_device_flags(command)
        .iter()
        .find(|id| matches.value_source(id) == Some(ValueSource::CommandLine));
    let Some(id) = typed else {
        return Ok(());
    };
    let name = matches.subcommand_name().unwrap_or("this command");
    Err(Cli::command().error(
        ErrorKind::ArgumentConflict,
        format!(
            "`kerfmeter {name}` does not use the device: --{} has no effect on it; leave it out",
            id.replace('_', "-")
        ),
    ))
}

/// `command` and all its subcommands take negative numbers as values, and their decimal
/// options any value starting with a hyphen (`--kerf-um -inf` is refused by the kerf's range,
/// not as "unexpected argument '-i'"; `-inf` is no number to clap).
fn negative_numbers_are_values(command: clap::Command) -> clap::Command {
    use std::any::TypeId;
    command
        .allow_negative_numbers(true)
        .mut_args(|arg| {
            let parser = arg.get_value_parser().type_id();
            if parser == TypeId::of::<f64>() || parser == TypeId::of::<f32>() {
                arg.allow_hyphen_values(true)
            } else {
                arg
            }
        })
        .mut_subcommands(negative_numbers_are_values)
}

fn main() -> ExitCode {
    kerfmeter_protocol::advice::in_words_of(&words::CLI, main_in_cli_words)
}

/// `main`, with every message's advice in the command line's words.
fn main_in_cli_words() -> ExitCode {
    one_malloc_arena();
    let cli = match parse_cli() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    if let Err(e) = interrupt::install(on_signal(&cli.command)) {
        eprintln!("warning: Ctrl-C will not stop the device or clean up: {e}");
    }
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let e = error::after_signal(e, interrupt::raised());
            if cli.global.json && !e.is_in_report() {
                let report = ErrorReport {
                    error: e.to_string(),
                    fault: e.fault(),
                    conditions: e.conditions(),
                    compensation_found: e.compensation_found(),
                    job_so_far: e.job_so_far(),
                };
                print_line(&to_json(&report, JsonLayout::CompactSorted));
                output::lossy_path::warn_if_replaced();
            } else if matches!(e, CliError::Interrupted { .. }) {
                // Not a failure of the command's: what the user asked for, done.
                eprintln!("{e}");
            } else if !cli.global.json {
                eprintln!("error: {e}");
            }
            ExitCode::from(exit_code(&e))
        }
    }
}

/// What Ctrl-C, SIGTERM and SIGHUP do to `command` (see [`interrupt`]): the commands that can
/// move the motor or a cutter stop it first; those that write an output file remove their
/// unfinished temporary file (an output is replaced only by a finished one); the others end.
/// `serve` stops its own way (it closes its listener and aborts a run in progress).
fn on_signal(command: &Command) -> interrupt::OnSignal {
    use interrupt::OnSignal;
    match command {
        Command::Run(_)
        | Command::Reset
        | Command::SelfTest
        | Command::Bringup(_)
        | Command::Map(_)
        | Command::Cut(_)
        | Command::Job(_) => OnSignal::Stop,
        Command::Dilate(_) | Command::Gcode(_) | Command::Gauge(_) | Command::Lightburn(_) => {
            OnSignal::CleanUp
        }
        Command::Info
        | Command::Status
        | Command::Kerf
        | Command::Abort
        | Command::ClearFault
        | Command::ConfirmZero
        | Command::Config(_)
        | Command::History(_)
        | Command::Serve(_) => OnSignal::Die,
    }
}

/// Run the command and print its report.
fn run(cli: &Cli) -> Result<(), CliError> {
    use commands::*;
    let g = &cli.global;
    let json = g.json;
    match &cli.command {
        Command::Info => emit(json, &info::run(g)?),
        Command::Status => emit(json, &status::run(g)?),
        Command::Run(args) => emit(json, &run::run(g, args)?),
        Command::Kerf => emit(json, &kerf::run(g)?),
        Command::Reset => emit(json, &reset::run(g)?),
        Command::Abort => emit(json, &abort::run(g)?),
        Command::ClearFault => emit(json, &clear_fault::run(g)?),
        Command::ConfirmZero => emit(json, &confirm_zero::run(g)?),
        Command::SelfTest => emit(json, &self_test::run(g)?),
        Command::Bringup(args) => emit(json, &bringup::run(g, args)?),
        Command::Config(c) => emit(json, &config::run(g, c)?),
        Command::Map(args) => emit(json, &map::run(g, args)?),
        Command::Gauge(args) => emit(json, &gauge::run(args)?),
        Command::Dilate(args) => emit(json, &dilate::run(g, args)?),
        Command::Cut(args) => emit(json, &cut::run(g, args)?),
        Command::Gcode(args) => emit(json, &gcode::run(g, args)?),
        Command::History(args) => emit(json, &history::run(g, args)?),
        Command::Serve(args) => emit(json, &commands::serve::run(g, args)?),
        Command::Lightburn(lightburn::LightBurnCommand::Pair(args)) => {
            emit(json, &lightburn::pair(args, g.sim)?)
        }
        Command::Lightburn(lightburn::LightBurnCommand::Apply(args)) => {
            emit(json, &lightburn::apply(args, g.sim)?)
        }
        Command::Job(args) => match job::run(g, args)? {
            job::JobOutcome::Done(report) => emit(json, report.as_ref()),
            job::JobOutcome::DryRun(report) => emit(json, &report),
        },
    }
}
