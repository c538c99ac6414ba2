//! Round-trip latency of `get_kerf_value` through a serial port (`cargo xtask bench-rtt`): the
//! twin behind a pseudo-terminal by default, a board with `--port PATH`. Prints p50, p99 and max.
//! A benchmark, not a test: the figures depend on the machine and its load.

use std::time::{Duration, Instant};

use kerfmeter::Kerfmeter;
use kerfmeter::sim::{SimDevice, SimOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let calls: usize = value("--calls")
        .map(|v| v.parse())
        .transpose()?
        .unwrap_or(2000);
    let (_sim, mut meter, what) = match value("--port") {
        Some(port) => (None, Kerfmeter::open(&port)?, format!("board on {port}")),
        None => {
            let (sim, meter) = SimDevice::connect(SimOptions::default(), Default::default())?;
            let what = format!("twin on {}", sim.path());
            (Some(sim), meter, what)
        }
    };
    // Warm up.
    for _ in 0..50 {
        meter.get_kerf_value()?;
    }
    let mut times: Vec<Duration> = Vec::with_capacity(calls);
    for _ in 0..calls {
        let t0 = Instant::now();
        meter.get_kerf_value()?;
        times.push(t0.elapsed());
    }
    times.sort();
    let pct = |p: f64| times[((times.len() - 1) as f64 * p).round() as usize];
    let us = |d: Duration| d.as_secs_f64() * 1e6;
    println!("get_kerf_value round trips, {what}, {calls} calls:");
    println!(
        "  p50 {:.0} µs   p99 {:.0} µs   max {:.0} µs   mean {:.0} µs",
        us(pct(0.5)),
        us(pct(0.99)),
        us(*times.last().expect("calls > 0")),
        times.iter().map(|d| us(*d)).sum::<f64>() / times.len() as f64
    );
    Ok(())
}
