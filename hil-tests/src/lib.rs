//! The acceptance suite's target: the digital twin by default, a real board when the environment
//! variable `KERFMETER_PORT` names its serial port.
//!
//! Every case in `tests/` calls [`Bench::connect`] and runs unchanged against either; it prints
//! one line `HIL <case> <target> <ran|skipped: reason>` so that `cargo xtask hil` can say what ran
//! against what.
//!
//! # Describing a bench
//!
//! A board measures a physical *reference gauge* whose kerf is known from elsewhere (a
//! microscope, or a machined gauge with a known gap). Describe it by environment variables, or by
//! a JSON file named in `KERFMETER_BENCH_FILE` (environment variables win):
//!
//! | variable | JSON key | meaning | default |
//! |---|---|---|---|
//! | `KERFMETER_PORT` | — | the board's serial port; unset: the twin | — |
//! | `KERFMETER_BENCH_KERF_UM` | `kerf_um` | documented kerf of the reference gauge, µm | required on a board |
//! | `KERFMETER_BENCH_TOLERANCE_UM` | `tolerance_um` | accepted error on a board, µm | 10 |
//! | `KERFMETER_BENCH_THICKNESS_MM` | `thickness_mm` | the reference gauge's stock, mm | 4 |
//! | `KERFMETER_SOAK_RUNS` | `soak_runs` | runs of the soak case | 100 |
//!
//! On the twin the reference gauge is cut with a nominal kerf of [`TWIN_KERF_UM`] (each run's
//! gauge cut afresh, as a real cutter cuts it) and the tolerance is [`TWIN_TOLERANCE_UM`] against
//! the run's truth: what an ideal device reads on that gauge at the force the run asked for.

use std::time::Duration;

use kerfmeter::protocol::{GaugeGeometry, KerfResult, RunParams};
use kerfmeter::sim::{SimDevice, SimOptions};
use kerfmeter::{JointSpec, Kerfmeter, Options};
use serialport::SerialPort;

/// Environment variable naming a real board's serial port.
pub const PORT_ENV: &str = "KERFMETER_PORT";
/// Kerf of the twin's reference gauge, µm.
pub const TWIN_KERF_UM: f64 = 180.0;
/// Accepted error on the twin, µm. Not 1 µm as on an ideal gauge: the twin cuts its gauges as a
/// real cutter does, and the device cannot see what that does to its hole-play correction (the
/// taper narrows the holes at the bottom of the sheet, displaced holes and off-centre prongs
/// shorten the play) nor the encoder's non-linearity and magnet eccentricity. At the defaults
/// these add 0.3–0.7 µm low on average, with an SD of about 0.4 µm and rare runs near 1.4 µm
/// (`cargo xtask accuracy`); 2 µm keeps a soak of 100 runs meaningful without failing on them.
pub const TWIN_TOLERANCE_UM: f64 = 2.0;

/// What the cases run against.
pub enum Target {
    /// The digital twin, in-process behind a pseudo-terminal (kept alive here).
    Twin(Box<SimDevice>),
    /// A real board on this serial port.
    Board(String),
}

impl Target {
    /// `twin` or `board`.
    pub fn kind(&self) -> &'static str {
        match self {
            Target::Twin(_) => "twin",
            Target::Board(_) => "board",
        }
    }

    /// True for the twin.
    pub fn is_twin(&self) -> bool {
        matches!(self, Target::Twin(_))
    }
}

/// The bench description (see the module docs).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct BenchFile {
    /// Documented kerf of the reference gauge, µm.
    pub kerf_um: Option<f64>,
    /// Accepted error, µm.
    pub tolerance_um: Option<f64>,
    /// Stock of the reference gauge, mm.
    pub thickness_mm: Option<f64>,
    /// Runs of the soak case.
    pub soak_runs: Option<u32>,
}

/// A connected target and what it is expected to measure.
pub struct Bench {
    /// What is connected.
    pub target: Target,
    /// The client.
    pub meter: Kerfmeter,
    /// Kerf the reference gauge should read, µm (on the twin: its nominal kerf; see
    /// [`Bench::expected_kerf_um`]).
    pub kerf_um: f64,
    /// Accepted error, µm.
    pub tolerance_um: f64,
    /// Run parameters for the reference gauge.
    pub params: RunParams,
    /// Runs of the soak case.
    pub soak_runs: u32,
}

/// Client options for the suite: quick polls (also what lets the lock-stepped twin run ahead).
pub fn options() -> Options {
    Options {
        poll_interval: Duration::from_millis(2),
        ..Options::default()
    }
}

fn env_f64(name: &str) -> Result<Option<f64>, String> {
    match std::env::var(name) {
        Ok(v) if !v.trim().is_empty() => v
            .trim()
            .parse()
            .map(Some)
            .map_err(|_| format!("{name}={v:?} is not a number")),
        _ => Ok(None),
    }
}

fn bench_file() -> Result<BenchFile, String> {
    match std::env::var("KERFMETER_BENCH_FILE") {
        Ok(path) if !path.is_empty() => {
            let text = std::fs::read_to_string(&path)
                .map_err(|e| format!("KERFMETER_BENCH_FILE {path}: {e}"))?;
            serde_json::from_str(&text).map_err(|e| format!("KERFMETER_BENCH_FILE {path}: {e}"))
        }
        _ => Ok(BenchFile::default()),
    }
}

impl Bench {
    /// Connect to the board named by `KERFMETER_PORT` (described by the bench variables), or
    /// start a twin with `twin` options (its kerf is set to [`TWIN_KERF_UM`] unless given).
    pub fn connect_with(twin: SimOptions) -> Result<Self, String> {
        let (target, port) = Self::open(twin)?;
        let meter = Kerfmeter::from_port(port, options()).map_err(|e| e.to_string())?;
        Self::describe(target, meter)
    }

    /// [`Bench::connect_with`] a default twin with this seed.
    pub fn connect(seed: u64) -> Result<Self, String> {
        Self::connect_with(SimOptions {
            kerf_um: TWIN_KERF_UM,
            seed,
            ..SimOptions::default()
        })
    }

    /// Open the target's serial port without a client (for protocol-abuse cases, which need the
    /// raw port too: clone it with `try_clone` before handing it to [`Kerfmeter::from_port`]).
    pub fn open(twin: SimOptions) -> Result<(Target, Box<dyn SerialPort>), String> {
        match std::env::var(PORT_ENV) {
            Ok(path) if !path.is_empty() => {
                let port = serialport::new(&path, 115_200)
                    .timeout(Duration::from_millis(10))
                    .open()
                    .map_err(|e| format!("cannot open {path}: {e}"))?;
                Ok((Target::Board(path), port))
            }
            _ => {
                let (sim, port) = SimDevice::start(twin).map_err(|e| e.to_string())?;
                Ok((Target::Twin(Box::new(sim)), port))
            }
        }
    }

    /// Attach the bench description to a connected target.
    pub fn describe(target: Target, meter: Kerfmeter) -> Result<Self, String> {
        let file = bench_file()?;
        let thickness_mm = env_f64("KERFMETER_BENCH_THICKNESS_MM")?
            .or(file.thickness_mm)
            .unwrap_or(4.0);
        let soak_runs = match std::env::var("KERFMETER_SOAK_RUNS") {
            Ok(v) if !v.is_empty() => v
                .parse()
                .map_err(|_| format!("KERFMETER_SOAK_RUNS={v:?} is not a count"))?,
            _ => file.soak_runs.unwrap_or(100),
        };
        let (kerf_um, tolerance_um) = match &target {
            Target::Twin(_) => (TWIN_KERF_UM, TWIN_TOLERANCE_UM),
            Target::Board(_) => (
                env_f64("KERFMETER_BENCH_KERF_UM")?.or(file.kerf_um).ok_or(
                    "a board needs its reference gauge's kerf: set KERFMETER_BENCH_KERF_UM or kerf_um in KERFMETER_BENCH_FILE",
                )?,
                env_f64("KERFMETER_BENCH_TOLERANCE_UM")?.or(file.tolerance_um).unwrap_or(10.0),
            ),
        };
        let params = JointSpec {
            thickness_mm,
            ..JointSpec::default()
        }
        .run_params(GaugeGeometry::PAPER)
        .map_err(|e| e.to_string())?;
        Ok(Self {
            target,
            meter,
            kerf_um,
            tolerance_um,
            params,
            soak_runs,
        })
    }

    /// What the reference gauge should read for `result`: on the twin, that run's truth (what an
    /// ideal device reads on the gauge the twin cut for it, at the force the run asked for); on a
    /// board, the documented kerf.
    pub fn expected_kerf_um(&self, result: &KerfResult) -> f64 {
        match &self.target {
            Target::Twin(sim) => sim
                .truth_um(result.run_id)
                .expect("the twin records the truth of every run it starts"),
            Target::Board(_) => self.kerf_um,
        }
    }

    /// Print the case's summary line.
    pub fn report(&self, case: &str) {
        eprintln!("HIL {case} {} ran", self.target.kind());
    }

    /// Print that a case was skipped on this target, and why.
    pub fn skip(&self, case: &str, why: &str) {
        eprintln!("HIL {case} {} skipped: {why}", self.target.kind());
    }
}
