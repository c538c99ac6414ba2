//! `kerfmeter-cli`: the `kerfmeter` command-line tool. Drive a Kerfmeter (or its simulated twin)
//! from a terminal or a script, draw the gauge, dilate plans. `kerfmeter --help` lists the
//! commands; `--json` makes every command print one JSON object on stdout for scripts.
//!
//! This package holds what only a terminal needs: the arguments (clap), progress bars, plots
//! ([`plot`]) and the reports; the work is done by the `kerfmeter` library (device, statistics, bed
//! map, twin) and `kerfmeter-plan` (gauge drawing, dilation). The package's other binary,
//! `kerfmeter-twin`, serves the digital twin on a real serial port.
//!
//! Exit codes follow the error's category ([`exit_code`]): 0 success; 2 bad arguments;
//! 3 communication error (port, timeout, protocol, device restarted); 4 the device refused,
//! faulted, failed its self-test or could not finish, or a file could not be read or written.

use std::io::{BufRead, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use kerfmeter::protocol::{
    DeviceConfig, EncoderPlacement, GaugeGeometry, KerfResult, QualityFlags, SelfTestItem,
    TestOutcome,
};
use kerfmeter::{Category, Error, JointSpec, Kerfmeter, Options, Progress};
use kerfmeter_plan::PlanError;
use serde_json::json;

mod plan;
mod plot;

/// `println!` that ends the program quietly when stdout is closed (`kerfmeter … | head`).
macro_rules! out {
    () => { out!("") };
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        if writeln!(std::io::stdout().lock(), $($arg)*).is_err() {
            // The reader went away: there is no one left to tell anything.
            std::process::exit(0);
        }
    }};
}

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
    about = "Measure a laser cutter's kerf with a Kerfmeter, and use it",
    after_help = "Without --port or --sim, the device is found by its USB ids (303a:1001).\nExamples:\n  kerfmeter --sim run --samples 3\n  kerfmeter --port /dev/ttyACM0 run --thickness-mm 3 --plot curve.png"
)]
struct Cli {
    #[command(flatten)]
    global: Global,
    #[command(subcommand)]
    command: Command,
}

#[derive(Args)]
struct Global {
    /// Serial port of the device (e.g. /dev/ttyACM0). Also from KERFMETER_PORT.
    #[arg(long, global = true, env = "KERFMETER_PORT", conflicts_with = "sim")]
    port: Option<String>,
    /// Use the simulated device (the digital twin) instead of hardware.
    #[arg(long, global = true)]
    sim: bool,
    /// Simulated device: true kerf of the cut gauges, µm.
    #[arg(long, global = true, default_value_t = 150.0, value_name = "UM")]
    sim_kerf_um: f64,
    /// Simulated device: gauge-to-gauge spread (SD) of the simulated cutter's kerf, µm.
    #[arg(long, global = true, default_value_t = 0.0, value_name = "UM")]
    sim_kerf_sd_um: f64,
    /// Simulated device: seed of every random number (same seed, same result).
    #[arg(long, global = true, default_value_t = 1)]
    sim_seed: u64,
    /// Simulated device: inject a fault (parity, magnet-lost, miso-stuck, no-inset,
    /// motor-disconnected, driver-fault, over-current, host-silent, prong-slip).
    #[arg(long, global = true, value_name = "NAME")]
    sim_fault: Option<kerfmeter::sim::SimFault>,
    /// Simulated device: run in real time instead of as fast as the host keeps up.
    #[arg(long, global = true)]
    sim_realtime: bool,
    /// Print one JSON object instead of text.
    #[arg(long, global = true)]
    json: bool,
    /// Per-attempt response timeout, ms.
    #[arg(long, global = true, default_value_t = 300, value_parser = clap::value_parser!(u64).range(10..=60_000))]
    timeout_ms: u64,
}

#[derive(Subcommand)]
enum Command {
    /// Print the device's protocol and firmware versions, boot id and hardware constants.
    Info,
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
    /// Check the encoder, magnet, drive direction and torque constant (no gauge under the prongs).
    SelfTest,
    /// Read or change the device configuration (stored in its flash).
    #[command(subcommand)]
    Config(ConfigCommand),
    /// Measure a grid of gauges across the bed and save a location-compensation map (JSON).
    Map(MapArgs),
    /// Draw the spiral gauge to cut before a measurement (SVG or DXF by extension).
    Gauge(plan::GaugeArgs),
    /// Dilate a cutting plan (SVG or DXF) by the measured kerf: cuts grow by half the kerf on
    /// each side, so parts come out at their drawn size.
    Dilate(plan::DilateArgs),
}

#[derive(Args)]
struct RunArgs {
    /// Sheet thickness, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_THICKNESS_MM)]
    thickness_mm: f64,
    /// Assembly force of the joint, N (default: 18.3 N per finger, the paper's fit-window centre).
    #[arg(long)]
    force_n: Option<f64>,
    /// Fingers in the joint.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_FINGERS)]
    fingers: u32,
    /// Length of each finger's pressed face, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_FINGER_LENGTH_MM)]
    finger_length_mm: f64,
    /// Gauges to measure (a fresh gauge for each).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=50))]
    samples: u32,
    /// Draw the last run's torque–angle curve into this .png or .svg file.
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Do not ask before each gauge (hardware only; the simulator never asks).
    #[arg(long, short = 'y')]
    yes: bool,
    /// Also read the kerf at these other assembly forces (N) off the last run's curve.
    #[arg(long, value_name = "N", value_delimiter = ',')]
    also_at_force_n: Vec<f32>,
}

#[derive(Subcommand)]
enum ConfigCommand {
    /// Print the configuration and whether it is the default.
    Get,
    /// Change some values; the others stay as they are.
    Set(ConfigSet),
}

#[derive(Args)]
struct ConfigSet {
    /// Output torque at full duty and standstill, N·m.
    #[arg(long)]
    torque_per_duty_nm: Option<f32>,
    /// Duty (0–0.5) below which the gearbox does not move.
    #[arg(long)]
    breakaway_duty: Option<f32>,
    /// Raw encoder reading (0–16383) at the hub's zero position.
    #[arg(long)]
    encoder_zero_raw: Option<u16>,
    /// Encoder magnet on the output shaft (hub) or the motor shaft.
    #[arg(long, value_parser = ["output", "motor"])]
    encoder_on: Option<String>,
    /// Gearbox ratio.
    #[arg(long)]
    gear_ratio: Option<f32>,
    /// Motor wired the other way round.
    #[arg(long)]
    motor_inverted: Option<bool>,
    /// Encoder counting the other way round.
    #[arg(long)]
    encoder_inverted: Option<bool>,
    /// Over-current trip, A.
    #[arg(long)]
    max_current_a: Option<f32>,
    /// Output torque per motor amp, N·m/A.
    #[arg(long)]
    torque_per_amp_nm: Option<f32>,
}

#[derive(Args)]
struct MapArgs {
    /// Where to save the map (JSON).
    #[arg(long, short = 'o', default_value = "kerf-map.json")]
    output: PathBuf,
    /// Bed width (x), mm.
    #[arg(long, default_value_t = 600.0)]
    bed_width_mm: f64,
    /// Bed depth (y), mm.
    #[arg(long, default_value_t = 400.0)]
    bed_depth_mm: f64,
    /// Grid columns along x.
    #[arg(long, default_value_t = 4)]
    cols: usize,
    /// Grid rows along y.
    #[arg(long, default_value_t = 3)]
    rows: usize,
    /// Measurements per cell.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=20))]
    per_cell: u32,
    /// Reference cell column.
    #[arg(long, default_value_t = 0)]
    reference_col: usize,
    /// Reference cell row.
    #[arg(long, default_value_t = 0)]
    reference_row: usize,
    /// Sheet thickness, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_THICKNESS_MM)]
    thickness_mm: f64,
    /// Simulated device only: how much the simulated bed's kerf grows from one corner to the
    /// opposite one, µm.
    #[arg(long, default_value_t = 20.0, value_name = "UM")]
    sim_bed_variation_um: f64,
    /// Do not ask before each cell (hardware only).
    #[arg(long, short = 'y')]
    yes: bool,
}

/// Why a command failed.
#[derive(Debug, thiserror::Error)]
enum CliError {
    /// The arguments do not fit together.
    #[error("{0}")]
    Usage(String),
    /// The library (device, map, files) failed.
    #[error(transparent)]
    Meter(#[from] Error),
    /// A cutting plan could not be drawn, read or dilated.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The device ran its self-test and an item failed.
    #[error("the self-test failed; see the items above")]
    SelfTestFailed,
}

impl CliError {
    /// What kind of failure this is.
    fn category(&self) -> Category {
        match self {
            CliError::Usage(_) => Category::Usage,
            CliError::Meter(e) => e.category(),
            // A plan error about a file is the file's; any other is about the arguments.
            CliError::Plan(e) if e.path().is_some() => Category::File,
            CliError::Plan(_) => Category::Usage,
            CliError::SelfTestFailed => Category::Device,
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if cli.global.json {
                let fault = match &e {
                    CliError::Meter(m) => m.fault().map(|f| format!("{f:?}")),
                    CliError::Usage(_) | CliError::Plan(_) | CliError::SelfTestFailed => None,
                };
                out!("{}", json!({ "error": e.to_string(), "fault": fault }));
            } else {
                eprintln!("error: {e}");
            }
            ExitCode::from(exit_code(&e))
        }
    }
}

/// The process's exit code for an error: from its category, and from nothing else.
fn exit_code(e: &CliError) -> u8 {
    match e.category() {
        Category::Usage => EXIT_USAGE,
        Category::Communication => EXIT_COMMUNICATION,
        Category::Device | Category::File => EXIT_DEVICE,
    }
}

/// The connection: a real port, or the twin (kept alive as long as the client).
struct Session {
    meter: Kerfmeter,
    sim: Option<kerfmeter::sim::SimDevice>,
}

fn client_options(g: &Global) -> Options {
    Options {
        timeout: Duration::from_millis(g.timeout_ms),
        ..Options::default()
    }
}

fn sim_options(g: &Global, kerf_um: f64, seed: u64) -> kerfmeter::sim::SimOptions {
    kerfmeter::sim::SimOptions {
        kerf_um,
        kerf_sd_um: g.sim_kerf_sd_um,
        seed,
        fault: g.sim_fault,
        realtime: g.sim_realtime,
        ..kerfmeter::sim::SimOptions::default()
    }
}

fn connect(g: &Global) -> Result<Session, CliError> {
    if g.sim {
        let (sim, meter) = kerfmeter::sim::SimDevice::connect(
            sim_options(g, g.sim_kerf_um, g.sim_seed),
            client_options(g),
        )?;
        return Ok(Session {
            meter,
            sim: Some(sim),
        });
    }
    if g.sim_fault.is_some() || g.sim_realtime {
        return Err(CliError::Usage(
            "--sim-fault and --sim-realtime need --sim".into(),
        ));
    }
    let meter = match &g.port {
        Some(path) => Kerfmeter::open_with(path, client_options(g))?,
        None => Kerfmeter::discover(client_options(g))?,
    };
    Ok(Session { meter, sim: None })
}

fn run(cli: &Cli) -> Result<(), CliError> {
    let g = &cli.global;
    match &cli.command {
        Command::Info => info(g),
        Command::Run(args) => measure(g, args),
        Command::Kerf => {
            let mut s = connect(g)?;
            let result = s.meter.get_kerf_value()?;
            if g.json {
                out!(
                    "{}",
                    json!({ "kerf_um": result.map(|r| r.kerf_um), "result": result })
                );
            } else {
                match result {
                    Some(r) => print_results(&[r]),
                    None => out!("no result: the device has not measured since its last reset"),
                }
            }
            Ok(())
        }
        Command::Reset => simple(g, "reset: the hub is at zero", |m| m.reset_kerfmeter()),
        Command::Abort => simple(g, "aborted: the motor is stopped", |m| m.abort()),
        Command::ClearFault => simple(g, "fault cleared", |m| m.clear_fault()),
        Command::SelfTest => self_test(g),
        Command::Config(c) => config(g, c),
        Command::Map(args) => map(g, args),
        Command::Gauge(args) => print_report(g, &plan::run_gauge(args)?),
        Command::Dilate(args) => print_report(g, &plan::run_dilate(args)?),
    }
}

/// Print a report as JSON (`--json`) or as its text.
fn print_report(
    g: &Global,
    report: &(impl serde::Serialize + std::fmt::Display),
) -> Result<(), CliError> {
    if g.json {
        out!(
            "{}",
            serde_json::to_string_pretty(report).expect("reports serialize")
        );
    } else {
        out!("{report}");
    }
    Ok(())
}

fn simple(
    g: &Global,
    done: &str,
    f: impl FnOnce(&mut Kerfmeter) -> kerfmeter::Result<()>,
) -> Result<(), CliError> {
    let mut s = connect(g)?;
    f(&mut s.meter)?;
    if g.json {
        out!("{}", json!({ "ok": true }));
    } else {
        out!("{done}");
    }
    Ok(())
}

fn info(g: &Global) -> Result<(), CliError> {
    let mut s = connect(g)?;
    let info = s.meter.info()?;
    if g.json {
        out!(
            "{}",
            serde_json::to_string_pretty(&info).expect("info serializes")
        );
    } else {
        let h = &info.hardware;
        out!("port:       {}", s.meter.path());
        out!("board:      {}", h.board);
        out!(
            "firmware:   {}.{}.{}",
            info.firmware.major,
            info.firmware.minor,
            info.firmware.patch
        );
        out!(
            "protocol:   {}.{}",
            info.protocol.major,
            info.protocol.minor
        );
        out!("boot id:    {:08x}", info.boot_id);
        out!("control:    {} Hz", h.control_rate_hz);
        out!("encoder:    {} bit", h.encoder_bits);
        out!("pwm:        {} bit", h.pwm_bits);
        out!("sample log: {} samples", h.max_samples);
    }
    Ok(())
}

fn progress_bar(g: &Global, label: &str) -> ProgressBar {
    if g.json {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {prefix} {msg}").expect("valid template"),
    );
    bar.set_prefix(label.to_owned());
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

fn show(bar: &ProgressBar, p: &Progress) {
    bar.set_message(format!(
        "{:<10} torque {:6.3} N·m   angle {:7.2}°   {:5.2} s",
        format!("{:?}", p.state),
        p.torque_nm,
        p.angle_deg,
        f64::from(p.elapsed_ms) / 1000.0
    ));
}

/// Ask the person at the cutter to do something (hardware only, interactive only).
fn ask(g: &Global, yes: bool, sim: bool, what: &str) -> Result<(), CliError> {
    if sim || yes || g.json || !std::io::stdin().is_terminal() {
        return Ok(());
    }
    eprint!("{what}, then press Enter (Ctrl-C to stop) ");
    std::io::stderr().flush().ok();
    let mut line = String::new();
    std::io::stdin()
        .lock()
        .read_line(&mut line)
        .map_err(|e| CliError::Usage(format!("cannot read the answer: {e}")))?;
    Ok(())
}

/// Prepare for a run (reset to zero if needed), then one run with a progress bar.
fn one_run(
    g: &Global,
    meter: &mut Kerfmeter,
    params: &kerfmeter::protocol::RunParams,
    label: &str,
) -> Result<KerfResult, CliError> {
    meter.prepare_for_run()?;
    let bar = progress_bar(g, label);
    let result = meter.run_kerfmeter(params, |p| show(&bar, p));
    bar.finish_and_clear();
    Ok(result?)
}

fn measure(g: &Global, args: &RunArgs) -> Result<(), CliError> {
    let joint = JointSpec {
        thickness_mm: args.thickness_mm,
        fingers: args.fingers,
        finger_length_mm: args.finger_length_mm,
        force_n: args.force_n,
    };
    let params = joint.run_params(GaugeGeometry::PAPER)?;
    if let Some(plot) = &args.plot {
        plot::PlotFormat::for_path(plot)?;
    }
    let mut s = connect(g)?;
    let sim = s.sim.is_some();
    let samples = args.samples as usize;
    let bar = progress_bar(g, "gauge 1");
    let measured = s.meter.measure(
        &params,
        samples,
        |i| {
            bar.suspend(|| {
                ask(
                    g,
                    args.yes,
                    sim,
                    &format!("Place gauge {} of {samples} under the prongs", i + 1),
                )
            })
            .map_err(|e| Error::InvalidArgument(e.to_string()))?;
            bar.set_prefix(format!("gauge {}/{samples}", i + 1));
            Ok(())
        },
        |_, p| show(&bar, p),
    );
    bar.finish_and_clear();
    let kerfmeter::Measurement {
        runs: results,
        summary,
    } = measured?;
    let kerfs: Vec<f64> = results.iter().map(|r| f64::from(r.kerf_um)).collect();
    let curve = if args.plot.is_some() || !args.also_at_force_n.is_empty() {
        Some(s.meter.curve()?)
    } else {
        None
    };
    if let (Some(path), Some(curve)) = (&args.plot, &curve) {
        plot::plot_curve(curve, results.last(), path)?;
    }
    let at_forces: Vec<(f32, Option<f32>)> = match &curve {
        Some(c) => args
            .also_at_force_n
            .iter()
            .map(|&f| (f, c.kerf_at_force_um(&params, f)))
            .collect(),
        None => Vec::new(),
    };
    if g.json {
        out!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "kerf_um": summary.mean_um,
                "summary": summary,
                "runs": results,
                "force_n": params.target_force_n,
                "thickness_mm": params.thickness_mm,
                "simulated": sim,
                "plot": args.plot,
                "kerf_at_force_um": at_forces.iter().map(|(f, k)| json!({ "force_n": f, "kerf_um": k })).collect::<Vec<_>>(),
            }))
            .expect("results serialize")
        );
    } else {
        print_results(&results);
        out!();
        match summary.ci95_um {
            Some(ci) => out!(
                "kerf {:.1} µm ± {:.1} µm (95 % CI, n = {}, SD {:.1} µm) at {:.1} N",
                summary.mean_um,
                ci,
                summary.n,
                summary.sd_um,
                params.target_force_n
            ),
            None => out!(
                "kerf {:.1} µm at {:.1} N",
                summary.mean_um,
                params.target_force_n
            ),
        }
        for (force, kerf) in &at_forces {
            match kerf {
                Some(k) => out!("  at {force:.1} N (from the last run's curve): {k:.1} µm"),
                None => out!("  at {force:.1} N: beyond the force the last run reached"),
            }
        }
        for &i in &summary.outliers {
            out!(
                "warning: run {} ({:.1} µm) is an outlier; check that gauge",
                i + 1,
                kerfs[i]
            );
        }
        if let Some(path) = &args.plot {
            out!("curve: {}", path.display());
        }
        if let (Some(sim), Some(last)) = (&s.sim, results.last()) {
            out!(
                "(simulated device: gauges cut with {:.1} µm{}; at the applied force the spiral contact compresses, so an ideal device reads {:.1} µm)",
                g.sim_kerf_um,
                if g.sim_kerf_sd_um > 0.0 {
                    format!(" ± {:.1} µm SD", g.sim_kerf_sd_um)
                } else {
                    String::new()
                },
                sim.ideal_reading_um(last.torque_at_jam_nm)
            );
        }
    }
    Ok(())
}

fn flags_text(flags: QualityFlags) -> String {
    let names: Vec<&str> = flags.names().collect();
    if names.is_empty() {
        "ok".into()
    } else {
        names.join(",")
    }
}

fn print_results(results: &[KerfResult]) {
    out!(
        "{:>4} {:>10} {:>10} {:>9} {:>11} {:>9}  flags",
        "run",
        "kerf µm",
        "angle °",
        "play °",
        "torque N·m",
        "force N"
    );
    for r in results {
        out!(
            "{:>4} {:>10.1} {:>10.2} {:>9.2} {:>11.3} {:>9.1}  {}",
            r.run_id,
            r.kerf_um,
            r.angle_deg,
            r.play_deg,
            r.torque_at_jam_nm,
            r.force_at_jam_n,
            flags_text(r.flags)
        );
    }
}

fn self_test(g: &Global) -> Result<(), CliError> {
    let mut s = connect(g)?;
    let bar = progress_bar(g, "self-test");
    let report = s.meter.self_test(|p| show(&bar, p));
    bar.finish_and_clear();
    let report = report?;
    let items = [
        ("encoder reads ok", report.encoder_ok_fraction, ""),
        ("magnet magnitude", report.magnet_magnitude, ""),
        ("direction", report.direction_deg, "°"),
        ("torque constant", report.torque_per_duty_nm, " N·m"),
    ];
    let passed = items.iter().all(|(_, i, _)| i.outcome == TestOutcome::Pass);
    if g.json {
        out!("{}", json!({ "passed": passed, "report": report }));
    } else {
        for (name, SelfTestItem { outcome, value }, unit) in items {
            out!("{name:<18} {:<8} {value:.3}{unit}", format!("{outcome:?}"));
        }
        out!(
            "{}",
            if passed {
                "self-test passed"
            } else {
                "self-test FAILED"
            }
        );
    }
    if passed {
        Ok(())
    } else {
        Err(CliError::SelfTestFailed)
    }
}

fn config(g: &Global, c: &ConfigCommand) -> Result<(), CliError> {
    let mut s = connect(g)?;
    let report = match c {
        ConfigCommand::Get => s.meter.config()?,
        ConfigCommand::Set(set) => {
            let mut config: DeviceConfig = s.meter.config()?.config;
            macro_rules! apply {
                ($($field:ident),*) => { $( if let Some(v) = set.$field { config.$field = v; } )* };
            }
            apply!(
                torque_per_duty_nm,
                breakaway_duty,
                encoder_zero_raw,
                gear_ratio,
                motor_inverted,
                encoder_inverted,
                max_current_a,
                torque_per_amp_nm
            );
            if let Some(on) = &set.encoder_on {
                config.encoder_placement = if on == "motor" {
                    EncoderPlacement::MotorShaft
                } else {
                    EncoderPlacement::OutputShaft
                };
            }
            s.meter.set_config(&config)?
        }
    };
    if g.json {
        out!(
            "{}",
            serde_json::to_string_pretty(&report).expect("config serializes")
        );
    } else {
        let c = &report.config;
        out!("torque_per_duty_nm  {}", c.torque_per_duty_nm);
        out!("breakaway_duty      {}", c.breakaway_duty);
        out!("encoder_zero_raw    {}", c.encoder_zero_raw);
        out!(
            "encoder_on          {}",
            if c.encoder_placement == EncoderPlacement::MotorShaft {
                "motor"
            } else {
                "output"
            }
        );
        out!("gear_ratio          {}", c.gear_ratio);
        out!("motor_inverted      {}", c.motor_inverted);
        out!("encoder_inverted    {}", c.encoder_inverted);
        out!("max_current_a       {}", c.max_current_a);
        out!("torque_per_amp_nm   {}", c.torque_per_amp_nm);
        if report.defaults_in_use {
            out!("(defaults: no valid configuration is stored on the device)");
        }
    }
    Ok(())
}

fn map(g: &Global, args: &MapArgs) -> Result<(), CliError> {
    use kerfmeter::map::{Grid, KerfMap};
    let grid = Grid::new(args.bed_width_mm, args.bed_depth_mm, args.cols, args.rows)?;
    if args.reference_col >= args.cols || args.reference_row >= args.rows {
        return Err(CliError::Usage(format!(
            "the reference cell ({}, {}) is outside the {} × {} grid",
            args.reference_col, args.reference_row, args.cols, args.rows
        )));
    }
    let joint = JointSpec {
        thickness_mm: args.thickness_mm,
        ..JointSpec::default()
    };
    let params = joint.run_params(GaugeGeometry::PAPER)?;
    let mut hardware = if g.sim { None } else { Some(connect(g)?) };
    let mut runs = Vec::new();
    for row in 0..args.rows {
        for col in 0..args.cols {
            let (x, y) = grid.centre_mm(col, row);
            // The simulated bed: its kerf grows linearly from one corner to the opposite one.
            let mut sim_session;
            let session = match &mut hardware {
                Some(s) => s,
                None => {
                    let across = (x / args.bed_width_mm + y / args.bed_depth_mm) / 2.0;
                    let kerf = g.sim_kerf_um + args.sim_bed_variation_um * (across - 0.5);
                    let seed = g
                        .sim_seed
                        .wrapping_add((row * args.cols + col) as u64 * 7919);
                    let (sim, meter) = kerfmeter::sim::SimDevice::connect(
                        sim_options(g, kerf, seed),
                        client_options(g),
                    )?;
                    sim_session = Session {
                        meter,
                        sim: Some(sim),
                    };
                    &mut sim_session
                }
            };
            let mut cell = Vec::new();
            for i in 0..args.per_cell {
                ask(
                    g,
                    args.yes,
                    g.sim,
                    &format!(
                        "Cut and place gauge {} of {} at cell ({col}, {row}), x {x:.0} mm y {y:.0} mm",
                        i + 1,
                        args.per_cell
                    ),
                )?;
                if i > 0 {
                    session.meter.reset_kerfmeter()?;
                }
                let label = format!("cell ({col},{row}) {}/{}", i + 1, args.per_cell);
                cell.push(f64::from(
                    one_run(g, &mut session.meter, &params, &label)?.kerf_um,
                ));
            }
            runs.push(cell);
        }
    }
    let map = KerfMap::from_runs(grid, (args.reference_col, args.reference_row), runs)?;
    map.save(&args.output)?;
    if g.json {
        out!(
            "{}",
            json!({ "map": args.output, "reference_kerf_um": map.reference_kerf_um, "cells": map.cells })
        );
    } else {
        out!(
            "compensation (µm) relative to cell ({}, {}) = {:.1} µm:",
            args.reference_col,
            args.reference_row,
            map.reference_kerf_um
        );
        for row in 0..args.rows {
            let line: Vec<String> = (0..args.cols)
                .map(|col| format!("{:+7.1}", map.cells[row * args.cols + col].compensation_um))
                .collect();
            out!("  row {row}: {}", line.join(" "));
        }
        out!("saved {}", args.output.display());
    }
    Ok(())
}
