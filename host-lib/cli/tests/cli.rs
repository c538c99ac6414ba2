//! The `kerfmeter` binary as a user or a script runs it: exit codes by the error's category, the
//! `--json` output, and what only the `dilate` command does (never writing over the input, the
//! dry-run report, the kerf map file, no temporary files left behind, no progress printed when
//! stderr is not a terminal), and the G-code of `gcode` and `gauge`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use kerfmeter::map::{Grid, KerfMap};

/// Run `kerfmeter` with `args`, recording into a history of its own (never the user's; a test
/// that reads the history back passes its own `--db`).
fn kerfmeter(args: &[&str]) -> Output {
    let history = tempfile::tempdir().unwrap();
    Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        .env_remove("KERFMETER_PORT")
        .env("KERFMETER_DB", history.path().join("history.sqlite3"))
        .output()
        .expect("the kerfmeter binary runs")
}

/// `kerfmeter dilate INPUT --kerf-um KERF_UM -o OUTPUT`.
fn dilate(input: &Path, kerf_um: &str, output: &Path) -> Output {
    kerfmeter(&[
        "dilate",
        path(input),
        "--kerf-um",
        kerf_um,
        "-o",
        path(output),
    ])
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

/// The `box_generator.svg` plan of `kerfmeter-plan`'s fixtures, copied into a fresh folder.
fn box_plan() -> (tempfile::TempDir, PathBuf) {
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../plan/tests/fixtures/box_generator.svg");
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join("box_generator.svg");
    std::fs::copy(fixture, &to).unwrap();
    (dir, to)
}

fn path(p: &Path) -> &str {
    p.to_str().expect("temporary paths are UTF-8")
}

#[test]
fn a_failed_self_test_exits_4_like_any_device_failure() {
    let out = kerfmeter(&["--sim", "--sim-fault", "motor-disconnected", "self-test"]);
    assert!(
        stdout(&out).contains("self-test FAILED"),
        "{}",
        stdout(&out)
    );
    assert!(
        stderr(&out).contains("the self-test failed"),
        "{}",
        stderr(&out)
    );
    assert_eq!(code(&out), 4);

    let out = kerfmeter(&[
        "--sim",
        "--json",
        "--sim-fault",
        "motor-disconnected",
        "self-test",
    ]);
    assert_eq!(code(&out), 4);
    // One JSON object, the report, which says the failure itself.
    let text = stdout(&out);
    let report: serde_json::Value = serde_json::from_str(&text).expect("one JSON object");
    assert_eq!(report["passed"], false, "{text}");

    // The failed items are explained in words.
    let out = kerfmeter(&["--sim", "--sim-fault", "motor-disconnected", "self-test"]);
    assert!(
        stdout(&out).contains("the motor is disconnected"),
        "{}",
        stdout(&out)
    );

    // A healthy twin's self-test passes, and exits 0.
    let out = kerfmeter(&["--sim", "self-test"]);
    assert!(
        stdout(&out).contains("self-test passed"),
        "{}",
        stdout(&out)
    );
    assert_eq!(code(&out), 0);
}

#[test]
fn exit_codes_follow_the_error_category() {
    // Bad arguments: 2, whether clap or the command finds them.
    assert_eq!(code(&kerfmeter(&["run", "--samples", "0"])), 2);
    assert_eq!(code(&kerfmeter(&["--sim-realtime", "info"])), 2);
    let (dir, input) = box_plan();
    let out = kerfmeter(&["dilate", path(&input), "--kerf-um", "9000", "--dry-run"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    // A port that cannot be opened: 3.
    let missing = dir.path().join("no-such-port");
    assert_eq!(code(&kerfmeter(&["--port", path(&missing), "info"])), 3);
    // A plan file that cannot be read: 4, and the message names it.
    let broken = dir.path().join("broken.svg");
    std::fs::write(&broken, "<svg").unwrap();
    let out = kerfmeter(&["dilate", path(&broken), "--kerf-um", "150", "--dry-run"]);
    assert_eq!(code(&out), 4);
    assert!(stderr(&out).contains("broken.svg"), "{}", stderr(&out));
    // A device fault: 4, and `--json` names it.
    let out = kerfmeter(&["--sim", "--json", "--sim-fault", "driver-fault", "run"]);
    assert_eq!(code(&out), 4);
    let error: serde_json::Value = serde_json::from_str(stdout(&out).trim()).unwrap();
    assert_eq!(error["fault"], "DriverFault", "{error}");
}

#[test]
fn dilate_never_writes_over_its_input_nor_into_another_format() {
    let (dir, input) = box_plan();
    let before = std::fs::read(&input).unwrap();
    let same = dir.path().join(".").join("box_generator.svg");
    for output in [input.clone(), same] {
        let out = dilate(&input, "150", &output);
        assert!(
            stderr(&out).contains("inputs are never overwritten"),
            "{}",
            stderr(&out)
        );
        assert_eq!(code(&out), 2);
    }
    let dxf = dir.path().join("x.dxf");
    let out = dilate(&input, "150", &dxf);
    assert!(stderr(&out).contains("format"), "{}", stderr(&out));
    assert_eq!(code(&out), 2);
    assert_eq!(std::fs::read(&input).unwrap(), before);
}

#[test]
fn dilate_writes_the_output_atomically_and_reports_it() {
    let (dir, input) = box_plan();
    let output = dir.path().join("box-k200.svg");
    let out = dilate(&input, "200", &output);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("each cut moved 100 µm"),
        "{}",
        stdout(&out)
    );
    assert!(std::fs::read_to_string(&output).unwrap().contains("<svg"));
    // The input and the output, no temporary file left next to them.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    // The progress bar is for a terminal: with stderr going elsewhere nothing is printed there.
    assert_eq!(stderr(&out), "");
}

#[test]
fn a_plan_with_no_cut_is_refused_and_the_json_report_has_one_format_key() {
    // A green square only: not a cut by the default rules. Nothing to dilate, so nothing is
    // written (an output would record a compensation that was never applied).
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("green.svg");
    std::fs::write(
        &input,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50"><rect x="5" y="5" width="20" height="20" fill="none" stroke="#00ff00" stroke-width="0.1"/></svg>"##,
    )
    .unwrap();
    let output = dir.path().join("out.svg");
    let args = [
        "dilate",
        path(&input),
        "--kerf-um",
        "150",
        "-o",
        path(&output),
    ];
    let refused = kerfmeter(&args);
    assert_ne!(code(&refused), 0, "{}", stdout(&refused));
    assert!(
        stderr(&refused).contains("no closed cut contour")
            && stderr(&refused).contains("--cut-color"),
        "{}",
        stderr(&refused)
    );
    assert!(!output.exists());
    // Told the colour, it dilates; its JSON report names the format once.
    let mut green = args.to_vec();
    green.extend(["--cut-color", "#00ff00", "--json"]);
    let done = kerfmeter(&green);
    assert_eq!(code(&done), 0, "{}", stderr(&done));
    assert_eq!(
        stdout(&done).matches("\"format\"").count(),
        1,
        "{}",
        stdout(&done)
    );
    let report: serde_json::Value = serde_json::from_str(&stdout(&done)).unwrap();
    assert_eq!(report["format"], "svg");
    assert_eq!(report["contours_dilated"], 1);
}

#[test]
fn negative_numbers_get_the_options_message_and_usage_errors_honour_json() {
    let (dir, input) = box_plan();
    let output = dir.path().join("out.svg");
    let neg = dilate(&input, "-150", &output);
    assert_eq!(code(&neg), 2);
    assert!(
        stderr(&neg).contains("between 0 and 5000 µm, got -150"),
        "{}",
        stderr(&neg)
    );
    // An X,Y pair may start with a minus (a prong left of the nozzle; a plan placed at -10).
    let gcode = dir.path().join("out.gcode");
    let xy = kerfmeter(&[
        "gcode",
        path(&input),
        "--kerf-um",
        "150",
        "-o",
        path(&gcode),
        "--feed-mm-per-min",
        "600",
        "--power-percent",
        "80",
        "--origin-mm",
        "-10,5",
    ]);
    // (Read as a pair: the plan is then refused for its open slit, not for the argument.)
    assert_ne!(code(&xy), 2, "{}", stderr(&xy));
    assert!(stderr(&xy).contains("open cut path"), "{}", stderr(&xy));
    let gauge = kerfmeter(&["gauge", "-o", path(&gcode), "--at-mm", "-5,20"]);
    assert!(
        !stderr(&gauge).contains("unexpected argument"),
        "{}",
        stderr(&gauge)
    );
    let bogus = kerfmeter(&["--json", "run", "--bogus"]);
    assert_eq!(code(&bogus), 2);
    let report: serde_json::Value = serde_json::from_str(&stdout(&bogus)).unwrap();
    assert!(
        report["error"].as_str().unwrap().contains("--bogus"),
        "{report}"
    );
}

#[test]
fn a_flagged_run_and_a_force_not_reached_are_said_under_the_kerf() {
    // 500 N is more than the default 12 V bus drives through the 0.8 N·m cap (some 70 N). Full
    // duty on the sagging bus gives about the cap itself, so the run is flagged
    // `supply-limited` or `torque-limited` by a hair (since the twin's ADC reads the supply one
    // tick in ten, as the board does, `torque-limited` at 0.800 N·m; before, `supply-limited`
    // at 0.794 N·m).
    let out = kerfmeter(&["--sim", "run", "--force-n", "500"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    for said in [
        "warning: run 1 is flagged",
        "warning: run 1 pressed the joint at",
        "not the 500.0 N asked for",
    ] {
        assert!(stdout(&out).contains(said), "{said:?} in {}", stdout(&out));
    }
    assert!(
        ["supply-limited", "torque-limited"]
            .iter()
            .any(|flag| stdout(&out).contains(&format!("flagged {flag}"))),
        "{}",
        stdout(&out)
    );
    // An unflagged run at the default force says neither.
    let out = kerfmeter(&["--sim", "run"]);
    assert!(!stdout(&out).contains("warning: run"), "{}", stdout(&out));
}

#[test]
fn cut_refuses_a_drawing_and_fault_messages_read_as_sentences() {
    let (_dir, input) = box_plan();
    let out = kerfmeter(&["cut", path(&input), "--cutter", "sim"]);
    assert_eq!(code(&out), 2);
    assert!(
        stderr(&out).contains("is a drawing (.svg), not a G-code program")
            && stderr(&out).contains("kerfmeter gcode"),
        "{}",
        stderr(&out)
    );
    let fault = kerfmeter(&["--sim", "--sim-fault", "over-current", "run"]);
    assert!(
        stderr(&fault).contains("is the hub blocked? Fix the cause"),
        "{}",
        stderr(&fault)
    );
}

#[test]
fn simulator_options_without_sim_are_refused_not_ignored() {
    for args in [
        &["--sim-kerf-um", "200", "run"][..],
        &["--sim-seed", "7", "status"][..],
        &["--sim-fault", "parity", "run"][..],
        &["--sim-adc-uncalibrated", "self-test"][..],
        &["--sim-driver", "24v13", "status"][..],
    ] {
        let out = kerfmeter(args);
        assert_eq!(code(&out), 2, "{args:?}: {}", stderr(&out));
        assert!(stderr(&out).contains("add --sim"), "{}", stderr(&out));
    }
}

#[test]
fn an_uncalibrated_adc_and_the_g2_variant_are_said_by_status_info_and_self_test() {
    // Protocol 2.6 (issue 34): a chip without ADC calibration eFuses passes its self-test with
    // a torque constant some 35 % high, so the self-test and status say why.
    let out = kerfmeter(&["--sim", "--sim-adc-uncalibrated", "self-test"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("ADC is uncalibrated"),
        "{}",
        stdout(&out)
    );
    let out = kerfmeter(&["--sim", "--sim-adc-uncalibrated", "status"]);
    assert!(
        stdout(&out).contains("adc-uncalibrated"),
        "{}",
        stdout(&out)
    );
    let out = kerfmeter(&["--sim", "info"]);
    for said in ["last reset: power-on", "adc:        calibrated", "G2 18v17"] {
        assert!(stdout(&out).contains(said), "{said:?} in {}", stdout(&out));
    }
    // 25 V: over an 18v17's safe 24 V, within a 24v13's.
    let on_18v17 = kerfmeter(&["--sim", "--sim-plant", "supply_v=25", "status"]);
    assert!(
        stdout(&on_18v17).contains("supply-out-of-range"),
        "{}",
        stdout(&on_18v17)
    );
    let args = [
        "--sim",
        "--sim-driver",
        "24v13",
        "--sim-plant",
        "supply_v=25",
        "status",
    ];
    let on_24v13 = kerfmeter(&args);
    assert!(
        stdout(&on_24v13).contains("conditions:   none"),
        "{}",
        stdout(&on_24v13)
    );
}

#[test]
fn device_flags_on_a_command_without_the_device_are_refused_not_ignored() {
    let (_dir, plan) = box_plan();
    let dilate_args = ["dilate", path(&plan), "--kerf-um", "150", "--dry-run"];
    for flags in [
        &["--sim-fault", "parity"][..],
        &["--port", "/dev/ttyACM0"][..],
        &["--sim"][..],
    ] {
        let out = kerfmeter(&[flags, &dilate_args[..]].concat());
        assert_eq!(code(&out), 2, "{flags:?}: {}", stderr(&out));
        let flag = flags[0];
        assert!(
            stderr(&out).contains(&format!(
                "`kerfmeter dilate` does not use the device: {flag}"
            )),
            "{}",
            stderr(&out)
        );
    }
    // The same with --json: one object on stdout.
    let out = kerfmeter(&[&["--json", "--sim-seed", "3"][..], &dilate_args[..]].concat());
    assert_eq!(code(&out), 2);
    assert!(
        stdout(&out).contains("--sim-seed has no effect"),
        "{}",
        stdout(&out)
    );
    // history takes --sim (the simulated records), not the twin's settings.
    let out = kerfmeter(&["--sim", "--sim-kerf-um", "90", "history"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(
        stderr(&out).contains("--sim-kerf-um has no effect"),
        "{}",
        stderr(&out)
    );
    let out = kerfmeter(&["--port", "/dev/ttyACM0", "history"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    // A port from the environment is not the user's word for this command.
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(dilate_args)
        .env("KERFMETER_PORT", "/dev/ttyACM0")
        .output()
        .unwrap();
    assert_eq!(code(&out), 0, "{}", stderr(&out));
}

#[test]
fn a_refused_plan_leaves_the_output_as_it_was() {
    // The output is written as it is made, into a temporary file: `--strict`'s refusal of an
    // open cut path comes after that, and must neither replace the output nor leave the
    // temporary file.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("slit.svg");
    std::fs::write(
        &input,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50"><rect x="5" y="5" width="20" height="20" fill="none" stroke="#ff0000" stroke-width="0.1"/><path d="M 30 5 L 30 25" fill="none" stroke="#ff0000" stroke-width="0.1"/></svg>"##,
    )
    .unwrap();
    let output = dir.path().join("out.svg");
    std::fs::write(&output, "earlier").unwrap();
    // (--force: not this tool's file, which would otherwise be refused before anything is read.)
    let out = kerfmeter(&[
        "dilate",
        path(&input),
        "--kerf-um",
        "150",
        "--strict",
        "--force",
        "-o",
        path(&output),
    ]);
    assert_ne!(code(&out), 0, "{}", stdout(&out));
    assert!(stderr(&out).contains("open cut path"), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(&output).unwrap(), "earlier");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn dry_run_reports_without_writing() {
    let (dir, input) = box_plan();
    let output = dir.path().join("out.svg");
    let args = [
        "dilate",
        path(&input),
        "--kerf-um",
        "150",
        "-o",
        path(&output),
        "--dry-run",
    ];
    let out = kerfmeter(&args);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let text = stdout(&out);
    assert!(
        text.contains("dry run") && text.contains("open cut path"),
        "{text}"
    );
    assert!(
        text.contains("<path> at line"),
        "open paths are named: {text}"
    );
    let out = kerfmeter(&[&["--json"], &args[..]].concat());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["contours_dilated"], 4);
    assert_eq!(json["dry_run"], true);
    assert_eq!(json["open_paths"].as_array().unwrap().len(), 1);
    assert!(!output.exists());
}

#[test]
fn a_kerf_map_file_gives_each_part_its_own_kerf() {
    let (dir, input) = box_plan();
    // Two cells, centres x = 50 and x = 150 mm: +100 µm on the right.
    let grid = Grid::new(200.0, 100.0, 2, 1).unwrap();
    let map = KerfMap::from_runs(grid, (0, 0), vec![vec![150.0], vec![250.0]]).unwrap();
    let map_path = dir.path().join("map.json");
    map.save(&map_path).unwrap();
    let output = dir.path().join("out.svg");
    let out = kerfmeter(&[
        "--json",
        "dilate",
        path(&input),
        "--kerf-um",
        "150",
        "--map",
        path(&map_path),
        "-o",
        path(&output),
    ]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let range = json["kerf_range_um"].as_array().unwrap();
    let (lo, hi) = (range[0].as_f64().unwrap(), range[1].as_f64().unwrap());
    assert!(
        (lo - 150.0).abs() < 1e-9,
        "side A lies left of the first centre: {lo}"
    );
    assert!(
        hi > 200.0 && hi < 230.0,
        "side B's centroid is near x = 120: {hi}"
    ); // The text's headline names the map, not one kerf for every part.
    let text_out = dir.path().join("out-text.svg");
    let out = kerfmeter(&[
        "dilate",
        path(&input),
        "--kerf-um",
        "150",
        "--map",
        path(&map_path),
        "-o",
        path(&text_out),
    ]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("by the kerf map (150 µm at its reference cell"),
        "{}",
        stdout(&out)
    );
}

#[test]
fn gauge_writes_the_paper_gauge_and_refuses_a_test_piece_without_its_kerf() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("gauge.svg");
    let out = kerfmeter(&["gauge", "-o", path(&svg)]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("cut the red hairlines"),
        "{}",
        stdout(&out)
    );
    assert!(svg.exists());
    let dxf = dir.path().join("piece.dxf");
    let out = kerfmeter(&["gauge", "-o", path(&dxf), "--test-piece"]);
    assert_eq!(code(&out), 2);
    assert!(!dxf.exists());
    // A name it cannot draw says every format it can, G-code included.
    let txt = dir.path().join("gauge.txt");
    let out = kerfmeter(&["gauge", "-o", path(&txt)]);
    assert_eq!(code(&out), 2);
    assert!(
        stderr(&out).contains(".svg, .dxf or a G-code extension (.gcode"),
        "{}",
        stderr(&out)
    );
    assert!(!txt.exists());
    // A kerf for a test piece that is not drawn: refused, not ignored.
    let dir2 = tempfile::tempdir().unwrap();
    let out = kerfmeter(&[
        "gauge",
        "-o",
        path(&dir2.path().join("g.svg")),
        "--test-piece-kerf-um",
        "150",
    ]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(stderr(&out).contains("add it"), "{}", stderr(&out));
    assert!(!dir2.path().join("g.svg").exists());
}

#[test]
fn the_simulated_plant_is_set_by_name_file_and_material_and_checked() {
    // Out of range: a usage error naming the range.
    let out = kerfmeter(&["--sim", "--sim-plant", "supply_v=40", "info"]);
    assert_eq!(code(&out), 2);
    assert!(
        stderr(&out).contains("supply_v must be between 6 and 28 V, got 40"),
        "{}",
        stderr(&out)
    );
    // Unknown: every valid name is listed with its range.
    let out = kerfmeter(&["--sim", "--sim-plant", "voltage=12", "info"]);
    assert_eq!(code(&out), 2);
    assert!(stderr(&out).contains("unknown plant parameter `voltage`"));
    assert!(stderr(&out).contains("tick_jitter_us"), "{}", stderr(&out));
    assert_eq!(
        code(&kerfmeter(&["--sim", "--sim-material", "glass", "info"])),
        2
    );
    // Without --sim, the flags are refused rather than ignored.
    assert_eq!(code(&kerfmeter(&["--sim-material", "mdf", "info"])), 2);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("plant.json");
    std::fs::write(&file, r#"{"supply_v": "high"}"#).unwrap();
    // A plant file that cannot be read or parsed is a file error (exit 4), as a plan's is.
    let out = kerfmeter(&["--sim", "--sim-plant-file", path(&file), "info"]);
    assert_eq!(code(&out), 4);
    assert!(stderr(&out).contains("plant.json"), "{}", stderr(&out));
    let missing = dir.path().join("missing.json");
    let out = kerfmeter(&["--sim", "--sim-plant-file", path(&missing), "info"]);
    assert_eq!(code(&out), 4, "{}", stderr(&out));

    // Accepted: the run's JSON carries the truth beside the reading, and a stiffer material
    // compresses less, so its truth is lower.
    std::fs::write(&file, r#"{"supply_v": 12}"#).unwrap();
    let truth = |material: &str| {
        let out = kerfmeter(&[
            "--sim",
            "--json",
            "--sim-material",
            material,
            "--sim-plant-file",
            path(&file),
            "--sim-plant",
            "kerf_taper_um=20",
            "run",
        ]);
        assert_eq!(code(&out), 0, "{}", stderr(&out));
        let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
        let kerf_um = json["kerf_um"].as_f64().unwrap();
        let truth_um = json["sim_truth_um"].as_f64().expect("sim_truth_um");
        assert_eq!(json["sim_truths_um"].as_array().unwrap().len(), 1);
        assert!(
            (kerf_um - truth_um).abs() < 10.0,
            "{kerf_um} against {truth_um}"
        );
        truth_um
    };
    assert!(truth("acrylic") < truth("cardboard"));
}

#[test]
fn a_plot_that_cannot_be_written_is_refused_before_measuring() {
    let out = kerfmeter(&[
        "--sim",
        "--json",
        "run",
        "--plot",
        "/nonexistent-kerfmeter-dir/curve.svg",
    ]);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    // One JSON object: the error, naming the plot's path; no kerf was measured.
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("one JSON object");
    let error = json["error"].as_str().unwrap();
    assert!(error.contains("/nonexistent-kerfmeter-dir"), "{json}");
    assert!(json.get("kerf_um").is_none(), "{json}");
}

#[test]
fn a_flagged_result_names_its_flags_in_the_json() {
    // A magnet glued a little too far: every reading is flagged `weak-magnet`.
    let out = kerfmeter(&["--sim", "--json", "--sim-plant", "magnet_agc=225", "run"]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let run = &json["runs"][0];
    assert_ne!(run["flags"], 0, "{json}");
    let names = run["flag_names"].as_array().expect("flag_names");
    assert!(names.iter().any(|n| n == "weak-magnet"), "{json}");
}

#[test]
fn the_twin_binary_lists_and_checks_its_plant() {
    let twin = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
            .args(args)
            .output()
            .expect("the kerfmeter-twin binary runs")
    };
    let out = twin(&["--list-plant"]);
    assert_eq!(code(&out), 0);
    let table = stdout(&out);
    for name in [
        "supply_v",
        "cs_filter_tau_us",
        "kerf_taper_um",
        "flash_erase_ms",
    ] {
        assert!(table.contains(name), "{name} missing from\n{table}");
    }
    // Each with its whole description: what it is, and where its default comes from.
    assert!(table.contains("Reference build 12 V"), "{table}");
    let out = twin(&["--sim-plant", "supply_v=99"]);
    assert_eq!(code(&out), 2);
    assert!(stderr(&out).contains("supply_v must be between 6 and 28 V"));
    let out = twin(&["--material", "felt"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
}

#[test]
fn status_reports_state_conditions_supply_and_timing_as_text_and_json() {
    let out = kerfmeter(&["--sim", "status"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let text = stdout(&out);
    for line in [
        "state:        idle",
        "conditions:   none",
        "supply:",
        "longest gap:",
        // A step's duration is a board's figure: the twin says it does not model it.
        "longest step: 0 µs (the simulated device does not model a step's duration",
    ] {
        assert!(text.contains(line), "{line:?} missing from\n{text}");
    }

    let out = kerfmeter(&["--sim", "--json", "status"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let status: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("JSON");
    assert_eq!(status["state"], "idle", "{status}");
    assert_eq!(status["fault"], serde_json::Value::Null, "{status}");
    assert_eq!(status["conditions"], serde_json::json!([]), "{status}");
    let supply_v = status["supply_v"].as_f64().expect("the twin measures it");
    assert!((11.0..13.5).contains(&supply_v), "{status}");
    assert!(
        status["longest_gap_us"].as_u64().unwrap() >= 1000,
        "{status}"
    );
    assert!(status["longest_step_us"].is_u64(), "{status}");
}

/// A device with its encoder on the motor shaft refuses a run after power-up, saying why and
/// what to do (exit 4), and shows the condition in `status`; `confirm-zero` says what it did
/// there, and that an output-shaft encoder needs nothing.
#[test]
fn a_motor_shaft_encoder_refuses_runs_until_confirm_zero() {
    let motor = ["--sim", "--sim-encoder-on-motor-shaft"];
    let out = kerfmeter(&[&motor[..], &["run"]].concat());
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    for words in ["motor shaft", "zero mark", "`kerfmeter confirm-zero`"] {
        assert!(
            stderr(&out).contains(words),
            "{words:?} in {}",
            stderr(&out)
        );
    }
    let out = kerfmeter(&[&motor[..], &["--json", "status"]].concat());
    let status: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("JSON");
    assert_eq!(
        status["conditions"],
        serde_json::json!(["hub-turn-unknown"])
    );
    let out = kerfmeter(&[&motor[..], &["reset"]].concat());
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("may be whole motor turns from its mark"),
        "{}",
        stdout(&out)
    );
    // A script is warned as a reader is.
    let out = kerfmeter(&[&motor[..], &["--json", "reset"]].concat());
    let reset: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("JSON");
    assert!(
        reset["warning"].as_str().unwrap().contains("confirm-zero"),
        "{reset}"
    );
    let out = kerfmeter(&[&motor[..], &["--json", "confirm-zero"]].concat());
    let confirmed: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("JSON");
    assert!(
        confirmed["warning"].as_str().unwrap().contains("fresh one"),
        "{confirmed}"
    );
    let out = kerfmeter(&[&motor[..], &["confirm-zero"]].concat());
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("hub confirmed at its zero mark"),
        "{}",
        stdout(&out)
    );
    // Each --sim command is a fresh twin: the confirmation says it does not carry over.
    assert!(
        stdout(&out).contains("starts a fresh one"),
        "{}",
        stdout(&out)
    );

    let out = kerfmeter(&["--sim", "confirm-zero"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("nothing to confirm: the encoder is on the output shaft"),
        "{}",
        stdout(&out)
    );
    let out = kerfmeter(&["--sim", "--json", "confirm-zero"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert_eq!(stdout(&out).trim(), r#"{"ok":true}"#);
}

/// A motor supply under the driver's under-voltage lockout holds FLT low from boot, and is below
/// the rated 9 V: two idle conditions, shown by `status`, that refuse a run with a typed error
/// (exit 4) and latch nothing, so the device stays configurable.
#[test]
fn a_supply_below_the_driver_lockout_blocks_a_run_but_not_the_configuration() {
    let low = [
        "--sim",
        "--sim-plant",
        "supply_v=6",
        "--sim-plant",
        "driver_uvlo_v=6.5",
    ];
    let with = |args: &[&str]| kerfmeter(&[&low[..], args].concat());

    let out = with(&["--json", "status"]);
    let status: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("JSON");
    assert_eq!(status["state"], "idle", "{status}");
    let both = serde_json::json!(["driver-fault", "supply-out-of-range"]);
    assert_eq!(status["conditions"], both);

    let out = with(&["run"]);
    assert_eq!(code(&out), 4);
    let message = stderr(&out);
    assert!(message.contains("refused Run"), "{message}");
    assert!(message.contains("motor supply"), "{message}");
    assert!(message.contains("Nothing is latched"), "{message}");
    assert!(message.contains("outside the rated 9–26 V"), "{message}");

    let out = with(&["--json", "run"]);
    assert_eq!(code(&out), 4);
    let error: serde_json::Value = serde_json::from_str(stdout(&out).trim()).unwrap();
    assert_eq!(error["fault"], serde_json::Value::Null, "{error}");
    assert_eq!(error["conditions"], both);

    let out = with(&["config", "set", "--max-current-a", "4"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
}

/// On 9 V the default run's torque cap (0.8 N·m) is out of reach: `run` is refused before the
/// motor moves, with the supply, the supply needed and what to do; a lower force (35 N: 0.58
/// N·m at most, which 8.4 V gives) runs.
#[test]
fn a_run_the_supply_cannot_drive_is_refused_with_the_figures() {
    let out = kerfmeter(&["--sim", "--sim-plant", "supply_v=9", "run"]);
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    let message = stderr(&out);
    for part in [
        "refused Run",
        "measures 9.",
        "needs 11.",
        "did not move",
        "--force-n",
    ] {
        assert!(message.contains(part), "{part:?} in {message}");
    }
    let out = kerfmeter(&[
        "--sim",
        "--sim-plant",
        "supply_v=9",
        "run",
        "--force-n",
        "35",
    ]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
}

#[test]
fn info_shows_the_measured_supply_as_text_and_json() {
    let out = kerfmeter(&["--sim", "--sim-plant", "supply_v=24", "info"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(stdout(&out).contains("supply:     24."), "{}", stdout(&out));
    let out = kerfmeter(&["--sim", "--sim-plant", "supply_v=24", "--json", "info"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let info: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("JSON");
    let supply_v = info["supply_v"].as_f64().expect("the twin measures it");
    assert!((23.5..24.7).contains(&supply_v), "{info}");
    assert_eq!(
        info["hardware"]["board"], "twin",
        "DeviceInfo's own fields stand: {info}"
    );
    assert!(info["protocol"]["major"].is_u64(), "{info}");
}

#[test]
fn config_help_says_the_torque_calibration_is_at_the_reference_supply() {
    let out = kerfmeter(&["config", "set", "--help"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let help = stdout(&out);
    let reference = format!("{} V supply", kerfmeter::protocol::REFERENCE_SUPPLY_V);
    assert_eq!(help.matches(&reference).count(), 2, "{help}");
}

#[test]
fn gauge_help_names_no_flag_the_gauge_lacks() {
    let out = kerfmeter(&["gauge", "--help"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let help = stdout(&out);
    assert!(
        help.contains("--feed-mm-per-min") && !help.contains("--profile"),
        "{help}"
    );
}

/// A square part as boxes.py writes it with `--burn 0.1`: drawn 0.1 mm outside (corners rounded
/// by the burn), its command line in the comment.
fn boxes_plan() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join("abox.svg");
    std::fs::write(
        &to,
        r#"<?xml version='1.0' encoding='utf-8'?>
<svg height="40.00mm" viewBox="0.0 0.0 40.00 40.00" width="40.00mm" xmlns="http://www.w3.org/2000/svg">
<!--
ABox - A simple Box

Created with Boxes.py (https://boxes.hackerspace-bamberg.de/)
Command line (remove spaces between dashes): boxes ABox - -burn=0.1
-->
<rect id="part" x="9.9" y="9.9" width="20.2" height="20.2" rx="0.1" fill="none" stroke="rgb(0,0,0)" stroke-width="0.20"/>
</svg>
"#,
    )
    .unwrap();
    (dir, to)
}

#[test]
fn an_already_compensated_plan_is_refused_like_any_plan_error_and_the_flags_lead_on() {
    let (dir, input) = boxes_plan();
    let out_file = dir.path().join("out.svg");
    let refused = dilate(&input, "150", &out_file);
    assert_eq!(code(&refused), 4, "{}", stderr(&refused));
    for needle in [
        "boxes.py compensated this plan with --burn 0.1 (mm",
        "--recompensate",
        "--already-compensated-ok",
    ] {
        assert!(stderr(&refused).contains(needle), "{}", stderr(&refused));
    }
    assert!(!out_file.exists());
    let args = [
        "dilate",
        path(&input),
        "--kerf-um",
        "150",
        "-o",
        path(&out_file),
    ];
    // With --json the refusal says what it found as data, as a success would.
    let refused = kerfmeter(&[&["--json"][..], &args[..]].concat());
    assert_eq!(code(&refused), 4);
    let json: serde_json::Value = serde_json::from_str(&stdout(&refused)).unwrap();
    assert!(json["error"].as_str().unwrap().contains("--recompensate"));
    assert_eq!(json["compensation_found"]["by"], "boxes_py");
    assert_eq!(
        json["compensation_found"]["offset_um"],
        serde_json::json!([100.0, 100.0])
    );
    assert!(!out_file.exists());

    // Undo the burn, apply the kerf: the part comes out 150 µm larger than drawn, not 350.
    let done = kerfmeter(&[&["--json"][..], &args[..], &["--recompensate"]].concat());
    assert_eq!(code(&done), 0, "{}", stderr(&done));
    let json: serde_json::Value = serde_json::from_str(&stdout(&done)).unwrap();
    assert_eq!(json["compensation_found"]["by"], "boxes_py");
    assert_eq!(
        json["compensation_found"]["offset_um"],
        serde_json::json!([100.0, 100.0])
    );
    assert_eq!(json["compensation_applied"]["action"], "recompensate");
    assert_eq!(
        json["compensation_applied"]["net_offset_um"],
        serde_json::json!([-25.0, -25.0])
    );
    assert_eq!(
        json["compensation_applied"]["offset_um"],
        serde_json::json!([75.0, 75.0])
    );
    let written = std::fs::read_to_string(&out_file).unwrap();
    assert!(written.contains("<kerfmeter:compensation"), "{written}");
    // The text's headline gives the net offset applied, as its detail does.
    let text = kerfmeter(&[&args[..], &["--recompensate"]].concat());
    assert_eq!(code(&text), 0, "{}", stderr(&text));
    assert!(
        stdout(&text).contains("each cut moved -25 µm"),
        "{}",
        stdout(&text)
    );

    // The output is this tool's own: refused too, and on top only when asked.
    let again = dir.path().join("again.svg");
    let refused = dilate(&out_file, "150", &again);
    assert_eq!(code(&refused), 4);
    assert!(
        stderr(&refused).contains("kerfmeter"),
        "{}",
        stderr(&refused)
    );
    let anyway = kerfmeter(&[
        "dilate",
        path(&out_file),
        "--kerf-um",
        "150",
        "-o",
        path(&again),
        "--already-compensated-ok",
    ]);
    assert_eq!(code(&anyway), 0, "{}", stderr(&anyway));
    assert!(
        stdout(&anyway).contains("the kerf added on top"),
        "{}",
        stdout(&anyway)
    );

    // Not both.
    let both = kerfmeter(&[&args[..], &["--recompensate", "--already-compensated-ok"]].concat());
    assert_eq!(code(&both), 2);
}

/// A small program: a square with an arc, travels with the laser off.
const SQUARE_GCODE: &str = "; a 20 mm square\nG21 G90\nM4 S0\nG0 X10 Y10\nG1 X30 Y10 S700 F1200\nG1 X30 Y30\nG2 X10 Y30 I-10 J0\nG1 X10 Y10\nM5\nG0 X0 Y0\nM2\n";

fn gcode_file(text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("job.gcode");
    std::fs::write(&file, text).unwrap();
    (dir, file)
}

#[test]
fn map_refuses_an_output_it_cannot_write_before_it_connects() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("no such folder").join("kerf-map.json");
    // A port that does not exist: a map checked only at the end would fail on connecting.
    let out = kerfmeter(&["--port", "/nonexistent/ttyKERF", "map", "-o", path(&output)]);
    assert_ne!(code(&out), 0);
    let message = stderr(&out);
    assert!(message.contains("does not exist"), "{message}");
    assert!(!message.contains("ttyKERF"), "{message}");
    // A folder given for the map is refused as such, not found when the survey is done.
    let out = kerfmeter(&[
        "--port",
        "/nonexistent/ttyKERF",
        "map",
        "-o",
        path(dir.path()),
    ]);
    assert!(stderr(&out).contains("is a directory"), "{}", stderr(&out));
}

#[test]
fn cut_streams_a_program_to_the_simulated_cutter() {
    let (_dir, file) = gcode_file(SQUARE_GCODE);
    let out = kerfmeter(&["--json", "cut", path(&file), "--cutter", "sim"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(report["lines"], 10);
    assert_eq!(report["grbl_version"], "1.1h");
    assert!(report["max_unanswered_bytes"].as_u64().unwrap() <= 128);
    assert_eq!(report["constant_power_line"], serde_json::Value::Null);
}

#[test]
fn cut_warns_of_a_program_that_fires_at_constant_power() {
    let (_dir, file) = gcode_file(&SQUARE_GCODE.replace("M4 S0", "M3 S0"));
    let out = kerfmeter(&["cut", path(&file), "--cutter", "sim"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let message = stderr(&out);
    assert!(
        message.contains("warning: line 3 switches the laser on with M3 (constant power)"),
        "{message}"
    );
    let out = kerfmeter(&["--json", "cut", path(&file), "--cutter", "sim"]);
    let report: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(report["constant_power_line"], 3);
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
}

#[test]
fn cut_refuses_an_unstreamable_program_and_reports_a_refused_line() {
    let (_dir, file) = gcode_file("G0 X1\nG1 X2 F100 ?\n");
    let out = kerfmeter(&["cut", path(&file), "--cutter", "sim"]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
    assert!(stderr(&out).contains("line 2"), "{}", stderr(&out));
    assert!(
        !stderr(&out).contains("streaming"),
        "refused before connecting"
    );
    // Quoted as written in the file, spaces kept.
    let (_dir, file) = gcode_file("G0 X1\nG28 G91 Z0\n");
    let out = kerfmeter(&["cut", path(&file), "--cutter", "sim"]);
    assert_eq!(code(&out), 4);
    let message = stderr(&out);
    assert!(
        message.contains("line 2 (`G28 G91 Z0`) with error:20"),
        "{message}"
    );
    assert!(message.contains("laser is off"), "{message}");
}

#[test]
fn cut_refuses_a_program_written_for_another_s_max() {
    // The simulated cutter has GRBL's default $30=1000.
    let program = format!("(S_MAX=255 must equal GRBL setting 30)\n{SQUARE_GCODE}");
    let (_dir, file) = gcode_file(&program);
    let out = kerfmeter(&["cut", path(&file), "--cutter", "sim"]);
    assert_eq!(code(&out), 4, "{}", stderr(&out));
    let message = stderr(&out);
    assert!(
        message.contains("S max 255") && message.contains("$30 is 1000"),
        "{message}"
    );
    assert!(message.contains("Nothing was sent"), "{message}");
}

#[test]
fn ctrl_c_during_cut_stops_the_cutter_and_fails() {
    interrupting_a_cut_stops_the_cutter("-INT");
}

#[test]
fn sigterm_and_sighup_during_cut_stop_the_cutter_too() {
    // Without ctrlc's "termination" feature these killed the process with the laser running.
    interrupting_a_cut_stops_the_cutter("-TERM");
    interrupting_a_cut_stops_the_cutter("-HUP");
}

fn interrupting_a_cut_stops_the_cutter(signal: &str) {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    // Long enough (hours of simulated motion) that only the signal ends it.
    let long: String = (0..2000)
        .map(|i| format!("G1 X{} Y0 S500 F600\n", 100 * (i % 2)))
        .collect();
    let (_dir, file) = gcode_file(&format!("M4\n{long}"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(["cut", path(&file), "--cutter", "sim"])
        .stderr(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    stderr.read_line(&mut first).unwrap();
    assert!(first.starts_with("streaming"), "{first}");
    let interrupted = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(interrupted.success());
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(4), "{signal}: {rest}");
    assert!(rest.contains("cancelled after"), "{signal}: {rest}");
    assert!(rest.contains("laser is off"), "{signal}: {rest}");
}

#[test]
fn ctrl_c_mid_cut_leaves_the_machine_idle_with_the_laser_off() {
    use std::io::{BufRead, BufReader, Read, Write};
    use std::process::Stdio;
    // The cutter twin in a process of its own, so that its state can be asked afterwards.
    let mut twin = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
        .args(["--cutter", "--tcp", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut url = String::new();
    BufReader::new(twin.stdout.take().unwrap())
        .read_line(&mut url)
        .unwrap();
    let url = url.trim().to_owned();
    // Under M3, whose beam GRBL leaves on at rest after a cut.
    let long: String = (0..2000)
        .map(|i| format!("G1 X{} Y0 S500 F600\n", 100 * (i % 2)))
        .collect();
    let (_dir, file) = gcode_file(&format!("M3\n{long}"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(["cut", path(&file), "--cutter", &url, "--no-check"])
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut first = String::new();
    stderr.read_line(&mut first).unwrap();
    assert!(
        first.starts_with("warning: line 1 switches the laser on with M3"),
        "{first}"
    );
    let mut second = String::new();
    stderr.read_line(&mut second).unwrap();
    assert!(second.starts_with("streaming"), "{second}");
    std::thread::sleep(std::time::Duration::from_millis(300));
    let interrupted = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(interrupted.success());
    let mut rest = String::new();
    stderr.read_to_string(&mut rest).unwrap();
    assert_eq!(child.wait().unwrap().code(), Some(4), "{rest}");
    // Ask the machine itself.
    let mut link = std::net::TcpStream::connect(url.trim_start_matches("grbl+tcp://")).unwrap();
    link.set_read_timeout(Some(std::time::Duration::from_secs(3)))
        .unwrap();
    link.write_all(b"?").unwrap();
    let status = BufReader::new(link)
        .lines()
        .map_while(Result::ok)
        .find(|l| l.starts_with('<'))
        .unwrap_or_default();
    twin.kill().unwrap();
    twin.wait().unwrap();
    assert!(status.starts_with("<Idle|"), "{status}");
    assert!(status.ends_with(",0>"), "the laser is off: {status}");
}

#[test]
fn the_twin_binary_serves_the_cutter_on_tcp_for_cut() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut twin = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
        .args(["--cutter", "--tcp", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut url = String::new();
    BufReader::new(twin.stdout.take().unwrap())
        .read_line(&mut url)
        .unwrap();
    let url = url.trim().to_owned();
    assert!(url.starts_with("grbl+tcp://127.0.0.1:"), "{url}");
    let (_dir, file) = gcode_file(SQUARE_GCODE);
    let out = kerfmeter(&["--json", "cut", path(&file), "--cutter", &url]);
    twin.kill().unwrap();
    twin.wait().unwrap();
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(stdout(&out).contains("\"lines\":10"), "{}", stdout(&out));
}

/// A 40 × 30 mm plate with a round hole (red) and a blue square, in mm.
fn plate_plan() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join("plate.svg");
    std::fs::write(
        &to,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">
  <rect x="5" y="5" width="40" height="30" fill="none" stroke="red" stroke-width="0.01"/>
  <circle cx="25" cy="20" r="5" fill="none" stroke="red" stroke-width="0.01"/>
  <rect x="60" y="5" width="20" height="20" fill="none" stroke="blue" stroke-width="0.01"/>
</svg>"#,
    )
    .unwrap();
    (dir, to)
}

#[test]
fn gcode_writes_the_dilated_plan_with_settings_per_colour_and_refuses_what_it_cannot_cut() {
    let (dir, input) = plate_plan();
    let out = dir.path().join("plate.gcode");
    let profile = dir.path().join("cut.toml");
    std::fs::write(
        &profile,
        "[color.red]\nfeed_mm_per_min = 400\npower_percent = 90\npasses = 2\n",
    )
    .unwrap();
    let args = [
        "gcode",
        path(&input),
        "--kerf-um",
        "200",
        "-o",
        path(&out),
        "--profile",
        path(&profile),
    ];
    // The blue square has no settings: refused like any plan that cannot be cut (4), naming its
    // colour; nothing written.
    let refused = kerfmeter(&args);
    assert_eq!(code(&refused), 4, "{}", stderr(&refused));
    assert!(
        stderr(&refused).contains("colour #0000FF"),
        "{}",
        stderr(&refused)
    );
    assert!(!out.exists());
    // With a default for the rest it is written.
    let mut with_default = args.to_vec();
    with_default.extend([
        "--feed-mm-per-min",
        "900",
        "--power-percent",
        "50",
        "--json",
    ]);
    let done = kerfmeter(&with_default);
    assert_eq!(code(&done), 0, "{}", stderr(&done));
    assert_eq!(stdout(&done).matches("\"format\"").count(), 1);
    let report: serde_json::Value = serde_json::from_str(&stdout(&done)).unwrap();
    assert_eq!(report["format"], "svg");
    assert_eq!(report["program"]["contours"], 3);
    assert_eq!(report["mapping"]["flip_y"], true);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("(kerf applied: 200 um)"), "{text}");
    assert!(
        text.contains("M4 S900") && text.contains("M4 S500"),
        "{text}"
    );
    assert!(text.contains("F400") && text.contains("F900"));
    // Never over the input, and only into a G-code file.
    let over = kerfmeter(&[
        "gcode",
        path(&input),
        "--kerf-um",
        "200",
        "-o",
        path(&input),
    ]);
    assert_eq!(code(&over), 2);
    assert!(stderr(&over).contains(".gcode"), "{}", stderr(&over));
}

#[test]
fn gcode_says_what_it_left_out_and_which_profile_entries_set_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("two.svg");
    std::fs::write(
        &input,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">
  <rect x="5" y="5" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>
  <rect x="60" y="5" width="20" height="20" fill="none" stroke="green" stroke-width="0.01"/>
</svg>"#,
    )
    .unwrap();
    // Green is no cut under the default rules: a [color.green] entry does not make it one.
    let profile = dir.path().join("cut.toml");
    std::fs::write(
        &profile,
        "[color.red]\nfeed_mm_per_min = 400\npower_percent = 90\n\n[color.green]\nfeed_mm_per_min = 300\npower_percent = 100\n",
    )
    .unwrap();
    let out = dir.path().join("two.gcode");
    let done = kerfmeter(&[
        "gcode",
        path(&input),
        "--kerf-um",
        "200",
        "-o",
        path(&out),
        "--profile",
        path(&profile),
    ]);
    assert_eq!(code(&done), 0, "{}", stderr(&done));
    let said = format!("{}{}", stdout(&done), stderr(&done));
    assert!(said.contains("not cut: 1 ×"), "{said}");
    assert!(
        said.contains("[color.\"#008000\"] sets no contour"),
        "{said}"
    );
    assert!(!said.contains("[color.\"#FF0000\"]"), "{said}");
}

#[test]
fn gauge_writes_g_code_with_its_spiral_centre_where_asked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gauge.gcode");
    // Without cut settings it is refused: the kerf it measures depends on them.
    let refused = kerfmeter(&["gauge", "-o", path(&out), "--at-mm", "120,40"]);
    assert_eq!(code(&refused), 2, "{}", stderr(&refused));
    assert!(
        stderr(&refused).contains("--feed-mm-per-min"),
        "{}",
        stderr(&refused)
    );
    assert!(!out.exists());
    let done = kerfmeter(&[
        "--json",
        "gauge",
        "-o",
        path(&out),
        "--at-mm",
        "120,40",
        "--feed-mm-per-min",
        "400",
        "--power-percent",
        "90",
    ]);
    assert_eq!(code(&done), 0, "{}", stderr(&done));
    let report: serde_json::Value = serde_json::from_str(&stdout(&done)).unwrap();
    assert_eq!(report["format"], "gcode");
    assert_eq!(report["gcode"]["at_mm"], serde_json::json!([120.0, 40.0]));
    assert_eq!(report["gcode"]["program"]["contours"], 3);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("(spiral centre at X120 Y40 mm)"), "{text}");
    // --at-mm means nothing for a drawing.
    let svg = dir.path().join("gauge.svg");
    let refused = kerfmeter(&["gauge", "-o", path(&svg), "--at-mm", "1,2"]);
    assert_eq!(code(&refused), 2);
    // Nor --s-max: silently ignoring it would hide a mistake.
    let refused = kerfmeter(&["gauge", "-o", path(&svg), "--s-max", "255"]);
    assert_eq!(code(&refused), 2, "{}", stderr(&refused));
    assert!(!svg.exists());
}

/// `kerfmeter --sim --json --db DB run` at the twin's `kerf_um`, labelled `label`: its JSON.
fn sim_run(db: &Path, label: &str, kerf_um: &str) -> serde_json::Value {
    let out = kerfmeter(&[
        "--sim",
        "--json",
        "--db",
        path(db),
        "--sim-kerf-um",
        kerf_um,
        "run",
        "--label",
        label,
    ]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    serde_json::from_str(&stdout(&out)).expect("JSON")
}

#[test]
fn runs_are_recorded_listed_newest_first_and_a_drift_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("history.sqlite3");
    // Listing a history named that does not exist yet says so (a mistyped path is not an empty
    // history), and creates nothing.
    let out = kerfmeter(&["--db", path(&db), "history"]);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    assert!(stderr(&out).contains("no history at"), "{}", stderr(&out));
    assert!(!db.exists());
    for (i, kerf) in ["150", "152", "148"].into_iter().enumerate() {
        let json = sim_run(&db, "birch", kerf);
        assert_eq!(json["history"]["id"], i + 1, "{json}");
        assert_eq!(json["history"]["db"], path(&db));
        assert_eq!(json["history"]["drift"], serde_json::Value::Null);
        assert_eq!(json["label"], "birch");
    }
    sim_run(&db, "mdf", "300");
    // Birch's kerf jumps: the run warns, as text and in its JSON.
    let out = kerfmeter(&[
        "--sim",
        "--db",
        path(&db),
        "--sim-kerf-um",
        "230",
        "run",
        "--label",
        "birch",
    ]);
    let text = stdout(&out);
    assert!(text.contains("recorded as #5 in"), "{text}");
    assert!(text.contains("warning: drift: birch measured"), "{text}");
    assert!(text.contains("dirty lens"), "{text}");
    // The history, from another process: newest first, the drift with it.
    let out = kerfmeter(&["--sim", "--json", "--db", path(&db), "history"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let listed: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let labels: Vec<&str> = listed["records"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["label"].as_str().unwrap())
        .collect();
    assert_eq!(labels, ["birch", "mdf", "birch", "birch", "birch"]);
    assert_eq!(listed["records"][0]["device_id"], "twin");
    assert_eq!(listed["records"][0]["simulated"], true);
    assert_eq!(listed["drift"][0]["label"], "birch", "{listed}");
    let usual = listed["drift"][0]["usual_mean_um"].as_f64().unwrap();
    let newest = listed["records"][0]["kerf_um"].as_f64().unwrap();
    assert!(newest - usual > 50.0, "{newest} vs {usual}");
    let out = kerfmeter(&[
        "--sim",
        "--db",
        path(&db),
        "history",
        "--label",
        "mdf",
        "--limit",
        "5",
    ]);
    let text = stdout(&out);
    assert!(
        text.starts_with("1 simulated measurement labelled \"mdf\" in"),
        "{text}"
    );
    assert!(!text.contains("warning"), "{text}");
    // A limit reached says there may be more; a label with none says so.
    let listed = |args: &[&str]| {
        let out = kerfmeter(&[&["--sim", "--db", path(&db), "history"], args].concat());
        stdout(&out)
    };
    let text = listed(&["--limit", "2"]);
    assert!(
        text.starts_with("the newest 2 simulated measurements in")
            && text.contains("(--limit 2: there may be more)"),
        "{text}"
    );
    let text = listed(&["--label", "nope"]);
    assert!(
        text.starts_with("no simulated measurements labelled \"nope\" in"),
        "{text}"
    );
    // The simulated records are not among the real ones.
    let out = kerfmeter(&["--db", path(&db), "history"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains("no real measurements"),
        "{}",
        stdout(&out)
    );
}

#[test]
fn a_history_in_a_folder_that_does_not_exist_is_refused_before_measuring() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("no-such-folder").join("history.sqlite3");
    let out = kerfmeter(&["--sim", "--json", "--db", path(&db), "run"]);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).expect("one JSON object");
    let error = json["error"].as_str().unwrap();
    assert!(error.contains("folder does not exist"), "{json}");
    assert!(json.get("kerf_um").is_none(), "{json}");
    assert!(
        !dir.path().join("no-such-folder").exists(),
        "a mistyped folder is not made"
    );
}

#[test]
fn a_history_that_cannot_be_written_warns_and_keeps_the_measurement() {
    let dir = tempfile::tempdir().unwrap();
    let not_a_db = dir.path().join("notes.txt");
    let text = "these are notes, not a database; they must survive";
    std::fs::write(&not_a_db, text).unwrap();
    let json = sim_run(&not_a_db, "birch", "150");
    assert!(json["kerf_um"].as_f64().unwrap() > 100.0);
    assert_eq!(json["history"]["id"], serde_json::Value::Null);
    let error = json["history"]["error"].as_str().unwrap();
    assert!(error.contains("notes.txt"), "{error}");
    assert_eq!(std::fs::read_to_string(&not_a_db).unwrap(), text);
    // A database from a newer kerfmeter: `history` refuses it, `run` still measures.
    let db = dir.path().join("history.sqlite3");
    sim_run(&db, "birch", "150");
    let mut bytes = std::fs::read(&db).unwrap();
    // SQLite's header keeps `PRAGMA user_version` at bytes 60..64, big-endian.
    bytes[60..64].copy_from_slice(&99u32.to_be_bytes());
    std::fs::write(&db, &bytes).unwrap();
    let out = kerfmeter(&["--sim", "--db", path(&db), "history"]);
    assert_eq!(code(&out), 4);
    let message = stderr(&out);
    assert!(message.contains("schema version 99"), "{message}");
    assert!(message.contains("Upgrade kerfmeter"), "{message}");
    let json = sim_run(&db, "birch", "150");
    assert!(json["history"]["error"].as_str().unwrap().contains("newer"));
    assert_eq!(std::fs::read(&db).unwrap(), bytes);
    // A bad label is refused before anything is measured.
    let out = kerfmeter(&["--sim", "--db", path(&db), "run", "--label", " "]);
    assert_eq!(code(&out), 2, "{}", stderr(&out));
}

#[test]
fn a_cut_single_precision_cannot_hold_is_refused_by_name_and_nothing_written() {
    // usvg dropped such a cut whole: the plan was dilated without it, with no word.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("far.svg");
    std::fs::write(
        &input,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50"><g fill="none" stroke="#ff0000" stroke-width="0.1"><rect x="5" y="5" width="20" height="20"/><circle id="far" cx="1e38" cy="15" r="5"/></g></svg>"##,
    )
    .unwrap();
    let output = dir.path().join("out.svg");
    let out = dilate(&input, "150", &output);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    let message = stderr(&out);
    assert!(message.contains("far.svg"), "{message}");
    assert!(
        message.contains(r#"circle "far" has the number 1e38 in its cx attribute"#),
        "{message}"
    );
    assert!(!output.exists());
}
