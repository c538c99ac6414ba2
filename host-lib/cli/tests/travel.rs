//! `kerfmeter job` and `kerfmeter cut` against a cutter twin with GRBL's default 200 × 200 mm of
//! travel (and 50 mm of Z), served by `kerfmeter-twin` in another process that prints every
//! G-code line it receives: every move outside the travel is refused with exit 4 before a line
//! is sent, naming the number, the machine's limit and the flag that changes it; the bed
//! defaults to the travel; and what stays inside runs without hitting an end stop.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Arc, Mutex};

/// Run `kerfmeter` with `args`, recording into a history of its own.
fn kerfmeter(args: &[&str]) -> Output {
    let history = tempfile::tempdir().unwrap();
    Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        .env_remove("KERFMETER_PORT")
        .env_remove("KERFMETER_CUTTER")
        .env("KERFMETER_DB", history.path().join("history.sqlite3"))
        .output()
        .expect("the kerfmeter binary runs")
}

/// What it said: stderr, and stdout (where `--json` puts an error).
fn stderr(out: &Output) -> String {
    let said = [&out.stderr, &out.stdout].map(|s| String::from_utf8_lossy(s).into_owned());
    said.join("\n")
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A `kerfmeter-twin` process: its address (first line) and everything it prints after.
struct Twin {
    child: Child,
    address: String,
    said: Arc<Mutex<Vec<String>>>,
}

impl Twin {
    fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the kerfmeter-twin binary runs");
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        let address = lines.next().unwrap().unwrap().trim().to_owned();
        let said = Arc::new(Mutex::new(Vec::new()));
        let keep = said.clone();
        std::thread::spawn(move || {
            for line in lines.map_while(Result::ok) {
                keep.lock().unwrap().push(line);
            }
        });
        Self {
            child,
            address,
            said,
        }
    }

    /// A cutter twin of 200 × 200 × 50 mm printing what it receives, with `extra` flags.
    fn cutter(extra: &[&str]) -> Self {
        let base = [
            "--cutter",
            "--cutter-travel-mm",
            "200,200,50",
            "--cutter-print-lines",
        ];
        Self::start(&[&base[..], extra].concat())
    }

    /// The G-code lines it received, and the end stops it hit, so far (after a moment for the
    /// last to be printed).
    fn received(&self) -> (Vec<String>, Vec<String>) {
        std::thread::sleep(std::time::Duration::from_millis(100));
        let said = self.said.lock().unwrap();
        let with = |prefix: &str| -> Vec<String> {
            said.iter()
                .filter(|l| l.starts_with(prefix))
                .cloned()
                .collect()
        };
        (with("received: "), with("end stop: "))
    }
}

impl Drop for Twin {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A G-code file in a folder of its own.
fn gcode_file(program: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("job.gcode");
    std::fs::write(&file, program).unwrap();
    (dir, file)
}

/// `cut` of `program` on `cutter`: refused with exit 4 and nothing sent; its message.
fn cut_refused(cutter: &Twin, program: &str, extra: &[&str]) -> String {
    let (_dir, file) = gcode_file(program);
    let args = ["cut", path(&file), "--cutter", &cutter.address];
    let out = kerfmeter(&[&args[..], extra].concat());
    let message = stderr(&out);
    assert_eq!(out.status.code(), Some(4), "{program}: {message}");
    let (received, _) = cutter.received();
    assert!(received.is_empty(), "{program}: {received:?}");
    message
}

fn says_all(message: &str, parts: &[&str]) {
    for part in parts {
        assert!(message.contains(part), "{part:?} in: {message}");
    }
}

#[test]
fn cut_refuses_a_program_that_leaves_the_travel_before_sending_a_line() {
    let cutter = Twin::cutter(&[]);
    let absolute = cut_refused(&cutter, "G21 G90\nG0 X10 Y10\nG1 X250 Y10 F600\n", &[]);
    says_all(
        &absolute,
        &[
            "line 3 (`G1 X250 Y10 F600`) takes the head to X 250.000 mm",
            "X runs 0.000 to 200.000 mm",
            "$130=200",
            "$22=0",
            "soft limits are off ($20=0), so GRBL would drive the head into its end stop",
            "Nothing was sent",
            "--origin-mm",
        ],
    );
    let relative = cut_refused(&cutter, "G91\nG0 X150\nG0 X60\n", &[]);
    says_all(&relative, &["line 3 (`G0 X60`)", "X 210.000 mm"]);
    // The arc's ends are inside; its top, at Y210, is not.
    let arc = cut_refused(&cutter, "G0 X50 Y150\nG2 X170 Y150 I60 J0 F600\n", &[]);
    says_all(
        &arc,
        &["line 2 (`G2 X170 Y150 I60 J0 F600`)", "Y 210.000 mm"],
    );
    let z = cut_refused(&cutter, "G0 Z-30\nG0 Z30\n", &[]);
    says_all(
        &z,
        &[
            "line 2 (`G0 Z30`) takes the head to Z 30.000 mm",
            "60.000 mm from the Z -30.000 mm it also reaches (line 1, `G0 Z-30`)",
            "$132=50",
        ],
    );
    let inches = cut_refused(&cutter, "G20\nG0 X8\n", &[]);
    says_all(&inches, &["X 203.200 mm"]);
    let probe = cut_refused(&cutter, "G0 X10\nG38.2 Z-20 F100\n", &[]);
    says_all(
        &probe,
        &[
            "line 2 (`G38.2 Z-20 F100`)",
            "cannot be checked against the machine's travel",
            "Nothing was sent",
        ],
    );
    // Inside the travel it runs, and hits no end stop.
    let (_dir, file) = gcode_file("G21 G90\nG0 X10 Y10\nM4 S100\nG1 X190 Y190 F3000\nM5\n");
    let out = kerfmeter(&["cut", path(&file), "--cutter", &cutter.address]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let (received, end_stops) = cutter.received();
    assert!(
        received.contains(&"received: G1X190Y190F3000".into()),
        "{received:?}"
    );
    assert!(end_stops.is_empty(), "{end_stops:?}");
}

#[test]
fn cut_maps_work_coordinates_through_the_offsets_of_a_homed_machine() {
    // Homing and soft limits: machine space −200..0; G54 puts work 0,0,0 at its low corner.
    let cutter = Twin::cutter(&[
        "--cutter-homing",
        "--cutter-soft-limits",
        "--cutter-work-offset-mm=-200,-200,-50",
    ]);
    let message = cut_refused(&cutter, "G0 X210 Y10\n", &["--unlock"]);
    says_all(
        &message,
        &[
            "X 210.000 mm in work coordinates (machine 10.000)",
            "machine -200.000 to 0.000",
            "$22=1",
            "ALARM:2",
        ],
    );
    let (_dir, file) = gcode_file("G0 X190 Y10 Z40\n");
    let out = kerfmeter(&["cut", path(&file), "--cutter", &cutter.address, "--unlock"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}

#[test]
fn the_laser_mode_refusal_names_its_flag_and_how_to_set_it() {
    let cutter = Twin::cutter(&["--cutter-no-laser-mode"]);
    let message = cut_refused(&cutter, "G0 X10\n", &[]);
    says_all(
        &message,
        &["$32=0", "send it `$32=1`", "--allow-without-laser-mode"],
    );
}

/// A 40 × 30 mm plate with a round hole, in a folder of its own: it fills (0, 0)–(40, 30) mm
/// placed at the origin.
fn plate_plan() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("plate.svg");
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">
  <rect x="5" y="5" width="40" height="30" fill="none" stroke="red" stroke-width="0.01"/>
  <circle cx="25" cy="20" r="5" fill="none" stroke="red" stroke-width="0.01"/>
</svg>"#;
    std::fs::write(&plan, svg).unwrap();
    (dir, plan)
}

/// `job` on the plate with a device twin and `cutter`, with `extra` flags.
fn job(cutter: &Twin, extra: &[&str]) -> Output {
    let device = Twin::start(&[]);
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let args = [
        "--json",
        "--port",
        &device.address,
        "job",
        path(&plan),
        "--cutter",
        &cutter.address,
        "-o",
        path(&out_svg),
    ];
    kerfmeter(&[&args[..], extra].concat())
}

/// `job` refused with exit 4 and nothing sent to `cutter`; its message.
fn job_refused(cutter: &Twin, extra: &[&str]) -> String {
    let out = job(cutter, extra);
    let message = stderr(&out);
    assert_eq!(out.status.code(), Some(4), "{extra:?}: {message}");
    let (received, _) = cutter.received();
    assert!(received.is_empty(), "{extra:?}: {received:?}");
    message
}

#[test]
fn job_refuses_a_gauge_prongs_heights_or_plan_outside_the_travel_before_sending_a_line() {
    let cutter = Twin::cutter(&[]);
    let gauge = job_refused(&cutter, &["--gauge-at-mm", "350,100"]);
    says_all(
        &gauge,
        &[
            "the gauge at (350.0, 100.0) mm",
            "$130=200",
            "--gauge-at-mm",
            "Nothing was sent",
        ],
    );
    let prongs = job_refused(
        &cutter,
        &["--gauge-at-mm", "150,150", "--prong-offset-mm=-80,0"],
    );
    says_all(
        &prongs,
        &[
            "the head would move to X 230.000 mm",
            "--prong-offset-mm",
            "$130=200",
        ],
    );
    let heights = job_refused(&cutter, &["--travel-z-mm", "40", "--insert-z-mm=-20"]);
    says_all(
        &heights,
        &[
            "Z 40.000 mm in work coordinates (machine 40.000), 60.000 mm from the Z -20.000 mm",
            "--travel-z-mm 40",
            "--insert-z-mm -20",
            "$132=50",
        ],
    );
    let plan = job_refused(&cutter, &["--origin-mm", "180,0"]);
    says_all(
        &plan,
        &[
            "the plan as placed fills (180.0, 0.0)–(220.0, 30.0) mm",
            "--origin-mm",
            "$130=200",
        ],
    );
    // A bed said larger than the travel puts the gauge right of the plan, off the machine.
    let bed = job_refused(&cutter, &["--origin-mm", "150,0", "--bed-mm", "600,400"]);
    says_all(&bed, &["the gauge at", "--bed-mm", "$130=200"]);
}

#[test]
fn job_refuses_an_insert_z_below_a_homed_machines_travel() {
    let cutter = Twin::cutter(&["--cutter-homing", "--cutter-work-offset-mm=-200,-200,-50"]);
    let message = job_refused(&cutter, &["--unlock", "--insert-z-mm=-6"]);
    says_all(
        &message,
        &[
            "--insert-z-mm -6 lowers the head to Z -6.000 mm in work coordinates (machine -56.000)",
            "$132=50",
        ],
    );
}

#[test]
fn without_bed_mm_the_gauge_goes_on_the_travel_and_the_job_stays_inside_it() {
    // The plan at X150–190: no room right of it on 200 mm, so the gauge goes above it.
    let cutter = Twin::cutter(&[]);
    let out = job(&cutter, &["--origin-mm", "150,0"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let [x, y] = [0, 1].map(|i| report["gauge_at_mm"][i].as_f64().unwrap());
    assert!(x < 200.0 && y > 30.0 && y < 200.0, "{report}");
    let (received, end_stops) = cutter.received();
    assert!(!received.is_empty());
    assert!(end_stops.is_empty(), "{end_stops:?}");
}
