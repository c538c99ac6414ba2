//! The project's Python: one virtual environment (`target/python-venv`) made with the machine's
//! `python3` and filled with pip, and the Python package's test step.
//!
//! `cargo xtask test` builds and installs `host-lib/python` (the `kerfmeter` package) into it
//! and runs its pytest suite against the twin, against ezdxf and GEOS (shapely) for the DXF
//! plans, and against MeerK40t's Ruida code and `ruida-pa` (in a venv of its own,
//! `target/ruida-pa-venv`) for the Ruida crate's streams (written by the crate's `encode`
//! example, built here). This needs `python3` (3.9 or later) with its
//! `venv` module, and PyPI for maturin and pytest on first use; without them the step fails and
//! says what is missing. The wheel is built by maturin into the workspace's own `target/` in the
//! dev profile, so it reuses what `cargo test --workspace` already compiled instead of building
//! the whole dependency tree again in release.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};

use crate::{root, run_cmd};

/// What the environment is made with.
const PYTHON: &str = "python3";
/// The test runner (also of the web step); pinned below the next major version.
pub const PYTEST: &str = "pytest>=7,<10";
/// The build backend and the test runner; pinned below the next major versions.
const TOOLS: [&str; 2] = ["maturin>=1.9.4,<2", PYTEST];
/// The independent implementations the package's tests check the plans against (issue 32):
/// ezdxf opens and audits every DXF written, GEOS (through shapely) buffers the same cuts (and,
/// in the host tests, the polygons of the plan crate's recompensation property). MeerK40t's
/// Ruida emulator and parser decode every stream the Ruida encoder writes (issue 35,
/// `tests/test_ruida_peer.py`); pinned exactly, as `docs/ruida.md` names the version checked
/// (its core needs only pyusb, pyserial and numpy).
pub const PEERS: [&str; 3] = ["ezdxf>=1.4,<2", "shapely>=2,<3", "meerk40t==0.9.9100"];

/// The second Ruida decoder, `ruida-pa`, whose `rpa` reads the encoder's programs as `.rd` files
/// in `tests/test_ruida_peer.py` (issue 35). It has a venv of its own: it pulls in bokeh,
/// textual and rpyc, and installs top-level packages named `protocols` and `rpalib`, which have
/// no place beside the package's.
const RUIDA_PA: &str = "ruida-pa==0.23.0";

/// LibreCAD's part library (Debian's `librecad-data`): real-world DXF drawings the package's
/// tests dilate and ezdxf audits; installed with apt-get when missing and this runs as root.
const LIBRECAD_PACKAGE: &str = "librecad-data";
const LIBRECAD_DIR: &str = "/usr/share/librecad";

/// The environment's directory.
fn venv_dir() -> PathBuf {
    root().join("target").join("python-venv")
}

/// A program of the environment (`python`, `pip`, `pytest`).
pub fn venv_bin(name: &str) -> PathBuf {
    venv_dir().join("bin").join(name)
}

/// Make the environment if it is missing and install `packages` into it (pip skips those
/// already satisfied). Returns its `python`.
pub fn ensure_venv(packages: &[&str]) -> Result<PathBuf> {
    let python = venv_bin("python");
    if !has_pip(&python) {
        make_venv()?;
    }
    if !packages.is_empty() {
        run_cmd(
            Command::new(&python)
                .args([
                    "-m",
                    "pip",
                    "install",
                    "--quiet",
                    "--disable-pip-version-check",
                ])
                .args(packages),
        )
        .context("pip could not install the packages (is PyPI reachable?)")?;
    }
    Ok(python)
}

/// Whether `python` runs and has pip: false for a missing environment and for one left half
/// made (without Debian's python3-venv, `python3 -m venv` fails after creating `bin/python`).
fn has_pip(python: &std::path::Path) -> bool {
    Command::new(python)
        .args(["-m", "pip", "--version"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Make the environment afresh (removing a half-made one first); on failure remove what was
/// made, so that the next run tries again instead of using it.
fn make_venv() -> Result<()> {
    let dir = venv_dir();
    if dir.exists() {
        std::fs::remove_dir_all(&dir)
            .with_context(|| format!("cannot remove the broken {}", dir.display()))?;
    }
    let made = Command::new(PYTHON)
        .arg("-m")
        .arg("venv")
        .arg(&dir)
        .status();
    let failed = match made {
        Ok(s) if s.success() && has_pip(&venv_bin("python")) => return Ok(()),
        Ok(s) => format!(
            "`{PYTHON} -m venv {}` failed ({s}) or made no pip: install Python 3.9+ with its venv module (Debian: apt-get install python3-venv)",
            dir.display()
        ),
        Err(e) => format!("cannot run {PYTHON} ({e}): install Python 3.9 or later"),
    };
    let _ = std::fs::remove_dir_all(&dir);
    bail!(failed)
}

/// The PATH with the environment's programs first.
fn path_with_venv() -> std::ffi::OsString {
    let mut dirs = vec![venv_dir().join("bin")];
    dirs.extend(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    ));
    std::env::join_paths(dirs).unwrap_or_default()
}

/// Build and install the `kerfmeter` Python package into the environment, then run its tests.
pub fn test_package() -> Result<()> {
    let python = ensure_venv(&[&TOOLS[..], &PEERS[..]].concat())?;
    let package = root().join("host-lib").join("python");
    run_cmd(
        Command::new(&python)
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
            ])
            // maturin is already in the environment: no isolated build environment to fetch.
            .arg("--no-build-isolation")
            .arg("--force-reinstall")
            .arg("--no-deps")
            .arg(&package)
            // The build backend runs the environment's `maturin` from the PATH.
            .env("PATH", path_with_venv())
            .env("CARGO_TARGET_DIR", root().join("target"))
            .env("MATURIN_PEP517_ARGS", "--profile dev"),
    )?;
    ensure_librecad_parts()?;
    let ruida_encoder = build_ruida_encoder()?;
    let ruida_streams = build_ruida_driver_streams()?;
    let ruida_pa = ensure_ruida_pa()?;
    run_cmd(
        Command::new(&python)
            .args(["-m", "pytest", "-q"])
            .arg(package.join("tests"))
            .env("KERFMETER_LIBRECAD_PARTS", LIBRECAD_DIR)
            .env("KERFMETER_RUIDA_ENCODER", ruida_encoder)
            .env("KERFMETER_RUIDA_STREAMS", ruida_streams)
            .env("KERFMETER_RUIDA_PA", ruida_pa),
    )
}

/// `ruida-pa` in `target/ruida-pa-venv` (made when missing or broken); its `rpa` program.
fn ensure_ruida_pa() -> Result<PathBuf> {
    let dir = root().join("target").join("ruida-pa-venv");
    let python = dir.join("bin").join("python");
    if !has_pip(&python) {
        if dir.exists() {
            std::fs::remove_dir_all(&dir)
                .with_context(|| format!("cannot remove the broken {}", dir.display()))?;
        }
        run_cmd(Command::new(PYTHON).args(["-m", "venv"]).arg(&dir))
            .context("cannot make ruida-pa's venv (Debian: apt-get install python3-venv)")?;
    }
    run_cmd(Command::new(&python).args([
        "-m",
        "pip",
        "install",
        "--quiet",
        "--disable-pip-version-check",
        RUIDA_PA,
    ]))
    .context("pip could not install ruida-pa (is PyPI reachable?)")?;
    Ok(dir.join("bin").join("rpa"))
}

/// Build the Ruida crate's `encode` example, which writes the streams MeerK40t decodes in
/// `tests/test_ruida_peer.py`; its path.
fn build_ruida_encoder() -> Result<PathBuf> {
    run_cmd(crate::cargo().args(["build", "-p", "kerfmeter-ruida", "--example", "encode"]))?;
    let name = format!("encode{}", std::env::consts::EXE_SUFFIX);
    Ok(root()
        .join("target")
        .join("debug")
        .join("examples")
        .join(name))
}

/// Build the host library's `ruida_streams` example, which writes every stream the Ruida driver
/// sends in its scenarios (on the simulated controller) for MeerK40t to decode in
/// `tests/test_ruida_driver_peer.py`; its path.
fn build_ruida_driver_streams() -> Result<PathBuf> {
    run_cmd(crate::cargo().args([
        "build",
        "-p",
        "kerfmeter",
        "--features",
        "sim",
        "--example",
        "ruida_streams",
    ]))?;
    let name = format!("ruida_streams{}", std::env::consts::EXE_SUFFIX);
    Ok(root()
        .join("target")
        .join("debug")
        .join("examples")
        .join(name))
}

/// Install LibreCAD's part library when it is missing (apt-get, as root); otherwise say how.
fn ensure_librecad_parts() -> Result<()> {
    if Path::new(LIBRECAD_DIR).join("library").is_dir() {
        return Ok(());
    }
    let install = format!("apt-get install -y --no-install-recommends {LIBRECAD_PACKAGE}");
    if !crate::browser::is_root() || !Path::new("/usr/bin/apt-get").exists() {
        bail!("LibreCAD's part library ({LIBRECAD_DIR}) is missing: run `{install}` as root");
    }
    eprintln!("LibreCAD's part library is missing: installing {LIBRECAD_PACKAGE} with apt-get");
    let apt = || {
        run_cmd(Command::new("apt-get").args([
            "install",
            "-y",
            "-q",
            "--no-install-recommends",
            LIBRECAD_PACKAGE,
        ]))
    };
    if apt().is_err() {
        run_cmd(Command::new("apt-get").arg("update"))?;
        apt().with_context(|| format!("could not install {LIBRECAD_PACKAGE}; run: {install}"))?;
    }
    Ok(())
}
