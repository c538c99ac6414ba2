//! Host tools the tasks need: find them, and install the missing ones with `cargo install`.
//!
//! `cargo xtask test` must work on a fresh machine that has only Rust, so every tool it uses
//! beyond cargo itself (espflash, cargo-fuzz, probe-rs) is installed on first use, saying what
//! it installs and roughly how long that takes, and failing loudly if it cannot.

use std::process::{Command, Stdio};

use anyhow::Result;

use crate::run_cmd;

/// A tool installed from crates.io.
pub struct CargoTool {
    /// What to call it in messages.
    pub name: &'static str,
    /// The crate `cargo install` takes.
    pub crate_name: &'static str,
    /// How long the first install takes, for the message.
    pub install_time: &'static str,
}

/// Install `tool` with `cargo install --locked` unless `probe` (a command that prints its version)
/// already succeeds.
pub fn ensure(tool: &CargoTool, mut probe: Command) -> Result<()> {
    let present = probe
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if present {
        return Ok(());
    }
    eprintln!(
        "{} is missing: installing it (`cargo install {} --locked`, {} once)",
        tool.name, tool.crate_name, tool.install_time
    );
    run_cmd(
        Command::new("cargo")
            .args(["install", tool.crate_name, "--locked"])
            .env_remove("RUSTUP_TOOLCHAIN"),
    )
}
