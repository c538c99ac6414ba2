//! The twin's accuracy table (`cargo xtask accuracy`): the real firmware measuring simulated
//! gauges across kerf 50–430 µm and stock 3–6 mm, many seeds per point, default noise.
//!
//! Every run is a new twin (seed): its own encoder errors, cutter location bias and gauge cut
//! (displaced holes, off-centre prongs, taper, drawn stiffness and μ), at the plant's defaults.
//! For every run the truth is the one the twin recorded when it placed the gauge
//! (`Plant::truth_um`): the kerf an ideal device reads on that gauge at the force the run asked
//! for, so the error is what the device adds. Beside it, the table shows the error of the
//! uncorrected reading c·θm, which ignores the hole play, and the compression (truth minus the
//! mid-sheet kerf).
//!
//! Usage: `accuracy [--seeds N] [--quick] [--plant NAME=VALUE]...` (`--help` says what each
//! does; prints a table; exits
//! non-zero if a point misses the targets |mean error| ≤ 1 µm and SD ≤ 2 µm, or if any run
//! failed). `--plant` sets a plant parameter for every run (e.g. `--plant kerf_taper_um=0` to
//! see what the taper alone costs).

use std::time::Instant;

use clap::Parser;

use kerfmeter_protocol::spiral::uncorrected_kerf_um;
use kerfmeter_protocol::{GaugeGeometry, KerfResult, Request, Response, RunParams, RunState};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

/// Target: |mean error| at every point, µm.
const MAX_MEAN_ERROR_UM: f64 = 1.0;
/// Target: per-run standard deviation at every point, µm.
const MAX_SD_UM: f64 = 2.0;

struct Run {
    result: KerfResult,
    truth_um: f64,
    geometric_um: f64,
    sim_ms: u64,
}

fn measure(plant: PlantParams, kerf_um: f64, thickness_mm: f32, seed: u64) -> Result<Run, String> {
    let mut twin = Twin::new(TwinOptions {
        kerf_um,
        seed,
        plant,
        ..TwinOptions::default()
    });
    twin.advance_ticks(5);
    // The paper's joint in this stock: three fingers, two faces each, 6.3 mm long.
    let params = RunParams {
        thickness_mm,
        contact_area_mm2: 3.0 * 2.0 * thickness_mm * 6.3,
        ..RunParams::DEFAULT
    };
    let start = twin.now_us();
    match twin.request(&Request::Run(params)) {
        Response::Ok => {}
        other => return Err(format!("Run refused: {other:?}")),
    }
    for _ in 0..2000 {
        twin.advance_ticks(10);
        let Response::Status(status) = twin.request(&Request::GetStatus) else {
            return Err("no status".into());
        };
        match status.state {
            RunState::Done => {
                let Response::Kerf(Some(result)) = twin.request(&Request::GetKerf) else {
                    return Err("Done without a result".into());
                };
                let truth_um = twin
                    .truths()
                    .truth_um(result.run_id)
                    .ok_or("no truth recorded for the run")?;
                return Ok(Run {
                    truth_um,
                    geometric_um: twin.plant().kerf_um(),
                    sim_ms: (twin.now_us() - start) / 1000,
                    result,
                });
            }
            RunState::Fault(f) => return Err(format!("fault {f:?}")),
            _ => {}
        }
    }
    Err("no result within 20 s of simulated time".into())
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    (mean, sd)
}

/// The twin's accuracy table: the real firmware measuring simulated gauges across kerf and stock
/// thickness, many seeds per point (`cargo xtask accuracy`).
#[derive(Parser)]
#[command(name = "accuracy")]
struct Args {
    /// Seeds (runs) per point (default: 20, or 5 with --quick).
    #[arg(long)]
    seeds: Option<u64>,
    /// Fewer points (3 kerfs × 2 thicknesses) and seeds: a quick look.
    #[arg(long)]
    quick: bool,
    /// Set a plant parameter for every run, NAME=VALUE (repeatable; e.g. `kerf_taper_um=0`).
    #[arg(long, value_name = "NAME=VALUE", value_parser = plant_assignment)]
    plant: Vec<String>,
}

/// `s` if it sets a plant parameter within its range.
fn plant_assignment(s: &str) -> Result<String, String> {
    PlantParams::default()
        .assign(s)
        .map(|_| s.to_owned())
        .map_err(|e| e.to_string())
}

fn main() {
    let args = Args::parse();
    let quick = args.quick;
    let seeds = args.seeds.unwrap_or(if quick { 5 } else { 20 });
    let kerfs: &[f64] = if quick {
        &[50.0, 200.0, 430.0]
    } else {
        &[50.0, 100.0, 150.0, 200.0, 250.0, 300.0, 350.0, 400.0, 430.0]
    };
    let thicknesses: &[f32] = if quick {
        &[3.0, 6.0]
    } else {
        &[3.0, 4.0, 5.0, 6.0]
    };
    let gauge = GaugeGeometry::PAPER;
    let mut plant = PlantParams::default();
    for assignment in &args.plant {
        plant
            .assign(assignment)
            .expect("checked when the flags were parsed");
    }

    let changed: Vec<String> = kerfmeter_twin::plant::PARAMS
        .iter()
        .filter(|p| p.get(&plant) != p.default_value())
        .map(|p| format!("{}={}", p.name, p.get(&plant)))
        .collect();
    println!(
        "Kerfmeter twin accuracy: {seeds} seeds per point, {}, paper gauge, 55 N over 3 fingers",
        if changed.is_empty() {
            "default plant".to_owned()
        } else {
            format!("plant defaults but {}", changed.join(", "))
        }
    );
    println!(
        "{:>7} {:>6} | {:>9} {:>8} {:>7} | {:>10} {:>9} | {:>11} | {:>7} {:>7} | flags",
        "kerf",
        "stock",
        "mean err",
        "SD",
        "max|e|",
        "uncorr err",
        "compress",
        "force N",
        "sim ms",
        "wall ms"
    );
    println!(
        "{:>7} {:>6} | {:>9} {:>8} {:>7} | {:>10} {:>9} | {:>11} | {:>7} {:>7} |",
        "µm", "mm", "µm", "µm", "µm", "µm", "µm", "at jam", "max", "mean"
    );
    let mut misses = 0;
    let mut failures = 0;
    let mut worst_sim_ms = 0;
    let mut worst_wall_ms: f64 = 0.0;
    for &kerf in kerfs {
        for &thickness in thicknesses {
            let mut errors = Vec::new();
            let mut uncorrected = Vec::new();
            let mut compression = Vec::new();
            let mut forces = Vec::new();
            let mut flags = std::collections::BTreeSet::new();
            let mut sim_ms = 0;
            let mut wall_ms = 0.0;
            for seed in 0..seeds {
                let t0 = Instant::now();
                let outcome = measure(plant, kerf, thickness, 1000 + seed);
                let wall = t0.elapsed().as_secs_f64() * 1000.0;
                wall_ms += wall / seeds as f64;
                worst_wall_ms = worst_wall_ms.max(wall);
                match outcome {
                    Ok(run) => {
                        let measured = f64::from(run.result.kerf_um);
                        errors.push(measured - run.truth_um);
                        uncorrected.push(
                            f64::from(uncorrected_kerf_um(&gauge, run.result.angle_deg))
                                - run.truth_um,
                        );
                        compression.push(run.truth_um - run.geometric_um);
                        forces.push(f64::from(run.result.force_at_jam_n));
                        flags.extend(run.result.flags.names());
                        sim_ms = sim_ms.max(run.sim_ms);
                    }
                    Err(e) => {
                        failures += 1;
                        eprintln!("kerf {kerf} µm, {thickness} mm, seed {seed}: {e}");
                    }
                }
            }
            worst_sim_ms = worst_sim_ms.max(sim_ms);
            if errors.is_empty() {
                println!("{kerf:>7.0} {thickness:>6.1} | every run failed");
                misses += 1;
                continue;
            }
            let (mean, sd) = mean_sd(&errors);
            let max_abs = errors.iter().fold(0.0f64, |m, e| m.max(e.abs()));
            let (unc, _) = mean_sd(&uncorrected);
            let (comp, _) = mean_sd(&compression);
            let (force, _) = mean_sd(&forces);
            let ok = mean.abs() <= MAX_MEAN_ERROR_UM && sd <= MAX_SD_UM;
            if !ok {
                misses += 1;
            }
            let flag_text: Vec<&str> = flags.into_iter().collect();
            println!(
                "{kerf:>7.0} {thickness:>6.1} | {mean:>+9.2} {sd:>8.2} {max_abs:>7.2} | {unc:>+10.1} {comp:>9.2} | {force:>11.1} | {sim_ms:>7} {wall_ms:>7.1} | {}{}",
                if flag_text.is_empty() {
                    "-".to_owned()
                } else {
                    flag_text.join(",")
                },
                if ok { "" } else { "  <-- MISSES TARGET" }
            );
        }
    }
    println!();
    println!("targets: |mean error| <= {MAX_MEAN_ERROR_UM} µm, SD <= {MAX_SD_UM} µm per point");
    println!(
        "slowest measurement: {worst_sim_ms} ms simulated (target <= 3000), {worst_wall_ms:.1} ms wall (target <= 100)"
    );
    println!("points missing the targets: {misses}; failed runs: {failures}");
    if misses > 0 || failures > 0 {
        std::process::exit(1);
    }
}
