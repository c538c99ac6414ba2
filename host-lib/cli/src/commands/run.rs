//! `kerfmeter run`: measure the kerf (the hub is reset to zero first). With `--samples N`, N
//! gauges are measured and the mean with its 95 % confidence interval is reported; `--plot` draws
//! the last run's torque–angle curve and `--also-at-force-n` reads other forces off it. The
//! measurement is recorded in the history (under `--label`), and a drift warning printed when the
//! label's kerf left its usual spread ([`kerfmeter_app::history`]).

use std::path::PathBuf;

use clap::Args;
use kerfmeter::Error;
use kerfmeter::protocol::{KerfResult, RunParams};

use crate::connection::{Global, Session};
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::plot;
use crate::progress::{ask, progress_bar, show};
use kerfmeter_app::history::parse_label;
use kerfmeter_app::measure::{
    KerfAtForce, MAX_SAMPLES, MeasureRequest, RunReport, measure_and_record,
};

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
    let report = measure(g, args, &mut s, &params)?;
    let mut report = s.with_twin_truth(report);
    let last = report.runs.last().copied();
    match read_curve(&mut s, args, &params, last.as_ref()) {
        Ok(kerf_at_force_um) => report.kerf_at_force_um = kerf_at_force_um,
        // The kerf is measured and recorded: show it, then fail for the curve.
        Err(e) => report.curve_failed(e.to_string(), e.category()),
    }
    report.plot.clone_from(&args.plot);
    Ok(report)
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

/// The `--samples` runs, each after its prompt, with a progress bar, recorded in the history.
fn measure(
    g: &Global,
    args: &RunArgs,
    s: &mut Session,
    params: &RunParams,
) -> Result<RunReport, CliError> {
    let sim = s.sim.is_some();
    let samples = args.samples as usize;
    let bar = progress_bar(g, "gauge 1");
    let measured = measure_and_record(
        &mut s.meter,
        params,
        samples,
        args.label.as_deref(),
        g.db.as_deref(),
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
