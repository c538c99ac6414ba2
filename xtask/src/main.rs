//! `cargo xtask`: the project's build and check entry points (see `cargo xtask --help`).
//!
//! Everything a developer or CI runs goes through here, so that what CI checks is exactly what
//! the README tells a newcomer to run.

mod firmware;

use anyhow::Result;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "cargo xtask", about = "Kerfmeter build and check tasks")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Build the firmware image for a chip (release) and print its flash and RAM use.
    Firmware(firmware::FirmwareArgs),
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Firmware(args) => firmware::run(&args),
    }
}
