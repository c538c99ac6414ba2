//! `kerfmeter job`: the paper's whole loop on a GRBL laser cutter: cut the gauge beside the plan,
//! lower the prongs into it, measure, lift, dilate the plan by the kerf measured and cut it
//! ([`kerfmeter::job`] runs the loop; this module turns the arguments into its inputs, makes the
//! gauge's and the job's G-code with `kerfmeter_plan`, and writes the dilated plan and the job's
//! G-code atomically, never over the input nor each other, checked writable before anything
//! moves).
//!
//! The plan is read (and checked) before anything moves, and the gauge's place chosen: at
//! `--gauge-at-mm`, or on a free spot of the `--bed-mm` bed beside the plan's placed bounding
//! box. The bed is the controller's X and Y travel (`$130`, `$131`) unless `--bed-mm` gives it
//! (600 × 400 mm for a controller that reports none, and for `--dry-run`), so without
//! `--bed-mm` the gauge is placed once the cutter is connected. Every planned move is then
//! checked: against the machine's travel first ([`kerfmeter::job::check_travel`]: exit 4), then
//! ([`kerfmeter::job::Placement::check_layout`]) the plan and the gauge on the bed, the gauge
//! 5 mm clear of the plan as drawn, the head's move over the gauge on the bed, the insert Z
//! below the travel Z. The gauge is cut with the job's own settings (the kerf depends on them).
//!
//! # Simulated and real machines
//!
//! `--sim` with `--cutter sim` closes the loop in simulation: the cutter twin's trace of the
//! gauge goes under the device twin's prongs, where the lowered head put them, so the device
//! measures the gauge the cutter cut. Mixing is refused: a simulated device cannot measure a
//! gauge a real cutter cut (and a real job would then be cut by a made-up kerf), and a real
//! device lowered onto a simulated cutter's bed would turn in nothing. `--dry-run` moves
//! nothing and opens neither: it prints every stage's G-code (the job's at `--dry-run-kerf-um`).
//!
//! # History
//!
//! The measurement is recorded in the history under `--label` ([`kerfmeter_app::history`]), also when the
//! job fails after it was measured (the device's last result is read back for it; the error
//! still fails the command).

use std::fmt;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use kerfmeter::JointSpec;
use kerfmeter::files::{ensure_not_input, ensure_writable, same_file, write_atomically};
use kerfmeter::grbl::travel::Travel;
use kerfmeter::grbl::{ConnectOptions, Cutter, CutterAddress, SimCutterOptions};
use kerfmeter::job::{
    Devices, JobError, JobEvent, JobRequest, Layout, Placement, SimLink, Stage, StageTime,
    check_plan_travel, check_travel, free_spot_mm, run_job,
};
use kerfmeter::protocol::{GaugeGeometry, KerfResult, RunParams};
use kerfmeter_plan::compensation::check_before_measuring;
use kerfmeter_plan::gauge::{GaugeDrawing, GaugeOptions, build};
use kerfmeter_plan::gcode::{
    GcodeOptions, Mapping, Provenance, gauge_cuts, gauge_program, placed_box, plan_program,
};
use kerfmeter_plan::outcome::AssumedUnits;
use kerfmeter_plan::profile::Profile;
use kerfmeter_plan::{PlanError, PlanFormat, dilate_file, dilate_file_cuts};
use serde::Serialize;

use super::dilate::{DilationArgs, plan_output_format, units_parser};
use super::gauge::GAUGE_SETTINGS;
use super::gcode::{CutArgs, parse_xy};
use crate::connection::{Global, Session};
use crate::error::{CliError, JobSoFar};
use crate::output::{JsonLayout, Report};
use crate::progress::show;
use kerfmeter_app::history::{Measured, Recorded, parse_label, record};

type Result<T, E = CliError> = std::result::Result<T, E>;

/// Space kept between the plan and the gauge, mm.
const GAUGE_MARGIN_MM: f64 = 5.0;
/// The bed when neither `--bed-mm` nor the controller gives one, mm.
const DEFAULT_BED_MM: [f64; 2] = [600.0, 400.0];

/// `kerfmeter job`: cut the gauge, measure, dilate and cut the plan.
#[derive(Debug, Clone, clap::Args)]
pub struct JobArgs {
    /// The plan: an .svg or .dxf file.
    #[arg(value_name = "PLAN")]
    pub input: PathBuf,
    /// The cutter: `sim`, `grbl:/dev/ttyUSB0[?baud=N]` or `grbl+tcp://HOST:PORT`. Also from
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
    #[arg(long, default_value_t = 10.0, allow_hyphen_values = true)]
    pub travel_z_mm: f64,
    /// Feed of the plunge into the gauge, mm/min.
    #[arg(long, default_value_t = 300.0)]
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
    #[arg(long, default_value_t = 0.3)]
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

/// What the loop did.
#[derive(Debug, Clone, Serialize)]
pub struct JobCliReport {
    /// The plan read.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub input: PathBuf,
    /// The dilated plan written.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub output: PathBuf,
    /// The job's G-code written (and streamed).
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub gcode_out: PathBuf,
    /// The cutter's address.
    pub cutter: String,
    /// The kerf measured, µm.
    pub kerf_um: f32,
    /// Each stage's wall-clock time, s.
    pub stages: Vec<StageTime>,
    /// All stages, s.
    pub total_s: f64,
    /// Where the gauge was cut, mm.
    pub gauge_at_mm: [f64; 2],
    /// Where the prongs came down, mm.
    pub landing_mm: [f64; 2],
    /// Lines of the job streamed.
    pub job_lines: usize,
    /// On the simulated device: what an ideal device reads on the gauge the cutter twin cut, µm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_truth_um: Option<f64>,
    /// What was measured (`--label`).
    pub label: Option<String>,
    /// Where the measurement was recorded, or why not, and its drift.
    pub history: Recorded,
}

impl fmt::Display for JobCliReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "kerf {:.1} µm", self.kerf_um)?;
        if let Some(t) = self.sim_truth_um {
            write!(f, " (simulated truth {t:.1} µm)")?;
        }
        writeln!(
            f,
            "; gauge cut at ({:.1}, {:.1}) mm on {}",
            self.gauge_at_mm[0], self.gauge_at_mm[1], self.cutter
        )?;
        for s in &self.stages {
            writeln!(f, "  {:<12} {:8.2} s", s.stage.name(), s.elapsed_s)?;
        }
        writeln!(f, "  {:<12} {:8.2} s", "total", self.total_s)?;
        writeln!(
            f,
            "wrote {} and {} ({} lines streamed); the laser is off",
            self.output.display(),
            self.gcode_out.display(),
            self.job_lines
        )?;
        write!(f, "{}", self.history)
    }
}

impl Report for JobCliReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

/// One stage's G-code, for `--dry-run`.
#[derive(Debug, Clone, Serialize)]
pub struct StageGcode {
    /// The stage.
    pub stage: Stage,
    /// Its program.
    pub gcode: String,
}

/// What `--dry-run` prints.
#[derive(Debug, Clone, Serialize)]
pub struct DryRunReport {
    /// Where the gauge would be cut, mm.
    pub gauge_at_mm: [f64; 2],
    /// The kerf the job is shown dilated by, µm.
    pub kerf_um: f64,
    /// The programs, in order.
    pub stages: Vec<StageGcode>,
}

impl fmt::Display for DryRunReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for s in &self.stages {
            writeln!(f, "; ==== stage {}: {}", s.stage, s.stage.describe())?;
            if s.stage == Stage::StreamJob {
                writeln!(
                    f,
                    "; (dilated by {} um here; the job uses the kerf measured)",
                    self.kerf_um
                )?;
            }
            f.write_str(&s.gcode)?;
        }
        Ok(())
    }
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
    let setup = Setup::new(args)?;
    if args.dry_run {
        return Ok(JobOutcome::DryRun(setup.dry_run(args)?));
    }
    check_machines(g, args)?;
    g.check_db_folder()?;
    // Raised by Ctrl-C, SIGTERM and SIGHUP (`main` installs the handler for `job`).
    let cancel = crate::interrupt::flag();
    let mut session = g.connect()?;
    let bar = stage_bar(g.json);
    let report = run_on(g, args, &setup, &mut session, &cancel, &mut |e| {
        show_event(&bar, e)
    });
    bar.finish_and_clear();
    Ok(JobOutcome::Done(Box::new(report?)))
}

/// Run the loop as `args` say with `setup` on the device of `session` (the cutter is opened
/// here), until done or `cancel` is raised; `on_event` hears of every stage (`kerfmeter serve`
/// shares it).
pub fn run_on(
    g: &Global,
    args: &JobArgs,
    setup: &Setup,
    session: &mut Session,
    cancel: &Arc<AtomicBool>,
    on_event: &mut dyn FnMut(JobEvent<'_>),
) -> Result<JobCliReport> {
    check_machines(g, args)?;
    let (mut cutter, sim_kerf) = open_cutter(g, args, cancel)?;
    let placed = setup.on_machine(args, cutter.travel().as_ref())?;
    if !g.json {
        eprintln!(
            "job on {} (GRBL {}); gauge at ({:.1}, {:.1}) mm; Ctrl-C stops the cutter and the device",
            cutter.address(),
            cutter.version(),
            placed.placement.gauge_at_mm[0],
            placed.placement.gauge_at_mm[1]
        );
    }
    let request = JobRequest {
        gauge_gcode: &placed.gauge_gcode,
        placement: placed.placement,
        params: setup.params,
        plan_box_mm: Some(setup.plan_box_mm),
    };
    let devices = Devices {
        cutter: &mut cutter,
        meter: &mut session.meter,
        sim: session.sim.as_ref().map(|device| SimLink {
            device,
            kerf: sim_kerf,
        }),
    };
    let mut written = Vec::new();
    let mut dilate = |kerf_um: f64| setup.dilate_and_write(args, kerf_um, &mut written);
    let mut measured = false;
    let report = run_job(devices, &request, &mut dilate, cancel, &mut |e| {
        measured |= matches!(e, JobEvent::Finished(Stage::Measure, _));
        on_event(e)
    });
    let report = match report {
        Ok(report) => report,
        Err(e) if !measured => return Err(job_error(e)),
        Err(e) => {
            let (kerf_um, history) = record_after_failure(g, args, setup, session);
            if !written.is_empty() {
                let files: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
                eprintln!(
                    "note: written before the job stopped, complete: {}; the plan was not cut (or not all of it)",
                    files.join(" and ")
                );
            }
            let so_far = JobSoFar {
                kerf_um,
                history,
                written,
            };
            return Err(match job_error(e) {
                CliError::Job(source) => CliError::JobAfterMeasuring {
                    source,
                    so_far: Box::new(so_far),
                },
                other => other,
            });
        }
    };
    let history = record_kerf(g, args, setup, session, &report.kerf);
    let sim_truth_um = session
        .sim
        .as_ref()
        .and_then(|s| s.truth_um(report.kerf.run_id));
    Ok(JobCliReport {
        input: args.input.clone(),
        output: args.output.clone(),
        gcode_out: setup.gcode_out.clone(),
        cutter: cutter.address().to_owned(),
        kerf_um: report.kerf.kerf_um,
        total_s: report.stages.iter().map(|s| s.elapsed_s).sum(),
        stages: report.stages,
        gauge_at_mm: placed.placement.gauge_at_mm,
        landing_mm: report.landing_mm,
        job_lines: report.job_lines,
        sim_truth_um,
        label: args.label.clone(),
        history,
    })
}

/// Record the job's measurement `kerf` in the history.
fn record_kerf(
    g: &Global,
    args: &JobArgs,
    setup: &Setup,
    session: &Session,
    kerf: &KerfResult,
) -> Recorded {
    let measured = Measured {
        label: args.label.as_deref(),
        thickness_mm: f64::from(setup.params.thickness_mm),
        force_n: f64::from(setup.params.target_force_n),
        kerf_um: f64::from(kerf.kerf_um),
        ci95_um: None,
        runs: std::slice::from_ref(kerf),
    };
    record(g.db.as_deref(), &session.meter, &measured)
}

/// A job that failed after its measurement: record the device's last result, saying so on
/// stderr (the command fails with the job's error); the kerf and its record, for `--json`.
fn record_after_failure(
    g: &Global,
    args: &JobArgs,
    setup: &Setup,
    session: &mut Session,
) -> (Option<f32>, Option<Recorded>) {
    let (kerf_um, history, note) = match session.meter.get_kerf_value() {
        Ok(Some(kerf)) => {
            let recorded = record_kerf(g, args, setup, session, &kerf);
            let note = recorded.to_string();
            (Some(kerf.kerf_um), Some(recorded), note)
        }
        Ok(None) => {
            let note = "warning: not recorded in the history: the device kept no result";
            (None, None, note.to_owned())
        }
        Err(e) => {
            let note = format!("warning: not recorded in the history: cannot read the result: {e}");
            (None, None, note)
        }
    };
    eprintln!("the job failed after its measurement; {note}");
    (kerf_um, history)
}

/// Refuse a simulated device with a real cutter, and the other way round (see the module doc).
fn check_machines(g: &Global, args: &JobArgs) -> Result<()> {
    let sim_cutter = args.cutter == CutterAddress::Sim;
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

/// Open the cutter (given up as soon as `cancel` is set: Ctrl-C while a controller boots); the
/// simulated one cuts with `--sim-kerf-um` and `--sim-kerf-sd-um`, and its kerf model is handed
/// back for the device twin.
fn open_cutter(
    g: &Global,
    args: &JobArgs,
    cancel: &Arc<AtomicBool>,
) -> Result<(Cutter, Option<kerfmeter_twin::plant::CutterKerf>)> {
    let options = ConnectOptions {
        unlock: args.unlock,
        ..ConnectOptions::default()
    };
    if args.cutter != CutterAddress::Sim {
        return Ok((
            Cutter::open_cancellable(&args.cutter, options, cancel.clone())?,
            None,
        ));
    }
    let mut twin = SimCutterOptions::default();
    if let Some([w, h]) = args.bed_mm {
        twin.travel_mm = [w, h, twin.travel_mm[2]];
    }
    twin.kerf.kerf_um = g.sim_kerf_um;
    twin.kerf.kerf_sd_um = g.sim_kerf_sd_um;
    let kerf = twin.kerf;
    Ok((
        Cutter::sim_cancellable(twin, options, cancel.clone())?,
        Some(kerf),
    ))
}

/// What the loop needs, made from the arguments before anything moves.
pub struct Setup {
    /// Where the gauge goes and its G-code, when the bed was known before connecting
    /// (`--bed-mm`, or a dry run); else placed once the cutter reports its travel.
    placed: Option<Placed>,
    plan_box_mm: [[f64; 2]; 2],
    gauge_extent_mm: [[f64; 2]; 2],
    drawing: GaugeDrawing,
    params: RunParams,
    gcode_out: PathBuf,
    profile: Profile,
    gcode_options: GcodeOptions,
}

/// Where the gauge is cut, how the prongs reach it, and its G-code.
#[derive(Clone)]
pub struct Placed {
    placement: Placement,
    gauge_gcode: String,
}

impl Setup {
    /// Check the plan (read at kerf 0) before anything moves; when the bed is known (`--bed-mm`,
    /// or a dry run), choose the gauge's place and write its G-code.
    pub fn new(args: &JobArgs) -> Result<Setup> {
        let gcode_out = check_outputs(args)?;
        let profile = job_profile(args)?;
        let gcode_options = GcodeOptions {
            s_max: args.cut.s_max,
            origin_mm: args.origin_mm,
        };
        gcode_options.check()?;
        let params = JointSpec {
            thickness_mm: args.thickness_mm,
            force_n: args.force_n,
            ..JointSpec::default()
        }
        .run_params(GaugeGeometry::PAPER)?;
        let drawing = build(&GaugeGeometry::PAPER, &GaugeOptions::default())?;
        let mut setup = Setup {
            placed: None,
            plan_box_mm: placed_plan_box(args, &gcode_options)?,
            gauge_extent_mm: gauge_extent_mm(&drawing)?,
            drawing,
            params,
            gcode_out,
            profile,
            gcode_options,
        };
        // The numbers and the Z order, wherever the gauge goes.
        setup
            .placement(args, args.gauge_at_mm.unwrap_or_default())
            .check()
            .map_err(job_error)?;
        let bed_now = args.bed_mm.or(args.dry_run.then_some(DEFAULT_BED_MM));
        if let Some(bed_mm) = bed_now {
            setup.placed = Some(setup.place(args, bed_mm, None)?);
        }
        Ok(setup)
    }

    /// Where the job goes on the connected cutter whose travel is `travel`: as placed before
    /// connecting (`--bed-mm`), or now on the travel's bed (600 × 400 mm without one). The
    /// travel is checked by the loop itself.
    pub fn on_machine(&self, args: &JobArgs, travel: Option<&Travel>) -> Result<Placed> {
        match (&self.placed, travel) {
            (Some(placed), _) => Ok(placed.clone()),
            (None, Some(t)) => self.place(args, t.bed_mm(), Some(t)),
            (None, None) => self.place(args, DEFAULT_BED_MM, None),
        }
    }

    /// Place the gauge on a `bed_mm` bed (at `--gauge-at-mm`, or a free spot beside the plan) and
    /// check every move: against `travel` first (when known), then against the bed.
    fn place(&self, args: &JobArgs, bed_mm: [f64; 2], travel: Option<&Travel>) -> Result<Placed> {
        if let Some(t) = travel {
            check_plan_travel(t, self.plan_box_mm, &self.params).map_err(job_error)?;
        }
        let layout = Layout {
            bed_mm,
            plan_box_mm: self.plan_box_mm,
            gauge_extent_mm: self.gauge_extent_mm,
            margin_mm: GAUGE_MARGIN_MM,
        };
        let gauge_at_mm = match args.gauge_at_mm {
            Some(at) => at,
            None => free_spot(&layout)?,
        };
        let placement = self.placement(args, gauge_at_mm);
        let placed = Placed {
            placement,
            gauge_gcode: self.gauge_gcode(gauge_at_mm)?,
        };
        if let Some(t) = travel {
            let request = JobRequest {
                gauge_gcode: &placed.gauge_gcode,
                placement,
                params: self.params,
                plan_box_mm: None,
            };
            check_travel(t, &request).map_err(job_error)?;
        }
        placement.check_layout(&layout).map_err(job_error)?;
        Ok(placed)
    }

    /// The placement the flags give, with the gauge at `gauge_at_mm`.
    fn placement(&self, args: &JobArgs, gauge_at_mm: [f64; 2]) -> Placement {
        Placement {
            gauge_at_mm,
            prong_offset_mm: args.prong_offset_mm,
            insert_z_mm: args.insert_z_mm,
            travel_z_mm: args.travel_z_mm,
            plunge_feed_mm_per_min: args.plunge_feed_mm_per_min,
        }
    }

    /// The gauge's G-code with its spiral centre at `gauge_at_mm`, cut with the job's settings.
    fn gauge_gcode(&self, gauge_at_mm: [f64; 2]) -> Result<String> {
        let settings = self.profile.default.unwrap_or(GAUGE_SETTINGS);
        let provenance = Provenance {
            source: "gauge for kerfmeter job".into(),
            kerf: "none: the gauge measures it".into(),
        };
        let options = GcodeOptions {
            origin_mm: gauge_at_mm,
            ..self.gcode_options
        };
        let (program, _) = gauge_program(&self.drawing, &settings, &options, &provenance)?;
        Ok(program.to_text())
    }

    /// The job's dilated plan (the file's bytes) and G-code at `kerf_um`, which the job
    /// `measured` (else it is `--dry-run-kerf-um`'s, and the G-code's header says so).
    fn dilated(&self, args: &JobArgs, kerf_um: f64, measured: bool) -> Result<(Vec<u8>, String)> {
        let dilation = dilation_args(args, kerf_um);
        let (_, kerf) = dilation.kerf()?;
        let options = dilation.options(true, Default::default())?;
        let (bytes, _) = dilate_file(&args.input, &kerf, &options)?;
        let (format, cuts, _) = dilate_file_cuts(&args.input, &kerf, &options)?;
        let provenance = Provenance {
            source: args.input.display().to_string(),
            kerf: if measured {
                format!("{kerf_um:.1} um, measured by kerfmeter job")
            } else {
                format!("{kerf_um:.1} um, not measured: a dry run")
            },
        };
        let (program, _) = plan_program(
            &cuts,
            format == PlanFormat::Svg,
            &self.profile,
            &self.gcode_options,
            &provenance,
        )
        .map_err(|e| e.in_file(&args.input))?;
        Ok((bytes, program.to_text()))
    }

    /// The loop's dilate stage: dilate, write the plan and the G-code, hand the G-code back.
    /// Each file is named in `written` once it is.
    fn dilate_and_write(
        &self,
        args: &JobArgs,
        kerf_um: f64,
        written: &mut Vec<PathBuf>,
    ) -> Result<String, String> {
        let (bytes, gcode) = self
            .dilated(args, kerf_um, true)
            .map_err(|e| e.to_string())?;
        write_atomically(&args.output, &bytes).map_err(|e| e.to_string())?;
        written.push(args.output.clone());
        write_atomically(&self.gcode_out, gcode.as_bytes()).map_err(|e| e.to_string())?;
        written.push(self.gcode_out.clone());
        Ok(gcode)
    }

    /// Every stage's program, the job's dilated by `--dry-run-kerf-um`.
    fn dry_run(&self, args: &JobArgs) -> Result<DryRunReport> {
        let (_, job) = self.dilated(args, args.dry_run_kerf_um, false)?;
        let placed = self.on_machine(args, None)?;
        let p = &placed.placement;
        let programs = [
            (Stage::CutGauge, placed.gauge_gcode.clone()),
            (Stage::Lower, p.lower_program()),
            // The cut height is read from the cutter when the job begins.
            (
                Stage::Lift,
                p.lift_program()
                    + "(then back to the height the head stood at when the job began: G53 G0 Z<its machine Z>)\n",
            ),
            (Stage::StreamJob, job),
        ];
        Ok(DryRunReport {
            gauge_at_mm: p.gauge_at_mm,
            kerf_um: args.dry_run_kerf_um,
            stages: programs
                .into_iter()
                .map(|(stage, gcode)| StageGcode { stage, gcode })
                .collect(),
        })
    }
}

/// Check the two outputs before anything moves: the dilated plan (`-o`) in the input's format,
/// neither output the input nor each other, both in a directory that exists and takes a new file.
/// The G-code's path is handed back.
fn check_outputs(args: &JobArgs) -> Result<PathBuf> {
    plan_output_format(&args.input, &args.output)?;
    let gcode_out = match &args.gcode_out {
        Some(p) => p.clone(),
        None => args.output.with_extension("gcode"),
    };
    ensure_not_input(&args.input, &gcode_out)?;
    if same_file(&args.output, &gcode_out) {
        return Err(CliError::Usage(format!(
            "the dilated plan (-o) and the job's G-code (--gcode-out) are the same file {}: the \
             G-code would overwrite the plan; give --gcode-out another path (or leave it out: -o \
             with .gcode)",
            gcode_out.display()
        )));
    }
    for output in [&args.output, &gcode_out] {
        kerfmeter_plan::ownership::ensure_replaceable(output, args.force)?;
        ensure_writable(output)?;
    }
    Ok(gcode_out)
}

/// The job's cut settings: the profile, the flags, or the gauge's defaults.
fn job_profile(args: &JobArgs) -> Result<Profile> {
    if args.profile.is_none() && args.cut.settings()?.is_none() {
        return Ok(Profile::uniform(GAUGE_SETTINGS)?);
    }
    args.cut.profile(args.profile.as_deref())
}

/// The `dilate` options from the job's flags, at `kerf_um`.
fn dilation_args(args: &JobArgs, kerf_um: f64) -> DilationArgs {
    DilationArgs {
        kerf_um,
        map: None,
        cut_colors: args.cut_colors.clone(),
        cut_max_width_mm: args.cut_max_width_mm,
        cut_layers: args.cut_layers.clone(),
        units: args.units,
        already_compensated_ok: args.already_compensated_ok,
        recompensate: args.recompensate,
    }
}

/// Read and check the plan (its cuts at kerf 0, as `gcode` would refuse them, and the
/// compensation it records) and give back the bounding box of its cuts as placed on the
/// machine, mm.
fn placed_plan_box(args: &JobArgs, options: &GcodeOptions) -> Result<[[f64; 2]; 2]> {
    // Read as drawn whatever it records (the kerf is not measured yet), then judged by the
    // job's own rule.
    let dilation = DilationArgs {
        already_compensated_ok: true,
        recompensate: false,
        ..dilation_args(args, 0.0)
    };
    let (_, kerf) = dilation.kerf()?;
    let dilate_options = dilation.options(true, Default::default())?;
    let (format, cuts, summary) = dilate_file_cuts(&args.input, &kerf, &dilate_options)?;
    // At kerf 0 a gauge drawing passes and a compensation is only found: refused now, before
    // anything moves, as the dilation by the measured kerf would refuse it after the gauge.
    let policy = dilation_args(args, 0.0).if_compensated();
    check_before_measuring(summary.compensation_found.as_ref(), policy)
        .map_err(|e| e.in_file(&args.input))?;
    let plines = || cuts.iter().map(|c| &c.pline);
    let mapping = Mapping::for_plan(plines(), format == PlanFormat::Svg, options.origin_mm);
    placed_box(plines(), &mapping).ok_or_else(|| {
        PlanError::InvalidArgument("the plan has no closed cut contours: nothing to cut".into())
            .in_file(&args.input)
            .into()
    })
}

/// The gauge's cuts relative to its spiral centre, mm.
fn gauge_extent_mm(drawing: &kerfmeter_plan::gauge::GaugeDrawing) -> Result<[[f64; 2]; 2]> {
    let gauge = gauge_cuts(drawing);
    let centred = Mapping {
        flip_y: false,
        offset_mm: [-drawing.center.x, -drawing.center.y],
    };
    placed_box(gauge.iter().map(|(_, p)| p), &centred)
        .ok_or_else(|| CliError::Usage("the gauge drawing has no cuts".into()))
}

/// A free spot on the bed for the gauge, beside the plan's cuts (as placed).
fn free_spot(layout: &Layout) -> Result<[f64; 2]> {
    layout.check_plan_on_bed().map_err(job_error)?;
    let gauge_box = layout.gauge_extent_mm;
    let plan_box = layout.plan_box_mm;
    free_spot_mm(plan_box, gauge_box, layout.bed_mm, layout.margin_mm).ok_or_else(|| {
        CliError::Usage(format!(
            "no room for the gauge ({:.0} × {:.0} mm) on the {} × {} mm bed beside the plan, which fills ({:.1}, {:.1})–({:.1}, {:.1}) mm: give --gauge-at-mm X,Y, or --bed-mm W,H if the bed is larger",
            gauge_box[1][0] - gauge_box[0][0],
            gauge_box[1][1] - gauge_box[0][1],
            layout.bed_mm[0],
            layout.bed_mm[1],
            plan_box[0][0],
            plan_box[0][1],
            plan_box[1][0],
            plan_box[1][1]
        ))
    })
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
