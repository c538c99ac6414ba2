//! `kerfmeter-twin`: the digital twin served on a pseudo-terminal, for any program that talks to a
//! Kerfmeter over a serial port (the `kerfmeter` CLI with `--port`, cutter-integration code, a
//! serial monitor). Prints the port's path, then serves until interrupted (Ctrl-C).
//!
//! With `--cutter` it serves the cutter twin instead, a simulated GRBL 1.1 laser cutter, on a
//! pseudo-terminal (`kerfmeter cut FILE --cutter grbl:PATH`, or any G-code sender) or, with
//! `--tcp PORT`, on a loopback TCP port (`--cutter grbl+tcp://127.0.0.1:PORT`).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use kerfmeter::grbl::twin::{CutterLog, CutterOptions, CutterServer};
use kerfmeter::protocol::G2Variant;
use kerfmeter_twin::plant::{Material, PlantParams, param_list};
use kerfmeter_twin::{InjectedFault, MotorEdge, Pace, PtyTwin, StartError, TwinOptions};

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
    fault: Option<InjectedFault>,
    /// Follow the wall clock (default: run ahead of the host in lock-step, much faster).
    #[arg(long)]
    realtime: bool,
    /// The encoder on the motor shaft, so configured in the twin's flash: from power-up it
    /// refuses runs until `kerfmeter confirm-zero` (its hub stands at its mark).
    #[arg(long)]
    encoder_on_motor_shaft: bool,
    /// A chip without ADC calibration eFuses: its current sense reads 35 % high, and it reports
    /// `adc-uncalibrated`.
    #[arg(long)]
    adc_uncalibrated: bool,
    /// The Pololu G2 variant the device is built with (18v17, 24v13, 24v21): its current-sense
    /// gain and the highest supply it accepts.
    #[arg(long, value_name = "VARIANT", default_value = "18v17")]
    driver: G2Variant,
    /// The gauge's material (mdf, plywood, acrylic, cardboard): the contact's stiffness and
    /// friction and their spread.
    #[arg(long, visible_alias = "sim-material", value_name = "NAME")]
    material: Option<Material>,
    /// Plant parameters from a JSON object of numbers, applied over the material.
    #[arg(long, visible_alias = "sim-plant-file", value_name = "FILE")]
    plant_file: Option<PathBuf>,
    /// Set one plant parameter, applied last (repeatable), e.g. supply_v=24.
    #[arg(long, visible_alias = "sim-plant", value_name = "NAME=VALUE")]
    plant: Vec<String>,
    /// List every plant parameter with its range, default and meaning, and exit.
    #[arg(long)]
    list_plant: bool,
    /// Serve the cutter twin (a simulated GRBL 1.1 laser cutter) instead of the device.
    #[arg(long, conflicts_with_all = ["fault", "material", "plant_file", "plant", "list_plant"])]
    cutter: bool,
    /// Cutter twin: serve on this loopback TCP port (0: any free one) instead of a
    /// pseudo-terminal.
    #[arg(long, value_name = "PORT", requires = "cutter")]
    tcp: Option<u16>,
    /// Cutter twin: boot in alarm, as a machine with homing enabled does.
    #[arg(long, requires = "cutter")]
    cutter_alarm: bool,
    /// Cutter twin: without laser mode ($32=0), a spindle machine that fires on travels.
    #[arg(long, requires = "cutter")]
    cutter_no_laser_mode: bool,
    /// Cutter twin on TCP: greet no client with the banner (many networked controllers say
    /// nothing until spoken to).
    #[arg(long, requires = "tcp")]
    cutter_no_greeting: bool,
    /// Cutter twin: answer the Nth G-code line since boot (1 = the first) with GRBL's
    /// `error:20` (unsupported command), as a controller refusing a line mid-job does.
    #[arg(long, value_name = "N", requires = "cutter", value_parser = clap::value_parser!(u32).range(1..))]
    cutter_error_on_line: Option<u32>,
    /// Cutter twin: its travel, mm ($130–$132, and where its end stops are) [default:
    /// 600,400,50].
    #[arg(long, value_name = "X,Y,Z", requires = "cutter", value_parser = parse_xyz)]
    cutter_travel_mm: Option<[f64; 3]>,
    /// Cutter twin: homing enabled ($22=1): it boots in alarm (`$H` homes it, `$X` unlocks it)
    /// and its machine space runs from −travel to 0.
    #[arg(long, requires = "cutter")]
    cutter_homing: bool,
    /// Cutter twin: soft limits on ($20=1; needs --cutter-homing, as GRBL does): a target
    /// beyond the travel is ALARM:2 before it moves.
    #[arg(long, requires = "cutter_homing")]
    cutter_soft_limits: bool,
    /// Cutter twin: its G54 work offset, mm (work = machine − offset).
    #[arg(long, value_name = "X,Y,Z", requires = "cutter", allow_hyphen_values = true, value_parser = parse_xyz)]
    cutter_work_offset_mm: Option<[f64; 3]>,
    /// Cutter twin: print every G-code line it receives on stdout (`received: G0 X10`), and
    /// every move that runs into an end stop (`end stop: line 12, X 50.000 mm beyond`), for a
    /// test in another process.
    #[arg(long, requires = "cutter")]
    cutter_print_lines: bool,
    /// Print a line on stdout whenever the motor bridge enters its safe state (duty 0, driver
    /// asleep) or leaves it: `motor safe at 1234.000 ms` / `motor unsafe at …` (simulated time
    /// since boot). What a scope on the G2's pins would show, for a test in another process.
    #[arg(long, conflicts_with = "cutter")]
    log_motor: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    if args.list_plant {
        print!("{}", param_list());
        return ExitCode::SUCCESS;
    }
    if args.cutter {
        return serve_cutter(&args);
    }
    let plant = match PlantParams::build(args.material, args.plant_file.as_deref(), &args.plant) {
        Ok(plant) => plant,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let options = TwinOptions {
        kerf_um: args.kerf_um,
        kerf_sd_um: args.kerf_sd_um,
        seed: args.seed,
        fault: args.fault,
        realtime: args.realtime,
        plant,
        encoder_on_motor_shaft: args.encoder_on_motor_shaft,
        adc_uncalibrated: args.adc_uncalibrated,
        driver: args.driver,
        ..TwinOptions::default()
    };
    // This process keeps the client side open (without locking it: the pair takes no lock, and a
    // client opening the path takes its own) so that the terminal survives clients coming and
    // going.
    let (edges, watched) = std::sync::mpsc::channel();
    let watch = args.log_motor.then_some(edges);
    let (twin, _client) = match PtyTwin::start_watched(options, watch) {
        Ok(started) => started,
        Err(e @ StartError::Options(_)) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(3);
        }
    };
    let path = twin.path().to_owned();
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
    // Ends when the twin does (its sender goes with it).
    std::thread::spawn(move || print_motor_edges(&watched));
    match twin.wait() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(3)
        }
    }
}

/// Print each motor edge as it comes, flushed at once (a test times its arrival).
fn print_motor_edges(edges: &std::sync::mpsc::Receiver<MotorEdge>) {
    for edge in edges {
        let what = if edge.safe { "safe" } else { "unsafe" };
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "motor {what} at {:.3} ms", edge.at_us as f64 / 1000.0);
        let _ = out.flush();
    }
}

/// Serve the cutter twin on a pseudo-terminal or a TCP port until interrupted.
fn serve_cutter(args: &Args) -> ExitCode {
    let defaults = CutterOptions::default();
    let options = CutterOptions {
        laser_mode: !args.cutter_no_laser_mode,
        boot_in_alarm: args.cutter_alarm,
        error_on_line: args.cutter_error_on_line.map(|line| (line, 20)),
        travel_mm: args.cutter_travel_mm.unwrap_or(defaults.travel_mm),
        homing: args.cutter_homing,
        soft_limits: args.cutter_soft_limits,
        work_offset_mm: args
            .cutter_work_offset_mm
            .unwrap_or(defaults.work_offset_mm),
        ..defaults
    };
    let pace = if args.realtime {
        Pace::RealTime
    } else {
        Pace::LockStep
    };
    // The pseudo-terminal's client side stays open here so that senders may come and go.
    let started = match args.tcp {
        Some(port) => CutterServer::tcp_greeting(options, pace, port, !args.cutter_no_greeting)
            .map(|server| (server, None)),
        None => CutterServer::pty(options, pace).map(|(server, client)| (server, Some(client))),
    };
    let (server, _client) = match started {
        Ok(started) => started,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(3);
        }
    };
    let address = server.address().to_owned();
    let url = match args.tcp {
        Some(_) => format!("grbl+tcp://{address}"),
        None => format!("grbl:{address}"),
    };
    println!("{url}");
    eprintln!(
        "kerfmeter cutter twin (GRBL 1.1) on {address}{}. Try: kerfmeter cut FILE.gcode --cutter {url}   (Ctrl-C stops)",
        if args.realtime { ", real time" } else { "" }
    );
    let _ = std::io::stdout().flush();
    if args.cutter_print_lines {
        let log = server.log().clone();
        std::thread::spawn(move || print_received(&log));
    }
    match server.wait() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(3)
        }
    }
}

/// Print each G-code line the cutter twin receives, and each end stop it hits, as they come
/// (polled; flushed at once for a test reading them).
fn print_received(log: &CutterLog) {
    let (mut lines, mut hits) = (0, 0);
    loop {
        let news: Vec<String> = {
            let record = log.lock();
            let received = record.gcode_received[lines..]
                .iter()
                .map(|l| format!("received: {l}"));
            let hit = |h: &kerfmeter::grbl::twin::EndStopHit| {
                let axis = ['X', 'Y', 'Z'][h.axis];
                format!(
                    "end stop: line {}, {axis} {:.3} mm beyond",
                    h.line, h.beyond_mm
                )
            };
            let stopped = record.end_stop_hits[hits..].iter().map(hit);
            let news = received.chain(stopped).collect();
            (lines, hits) = (record.gcode_received.len(), record.end_stop_hits.len());
            news
        };
        let mut out = std::io::stdout().lock();
        for line in news {
            let _ = writeln!(out, "{line}");
        }
        let _ = out.flush();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// `X,Y,Z` in mm.
fn parse_xyz(text: &str) -> Result<[f64; 3], String> {
    let numbers: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("{v:?}: {e}")))
        .collect::<Result<_, _>>()?;
    match numbers.as_slice() {
        [x, y, z] if numbers.iter().all(|v| v.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(format!("give three finite numbers X,Y,Z, got {text:?}")),
    }
}
