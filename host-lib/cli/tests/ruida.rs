//! `--cutter ruida-sim` and `ruida:HOST` as a user gives them: the whole job on the twins (the
//! simulated Ruida controller answering over loopback UDP), `cut` of Kerfmeter's G-code, and the
//! refusals: an address without the Z travel, a simulated device with a real controller, a
//! program beyond the bed, a controller that never answers.

use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Output};

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

fn text(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr)
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A 40 × 30 mm plate with a round hole, and its folder.
fn plate() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("plate.svg");
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">
  <rect x="5" y="5" width="40" height="30" fill="none" stroke="red" stroke-width="0.01"/>
  <circle cx="25" cy="20" r="5" fill="none" stroke="red" stroke-width="0.01"/>
</svg>"#;
    std::fs::write(&plan, svg).unwrap();
    (dir, plan)
}

/// A program in a folder of its own.
fn program(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("job.gcode");
    std::fs::write(&file, text).unwrap();
    (dir, file)
}

const SQUARE: &str = "(S_MAX=1000)\nG21 G90\nM5\nG0 X10 Y10\nF600\nM4 S500\nG1 X30\nG1 Y30\nG1 X10\nG1 Y10\nM5\nM2\n";

#[test]
fn the_whole_job_runs_on_the_ruida_twin() {
    let (dir, plan) = plate();
    let out_svg = dir.path().join("out.svg");
    let out = kerfmeter(&[
        "--sim",
        "--json",
        "job",
        path(&plan),
        "--cutter",
        "ruida-sim",
        "-o",
        path(&out_svg),
    ]);
    assert_eq!(code(&out), 0, "{}", text(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(
        report["cutter"].as_str().unwrap().starts_with("ruida-sim"),
        "{report}"
    );
    let kerf = report["kerf_um"].as_f64().unwrap();
    let truth = report["sim_truth_um"].as_f64().unwrap();
    assert!((kerf - truth).abs() < 3.0, "{kerf} vs {truth}");
    let stages: Vec<&str> = report["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(stages.len(), 7, "{stages:?}");
    assert!(out_svg.exists() && dir.path().join("out.gcode").exists());
}

#[test]
fn cut_sends_kerfmeters_gcode_to_the_ruida_twin_and_refuses_it_beyond_the_bed() {
    let (_dir, file) = program(SQUARE);
    let out = kerfmeter(&["cut", path(&file), "--cutter", "ruida-sim"]);
    assert_eq!(code(&out), 0, "{}", text(&out));
    assert!(text(&out).contains("(Ruida)"), "{}", text(&out));
    let (_dir, far) = program(&SQUARE.replace("G1 X30", "G1 X900"));
    let out = kerfmeter(&["cut", path(&far), "--cutter", "ruida-sim"]);
    assert_eq!(code(&out), 4, "{}", text(&out));
    assert!(text(&out).contains("Nothing was sent"), "{}", text(&out));
}

#[test]
fn a_ruida_address_without_its_z_travel_or_with_the_simulated_device_is_refused() {
    let (_dir, file) = program(SQUARE);
    let out = kerfmeter(&["cut", path(&file), "--cutter", "ruida:192.0.2.1"]);
    assert_eq!(code(&out), 2, "{}", text(&out));
    assert!(
        text(&out).contains("z-mm=MIN,MAX is required"),
        "{}",
        text(&out)
    );
    let (dir, plan) = plate();
    let out_svg = dir.path().join("out.svg");
    let real = "ruida:192.0.2.1?z-mm=-10,10";
    let out = kerfmeter(&[
        "--sim",
        "job",
        path(&plan),
        "--cutter",
        real,
        "-o",
        path(&out_svg),
    ]);
    assert_eq!(code(&out), 2, "{}", text(&out));
    assert!(
        text(&out).contains("--sim with a real cutter is refused"),
        "{}",
        text(&out)
    );
}

#[test]
fn a_ruida_controller_that_never_answers_is_a_clear_error_and_nothing_is_cut() {
    let silent = UdpSocket::bind("127.0.0.1:0").unwrap();
    let address = format!(
        "ruida:127.0.0.1:{}?z-mm=-10,10&local-port=0",
        silent.local_addr().unwrap().port()
    );
    let (_dir, file) = program(SQUARE);
    let out = kerfmeter(&["cut", path(&file), "--cutter", &address]);
    assert_eq!(code(&out), 3, "{}", text(&out));
    assert!(
        text(&out).contains("did not answer while connecting"),
        "{}",
        text(&out)
    );
}
