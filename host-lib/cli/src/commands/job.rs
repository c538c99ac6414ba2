//! `kerfmeter job`: the paper's whole loop on a GRBL or Ruida laser cutter: cut the gauge beside
//! the plan, lower the prongs into it, measure, lift, dilate the plan by the kerf measured and cut
//! it. The flags become a [`JobRequest`] and the files it names ([`JobFiles`]); the application
//! layer ([`kerfmeter_app::job`]) sets the job up before anything moves (the plan read and
//! checked, the gauge placed, every move checked against the machine's travel and the bed, the
//! outputs checked writable) and dilates and writes the plan and the job's G-code atomically,
//! never over the input nor each other, drives the loop ([`kerfmeter::job`]'s) and records the
//! measurement. This module opens the machines, tells on stderr how it goes, and prints the
//! report ([`JobCliReport`]).
//!
//! The bed is the controller's X and Y travel (GRBL's `$130`, `$131`; a Ruida's bed-size
//! registers, or its address's `bed-mm`) unless `--bed-mm` gives it (600 × 400 mm for a
//! controller that reports none, and for `--dry-run`), so without `--bed-mm` the gauge is placed
//! once the cutter is connected. The gauge is cut with the job's own settings (the kerf depends
//! on them).
//!
//! # Simulated and real machines
//!
//! `--sim` with `--cutter sim` (or `ruida-sim`) closes the loop in simulation: the cutter twin's
//! trace of the gauge goes under the device twin's prongs, where the lowered head put them, so
//! the device measures the gauge the cutter cut. Mixing is refused: a simulated device cannot measure a
//! gauge a real cutter cut (and a real job would then be cut by a made-up kerf), and a real
//! device lowered onto a simulated cutter's bed would turn in nothing. `--dry-run` moves
//! nothing and opens neither: it prints every stage's G-code (the job's at `--dry-run-kerf-um`).
//!
//! # History
//!
//! The measurement is recorded in the history under `--label` ([`kerfmeter_app::history`]), also when the
//! job fails after it was measured (the device's last result is read back for it; the error
//! still fails the command).

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use kerfmeter::grbl::{ConnectOptions, Cutter, CutterAddress, SimCutterOptions};
use kerfmeter::job::{Devices, JobCutter, JobError, JobEvent, SimLink};
use kerfmeter_app::dilate::DEFAULT_CUT_MAX_WIDTH_MM;
use kerfmeter_app::job::{
    DEFAULT_PLUNGE_FEED_MM_PER_MIN, DEFAULT_TRAVEL_Z_MM, DryRunReport, JobCliReport, JobFiles,
    JobRequest, JobSetup, JobSetupError, Stopped,
};
use kerfmeter_plan::outcome::AssumedUnits;

use super::dilate::units_parser;
use super::gcode::{CutArgs, parse_xy};
use crate::connection::{Global, Session};
use crate::error::{CliError, JobSoFar};
use crate::output::{JsonLayout, Report};
use crate::progress::show;
use kerfmeter_app::history::parse_label;

type Result<T, E = CliError> = std::result::Result<T, E>;

/// `kerfmeter job`: cut the gauge, measure, dilate and cut the plan.
#[derive(Debug, Clone, clap::Args)]
pub struct JobArgs {
    /// The plan: an .svg or .dxf file.
    #[arg(value_name = "PLAN")]
    pub input: PathBuf,
    /// The cutter: `sim`, `grbl:/dev/ttyUSB0[?baud=N]`, `grbl+tcp://HOST:PORT`,
    /// `ruida:HOST?z-mm=MIN,MAX[&bed-mm=W,H][&axis=z|u]` or `ruida-sim`. Also from
    /// KERFMETER_CUTTER.
    #[arg(long, env = "KERFMETER_CUTTER", value_name = "ADDRESS")]
    pub cutter: CutterAddress,
    /// The dilated plan, same format as the input (never the input itself).
    #[arg(short, long, value_name = "DILATED")]
    pub output: PathBuf,
    /// The job's G-code as streamed [default: the output with the extension .gcode].
    #[arg(long, value_name = "FILE.gcode")]
    pub gcode_out: Option<PathBuf>,
    /// Replace the outputs even if they exist and kerfmeter did not write them (by default only
    /// kerfmeter's own outputs are replaced: a typo must not replace a cutting plan).
    #[arg(long)]
    pub force: bool,
    /// Sheet thickness, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_THICKNESS_MM)]
    pub thickness_mm: f64,
    /// Assembly force of the joint, N (default: 18.3 N per finger).
    #[arg(long)]
    pub force_n: Option<f64>,
    /// Where the gauge's spiral centre goes on the bed, mm [default: a free spot beside the plan
    /// on the --bed-mm bed].
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_xy)]
    pub gauge_at_mm: Option<[f64; 2]>,
    /// The bed's size, mm, from the work origin (to find a free spot for the gauge) [default:
    /// the controller's X and Y travel, $130 and $131; 600,400 when it reports none, and with
    /// --dry-run]. With --cutter sim, the simulated cutter's travel too.
    #[arg(long, value_name = "W,H", allow_hyphen_values = true, value_parser = parse_xy)]
    pub bed_mm: Option<[f64; 2]>,
    /// The prongs' axis relative to the laser nozzle, mm (see docs/cutters.md to calibrate it).
    #[arg(long, value_name = "DX,DY", allow_hyphen_values = true, value_parser = parse_xy, default_value = "0,0")]
    pub prong_offset_mm: [f64; 2],
    /// Z that lowers the prongs into the gauge's holes, mm.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub insert_z_mm: f64,
    /// Z that keeps the prongs clear of the work while the head travels, mm.
    #[arg(long, default_value_t = DEFAULT_TRAVEL_Z_MM, allow_hyphen_values = true)]
    pub travel_z_mm: f64,
    /// Feed of the plunge into the gauge, mm/min.
    #[arg(long, default_value_t = DEFAULT_PLUNGE_FEED_MM_PER_MIN)]
    pub plunge_feed_mm_per_min: f64,
    /// Where the lower-left corner of the plan's cuts goes on the machine, mm.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_xy, default_value = "0,0")]
    pub origin_mm: [f64; 2],
    /// Cut settings by colour or layer (TOML), for the job; the gauge takes its default.
    #[arg(long, value_name = "PROFILE.toml")]
    pub profile: Option<PathBuf>,
    /// Cut settings [default: 300 mm/min, 100 %, 1 pass, for the gauge and the job].
    #[command(flatten)]
    pub cut: CutArgs,
    /// Colours that mean "cut": CSS syntax (`#808080`, `rgb(255,0,0)`, names) or an ACI number
    /// 1–255, compared by colour both ways in DXF; repeat or separate by commas [default: red,
    /// blue, black].
    #[arg(long = "cut-color", value_name = "COLOR")]
    pub cut_colors: Vec<String>,
    /// Widest stroke (SVG) or lineweight (DXF) that is still a cut line, mm.
    #[arg(long, default_value_t = DEFAULT_CUT_MAX_WIDTH_MM)]
    pub cut_max_width_mm: f64,
    /// DXF: the entities on these layers are the cuts (repeat or separate by commas; a layer's
    /// whole name with a comma in it matches too).
    #[arg(long = "cut-layer", value_name = "LAYER")]
    pub cut_layers: Vec<String>,
    /// What one drawing unit is, for files that do not say (unitless SVG, DXF without
    /// $INSUNITS).
    #[arg(long, value_parser = units_parser())]
    pub units: Option<AssumedUnits>,
    /// A plan that says it is already compensated (a boxes.py --burn, this tool's own output)
    /// is refused before anything moves; dilate it by the full measured kerf on top anyway.
    #[arg(long, conflicts_with = "recompensate")]
    pub already_compensated_ok: bool,
    /// Undo the compensation the plan records (boxes.py's burn, this tool's earlier offset) and
    /// apply the measured kerf instead: each cut moves by kerf/2 − burn, inner corners kept
    /// sharp.
    #[arg(long)]
    pub recompensate: bool,
    /// Print every stage's G-code to stdout; move nothing, open neither machine.
    #[arg(long)]
    pub dry_run: bool,
    /// With --dry-run: the kerf the job's G-code is shown dilated by, µm.
    #[arg(long, default_value_t = 0.0, requires = "dry_run")]
    pub dry_run_kerf_um: f64,
    /// Unlock a cutter that is in alarm (`$X`) instead of refusing it.
    #[arg(long)]
    pub unlock: bool,
    /// What is measured, for the history (material, cutter), e.g. "birch 3 mm, CO2 40 W".
    #[arg(long, value_parser = parse_label)]
    pub label: Option<String>,
}

impl JobArgs {
    /// The job the flags ask for.
    pub fn request(&self) -> JobRequest {
        JobRequest {
            thickness_mm: self.thickness_mm,
            force_n: self.force_n,
            gauge_at_mm: self.gauge_at_mm,
            bed_mm: self.bed_mm,
            prong_offset_mm: self.prong_offset_mm,
            insert_z_mm: self.insert_z_mm,
            travel_z_mm: self.travel_z_mm,
            plunge_feed_mm_per_min: self.plunge_feed_mm_per_min,
            origin_mm: self.origin_mm,
            feed_mm_per_min: self.cut.feed_mm_per_min,
            power_percent: self.cut.power_percent,
            passes: self.cut.passes,
            s_max: self.cut.s_max,
            cut_colors: self.cut_colors.clone(),
            cut_max_width_mm: self.cut_max_width_mm,
            cut_layers: self.cut_layers.clone(),
            units: self.units,
            already_compensated_ok: self.already_compensated_ok,
            recompensate: self.recompensate,
            unlock: self.unlock,
            label: self.label.clone(),
        }
    }

    /// The files the flags name.
    pub fn files(&self) -> JobFiles {
        JobFiles {
            input: self.input.clone(),
            output: self.output.clone(),
            gcode_out: self.gcode_out.clone(),
            profile: self.profile.clone(),
            force: self.force,
        }
    }
}

impl Report for JobCliReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

impl Report for DryRunReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

/// What `job` prints: the loop's report, or the dry run's programs.
pub enum JobOutcome {
    /// The loop ran.
    Done(Box<JobCliReport>),
    /// `--dry-run`.
    DryRun(DryRunReport),
}

/// Run the loop as `args` say (or print its programs with `--dry-run`).
pub fn run(g: &Global, args: &JobArgs) -> Result<JobOutcome> {
    let setup = JobSetup::new(args.request(), args.files(), args.dry_run)?;
    if args.dry_run {
        return Ok(JobOutcome::DryRun(setup.dry_run(args.dry_run_kerf_um)?));
    }
    check_machines(g, &args.cutter)?;
    g.check_db_folder()?;
    // Raised by Ctrl-C, SIGTERM and SIGHUP (`main` installs the handler for `job`).
    let cancel = crate::interrupt::flag();
    let mut session = g.connect()?;
    let bar = stage_bar(g.json);
    let report = run_on(g, &args.cutter, &setup, &mut session, &cancel, &mut |e| {
        show_event(&bar, e)
    });
    bar.finish_and_clear();
    Ok(JobOutcome::Done(Box::new(report?)))
}

/// Run the loop `setup` made ready on the cutter at `address` (opened here) and the device of
/// `session`, until done or `cancel` is raised; `on_event` hears of every stage (`kerfmeter
/// serve` shares it).
pub fn run_on(
    g: &Global,
    address: &CutterAddress,
    setup: &JobSetup,
    session: &mut Session,
    cancel: &Arc<AtomicBool>,
    on_event: &mut dyn FnMut(JobEvent<'_>),
) -> Result<JobCliReport> {
    check_machines(g, address)?;
    let mut opened = open_cutter(g, address, setup.request(), cancel)?;
    let placed = setup.on_machine(opened.cutter.travel().as_ref())?;
    if !g.json {
        eprintln!(
            "job on {} ({}); gauge at ({:.1}, {:.1}) mm; Ctrl-C stops the cutter and the device",
            opened.address,
            opened.controller,
            placed.placement.gauge_at_mm[0],
            placed.placement.gauge_at_mm[1]
        );
    }
    let sim_kerf = opened.sim_kerf;
    let devices = Devices {
        cutter: opened.cutter.as_mut(),
        meter: &mut session.meter,
        sim: session.sim.as_ref().map(|device| SimLink {
            device,
            kerf: sim_kerf,
        }),
    };
    let done = match setup.drive(&placed, devices, cancel, on_event) {
        Ok(done) => done,
        Err(Stopped::Before(e)) => return Err(job_error(e)),
        Err(Stopped::After { error, written }) => {
            return Err(after_measuring(g, setup, session, error, written));
        }
    };
    let history = setup.record(g.db.as_deref(), &session.meter, &done.kerf);
    let sim_truth_um = session
        .sim
        .as_ref()
        .and_then(|s| s.truth_um(done.kerf.run_id));
    Ok(setup.report(&placed, opened.address, done, sim_truth_um, history))
}

/// The error of a job that failed after its measurement: the device's last result recorded
/// (said on stderr), the files `written` named on stderr, and both kept for `--json`.
fn after_measuring(
    g: &Global,
    setup: &JobSetup,
    session: &mut Session,
    e: JobError,
    written: Vec<PathBuf>,
) -> CliError {
    let recorded = setup.record_after_stop(g.db.as_deref(), &mut session.meter);
    eprintln!("the job failed after its measurement; {}", recorded.note);
    if !written.is_empty() {
        let files: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
        eprintln!(
            "note: written before the job stopped, complete: {}; the plan was not cut (or not all of it)",
            files.join(" and ")
        );
    }
    let so_far = JobSoFar {
        kerf_um: recorded.kerf_um,
        history: recorded.history,
        written,
    };
    match job_error(e) {
        CliError::Job(source) => CliError::JobAfterMeasuring {
            source,
            so_far: Box::new(so_far),
        },
        other => other,
    }
}

/// Refuse a simulated device with a real cutter, and the other way round (see the module doc).
fn check_machines(g: &Global, address: &CutterAddress) -> Result<()> {
    let sim_cutter = address.is_sim();
    match (g.sim, sim_cutter) {
        (true, false) => Err(CliError::Usage(
            "--sim with a real cutter is refused: the simulated device cannot measure the gauge \
             a real laser cut, and the job would be cut by a made-up kerf. Use --cutter sim, or \
             a real device (--port)"
                .into(),
        )),
        (false, true) => Err(CliError::Usage(
            "--cutter sim with a real device is refused: the simulated cutter cuts no gauge for \
             the real prongs to measure. Use --sim with --cutter sim, or a real cutter"
                .into(),
        )),
        _ => Ok(()),
    }
}

/// A cutter opened for the job: the driver, its address and controller as the user is told
/// them, and a simulated cutter's kerf model for the device twin.
struct Opened {
    cutter: Box<dyn JobCutter>,
    address: String,
    controller: String,
    sim_kerf: Option<kerfmeter_twin::plant::CutterKerf>,
}

/// Open the cutter at `address` (given up as soon as `cancel` is set: Ctrl-C while a controller
/// boots), unlocked if `request` says; a simulated one cuts with `--sim-kerf-um` and
/// `--sim-kerf-sd-um` on the request's bed, and its kerf model is handed back for the device
/// twin.
fn open_cutter(
    g: &Global,
    address: &CutterAddress,
    request: &JobRequest,
    cancel: &Arc<AtomicBool>,
) -> Result<Opened> {
    let mut kerf = SimCutterOptions::default().kerf;
    kerf.kerf_um = g.sim_kerf_um;
    kerf.kerf_sd_um = g.sim_kerf_sd_um;
    let sim_kerf = address.is_sim().then_some(kerf);
    if address.is_ruida() {
        let cutter = kerfmeter::ruida::open(address, request.bed_mm)?;
        return Ok(Opened {
            address: cutter.address().to_owned(),
            controller: "Ruida".into(),
            cutter: Box::new(cutter),
            sim_kerf,
        });
    }
    let options = ConnectOptions {
        unlock: request.unlock,
        ..ConnectOptions::default()
    };
    let cutter = if *address == CutterAddress::Sim {
        let mut twin = SimCutterOptions {
            kerf,
            ..SimCutterOptions::default()
        };
        if let Some([w, h]) = request.bed_mm {
            twin.travel_mm = [w, h, twin.travel_mm[2]];
        }
        Cutter::sim_cancellable(twin, options, cancel.clone())?
    } else {
        Cutter::open_cancellable(address, options, cancel.clone())?
    };
    Ok(Opened {
        address: cutter.address().to_owned(),
        controller: format!("GRBL {}", cutter.version()),
        cutter: Box::new(cutter),
        sim_kerf,
    })
}

/// A setup's refusal as the CLI's error; a refused move's exit code follows its category.
impl From<JobSetupError> for CliError {
    fn from(e: JobSetupError) -> Self {
        match e {
            JobSetupError::Invalid(why) => CliError::Usage(why),
            JobSetupError::App(e) => CliError::from(e),
            JobSetupError::Job(e) => job_error(e),
        }
    }
}

/// A loop error as the CLI's; its exit code follows its category.
fn job_error(e: JobError) -> CliError {
    match e.category() {
        kerfmeter::Category::Usage => CliError::Usage(e.to_string()),
        _ => CliError::Job(e),
    }
}

/// A spinner naming the stage, on stderr when it is a terminal and `json` is off.
fn stage_bar(json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {prefix} {msg}").expect("valid template"),
    );
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

fn show_event(bar: &ProgressBar, e: JobEvent<'_>) {
    match e {
        JobEvent::Started(stage) => bar.set_prefix(stage.describe()),
        JobEvent::Cutter(_, p) => bar.set_message(format!("{}/{} lines", p.answered, p.total)),
        JobEvent::Device(p) => show(bar, p),
        JobEvent::Finished(stage, elapsed) => {
            bar.println(format!(
                "{:<12} {:8.2} s",
                stage.name(),
                elapsed.as_secs_f64()
            ));
            bar.set_message("");
        }
    }
}
