//! An output replaces only a file this tool wrote, unless `--force`: a typo in `--plot`,
//! `gauge -o`, `dilate -o` or `gcode -o` must not replace someone's cutting plan. Each of this
//! tool's outputs carries its marker (a plan's or gauge's record, a program's first comment, a
//! plot's comment or PNG text chunk), so that running a command again replaces its own output.

use std::path::Path;
use std::process::{Command, Output};

fn kerfmeter(home: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        .current_dir(home)
        .env("HOME", home)
        .env("XDG_DATA_HOME", home.join("data"))
        .env_remove("KERFMETER_DB")
        .env_remove("KERFMETER_PORT")
        .output()
        .unwrap()
}

/// `args` refuses to replace `theirs` (exit 4, untouched), replaces it with `--force`, and
/// then replaces its own output without it.
fn replaces_only_its_own(home: &Path, args: &[&str], theirs: &Path) {
    let original = "<svg xmlns=\"http://www.w3.org/2000/svg\"><!-- someone's plan --></svg>";
    std::fs::write(theirs, original).unwrap();
    let refused = kerfmeter(home, args);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(4), "{args:?}: {stderr}");
    assert!(stderr.contains("not written by kerfmeter"), "{stderr}");
    assert!(stderr.contains("--force"), "{stderr}");
    assert_eq!(std::fs::read_to_string(theirs).unwrap(), original);
    let forced: Vec<&str> = args.iter().copied().chain(["--force"]).collect();
    let out = kerfmeter(home, &forced);
    assert!(
        out.status.success(),
        "{forced:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_ne!(std::fs::read(theirs).unwrap(), original.as_bytes());
    let again = kerfmeter(home, args);
    assert!(
        again.status.success(),
        "{args:?} again: {}",
        String::from_utf8_lossy(&again.stderr)
    );
}

#[test]
fn plots_gauges_plans_and_programs_replace_only_their_own_files() {
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path();
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/box-parts.svg");
    let plan = plan.to_str().unwrap();
    for name in ["curve.svg", "curve.png"] {
        let out = home.join(name);
        let args = ["--sim", "run", "--plot", out.to_str().unwrap()];
        replaces_only_its_own(home, &args, &out);
    }
    for name in ["gauge.svg", "gauge.dxf"] {
        let out = home.join(name);
        replaces_only_its_own(home, &["gauge", "-o", out.to_str().unwrap()], &out);
    }
    let out = home.join("dilated.svg");
    let args = [
        "dilate",
        plan,
        "--kerf-um",
        "150",
        "-o",
        out.to_str().unwrap(),
    ];
    replaces_only_its_own(home, &args, &out);
    let out = home.join("plan.gcode");
    let args = [
        "gcode",
        plan,
        "--kerf-um",
        "150",
        "--feed-mm-per-min",
        "600",
        "--power-percent",
        "50",
        "-o",
        out.to_str().unwrap(),
    ];
    replaces_only_its_own(home, &args, &out);
}

#[test]
fn a_refused_plot_is_found_before_the_gauge_is_measured() {
    let dir = tempfile::tempdir().unwrap();
    let theirs = dir.path().join("plan.svg");
    std::fs::write(&theirs, "<svg/>").unwrap();
    let db = dir.path().join("history.sqlite3");
    let args = [
        "--sim",
        "--db",
        db.to_str().unwrap(),
        "run",
        "--plot",
        theirs.to_str().unwrap(),
    ];
    let out = kerfmeter(dir.path(), &args);
    assert_eq!(out.status.code(), Some(4));
    // Nothing was measured, so nothing was recorded.
    assert!(!db.exists());
}

#[test]
fn a_job_refuses_to_replace_someone_elses_files_before_anything_moves() {
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path();
    let plan = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/box-parts.svg");
    let theirs = home.join("theirs.svg");
    let original = "<svg xmlns=\"http://www.w3.org/2000/svg\"/>";
    std::fs::write(&theirs, original).unwrap();
    let args = [
        "--sim",
        "job",
        plan.to_str().unwrap(),
        "--cutter",
        "sim",
        "-o",
        theirs.to_str().unwrap(),
    ];
    let out = kerfmeter(home, &args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(4), "{stderr}");
    assert!(stderr.contains("not written by kerfmeter"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&theirs).unwrap(), original);
    assert!(!stderr.contains("gauge cut"), "{stderr}");
}
