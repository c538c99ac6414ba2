//! `cargo xtask`: the project's build and check entry points (see `cargo xtask --help`).
//!
//! Everything a developer or CI runs goes through here, so that what CI checks is exactly what
//! the README tells a newcomer to run. `cargo xtask test` installs what it needs (the RISC-V
//! targets, cargo-fuzz) and fails loudly when something it needs cannot be had.

mod firmware;
mod fuzz;

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
    /// host tests, docs, the firmware images for the C3 and C6 with their sizes, a short fuzz run.
    Test(TestArgs),
    /// Build the firmware image for a chip (release) and print its flash and RAM use.
    Firmware(firmware::FirmwareArgs),
    /// Build the firmware and write it to a board (real hardware: needs --port).
    Flash(firmware::FlashArgs),
    /// Run the protocol fuzz targets (cargo-fuzz on the nightly toolchain).
    Fuzz(fuzz::FuzzArgs),
    /// The twin's accuracy table: kerf 50–430 µm × stock 3–6 mm, 20 seeds per point.
    Accuracy(AccuracyArgs),
}

#[derive(clap::Args)]
struct AccuracyArgs {
    /// Seeds per point.
    #[arg(long, default_value_t = 20)]
    seeds: u32,
    /// A smaller grid (3 kerfs × 2 stocks × 5 seeds).
    #[arg(long)]
    quick: bool,
}

#[derive(clap::Args)]
struct TestArgs {
    /// Seconds of fuzzing per fuzz target.
    #[arg(long, default_value_t = 20)]
    fuzz_seconds: u64,
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Cmd::Test(args) => test(&args),
        Cmd::Firmware(args) => firmware::run(&args),
        Cmd::Flash(args) => firmware::flash(&args),
        Cmd::Fuzz(args) => fuzz::run(&args),
        Cmd::Accuracy(args) => accuracy(&args),
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

fn accuracy(args: &AccuracyArgs) -> Result<()> {
    let mut cmd = cargo();
    cmd.args([
        "run",
        "--release",
        "-p",
        "kerfmeter-firmware",
        "--features",
        "twin",
        "--example",
        "accuracy",
        "--",
    ]);
    cmd.args(["--seeds", &args.seeds.to_string()]);
    if args.quick {
        cmd.arg("--quick");
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
            "rustfmt",
            Box::new(|| {
                run_cmd(cargo().args(["fmt", "--all", "--check"]))?;
                run_cmd(cargo().args(["fmt", "--check", "--manifest-path", "fuzz/Cargo.toml"]))
            }),
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
            Box::new(|| run_cmd(cargo().args(["test", "--workspace"]))),
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
