//! Writes the byte streams Kerfmeter's Ruida encoder produces, for MeerK40t's Ruida parser to
//! decode (`host-lib/python/tests/test_ruida_peer.py`, run by `cargo xtask test-python`).
//!
//! - `encode OUT.json`: every program below with its plan (layers of paths in mm, speeds,
//!   powers) and its packets (hex, on the wire: checksum and swizzled payload), and the direct
//!   commands (head moves, Z/U moves, stop, register reads) each in its own packet.
//! - `encode parse-answer REGISTER HEX`: the value of a controller's (swizzled) answer packet
//!   to a register read (mm for a position or a size), as this crate reads it: how the test checks this crate's reading of
//!   MeerK40t's emulator's answers.

use std::f64::consts::TAU;

use kerfmeter_ruida::register::{Register, value_to_mm};
use kerfmeter_ruida::{Command, CutLayer, MAGIC, Packet, Program};
use serde_json::{Value, json};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.as_slice() {
        [out] => std::fs::write(out, streams().to_string()).expect("cannot write the streams"),
        [mode, register, hex] if mode == "parse-answer" => {
            println!("{}", parse_answer(register, hex))
        }
        _ => panic!("usage: encode OUT.json | encode parse-answer REGISTER HEX"),
    }
}

/// A closed polygon of `n` sides around `center`.
fn circle(center: [f64; 2], radius: f64, n: usize) -> Vec<[f64; 2]> {
    (0..=n)
        .map(|i| {
            let a = TAU * i as f64 / n as f64;
            [center[0] + radius * a.cos(), center[1] + radius * a.sin()]
        })
        .collect()
}

/// A gauge's shape placed at `center`: one turn of r = a + c·φ closed by its radial step, and
/// two holes at ±`hole_distance` on the X axis.
fn gauge(center: [f64; 2]) -> Vec<Vec<[f64; 2]>> {
    let (a, c, hole_distance) = (12.0, 0.35, 6.0);
    let mut spiral: Vec<[f64; 2]> = (0..=720)
        .map(|i| {
            let phi = TAU * i as f64 / 720.0;
            let r = a + c * phi;
            [center[0] + r * phi.cos(), center[1] + r * phi.sin()]
        })
        .collect();
    spiral.push(spiral[0]);
    let hole = |dx: f64| circle([center[0] + dx, center[1]], 1.5, 48);
    vec![spiral, hole(hole_distance), hole(-hole_distance)]
}

/// A program's name, where its gauge is centred (if it is one), and its layers.
type NamedProgram = (&'static str, Option<[f64; 2]>, Vec<CutLayer>);

fn layer(speed: f64, min: f64, max: f64, paths_mm: Vec<Vec<[f64; 2]>>) -> CutLayer {
    CutLayer {
        speed_mm_per_s: speed,
        min_power_percent: min,
        max_power_percent: max,
        paths_mm,
    }
}

/// The programs: a square; a gauge placed where asked, on two layers; many short paths far
/// apart (travels beyond relative moves' ±8.191 mm, several packets); negative coordinates.
fn programs() -> Vec<NamedProgram> {
    let square = vec![
        [10.0, 10.0],
        [60.0, 10.0],
        [60.0, 60.0],
        [10.0, 60.0],
        [10.0, 10.0],
    ];
    let at = [212.5, 143.25];
    let mut gauge_paths = gauge(at);
    let holes = gauge_paths.split_off(1);
    let scattered: Vec<Vec<[f64; 2]>> = (0..60)
        .map(|i| {
            let (x, y) = (5.0 + 9.7 * (i % 10) as f64, 7.3 + 41.1 * (i / 10) as f64);
            vec![[x, y], [x + 0.001, y + 3.333], [x + 2.5, y + 0.0005]]
        })
        .collect();
    vec![
        ("square", None, vec![layer(25.0, 10.0, 10.0, vec![square])]),
        (
            "gauge",
            Some(at),
            vec![
                layer(8.0, 30.0, 55.5, holes),
                layer(12.5, 12.0, 40.0, gauge_paths),
            ],
        ),
        ("scattered", None, vec![layer(100.0, 0.0, 100.0, scattered)]),
        (
            "negative",
            None,
            vec![layer(
                3.0,
                5.0,
                7.5,
                vec![vec![[-20.0, -5.5], [-0.001, 0.0], [-8.25, 12.0]]],
            )],
        ),
    ]
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn program_json(name: &str, center: Option<[f64; 2]>, layers: &[CutLayer]) -> Value {
    let program = Program::new(layers).expect("a valid program");
    let packets: Vec<String> = program
        .packets(MAGIC)
        .expect("packets")
        .iter()
        .map(|p| hex(p.as_bytes()))
        .collect();
    let layers: Vec<Value> = layers
        .iter()
        .map(|l| {
            json!({
                "speed_mm_per_s": l.speed_mm_per_s,
                "min_power_percent": l.min_power_percent,
                "max_power_percent": l.max_power_percent,
                "paths_mm": l.paths_mm,
            })
        })
        .collect();
    json!({ "name": name, "center_mm": center, "layers": layers, "packets": packets })
}

/// Direct commands, each in its own packet, with what it asks for.
fn direct() -> Vec<Value> {
    let one = |c: Command| {
        hex(Packet::new(&c.to_bytes(), MAGIC)
            .expect("packet")
            .as_bytes())
    };
    let mut out = vec![
        json!({ "kind": "move_xy", "x_um": 123_456, "y_um": 7_890,
                "packet": one(Command::RapidMoveXy { x_um: 123_456, y_um: 7_890 }) }),
        json!({ "kind": "move_z", "z_um": -2_500, "packet": one(Command::RapidMoveZ { z_um: -2_500 }) }),
        json!({ "kind": "move_u", "u_um": 15_000, "packet": one(Command::RapidMoveU { u_um: 15_000 }) }),
        json!({ "kind": "stop", "packet": one(Command::StopProcess) }),
        json!({ "kind": "keep_alive", "packet": one(Command::KeepAlive) }),
    ];
    for (name, register) in [
        ("position_x", Register::PositionX),
        ("position_y", Register::PositionY),
        ("bed_size_x", Register::BedSizeX),
        ("bed_size_y", Register::BedSizeY),
        ("machine_status", Register::MachineStatus),
    ] {
        out.push(json!({ "kind": "read", "register": name, "packet": one(register.read()) }));
    }
    out
}

fn streams() -> Value {
    let programs: Vec<Value> = programs()
        .iter()
        .map(|(name, center, layers)| program_json(name, *center, layers))
        .collect();
    json!({ "magic": MAGIC, "programs": programs, "direct": direct() })
}

/// The value of the answer `hex` (a swizzled packet) to reading `register`.
fn parse_answer(register: &str, hex: &str) -> String {
    let register = match register {
        "position_x" => Register::PositionX,
        "position_y" => Register::PositionY,
        "bed_size_x" => Register::BedSizeX,
        "bed_size_y" => Register::BedSizeY,
        "machine_status" => Register::MachineStatus,
        other => panic!("unknown register {other}"),
    };
    let bytes: Vec<u8> = (0..hex.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).expect("hex"))
        .collect();
    match register.parse_reply(&bytes, MAGIC) {
        Ok(value) => match register {
            Register::MachineStatus => value.to_string(),
            _ => format!("{}", value_to_mm(value).expect("a 32-bit length")),
        },
        Err(e) => format!("error: {e}"),
    }
}
