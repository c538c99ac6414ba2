//! The current sense on the twin, many seeds: how often the self-test's torque-constant item
//! passes, and how often a measurement ends in an `OverCurrent` fault, at 9, 12 and 24 V.
//!
//! Usage: `sense_study [SEEDS]` (default 50). Every seed is a fresh twin at the plant's
//! defaults but the supply: its own current-sense sampling phase, gain error and noise. Prints,
//! per supply, the self-test's pass counts, the spread of its torque-constant estimate against
//! the configured value, and the measurements' outcomes (kerf 150 µm, 55 N): how many ended in
//! `OverCurrent`, how many of those were false trips (the plant's true current below 90 % of the
//! limit all run long), and the true peak currents.

use kerfmeter_protocol::{
    DeviceConfig, Fault, Request, Response, RunParams, RunState, TestOutcome,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

/// A trip with the true current below this fraction of the limit is a false trip: beyond the
/// G2's current-sense gain error (±10 %), the reading was wrong, not the current too high.
const FALSE_TRIP_FRACTION: f64 = 0.9;

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

/// One measurement's end (`Ok` or its fault), and the largest motor current the plant drew
/// meanwhile, A (checked every tick).
fn measure(seed: u64, supply_v: f64) -> (Result<(), Option<Fault>>, f64) {
    let mut t = twin(seed, supply_v);
    let mut peak_a: f64 = 0.0;
    if t.request(&Request::Run(RunParams::DEFAULT)) != Response::Ok {
        return (Err(None), peak_a);
    }
    for _ in 0..3000 {
        for _ in 0..10 {
            t.tick();
            peak_a = peak_a.max(t.plant().current_a().abs());
        }
        if let Response::Status(s) = t.request(&Request::GetStatus) {
            match s.state {
                RunState::Done => return (Ok(()), peak_a),
                RunState::Fault(f) => return (Err(Some(f)), peak_a),
                _ => {}
            }
        }
    }
    (Err(None), peak_a)
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .map_or(50, |s| s.parse().expect("SEEDS is a number"));
    for supply_v in [12.0, 24.0, 9.0] {
        let mut passed = [0; 2];
        let mut ratios = Vec::new();
        let (mut ok, mut over_current, mut false_trips, mut other) = (0, 0, 0, 0);
        let limit_a = f64::from(DeviceConfig::DEFAULT.max_current_a);
        let mut peaks_a = Vec::new();
        for seed in 1..=seeds {
            let (all, torque, ratio) = self_test(seed, supply_v);
            passed[0] += u32::from(all);
            passed[1] += u32::from(torque);
            ratios.push(ratio);
            let (end, peak_a) = measure(seed, supply_v);
            peaks_a.push(peak_a);
            match (end, peak_a) {
                (Ok(()), _) => ok += 1,
                (Err(Some(Fault::OverCurrent)), peak_a) => {
                    over_current += 1;
                    false_trips += u32::from(peak_a < FALSE_TRIP_FRACTION * limit_a);
                }
                (Err(_), _) => other += 1,
            }
        }
        ratios.sort_by(f32::total_cmp);
        let n = ratios.len();
        println!(
            "{supply_v:>4} V: self-test passed {}/{seeds} (torque item {}/{seeds}; estimate/config \
             min {:.3} median {:.3} max {:.3}); runs ok {ok}, OverCurrent {over_current} \
             ({false_trips} false: the true current below 90 % of the limit), other {other}; the \
             runs' \
             true peak current {:.2}–{:.2} A",
            passed[0],
            passed[1],
            ratios[0],
            ratios[n / 2],
            ratios[n - 1],
            peaks_a.iter().copied().fold(f64::INFINITY, f64::min),
            peaks_a.iter().copied().fold(0.0, f64::max),
        );
    }
}
