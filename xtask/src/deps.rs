//! The library crates stay free of the front ends' dependencies: no CLI parser, web server,
//! async runtime, Python binding or plotting library in what a program that embeds the library
//! builds (issue 33). `cargo tree -e normal` of each library crate, with its default features,
//! is searched for the banned crates; a hit names the chain that pulls it in
//! (`cargo tree -i`), and the step fails.

use std::process::Command;

use anyhow::{Context, Result, bail};

use crate::cargo;

/// The crates that belong to a front end (the CLI, the server, Python, plots).
const BANNED: [&str; 5] = ["clap", "axum", "tokio", "pyo3", "plotters"];

/// The library crates (everything but the front ends, the firmware binary and the tooling).
const LIBRARIES: [&str; 9] = [
    "kerfmeter-protocol",
    "kerfmeter-grbl",
    "kerfmeter-ruida",
    "kerfmeter",
    "kerfmeter-plan",
    "kerfmeter-lightburn",
    "kerfmeter-history",
    "kerfmeter-app",
    "kerfmeter-twin",
];

/// Fail when a library crate's normal dependency tree holds a banned crate.
pub fn check_libraries() -> Result<()> {
    let mut found = Vec::new();
    for library in LIBRARIES {
        let tree =
            stdout_of(cargo().args(["tree", "-p", library, "-e", "normal", "--prefix", "none"]))?;
        for banned in BANNED {
            if tree
                .lines()
                .any(|line| line.split(' ').next() == Some(banned))
            {
                let chain =
                    stdout_of(cargo().args(["tree", "-p", library, "-e", "normal", "-i", banned]))?;
                found.push(format!("{library} depends on {banned}:\n{chain}"));
            }
        }
    }
    if !found.is_empty() {
        bail!(
            "a library crate pulls in a front end's dependency (they belong in the CLI, the server \
             or the Python package):\n{}",
            found.join("\n")
        );
    }
    eprintln!(
        "{} library crates free of {}",
        LIBRARIES.len(),
        BANNED.join(", ")
    );
    Ok(())
}

/// `cmd`'s stdout, or why it failed.
fn stdout_of(cmd: &mut Command) -> Result<String> {
    let out = cmd.output().context("cannot run cargo tree")?;
    if !out.status.success() {
        bail!(
            "cargo tree failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}
