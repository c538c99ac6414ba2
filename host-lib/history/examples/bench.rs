//! The history's figures on both back ends (`cargo xtask bench-history`, which starts a
//! PostgreSQL server and gives its URL in `KERFMETER_TEST_PG_URL`): write throughput through
//! [`History::record`] (one transaction per record, as a measurement records), from one writer
//! and from 8 at once, and the time to list the newest 100 of `--records` records (default
//! 100,000), as `kerfmeter history` lists them (with drift) and bare.
//!
//! The records the listing is timed on are put in by one SQL statement (`INSERT … SELECT`), not
//! one by one: only their number matters for the listing, and 100,000 transactions would time
//! the disk's flushes for minutes. A benchmark: not timed in the tests.

use std::time::{Duration, Instant};

use kerfmeter_history::{History, NewRecord, Query};

/// Records each writer writes in the throughput runs.
const WRITES: u32 = 1_000;
/// Writers at once in the concurrent run.
const WRITERS: u32 = 8;
/// Timed listings (the median is reported).
const LISTINGS: usize = 30;

fn measurement(label: String, kerf_um: f64) -> NewRecord {
    NewRecord {
        device_id: "esp32c3:bench".into(),
        firmware: "1.2.3".into(),
        label: Some(label),
        thickness_mm: 3.0,
        force_n: 55.0,
        kerf_um,
        ci95_um: Some(4.5),
        flags: vec![],
        simulated: false,
    }
}

/// What opens one more connection to the history being measured.
type Open<'a> = &'a (dyn Fn() -> Result<History, kerfmeter_history::Error> + Sync);

/// Records per second committed by `writers` writers at once, each recording [`WRITES`], and
/// how many records were refused (an SQLite writer that waits past its busy timeout is told
/// "database is locked"; its measurement is not recorded).
fn throughput(open: Open<'_>, writers: u32) -> (f64, u32) {
    let start = Instant::now();
    let refused: u32 = std::thread::scope(|s| {
        let handles: Vec<_> = (0..writers)
            .map(|w| {
                s.spawn(move || {
                    let Ok(mut h) = open() else {
                        return WRITES;
                    };
                    (0..WRITES)
                        .filter(|i| {
                            let kerf = 150.0 + f64::from(i % 7);
                            h.record(&measurement(format!("writer {w}"), kerf)).is_err()
                        })
                        .count() as u32
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a writer"))
            .sum()
    });
    let committed = writers * WRITES - refused;
    (
        f64::from(committed) / start.elapsed().as_secs_f64(),
        refused,
    )
}

/// The median of [`LISTINGS`] runs of `f`.
fn median(mut f: impl FnMut()) -> Duration {
    let mut times: Vec<Duration> = (0..LISTINGS)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed()
        })
        .collect();
    times.sort();
    times[LISTINGS / 2]
}

/// Time the listings of the newest 100 on `h`, which holds `records` records.
fn listings(h: &History, records: u64) -> (Duration, Duration) {
    let query = Query {
        label: None,
        limit: Some(100),
        simulated: false,
    };
    assert_eq!(h.list(&query).expect("listed").len(), 100);
    let bare = median(|| {
        h.list(&query).expect("listed");
    });
    let with_drift = median(|| {
        h.listing(&query).expect("listed");
    });
    eprintln!("  listed the newest 100 of {records}");
    (bare, with_drift)
}

/// The bulk insert's columns: `n` records (`i` from 1 to `n`), cycling through 20 labels and 11
/// kerfs.
const BULK_SELECT: &str = "'2026-12-08T00:00:00Z', 'esp32c3:bench', '1.2.3',
    'label ' || (i % 20), 3.0, 55.0, 150.0 + (i % 11), 4.5, '[]'";

struct Figures {
    one_writer: (f64, u32),
    eight_writers: (f64, u32),
    bare: Duration,
    with_drift: Duration,
}

fn sqlite(records: u64) -> Figures {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let db = dir.path().join("bench.sqlite3");
    let open = || History::open(&db);
    let one_writer = throughput(&open, 1);
    let eight_writers = throughput(&open, WRITERS);
    let h = open().expect("opened");
    let have = h.list(&Query::default()).expect("listed").len() as u64;
    let conn = rusqlite::Connection::open(&db).expect("opened");
    conn.execute(
        &format!(
            "WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n WHERE i < ?1)
             INSERT INTO measurements (time, device_id, firmware, label, thickness_mm, force_n,
                 kerf_um, ci95_um, flags, simulated)
             SELECT {BULK_SELECT}, 0 FROM n"
        ),
        [records.saturating_sub(have) as i64],
    )
    .expect("filled");
    let (bare, with_drift) = listings(&h, records);
    Figures {
        one_writer,
        eight_writers,
        bare,
        with_drift,
    }
}

fn postgres(url: &str, records: u64) -> Figures {
    let mut admin = postgres::Client::connect(url, postgres::NoTls).expect("connected");
    admin
        .batch_execute("DROP TABLE IF EXISTS measurements, kerfmeter_schema")
        .expect("a fresh history");
    let open = || History::connect(url);
    let one_writer = throughput(&open, 1);
    let eight_writers = throughput(&open, WRITERS);
    let h = open().expect("opened");
    let have = h.list(&Query::default()).expect("listed").len() as u64;
    admin
        .execute(
            &format!(
                "INSERT INTO measurements (time, device_id, firmware, label, thickness_mm,
                     force_n, kerf_um, ci95_um, flags, simulated)
                 SELECT {BULK_SELECT}, false FROM generate_series(1, $1::BIGINT) AS i"
            ),
            &[&(records.saturating_sub(have) as i64)],
        )
        .expect("filled");
    admin
        .batch_execute("ANALYZE measurements")
        .expect("analysed");
    let (bare, with_drift) = listings(&h, records);
    Figures {
        one_writer,
        eight_writers,
        bare,
        with_drift,
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mut records: u64 = 100_000;
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--records" => {
                records = args
                    .next()
                    .and_then(|n| n.parse().ok())
                    .expect("--records N")
            }
            other => panic!("unknown argument {other}; the one is --records N"),
        }
    }
    let url = std::env::var("KERFMETER_TEST_PG_URL")
        .expect("KERFMETER_TEST_PG_URL: run it with `cargo xtask bench-history`");
    eprintln!("SQLite ...");
    let lite = sqlite(records);
    eprintln!("PostgreSQL ...");
    let pg = postgres(&url, records);
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    println!(
        "back end      1 writer rec/s  {WRITERS} writers rec/s (refused)  newest 100 of {records}: list ms  listing+drift ms"
    );
    for (name, f) in [("SQLite", &lite), ("PostgreSQL", &pg)] {
        let eight = format!("{:.0} ({})", f.eight_writers.0, f.eight_writers.1);
        println!(
            "{name:<12}  {:>14.0}  {eight:>25}  {:>25.2}  {:>16.2}",
            f.one_writer.0,
            ms(f.bare),
            ms(f.with_drift)
        );
    }
}
