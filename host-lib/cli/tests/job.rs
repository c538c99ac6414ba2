//! `kerfmeter job` as a user runs it: the whole loop on the twins (`--sim --cutter sim`), its
//! JSON, the files it writes, the dry run, a failed measurement that stops before the job, and
//! the machine combinations it refuses.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Run `kerfmeter` with `args`, recording into a history of its own (never the user's; a test
/// that reads the history back passes its own `--db`).
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

fn code(out: &Output) -> i32 {
    out.status.code().expect("exited, not killed")
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A plan called `name` in a folder of its own, with `shapes` (red cuts, mm) on a 100 × 50 mm
/// page: the folder and the plan's path.
fn plan_in_a_folder(name: &str, shapes: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join(name);
    let svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">
{shapes}
</svg>"#
    );
    std::fs::write(&to, svg).unwrap();
    (dir, to)
}

/// A 40 × 30 mm plate with a round hole, in mm.
fn plate_plan() -> (tempfile::TempDir, PathBuf) {
    plan_in_a_folder(
        "plate.svg",
        r#"  <rect x="5" y="5" width="40" height="30" fill="none" stroke="red" stroke-width="0.01"/>
  <circle cx="25" cy="20" r="5" fill="none" stroke="red" stroke-width="0.01"/>"#,
    )
}

#[test]
fn the_whole_job_on_the_twins_prints_the_kerf_and_the_stage_times_and_writes_the_plan() {
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let db = dir.path().join("history.sqlite3");
    let out = kerfmeter(&[
        "--sim",
        "--json",
        "--sim-kerf-um",
        "180",
        "--db",
        path(&db),
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        path(&out_svg),
        "--prong-offset-mm",
        "30,-10",
        "--label",
        "plywood 3 mm",
    ]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let kerf = json["kerf_um"].as_f64().unwrap();
    // The measurement is in the history, under its label.
    assert_eq!(json["history"]["id"], 1, "{json}");
    assert_eq!(json["history"]["db"], path(&db));
    let listed = kerfmeter(&["--sim", "--json", "--db", path(&db), "history"]);
    let listed: serde_json::Value = serde_json::from_str(&stdout(&listed)).unwrap();
    let record = &listed["records"][0];
    assert_eq!(record["label"], "plywood 3 mm", "{listed}");
    assert!((record["kerf_um"].as_f64().unwrap() - kerf).abs() < 1e-3);
    let truth = json["sim_truth_um"].as_f64().unwrap();
    assert!((kerf - truth).abs() < 3.0, "{kerf} vs {truth}");
    assert!(truth > 175.0 && truth < 200.0, "{truth}");
    let stages: Vec<&str> = json["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        stages,
        [
            "cut-gauge",
            "wait-motion",
            "lower",
            "measure",
            "lift",
            "dilate",
            "stream-job"
        ]
    );
    assert!(json["stages"][0]["elapsed_s"].as_f64().unwrap() > 0.0);
    // The gauge went beside the plate (right of it), not on it.
    assert!(json["gauge_at_mm"][0].as_f64().unwrap() > 40.0);
    let dilated = std::fs::read_to_string(&out_svg).unwrap();
    assert!(dilated.contains("<svg"));
    let gcode = std::fs::read_to_string(dir.path().join("out.gcode")).unwrap();
    assert!(
        gcode.contains(&format!("{kerf:.1} um, measured by kerfmeter job")),
        "{gcode}"
    );
    assert!(std::fs::read_to_string(&plan).unwrap().contains("<rect"));
}

/// A plan whose two parts, 0.1 mm apart, merge when dilated by the kerf the twin's cutter cuts:
/// a job on it fails at its dilation, after its measurement. The folder and the plan's path.
fn close_parts_plan() -> (tempfile::TempDir, PathBuf) {
    plan_in_a_folder(
        "close.svg",
        r#"  <rect x="5" y="5" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>
  <rect x="25.1" y="5" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>"#,
    )
}

#[test]
fn a_job_that_fails_after_its_measurement_still_records_it() {
    let (dir, plan) = close_parts_plan();
    let out_svg = dir.path().join("out.svg");
    let db = dir.path().join("history.sqlite3");
    let args = ["--sim", "--db", path(&db), "job", path(&plan)];
    let out = kerfmeter(&[&args[..], &["--cutter", "sim", "-o", path(&out_svg)]].concat());
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    let message = stderr(&out);
    assert!(message.contains("dilat"), "{message}");
    assert!(
        message.contains("the job failed after its measurement; recorded as #1"),
        "{message}"
    );
    let listed = kerfmeter(&["--sim", "--json", "--db", path(&db), "history"]);
    let listed: serde_json::Value = serde_json::from_str(&stdout(&listed)).unwrap();
    assert_eq!(listed["records"].as_array().unwrap().len(), 1, "{listed}");
}

#[test]
fn a_failed_measurement_stops_before_the_job_and_writes_nothing() {
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let out = kerfmeter(&[
        "--sim",
        "--sim-fault",
        "prong-slip",
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        path(&out_svg),
    ]);
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    let message = stderr(&out);
    assert!(message.contains("measuring the kerf"), "{message}");
    assert!(
        message.contains("the job was not cut and the laser is off"),
        "{message}"
    );
    assert!(!out_svg.exists());
    assert!(!dir.path().join("out.gcode").exists());
}

#[test]
fn the_dry_run_prints_every_stage_and_opens_nothing() {
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    // A real device and cutter that do not exist: a dry run must not try them.
    let out = kerfmeter(&[
        "--port",
        "/dev/nonexistent-kerfmeter",
        "job",
        path(&plan),
        "--cutter",
        "grbl:/dev/nonexistent-cutter",
        "-o",
        path(&out_svg),
        "--gauge-at-mm",
        "150,40",
        "--prong-offset-mm",
        "20,5",
        "--insert-z-mm",
        "-2",
        "--dry-run",
        "--dry-run-kerf-um",
        "200",
    ]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let text = stdout(&out);
    for stage in ["cut-gauge", "lower", "lift", "stream-job"] {
        assert!(text.contains(&format!("stage {stage}")), "{text}");
    }
    assert!(text.contains("spiral centre at X150 Y40"), "{text}");
    assert!(
        text.contains("G0 X130.0000 Y35.0000\nG1 Z-2.0000"),
        "{text}"
    );
    // The dry run's kerf is not passed off as measured.
    assert!(
        text.contains("kerf applied: 200.0 um, not measured: a dry run"),
        "{text}"
    );
    assert!(!text.contains("measured by kerfmeter job"), "{text}");
    assert!(!out_svg.exists());
}

#[test]
fn mixed_simulated_and_real_machines_and_a_full_bed_are_refused() {
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let o = path(&out_svg);
    let out = kerfmeter(&[
        "--sim",
        "job",
        path(&plan),
        "--cutter",
        "grbl:/dev/null",
        "-o",
        o,
    ]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(stderr(&out).contains("--sim with a real cutter is refused"));
    let out = kerfmeter(&[
        "--port",
        "/dev/null",
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        o,
    ]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(stderr(&out).contains("--cutter sim with a real device is refused"));
    let out = kerfmeter(&[
        "--sim",
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        o,
        "--bed-mm",
        "60,50",
    ]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(
        stderr(&out).contains("no room for the gauge"),
        "{}",
        stderr(&out)
    );
    // A bed smaller than the plan: that is what is said, not that the gauge has no room.
    let out = kerfmeter(&[
        "--sim",
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        o,
        "--bed-mm",
        "30,20",
    ]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(
        stderr(&out).contains("the plan as placed fills")
            && stderr(&out).contains("beyond the 30 × 20 mm bed"),
        "{}",
        stderr(&out)
    );
    let out = kerfmeter(&[
        "--sim",
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        path(&plan),
    ]);
    assert_ne!(code(&out), 0);
    assert!(std::fs::read_to_string(&plan).unwrap().contains("<rect"));
}

/// Run the job on the twins with `extra` flags after `-o out.svg` on a 600 × 400 mm bed (given,
/// so checked before the cutter is opened); it must be refused before anything moved (exit 2,
/// nothing written); its message.
fn refused_before_moving(extra: &[&str]) -> String {
    let (dir, plan) = plate_plan();
    refused_before_moving_in(dir.path(), &plan, extra)
}

/// [`refused_before_moving`] with the `plan` in `dir`, which the output goes into.
fn refused_before_moving_in(dir: &Path, plan: &Path, extra: &[&str]) -> String {
    let out_svg = dir.join("out.svg");
    let args = [
        "--sim",
        "job",
        path(plan),
        "--cutter",
        "sim",
        "--bed-mm",
        "600,400",
        "-o",
    ];
    let out = kerfmeter(&[&args[..], &[path(&out_svg)], extra].concat());
    let message = stderr(&out);
    assert_eq!(code(&out), 2, "{extra:?}: {message}");
    // The cutter was never opened ("job on sim …" is printed once it is).
    assert!(!message.contains("job on"), "{message}");
    assert!(!out_svg.exists() && !dir.join("out.gcode").exists());
    message
}

#[test]
fn a_gauge_over_the_plan_or_off_the_bed_a_head_off_the_bed_and_an_upward_plunge_are_refused() {
    // The plate's cuts fill (0, 0)–(40, 30) mm on the machine.
    let over = refused_before_moving(&["--gauge-at-mm", "30,30"]);
    assert!(over.contains("within 5 mm of the plan"), "{over}");
    for at in ["-500,30", "5000,30"] {
        let off = refused_before_moving(&[&format!("--gauge-at-mm={at}")]);
        assert!(off.contains("off the 600 × 400 mm bed"), "{off}");
    }
    let head = refused_before_moving(&["--prong-offset-mm", "1000,1000"]);
    assert!(head.contains("the head would move to X-9"), "{head}");
    let plan = refused_before_moving(&["--origin-mm", "580,0"]);
    assert!(plan.contains("the plan as placed fills"), "{plan}");
    let z = refused_before_moving(&["--insert-z-mm", "50", "--travel-z-mm", "10"]);
    assert!(z.contains("must be below the travel Z"), "{z}");
}

#[test]
fn a_gcode_out_over_the_plan_or_in_a_missing_directory_is_refused_before_anything_moves() {
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let o = path(&out_svg);
    // The same file by another name, not written yet.
    let same = dir.path().join(".").join("out.svg");
    let message = refused_before_moving_in(dir.path(), &plan, &["--gcode-out", path(&same)]);
    assert!(message.contains("are the same file"), "{message}");
    let missing = dir.path().join("nodir");
    for (output, gcode) in [
        (o, missing.join("o.gcode")),
        (path(&missing.join("o.svg")), dir.path().join("o.gcode")),
    ] {
        let args = ["--sim", "job", path(&plan), "--cutter", "sim", "-o", output];
        let out = kerfmeter(&[&args[..], &["--gcode-out", path(&gcode)]].concat());
        let message = stderr(&out);
        assert_eq!(code(&out), 4, "{message}");
        let says = format!("the directory {} does not exist", missing.display());
        assert!(message.contains(&says), "{message}");
        assert!(!message.contains("job on"), "{message}");
    }
    // A folder where the plan goes is refused as such, before the gauge is cut.
    std::fs::create_dir(&out_svg).unwrap();
    let args = ["--sim", "job", path(&plan), "--cutter", "sim", "-o", o];
    let out = kerfmeter(&args);
    let message = stderr(&out);
    assert_eq!(code(&out), 4, "{message}");
    assert!(message.contains("is a directory"), "{message}");
    assert!(!message.contains("job on"), "{message}");
    std::fs::remove_dir(&out_svg).unwrap();
    assert!(!out_svg.exists());
}

/// `kerfmeter-twin` with `args`, and the first line it prints (its port or cutter URL).
fn twin(args: &[&str]) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("the kerfmeter-twin binary runs");
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    (child, line.trim().to_owned())
}

/// G-code lines a controller counts (neither blank, nor a comment, nor a `$` command).
fn gcode_lines(program: &str) -> usize {
    program
        .lines()
        .map(str::trim)
        .filter(|l| {
            !l.is_empty() && !l.starts_with(';') && !l.starts_with('(') && !l.starts_with('$')
        })
        .count()
}

#[test]
fn a_job_stopped_while_streaming_says_which_complete_files_it_wrote() {
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let base = ["job", path(&plan), "-o", path(&out_svg)];
    // The controller counts every G-code line since boot. Each stage's program, with the closing
    // line the sender adds, goes through once in check mode ($C) and once for real: the job's
    // real lines come after the other stages' (twice each) and the job's own check pass. Refuse
    // the one half-way through them.
    let dry_run = [
        &["--json"][..],
        &base[..],
        &["--cutter", "sim", "--dry-run"],
    ]
    .concat();
    let dry = kerfmeter(&dry_run);
    assert_eq!(code(&dry), 0, "{}", stderr(&dry));
    let dry: serde_json::Value = serde_json::from_str(&stdout(&dry)).unwrap();
    let sent = |s: &serde_json::Value| gcode_lines(s["gcode"].as_str().unwrap()) + 1;
    let stages = dry["stages"].as_array().unwrap();
    let (job, others): (Vec<_>, Vec<_>) = stages.iter().partition(|s| s["stage"] == "stream-job");
    let job_lines = sent(job[0]);
    let before_job: usize = others.iter().map(|s| 2 * sent(s)).sum::<usize>() + job_lines;
    let refused_line = (before_job + job_lines / 2).to_string();
    let (mut device, port) = twin(&[]);
    let (mut cutter, url) = twin(&[
        "--cutter",
        "--tcp",
        "0",
        "--cutter-error-on-line",
        &refused_line,
    ]);
    let out = kerfmeter(&[&["--port", &port][..], &base[..], &["--cutter", &url]].concat());
    let _ = (device.kill(), cutter.kill(), device.wait(), cutter.wait());
    assert_ne!(code(&out), 0, "{}", stderr(&out));
    let message = stderr(&out);
    assert!(
        message.contains("note: written before the job stopped, complete:")
            && message.contains("out.svg and ")
            && message.contains("out.gcode"),
        "{message}"
    );
    assert!(out_svg.exists() && dir.path().join("out.gcode").exists());
}

/// A plan that records a compensation is refused before the gauge is cut, with the job's own
/// ways on (its flags exist); `--recompensate` then runs it. A gauge drawing is refused too: it
/// was cut and measured before its dilation refused it.
#[test]
fn a_compensated_plan_or_a_gauge_is_refused_before_anything_moves() {
    let (dir, plan) = plate_plan();
    let first = dir.path().join("first.svg");
    let made = kerfmeter(&[
        "dilate",
        path(&plan),
        "--kerf-um",
        "150",
        "-o",
        path(&first),
    ]);
    assert_eq!(code(&made), 0, "{}", stderr(&made));
    let gauge = dir.path().join("gauge.svg");
    let made = kerfmeter(&["gauge", "-o", path(&gauge)]);
    assert_eq!(code(&made), 0, "{}", stderr(&made));
    let db = dir.path().join("history.sqlite3");
    let job = |input: &Path, extra: &[&str]| {
        let out_svg = dir.path().join("out.svg");
        let base = [
            "--sim",
            "--json",
            "--db",
            path(&db),
            "job",
            path(input),
            "--cutter",
            "sim",
            "-o",
            path(&out_svg),
        ];
        kerfmeter(&[&base[..], extra].concat())
    };
    for (input, words) in [
        (&first, "--recompensate"),
        (&gauge, "a gauge is cut as drawn"),
    ] {
        let out = job(input, &[]);
        assert_eq!(code(&out), 4, "{}", stderr(&out));
        let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
        let error = json["error"].as_str().unwrap();
        assert!(
            error.contains(words) && error.contains("nothing was cut"),
            "{error}"
        );
        assert!(json["compensation_found"]["by"].is_string(), "{json}");
    }
    // Nothing was measured: no history was even made (listing it says so).
    assert!(!db.exists());
    let listed = kerfmeter(&["--sim", "--json", "--db", path(&db), "history"]);
    assert_eq!(code(&listed), 4, "{}", stdout(&listed));
    let listed: serde_json::Value = serde_json::from_str(&stdout(&listed)).unwrap();
    let error = listed["error"].as_str().unwrap();
    assert!(error.contains("the file does not exist"), "{error}");
    // The flag the refusal names is the job's own.
    let out = job(&first, &["--recompensate"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
}

/// A job that stops after its measurement (here its plan's parts, 0.1 mm apart, would merge at
/// the kerf measured) says in its `--json` error what it had: the kerf, its record, the files.
#[test]
fn a_job_stopped_after_measuring_reports_its_kerf_and_record_in_json() {
    let (dir, plan) = close_parts_plan();
    let db = dir.path().join("history.sqlite3");
    let out_svg = dir.path().join("out.svg");
    let out = kerfmeter(&[
        "--sim",
        "--json",
        "--db",
        path(&db),
        "job",
        path(&plan),
        "--cutter",
        "sim",
        "-o",
        path(&out_svg),
    ]);
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert!(json["error"].as_str().unwrap().contains("merge"), "{json}");
    assert!(json["kerf_um"].as_f64().unwrap() > 100.0, "{json}");
    assert_eq!(json["history"]["id"], 1, "{json}");
    assert_eq!(json["written"], serde_json::json!([]), "{json}");
    assert!(!out_svg.exists());
}

/// Ctrl-C while the cutter connects (here a networked controller that never says a word) ends
/// the job there, as it ends a `cut`: it does not wait out the controller's silence. The device
/// is the twin on a pseudo-terminal (`--sim` takes only the simulated cutter).
#[test]
fn ctrl_c_while_the_cutter_connects_ends_the_job() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let mut device = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut port = String::new();
    BufReader::new(device.stdout.take().unwrap())
        .read_line(&mut port)
        .unwrap();
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    listener.set_nonblocking(true).unwrap();
    let url = format!("grbl+tcp://{}", listener.local_addr().unwrap());
    let (dir, plan) = plate_plan();
    let out_svg = dir.path().join("out.svg");
    let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(["--port", port.trim(), "job", path(&plan), "--cutter", &url])
        .args(["-o", path(&out_svg)])
        .env_remove("KERFMETER_CUTTER")
        .env("KERFMETER_DB", dir.path().join("history.sqlite3"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Connected: the job now waits for a banner that never comes.
    let deadline = Instant::now() + Duration::from_secs(60);
    let silent = loop {
        match listener.accept() {
            Ok((stream, _)) => break stream,
            Err(_) if Instant::now() < deadline && child.try_wait().unwrap().is_none() => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(_) => {
                let _ = child.kill();
                let out = child.wait_with_output().unwrap();
                panic!("the job never connected: {}", stderr(&out));
            }
        }
    };
    std::thread::sleep(Duration::from_millis(200));
    let interrupted = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(interrupted.success());
    let out = child.wait_with_output().unwrap();
    drop(silent);
    let _ = device.kill();
    let _ = device.wait();
    let message = stderr(&out);
    assert_eq!(code(&out), 4, "{message}");
    assert!(message.contains("cancelled while connecting"), "{message}");
    assert!(!out_svg.exists());
}
