//! `cargo xtask cli-outputs`: every command of a `kerfmeter` binary, in text and `--json`, run on
//! the twins and the repository's example plans, with what it printed and wrote kept in a folder.
//!
//! A reorganisation must leave the CLI's output byte for byte the same. Run this with the binary
//! from before the change and with the one after, into two folders, and `diff -r` them. Each
//! case runs in a folder of its own, with its own history database and home, so that nothing of
//! one case (a history id, a LightBurn pairing) shows in another. The twin's readings can move by
//! tenths of a µm with the machine's scheduling (see `--sim-seed`): such a difference is noise,
//! any other is a change of behaviour.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};

use crate::root;

#[derive(clap::Args)]
pub struct CliOutputsArgs {
    /// The `kerfmeter` binary to run (e.g. target/debug/kerfmeter, or a copy kept from before).
    #[arg(long)]
    kerfmeter: PathBuf,
    /// A folder to create, one sub-folder per case (it must not exist).
    #[arg(long)]
    out: PathBuf,
}

/// Each case's command line; `{plans}` is the plan crate's fixtures, `{examples}` the examples.
/// The help of every command comes first, then the device's calls, the plans, the cutter.
const CASES: &[&str] = &[
    "--help",
    "info --help",
    "status --help",
    "run --help",
    "kerf --help",
    "reset --help",
    "abort --help",
    "clear-fault --help",
    "confirm-zero --help",
    "self-test --help",
    "bringup --help",
    "config --help",
    "config set --help",
    "map --help",
    "gauge --help",
    "dilate --help",
    "cut --help",
    "gcode --help",
    "lightburn --help",
    "lightburn apply --help",
    "job --help",
    "history --help",
    "serve --help",
    "--sim info",
    "--sim status",
    "--sim run",
    "--sim run --samples 3 --label oak",
    "--sim run --sim-fault magnet-lost",
    "--sim run --sim-fault no-inset",
    "--sim run --plot curve.svg",
    "--sim kerf",
    "--sim reset",
    "--sim abort",
    "--sim clear-fault",
    "--sim confirm-zero",
    "--sim self-test",
    "--sim bringup --report bringup",
    "--sim --sim-motor-leads-swapped bringup --report miswired",
    "--sim --sim-plant supply_v=28 bringup --report high",
    "--sim config get",
    "--sim config set --max-current-a 2.5",
    "--sim map --cols 2 --rows 2 --per-cell 1 -o map.json",
    "--sim history",
    "gauge -o gauge.svg",
    "gauge -o gauge.dxf",
    "gauge -o gauge.gcode --feed-mm-per-min 600 --power-percent 80",
    "dilate {examples}/box-parts.svg --kerf-um 150 -o out.svg",
    "dilate {examples}/box-parts.svg --kerf-um 150 --dry-run",
    "dilate {plans}/cad_plate.dxf --kerf-um 150 -o out.dxf",
    "dilate {plans}/inkscape_layers.svg --kerf-um 120 -o out.svg",
    "dilate {plans}/box_generator.svg --kerf-um 100 --recompensate -o out.svg",
    "dilate {examples}/missing.svg --kerf-um 150 -o out.svg",
    "gcode {examples}/box-parts.svg --kerf-um 150 -o out.gcode --feed-mm-per-min 600 --power-percent 80",
    "gcode {plans}/cad_plate.dxf --kerf-um 150 -o out.gcode --feed-mm-per-min 600 --power-percent 80",
    "--sim job {examples}/box-parts.svg --cutter sim -o out.svg --gcode-out out.gcode",
    "--sim job {examples}/box-parts.svg --cutter sim -o dry.svg --dry-run",
    "--sim job {examples}/box-parts.svg --cutter sim -o far.svg --gauge-at-mm 900,10",
    "--sim lightburn apply --kerf-um 150",
];

pub fn run(args: &CliOutputsArgs) -> Result<()> {
    if args.out.exists() {
        bail!("{} exists: give a new folder", args.out.display());
    }
    let kerfmeter = fs::canonicalize(&args.kerfmeter)
        .with_context(|| format!("no binary at {}", args.kerfmeter.display()))?;
    let plans = root().join("host-lib/plan/tests/fixtures");
    let examples = root().join("examples");
    for (i, case) in CASES.iter().enumerate() {
        let line = case
            .replace("{plans}", &plans.to_string_lossy())
            .replace("{examples}", &examples.to_string_lossy());
        for json in [false, true] {
            let dir = args
                .out
                .join(format!("{i:02}{}", if json { "-json" } else { "" }));
            run_case(&kerfmeter, &line, json, &dir)?;
        }
    }
    eprintln!("{} cases in {}", CASES.len() * 2, args.out.display());
    Ok(())
}

/// Run one command line in `dir` (created), keeping its command, stdout, stderr and exit code.
fn run_case(kerfmeter: &Path, line: &str, json: bool, dir: &Path) -> Result<()> {
    fs::create_dir_all(dir)?;
    let dir = fs::canonicalize(dir)?;
    let mut cmd = Command::new(kerfmeter);
    cmd.current_dir(&dir)
        .env("HOME", &dir)
        .env("XDG_DATA_HOME", dir.join("data"))
        .env("XDG_CONFIG_HOME", dir.join("config"))
        .env_remove("KERFMETER_PORT")
        .env_remove("KERFMETER_DB")
        .args(["--db", "history.sqlite3"]);
    if json {
        cmd.arg("--json");
    }
    cmd.args(line.split_whitespace());
    let out = cmd
        .output()
        .with_context(|| format!("cannot start {}", kerfmeter.display()))?;
    fs::write(
        dir.join("command"),
        format!("{line}{}\n", if json { " --json" } else { "" }),
    )?;
    fs::write(dir.join("stdout"), &out.stdout)?;
    fs::write(dir.join("stderr"), &out.stderr)?;
    fs::write(dir.join("exit"), format!("{:?}\n", out.status.code()))?;
    // The database is binary and carries times; what `history` prints of it is compared instead.
    let _ = fs::remove_file(dir.join("history.sqlite3"));
    Ok(())
}
