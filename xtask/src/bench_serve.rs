//! `cargo xtask bench-serve`: many WebSocket clients watch the device while another measures
//! (issue 32 §3). A fresh `kerfmeter --sim --sim-realtime serve` (release build, same seed) runs
//! the measurement alone, then again under the load: `--clients` watchers (default 40), each
//! polling `status` and `get_kerf_value` in turn at `--hz` (default 50) over its own WebSocket
//! (Python's `websockets`, in the project's venv). It prints each case's JSON line (calls,
//! errors, p50 and p99 latency, the kerf) and compares the kerfs. A real-time twin: a run the
//! load delayed would show a fault (`HostSilent`, `StepOverrun`) or a different kerf.
//!
//! This is a benchmark, not a test: `cargo xtask test` does not run it (the web tests assert
//! the same behaviour at a smaller load, without timing it).

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

use anyhow::{Context, Result, bail};

use crate::{python, root};

/// The benchmark's options.
#[derive(clap::Args)]
pub struct BenchServeArgs {
    /// Watching clients under load.
    #[arg(long, default_value_t = 40)]
    clients: u32,
    /// Each watcher's polls per second.
    #[arg(long, default_value_t = 50.0)]
    hz: f64,
    /// Measurements in each case.
    #[arg(long, default_value_t = 1)]
    runs: u32,
}

/// Run the benchmark.
pub fn run(args: &BenchServeArgs) -> Result<()> {
    let venv_python = python::ensure_venv(&[crate::browser::WEBSOCKETS])?;
    crate::build_cli(true)?;
    let script = root().join("host-lib/cli/tests/web/serve_load.py");
    let mut kerfs = Vec::new();
    for clients in [0, args.clients] {
        let mut server = Server::start()?;
        let out = Command::new(&venv_python)
            .arg(&script)
            .arg(format!("ws://127.0.0.1:{}/rpc", server.port))
            .args(["--clients", &clients.to_string()])
            .args(["--hz", &args.hz.to_string()])
            .args(["--runs", &args.runs.to_string()])
            .output()
            .context("cannot run serve_load.py")?;
        server.stop();
        let line = String::from_utf8_lossy(&out.stdout).trim().to_owned();
        println!("{line}");
        if !out.status.success() {
            eprintln!("{}", String::from_utf8_lossy(&out.stderr));
            bail!("calls failed under {clients} clients (see the line above)");
        }
        let report: serde_json::Value = serde_json::from_str(&line)?;
        kerfs.push(report["kerf_um"].clone());
    }
    println!("kerf alone {} µm, under load {} µm", kerfs[0], kerfs[1]);
    Ok(())
}

/// A release `kerfmeter --sim --sim-realtime serve` on a free loopback port.
struct Server {
    child: Child,
    port: u16,
}

impl Server {
    fn start() -> Result<Self> {
        let binary = root().join("target/release/kerfmeter");
        let db = std::env::temp_dir().join(format!(
            "kerfmeter-bench-serve-{}.sqlite3",
            std::process::id()
        ));
        let _ = std::fs::remove_file(&db);
        let mut child = Command::new(binary)
            .args([
                "--sim",
                "--sim-realtime",
                "serve",
                "--listen",
                "127.0.0.1:0",
            ])
            .arg("--db")
            .arg(&db)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start kerfmeter serve")?;
        let stdout = child.stdout.take().expect("piped");
        for line in BufReader::new(stdout).lines() {
            let line = line?;
            if let Some(port) = line
                .split("127.0.0.1:")
                .nth(1)
                .and_then(|rest| rest.trim_end_matches('/').parse().ok())
            {
                return Ok(Self { child, port });
            }
        }
        bail!("the server printed no address")
    }

    fn stop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
