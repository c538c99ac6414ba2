//! `kerfmeter run`: measure the kerf (the hub is reset to zero first). With `--samples N`, N
//! gauges are measured and the mean with its 95 % confidence interval is reported; `--plot` draws
//! the last run's torque–angle curve and `--also-at-force-n` reads other forces off it. The
//! measurement is recorded in the history (under `--label`), and a drift warning printed when the
//! label's kerf left its usual spread ([`kerfmeter_app::history`]).

use std::fmt;
use std::path::PathBuf;

use clap::Args;
use kerfmeter::protocol::{KerfResult, RunParams};
use kerfmeter::stats::Summary;
use kerfmeter::{Error, Measurement};
use serde::Serialize;

use crate::connection::{Global, Session};
use crate::error::CliError;
use crate::output::{JsonLayout, Report, ResultsTable};
use crate::plot;
use crate::progress::{ask, progress_bar, show};
use kerfmeter_app::history::{Measured, Recorded, parse_label, record};
use kerfmeter_app::measure::{MAX_SAMPLES, MeasureRequest};

#[derive(Args)]
pub struct RunArgs {
    /// Sheet thickness, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_THICKNESS_MM)]
    thickness_mm: f64,
    /// Assembly force of the joint, N (default: 18.3 N per finger, the paper's fit-window centre).
    #[arg(long)]
    force_n: Option<f64>,
    /// Fingers in the joint (1 to 100).
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_FINGERS,
          value_parser = clap::value_parser!(u32).range(1..=i64::from(kerfmeter::params::MAX_FINGERS)))]
    fingers: u32,
    /// Length of each finger's pressed face, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_FINGER_LENGTH_MM)]
    finger_length_mm: f64,
    /// Gauges to measure (a fresh gauge for each).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_SAMPLES)))]
    samples: u32,
    /// Draw the last run's torque–angle curve into this .png or .svg file.
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Replace the plot's file even if it exists and kerfmeter did not write it (by default only
    /// kerfmeter's own plots and drawings are replaced: a typo must not replace a cutting plan).
    #[arg(long, requires = "plot")]
    force: bool,
    /// Do not ask before each gauge (hardware only; the simulator never asks).
    #[arg(long, short = 'y')]
    yes: bool,
    /// Also read the kerf at these other assembly forces (N) off the last run's curve.
    #[arg(long, value_name = "N", value_delimiter = ',')]
    also_at_force_n: Vec<f32>,
    /// What is measured, for the history (material, cutter), e.g. "birch 3 mm, CO2 40 W".
    #[arg(long, value_parser = parse_label)]
    label: Option<String>,
}

impl RunArgs {
    /// The measurement these flags ask for.
    pub fn request(&self) -> MeasureRequest {
        MeasureRequest {
            thickness_mm: self.thickness_mm,
            fingers: self.fingers,
            finger_length_mm: self.finger_length_mm,
            force_n: self.force_n,
            samples: self.samples,
            label: self.label.clone(),
        }
    }
}

/// The kerf at another force, read off the last run's curve.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct KerfAtForce {
    /// The force, N.
    pub force_n: f32,
    /// The kerf there, µm (`None` beyond the force the run reached).
    pub kerf_um: Option<f32>,
}

/// What the simulated device was told to cut (text only).
#[derive(Debug, Clone, Copy)]
pub struct SimNote {
    /// The twin's true kerf, µm.
    pub kerf_um: f64,
    /// Its gauge-to-gauge spread, µm.
    pub kerf_sd_um: f64,
    /// What an ideal device reads on the gauges at the force asked for (the mean truth), µm.
    pub ideal_reading_um: f64,
}

/// The measurement: every run, their summary and the readings at other forces.
#[derive(Serialize)]
pub struct RunReport {
    /// The joint force the runs were made at, N.
    pub force_n: f32,
    /// Kerf at the other forces asked for.
    pub kerf_at_force_um: Vec<KerfAtForce>,
    /// The mean kerf, µm.
    pub kerf_um: f64,
    /// The curve's file, if drawn.
    #[serde(serialize_with = "crate::output::lossy_path::option")]
    pub plot: Option<PathBuf>,
    /// Every run, in order, its flags also by name.
    #[serde(serialize_with = "crate::output::results_json")]
    pub runs: Vec<KerfResult>,
    /// What was measured (`--label`).
    pub label: Option<String>,
    /// Where the measurement was recorded, or why not, and its drift (`None` until recorded).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub history: Option<Recorded>,
    /// True on the simulated device.
    pub simulated: bool,
    /// Mean, spread, confidence interval and outliers.
    pub summary: Summary,
    /// Sheet thickness, mm.
    pub thickness_mm: f32,
    /// On the simulated device, the truth beside `kerf_um`: the mean of what an ideal device
    /// reads on each run's gauge at the force asked for, µm, from the twin's physics.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_truth_um: Option<f64>,
    /// On the simulated device, each run's truth, µm, in the order of `runs`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sim_truths_um: Vec<f64>,
    /// Why the curve could not be read or drawn after the measurement (which stands, and is
    /// recorded); the command then fails after printing the report.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub curve_error: Option<CurveError>,
    /// What the simulated device was told to cut, for the text output.
    #[serde(skip)]
    pub sim: Option<SimNote>,
}

/// Measure as `args` say.
pub fn run(g: &Global, args: &RunArgs) -> Result<RunReport, CliError> {
    let params = args.request().checked()?;
    check_other_forces(&args.also_at_force_n)?;
    if let Some(plot) = &args.plot {
        plot::PlotFormat::for_path(plot)?;
        kerfmeter_plan::ownership::ensure_replaceable(plot, args.force)?;
        // Before the gauge is measured: a plot that cannot be written is found now.
        kerfmeter::files::ensure_writable(plot)?;
    }
    g.check_db_folder()?;
    let mut s = g.connect()?;
    let measurement = measure(g, args, &mut s, &params)?;
    // Recorded before anything else can fail: the measurement is made.
    let history = record(
        g.db.as_deref(),
        &s.meter,
        &Measured {
            label: args.label.as_deref(),
            thickness_mm: f64::from(params.thickness_mm),
            force_n: f64::from(params.target_force_n),
            kerf_um: measurement.summary.mean_um,
            ci95_um: measurement.summary.ci95_um,
            runs: &measurement.runs,
        },
    );
    let last = measurement.runs.last().copied();
    let curve = read_curve(&mut s, args, &params, last.as_ref());
    let mut report = RunReport::new(&s, &params, measurement);
    match curve {
        Ok(kerf_at_force_um) => report.kerf_at_force_um = kerf_at_force_um,
        // The kerf is measured and recorded: show it, then fail for the curve.
        Err(e) => report.curve_failed(&e),
    }
    report.plot.clone_from(&args.plot);
    report.label.clone_from(&args.label);
    report.history = Some(history);
    Ok(report)
}

/// Why the curve could not be read or drawn after a measurement; its JSON is the message.
#[derive(Debug, Clone, Serialize)]
#[serde(transparent)]
pub struct CurveError {
    /// What failed.
    pub message: String,
    /// Its kind, for the exit code (and, on the server, whether the link is lost).
    #[serde(skip)]
    pub category: kerfmeter::Category,
}

impl RunReport {
    /// The report of `measurement`, made with `params` on the device of `s` (on the twin, with
    /// its truth); no readings at other forces, no plot.
    pub fn new(s: &Session, params: &RunParams, measurement: Measurement) -> Self {
        let Measurement { runs, summary } = measurement;
        let sim_truths_um: Vec<f64> = match &s.sim {
            Some(sim) => runs.iter().filter_map(|r| sim.truth_um(r.run_id)).collect(),
            None => Vec::new(),
        };
        let sim_truth_um = (!sim_truths_um.is_empty())
            .then(|| sim_truths_um.iter().sum::<f64>() / sim_truths_um.len() as f64);
        let sim = s
            .sim
            .as_ref()
            .zip(sim_truth_um)
            .map(|(sim, truth_um)| SimNote {
                kerf_um: sim.options().kerf_um,
                kerf_sd_um: sim.options().kerf_sd_um,
                ideal_reading_um: truth_um,
            });
        RunReport {
            force_n: params.target_force_n,
            kerf_at_force_um: Vec::new(),
            kerf_um: summary.mean_um,
            plot: None,
            runs,
            label: None,
            history: None,
            simulated: s.sim.is_some(),
            summary,
            thickness_mm: params.thickness_mm,
            sim_truth_um,
            sim_truths_um,
            curve_error: None,
            sim,
        }
    }

    /// Note that the curve could not be read or drawn after the measurement.
    pub fn curve_failed(&mut self, e: &CliError) {
        self.curve_error = Some(CurveError {
            message: e.to_string(),
            category: e.category(),
        });
    }
}

/// `--also-at-force-n`: each force in the range a run may ask for.
fn check_other_forces(forces_n: &[f32]) -> Result<(), CliError> {
    let field = kerfmeter::protocol::ParamField::TargetForceN;
    let (lo, hi) = field.range();
    match forces_n.iter().find(|f| !(lo..=hi).contains(*f)) {
        Some(&force_n) => Err(CliError::Usage(format!(
            "--also-at-force-n: {}",
            field.out_of_range(Some(force_n))
        ))),
        None => Ok(()),
    }
}

/// The `--samples` runs, each after its prompt, with a progress bar.
fn measure(
    g: &Global,
    args: &RunArgs,
    s: &mut Session,
    params: &RunParams,
) -> Result<Measurement, CliError> {
    let sim = s.sim.is_some();
    let samples = args.samples as usize;
    let bar = progress_bar(g, "gauge 1");
    let measured = s.meter.measure_until(
        params,
        samples,
        |i| {
            if crate::interrupt::raised().is_some() {
                return Err(Error::Cancelled);
            }
            bar.suspend(|| {
                ask(
                    g,
                    args.yes,
                    sim,
                    &format!("Place gauge {} of {samples} under the prongs", i + 1),
                )
            })
            .map_err(|e| Error::invalid(e.to_string()))?;
            bar.set_prefix(format!("gauge {}/{samples}", i + 1));
            Ok(())
        },
        |_, p| {
            show(&bar, p);
            crate::interrupt::check()
        },
    );
    bar.finish_and_clear();
    Ok(measured?)
}

/// Fetch the last run's curve if asked to plot it or read other forces off it; do both.
fn read_curve(
    s: &mut Session,
    args: &RunArgs,
    params: &RunParams,
    last: Option<&KerfResult>,
) -> Result<Vec<KerfAtForce>, CliError> {
    if args.plot.is_none() && args.also_at_force_n.is_empty() {
        return Ok(Vec::new());
    }
    let curve = s.meter.curve()?;
    if let Some(path) = &args.plot {
        plot::plot_curve(&curve, last, path)?;
    }
    Ok(args
        .also_at_force_n
        .iter()
        .map(|&force_n| KerfAtForce {
            force_n,
            kerf_um: curve.kerf_at_force_um(
                params,
                last.filter(|r| r.run_id == curve.run_id)
                    .map(|r| r.play_deg),
                force_n,
            ),
        })
        .collect())
}

impl fmt::Display for RunReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}\n", ResultsTable(&self.runs))?;
        let s = &self.summary;
        match s.ci95_um {
            Some(ci) => write!(
                f,
                "kerf {:.1} µm ± {:.1} µm (95 % CI, n = {}, SD {:.1} µm) at {:.1} N",
                s.mean_um, ci, s.n, s.sd_um, self.force_n
            )?,
            None => write!(f, "kerf {:.1} µm at {:.1} N", s.mean_um, self.force_n)?,
        }
        for KerfAtForce { force_n, kerf_um } in &self.kerf_at_force_um {
            match kerf_um {
                Some(k) => write!(
                    f,
                    "\n  at {force_n:.1} N (from the last run's curve): {k:.1} µm"
                )?,
                None => write!(
                    f,
                    "\n  at {force_n:.1} N: beyond the force the last run reached"
                )?,
            }
        }
        for &i in &s.outliers {
            write!(
                f,
                "\nwarning: run {} ({:.1} µm) is an outlier; check that gauge",
                i + 1,
                self.runs[i].kerf_um
            )?;
        }
        write_run_warnings(f, &self.runs, self.force_n)?;
        if let Some(path) = &self.plot {
            write!(f, "\ncurve: {}", path.display())?;
        }
        if let Some(sim) = &self.sim {
            write!(f, "\n{sim}")?;
        }
        match &self.history {
            Some(history) => write!(f, "\n{history}"),
            None => Ok(()),
        }
    }
}

/// A run the quality flags distrust (its kerf may be off by more than the device vouches for),
/// and a run whose joint force was not the one asked for (the supply or the torque cap held it
/// back): a warning line each, so that a number is never read without them.
fn write_run_warnings(
    f: &mut fmt::Formatter<'_>,
    runs: &[KerfResult],
    force_n: f32,
) -> fmt::Result {
    for (i, r) in runs.iter().enumerate() {
        let distrusting = r.flags.distrusting();
        if !distrusting.is_empty() {
            let names: Vec<&str> = distrusting.names().collect();
            write!(
                f,
                "\nwarning: run {} is flagged {}: its kerf may be off by more than 3 µm (docs/measurement.md)",
                i + 1,
                names.join(", ")
            )?;
        }
        if (r.force_at_jam_n - force_n).abs() > 0.05 * force_n {
            write!(
                f,
                "\nwarning: run {} pressed the joint at {:.1} N, not the {:.1} N asked for",
                i + 1,
                r.force_at_jam_n,
                force_n
            )?;
        }
    }
    Ok(())
}

impl fmt::Display for SimNote {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let spread = if self.kerf_sd_um > 0.0 {
            format!(" ± {:.1} µm SD", self.kerf_sd_um)
        } else {
            String::new()
        };
        write!(
            f,
            "(simulated device: gauges cut with a nominal {:.1} µm{spread}, as a real cutter cuts them; an ideal device reads {:.1} µm on them at the force asked for, the spiral contact compressing under it)",
            self.kerf_um, self.ideal_reading_um
        )
    }
}

impl Report for RunReport {
    const JSON: JsonLayout = JsonLayout::PrettySorted;

    fn verdict(&self) -> Result<(), CliError> {
        match &self.curve_error {
            Some(e) => Err(CliError::AfterMeasuring {
                message: e.message.clone(),
                category: e.category,
            }),
            None => Ok(()),
        }
    }
}
