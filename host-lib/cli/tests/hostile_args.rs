//! No argument makes the tool panic. Every subcommand, as `--help` lists it, is walked: each
//! option that takes a value gets a negative, NaN, infinite, huge and non-UTF-8 value in turn
//! (both `--flag VALUE` and `--flag=VALUE`), and each file it names a non-UTF-8 name. A refusal
//! must be a message on stderr (or one JSON object on stdout with `--json`), never a panic
//! (exit 101). Everything runs against the twins, in a temporary HOME.

use std::ffi::{OsStr, OsString};
use std::os::unix::ffi::{OsStrExt, OsStringExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The values every option is tried with.
fn hostile_values() -> Vec<OsString> {
    let mut values: Vec<OsString> = ["-1", "-0", "NaN", "inf", "-inf", "1e308"]
        .into_iter()
        .map(OsString::from)
        .collect();
    values.push(OsString::from_vec(b"x\xff\xfe".to_vec()));
    values
}

/// Options whose values are free text or start a long-lived server: a hostile number there is a
/// valid value, so only the non-UTF-8 one is tried.
const FREE_TEXT: [&str; 6] = [
    "--label",
    "--token",
    "--allow-origin",
    "--cut-color",
    "--cut-layer",
    "--layers",
];

/// A scratch folder with the inputs the commands need.
struct Scratch {
    _dir: tempfile::TempDir,
    root: PathBuf,
}

impl Scratch {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().to_path_buf();
        let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/box-parts.svg");
        std::fs::copy(plan, root.join("plan.svg")).unwrap();
        std::fs::write(root.join("job.gcode"), "G21\nG90\nM5\nG0 X1 Y1\n").unwrap();
        Self { _dir: dir, root }
    }

    fn file(&self, name: &str) -> String {
        self.root.join(name).to_str().unwrap().to_owned()
    }

    /// Each subcommand, and the arguments that make it runnable (on the twins).
    fn commands(&self) -> Vec<(Vec<&'static str>, Vec<String>)> {
        let plan = self.file("plan.svg");
        let s = |v: &[&str]| v.iter().map(|a| (*a).to_owned()).collect::<Vec<_>>();
        let with = |mut v: Vec<String>, more: &[String]| {
            v.extend_from_slice(more);
            v
        };
        vec![
            (vec!["info"], s(&["--sim"])),
            (vec!["status"], s(&["--sim"])),
            (vec!["kerf"], s(&["--sim"])),
            (vec!["reset"], s(&["--sim"])),
            (vec!["abort"], s(&["--sim"])),
            (vec!["clear-fault"], s(&["--sim"])),
            (vec!["confirm-zero"], s(&["--sim"])),
            (vec!["self-test"], s(&["--sim"])),
            (vec!["bringup"], s(&["--sim", "--no-gauge"])),
            (vec!["config", "get"], s(&["--sim"])),
            (vec!["config", "set"], s(&["--sim"])),
            (vec!["run"], s(&["--sim"])),
            (
                vec!["map"],
                with(
                    s(&[
                        "--sim",
                        "--cols",
                        "1",
                        "--rows",
                        "1",
                        "--per-cell",
                        "1",
                        "-o",
                    ]),
                    &[self.file("map.json")],
                ),
            ),
            (vec!["gauge"], vec!["-o".into(), self.file("gauge.svg")]),
            (
                vec!["dilate"],
                vec![
                    plan.clone(),
                    "--kerf-um".into(),
                    "150".into(),
                    "-o".into(),
                    self.file("out.svg"),
                ],
            ),
            (
                vec!["cut"],
                vec![self.file("job.gcode"), "--cutter".into(), "sim".into()],
            ),
            (
                vec!["gcode"],
                vec![
                    plan.clone(),
                    "--kerf-um".into(),
                    "150".into(),
                    "--feed-mm-per-min".into(),
                    "600".into(),
                    "--power-percent".into(),
                    "50".into(),
                    "-o".into(),
                    self.file("out.gcode"),
                ],
            ),
            (vec!["lightburn", "pair"], s(&["--sim"])),
            (
                vec!["lightburn", "apply"],
                s(&["--sim", "--kerf-um", "150"]),
            ),
            (
                vec!["job"],
                with(
                    s(&["--sim", "--dry-run", "--cutter", "sim", "-o"]),
                    &[self.file("job-out.svg"), plan],
                ),
            ),
            (vec!["history"], s(&["--sim"])),
            (vec!["serve"], s(&["--sim", "--listen", "127.0.0.1:0"])),
        ]
    }
}

/// The options `kerfmeter <sub> --help` lists as taking a value (device flags left out but
/// `--timeout-ms`, walked with `info`).
fn value_options(sub: &[&str]) -> Vec<String> {
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(sub)
        .arg("--help")
        .output()
        .unwrap();
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter_map(|line| {
            let line = line.trim_start();
            let line = line.split_once(", ").map_or(line, |(_, long)| long);
            let (flag, rest) = line.split_once(' ')?;
            (flag.starts_with("--") && rest.starts_with('<')).then(|| flag.to_owned())
        })
        .filter(|flag| !flag.starts_with("--sim") && flag != "--port" && flag != "--db")
        .filter(|flag| sub != ["info"] || flag == "--timeout-ms")
        .filter(|flag| sub == ["info"] || flag != "--timeout-ms")
        .collect()
}

/// `base` without `flag` and the value after it.
fn without(base: &[String], flag: &str, short: Option<&str>) -> Vec<String> {
    let mut out = Vec::new();
    let mut skip = false;
    for a in base {
        if skip {
            skip = false;
        } else if a == flag || Some(a.as_str()) == short {
            skip = true;
        } else {
            out.push(a.clone());
        }
    }
    out
}

/// Run the CLI with `args` (a server is stopped after a few seconds: it started, so it did not
/// panic on its arguments).
fn kerfmeter(home: &Path, args: &[OsString]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        // An output named `-1` lands here, not in the source tree.
        .current_dir(home)
        .env("HOME", home)
        .env("XDG_DATA_HOME", home.join("data"))
        .env("XDG_CONFIG_HOME", home.join("config"))
        .env_remove("KERFMETER_DB")
        .env_remove("KERFMETER_PORT")
        .env_remove("KERFMETER_CUTTER")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    child.wait_with_output().unwrap()
}

/// What a run of the CLI must never show: a panic, or a failure without a message.
fn check(args: &[OsString], out: &Output, json: bool) {
    let shown = format!("{args:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!stderr.contains("panicked"), "{shown}: {stderr}");
    assert_ne!(out.status.code(), Some(101), "{shown}: {stderr}");
    if out.status.success() || out.status.code().is_none() {
        return;
    }
    if json {
        let last = stdout.lines().last().unwrap_or_default();
        let report: serde_json::Value = serde_json::from_str(last)
            .unwrap_or_else(|e| panic!("{shown}: not one JSON object ({e}): {stdout}"));
        assert!(
            report["error"].is_string() || report.is_object(),
            "{shown}: {stdout}"
        );
    } else {
        assert!(
            stderr.contains("error") || stderr.contains("interrupted"),
            "{shown}: no message: {stderr}"
        );
        assert!(
            !stderr.contains("Custom {"),
            "{shown}: debug text: {stderr}"
        );
    }
}

#[test]
fn every_option_of_every_command_refuses_hostile_values_without_panicking() {
    let scratch = Scratch::new();
    let values = hostile_values();
    let mut tried = 0;
    for (sub, base) in scratch.commands() {
        for flag in value_options(&sub) {
            let short = (flag == "--output").then_some("-o");
            let rest = without(&base, &flag, short);
            let free = FREE_TEXT.contains(&flag.as_str()) || sub == ["serve"];
            for value in values.iter().filter(|v| !free || v.to_str().is_none()) {
                for json in [false, true] {
                    let mut args: Vec<OsString> = Vec::new();
                    if json {
                        args.push("--json".into());
                    }
                    args.extend(sub.iter().map(OsString::from));
                    args.extend(rest.iter().map(OsString::from));
                    let mut joined = OsString::from(format!("{flag}="));
                    joined.push(value);
                    let spaced = [OsString::from(&flag), value.clone()];
                    // `--flag=VALUE` in text only: the JSON path is the same after parsing.
                    let forms = if json {
                        vec![spaced.to_vec()]
                    } else {
                        vec![vec![joined], spaced.to_vec()]
                    };
                    for form in forms {
                        let mut args = args.clone();
                        args.extend(form);
                        let out = kerfmeter(&scratch.root, &args);
                        check(&args, &out, json);
                        tried += 1;
                    }
                }
            }
        }
    }
    eprintln!("{tried} hostile command lines, none panicked");
    assert!(tried > 500, "{tried}: the walk found too few options");
}

#[test]
fn a_non_utf8_file_name_is_read_written_and_reported_in_text_and_json() {
    let scratch = Scratch::new();
    let name = |stem: &[u8], ext: &str| {
        let mut bytes = scratch.root.as_os_str().as_bytes().to_vec();
        bytes.push(b'/');
        bytes.extend_from_slice(stem);
        bytes.extend_from_slice(ext.as_bytes());
        OsString::from_vec(bytes)
    };
    let plan = name(b"plan\xff", ".svg");
    std::fs::copy(scratch.root.join("plan.svg"), &plan).unwrap();
    let cases: Vec<Vec<OsString>> = vec![
        vec![
            "dilate".into(),
            plan.clone(),
            "--kerf-um".into(),
            "150".into(),
            "-o".into(),
            name(b"out\xfe", ".svg"),
        ],
        vec![
            "gcode".into(),
            plan.clone(),
            "--kerf-um".into(),
            "150".into(),
            "--feed-mm-per-min".into(),
            "600".into(),
            "--power-percent".into(),
            "50".into(),
            "-o".into(),
            name(b"out\xfe", ".gcode"),
        ],
        vec!["gauge".into(), "-o".into(), name(b"gauge\xfe", ".svg")],
        vec![
            "--sim".into(),
            "run".into(),
            "--plot".into(),
            name(b"curve\xfe", ".svg"),
        ],
    ];
    for case in cases {
        for json in [false, true] {
            let mut args: Vec<OsString> = if json {
                vec!["--json".into()]
            } else {
                Vec::new()
            };
            args.extend(case.iter().cloned());
            let out = kerfmeter(&scratch.root, &args);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(out.status.success(), "{args:?}: {stderr}");
            if json {
                let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
                assert!(
                    report.to_string().contains('\u{FFFD}'),
                    "{args:?}: {report}"
                );
                assert!(stderr.contains("not UTF-8"), "{args:?}: {stderr}");
            }
            // The file exists under its own bytes.
            let written = case.last().unwrap();
            assert!(
                Path::new(OsStr::from_bytes(written.as_bytes())).exists(),
                "{args:?}"
            );
            let _ = std::fs::remove_file(written);
        }
    }
}

#[test]
fn a_non_utf8_label_is_refused_with_a_message() {
    let scratch = Scratch::new();
    for json in [false, true] {
        let mut args: Vec<OsString> = if json {
            vec!["--json".into()]
        } else {
            Vec::new()
        };
        args.extend(["--sim".into(), "run".into(), "--label".into()]);
        args.push(OsString::from_vec(b"x\xff".to_vec()));
        let out = kerfmeter(&scratch.root, &args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        check(&args, &out, json);
    }
}

#[test]
fn each_refusal_tells_the_right_reason_in_plain_numbers() {
    let scratch = Scratch::new();
    let plan = scratch.file("plan.svg");
    let out = scratch.file("out.svg");
    let xxe = scratch.root.join("xxe.svg");
    std::fs::write(
        &xxe,
        r#"<?xml version="1.0"?>
<!DOCTYPE svg [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<svg xmlns="http://www.w3.org/2000/svg" width="10mm" height="10mm" viewBox="0 0 10 10"><text>&xxe;</text></svg>"#,
    )
    .unwrap();
    let empty = scratch.file("empty.gcode");
    std::fs::write(&empty, "; nothing but a comment\n\n").unwrap();
    let dilate = |kerf: &str, out: &str| {
        vec!["dilate", &plan, "--kerf-um", kerf, "-o", out]
            .into_iter()
            .map(str::to_owned)
            .collect::<Vec<_>>()
    };
    let xxe = xxe.to_str().unwrap().to_owned();
    // (arguments, exit code, what stderr says, what it must not say)
    let cases: Vec<(Vec<String>, i32, &str, &str)> = vec![
        (
            dilate("150", "/proc/x.svg"),
            4,
            "/proc: it does not take new files",
            ".kerfmeter-",
        ),
        (
            dilate("-inf", &out),
            2,
            "between 0 and 5000 µm, got -inf µm",
            "unexpected argument",
        ),
        (dilate("1e308", &out), 2, "got 1e308 µm", "00000000"),
        (dilate("-0", &out), 0, "by 0 µm", "-0 µm"),
        (
            vec![
                "--sim".into(),
                "run".into(),
                "--fingers".into(),
                "-1".into(),
            ],
            2,
            "1..=100",
            "4294967295",
        ),
        (
            vec![
                "--sim".into(),
                "run".into(),
                "--also-at-force-n".into(),
                "1e308".into(),
            ],
            2,
            "(allowed 1 to 500 N)",
            "",
        ),
        (
            vec![
                "gauge".into(),
                "-o".into(),
                out.clone(),
                "--thickness-mm".into(),
                "3".into(),
            ],
            2,
            "--test-piece",
            "",
        ),
        (
            vec![
                "--sim".into(),
                "serve".into(),
                "--listen".into(),
                "example.invalid:7903".into(),
            ],
            2,
            "other host names are not looked up",
            "invalid socket address syntax",
        ),
        (
            vec![
                "dilate".into(),
                xxe,
                "--kerf-um".into(),
                "150".into(),
                "-o".into(),
                out.clone(),
            ],
            4,
            "external entities",
            "",
        ),
        (
            vec!["cut".into(), empty, "--cutter".into(), "sim".into()],
            4,
            "has no G-code line to cut",
            "",
        ),
        (
            vec![
                "--sim".into(),
                "map".into(),
                "--bed-width-mm".into(),
                "1e308".into(),
                "-o".into(),
                scratch.file("m.json"),
            ],
            2,
            "at most 10000 mm",
            "",
        ),
    ];
    for (args, code, says, not) in cases {
        let args: Vec<OsString> = args.into_iter().map(OsString::from).collect();
        let out = kerfmeter(&scratch.root, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let all = format!("{stdout}{stderr}");
        assert_eq!(out.status.code(), Some(code), "{args:?}: {all}");
        assert!(all.contains(says), "{args:?}: {all}");
        assert!(not.is_empty() || !all.contains(not), "{args:?}: {all}");
    }
}
