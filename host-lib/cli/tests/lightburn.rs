//! `kerfmeter dilate project.lbrn2`: a LightBurn project's Line layers get a Kerf Offset of half
//! the kerf, written atomically beside the input (never over it), reported as text and JSON;
//! options that mean nothing for a project, and a project already compensated, are refused.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn kerfmeter(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        .env_remove("KERFMETER_PORT")
        .output()
        .expect("the kerfmeter binary runs")
}

fn code(out: &Output) -> i32 {
    out.status.code().expect("exited, not killed")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A project of `kerfmeter-plan`'s corpus, copied into a fresh folder.
fn project(name: &str) -> (tempfile::TempDir, PathBuf) {
    let from = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../lightburn/tests/corpus")
        .join(name);
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join(name);
    std::fs::copy(from, &to).unwrap();
    (dir, to)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn dilate_sets_the_kerf_offset_of_a_lightburn_project_and_reports_it() {
    let (dir, input) = project("lightburn_2x_layers.lbrn2");
    let before = std::fs::read(&input).unwrap();
    let out_path = dir.path().join("out.lbrn2");
    let out = kerfmeter(&["dilate", s(&input), "--kerf-um", "150", "-o", s(&out_path)]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    let report = text(&out.stdout);
    assert!(
        report.contains("Kerf Offset 0.075 mm (half the kerf"),
        "{report}"
    );
    assert!(
        report.contains("layer 1 \"Engrave\" (Scan): left alone"),
        "{report}"
    );
    assert_eq!(
        std::fs::read(&input).unwrap(),
        before,
        "the input is untouched"
    );
    let written = std::fs::read_to_string(&out_path).unwrap();
    assert_eq!(written.matches("<kerf Value=\"0.075\"/>").count(), 3);
    // Nothing but the project and its output in the folder: no temporary file left.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);

    let out = kerfmeter(&[
        "--json",
        "dilate",
        s(&input),
        "--kerf-um",
        "200",
        "--layers",
        "Score",
        "--dry-run",
    ]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["format"], "lightburn");
    assert_eq!(json["kerf_offset_mm"], 0.1);
    assert_eq!(json["layers"][2]["set"][0]["after_mm"], 0.1);
    assert!(json["output"].is_null());
}

#[test]
fn dilate_refuses_what_does_not_fit_a_lightburn_project() {
    let (dir, input) = project("lightburn_2x_layers.lbrn2");
    let svg = dir.path().join("out.svg");
    let out = kerfmeter(&["dilate", s(&input), "--kerf-um", "150", "-o", s(&svg)]);
    assert_eq!(code(&out), 2, "{}", text(&out.stderr));
    let out = kerfmeter(&["dilate", s(&input), "--kerf-um", "150", "-o", s(&input)]);
    assert_ne!(code(&out), 0);
    let out = kerfmeter(&[
        "dilate",
        s(&input),
        "--kerf-um",
        "150",
        "--dry-run",
        "--cut-color",
        "red",
    ]);
    assert_eq!(code(&out), 2);
    assert!(text(&out.stderr).contains("--cut-color does not apply to a LightBurn project"));
    let out = kerfmeter(&[
        "dilate",
        s(&input),
        "--kerf-um",
        "150",
        "--dry-run",
        "--layers",
        "Engrave",
    ]);
    assert_eq!(code(&out), 2, "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("not a Line (cut) layer"));
    assert!(!svg.exists());
}

#[test]
fn the_output_keeps_the_projects_extension() {
    let (dir, input) = project("lightburn_2x_layers.lbrn2");
    let old_format = dir.path().join("out.lbrn");
    let out = kerfmeter(&[
        "dilate",
        s(&input),
        "--kerf-um",
        "150",
        "-o",
        s(&old_format),
    ]);
    assert_eq!(code(&out), 2, "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("must have the input's extension .lbrn2"),
        "{}",
        text(&out.stderr)
    );
    assert!(!old_format.exists());
    // The reverse: a LightBurn 1.x project saved as .lbrn2.
    let lbrn = dir.path().join("in.lbrn");
    std::fs::copy(&input, &lbrn).unwrap();
    let new_format = dir.path().join("out.lbrn2");
    let out = kerfmeter(&["dilate", s(&lbrn), "--kerf-um", "150", "-o", s(&new_format)]);
    assert_eq!(code(&out), 2, "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("must have the input's extension .lbrn"));
    assert!(!new_format.exists());
    // Same extension, any case: accepted.
    let upper = dir.path().join("out.LBRN2");
    let out = kerfmeter(&["dilate", s(&input), "--kerf-um", "150", "-o", s(&upper)]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
}

#[test]
fn layers_is_for_lightburn_projects_only() {
    let plan =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../plan/tests/fixtures/box_generator.svg");
    let out = kerfmeter(&[
        "dilate",
        s(&plan),
        "--kerf-um",
        "150",
        "--dry-run",
        "--layers",
        "0",
    ]);
    assert_eq!(code(&out), 2);
    assert!(text(&out.stderr).contains("--cut-layer"));
}

#[test]
fn a_compensated_project_is_refused_until_told_to_replace_its_offsets() {
    let (dir, input) = project("lightburn_compensated.lbrn2");
    let output = dir.path().join("out.lbrn2");
    let out = kerfmeter(&["dilate", s(&input), "--kerf-um", "150", "-o", s(&output)]);
    assert_eq!(code(&out), 4, "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("--recompensate"));
    assert!(!output.exists());
    let out = kerfmeter(&[
        "dilate",
        s(&input),
        "--kerf-um",
        "150",
        "-o",
        s(&output),
        "--recompensate",
    ]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("line pass 0.08 → 0.075 mm"));
    assert!(text(&out.stdout).contains("replaced by this kerf's"));
}

#[test]
fn sim_pairs_with_and_applies_to_a_lightburn_twin_and_keeps_no_secret() {
    let dir = tempfile::tempdir().unwrap();
    let pairing = dir.path().join("lightburn.json");
    let with_pairing = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
            .args(args)
            .env("KERFMETER_LIGHTBURN_PAIRING", &pairing)
            .output()
            .expect("the kerfmeter binary runs")
    };
    let out = with_pairing(&["--sim", "lightburn", "pair"]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("paired with the LightBurn twin"));
    let out = with_pairing(&["--sim", "--json", "lightburn", "apply", "--kerf-um", "150"]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["simulated"], true, "{json}");
    assert_eq!(json["kerf_offset"], 0.075, "{json}");
    assert_eq!(json["layers"].as_array().unwrap().len(), 2, "{json}");
    assert!(!pairing.exists(), "a simulated pairing is not kept");
    // A layer already offset: refused, and the JSON error names what was found as `dilate`'s
    // does for a project file.
    let out = with_pairing(&[
        "--sim",
        "--json",
        "lightburn",
        "apply",
        "--kerf-um",
        "150",
        "--layers",
        "Old",
    ]);
    assert_eq!(code(&out), 2, "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let found = &json["compensation_found"];
    assert_eq!(found["by"], "lightburn", "{json}");
    assert_eq!(
        found["offset_um"],
        serde_json::json!([50.0, 50.0]),
        "{json}"
    );
    assert!(
        json["error"].as_str().unwrap().contains("--recompensate"),
        "{json}"
    );
    // The twin is the twin: a real LightBurn's address does not go with --sim.
    let out = with_pairing(&[
        "--sim",
        "lightburn",
        "apply",
        "--kerf-um",
        "150",
        "--host",
        "h:1",
    ]);
    assert_eq!(code(&out), 2, "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("--host"));
}

#[test]
fn pairing_again_says_the_earlier_secret_is_still_authorised_and_where_to_revoke_it() {
    // A LightBurn twin at --host: the path a real LightBurn takes, not --sim.
    let twin = kerfmeter_lightburn::twin::LightBurnTwin::start(Default::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("lightburn.json");
    let pair = || {
        kerfmeter(&[
            "lightburn",
            "pair",
            "--host",
            twin.host(),
            "--pairing-file",
            s(&file),
        ])
    };
    let first = pair();
    assert_eq!(code(&first), 0, "{}", text(&first.stderr));
    assert!(!text(&first.stdout).contains("Manage authorizations"));
    let second = pair();
    assert_eq!(code(&second), 0, "{}", text(&second.stderr));
    let said = text(&second.stdout);
    assert!(said.contains("still authorised in LightBurn"), "{said}");
    assert!(said.contains("Manage authorizations"), "{said}");
    // LightBurn holds both, and the file the newer.
    let granted = twin.authorisations();
    assert_eq!(granted.len(), 2);
    let kept: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(kept["secret"], granted[1].secret.as_str());
    // JSON says it too.
    let out = kerfmeter(&[
        "--json",
        "lightburn",
        "pair",
        "--host",
        twin.host(),
        "--pairing-file",
        s(&file),
    ]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["earlier_pairing_still_authorised"], true, "{json}");
}

#[test]
fn apply_says_the_project_is_modified_and_to_save_and_send_again() {
    let twin = kerfmeter_lightburn::twin::LightBurnTwin::start(Default::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("lightburn.json");
    let with_file = |args: &[&str]| {
        let mut all = args.to_vec();
        all.extend(["--host", twin.host(), "--pairing-file", s(&file)]);
        kerfmeter(&all)
    };
    assert_eq!(code(&with_file(&["lightburn", "pair"])), 0);
    let out = with_file(&["lightburn", "apply", "--kerf-um", "150"]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    let said = text(&out.stdout);
    assert!(
        said.contains("project is now modified and not saved"),
        "{said}"
    );
    assert!(said.contains("send the job again"), "{said}");
    assert!(twin.project().modified);
    let out = with_file(&[
        "--json",
        "lightburn",
        "apply",
        "--kerf-um",
        "150",
        "--recompensate",
    ]);
    assert_eq!(code(&out), 0, "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["project_modified"], true, "{json}");
    assert_eq!(json["layers"][1]["cut_index"], 2, "{json}");
}
