//! Studies over many twins, in-process: what `cargo xtask robustness` and `cargo xtask fit-study`
//! run (their command lines are the twin crate's `robustness` and `fit_study` examples).
//!
//! - [`robustness`]: every plant parameter drawn from its documented range, one measurement per
//!   draw, each ending classified (a reading right or flagged, an unflagged wrong reading, a typed
//!   fault, a refusal).
//! - [`fit`]: the paper's §7 fit study: box joints dilated by the device's reading of a gauge cut
//!   beside each, and the assembly force that gives.
//! - Here: one measurement driven as a host drives it ([`measure`]), the seeded streams both
//!   studies draw from ([`stream`]), simple statistics, and a deterministic parallel map.
//!
//! Everything is deterministic for a seed, whatever the number of threads.

pub mod fit;
pub mod robustness;

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_protocol::{
    DeviceConfig, ErrorCode, Fault, KerfResult, Request, Response, RunParams, RunState,
};

use crate::Twin;

/// How often the host polls the device's status, ms of simulated time.
pub const POLL_MS: u64 = 10;
/// Longest a reset may take before the measurement counts as never ending, ms (simulated).
pub const RESET_LIMIT_MS: u64 = 15_000;
/// Longest a run may take before it counts as never ending, ms (simulated): three times
/// `RunParams::max_time_ms`, after which the device itself must have faulted.
pub const RUN_LIMIT_MS: u64 = 30_000;

/// The part of a measurement an ending belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Setting the device's configuration.
    Configure,
    /// Bringing the hub to zero before the run.
    Reset,
    /// The run itself.
    Run,
}

impl Phase {
    /// Its name in reports.
    pub const fn name(self) -> &'static str {
        match self {
            Phase::Configure => "configure",
            Phase::Reset => "reset",
            Phase::Run => "run",
        }
    }
}

/// How one measurement ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// A result, and the truth the twin recorded for its run id.
    Reading {
        /// What the device reported.
        result: KerfResult,
        /// What an ideal device reads on that gauge at the force asked for, µm.
        truth_um: f64,
    },
    /// The device latched a typed fault.
    Fault {
        /// During the reset or the run.
        phase: Phase,
        /// Which fault.
        fault: Fault,
    },
    /// The device refused the request with a typed error.
    Refused {
        /// The reset or the run request.
        phase: Phase,
        /// Why.
        code: ErrorCode,
    },
    /// Neither a result nor a fault within the limit ([`RESET_LIMIT_MS`], [`RUN_LIMIT_MS`]).
    NoEnd {
        /// Where it was stuck.
        phase: Phase,
        /// The state it was stuck in.
        state: RunState,
    },
    /// An answer that does not belong to the request (a protocol bug).
    Unexpected {
        /// During the reset or the run.
        phase: Phase,
        /// The answer, as debug text.
        response: String,
    },
    /// The twin or the firmware panicked.
    Panic(String),
}

impl Outcome {
    /// Device-added error, reading − truth, µm (`None` without a reading).
    pub fn error_um(&self) -> Option<f64> {
        match self {
            Outcome::Reading { result, truth_um } => Some(f64::from(result.kerf_um) - truth_um),
            _ => None,
        }
    }

    /// The reading, if any.
    pub fn result(&self) -> Option<&KerfResult> {
        match self {
            Outcome::Reading { result, .. } => Some(result),
            _ => None,
        }
    }
}

/// One measurement as a host makes one: reset the hub to zero, start the run with `params`, poll
/// the status every [`POLL_MS`] until a result or a fault, read the result and look its truth up
/// in the twin's [`TruthLog`](crate::TruthLog) by run id.
pub fn measure(twin: &mut Twin, params: &RunParams) -> Outcome {
    if let Err(ending) = start(twin, Phase::Reset, &Request::Reset) {
        return ending;
    }
    if let Err(ending) = wait(twin, Phase::Reset, RESET_LIMIT_MS) {
        return ending;
    }
    if let Err(ending) = start(twin, Phase::Run, &Request::Run(*params)) {
        return ending;
    }
    if let Err(ending) = wait(twin, Phase::Run, RUN_LIMIT_MS) {
        return ending;
    }
    match twin.request(&Request::GetKerf) {
        Response::Kerf(Some(result)) => match twin.truths().truth_um(result.run_id) {
            Some(truth_um) => Outcome::Reading { result, truth_um },
            None => Outcome::Unexpected {
                phase: Phase::Run,
                response: format!("no truth recorded for run {}", result.run_id),
            },
        },
        other => Outcome::Unexpected {
            phase: Phase::Run,
            response: format!("{other:?}"),
        },
    }
}

/// Give the device `config` (`SetConfig`), as its owner does once for a build.
pub fn configure(twin: &mut Twin, config: &DeviceConfig) -> Result<(), Outcome> {
    let phase = Phase::Configure;
    match twin.request(&Request::SetConfig(*config)) {
        Response::Config(_) => Ok(()),
        Response::Error(code) => Err(Outcome::Refused { phase, code }),
        other => Err(Outcome::Unexpected {
            phase,
            response: format!("{other:?}"),
        }),
    }
}

/// Send `request`; a refusal or an odd answer ends the measurement.
fn start(twin: &mut Twin, phase: Phase, request: &Request) -> Result<(), Outcome> {
    match twin.request(request) {
        Response::Ok => Ok(()),
        Response::Error(code) => Err(Outcome::Refused { phase, code }),
        other => Err(Outcome::Unexpected {
            phase,
            response: format!("{other:?}"),
        }),
    }
}

/// Poll until the reset is back to `Idle` or the run is `Done`; a fault ends the measurement.
fn wait(twin: &mut Twin, phase: Phase, limit_ms: u64) -> Result<(), Outcome> {
    let goal = match phase {
        Phase::Configure | Phase::Reset => RunState::Idle,
        Phase::Run => RunState::Done,
    };
    let mut state = RunState::Idle;
    for _ in 0..limit_ms / POLL_MS {
        twin.advance_ticks(POLL_MS);
        match twin.request(&Request::GetStatus) {
            Response::Status(status) => state = status.state,
            other => {
                return Err(Outcome::Unexpected {
                    phase,
                    response: format!("{other:?}"),
                });
            }
        }
        match state {
            s if s == goal => return Ok(()),
            RunState::Fault(fault) => return Err(Outcome::Fault { phase, fault }),
            _ => {}
        }
    }
    Err(Outcome::NoEnd { phase, state })
}

/// A random stream of its own for (`seed`, `index`, `key`): a draw's values do not depend on how
/// many other values were drawn before them, so adding a parameter (a new key) reshuffles
/// nothing else.
pub fn stream(seed: u64, index: u32, key: &str) -> Rng {
    let mut mix = Rng::new(seed ^ 0x7374_7564_7900_0000);
    let seeded = mix.next_u64();
    let mut mix = Rng::new(seeded ^ u64::from(index));
    let indexed = mix.next_u64();
    Rng::new(indexed ^ fnv1a(key))
}

/// FNV-1a of `text`: a stable key for a name.
fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |hash, byte| {
        (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Mean and sample standard deviation (0 for fewer than two values; NaN mean for none).
pub fn mean_sd(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    if values.len() < 2 {
        return (mean, 0.0);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// The `q` quantile (0..=1) of `values`, by the nearest rank; NaN for none.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// `work(i)` for every i in 0..n on up to `threads` threads, results in index order whatever
/// the threads did; `progress(done)` after each.
pub fn parallel_map<T: Send>(
    n: u32,
    threads: usize,
    work: &(dyn Fn(u32) -> T + Sync),
    progress: &(dyn Fn(usize) + Sync),
) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<(u32, T)>> = Mutex::new(Vec::with_capacity(n as usize));
    std::thread::scope(|scope| {
        for _ in 0..threads.clamp(1, n.max(1) as usize) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n as usize {
                        break;
                    }
                    let result = work(i as u32);
                    results
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push((i as u32, result));
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1);
                }
            });
        }
    });
    let mut results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, r)| r).collect()
}

/// The cores to use: what the machine offers.
pub fn available_threads() -> usize {
    std::thread::available_parallelism().map_or(1, usize::from)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TwinOptions;

    #[test]
    fn a_default_twin_measures_and_its_truth_is_found() {
        let mut twin = Twin::new(TwinOptions::default());
        let outcome = measure(&mut twin, &RunParams::DEFAULT);
        let error = outcome.error_um().expect("a reading");
        assert!(error.abs() < 2.0, "{outcome:?}");
        assert!(twin.motor_safe());
    }

    #[test]
    fn an_injected_fault_ends_typed() {
        let mut twin = Twin::new(TwinOptions {
            fault: Some(crate::InjectedFault::MotorDisconnected),
            ..TwinOptions::default()
        });
        let outcome = measure(&mut twin, &RunParams::DEFAULT);
        assert_eq!(
            outcome,
            Outcome::Fault {
                phase: Phase::Run,
                fault: Fault::NoMotion
            }
        );
    }

    #[test]
    fn streams_differ_by_key_and_index_and_repeat_for_the_same() {
        let first = |seed, index, key| stream(seed, index, key).next_u64();
        assert_eq!(first(1, 2, "a"), first(1, 2, "a"));
        assert_ne!(first(1, 2, "a"), first(1, 2, "b"));
        assert_ne!(first(1, 2, "a"), first(1, 3, "a"));
        assert_ne!(first(1, 2, "a"), first(2, 2, "a"));
    }

    #[test]
    fn statistics_of_a_known_set() {
        let (mean, sd) = mean_sd(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(mean, 2.5);
        assert!((sd - 1.290_994).abs() < 1e-6);
        let values: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&values, 0.95), 95.0);
        assert_eq!(quantile(&values, 1.0), 100.0);
        assert_eq!(quantile(&[7.0], 0.0), 7.0);
        assert!(quantile(&[], 0.5).is_nan());
    }

    #[test]
    fn the_parallel_map_keeps_index_order_and_reports_progress() {
        let calls = AtomicUsize::new(0);
        let squares = parallel_map(50, 3, &|i| i * i, &|_| {
            calls.fetch_add(1, Ordering::Relaxed);
        });
        assert_eq!(squares, (0..50).map(|i| i * i).collect::<Vec<_>>());
        assert_eq!(calls.load(Ordering::Relaxed), 50);
        assert!(parallel_map(0, 2, &|i| i, &|_| {}).is_empty());
    }
}
