//! `kerfmeter-twin`: the digital twin served on a pseudo-terminal, for any program that talks to a
//! Kerfmeter over a serial port (the `kerfmeter` CLI with `--port`, cutter-integration code, a
//! serial monitor). Prints the port's path, then serves until interrupted (Ctrl-C).

use std::io::Write;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use clap::Parser;
use kerfmeter::sim::SimFault;
use kerfmeter_twin::{Pace, Twin, TwinOptions, serve_twin};
use serialport::{SerialPort, TTYPort};

#[derive(Parser)]
#[command(
    name = "kerfmeter-twin",
    version,
    about = "Serve a simulated Kerfmeter on a pseudo-terminal"
)]
struct Args {
    /// True kerf of the simulated gauges, µm.
    #[arg(long, default_value_t = 150.0)]
    kerf_um: f64,
    /// Gauge-to-gauge spread (SD) of the simulated cutter's kerf, µm.
    #[arg(long, default_value_t = 0.0)]
    kerf_sd_um: f64,
    /// Seed of every random number.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Inject a fault (parity, magnet-lost, miso-stuck, no-inset, motor-disconnected,
    /// driver-fault, over-current, host-silent, prong-slip).
    #[arg(long, value_name = "NAME")]
    fault: Option<SimFault>,
    /// Follow the wall clock (default: run ahead of the host in lock-step, much faster).
    #[arg(long)]
    realtime: bool,
}

fn main() -> std::process::ExitCode {
    let args = Args::parse();
    let options = kerfmeter::sim::SimOptions {
        kerf_um: args.kerf_um,
        kerf_sd_um: args.kerf_sd_um,
        seed: args.seed,
        fault: args.fault,
        realtime: args.realtime,
    };
    if let Err(e) = options.validate() {
        eprintln!("error: {e}");
        return std::process::ExitCode::from(2);
    }
    let (mut master, slave) = match TTYPort::pair() {
        Ok(pair) => pair,
        Err(e) => {
            eprintln!("error: cannot open a pseudo-terminal: {e}");
            return std::process::ExitCode::from(3);
        }
    };
    // This process keeps the slave end open (without locking it: `pair` takes no lock, and a
    // client opening the path takes its own) so that the terminal survives clients coming and
    // going.
    if let Err(e) = master.set_timeout(Duration::from_millis(1)) {
        eprintln!("error: cannot set up the pseudo-terminal: {e}");
        return std::process::ExitCode::from(3);
    }
    let path = slave.name().unwrap_or_else(|| "<pty>".into());
    println!("{path}");
    eprintln!(
        "kerfmeter twin on {path}: kerf {} µm, seed {}{}{}. Try: kerfmeter --port {path} info   (Ctrl-C stops)",
        args.kerf_um,
        args.seed,
        args.fault
            .map(|f| format!(", fault {f}"))
            .unwrap_or_default(),
        if args.realtime { ", real time" } else { "" }
    );
    let _ = std::io::stdout().flush();
    let mut twin = Twin::new(TwinOptions {
        kerf_um: args.kerf_um,
        kerf_sd_um: args.kerf_sd_um,
        seed: args.seed,
        fault: args.fault,
        ..TwinOptions::default()
    });
    let pace = if args.realtime {
        Pace::RealTime
    } else {
        Pace::LockStep
    };
    let stop = AtomicBool::new(false);
    match serve_twin(&mut master, &mut twin, &stop, pace) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::from(3)
        }
    }
}
