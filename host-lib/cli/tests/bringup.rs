//! `kerfmeter bringup` end to end on the twin, through the binary: the exit code, the report
//! printed and saved (text and JSON), the answers by flags, and the report's files never
//! replacing someone else's. The library's tests (`kerfmeter_app::bringup`) catch every twin
//! fault at its step; here a few, to see the command's verdict follow.

use std::path::Path;
use std::process::{Command, Output};

/// Run `kerfmeter` with `args` in `dir`, with no terminal on stdin.
fn kerfmeter(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        .current_dir(dir)
        .env_remove("KERFMETER_PORT")
        .env("KERFMETER_DB", dir.join("history.sqlite3"))
        .stdin(std::process::Stdio::null())
        .output()
        .expect("the kerfmeter binary runs")
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn the_healthy_twin_passes_and_its_report_is_saved_as_text_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let out = kerfmeter(dir.path(), &["--sim", "bringup"]);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("bring-up passed"), "{text}");
    let saved: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("kerfmeter-bringup-"))
        .collect();
    assert_eq!(saved.len(), 2, "{saved:?}");
    let json_name = saved.iter().find(|n| n.ends_with(".json")).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(json_name)).unwrap())
            .unwrap();
    assert_eq!(json["passed"], true);
    assert_eq!(json["device"]["simulated"], true);
    assert!(text.contains(&format!(
        "report saved to {}",
        saved[0].replace(".json", ".txt")
    )));
    // A second bring-up the same day keeps the first report.
    let again = kerfmeter(dir.path(), &["--sim", "bringup"]);
    assert_eq!(again.status.code(), Some(0));
    assert!(stdout(&again).contains("-2.txt"), "{}", stdout(&again));
}

#[test]
fn a_miswired_motor_fails_the_bring_up_with_exit_4_and_the_json_says_which_step() {
    let dir = tempfile::tempdir().unwrap();
    let out = kerfmeter(
        dir.path(),
        &[
            "--sim",
            "--sim-motor-leads-swapped",
            "--json",
            "bringup",
            "--report",
            "wired",
        ],
    );
    assert_eq!(out.status.code(), Some(4), "{}", stdout(&out));
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(json["failed"], serde_json::json!(["direction"]));
    assert_eq!(json["saved"]["text"], "wired.txt");
    let text = std::fs::read_to_string(dir.path().join("wired.txt")).unwrap();
    assert!(text.contains("direction        FAIL"), "{text}");
}

#[test]
fn answers_given_by_flags_are_said_so_and_a_wrong_meter_reading_fails() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "--sim",
        "bringup",
        "--meter-v",
        "12.05",
        "--hub-turned",
        "cw",
        "--no-gauge",
    ];
    let out = kerfmeter(dir.path(), &args);
    let text = stdout(&out);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("(answered by a flag)"), "{text}");
    assert!(text.contains("gauge run        NOT CHECKED"), "{text}");
    assert!(text.contains("not checked: gauge run"), "{text}");
    let wrong = kerfmeter(dir.path(), &["--sim", "bringup", "--meter-v", "13.5"]);
    let text = stdout(&wrong);
    assert_eq!(wrong.status.code(), Some(4), "{text}");
    assert!(text.contains("supply vs meter  FAIL"), "{text}");
}

#[test]
fn a_report_path_over_someone_elses_file_is_refused_before_anything_moves() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
    let out = kerfmeter(dir.path(), &["--sim", "bringup", "--report", "notes"]);
    assert_eq!(out.status.code(), Some(4));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("not a bring-up report"), "{err}");
    assert_eq!(
        std::fs::read_to_string(dir.path().join("notes.txt")).unwrap(),
        "mine"
    );
}

#[test]
fn at_a_terminal_the_person_is_asked_and_their_answers_are_said_so() {
    use serialport::SerialPort;
    use std::io::{BufRead, BufReader, Write};
    // The device in a process of its own, so that nobody but the person answers.
    let mut twin = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(twin.stdout.take().unwrap()).lines();
    let port = lines.next().unwrap().unwrap();
    // The person's terminal: a pseudo-terminal on the command's stdin.
    let (mut person, terminal) = serialport::TTYPort::pair().unwrap();
    let stdin = std::fs::File::options()
        .read(true)
        .write(true)
        .open(terminal.name().unwrap())
        .unwrap();
    // The meter's reading, Enter once watching the hub, its turn, and no gauge.
    person.write_all(b"12.1 V\n\ncw\nn\n").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(["--port", &port, "bringup", "--report", "asked"])
        .current_dir(dir.path())
        .env_remove("KERFMETER_PORT")
        .stdin(stdin)
        .output()
        .unwrap();
    let _ = twin.kill();
    let _ = twin.wait();
    let (text, asked) = (stdout(&out), String::from_utf8_lossy(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{text}\n{asked}");
    assert!(asked.contains("What does your meter read"), "{asked}");
    assert!(
        asked.contains("Which way did the hub turn first"),
        "{asked}"
    );
    assert!(
        text.contains("meter 12.10 V") && text.contains("(answered at the prompt)"),
        "{text}"
    );
    assert!(
        text.contains("seen: clockwise (answered at the prompt)"),
        "{text}"
    );
    assert!(text.contains("gauge run        NOT CHECKED"), "{text}");
    assert!(!text.contains("twin answered"), "{text}");
}
