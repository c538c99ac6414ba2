//! The same history on both back ends: one story of records, listings and drift told to an
//! SQLite file (always) and to a PostgreSQL server (with the `postgres` feature, which
//! `cargo xtask test-history-pg` and the step "history against PostgreSQL" of `cargo xtask test`
//! turn on, giving the server's URL in `KERFMETER_TEST_PG_URL`: without it these tests fail,
//! never skip). Then what only a server has: 8 writer processes at once, none of their 8,000
//! records lost or doubled; a newer or foreign database refused untouched.

use kerfmeter_history::{History, NewRecord, Query};

fn measurement(label: Option<&str>, kerf_um: f64, simulated: bool) -> NewRecord {
    NewRecord {
        device_id: "esp32c3:test".into(),
        firmware: "1.2.3".into(),
        label: label.map(str::to_owned),
        thickness_mm: 3.0,
        force_n: 36.6,
        kerf_um,
        ci95_um: Some(4.5),
        flags: vec![],
        simulated,
    }
}

fn all(label: Option<&str>, simulated: bool) -> Query {
    Query {
        label: label.map(str::to_owned),
        limit: None,
        simulated,
    }
}

/// Tell `h` (empty) the story; return its listing as JSON with the times taken out (they are
/// checked to be RFC 3339 UTC), for the back ends to be compared.
fn story(h: &mut History) -> serde_json::Value {
    for kerf in [150.0, 152.0, 148.0] {
        h.record(&measurement(Some("birch"), kerf, false)).unwrap();
    }
    h.record(&measurement(Some("birch"), 400.0, true)).unwrap();
    let mut harder = measurement(Some("birch"), 100.0, false);
    harder.force_n = 80.0;
    h.record(&harder).unwrap();
    let mut flagged = measurement(Some("birch"), 300.0, false);
    flagged.flags = vec!["torque-limited".into()];
    flagged.ci95_um = None;
    h.record(&flagged).unwrap();
    h.record(&measurement(Some("mdf"), 250.0, false)).unwrap();
    h.record(&measurement(None, 160.0, false)).unwrap();
    let steady = h.record(&measurement(Some("birch"), 160.0, false)).unwrap();
    assert_eq!(h.drift_at(steady).unwrap(), None);
    let drifted = h.record(&measurement(Some("birch"), 195.0, false)).unwrap();
    let d = h.drift_at(drifted).unwrap().expect("195 µm drifts");
    assert!((d.usual_mean_um - 152.5).abs() < 1e-9, "{d:?}");
    assert_eq!(h.drift("birch", false).unwrap(), Some(d));
    assert_eq!(h.drift("birch", true).unwrap(), None);
    // Refused records leave nothing behind.
    assert!(h.record(&measurement(Some(""), 150.0, false)).is_err());
    assert!(h.record(&measurement(Some("ok"), f64::NAN, false)).is_err());

    let limited = h
        .list(&Query {
            limit: Some(2),
            ..all(None, false)
        })
        .unwrap();
    assert_eq!(limited.len(), 2);
    assert_eq!(h.list(&all(Some("mdf"), false)).unwrap().len(), 1);
    let sim = h.list(&all(None, true)).unwrap();
    assert_eq!(sim.len(), 1);
    assert_eq!(h.get(sim[0].id).unwrap().as_ref(), Some(&sim[0]));
    assert_eq!(h.get(-1).unwrap(), None);

    let listing = h.listing(&all(None, false)).unwrap();
    let kerfs: Vec<f64> = listing
        .records
        .iter()
        .map(|r| r.measurement.kerf_um)
        .collect();
    assert_eq!(
        kerfs,
        [
            195.0, 160.0, 160.0, 250.0, 300.0, 100.0, 148.0, 152.0, 150.0
        ]
    );
    let mut json = serde_json::to_value(&listing).unwrap();
    for record in json["records"].as_array_mut().unwrap() {
        let time = record.as_object_mut().unwrap().remove("time").unwrap();
        let time = time.as_str().unwrap();
        assert!(time.ends_with('Z'), "{time}");
        time.parse::<jiff::Timestamp>().unwrap();
    }
    json
}

#[test]
fn the_story_on_sqlite() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = History::open(&dir.path().join("h.sqlite3")).unwrap();
    let json = story(&mut h);
    assert_eq!(json["records"][0]["id"], 10);
}

#[test]
fn a_url_names_a_server_and_a_path_a_file() {
    assert!(History::is_url("postgres://kerfmeter@db.lab/history"));
    assert!(History::is_url("postgresql://db.lab/history"));
    assert!(!History::is_url("history.sqlite3"));
    assert!(!History::is_url("/home/lab/postgres/history.sqlite3"));
}

#[cfg(feature = "postgres")]
mod postgres {
    use std::io::BufRead;
    use std::process::{Command, Stdio};

    use kerfmeter_history::{Error, History, SCHEMA_VERSION};

    use super::{all, measurement, story};

    /// The variable `cargo xtask test-history-pg` sets.
    const URL_VAR: &str = "KERFMETER_TEST_PG_URL";

    /// The test server's URL: these tests run only when asked for (the `postgres` feature),
    /// and then a missing server is a failure, not a skip.
    fn server_url() -> String {
        std::env::var(URL_VAR).unwrap_or_else(|_| {
            panic!(
                "{URL_VAR} is not set: the PostgreSQL tests need a server; run them with \
                 `cargo xtask test-history-pg`, which starts one"
            )
        })
    }

    /// A fresh database named `name` on the test server (dropped first if a run left it), and
    /// its URL.
    fn fresh_database(name: &str) -> String {
        let url = server_url();
        let mut admin = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        // One statement each: neither may run inside a transaction block.
        admin
            .batch_execute(&format!("DROP DATABASE IF EXISTS {name}"))
            .unwrap();
        admin
            .batch_execute(&format!("CREATE DATABASE {name}"))
            .unwrap();
        let (server, _) = url.rsplit_once('/').expect("a URL ending in /DATABASE");
        format!("{server}/{name}")
    }

    #[test]
    fn the_story_on_postgres_is_the_story_on_sqlite() {
        let url = fresh_database("story");
        let mut pg = History::connect(&url).unwrap();
        assert_eq!(pg.path().to_str(), Some(url.as_str()), "named by its URL");
        let dir = tempfile::tempdir().unwrap();
        let mut sqlite = History::open(&dir.path().join("h.sqlite3")).unwrap();
        assert_eq!(story(&mut pg), story(&mut sqlite));
        // Reconnecting finds everything, and migrates nothing again.
        drop(pg);
        let again = History::connect(&url).unwrap();
        assert_eq!(again.list(&all(None, false)).unwrap().len(), 9);
    }

    #[test]
    fn a_newer_or_foreign_database_is_refused_untouched() {
        let url = fresh_database("a_newer_one");
        History::connect(&url)
            .unwrap()
            .record(&measurement(Some("birch"), 150.0, false))
            .unwrap();
        let mut admin = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        let newer = SCHEMA_VERSION + 1;
        admin
            .execute("UPDATE kerfmeter_schema SET version = $1", &[&newer])
            .unwrap();
        let err = History::connect(&url).unwrap_err();
        assert!(
            matches!(err, Error::NewerSchema { found, known, .. } if found == newer && known == SCHEMA_VERSION),
            "{err}"
        );
        assert!(err.to_string().contains("Upgrade kerfmeter"), "{err}");
        assert!(!err.to_string().contains("password"), "{err}");
        let count: i64 = admin
            .query_one("SELECT count(*) FROM measurements", &[])
            .unwrap()
            .get(0);
        let version: i64 = admin
            .query_one("SELECT version FROM kerfmeter_schema", &[])
            .unwrap()
            .get(0);
        assert_eq!((count, version), (1, newer));

        let url = fresh_database("a_foreign_one");
        let mut admin = postgres::Client::connect(&url, postgres::NoTls).unwrap();
        admin
            .batch_execute("CREATE TABLE measurements (what TEXT)")
            .unwrap();
        let err = History::connect(&url).unwrap_err();
        assert!(matches!(err, Error::Foreign { .. }), "{err}");
        let schema: Option<String> = admin
            .query_one("SELECT to_regclass('kerfmeter_schema')::TEXT", &[])
            .unwrap()
            .get(0);
        assert_eq!(schema, None, "nothing created in a foreign database");
    }

    #[test]
    fn an_unreachable_server_is_an_error_that_names_it_without_its_password() {
        let err = History::connect("postgres://lab:secret@127.0.0.1:1/history").unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, Error::Postgres { .. }), "{text}");
        assert!(
            text.contains("postgres://lab@127.0.0.1:1/history"),
            "{text}"
        );
        assert!(!text.contains("secret"), "{text}");
    }

    /// Run the test server's `pg_ctl` (given by `cargo xtask test-history-pg`, one argument a
    /// line) with `action`.
    fn pg_ctl(action: &[&str]) {
        let ctl = std::env::var("KERFMETER_TEST_PG_CTL")
            .expect("KERFMETER_TEST_PG_CTL: run this with `cargo xtask test-history-pg`");
        let mut args = ctl.lines();
        let status = Command::new(args.next().unwrap())
            .args(args)
            .args(action)
            .stdout(Stdio::null())
            .status()
            .unwrap();
        assert!(status.success(), "pg_ctl {action:?}: {status}");
    }

    /// The server stopped between two measurements, then started again: what was committed is
    /// kept; a record tried while it is down is refused with an error naming the server (the
    /// caller keeps it; nothing is half-written); the same `History` records again once it is
    /// back, on a new connection; nothing is there twice.
    #[test]
    #[ignore = "stops the server the other tests use: cargo xtask test-history-pg runs it alone, after them"]
    fn the_server_stopped_and_started_again_keeps_every_record_once() {
        let url = fresh_database("restarted");
        let mut h = History::connect(&url).unwrap();
        for i in 0..50 {
            h.record(&measurement(Some("before"), f64::from(i), false))
                .unwrap();
        }
        pg_ctl(&["-m", "fast", "-w", "stop"]);
        let down = h.record(&measurement(Some("down"), 1.0, false));
        let restarted = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let err = down.expect_err("recorded with the server stopped");
            assert!(matches!(err, Error::Postgres { .. }), "{err}");
            assert!(err.to_string().contains("127.0.0.1"), "{err}");
        }));
        // Started again whatever happened, so that a failure here is not a stopped server.
        pg_ctl(&["-w", "-t", "60", "start"]);
        if let Err(panic) = restarted {
            std::panic::resume_unwind(panic);
        }
        for i in 0..50 {
            h.record(&measurement(Some("after"), f64::from(i), false))
                .unwrap();
        }
        let again = History::connect(&url).unwrap();
        for label in ["before", "after"] {
            let mut kerfs: Vec<u32> = again
                .list(&all(Some(label), false))
                .unwrap()
                .iter()
                .map(|r| r.measurement.kerf_um as u32)
                .collect();
            kerfs.sort_unstable();
            assert_eq!(kerfs, (0..50).collect::<Vec<_>>(), "{label}");
        }
        assert!(again.list(&all(Some("down"), false)).unwrap().is_empty());
        assert_eq!(again.list(&all(None, false)).unwrap().len(), 100);
    }

    /// The variable that makes [`pg_writer`] write (it is a child of
    /// [`eight_writer_processes_at_once_lose_and_double_nothing`]): `URL WRITER`.
    const WRITER_VAR: &str = "KERFMETER_HISTORY_TEST_PG_WRITER";
    /// Records each writer writes.
    const PER_WRITER: u32 = 1_000;
    /// Writer processes.
    const WRITERS: u32 = 8;

    /// Not a test of its own: one writer process, recording [`PER_WRITER`] records, each in
    /// its own transaction, labelled with its number and numbered by its kerf.
    #[test]
    #[ignore = "run as a child of eight_writer_processes_at_once_lose_and_double_nothing"]
    fn pg_writer() {
        let Ok(job) = std::env::var(WRITER_VAR) else {
            return;
        };
        let (url, writer) = job.split_once(' ').unwrap();
        let mut h = History::connect(url).unwrap();
        println!("connected");
        for i in 0..PER_WRITER {
            h.record(&measurement(
                Some(&format!("writer {writer}")),
                f64::from(i),
                false,
            ))
            .unwrap();
        }
        println!("wrote {PER_WRITER}");
    }

    #[test]
    fn eight_writer_processes_at_once_lose_and_double_nothing() {
        // A new database: the writers also race to create its schema.
        let url = fresh_database("writers");
        let children: Vec<_> = (0..WRITERS)
            .map(|w| {
                Command::new(std::env::current_exe().unwrap())
                    .args(["--ignored", "--exact", "postgres::pg_writer", "--nocapture"])
                    .env(WRITER_VAR, format!("{url} {w}"))
                    .stdout(Stdio::piped())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for mut child in children {
            let out = std::io::BufReader::new(child.stdout.take().unwrap());
            let lines: Vec<String> = out.lines().map_while(Result::ok).collect();
            assert!(
                child.wait().unwrap().success(),
                "a writer failed: {lines:?}"
            );
            assert!(
                lines.iter().any(|l| l == &format!("wrote {PER_WRITER}")),
                "{lines:?}"
            );
        }
        let h = History::connect(&url).unwrap();
        let records = h.list(&all(None, false)).unwrap();
        assert_eq!(records.len(), (WRITERS * PER_WRITER) as usize);
        let mut ids: Vec<i64> = records.iter().map(|r| r.id).collect();
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(ids.len(), records.len(), "an id twice");
        for w in 0..WRITERS {
            let mut kerfs: Vec<u32> = h
                .list(&all(Some(&format!("writer {w}")), false))
                .unwrap()
                .iter()
                .map(|r| r.measurement.kerf_um as u32)
                .collect();
            kerfs.sort_unstable();
            assert_eq!(kerfs, (0..PER_WRITER).collect::<Vec<_>>(), "writer {w}");
        }
    }
}
