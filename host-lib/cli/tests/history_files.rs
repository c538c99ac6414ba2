//! `kerfmeter history` tells the truth about its file: a history the user named that does not
//! exist, or whose folder does not, or that is a folder, is refused as such (exit 4), never
//! listed as an empty history; an empty file is an empty history and stays empty (listing
//! writes nothing); and before anything is recorded, the default history is "no measurements
//! recorded yet", not an error. A folder given to `run` is refused before it measures.

use std::path::Path;
use std::process::{Command, Output};

/// Run `kerfmeter` with `args` in a home of its own (`home`: the user's data directory is in
/// it), with no history named by the environment.
fn kerfmeter(home: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(args)
        .env("HOME", home)
        .env("XDG_DATA_HOME", home.join("data"))
        .env("XDG_CONFIG_HOME", home.join("config"))
        .env_remove("KERFMETER_DB")
        .env_remove("KERFMETER_PORT")
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
    p.to_str().expect("temporary paths are UTF-8")
}

/// Every file and folder under `dir`, for "nothing was created".
fn tree(dir: &Path) -> Vec<String> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        found.push(p.display().to_string());
        if p.is_dir() {
            found.extend(tree(&p));
        }
    }
    found.sort();
    found
}

#[test]
fn a_named_history_that_does_not_exist_is_refused_not_listed_empty() {
    let home = tempfile::tempdir().unwrap();
    let db = home.path().join("histroy.sqlite3");
    for json in [false, true] {
        let args = [
            &["--db", path(&db)][..],
            if json { &["--json"] } else { &[] },
            &["history"],
        ];
        let out = kerfmeter(home.path(), &args.concat());
        assert_eq!(code(&out), 4, "{}", stdout(&out));
        let said = if json { stdout(&out) } else { stderr(&out) };
        assert!(
            said.contains(&format!(
                "no history at {}: the file does not exist",
                db.display()
            )),
            "{said}"
        );
        assert!(!said.contains("no real measurements"), "{said}");
    }
    // The same from the environment: the user named it too.
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .arg("history")
        .env("KERFMETER_DB", &db)
        .env("HOME", home.path())
        .output()
        .unwrap();
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    assert!(tree(home.path()).is_empty(), "{:?}", tree(home.path()));
}

#[test]
fn a_named_history_in_a_folder_that_does_not_exist_says_the_folder_does_not() {
    let home = tempfile::tempdir().unwrap();
    let folder = home.path().join("no-such-folder");
    let db = folder.join("history.sqlite3");
    let out = kerfmeter(home.path(), &["--db", path(&db), "history"]);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    let message = stderr(&out);
    assert!(
        message.contains(&format!("no history at {}", db.display())),
        "{message}"
    );
    assert!(
        message.contains(&format!("the folder {} does not exist", folder.display())),
        "{message}"
    );
    assert!(tree(home.path()).is_empty(), "{:?}", tree(home.path()));
}

#[test]
fn a_folder_given_as_the_history_is_said_to_be_a_folder() {
    let home = tempfile::tempdir().unwrap();
    let out = kerfmeter(home.path(), &["--db", path(home.path()), "history"]);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    let message = stderr(&out);
    assert!(
        message.contains("is a folder, not a history file"),
        "{message}"
    );
    assert!(!message.contains("disk I/O error"), "{message}");
    // `run` refuses it before it measures, as it refuses a folder that does not exist.
    let out = kerfmeter(home.path(), &["--sim", "--db", path(home.path()), "run"]);
    assert_eq!(code(&out), 4, "{}", stdout(&out));
    assert!(stderr(&out).contains("is a folder"), "{}", stderr(&out));
    assert!(!stdout(&out).contains("kerf"), "measured: {}", stdout(&out));
    assert!(tree(home.path()).is_empty(), "{:?}", tree(home.path()));
}

#[test]
fn an_empty_file_is_an_empty_history_and_listing_leaves_it_empty() {
    let home = tempfile::tempdir().unwrap();
    let db = home.path().join("history.sqlite3");
    std::fs::write(&db, b"").unwrap();
    let out = kerfmeter(home.path(), &["--db", path(&db), "history"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    assert!(
        stdout(&out).contains(&format!("no real measurements in {}", db.display())),
        "{}",
        stdout(&out)
    );
    let out = kerfmeter(
        home.path(),
        &["--json", "--sim", "--db", path(&db), "history"],
    );
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(json["records"], serde_json::json!([]), "{json}");
    assert_eq!(
        std::fs::read(&db).unwrap(),
        b"",
        "listing wrote into the file"
    );
    assert_eq!(tree(home.path()), [path(&db).to_string()]);
}

#[test]
fn before_anything_is_recorded_the_default_history_is_empty_not_an_error() {
    let home = tempfile::tempdir().unwrap();
    let out = kerfmeter(home.path(), &["history"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let default = home.path().join("data/kerfmeter/history.sqlite3");
    assert!(
        stdout(&out).contains(&format!(
            "no measurements recorded yet (`kerfmeter run` and `job` record them in {})",
            default.display()
        )),
        "{}",
        stdout(&out)
    );
    let out = kerfmeter(home.path(), &["--json", "history"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let json: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(json["records"], serde_json::json!([]), "{json}");
    assert_eq!(json["db"], path(&default));
    assert!(tree(home.path()).is_empty(), "{:?}", tree(home.path()));
    // Once a measurement is recorded there, it is listed.
    let out = kerfmeter(home.path(), &["--sim", "run", "--label", "birch"]);
    assert_eq!(code(&out), 0, "{}", stderr(&out));
    let out = kerfmeter(home.path(), &["--sim", "history"]);
    assert!(
        stdout(&out).starts_with("1 simulated measurement in"),
        "{}",
        stdout(&out)
    );
}
