//! `cargo xtask fuzz`: the coverage-guided fuzz targets of the protocol and the plan readers
//! (`fuzz/`), run with cargo-fuzz on the nightly toolchain, seeded from `fuzz/seeds/<target>/`
//! and given `fuzz/dicts/<target>.dict` (the format's words) where there is one. Installs
//! cargo-fuzz when it is missing.

use std::process::Command;

use anyhow::{Context, Result, bail};

use crate::{root, run_cmd, tools};

/// The fuzz targets in `fuzz/fuzz_targets`.
pub const TARGETS: [&str; 3] = ["deframe", "link", "plan_readers"];

#[derive(clap::Args)]
pub struct FuzzArgs {
    /// Seconds to fuzz each target.
    #[arg(long, default_value_t = 60)]
    pub seconds: u64,
    /// Only this target (default: all).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(TARGETS))]
    pub target: Option<String>,
}

/// A `cargo +nightly` command, with the outer cargo's toolchain variables removed so that the
/// nightly toolchain is used all the way down (cargo-fuzz calls cargo itself).
fn nightly_cargo() -> Command {
    let mut cmd = Command::new("cargo");
    cmd.arg("+nightly")
        .current_dir(root())
        .env_remove("RUSTUP_TOOLCHAIN")
        .env_remove("CARGO")
        .env_remove("RUSTC")
        .env_remove("RUSTDOC");
    cmd
}

fn ensure_tools() -> Result<()> {
    let toolchains = Command::new("rustup")
        .args(["toolchain", "list"])
        .output()
        .context("rustup is needed to find the nightly toolchain")?;
    if !String::from_utf8_lossy(&toolchains.stdout)
        .lines()
        .any(|l| l.starts_with("nightly"))
    {
        bail!(
            "fuzzing needs a nightly toolchain (`rustup toolchain install nightly`); none is installed"
        );
    }
    let tool = tools::CargoTool {
        name: "cargo-fuzz",
        crate_name: "cargo-fuzz",
        install_time: "a few minutes",
    };
    let mut probe = nightly_cargo();
    probe.args(["fuzz", "--version"]);
    tools::ensure(&tool, probe)
}

pub fn run(args: &FuzzArgs) -> Result<()> {
    ensure_tools()?;
    let targets: Vec<&str> = match &args.target {
        Some(t) => vec![t.as_str()],
        None => TARGETS.to_vec(),
    };
    for target in targets {
        let corpus = root().join("fuzz/corpus").join(target);
        std::fs::create_dir_all(&corpus)?;
        let seeds = root().join("fuzz/seeds").join(target);
        let mut cmd = nightly_cargo();
        // `-O`: the assertions are the fuzz crate's profile's (see fuzz/Cargo.toml).
        cmd.args(["fuzz", "run", "-O", target]).arg(&corpus);
        if seeds.is_dir() {
            cmd.arg(&seeds);
        }
        cmd.args([
            "--",
            &format!("-max_total_time={}", args.seconds),
            "-rss_limit_mb=2048",
        ]);
        // The formats' words, so that mutations get past the tokenizers (`fuzz/dicts/`).
        let dict = root().join("fuzz/dicts").join(format!("{target}.dict"));
        if dict.is_file() {
            cmd.arg(format!("-dict={}", dict.display()));
        }
        run_cmd(&mut cmd).with_context(|| {
            format!(
                "fuzz target {target} failed: the crashing input is in fuzz/artifacts/{target}/"
            )
        })?;
    }
    Ok(())
}
