//! Text and `--json` agree: each test builds one report from the simulated device and checks
//! that the numbers its text prints are its JSON's numbers, rounded as printed.

use clap::Parser;
use serde_json::Value;

use crate::commands::{kerf, run, self_test};
use crate::output::{Report, to_json};
use crate::{Cli, Command};

/// The command line `args` (after `kerfmeter --sim --json --db D`), parsed, and the folder of D:
/// a history of the test's own, never the user's, removed when the folder is dropped.
fn cli(args: &[&str]) -> (Cli, tempfile::TempDir) {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let db = dir.path().join("history.sqlite3");
    let db = db.to_str().expect("temporary paths are UTF-8");
    let all = ["kerfmeter", "--sim", "--json", "--db", db]
        .into_iter()
        .chain(args.iter().copied());
    let cli = Cli::try_parse_from(all).expect("valid arguments");
    (cli, dir)
}

/// `report`'s text and its JSON.
fn both<R: Report>(report: &R) -> (String, Value) {
    let json = serde_json::from_str(&to_json(report, R::JSON)).expect("JSON");
    (report.to_string(), json)
}

/// `x` as printed with one decimal.
fn one_decimal(x: &Value) -> String {
    format!("{:.1}", x.as_f64().expect("a number"))
}

#[test]
fn run_prints_the_kerfs_its_json_holds() {
    let (cli, _history) = cli(&["run", "--samples", "3", "--also-at-force-n", "20,500"]);
    let Command::Run(args) = &cli.command else {
        unreachable!("parsed as run")
    };
    let (text, json) = both(&run::run(&cli.global, args).expect("the twin measures"));
    let lines: Vec<&str> = text.lines().collect();
    let runs = json["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3);
    for (line, r) in lines[1..=3].iter().zip(runs) {
        let columns: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(columns[0], r["run_id"].to_string(), "{text}");
        assert_eq!(columns[1], one_decimal(&r["kerf_um"]), "{text}");
    }
    let summary = format!(
        "kerf {} µm ± {} µm (95 % CI, n = 3, SD {} µm) at {} N",
        one_decimal(&json["kerf_um"]),
        one_decimal(&json["summary"]["ci95_um"]),
        one_decimal(&json["summary"]["sd_um"]),
        one_decimal(&json["force_n"])
    );
    assert_eq!(lines[5], summary, "{text}");
    let at_20 = &json["kerf_at_force_um"][0];
    assert_eq!(
        lines[6],
        format!(
            "  at 20.0 N (from the last run's curve): {} µm",
            one_decimal(&at_20["kerf_um"])
        )
    );
    assert!(json["kerf_at_force_um"][1]["kerf_um"].is_null(), "{json}");
    assert_eq!(
        lines[7],
        "  at 500.0 N: beyond the force the last run reached"
    );
    assert_eq!(json["simulated"], true);
}

#[test]
fn kerf_prints_the_kerf_its_json_holds() {
    let (cli, _history) = cli(&["kerf"]);
    let mut session = cli.global.connect().expect("the twin answers");
    let before = kerf::KerfReport::new(session.meter.get_kerf_value().unwrap());
    let (text, json) = both(&before);
    assert!(
        json["kerf_um"].is_null() && json["result"].is_null(),
        "{json}"
    );
    assert!(text.starts_with("no result"), "{text}");

    let params = kerfmeter::JointSpec::default()
        .run_params(kerfmeter::protocol::GaugeGeometry::PAPER)
        .unwrap();
    session.meter.prepare_for_run().unwrap();
    session.meter.run_kerfmeter(&params, |_| ()).unwrap();
    let after = kerf::KerfReport::new(session.meter.get_kerf_value().unwrap());
    let (text, json) = both(&after);
    let row: Vec<&str> = text.lines().nth(1).unwrap().split_whitespace().collect();
    assert_eq!(row[1], one_decimal(&json["kerf_um"]), "{text}");
    assert_eq!(json["kerf_um"], json["result"]["kerf_um"]);
}

#[test]
fn self_test_prints_the_items_its_json_holds() {
    for fault in [None, Some("motor-disconnected")] {
        let mut args = vec!["self-test"];
        if let Some(f) = fault {
            args.extend(["--sim-fault", f]);
        }
        let (cli, _history) = cli(&args);
        let report = self_test::run(&cli.global).expect("the twin tests itself");
        let (text, json) = both(&report);
        let lines: Vec<&str> = text.lines().collect();
        let items = [
            "encoder_ok_fraction",
            "magnet_magnitude",
            "direction_deg",
            "torque_per_duty_nm",
        ];
        for (line, item) in lines.iter().zip(items) {
            let item = &json["report"][item];
            let value = format!("{:.3}", item["value"].as_f64().unwrap());
            let outcome = item["outcome"].as_str().unwrap();
            assert!(line[18..].trim_start().starts_with(outcome), "{line}");
            assert!(line.contains(&value), "{line} vs {value}");
        }
        let passed = json["passed"].as_bool().unwrap();
        assert_eq!(passed, fault.is_none(), "{text}");
        let verdict = if passed { "passed" } else { "FAILED" };
        assert_eq!(lines[4], format!("self-test {verdict}"));
        assert_eq!(report.verdict().is_ok(), passed);
        // A disconnected motor fails the items that need it, each explained in words, in the
        // text and in the JSON alike.
        let explained: Vec<&str> = lines[5..].iter().map(|l| l.trim_start()).collect();
        let failures = json["failures"].as_array().unwrap();
        assert_eq!(explained.len(), failures.len(), "{text}");
        if fault.is_some() {
            assert!(
                explained[0].starts_with("direction: the hub did not turn"),
                "{text}"
            );
            assert!(
                explained[1].starts_with("torque constant: no motor current flowed"),
                "{text}"
            );
            assert!(explained[1].contains("disconnected"), "{text}");
            assert_eq!(failures[1]["item"], "torque constant", "{json}");
        }
    }
}
