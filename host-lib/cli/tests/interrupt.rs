//! Ctrl-C, SIGTERM and SIGHUP during a command that moves the motor: the CLI aborts the device,
//! waits for it to report its motor at rest, says so in one line and exits 128 + the signal's
//! number. Against the twin served on a pseudo-terminal by `kerfmeter-twin`, a process of its
//! own (a `--sim` twin dies with the CLI, so it could not tell), in real time, with
//! `--log-motor`: the twin prints each change of its motor bridge, as a scope on the G2's PWM
//! and SLP pins would show it, and the test times the line's arrival from the signal.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

/// Longest the motor may take to be safe after the signal in these tests. The device's own
/// host-silence check would stop it after a second, with a `HostSilent` fault latched (checked
/// apart); the figures measured are printed (`--nocapture`) for the note, not asserted on.
const SAFE_WITHIN: Duration = Duration::from_millis(500);

/// A twin on a pseudo-terminal in its own process, its motor edges timed as they arrive.
struct Twin {
    child: Child,
    port: String,
    edges: Receiver<(Instant, String)>,
}

impl Twin {
    fn start() -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
            .args(["--realtime", "--log-motor"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the kerfmeter-twin binary runs");
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        let port = lines.next().unwrap().unwrap();
        let (tx, edges) = channel();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                if tx.send((Instant::now(), line)).is_err() {
                    break;
                }
            }
        });
        Self { child, port, edges }
    }

    /// Wait for the next motor line that contains `what`; when it arrived.
    fn wait_for(&self, what: &str, limit: Duration) -> Instant {
        let deadline = Instant::now() + limit;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let (at, line) = self
                .edges
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("no `{what}` from the twin within {limit:?}"));
            if line.contains(what) {
                return at;
            }
        }
    }

    fn kerfmeter(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
            .arg("--port")
            .arg(&self.port)
            .args(args)
            .env_remove("KERFMETER_DB")
            .output()
            .unwrap()
    }

    /// Start `args` on the twin, and once the motor is driven and `after` has passed, send
    /// `signal`. The command's output, and the time from the signal to the motor's safe state.
    fn interrupt(&self, args: &[&str], after: Duration, signal: &str) -> (Output, Duration) {
        let child = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
            .arg("--port")
            .arg(&self.port)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        self.wait_for("motor unsafe", Duration::from_secs(20));
        std::thread::sleep(after);
        let sent = Instant::now();
        let killed = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let safe = self.wait_for("motor safe", Duration::from_secs(5));
        let out = child.wait_with_output().unwrap();
        (out, safe.saturating_duration_since(sent))
    }

    /// The device's state and latched fault, from `status --json`.
    fn state(&self) -> (String, serde_json::Value) {
        let out = self.kerfmeter(&["status", "--json"]);
        assert!(out.status.success(), "{out:?}");
        let status: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        (status["state"].to_string(), status["fault"].clone())
    }
}

impl Drop for Twin {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `args` interrupted by `signal` mid-motion: exit `code`, one line saying the motor is at
/// rest, the twin's motor safe within [`SAFE_WITHIN`], idle, and no fault latched.
fn stops_the_motor(twin: &Twin, args: &[&str], after_ms: u64, signal: &str, code: i32) {
    let (out, latency) = twin.interrupt(args, Duration::from_millis(after_ms), signal);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!(
        "{signal} during `{}`: motor safe {:.1} ms after the signal",
        args.join(" "),
        latency.as_secs_f64() * 1000.0
    );
    assert_eq!(out.status.code(), Some(code), "{signal} {args:?}: {stderr}");
    let last = stderr.lines().last().unwrap_or_default();
    assert!(
        last.contains("the device aborted and reports its motor at rest"),
        "{signal} {args:?}: {stderr}"
    );
    assert!(latency < SAFE_WITHIN, "{signal} {args:?}: {latency:?}");
    // Well after the device's host-silence window (1 s): an abort, not the watchdog.
    std::thread::sleep(Duration::from_millis(1500));
    let (state, fault) = twin.state();
    assert_eq!(state, "\"idle\"", "{signal} {args:?}");
    assert!(fault.is_null(), "{signal} {args:?}: {fault}");
}

#[test]
fn every_signal_during_a_run_stops_the_motor_and_exits_128_plus_its_number() {
    let twin = Twin::start();
    for (signal, code) in [("-INT", 130), ("-TERM", 143), ("-HUP", 129)] {
        stops_the_motor(&twin, &["run"], 300, signal, code);
    }
}

#[test]
fn a_signal_during_a_reset_a_self_test_or_a_map_stops_the_motor() {
    let twin = Twin::start();
    // Leave the hub away from zero, so that the reset turns it back.
    stops_the_motor(&twin, &["run"], 600, "-INT", 130);
    stops_the_motor(&twin, &["reset"], 0, "-TERM", 143);
    stops_the_motor(&twin, &["self-test"], 50, "-INT", 130);
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("map.json");
    let map = map.to_str().unwrap();
    let args = [
        "map",
        "--yes",
        "--cols",
        "1",
        "--rows",
        "1",
        "--per-cell",
        "1",
        "-o",
        map,
    ];
    stops_the_motor(&twin, &args, 300, "-HUP", 129);
    assert!(!std::path::Path::new(map).exists());
}

#[test]
fn a_signal_during_a_bringups_self_test_or_its_gauge_run_stops_the_motor_and_saves_nothing() {
    let twin = Twin::start();
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("bringup");
    let report = report.to_str().unwrap();
    // Every question answered by a flag: no prompt, whatever stdin is.
    let args = |gauge: &'static str| {
        [
            "bringup",
            "--meter-v",
            "12",
            "--hub-turned",
            "cw",
            gauge,
            "--report",
            report,
        ]
    };
    stops_the_motor(&twin, &args("--no-gauge"), 50, "-INT", 130);
    // Later in the bring-up: the self-test's last turns, or the run on the gauge after it.
    stops_the_motor(&twin, &args("--gauge-placed"), 600, "-TERM", 143);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn with_json_the_interruption_is_one_error_object() {
    let twin = Twin::start();
    let (out, _) = twin.interrupt(&["run", "--json"], Duration::from_millis(200), "-INT");
    assert_eq!(out.status.code(), Some(130));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let error = report["error"].as_str().unwrap();
    assert!(error.starts_with("interrupted (SIGINT)"), "{error}");
}
