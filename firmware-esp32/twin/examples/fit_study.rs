//! The paper's fit study on the twin (`cargo xtask fit-study`): one-finger box joints in 4 mm
//! MDF, each cut beside a gauge the real firmware measures, each dilated by that reading; the
//! force each takes to assemble, against the paper's figures. The model and its derivation are
//! in `kerfmeter_twin::study::fit`.
//!
//! Usage: `fit_study [--trials N] [--seed S] [--json] [--threads N] [--kerf-sd-um SD]
//! [--edge-sd-um SD] [--location-sd-um SD] [--kerf-um K]` (`--help` says what each does).
//!
//! A gauge whose measurement ends in a fault is reported (its joint is not assembled); exits 1
//! when no joint could be, 2 for bad arguments.

use std::io::IsTerminal;

use clap::Parser;

use kerfmeter_twin::study::available_threads;
use kerfmeter_twin::study::fit::{
    FIT_WINDOW_N, FORCE_PER_FINGER_N, ForceFigures, PAPER, Setup, Trial, device_sd_n, study,
};
use kerfmeter_twin::study::robustness::failure_name;
use serde_json::{Value, json};

/// The paper's fit study on the twin: box joints dilated by the device's readings, and the force
/// each takes to assemble (`cargo xtask fit-study`).
#[derive(Parser)]
#[command(name = "fit-study")]
struct Args {
    /// Joints to cut and assemble (the paper: 30).
    #[arg(long, default_value_t = Setup::default().trials)]
    trials: u32,
    /// Seed of every draw.
    #[arg(long, default_value_t = Setup::default().seed)]
    seed: u64,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Worker threads (default: the cores available).
    #[arg(long, default_value_t = available_threads())]
    threads: usize,
    /// Nominal kerf of the cutter, µm.
    #[arg(long, default_value_t = Setup::default().kerf_um)]
    kerf_um: f64,
    /// SD of the kerf from one cut to the next at one place, µm.
    #[arg(long, default_value_t = Setup::default().kerf_sd_um)]
    kerf_sd_um: f64,
    /// SD of each edge's position, µm.
    #[arg(long, default_value_t = Setup::default().edge_sd_um)]
    edge_sd_um: f64,
    /// SD of the kerf from place to place on the bed, µm.
    #[arg(long, default_value_t = Setup::default().location_sd_um)]
    location_sd_um: f64,
}

impl Args {
    /// The study's set-up: the defaults (MDF) with the flags given.
    fn setup(&self) -> Setup {
        Setup {
            trials: self.trials,
            seed: self.seed,
            kerf_um: self.kerf_um,
            kerf_sd_um: self.kerf_sd_um,
            edge_sd_um: self.edge_sd_um,
            location_sd_um: self.location_sd_um,
            ..Setup::default()
        }
    }
}

fn main() {
    let args = Args::parse();
    let setup = args.setup();
    let terminal = std::io::stderr().is_terminal();
    let trials = study(&setup, args.threads, &|done| {
        if terminal {
            eprint!("\rfit-study: {done}/{} joints", setup.trials);
        }
    });
    if terminal {
        eprintln!();
    }
    let results = Results::of(&trials);
    if args.json {
        println!("{}", to_json(&setup, &trials, &results));
    } else {
        print_text(&setup, &trials, &results);
    }
    if results.device.n == 0 {
        std::process::exit(1);
    }
}

/// The study's figures: with the device, with an ideal device.
struct Results {
    device: ForceFigures,
    ideal: ForceFigures,
    device_adds_sd_n: f64,
    failed: usize,
}

impl Results {
    fn of(trials: &[Trial]) -> Self {
        let device: Vec<f64> = trials.iter().filter_map(Trial::device_force_n).collect();
        let ideal: Vec<f64> = trials.iter().filter_map(Trial::ideal_force_n).collect();
        let (device, ideal) = (ForceFigures::of(&device), ForceFigures::of(&ideal));
        Self {
            device_adds_sd_n: device_sd_n(device.sd_n, ideal.sd_n),
            failed: trials.len() - device.n,
            device,
            ideal,
        }
    }
}

fn print_text(setup: &Setup, trials: &[Trial], results: &Results) {
    println!(
        "Kerfmeter fit study on the twin: {} one-finger joints, 4 mm MDF, device set for {FORCE_PER_FINGER_N} N per finger, seed {}",
        setup.trials, setup.seed
    );
    println!(
        "cutter: kerf {} µm, place-to-place SD {} µm (gauge and joint share it), cut-to-cut SD {} µm, edge SD {} µm (±{} µm at 95 %)",
        setup.kerf_um,
        setup.location_sd_um,
        setup.kerf_sd_um,
        setup.edge_sd_um,
        2.0 * setup.edge_sd_um
    );
    println!(
        "{:>5} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "joint", "k_gauge", "reading", "ideal", "k_joint", "F device", "F ideal"
    );
    for t in trials {
        print_trial(t);
    }
    let (lo, hi) = FIT_WINDOW_N;
    println!();
    println!(
        "{:<34} {:>9} {:>9} {:>12} {:>10}",
        "assembly force per finger", "mean N", "SD N", "in window", "loose/tight"
    );
    let row = |label: &str, f: &ForceFigures| {
        println!(
            "{label:<34} {:>9.1} {:>9.1} {:>7} of {:<2} {:>5}/{}",
            f.mean_n, f.sd_n, f.in_window, f.n, f.loose, f.tight
        );
    };
    row("twin, with the device", &results.device);
    row("twin, ideal device (cutter alone)", &results.ideal);
    println!(
        "{:<34} {:>9.1} {:>9.1} {:>7} of {:<2}",
        "paper, with the device", PAPER.mean_n, PAPER.sd_n, PAPER.in_window, PAPER.trials
    );
    println!(
        "{:<34} {:>9} {:>9.1}",
        "paper, cutter alone", "", PAPER.cutter_sd_n
    );
    println!("fit window: {lo}–{hi} N per finger");
    let share = |sd: f64| 100.0 * sd.powi(2) / results.device.sd_n.powi(2).max(f64::MIN_POSITIVE);
    println!(
        "SD the device adds (√(SD² − SD_cutter²)): twin {:.1} N, paper {:.1} N; share of the variance: cutter {:.0} %, device {:.0} % (paper: {:.0} % / {:.0} %)",
        results.device_adds_sd_n,
        PAPER.device_sd_n,
        share(results.ideal.sd_n).min(100.0),
        share(results.device_adds_sd_n),
        100.0 * (PAPER.cutter_sd_n / PAPER.sd_n).powi(2),
        100.0 * (PAPER.device_sd_n / PAPER.sd_n).powi(2),
    );
    if results.failed > 0 {
        println!("gauges without a reading: {}", results.failed);
    }
}

fn print_trial(t: &Trial) {
    let Some(result) = t.outcome.result() else {
        println!(
            "{:>5} {:>9.1} {}",
            t.index,
            t.gauge_kerf_um,
            failure_name(&t.outcome).unwrap_or_default()
        );
        return;
    };
    let ideal = match t.outcome {
        kerfmeter_twin::study::Outcome::Reading { truth_um, .. } => truth_um,
        _ => f64::NAN,
    };
    println!(
        "{:>5} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
        t.index,
        t.gauge_kerf_um,
        result.kerf_um,
        ideal,
        t.joint.kerf_um,
        t.device_force_n().unwrap_or(f64::NAN),
        t.ideal_force_n().unwrap_or(f64::NAN)
    );
}

fn figures_json(f: &ForceFigures) -> Value {
    json!({
        "joints": f.n,
        "mean_n": f.mean_n,
        "sd_n": f.sd_n,
        "in_window": f.in_window,
        "loose": f.loose,
        "tight": f.tight,
    })
}

fn to_json(setup: &Setup, trials: &[Trial], results: &Results) -> Value {
    let joints: Vec<Value> = trials
        .iter()
        .map(|t| {
            json!({
                "joint": t.index,
                "location_kerf_um": t.location_kerf_um,
                "gauge_kerf_um": t.gauge_kerf_um,
                "reading_um": t.outcome.result().map(|r| r.kerf_um),
                "failure": failure_name(&t.outcome),
                "joint_kerf_um": t.joint.kerf_um,
                "device_force_n": t.device_force_n(),
                "ideal_force_n": t.ideal_force_n(),
            })
        })
        .collect();
    json!({
        "seed": setup.seed,
        "trials": setup.trials,
        "kerf_um": setup.kerf_um,
        "location_sd_um": setup.location_sd_um,
        "kerf_sd_um": setup.kerf_sd_um,
        "edge_sd_um": setup.edge_sd_um,
        "force_per_finger_n": FORCE_PER_FINGER_N,
        "fit_window_n": [FIT_WINDOW_N.0, FIT_WINDOW_N.1],
        "with_device": figures_json(&results.device),
        "ideal_device": figures_json(&results.ideal),
        "device_adds_sd_n": results.device_adds_sd_n,
        "failed": results.failed,
        "paper": {
            "mean_n": PAPER.mean_n,
            "sd_n": PAPER.sd_n,
            "cutter_sd_n": PAPER.cutter_sd_n,
            "device_sd_n": PAPER.device_sd_n,
            "in_window": PAPER.in_window,
            "trials": PAPER.trials,
        },
        "joints": joints,
    })
}
