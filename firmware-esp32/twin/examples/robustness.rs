//! The robustness sweep (`cargo xtask robustness`): many twins with every plant parameter drawn
//! from its documented range, one measurement each, every ending classified
//! (`kerfmeter_twin::study::robustness` has the rules).
//!
//! Usage: `robustness [--draws N] [--seed S] [--set NAME=VALUE]... [--force-n F] [--json]
//! [--strict] [--tolerance-um T] [--threads N] [--worst N] [--out-dir DIR]
//! [--replay DRAW [--ablate]] [--seeds LIST] [--hang-s S]` (`--help` says what each does).
//!
//! Prints the success rate, the device-added error over the readings, every failure by its
//! typed fault or refusal, the unflagged wrong readings and the worst readings, each with the
//! commands that replay it; writes the plant parameters of each listed draw to
//! `DIR/seed<S>-draw<D>.json` (`--sim-plant-file`). `--replay D` runs draw D alone and prints
//! everything about it; with `--ablate` also what each plant parameter contributes to its error
//! (the draw run again with that parameter at its default).
//!
//! Exits 1 when a draw did not end in a reading or a typed fault or refusal, or left the motor
//! unsafe; with `--strict` also when a reading was wrong with no flag. 2 for bad arguments.
//!
//! A draw that never returns (a loop that simulated time cannot bound) is caught by a watchdog:
//! when no draw has finished for `--hang-s` seconds of wall time (default 600, far beyond any
//! draw's few milliseconds), it names the draws in progress and exits 1.

use std::collections::BTreeSet;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use clap::Parser;

use kerfmeter_protocol::RunParams;
use kerfmeter_twin::plant::{PARAMS, ParamSpec};
use kerfmeter_twin::study::robustness::{
    Class, Draw, DrawReport, ErrorStats, Scale, Summary, Sweep, TOLERANCE_UM, classify,
    failure_name, run_draw, scale,
};
use kerfmeter_twin::study::{Outcome, available_threads, parallel_map};
use serde_json::{Value, json};

#[path = "robustness/seeds.rs"]
mod seeds;

/// The robustness sweep: many twins with every plant parameter drawn from its range, one
/// measurement each, every ending classified (`cargo xtask robustness`).
#[derive(Parser)]
#[command(name = "robustness")]
struct Args {
    /// Draws (twins) to run.
    #[arg(long, default_value_t = 200)]
    draws: u32,
    /// Seed of the draws: the same seed gives the same draws on any number of threads.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Hold a plant parameter at one value in every draw instead of drawing it (repeatable):
    /// `--set supply_v=24` is the sweep on a 24 V rail. An unknown name lists the parameters
    /// and their ranges.
    #[arg(long = "set", value_name = "NAME=VALUE", value_parser = held_param)]
    held: Vec<(String, f64)>,
    /// The joint's assembly force each run measures at, N (`kerfmeter run --force-n`).
    #[arg(long, default_value_t = RunParams::DEFAULT.target_force_n)]
    force_n: f32,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Also exit 1 when a reading is wrong with no flag.
    #[arg(long)]
    strict: bool,
    /// A reading off by more than this with no flag is wrong, µm.
    #[arg(long, default_value_t = TOLERANCE_UM)]
    tolerance_um: f64,
    /// Worker threads (default: the cores available).
    #[arg(long, default_value_t = available_threads())]
    threads: usize,
    /// How many of the worst readings to list.
    #[arg(long, default_value_t = 5)]
    worst: usize,
    /// Where the plant files of the listed draws go (`--sim-plant-file`).
    #[arg(long, default_value = "target/robustness")]
    out_dir: PathBuf,
    /// Run this draw alone and print everything about it.
    #[arg(long, value_name = "DRAW")]
    replay: Option<u32>,
    /// With --replay: run the draw again with each plant parameter in turn at its default, and
    /// list the parameters whose default moves the reading's error most (what causes it).
    #[arg(long, requires = "replay")]
    ablate: bool,
    /// Run the sweep once for each of these seeds (`7001-7010`, `1,4,9`) and pool their
    /// readings: a row per seed, then the figures over all of them.
    #[arg(long, value_name = "LIST", value_parser = seeds::seed_list, conflicts_with = "replay")]
    seeds: Option<seeds::SeedList>,
    /// Give up when no draw has finished for this many seconds of wall time (a hung draw).
    #[arg(long, default_value_t = 600)]
    hang_s: u64,
}

/// `NAME=VALUE` with a number (the name and the range are checked by [`Sweep::fix`]).
fn held_param(text: &str) -> Result<(String, f64), String> {
    text.split_once('=')
        .and_then(|(name, value)| Some((name.trim().to_owned(), value.trim().parse().ok()?)))
        .ok_or_else(|| format!("`{text}` is not NAME=VALUE with a number (e.g. supply_v=24)"))
}

/// The sweep the arguments describe, or why not.
fn sweep_of(args: &Args, seed: u64) -> Result<Sweep, String> {
    let mut sweep = Sweep::new(seed);
    for (name, value) in &args.held {
        sweep.fix(name, *value).map_err(|e| e.to_string())?;
    }
    sweep.run.target_force_n = args.force_n;
    sweep.run.validate().map_err(|field| {
        let (lo, hi) = field.range();
        format!(
            "--force-n {}: must be between {lo} and {hi} N",
            args.force_n
        )
    })?;
    Ok(sweep)
}

fn main() {
    let args = Args::parse();
    let sweep = sweep_of(&args, args.seed).unwrap_or_else(|message| {
        eprintln!("error: {message}");
        std::process::exit(2);
    });
    let ok = match (&args.seeds, args.replay) {
        (Some(list), _) => seeds::run_seeds(&args, &list.0, &|seed| {
            sweep_of(&args, seed).expect("the same arguments made a sweep for --seed")
        }),
        (None, Some(index)) => replay(&args, &sweep.draw(index)),
        (None, None) => run_sweep(&args, &sweep),
    };
    if !ok {
        std::process::exit(1);
    }
}

/// The whole sweep; whether it passes.
fn run_sweep(args: &Args, sweep: &Sweep) -> bool {
    let progress = Progress::new(args.draws);
    let watch = Watchdog::start(Duration::from_secs(args.hang_s));
    let reports = parallel_map(
        args.draws,
        args.threads,
        &|index| {
            watch.begin(index);
            let report = run_draw(&sweep.draw(index));
            watch.end(index);
            report
        },
        &|done| progress.show(done),
    );
    progress.finish();
    let summary = Summary::of(&reports, args.tolerance_um);
    let listed = Listed::choose(&summary, &reports, args.worst);
    for report in listed.all() {
        write_plant_file(args, &report.draw);
    }
    if args.json {
        println!("{}", sweep_json(args, &summary, &listed));
    } else {
        print_sweep(args, &summary, &listed);
    }
    let unflagged_wrong = summary.of_class(Class::UnflaggedWrong).len();
    summary.all_ended_safely() && !(args.strict && unflagged_wrong > 0)
}

/// Whether `--set` holds the parameter.
fn is_held(args: &Args, spec: &ParamSpec) -> bool {
    args.held.iter().any(|(name, _)| name == spec.name)
}

/// How a parameter came by its value: held by `--set`, or drawn (how, from what range).
fn how_set(args: &Args, spec: &ParamSpec) -> String {
    if is_held(args, spec) {
        return "held by --set".to_owned();
    }
    format!("drawn {} in {}..={}", scale_name(spec), spec.min, spec.max)
}

/// One draw alone, in full; whether it ended properly.
fn replay(args: &Args, draw: &Draw) -> bool {
    let report = run_draw(draw);
    write_plant_file(args, &report.draw);
    let class = classify(&report.outcome, args.tolerance_um);
    if args.json {
        println!("{}", draw_json(args, &report));
    } else {
        println!("{}", describe(args, &report));
        println!("simulated time: {} ms", report.sim_ms);
        println!("plant parameters:");
        for spec in PARAMS {
            let value = spec.get(&report.draw.plant);
            println!(
                "  {:<30} {:>12} {:<6} (default {}, {})",
                spec.name,
                number(value),
                spec.unit,
                number(spec.default_value()),
                how_set(args, spec)
            );
        }
    }
    if args.ablate {
        print_ablation(&report);
    }
    class.ends_properly() && report.motor_safe == Some(true)
}

/// The draw run again with each plant parameter in turn at its default: the parameters that
/// move the reading's error (or its ending) most, largest first.
fn print_ablation(report: &DrawReport) {
    let Some(base_um) = reading_error_um(&report.outcome) else {
        println!("ablation: the draw ended without a reading; nothing to compare");
        return;
    };
    let changes = parallel_map(
        PARAMS.len() as u32,
        available_threads(),
        &|index| {
            let spec = &PARAMS[index as usize];
            let mut draw = report.draw.clone();
            draw.plant
                .set(spec.name, spec.default_value())
                .expect("a parameter's default is within its range");
            (spec.name, run_draw(&draw).outcome)
        },
        &|_| {},
    );
    let mut rows: Vec<(f64, String)> = changes
        .into_iter()
        .map(
            |(name, outcome)| match (&outcome, reading_error_um(&outcome)) {
                (Outcome::Reading { result, .. }, Some(error_um)) => (
                    (error_um - base_um).abs(),
                    format!(
                        "  {name:<30} error {error_um:+.2} µm ({:+.2}), flags [{}]",
                        error_um - base_um,
                        result.flags.names().collect::<Vec<_>>().join(", ")
                    ),
                ),
                _ => (
                    f64::INFINITY,
                    format!(
                        "  {name:<30} {}",
                        failure_name(&outcome).unwrap_or_default()
                    ),
                ),
            },
        )
        .collect();
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    println!("ablation: error {base_um:+.2} µm; with one parameter at its default:");
    for (_, row) in rows.iter().take(12) {
        println!("{row}");
    }
}

/// A reading's error against its truth, µm.
fn reading_error_um(outcome: &Outcome) -> Option<f64> {
    match outcome {
        Outcome::Reading { result, truth_um } => Some(f64::from(result.kerf_um) - truth_um),
        _ => None,
    }
}

/// Exits the process, naming the draws in progress, when none has finished for a while.
struct Watchdog {
    in_progress: Mutex<BTreeSet<u32>>,
    last_end: Mutex<Instant>,
}

impl Watchdog {
    /// A watchdog checking every second for `limit` without a finished draw.
    fn start(limit: Duration) -> &'static Self {
        let watch: &'static Self = Box::leak(Box::new(Self {
            in_progress: Mutex::new(BTreeSet::new()),
            last_end: Mutex::new(Instant::now()),
        }));
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_secs(1));
                let idle = watch
                    .last_end
                    .lock()
                    .map_or(Duration::ZERO, |t| t.elapsed());
                if idle > limit {
                    let hung = watch
                        .in_progress
                        .lock()
                        .map(|s| s.clone())
                        .unwrap_or_default();
                    eprintln!(
                        "robustness: no draw finished in {} s; hung: draws {hung:?} (replay one with --replay)",
                        limit.as_secs()
                    );
                    std::process::exit(1);
                }
            }
        });
        watch
    }

    fn begin(&self, index: u32) {
        if let Ok(mut set) = self.in_progress.lock() {
            set.insert(index);
        }
    }

    fn end(&self, index: u32) {
        if let Ok(mut set) = self.in_progress.lock() {
            set.remove(&index);
        }
        if let Ok(mut last) = self.last_end.lock() {
            *last = Instant::now();
        }
    }
}

/// A count of finished draws on a terminal's stderr.
struct Progress {
    total: u32,
    step: usize,
    shown: bool,
}

impl Progress {
    fn new(total: u32) -> Self {
        Self {
            total,
            step: (total as usize / 20).max(1),
            shown: std::io::stderr().is_terminal(),
        }
    }

    fn show(&self, done: usize) {
        if self.shown && (done.is_multiple_of(self.step) || done == self.total as usize) {
            eprint!("\rrobustness: {done}/{} draws", self.total);
        }
    }

    fn finish(&self) {
        if self.shown {
            eprintln!();
        }
    }
}

/// The draws printed in detail: the unflagged wrong readings, the worst readings, and the first
/// draw of each kind of failure.
struct Listed<'a> {
    unflagged_wrong: Vec<&'a DrawReport>,
    worst: Vec<&'a DrawReport>,
    failure_examples: Vec<&'a DrawReport>,
}

impl<'a> Listed<'a> {
    fn choose(summary: &Summary, reports: &'a [DrawReport], worst: usize) -> Self {
        let pick = |indices: &[u32]| -> Vec<&'a DrawReport> {
            indices.iter().map(|&i| &reports[i as usize]).collect()
        };
        let firsts: Vec<u32> = summary.failures.values().map(|draws| draws[0]).collect();
        Self {
            unflagged_wrong: pick(summary.of_class(Class::UnflaggedWrong)),
            worst: pick(&summary.worst[..worst.min(summary.worst.len())]),
            failure_examples: pick(&firsts),
        }
    }

    fn all(&self) -> impl Iterator<Item = &&'a DrawReport> {
        self.unflagged_wrong
            .iter()
            .chain(&self.worst)
            .chain(&self.failure_examples)
    }
}

/// `DIR/seed<S>-draw<D>.json`, with what the sweep held and its force when not the default
/// (`seed1-draw4-supply_v=24-force=40.json`): sweeps of one seed at two supplies must not
/// overwrite each other's plants.
fn plant_file(args: &Args, draw: &Draw) -> PathBuf {
    let mut name = format!("seed{}-draw{}", draw.seed, draw.index);
    for (param, value) in &args.held {
        name.push_str(&format!("-{param}={value}"));
    }
    if args.force_n != RunParams::DEFAULT.target_force_n {
        name.push_str(&format!("-force={}", args.force_n));
    }
    args.out_dir.join(name + ".json")
}

fn write_plant_file(args: &Args, draw: &Draw) {
    let path = plant_file(args, draw);
    let written = std::fs::create_dir_all(&args.out_dir).and_then(|()| {
        std::fs::write(
            &path,
            serde_json::to_string_pretty(&draw.plant.to_json()).unwrap_or_default() + "\n",
        )
    });
    if let Err(e) = written {
        eprintln!("robustness: cannot write {}: {e}", path.display());
    }
}

/// The commands that replay a draw: exactly, and through the host's simulated device. The host
/// replays the same plant, gauge and seed, but its twin's device keeps the default configuration
/// (each `kerfmeter --sim` starts a fresh twin) and the noise differs, as the host polls at other
/// instants.
fn replay_commands(args: &Args, draw: &Draw) -> (String, String) {
    let held: String = args
        .held
        .iter()
        .map(|(name, value)| format!(" --set {name}={value}"))
        .collect();
    let force = if args.force_n == RunParams::DEFAULT.target_force_n {
        String::new()
    } else {
        format!(" --force-n {}", args.force_n)
    };
    let exact = format!(
        "cargo xtask robustness --seed {}{held}{force} --replay {}",
        draw.seed, draw.index
    );
    let cli = format!(
        "kerfmeter --sim --sim-kerf-um {:.3} --sim-kerf-sd-um {:.3} --sim-seed {} --sim-plant-file {} run{force}",
        draw.kerf_um,
        draw.kerf_sd_um,
        draw.twin_seed,
        plant_file(args, draw).display()
    );
    (exact, cli)
}

/// The held parameters, `NAME=VALUE, …`, or `none`.
fn held_text(args: &Args) -> String {
    if args.held.is_empty() {
        return "none".to_owned();
    }
    let held: Vec<String> = args
        .held
        .iter()
        .map(|(name, value)| format!("{name}={value}"))
        .collect();
    held.join(", ")
}

/// One line on how a draw ended, then the most unusual parameters and the replay commands.
fn describe(args: &Args, report: &DrawReport) -> String {
    let draw = &report.draw;
    let ending = match &report.outcome {
        Outcome::Reading { result, truth_um } => format!(
            "read {:.2} µm, truth {truth_um:.2} µm, error {:+.2} µm, flags [{}]",
            result.kerf_um,
            f64::from(result.kerf_um) - truth_um,
            result.flags.names().collect::<Vec<_>>().join(",")
        ),
        Outcome::Panic(text) => format!("panic: {text}"),
        other => failure_name(other).unwrap_or_default(),
    };
    let unusual: Vec<String> = draw
        .most_unusual(4)
        .into_iter()
        .map(|(spec, value)| format!("{} {} {}", spec.name, number(value), spec.unit))
        .collect();
    let (exact, cli) = replay_commands(args, draw);
    format!(
        "draw {}: kerf {:.1} µm (spread {:.1}): {ending}\n    most unusual: {}\n    replay: {exact}\n    host:   {cli}",
        draw.index,
        draw.kerf_um,
        draw.kerf_sd_um,
        unusual.join(", ")
    )
}

/// How a parameter is drawn, in words.
fn scale_name(spec: &kerfmeter_twin::plant::ParamSpec) -> &'static str {
    match scale(spec) {
        Scale::Uniform => "uniformly",
        Scale::LogUniform => "log-uniformly",
    }
}

/// The parameters drawn log-uniformly (held ones are not drawn).
fn log_uniform_names(args: &Args) -> Vec<&'static str> {
    PARAMS
        .iter()
        .filter(|spec| scale(spec) == Scale::LogUniform)
        .filter(|spec| !is_held(args, spec))
        .map(|spec| spec.name)
        .collect()
}

/// A parameter's value, readable whatever its scale.
fn number(value: f64) -> String {
    if value != 0.0 && value.abs() < 0.01 {
        format!("{value:.3e}")
    } else {
        format!("{value:.4}")
    }
}

fn error_line(label: &str, stats: &ErrorStats) -> String {
    if stats.n == 0 {
        return format!("{label} (n=0): none");
    }
    format!(
        "{label} (n={}): mean {:+.2} µm, SD {:.2} µm, p95 |e| {:.2} µm, max |e| {:.2} µm",
        stats.n, stats.mean_um, stats.sd_um, stats.p95_abs_um, stats.max_abs_um
    )
}

fn print_sweep(args: &Args, summary: &Summary, listed: &Listed) {
    let count = |class| summary.of_class(class).len();
    let readings = summary.readings();
    println!(
        "Kerfmeter robustness sweep: {} draws, seed {}, every plant parameter drawn from its range unless held, kerf {}–{} µm, {} N over 3 fingers of 4 mm",
        summary.draws,
        args.seed,
        kerfmeter_twin::study::robustness::KERF_RANGE_UM.0,
        kerfmeter_twin::study::robustness::KERF_RANGE_UM.1,
        args.force_n
    );
    println!("held at one value: {}", held_text(args));
    println!(
        "drawn log-uniformly (range over 10×): {}; every other parameter uniformly",
        log_uniform_names(args).join(", ")
    );
    println!(
        "success: {readings}/{} readings ({:.1} %): {} correct, {} flagged, {} unflagged wrong (|error| > {} µm, no flag)",
        summary.draws,
        100.0 * readings as f64 / summary.draws.max(1) as f64,
        count(Class::Correct),
        count(Class::Flagged),
        count(Class::UnflaggedWrong),
        args.tolerance_um
    );
    println!("device-added error, reading − truth:");
    println!("  {}", error_line("every reading", &summary.all_readings));
    println!(
        "  {}",
        error_line("unflagged readings", &summary.unflagged_readings)
    );
    println!("failures by type ({}):", summary.draws - readings);
    for (name, draws) in &summary.failures {
        let shown: Vec<String> = draws.iter().take(12).map(u32::to_string).collect();
        let more = if draws.len() > 12 { ", …" } else { "" };
        println!(
            "  {:>4}  {name:<40} draws {}{more}",
            draws.len(),
            shown.join(", ")
        );
    }
    let sections = [
        ("unflagged wrong readings", &listed.unflagged_wrong),
        ("worst readings", &listed.worst),
        ("first draw of each failure", &listed.failure_examples),
    ];
    for (title, reports) in sections {
        println!("{title} ({}):", reports.len());
        for report in reports {
            println!("  {}", describe(args, report));
        }
    }
    println!(
        "every draw ended in a reading or a typed fault or refusal, motor safe: {}",
        if summary.all_ended_safely() {
            "yes"
        } else {
            "NO"
        }
    );
    if !summary.motor_unsafe.is_empty() {
        println!(
            "  motor not safe at the end of draws {:?}",
            summary.motor_unsafe
        );
    }
    println!("plant files: {}", args.out_dir.display());
    println!(
        "host replays run the same plant, gauge and seed, with the device's default configuration and other noise"
    );
}

fn stats_json(stats: &ErrorStats) -> Value {
    let finite = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
    json!({
        "n": stats.n,
        "mean_um": finite(stats.mean_um),
        "sd_um": finite(stats.sd_um),
        "p95_abs_um": finite(stats.p95_abs_um),
        "max_abs_um": finite(stats.max_abs_um),
    })
}

fn draw_json(args: &Args, report: &DrawReport) -> Value {
    let draw = &report.draw;
    let (exact, cli) = replay_commands(args, draw);
    let class = classify(&report.outcome, args.tolerance_um);
    let mut object = json!({
        "draw": draw.index,
        "seed": draw.seed,
        "class": class.name(),
        "kerf_um": draw.kerf_um,
        "kerf_sd_um": draw.kerf_sd_um,
        "twin_seed": draw.twin_seed,
        "motor_safe": report.motor_safe,
        "sim_ms": report.sim_ms,
        "failure": failure_name(&report.outcome),
        "plant_file": plant_file(args, draw),
        "replay": exact,
        "host_replay": cli,
        "plant": draw.plant.to_json(),
    });
    if let Outcome::Reading { result, truth_um } = &report.outcome {
        object["reading_um"] = json!(result.kerf_um);
        object["truth_um"] = json!(truth_um);
        object["error_um"] = json!(f64::from(result.kerf_um) - truth_um);
        object["flags"] = json!(result.flags.names().collect::<Vec<_>>());
    }
    if let Outcome::Panic(text) = &report.outcome {
        object["panic"] = json!(text);
    }
    object
}

fn sweep_json(args: &Args, summary: &Summary, listed: &Listed) -> Value {
    let classes: serde_json::Map<String, Value> = summary
        .by_class
        .iter()
        .map(|(class, draws)| (class.name().to_owned(), json!(draws.len())))
        .collect();
    let failures: serde_json::Map<String, Value> = summary
        .failures
        .iter()
        .map(|(name, draws)| (name.clone(), json!({"count": draws.len(), "draws": draws})))
        .collect();
    let list = |reports: &[&DrawReport]| -> Vec<Value> {
        reports.iter().map(|r| draw_json(args, r)).collect()
    };
    json!({
        "seed": args.seed,
        "draws": summary.draws,
        "held": args.held.iter().map(|(name, value)| (name.clone(), json!(value))).collect::<serde_json::Map<_, _>>(),
        "force_n": args.force_n,
        "tolerance_um": args.tolerance_um,
        "log_uniform_params": log_uniform_names(args),
        "readings": summary.readings(),
        "success_rate": summary.readings() as f64 / summary.draws.max(1) as f64,
        "classes": classes,
        "error_all_readings": stats_json(&summary.all_readings),
        "error_unflagged_readings": stats_json(&summary.unflagged_readings),
        "failures": failures,
        "unflagged_wrong": list(&listed.unflagged_wrong),
        "worst": list(&listed.worst),
        "failure_examples": list(&listed.failure_examples),
        "motor_unsafe": summary.motor_unsafe,
        "all_ended_safely": summary.all_ended_safely(),
        "plant_files": Path::new(&args.out_dir),
    })
}
