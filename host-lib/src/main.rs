//! The `kerfmeter` command-line tool: drive a Kerfmeter (or its simulated twin) from a terminal
//! or a script. `kerfmeter --help` lists the commands; `--json` makes every command print one JSON
//! object for scripts.
//!
//! Exit codes: 0 success; 2 bad arguments; 3 communication error (port, timeout, protocol);
//! 4 the device refused or faulted.

use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use kerfmeter::{Error, Kerfmeter, Options};

/// Exit code for bad arguments (clap uses it too).
const EXIT_USAGE: u8 = 2;
/// Exit code for errors of the serial link.
const EXIT_COMMUNICATION: u8 = 3;
/// Exit code for device refusals and faults.
const EXIT_DEVICE: u8 = 4;

#[derive(Parser)]
#[command(
    name = "kerfmeter",
    version,
    about = "Measure a laser cutter's kerf with a Kerfmeter"
)]
struct Cli {
    /// Serial port of the device (e.g. /dev/ttyACM0). Also from KERFMETER_PORT.
    #[arg(long, global = true, env = "KERFMETER_PORT", conflicts_with = "sim")]
    port: Option<String>,
    /// Talk to the simulated device (the digital twin) instead of hardware.
    #[arg(long, global = true)]
    sim: bool,
    /// Seed of the simulated device.
    #[arg(long, global = true, default_value_t = 1, requires = "sim")]
    sim_seed: u64,
    /// Print machine-readable JSON instead of text.
    #[arg(long, global = true)]
    json: bool,
    /// Per-attempt response timeout, ms.
    #[arg(long, global = true, default_value_t = 300, value_parser = clap::value_parser!(u64).range(10..=60_000))]
    timeout_ms: u64,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the device's protocol and firmware versions, boot id and hardware constants.
    Info,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if cli.json {
                println!("{}", serde_json::json!({ "error": e.to_string() }));
            } else {
                eprintln!("error: {e}");
            }
            ExitCode::from(exit_code(&e))
        }
    }
}

fn exit_code(e: &CliError) -> u8 {
    match e {
        CliError::Usage(_) => EXIT_USAGE,
        CliError::Meter(e) if e.is_communication() => EXIT_COMMUNICATION,
        CliError::Meter(Error::Sim(_)) => EXIT_COMMUNICATION,
        CliError::Meter(_) => EXIT_DEVICE,
    }
}

#[derive(Debug, thiserror::Error)]
enum CliError {
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Meter(#[from] Error),
}

/// The connection: a real port, or the twin (kept alive as long as the client).
struct Session {
    meter: Kerfmeter,
    #[cfg(feature = "sim")]
    _sim: Option<kerfmeter::sim::SimDevice>,
}

fn connect(cli: &Cli) -> Result<Session, CliError> {
    let options = Options {
        timeout: Duration::from_millis(cli.timeout_ms),
        ..Options::default()
    };
    if cli.sim {
        #[cfg(feature = "sim")]
        {
            let sim_options = kerfmeter::sim::SimOptions { seed: cli.sim_seed };
            let (sim, meter) = kerfmeter::sim::SimDevice::connect(sim_options, options)?;
            return Ok(Session {
                meter,
                _sim: Some(sim),
            });
        }
        #[cfg(not(feature = "sim"))]
        return Err(CliError::Usage(
            "this build has no simulator (feature `sim`)".into(),
        ));
    }
    let Some(path) = &cli.port else {
        return Err(CliError::Usage(
            "no device given: pass --port PATH (or set KERFMETER_PORT), or --sim for the simulated device".into(),
        ));
    };
    Ok(Session {
        meter: Kerfmeter::open_with(path, options)?,
        #[cfg(feature = "sim")]
        _sim: None,
    })
}

fn run(cli: &Cli) -> Result<(), CliError> {
    let mut session = connect(cli)?;
    match cli.command {
        Command::Info => {
            let info = session.meter.info()?;
            if cli.json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&info).expect("info serializes")
                );
            } else {
                let h = &info.hardware;
                println!("port:       {}", session.meter.path());
                println!("board:      {}", h.board);
                println!(
                    "firmware:   {}.{}.{}",
                    info.firmware.major, info.firmware.minor, info.firmware.patch
                );
                println!(
                    "protocol:   {}.{}",
                    info.protocol.major, info.protocol.minor
                );
                println!("boot id:    {:08x}", info.boot_id);
                println!("control:    {} Hz", h.control_rate_hz);
                println!("encoder:    {} bit", h.encoder_bits);
                println!("pwm:        {} bit", h.pwm_bits);
                println!("sample log: {} samples", h.max_samples);
            }
        }
    }
    Ok(())
}
