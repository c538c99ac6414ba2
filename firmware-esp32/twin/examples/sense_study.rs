//! The current sense on the twin, many seeds: how often the self-test's torque-constant item
//! passes, and how often a measurement ends in an `OverCurrent` fault, at 9, 12 and 24 V.
//!
//! Usage: `sense_study [SEEDS]` (default 50). Every seed is a fresh twin at the plant's
//! defaults but the supply: its own current-sense sampling phase, gain error and noise. Prints,
//! per supply, the self-test's pass counts, the spread of its torque-constant estimate against
//! the configured value, and the measurements' outcomes (kerf 150 µm, 55 N).

use kerfmeter_protocol::{
    DeviceConfig, Fault, Request, Response, RunParams, RunState, TestOutcome,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

fn twin(seed: u64, supply_v: f64) -> Twin {
    let mut t = Twin::new(TwinOptions {
        seed,
        plant: PlantParams {
            supply_v,
            ..PlantParams::default()
        },
        ..TwinOptions::default()
    });
    t.advance_ticks(5);
    t
}

/// The self-test's report: (all passed, torque item passed, estimate / configured).
fn self_test(seed: u64, supply_v: f64) -> (bool, bool, f32) {
    let mut t = twin(seed, supply_v);
    assert_eq!(t.request(&Request::SelfTest), Response::Ok);
    for _ in 0..100 {
        t.advance_ticks(10);
        t.request(&Request::GetStatus);
    }
    let Response::SelfTest(Some(r)) = t.request(&Request::GetSelfTest) else {
        return (false, false, f32::NAN);
    };
    let items = [
        r.encoder_ok_fraction,
        r.magnet_magnitude,
        r.direction_deg,
        r.torque_per_duty_nm,
    ];
    let all = items.iter().all(|i| i.outcome == TestOutcome::Pass);
    let torque = r.torque_per_duty_nm.outcome == TestOutcome::Pass;
    let ratio = r.torque_per_duty_nm.value / DeviceConfig::DEFAULT.torque_per_duty_nm;
    (all, torque, ratio)
}

/// One measurement's end: `Ok` or its fault.
fn measure(seed: u64, supply_v: f64) -> Result<(), Option<Fault>> {
    let mut t = twin(seed, supply_v);
    if t.request(&Request::Run(RunParams::DEFAULT)) != Response::Ok {
        return Err(None);
    }
    for _ in 0..3000 {
        t.advance_ticks(10);
        if let Response::Status(s) = t.request(&Request::GetStatus) {
            match s.state {
                RunState::Done => return Ok(()),
                RunState::Fault(f) => return Err(Some(f)),
                _ => {}
            }
        }
    }
    Err(None)
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .map_or(50, |s| s.parse().expect("SEEDS is a number"));
    for supply_v in [12.0, 24.0, 9.0] {
        let mut passed = [0; 2];
        let mut ratios = Vec::new();
        let (mut ok, mut over_current, mut other) = (0, 0, 0);
        for seed in 1..=seeds {
            let (all, torque, ratio) = self_test(seed, supply_v);
            passed[0] += u32::from(all);
            passed[1] += u32::from(torque);
            ratios.push(ratio);
            match measure(seed, supply_v) {
                Ok(()) => ok += 1,
                Err(Some(Fault::OverCurrent)) => over_current += 1,
                Err(_) => other += 1,
            }
        }
        ratios.sort_by(f32::total_cmp);
        let n = ratios.len();
        println!(
            "{supply_v:>4} V: self-test passed {}/{seeds} (torque item {}/{seeds}; estimate/config \
             min {:.3} median {:.3} max {:.3}); runs ok {ok}, OverCurrent {over_current}, other {other}",
            passed[0],
            passed[1],
            ratios[0],
            ratios[n / 2],
            ratios[n - 1],
        );
    }
}
