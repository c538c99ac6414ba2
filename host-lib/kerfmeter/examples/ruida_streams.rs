//! Every byte stream the Ruida driver sends in the scenarios `tests/ruida.rs` runs, as the
//! simulated controller received them, with what each stream was meant to do: for the Python
//! step (`host-lib/python/tests/test_ruida_driver_peer.py`), which hands each stream to
//! MeerK40t's own Ruida emulator and checks its moves, speeds and powers against the plan's, the
//! laser off on every travel, and the gauge where it was asked.
//!
//! `cargo run -p kerfmeter --features sim --example ruida_streams -- streams.json`

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use kerfmeter::job::Placement;
use kerfmeter::protocol::GaugeGeometry;
use kerfmeter::ruida::steps::{Step, read};
use kerfmeter::ruida::{RuidaCutter, Timing};
use kerfmeter_plan::gauge::{GaugeOptions, build};
use kerfmeter_plan::gcode::{GcodeOptions, Provenance, gauge_program};
use kerfmeter_plan::profile::CutSettings;
use kerfmeter_ruida::twin::{Faults, TwinConfig};
use serde_json::{Value, json};

/// Where the gauge's spiral centre is asked to go, mm.
const GAUGE_AT_MM: [f64; 2] = [212.5, 143.25];

fn gauge_gcode() -> String {
    let drawing = build(&GaugeGeometry::PAPER, &GaugeOptions::default()).unwrap();
    let settings = CutSettings {
        feed_mm_per_min: 300.0,
        power_percent: 100.0,
        passes: 1,
    };
    let options = GcodeOptions {
        origin_mm: GAUGE_AT_MM,
        ..GcodeOptions::default()
    };
    let (program, _) =
        gauge_program(&drawing, &settings, &options, &Provenance::default()).unwrap();
    program.to_text()
}

/// A job of two settings: squares at 600 mm/min and 80 %, a circle (two arcs) at 1200 mm/min
/// and 35 %.
fn job_gcode() -> String {
    let mut g = String::from("(S_MAX=1000)\nG17 G21 G90 G94\nM5\n");
    for i in 0..3 {
        let x0 = 400.0 + 25.0 * f64::from(i);
        g += &format!("G0 X{x0} Y10\nF600\nM4 S800\nG1 X{} Y10\n", x0 + 20.0);
        g += &format!("G1 X{} Y30\nG1 X{x0} Y30\nG1 X{x0} Y10\nM5\n", x0 + 20.0);
    }
    g + "G0 X510 Y60\nF1200\nM4 S350\nG3 X490 Y60 I-10 J0\nG3 X510 Y60 I10 J0\nM5\nM2\n"
}

fn placement() -> Placement {
    Placement {
        gauge_at_mm: GAUGE_AT_MM,
        prong_offset_mm: [35.0, -12.5],
        insert_z_mm: -3.0,
        travel_z_mm: 8.0,
        plunge_feed_mm_per_min: 300.0,
    }
}

/// What `program` is meant to do: its layers and direct moves, in order.
fn plan(program: &str, head_mm: [f64; 2]) -> Value {
    let steps = read(program, head_mm).unwrap().steps;
    let steps: Vec<Value> = steps
        .iter()
        .map(|s| match s {
            Step::MoveXy([x, y]) => json!({"kind": "move_xy", "x_mm": x, "y_mm": y}),
            Step::MoveZ(z) => json!({"kind": "move_z", "z_mm": z}),
            Step::Cut(layers) => json!({"kind": "cut", "layers": layers.iter().map(|l| json!({
                "speed_mm_per_s": l.speed_mm_per_s,
                "min_power_percent": l.min_power_percent,
                "max_power_percent": l.max_power_percent,
                "paths_mm": l.paths_mm,
            })).collect::<Vec<_>>()}),
        })
        .collect();
    json!(steps)
}

/// Stream `program` on a fresh twin made unkind by `faults`; the datagrams it received.
fn stream(program: &str, faults: Faults) -> (Vec<String>, bool) {
    let config = TwinConfig {
        busy_reads: 2,
        ..TwinConfig::default()
    };
    let mut cutter = RuidaCutter::sim(config, Timing::sim()).unwrap();
    let twin = cutter.twin().unwrap();
    let before = twin.log().received.len();
    twin.inject(faults);
    let cancel = AtomicBool::new(false);
    let ok = cutter.stream(program, &cancel, &mut |_| {}).is_ok();
    let received = cutter.twin().unwrap().log().received[before..]
        .iter()
        .map(|d| d.iter().map(|b| format!("{b:02x}")).collect())
        .collect();
    (received, ok)
}

fn scenario(name: &str, program: &str, faults: Faults) -> Value {
    let (datagrams, ok) = stream(program, faults);
    json!({"name": name, "ok": ok, "datagrams": datagrams, "plan": plan(program, [0.0, 0.0])})
}

fn main() {
    let out = std::env::args()
        .nth(1)
        .expect("usage: ruida_streams OUT.json");
    let p = placement();
    let late = Faults {
        late_from_program: Some(Duration::from_millis(700)),
        ..Faults::default()
    };
    let scenarios = vec![
        scenario("gauge", &gauge_gcode(), Faults::default()),
        scenario("job", &job_gcode(), Faults::default()),
        scenario("lower", &p.lower_program(), Faults::default()),
        scenario("lift", &p.lift_program(), Faults::default()),
        scenario(
            "lost_packet",
            &gauge_gcode(),
            Faults {
                drop_program_packets: 1,
                ..Faults::default()
            },
        ),
        scenario(
            "refused",
            &job_gcode(),
            Faults {
                refuse_program: Some(0),
                ..Faults::default()
            },
        ),
        scenario("late_ack", &job_gcode(), late),
    ];
    let all = json!({"magic": 0x88, "gauge_at_mm": GAUGE_AT_MM, "scenarios": scenarios});
    std::fs::write(&out, serde_json::to_string_pretty(&all).unwrap()).unwrap();
}
