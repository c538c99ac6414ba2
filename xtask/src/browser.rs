//! The web step of `cargo xtask test` (`cargo xtask test-browser` alone): the server's page in a
//! real headless Chromium, and the WebSocket clients of docs/server.md, against `kerfmeter --sim serve`.
//!
//! The browser is Debian's `chromium` with its `chromium-driver` (the same source package, so
//! the driver always matches the browser), installed with apt-get when missing and this runs as
//! root; otherwise the step fails with the command to run. The tests are Python (pytest, in
//! `host-lib/cli/tests/web/`) driving the browser with Selenium, in the project's one venv (see
//! [`crate::python`]), which also holds `websockets` for the Python client of docs/server.md: one
//! language and one environment for everything the step runs, and a driver that talks to the
//! matching chromedriver with no browser download of its own. The JavaScript client runs on the
//! machine's Node.js (20 or later).

use std::path::Path;
use std::process::{Command, Stdio};

use anyhow::{Context, Result, bail};

use crate::{python, root, run_cmd};

/// Debian's browser and its WebDriver.
const CHROMIUM: &str = "/usr/bin/chromium";
const CHROMEDRIVER: &str = "/usr/bin/chromedriver";
/// The Debian packages that hold them.
const PACKAGES: [&str; 2] = ["chromium", "chromium-driver"];
/// The Python packages the tests use, pinned: the browser driver (needs Python 3.10 or later)
/// and the WebSocket library of docs/server.md's client (the newest that still runs on Python 3.9).
const PYTHON_PACKAGES: [&str; 2] = ["selenium==4.51.0", WEBSOCKETS];
/// The WebSocket client library of docs/server.md's client, the web tests and `bench-serve`.
pub const WEBSOCKETS: &str = "websockets==15.0.1";

/// Build the CLI, make sure the browser is there, and run the web tests.
pub fn test_web() -> Result<()> {
    ensure_chromium()?;
    let mut packages = vec![python::PYTEST];
    packages.extend(PYTHON_PACKAGES);
    let venv_python = python::ensure_venv(&packages)?;
    crate::build_cli(false)?;
    let kerfmeter = root().join("target").join("debug").join("kerfmeter");
    let tests = root()
        .join("host-lib")
        .join("cli")
        .join("tests")
        .join("web");
    run_cmd(
        Command::new(venv_python)
            .args(["-m", "pytest", "-v", "-p", "no:cacheprovider"])
            .arg(&tests)
            .env("KERFMETER", kerfmeter)
            .env("CHROMIUM", CHROMIUM)
            .env("CHROMEDRIVER", CHROMEDRIVER)
            // Selenium must not try to download a browser or a driver: both are given.
            .env("SE_OFFLINE", "true"),
    )
}

/// Chromium and its driver: present, or installed from the system's packages when possible.
fn ensure_chromium() -> Result<()> {
    if runs(CHROMIUM) && runs(CHROMEDRIVER) {
        return Ok(());
    }
    let install = format!(
        "apt-get update && apt-get install -y --no-install-recommends {}",
        PACKAGES.join(" ")
    );
    if !is_root() || !Path::new("/usr/bin/apt-get").exists() {
        bail!(
            "the browser test needs Debian's Chromium and its driver ({CHROMIUM}, {CHROMEDRIVER}); \
             install them as root: {install}"
        );
    }
    eprintln!("Chromium or its driver is missing: installing {PACKAGES:?} with apt-get");
    // A fresh machine may have no package lists yet: update them only when the install fails.
    if apt_install().is_err() {
        run_cmd(Command::new("apt-get").arg("update"))?;
        apt_install().with_context(|| format!("could not install Chromium; run: {install}"))?;
    }
    if !(runs(CHROMIUM) && runs(CHROMEDRIVER)) {
        bail!("{CHROMIUM} or {CHROMEDRIVER} still does not run after installing; run: {install}");
    }
    Ok(())
}

fn apt_install() -> Result<()> {
    run_cmd(
        Command::new("apt-get")
            .args(["install", "-y", "--no-install-recommends"])
            .args(PACKAGES)
            .env("DEBIAN_FRONTEND", "noninteractive"),
    )
}

/// Whether `program --version` runs and succeeds.
fn runs(program: &str) -> bool {
    Command::new(program)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

pub(crate) fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions and cannot fail.
    unsafe { libc::geteuid() == 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bodies of a Markdown page's fenced code blocks.
    fn code_blocks(markdown: &str) -> Vec<String> {
        let mut blocks = Vec::new();
        let mut open: Option<String> = None;
        for line in markdown.split_inclusive('\n') {
            match (&mut open, line.starts_with("```")) {
                (None, true) => open = Some(String::new()),
                (Some(_), true) => blocks.extend(open.take()),
                (Some(body), false) => body.push_str(line),
                (None, false) => {}
            }
        }
        blocks
    }

    /// The server's page shows the clients the web step runs, verbatim: what a reader copies
    /// works.
    #[test]
    fn the_docs_show_the_clients_verbatim() {
        let page = std::fs::read_to_string(root().join("docs").join("server.md")).unwrap();
        let blocks = code_blocks(&page);
        for name in ["client.py", "client.mjs"] {
            let path = root().join("examples").join("clients").join(name);
            let client = std::fs::read_to_string(&path).unwrap();
            assert!(
                blocks.contains(&client),
                "docs/server.md has no code block equal to {}: copy the file into it",
                path.display()
            );
        }
    }

    #[test]
    fn code_blocks_are_read_whole() {
        let text = "a\n```python\nx = 1\n\ny = 2\n```\nb\n```\nz\n```\n";
        assert_eq!(code_blocks(text), ["x = 1\n\ny = 2\n", "z\n"]);
    }
}
