//! `cargo xtask`: the project's build and check entry points (see `cargo xtask --help`).
//!
//! Everything a developer or CI runs goes through here, so that what CI checks is exactly what
//! the README tells a newcomer to run. `cargo xtask test` installs what it needs (the RISC-V
//! targets, cargo-fuzz, the Python venv with maturin and pytest) and fails loudly when something
//! it needs cannot be had.

mod bench;
mod bench_plan;
mod bench_serve;
mod browser;
mod cli_outputs;
mod deps;
mod firmware;
mod fuzz;
mod postgres;
mod python;
mod recompensation;
mod tools;
mod wiring;

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "cargo xtask", about = "Kerfmeter build and check tasks")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// The whole check suite, as CI runs it: formatting, clippy (host and firmware targets), all
    /// host tests, the history against a real PostgreSQL, the Python package's tests, the web page in headless Chromium and the
    /// README's WebSocket clients, a short robustness sweep, docs, the firmware
    /// images for the C3 and C6 with their sizes, a short fuzz run.
    Test(TestArgs),
    /// The dependency step of `test` alone: no library crate pulls in clap, axum, tokio, pyo3
    /// or plotters.
    CheckDeps,
    /// The Python package's step of `test` alone: build and install `host-lib/python` into the
    /// project's venv (`target/python-venv`) and run its pytest suite on the twin.
    TestPython,
    /// The web step of `test` alone: the server's page in headless Chromium (Debian's chromium
    /// and chromium-driver, installed when missing) and the WebSocket clients of docs/server.md, against
    /// `kerfmeter --sim serve`.
    TestBrowser,
    /// The history step of `test` alone: `kerfmeter-history` with its PostgreSQL back end,
    /// clippy and its tests against a PostgreSQL server started for them (Debian's, installed
    /// when missing) in a temporary folder on a loopback port, stopped afterwards.
    TestHistoryPg,
    /// Write throughput and the time to list the newest 100 of many records, on SQLite and on a
    /// PostgreSQL server of its own. A benchmark: not part of `test`.
    BenchHistory(BenchHistoryArgs),
    /// Build the firmware image for a chip (release) and print its flash and RAM use.
    Firmware(firmware::FirmwareArgs),
    /// Draw the ESP32-C3 board's wiring (docs/wiring.svg) from the firmware's pin table;
    /// `--check` fails when the committed drawing is stale (a step of `test`).
    Wiring(wiring::WiringArgs),
    /// Build the firmware and write it to a board (real hardware: needs --port).
    Flash(firmware::FlashArgs),
    /// Run the fuzz targets: protocol and plan readers (cargo-fuzz on the nightly toolchain).
    Fuzz(fuzz::FuzzArgs),
    /// The twin's accuracy table: kerf 50–430 µm × stock 3–6 mm, 20 seeds per point.
    Accuracy(AccuracyArgs),
    /// The robustness sweep: every plant parameter drawn from its documented range, one
    /// measurement per draw; success rate, device-added error, failures by typed fault, unflagged
    /// wrong readings, the worst draws with the commands that replay them.
    Robustness(RobustnessArgs),
    /// The paper's fit study (its §7) on the twin: one-finger 4 mm MDF joints, each dilated by the
    /// reading of a gauge cut beside it; their assembly force against the paper's figures.
    FitStudy(FitStudyArgs),
    /// Instructions per control step and per kerf solve on RV32IMC (qemu), and the CPU share at
    /// 1 kHz on a 160 MHz ESP32-C3 (`--json`: the target figures alone). A benchmark: not part
    /// of `test`.
    BenchStep(bench::BenchArgs),
    /// The whole `kerfmeter dilate` command on generated plans of 624 to 10,000 contours (SVG
    /// and DXF): time, growth per 4× the parts, the kernel's share, peak memory against the
    /// file's size, and GEOS buffering the same parts. A benchmark: not part of `test`.
    BenchPlan(bench_plan::BenchPlanArgs),
    /// Many WebSocket clients (default 40 at 50 Hz) poll `status` and `get_kerf_value` while
    /// another measures on a real-time twin: p50 and p99 latency, errors, and the kerf against
    /// the same run alone. A benchmark: not part of `test`.
    BenchServe(bench_serve::BenchServeArgs),
    /// The on-target driver tests (encoder, PWM) on a real ESP32-C3 board through probe-rs
    /// (needs --probe; see firmware-esp32/tests/on_target.rs for the bench set-up).
    OnTarget(firmware::OnTargetArgs),
    /// The acceptance suite: on the twin, or on a board with --port (see hil-tests/src/lib.rs
    /// for the bench description).
    Hil(HilArgs),
    /// Round-trip latency of get_kerf_value over the serial port (p50, p99): the twin behind a
    /// pseudo-terminal, or a board with --port.
    BenchRtt(BenchRttArgs),
    /// Every `kerfmeter` command in text and `--json` on the twins and the example plans, its
    /// output and files kept one folder per case: run it with the binary from before a
    /// reorganisation and after, and `diff -r` the two folders.
    CliOutputs(cli_outputs::CliOutputsArgs),
}

#[derive(clap::Args)]
struct HilArgs {
    /// Run against the board on this serial port instead of the twin.
    #[arg(long)]
    port: Option<String>,
    /// Runs of the soak case (the default suite runs 100; the long soak is 1000).
    #[arg(long)]
    soak: Option<u32>,
}

#[derive(clap::Args)]
struct BenchRttArgs {
    /// Measure against the board on this serial port instead of the twin.
    #[arg(long)]
    port: Option<String>,
    /// Round trips to time.
    #[arg(long, default_value_t = 2000)]
    calls: u32,
}

#[derive(clap::Args)]
struct BenchHistoryArgs {
    /// Records in the history the listing is timed on.
    #[arg(long, default_value_t = 100_000)]
    records: u32,
}

#[derive(clap::Args)]
struct AccuracyArgs {
    /// Seeds per point.
    #[arg(long, default_value_t = 20)]
    seeds: u32,
    /// A smaller grid (3 kerfs × 2 stocks × 5 seeds).
    #[arg(long)]
    quick: bool,
    /// Set a plant parameter for every run (repeatable): `--plant kerf_taper_um=0` turns the
    /// gauge's taper off (`kerfmeter-twin --list-plant` names them all).
    #[arg(long = "plant", value_name = "NAME=VALUE")]
    plant: Vec<String>,
}

#[derive(clap::Args)]
struct RobustnessArgs {
    /// Twins to draw and run.
    #[arg(long, default_value_t = 200)]
    draws: u32,
    /// Seed of the draws (the same seed gives the same draws and results).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Hold a plant parameter at one value in every draw (repeatable): `--set supply_v=24` is
    /// the sweep on a 24 V rail.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    held: Vec<String>,
    /// The joint's assembly force each run measures at, N (default: the run's 55 N).
    #[arg(long)]
    force_n: Option<f64>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Fail on unflagged wrong readings too, not only on draws that end without a reading or a
    /// typed fault or refusal, or with the motor unsafe.
    #[arg(long)]
    strict: bool,
    /// Largest device-added error, µm, that an unflagged reading may have.
    #[arg(long)]
    tolerance_um: Option<f64>,
    /// Run only this draw of the seed's sweep and print everything about it.
    #[arg(long, value_name = "DRAW")]
    replay: Option<u32>,
    /// Run the sweep once per seed (`7001-7010`, `1,4,9`) and pool the readings: the held-out
    /// check of the firmware's flags (docs/twin.md).
    #[arg(long, value_name = "LIST", conflicts_with = "replay")]
    seeds: Option<String>,
    /// With --replay: run the draw again with each plant parameter at its default in turn, and
    /// list the parameters that move its error most.
    #[arg(long, requires = "replay")]
    ablate: bool,
}

#[derive(clap::Args)]
struct FitStudyArgs {
    /// Joints (the paper: 30).
    #[arg(long, default_value_t = 30)]
    trials: u32,
    /// Seed of the draws.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// SD of each joint edge's position, µm (default 7.5: ±15 µm repeatability at 95 %).
    #[arg(long)]
    edge_sd_um: Option<f64>,
    /// SD of the kerf from one cut to the next at one place, µm (default 3).
    #[arg(long)]
    kerf_sd_um: Option<f64>,
}

#[derive(clap::Args)]
struct TestArgs {
    /// Seconds of fuzzing per fuzz target.
    #[arg(long, default_value_t = 20)]
    fuzz_seconds: u64,
    /// Only report unflagged wrong readings in the short robustness sweep instead of failing on
    /// them (for a firmware experiment whose flags are not settled yet; never in CI).
    #[arg(long)]
    lenient_robustness: bool,
}

/// Draws in the short robustness sweep of `cargo xtask test`.
const TEST_SWEEP_DRAWS: u32 = 24;

fn main() -> Result<()> {
    match Cli::parse().command {
        Cmd::Test(args) => test(&args),
        Cmd::TestPython => python::test_package(),
        Cmd::CheckDeps => deps::check_libraries(),
        Cmd::TestBrowser => browser::test_web(),
        Cmd::TestHistoryPg => postgres::test_history(),
        Cmd::BenchHistory(args) => postgres::bench_history(args.records),
        Cmd::Firmware(args) => firmware::run(&args),
        Cmd::Wiring(args) => wiring::run(&args),
        Cmd::Flash(args) => firmware::flash(&args),
        Cmd::Fuzz(args) => fuzz::run(&args),
        Cmd::Accuracy(args) => accuracy(&args),
        Cmd::Robustness(args) => robustness(&args, true),
        Cmd::FitStudy(args) => fit_study(&args),
        Cmd::BenchStep(args) => bench::step(&args),
        Cmd::BenchPlan(args) => bench_plan::run(&args),
        Cmd::BenchServe(args) => bench_serve::run(&args),
        Cmd::OnTarget(args) => firmware::run_on_target_tests(args.probe),
        Cmd::Hil(args) => hil(&args),
        Cmd::CliOutputs(args) => cli_outputs::run(&args),
        Cmd::BenchRtt(args) => {
            let mut cmd = cargo();
            cmd.args([
                "run",
                "--release",
                "-p",
                "kerfmeter",
                "--example",
                "roundtrip",
                "--",
            ]);
            cmd.args(["--calls", &args.calls.to_string()]);
            if let Some(port) = &args.port {
                cmd.args(["--port", port]);
            }
            run_cmd(&mut cmd)
        }
    }
}

/// The workspace root.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives in the workspace")
        .to_path_buf()
}

/// A `cargo` command run from the workspace root with the toolchain of `rust-toolchain.toml`.
pub fn cargo() -> Command {
    let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    cmd.current_dir(root());
    cmd
}

/// Build the `kerfmeter` binary (`release` or debug) and give its path: the one build of it
/// that the benchmarks and the test steps that run it share.
pub fn build_cli(release: bool) -> Result<PathBuf> {
    let mut cmd = cargo();
    cmd.args(["build", "-p", "kerfmeter-cli", "--bin", "kerfmeter"]);
    if release {
        cmd.arg("--release");
    }
    run_cmd(&mut cmd)?;
    let profile = if release { "release" } else { "debug" };
    Ok(root().join("target").join(profile).join("kerfmeter"))
}

/// Run `cmd`, echoing it, and fail with its exit status.
pub fn run_cmd(cmd: &mut Command) -> Result<()> {
    eprintln!("$ {}", show(cmd));
    let status = cmd
        .status()
        .with_context(|| format!("cannot start {}", show(cmd)))?;
    if !status.success() {
        bail!("`{}` failed ({status})", show(cmd));
    }
    Ok(())
}

fn show(cmd: &Command) -> String {
    let mut s = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        s.push(' ');
        s.push_str(&a.to_string_lossy());
    }
    s
}

/// Run the acceptance suite and summarise the `HIL <case> <target> <outcome>` lines its cases
/// print.
fn hil(args: &HilArgs) -> Result<()> {
    use std::io::BufRead;
    let mut cmd = cargo();
    cmd.args(["test", "-p", "kerfmeter-hil", "--", "--nocapture"]);
    match &args.port {
        // One device: one case at a time.
        Some(port) => {
            cmd.env("KERFMETER_PORT", port).arg("--test-threads=1");
        }
        None => {
            cmd.env_remove("KERFMETER_PORT");
        }
    }
    if let Some(runs) = args.soak {
        // The soak is part of the default suite (100 runs); this sets its length.
        cmd.env("KERFMETER_SOAK_RUNS", runs.to_string());
    }
    eprintln!("$ {}", show(&cmd));
    let mut child = cmd
        .stderr(std::process::Stdio::piped())
        .spawn()
        .context("cannot start cargo test")?;
    let mut summary = Vec::new();
    for line in std::io::BufReader::new(child.stderr.take().expect("piped")).lines() {
        let line = line?;
        eprintln!("{line}");
        if let Some(rest) = line.strip_prefix("HIL ") {
            summary.push(rest.to_owned());
        }
    }
    let status = child.wait()?;
    eprintln!("\n=== acceptance suite: what ran against what");
    for line in &summary {
        eprintln!("  {line}");
    }
    if !status.success() {
        bail!("the acceptance suite failed (see above)");
    }
    Ok(())
}

fn accuracy(args: &AccuracyArgs) -> Result<()> {
    let mut cmd = cargo();
    cmd.args([
        "run",
        "--release",
        "-p",
        "kerfmeter-twin",
        "--example",
        "accuracy",
        "--",
    ]);
    cmd.args(["--seeds", &args.seeds.to_string()]);
    if args.quick {
        cmd.arg("--quick");
    }
    for setting in &args.plant {
        cmd.args(["--plant", setting]);
    }
    run_cmd(&mut cmd)
}

/// `cargo run -p kerfmeter-twin --example NAME -- ARGS`, optimised when `release`.
fn twin_example(name: &str, release: bool) -> Command {
    let mut cmd = cargo();
    cmd.arg("run");
    if release {
        cmd.arg("--release");
    }
    cmd.args(["-p", "kerfmeter-twin", "--example", name, "--"]);
    cmd
}

/// The robustness sweep (the `robustness` example); `release` builds it optimised, which pays for
/// long sweeps and not for the test command's short one.
fn robustness(args: &RobustnessArgs, release: bool) -> Result<()> {
    let mut cmd = twin_example("robustness", release);
    cmd.args(["--draws", &args.draws.to_string()]);
    cmd.args(["--seed", &args.seed.to_string()]);
    for held in &args.held {
        cmd.args(["--set", held]);
    }
    if let Some(force) = args.force_n {
        cmd.args(["--force-n", &force.to_string()]);
    }
    cmd.arg("--out-dir")
        .arg(root().join("target").join("robustness"));
    if let Some(tolerance) = args.tolerance_um {
        cmd.args(["--tolerance-um", &tolerance.to_string()]);
    }
    if let Some(seeds) = &args.seeds {
        cmd.args(["--seeds", seeds]);
    }
    if let Some(draw) = args.replay {
        cmd.args(["--replay", &draw.to_string()]);
    }
    if args.ablate {
        cmd.arg("--ablate");
    }
    if args.json {
        cmd.arg("--json");
    }
    if args.strict {
        cmd.arg("--strict");
    }
    run_cmd(&mut cmd)
}

fn fit_study(args: &FitStudyArgs) -> Result<()> {
    let mut cmd = twin_example("fit_study", true);
    cmd.args(["--trials", &args.trials.to_string()]);
    cmd.args(["--seed", &args.seed.to_string()]);
    if let Some(sd) = args.edge_sd_um {
        cmd.args(["--edge-sd-um", &sd.to_string()]);
    }
    if let Some(sd) = args.kerf_sd_um {
        cmd.args(["--kerf-sd-um", &sd.to_string()]);
    }
    if args.json {
        cmd.arg("--json");
    }
    run_cmd(&mut cmd)
}

fn test(args: &TestArgs) -> Result<()> {
    type Step<'a> = (&'static str, Box<dyn Fn() -> Result<()> + 'a>);
    let steps: Vec<Step> = vec![
        (
            "riscv targets installed",
            Box::new(firmware::ensure_targets),
        ),
        (
            // Cheap, and a stale drawing is a wrong build: first.
            "wiring drawing current (docs/wiring.svg)",
            Box::new(wiring::check_committed),
        ),
        (
            "rustfmt",
            Box::new(|| {
                run_cmd(cargo().args(["fmt", "--all", "--check"]))?;
                run_cmd(cargo().args(["fmt", "--check", "--manifest-path", "fuzz/Cargo.toml"]))
            }),
        ),
        (
            "library crates free of front-end dependencies",
            Box::new(deps::check_libraries),
        ),
        (
            "clippy (host)",
            Box::new(|| {
                run_cmd(cargo().args([
                    "clippy",
                    "--workspace",
                    "--all-targets",
                    "--",
                    "-D",
                    "warnings",
                ]))
            }),
        ),
        (
            "clippy (firmware, esp32c3)",
            Box::new(|| firmware::clippy(firmware::Chip::C3)),
        ),
        (
            "clippy (firmware, esp32c6)",
            Box::new(|| firmware::clippy(firmware::Chip::C6)),
        ),
        (
            "host tests",
            // Never on a board by chance: the acceptance suite takes a real device whenever
            // KERFMETER_PORT is set (`cargo xtask hil --port` is the way to it).
            // The plan crate's recompensation property compares with GEOS, through shapely in
            // the project's venv (issue 32 §4).
            Box::new(|| {
                python::ensure_venv(&python::PEERS)?;
                run_cmd(
                    cargo()
                        .args(["test", "--workspace"])
                        .env_remove("KERFMETER_PORT"),
                )
            }),
        ),
        (
            // Debian's PostgreSQL, installed when missing, started in a temporary folder as an
            // unprivileged user and stopped afterwards (xtask/src/postgres.rs).
            "history against PostgreSQL",
            Box::new(postgres::test_history),
        ),
        (
            "recompensation against boxes.py's own plans",
            Box::new(recompensation::test),
        ),
        (
            "python package (pip install ./host-lib/python, pytest)",
            Box::new(python::test_package),
        ),
        (
            "web page in headless Chromium, WebSocket clients",
            Box::new(browser::test_web),
        ),
        (
            "robustness sweep (short)",
            // Fails on a panic, a draw that ends in neither a reading nor a typed fault or
            // refusal, a motor left unsafe, or an unflagged wrong reading (only reported with
            // --lenient-robustness).
            Box::new(|| {
                robustness(
                    &RobustnessArgs {
                        draws: TEST_SWEEP_DRAWS,
                        seed: 1,
                        held: Vec::new(),
                        force_n: None,
                        json: false,
                        strict: !args.lenient_robustness,
                        tolerance_um: None,
                        replay: None,
                        seeds: None,
                        ablate: false,
                    },
                    false,
                )
            }),
        ),
        (
            "docs",
            Box::new(|| {
                run_cmd(
                    cargo()
                        .args(["doc", "--workspace", "--no-deps"])
                        .env("RUSTDOCFLAGS", "-D warnings"),
                )
            }),
        ),
        (
            "firmware image (esp32c3), flashable",
            Box::new(|| {
                let report = firmware::build(firmware::Chip::C3)?;
                firmware::save_image(&report).map(|_| ())
            }),
        ),
        (
            "firmware image (esp32c6)",
            Box::new(|| firmware::build(firmware::Chip::C6).map(|_| ())),
        ),
        (
            "on-target tests build (esp32c3)",
            Box::new(firmware::build_on_target_tests),
        ),
        (
            "fuzz",
            Box::new(|| {
                fuzz::run(&fuzz::FuzzArgs {
                    seconds: args.fuzz_seconds,
                    target: None,
                })
            }),
        ),
    ];

    let mut results = Vec::new();
    for (name, step) in &steps {
        eprintln!("\n=== {name}");
        let start = Instant::now();
        let outcome = step();
        if let Err(e) = &outcome {
            eprintln!("!!! {name}: {e:#}");
        }
        results.push((*name, outcome.is_ok(), start.elapsed()));
    }

    let failed = results.iter().filter(|r| !r.1).count();
    eprintln!("\n=== summary");
    for (name, ok, took) in &results {
        eprintln!(
            "{:>6}  {:>6.1}s  {name}",
            if *ok { "ok" } else { "FAILED" },
            took.as_secs_f64()
        );
    }
    println!(
        "xtask: {} passed, {} failed",
        results.len() - failed,
        failed
    );
    if failed > 0 {
        bail!("{failed} check(s) failed");
    }
    Ok(())
}
