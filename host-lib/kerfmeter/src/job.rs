//! The paper's automatic loop, driven from the host: cut the gauge beside the job, wait for the
//! motion to end, move the prongs over the gauge and lower them (Z), measure, lift, dilate the
//! plan by the kerf measured and stream the job ([`run_job`]).
//!
//! # Design
//!
//! - The cutter is the GRBL driver ([`Cutter`]): every program here is streamed with its
//!   character counting and its stop on every failure. The device is the [`Kerfmeter`] client.
//! - The plan is the caller's: [`run_job`] gets the gauge's G-code and a `dilate` function that
//!   turns the measured kerf into the job's G-code (the command-line tool's uses the plan crate's
//!   dilation and G-code writer), so this crate stays free of SVG/DXF code.
//! - Each stage is timed ([`StageTime`]) and reported to a progress callback ([`JobEvent`]).
//! - Safety: a measurement that fails or is flagged (any quality flag but `decimated`) stops
//!   before the job: the device's run is aborted (motor safe), the prongs lifted and the cutter
//!   stopped ([`Cutter::stop`]: feed hold, soft reset, laser off). The `cancel` flag is watched in
//!   every stage: a stream stops the cutter itself, a device run is aborted, and the cutter is
//!   stopped. The laser is never on during the Z and XY moves of the prongs: they are `G0`
//!   travels and a `G1` Z plunge after `M5` with `S0`.
//! - The prongs' axis is at `prong_offset_mm` from the nozzle: the head goes to the gauge's
//!   centre minus the offset ([`Placement::head_over_gauge_mm`]). Where the head ended (the
//!   controller's reported position) plus the offset is where the prongs landed, which the
//!   simulated device is told ([`SimLink`]).
//! - The gauge and the plan are cut at one height: where the head stood when the job began (the
//!   user's focus, [`CutHeight`]). The gauge programs and the plan's make no Z move; after the
//!   prongs are lifted to the travel height the head goes back down to that height (`G53` when the
//!   controller reports its machine position), so the plan is cut as the gauge was, in focus. A
//!   stop in the stages that lower, hold or lift the prongs moves nothing: its error says the
//!   prongs may still be down ([`Stage::prongs_note`]).
//! - A gauge position can be chosen on a free spot of the bed beside the plan ([`free_spot_mm`]).
//! - Before anything moves, [`Placement::check_layout`] checks every move the job plans: the
//!   plan and the gauge on the bed, the gauge a margin clear of the plan, the head's move over
//!   the gauge on the bed, and the insert Z below the travel Z (Z grows upward: the prongs plunge
//!   down). [`run_job`] checks the numbers again ([`Placement::check`]); it knows no bed.
//! - Also before anything moves, [`run_job`] checks them against the machine's travel when the
//!   controller reports one ([`check_travel`]: the gauge, the prong offset, the Z heights and the
//!   plan as placed, each refused with its flag, [`JobError::Travel`]).

use std::fmt;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use kerfmeter_protocol::{KerfResult, QualityFlags, RunParams};
use serde::Serialize;

use crate::client::Kerfmeter;
use crate::error::Error;
use crate::grbl::protocol::Status;
use crate::grbl::{Cutter, CutterError, StreamProgress};
use crate::{Category, Progress};

mod travel;

pub use travel::{check_plan_travel, check_travel};

/// The loop's stages, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Stream the gauge's G-code.
    CutGauge,
    /// Wait until the controller reports the motion finished.
    WaitMotion,
    /// Move the prongs over the gauge and lower them into its holes.
    Lower,
    /// Run the device.
    Measure,
    /// Lift the prongs clear.
    Lift,
    /// Dilate the plan by the kerf measured and write its G-code.
    Dilate,
    /// Stream the job.
    StreamJob,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 7] = [
        Stage::CutGauge,
        Stage::WaitMotion,
        Stage::Lower,
        Stage::Measure,
        Stage::Lift,
        Stage::Dilate,
        Stage::StreamJob,
    ];

    /// Its name in JSON and messages.
    pub fn name(self) -> &'static str {
        match self {
            Stage::CutGauge => "cut-gauge",
            Stage::WaitMotion => "wait-motion",
            Stage::Lower => "lower",
            Stage::Measure => "measure",
            Stage::Lift => "lift",
            Stage::Dilate => "dilate",
            Stage::StreamJob => "stream-job",
        }
    }

    /// What it does, for a progress display.
    pub fn describe(self) -> &'static str {
        match self {
            Stage::CutGauge => "cutting the gauge",
            Stage::WaitMotion => "waiting for the motion to end",
            Stage::Lower => "lowering the prongs into the gauge",
            Stage::Measure => "measuring the kerf",
            Stage::Lift => "lifting the prongs",
            Stage::Dilate => "dilating the plan",
            Stage::StreamJob => "cutting the job",
        }
    }

    /// What to do before the head moves again when the loop stopped in this stage: in the
    /// stages that lower, hold and lift the prongs they may still be down in the gauge (a stop
    /// moves nothing, not even Z). Empty for the other stages.
    pub fn prongs_note(self) -> &'static str {
        match self {
            Stage::Lower | Stage::Measure | Stage::Lift => {
                ". The prongs may still be down in the gauge: lift them (jog Z up to the travel height) before anything moves the head"
            }
            _ => "",
        }
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Where the gauge is cut and how the prongs reach it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Placement {
    /// The gauge's spiral centre on the bed, mm.
    pub gauge_at_mm: [f64; 2],
    /// The prongs' axis relative to the laser nozzle, mm.
    pub prong_offset_mm: [f64; 2],
    /// Z that puts the prongs into the gauge's holes, mm (machine coordinates).
    pub insert_z_mm: f64,
    /// Z that keeps the prongs clear of the work, mm.
    pub travel_z_mm: f64,
    /// Feed of the plunge to `insert_z_mm`, mm/min.
    pub plunge_feed_mm_per_min: f64,
}

/// Largest coordinate accepted, mm (as the plan crate's G-code writer).
const MAX_COORDINATE_MM: f64 = 100_000.0;

impl Placement {
    /// Where the head goes so that the prongs stand over the gauge's centre, mm.
    pub fn head_over_gauge_mm(&self) -> [f64; 2] {
        [
            self.gauge_at_mm[0] - self.prong_offset_mm[0],
            self.gauge_at_mm[1] - self.prong_offset_mm[1],
        ]
    }

    /// Check the numbers: finite, on a plausible machine, a positive plunge feed.
    pub fn check(&self) -> Result<(), JobError> {
        let coordinates = [
            self.gauge_at_mm[0],
            self.gauge_at_mm[1],
            self.prong_offset_mm[0],
            self.prong_offset_mm[1],
            self.insert_z_mm,
            self.travel_z_mm,
        ];
        if !coordinates
            .iter()
            .all(|x| x.is_finite() && x.abs() < MAX_COORDINATE_MM)
        {
            return Err(JobError::Invalid(format!(
                "the gauge position, prong offset and Z heights must be finite mm within ±100000, got {self:?}"
            )));
        }
        let feed = self.plunge_feed_mm_per_min;
        if !(feed.is_finite() && feed > 0.0 && feed <= 100_000.0) {
            return Err(JobError::Invalid(format!(
                "the plunge feed must be above 0 and at most 100000 mm/min, got {feed}"
            )));
        }
        if self.insert_z_mm >= self.travel_z_mm {
            return Err(JobError::Invalid(format!(
                "the insert Z (--insert-z-mm {}) must be below the travel Z (--travel-z-mm {}): Z \
                 grows upward, and the prongs plunge from the travel height down into the gauge; \
                 give a lower --insert-z-mm (e.g. -6) or a higher --travel-z-mm",
                self.insert_z_mm, self.travel_z_mm
            )));
        }
        Ok(())
    }

    /// [`check`](Self::check) the numbers, then every move the job plans against `layout`: the
    /// plan and the gauge on the bed, the gauge (with the margin) clear of the plan, and the
    /// head's move that puts the prongs over the gauge on the bed. The one check of where the
    /// job's moves go, made before anything moves.
    pub fn check_layout(&self, layout: &Layout) -> Result<(), JobError> {
        self.check()?;
        layout.check_plan_on_bed()?;
        let bed = layout.bed_box_mm();
        let [bw, bh] = layout.bed_mm;
        let plan = layout.plan_box_mm;
        let gauge = placed(layout.gauge_extent_mm, self.gauge_at_mm);
        let [gx, gy] = self.gauge_at_mm;
        if !contains(bed, gauge) {
            return Err(JobError::Invalid(format!(
                "the gauge at ({gx:.1}, {gy:.1}) mm would be cut over {}, off the {bw} × {bh} mm \
                 bed {}: give a --gauge-at-mm X,Y that keeps it on the bed (or leave it out for a \
                 free spot beside the plan), or --bed-mm W,H if the bed is larger",
                show_box(gauge),
                show_box(bed)
            )));
        }
        let margin = layout.margin_mm;
        if overlap(grown(gauge, margin), plan) {
            return Err(JobError::Invalid(format!(
                "the gauge at ({gx:.1}, {gy:.1}) mm would be cut over {}, within {margin} mm of \
                 the plan, which fills {}: the gauge would cut into the job. Give a --gauge-at-mm \
                 X,Y clear of the plan, or leave it out for a free spot beside the plan",
                show_box(gauge),
                show_box(plan)
            )));
        }
        let [hx, hy] = self.head_over_gauge_mm();
        if !contains(bed, [[hx, hy], [hx, hy]]) {
            let [dx, dy] = self.prong_offset_mm;
            return Err(JobError::Invalid(format!(
                "to put the prongs over the gauge at ({gx:.1}, {gy:.1}) mm the head would move to \
                 X{hx:.1} Y{hy:.1}, off the {bw} × {bh} mm bed {}: check --prong-offset-mm \
                 ({dx}, {dy} mm: the prongs' axis relative to the nozzle, a few tens of mm; see \
                 docs/cutters.md to calibrate it), or move the gauge with --gauge-at-mm",
                show_box(bed)
            )));
        }
        Ok(())
    }

    /// The program that lifts to the travel height, moves the prongs over the gauge and lowers
    /// them (laser off throughout).
    pub fn lower_program(&self) -> String {
        let [x, y] = self.head_over_gauge_mm();
        format!(
            "G21 G90\nM5 S0\nG0 Z{:.4}\nG0 X{x:.4} Y{y:.4}\nG1 Z{:.4} F{:.1}\n",
            self.travel_z_mm, self.insert_z_mm, self.plunge_feed_mm_per_min
        )
    }

    /// The program that lifts the prongs clear (laser off).
    pub fn lift_program(&self) -> String {
        format!("G21 G90\nM5 S0\nG0 Z{:.4}\n", self.travel_z_mm)
    }
}

/// The height the job cuts at: where the head stood when the job began (the user's focus), in
/// the coordinates the controller reports it in. The gauge is cut there, and the head comes back
/// to it once the prongs are lifted, so that the plan is cut as the gauge was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CutHeight {
    /// Machine Z, mm (`MPos`): gone back to with `G53`, whatever the work offset.
    Machine(f64),
    /// Work Z, mm (`WPos`, a controller set to report it): gone back to in work coordinates.
    Work(f64),
}

impl CutHeight {
    /// The height in `status`, when it reports a position.
    pub fn of(status: &Status) -> Option<Self> {
        let machine = status.position_mm.map(|p| Self::Machine(p[2]));
        machine.or(status.work_position_mm.map(|p| Self::Work(p[2])))
    }

    /// The program that takes the head back to it, straight down or up (laser off).
    pub fn return_program(self) -> String {
        match self {
            Self::Machine(z) => format!("G21 G90\nM5 S0\nG53 G0 Z{z:.4}\n"),
            Self::Work(z) => format!("G21 G90\nM5 S0\nG0 Z{z:.4}\n"),
        }
    }
}

/// Where the job's moves must stay, for [`Placement::check_layout`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    /// The bed's size, mm, from the machine origin (0, 0).
    pub bed_mm: [f64; 2],
    /// The plan's cuts as placed on the machine, `[[min_x, min_y], [max_x, max_y]]`, mm (as
    /// drawn: the dilation grows them by half the kerf, well within `margin_mm`).
    pub plan_box_mm: [[f64; 2]; 2],
    /// The gauge's cuts relative to its spiral centre, `[[min_x, min_y], [max_x, max_y]]`, mm.
    pub gauge_extent_mm: [[f64; 2]; 2],
    /// Space kept between the gauge's cuts and the plan's, mm.
    pub margin_mm: f64,
}

impl Layout {
    /// The bed as a box, mm.
    fn bed_box_mm(&self) -> [[f64; 2]; 2] {
        [[0.0, 0.0], self.bed_mm]
    }

    /// The plan as placed lies on the bed (checked first: a plan off the bed leaves no room
    /// for the gauge either, and that is not what to fix).
    pub fn check_plan_on_bed(&self) -> Result<(), JobError> {
        let (bed, plan) = (self.bed_box_mm(), self.plan_box_mm);
        let [bw, bh] = self.bed_mm;
        if contains(bed, plan) {
            return Ok(());
        }
        Err(JobError::Invalid(format!(
            "the plan as placed fills {}, beyond the {bw} × {bh} mm bed {}: move it with \
             --origin-mm X,Y, or give the bed's size with --bed-mm W,H if it is larger",
            show_box(plan),
            show_box(bed)
        )))
    }
}

/// Rounding allowed when a box is compared with another, mm.
const TOLERANCE_MM: f64 = 1e-6;

/// `extent` (relative to a centre) with its centre at `at`.
fn placed(extent: [[f64; 2]; 2], at: [f64; 2]) -> [[f64; 2]; 2] {
    let [[x0, y0], [x1, y1]] = extent;
    [[at[0] + x0, at[1] + y0], [at[0] + x1, at[1] + y1]]
}

/// `b` grown by `by` on every side.
fn grown(b: [[f64; 2]; 2], by: f64) -> [[f64; 2]; 2] {
    [[b[0][0] - by, b[0][1] - by], [b[1][0] + by, b[1][1] + by]]
}

/// True when `inner` lies within `outer`.
fn contains(outer: [[f64; 2]; 2], inner: [[f64; 2]; 2]) -> bool {
    let outer = grown(outer, TOLERANCE_MM);
    (0..2).all(|i| inner[0][i] >= outer[0][i] && inner[1][i] <= outer[1][i])
}

/// True when `a` and `b` share more than their edges.
fn overlap(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> bool {
    let a = grown(a, -TOLERANCE_MM);
    (0..2).all(|i| a[0][i] < b[1][i] && b[0][i] < a[1][i])
}

/// A box as `(x0, y0)–(x1, y1) mm`.
fn show_box(b: [[f64; 2]; 2]) -> String {
    format!(
        "({:.1}, {:.1})–({:.1}, {:.1}) mm",
        b[0][0], b[0][1], b[1][0], b[1][1]
    )
}

/// A free spot on a bed of `bed_mm` (from 0,0) for a gauge whose cuts reach `gauge_extent_mm`
/// (`[[min_x, min_y], [max_x, max_y]]`, relative to its centre) beside a plan whose cuts fill
/// `plan_box_mm` on the machine, `margin_mm` apart: to the right of the plan, above, left or
/// below, in that order, aligned with the plan's lower-left corner. `None` when none fits.
pub fn free_spot_mm(
    plan_box_mm: [[f64; 2]; 2],
    gauge_extent_mm: [[f64; 2]; 2],
    bed_mm: [f64; 2],
    margin_mm: f64,
) -> Option<[f64; 2]> {
    let [[px0, py0], [px1, py1]] = plan_box_mm;
    let [[gx0, gy0], [gx1, gy1]] = gauge_extent_mm;
    let candidates = [
        [px1 + margin_mm - gx0, py0 - gy0],
        [px0 - gx0, py1 + margin_mm - gy0],
        [px0 - margin_mm - gx1, py0 - gy0],
        [px0 - gx0, py0 - margin_mm - gy1],
    ];
    let bed = [[0.0, 0.0], bed_mm];
    candidates
        .into_iter()
        .find(|c| contains(bed, placed(gauge_extent_mm, *c)))
}

/// What the loop reports as it goes.
#[derive(Debug)]
pub enum JobEvent<'a> {
    /// A stage began.
    Started(Stage),
    /// A stream of the stage went on.
    Cutter(Stage, &'a StreamProgress),
    /// The device run went on.
    Device(&'a Progress),
    /// A stage ended, after `elapsed`.
    Finished(Stage, Duration),
}

/// How long a stage took.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StageTime {
    /// The stage.
    pub stage: Stage,
    /// Its wall-clock time, s.
    pub elapsed_s: f64,
}

/// What the loop did.
#[derive(Debug, Clone, Serialize)]
pub struct JobReport {
    /// The measurement.
    pub kerf: KerfResult,
    /// Each stage's time, in order.
    pub stages: Vec<StageTime>,
    /// The job's G-code as streamed.
    #[serde(skip)]
    pub job_gcode: String,
    /// Lines of the job streamed.
    pub job_lines: usize,
    /// Where the prongs came down, mm (the head's reported position plus the prong offset).
    pub landing_mm: [f64; 2],
}

/// Why the loop stopped. Every error is returned with the cutter stopped (laser off) and any
/// device run aborted, unless it says otherwise.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// A setting is out of range.
    #[error("{0}")]
    Invalid(String),
    /// Something the job moves over lies outside the machine's travel; nothing was sent.
    #[error("{0}")]
    Travel(String),
    /// The cutter failed (it stopped itself, or says it could not).
    #[error("{stage} ({}): {source}{}", stage.describe(), stage.prongs_note())]
    Cutter {
        /// The stage.
        stage: Stage,
        /// The driver's error.
        source: CutterError,
    },
    /// The device failed or refused.
    #[error("{stage} ({}): {source}; the job was not cut and the laser is off", stage.describe())]
    Device {
        /// The stage.
        stage: Stage,
        /// The client's error.
        source: Error,
    },
    /// The motion did not end as it should.
    #[error("{0}; the laser is off")]
    Motion(String),
    /// The measurement carries a reason to distrust it.
    #[error(
        "the measurement ({kerf_um:.1} µm) was flagged {flags}: the job was not cut and the laser is off; check the gauge and the prongs, then run the job again"
    )]
    Flagged {
        /// The kerf read, µm.
        kerf_um: f32,
        /// The flags' names.
        flags: String,
    },
    /// The plan could not be dilated or written as G-code.
    #[error("dilating the plan by {kerf_um:.1} µm failed: {reason}; the job was not cut")]
    Dilate {
        /// The kerf measured, µm.
        kerf_um: f32,
        /// Why.
        reason: String,
    },
    /// The cancel flag was set.
    #[error(
        "cancelled while {}: the cutter was stopped (laser off) and the device run aborted{}",
        stage.describe(),
        stage.prongs_note()
    )]
    Cancelled {
        /// The stage it was in.
        stage: Stage,
    },
    /// Stopping the cutter after an error failed too.
    #[error(
        "THE LASER MAY STILL BE ON: switch it off at the machine now. {cause}; then stopping the \
         cutter failed ({stop})"
    )]
    NotStopped {
        /// The first error.
        cause: Box<JobError>,
        /// The stop's error.
        stop: CutterError,
    },
}

impl JobError {
    /// What kind of failure this is (the command-line tool's exit code follows from it).
    pub fn category(&self) -> Category {
        match self {
            JobError::Invalid(_) => Category::Usage,
            JobError::Cutter { source, .. } => source.category(),
            JobError::Device { source, .. } => source.category(),
            JobError::Flagged { .. }
            | JobError::Cancelled { .. }
            | JobError::Motion(_)
            | JobError::Travel(_) => Category::Device,
            JobError::Dilate { .. } => Category::File,
            JobError::NotStopped { cause, .. } => cause.category(),
        }
    }

    /// True when the cutter could not be stopped after a failure: its laser may still be on (the
    /// command-line tool gives this its own exit code, as for [`CutterError::laser_may_be_on`]).
    pub fn laser_may_be_on(&self) -> bool {
        match self {
            JobError::NotStopped { .. } => true,
            JobError::Cutter { source, .. } => source.laser_may_be_on(),
            _ => false,
        }
    }
}

/// The quality flags that stop the job: those that distrust the number (all but the advisory
/// `decimated` and `play-modelled`, [`QualityFlags::ADVISORY`]).
pub fn stopping_flags(flags: QualityFlags) -> QualityFlags {
    flags.distrusting()
}

/// The simulated device behind `--sim`, told where the prongs landed on the gauge the simulated
/// cutter traced.
#[cfg(feature = "sim")]
pub struct SimLink<'a> {
    /// The device twin.
    pub device: &'a crate::sim::SimDevice,
    /// The cutter twin's kerf model (`None`: the device twin's own).
    pub kerf: Option<kerfmeter_twin::plant::CutterKerf>,
}

/// The machines the loop drives.
pub struct Devices<'a> {
    /// The laser cutter.
    pub cutter: &'a mut Cutter,
    /// The Kerfmeter.
    pub meter: &'a mut Kerfmeter,
    /// With `--sim`: the device twin, which must measure the gauge the cutter twin cut.
    #[cfg(feature = "sim")]
    pub sim: Option<SimLink<'a>>,
}

/// What to cut and measure.
#[derive(Debug, Clone, Copy)]
pub struct JobRequest<'a> {
    /// The gauge's G-code, with its spiral centre at `placement.gauge_at_mm`.
    pub gauge_gcode: &'a str,
    /// Where the gauge is and how the prongs reach it.
    pub placement: Placement,
    /// The device run's parameters.
    pub params: RunParams,
    /// The plan's cuts as placed on the machine (as drawn), `[[min_x, min_y], [max_x, max_y]]`,
    /// mm: checked against the machine's travel before anything moves (`None`: only the job's
    /// own G-code is, by the driver, once it is dilated).
    pub plan_box_mm: Option<[[f64; 2]; 2]>,
}

/// The job's G-code for the kerf measured (µm), or why it cannot be made.
pub type Dilate<'a> = dyn FnMut(f64) -> Result<String, String> + 'a;

/// Run the loop (see the [module docs](self)). `progress` hears of every stage.
pub fn run_job(
    devices: Devices<'_>,
    request: &JobRequest<'_>,
    dilate: &mut Dilate<'_>,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(JobEvent<'_>),
) -> Result<JobReport, JobError> {
    request.placement.check()?;
    crate::params::check(&request.params).map_err(|e| JobError::Invalid(e.to_string()))?;
    if let Some(travel) = devices.cutter.travel() {
        check_travel(&travel, request)?;
    }
    let mut run = Loop {
        devices,
        request,
        cancel,
        progress,
        stages: Vec::new(),
        sent_to_cutter: false,
    };
    let result = run.all(dilate);
    result.map_err(|e| run.make_safe(e))
}

/// The loop's state while it runs.
struct Loop<'a, 'r> {
    devices: Devices<'a>,
    request: &'r JobRequest<'r>,
    cancel: &'r AtomicBool,
    progress: &'r mut dyn FnMut(JobEvent<'_>),
    stages: Vec<StageTime>,
    /// Whether a program was given to the cutter yet: before, the laser was not this job's to
    /// switch on (see [`unless_nothing_sent`]).
    sent_to_cutter: bool,
}

impl Loop<'_, '_> {
    fn all(&mut self, dilate: &mut Dilate<'_>) -> Result<JobReport, JobError> {
        // Ctrl-C while the cutter connected: nothing moves, not even the device's reset.
        self.check_cancel(Stage::CutGauge)?;
        let cut_height = self.cut_height()?;
        self.devices
            .meter
            .prepare_for_run()
            .map_err(|source| JobError::Device {
                stage: Stage::CutGauge,
                source,
            })?;
        let gauge = self.request.gauge_gcode;
        self.timed(Stage::CutGauge, |l| l.stream(Stage::CutGauge, gauge))?;
        self.timed(Stage::WaitMotion, Self::wait_idle)?;
        let lower = self.request.placement.lower_program();
        let at = self.timed(Stage::Lower, |l| l.stream(Stage::Lower, &lower))?;
        let landing_mm = self.landing_mm(at);
        let kerf = self.timed(Stage::Measure, |l| l.measure(landing_mm))?;
        let lift = self.request.placement.lift_program() + &cut_height.return_program();
        self.timed(Stage::Lift, |l| l.stream(Stage::Lift, &lift))?;
        let kerf_um = kerf.kerf_um;
        let job_gcode = self.timed(Stage::Dilate, |_| {
            dilate(f64::from(kerf_um)).map_err(|reason| JobError::Dilate { kerf_um, reason })
        })?;
        self.check_cancel(Stage::StreamJob)?;
        let report = self.timed(Stage::StreamJob, |l| {
            l.stream_report(Stage::StreamJob, &job_gcode)
        })?;
        Ok(JobReport {
            kerf,
            stages: std::mem::take(&mut self.stages),
            job_gcode,
            job_lines: report.lines,
            landing_mm,
        })
    }

    /// Run `stage`, timing it and telling the progress callback.
    fn timed<T>(
        &mut self,
        stage: Stage,
        body: impl FnOnce(&mut Self) -> Result<T, JobError>,
    ) -> Result<T, JobError> {
        self.check_cancel(stage)?;
        (self.progress)(JobEvent::Started(stage));
        let start = Instant::now();
        let out = body(self)?;
        let elapsed = start.elapsed();
        self.stages.push(StageTime {
            stage,
            elapsed_s: elapsed.as_secs_f64(),
        });
        (self.progress)(JobEvent::Finished(stage, elapsed));
        Ok(out)
    }

    fn check_cancel(&self, stage: Stage) -> Result<(), JobError> {
        if self.cancel.load(Ordering::Relaxed) {
            return Err(JobError::Cancelled { stage });
        }
        Ok(())
    }

    /// Stream `program`; the head's position at the end, when reported.
    fn stream(&mut self, stage: Stage, program: &str) -> Result<Option<[f64; 3]>, JobError> {
        Ok(self.stream_report(stage, program)?.position_mm)
    }

    /// Stream `program` in `stage`, noting whether the cutter was given it; the stream's report.
    fn stream_report(
        &mut self,
        stage: Stage,
        program: &str,
    ) -> Result<crate::grbl::StreamReport, JobError> {
        let progress = &mut *self.progress;
        let streamed = self.devices.cutter.stream(program, self.cancel, &mut |p| {
            progress(JobEvent::Cutter(stage, p))
        });
        self.note_sent(&streamed);
        streamed.map_err(|e| cutter_error(stage, e))
    }

    /// Whether a stream's outcome means the cutter was given the program: it was unless the
    /// stream refused it before sending a line (no stop tried then).
    fn note_sent<T>(&mut self, streamed: &Result<T, CutterError>) {
        self.sent_to_cutter |= streamed
            .as_ref()
            .map_or_else(CutterError::stop_was_tried, |_| true);
    }

    /// Where the head stands before anything moves: the height the gauge and the plan are cut at.
    fn cut_height(&mut self) -> Result<CutHeight, JobError> {
        let status = self.devices.cutter.status();
        let status = status.map_err(|e| cutter_error(Stage::CutGauge, e))?;
        CutHeight::of(&status).ok_or_else(|| {
            JobError::Motion(
                "the cutter reports no position (neither MPos nor WPos), so the plan could not be cut at the height the gauge is cut at; nothing was cut".into(),
            )
        })
    }

    /// Poll the controller until it reports Idle (a stream already waits for it; this checks it
    /// again, and is where a controller that reports motion late is waited for).
    fn wait_idle(&mut self) -> Result<(), JobError> {
        use crate::grbl::protocol::MachineState;
        let deadline = Instant::now() + Duration::from_secs(600);
        loop {
            self.check_cancel(Stage::WaitMotion)?;
            let status = self
                .devices
                .cutter
                .status()
                .map_err(|e| cutter_error(Stage::WaitMotion, e))?;
            match status.state {
                MachineState::Idle => return Ok(()),
                MachineState::Alarm => {
                    return Err(JobError::Motion(
                        "the cutter went into alarm after the gauge was cut".into(),
                    ));
                }
                _ if Instant::now() > deadline => {
                    return Err(JobError::Motion(format!(
                        "the cutter was still {} 10 minutes after the gauge was streamed",
                        status.state
                    )));
                }
                _ => std::thread::sleep(Duration::from_millis(50)),
            }
        }
    }

    /// Where the prongs came down: the head's reported position plus the offset, or the gauge's
    /// centre when the controller does not report its machine position.
    fn landing_mm(&self, head: Option<[f64; 3]>) -> [f64; 2] {
        let p = &self.request.placement;
        match head {
            Some([x, y, _]) => [x + p.prong_offset_mm[0], y + p.prong_offset_mm[1]],
            None => p.gauge_at_mm,
        }
    }

    /// Run the device on the gauge under the prongs; a failed, flagged or cancelled run lifts
    /// the prongs (unless cancelled) before the error goes up.
    fn measure(&mut self, landing_mm: [f64; 2]) -> Result<KerfResult, JobError> {
        let result = self
            .place_sim_gauge(landing_mm)
            .and_then(|()| self.device_run());
        if let Err(e) = &result {
            let _ = self.devices.meter.abort();
            if !matches!(e, JobError::Cancelled { .. }) {
                // A failed lift has stopped the cutter itself; the first error is the one to tell.
                let lift = self.request.placement.lift_program();
                let _ = self.stream(Stage::Lift, &lift);
            }
        }
        result
    }

    fn device_run(&mut self) -> Result<KerfResult, JobError> {
        let progress = &mut *self.progress;
        let cancel = self.cancel;
        let run = self
            .devices
            .meter
            .run_kerfmeter_until(&self.request.params, |p| {
                progress(JobEvent::Device(p));
                if cancel.load(Ordering::Relaxed) {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            });
        let stage = Stage::Measure;
        let kerf = match run {
            Ok(kerf) => kerf,
            Err(Error::Cancelled) => return Err(JobError::Cancelled { stage }),
            Err(source) => return Err(JobError::Device { stage, source }),
        };
        let flags = stopping_flags(kerf.flags);
        if !flags.is_empty() {
            return Err(JobError::Flagged {
                kerf_um: kerf.kerf_um,
                flags: flags.names().collect::<Vec<_>>().join(", "),
            });
        }
        Ok(kerf)
    }

    /// With `--sim`: the gauge the cutter twin traced goes under the device twin's prongs.
    #[cfg(feature = "sim")]
    fn place_sim_gauge(&mut self, landing_mm: [f64; 2]) -> Result<(), JobError> {
        let Some(link) = &self.devices.sim else {
            return Ok(());
        };
        let Some(log) = self.devices.cutter.sim_log() else {
            return Err(JobError::Invalid(
                "the simulated device measures only a gauge the simulated cutter cut".into(),
            ));
        };
        let segments = log.snapshot().segments;
        link.device
            .place_traced_gauge(&segments, landing_mm, link.kerf)
            .map(|_| ())
            .map_err(|source| JobError::Device {
                stage: Stage::Measure,
                source,
            })
    }

    #[cfg(not(feature = "sim"))]
    fn place_sim_gauge(&mut self, _landing_mm: [f64; 2]) -> Result<(), JobError> {
        Ok(())
    }

    /// Stop the cutter after `e` (the laser off), unless a stream already tried to. A cutter's
    /// own failure is stopped as a stream's is, and tells how that went (a reset that found the
    /// head moving, an alarm that hears only a reset).
    fn make_safe(&mut self, e: JobError) -> JobError {
        let _ = self.devices.meter.abort();
        if stream_stopped(&e) {
            return e;
        }
        let sent = self.sent_to_cutter;
        match e {
            JobError::Cutter { stage, source } => JobError::Cutter {
                stage,
                source: unless_nothing_sent(self.devices.cutter.stop_after(source), sent),
            },
            e => match self.devices.cutter.stop() {
                Err(stop) if sent => JobError::NotStopped {
                    cause: Box::new(e),
                    stop,
                },
                _ => e,
            },
        }
    }
}

/// Whether `e` is a stream's failure after which the stream tried to stop the cutter itself.
fn stream_stopped(e: &JobError) -> bool {
    matches!(e, JobError::Cutter { source, .. } if source.stop_was_tried())
}

/// A cutter's failure after the stop that followed it, as the user is told it: before the job
/// sent the cutter a program (`sent`) it had only asked its state, so a stop that failed (the
/// port gone) is no sign of a laser this job switched on, and the failure is told as it was.
fn unless_nothing_sent(after_stop: CutterError, sent: bool) -> CutterError {
    match after_stop {
        CutterError::NotStopped { cause, .. } if !sent => *cause,
        after_stop => after_stop,
    }
}

/// A stream's error in `stage`; a cancelled stream is the loop's cancel, unless its stop left
/// more to say (the laser may be on, or the reset found the head moving: home it).
fn cutter_error(stage: Stage, e: CutterError) -> JobError {
    let plain_stop = matches!(
        e,
        CutterError::Stopped {
            position_lost: false,
            ..
        }
    );
    match e.cause() {
        CutterError::Cancelled { .. } if plain_stop => JobError::Cancelled { stage },
        _ => JobError::Cutter { stage, source: e },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAUGE: [[f64; 2]; 2] = [[-30.0, -30.0], [30.0, 30.0]];

    #[test]
    fn a_failed_status_read_is_stopped_and_a_stop_that_fails_before_any_program_alarms_no_one() {
        let lost = || CutterError::Io {
            address: "grbl:/dev/ttyUSB0".into(),
            source: std::io::Error::other("the port vanished"),
        };
        let read_failed = JobError::Cutter {
            stage: Stage::WaitMotion,
            source: lost(),
        };
        assert!(!stream_stopped(&read_failed));
        let stream_failed = JobError::Cutter {
            stage: Stage::StreamJob,
            source: CutterError::Stopped {
                cause: Box::new(lost()),
                position_lost: false,
            },
        };
        assert!(stream_stopped(&stream_failed));
        let not_stopped = || CutterError::NotStopped {
            cause: Box::new(lost()),
            stop: Box::new(lost()),
        };
        assert!(unless_nothing_sent(not_stopped(), true).laser_may_be_on());
        let before_any = unless_nothing_sent(not_stopped(), false);
        assert!(!before_any.laser_may_be_on());
        assert!(
            before_any.to_string().contains("the port vanished"),
            "{before_any}"
        );
    }

    #[test]
    fn the_gauge_goes_beside_the_plan_where_the_bed_has_room() {
        let bed = [400.0, 300.0];
        // Room on the right.
        let at = free_spot_mm([[0.0, 0.0], [100.0, 80.0]], GAUGE, bed, 5.0).unwrap();
        assert_eq!(at, [135.0, 30.0]);
        // A plan as wide as the bed: above it.
        let at = free_spot_mm([[0.0, 0.0], [400.0, 80.0]], GAUGE, bed, 5.0).unwrap();
        assert_eq!(at, [30.0, 115.0]);
        // No room anywhere.
        assert!(free_spot_mm([[0.0, 0.0], [390.0, 290.0]], GAUGE, bed, 5.0).is_none());
    }

    #[test]
    fn the_prong_moves_never_fire_the_laser_and_put_the_prongs_over_the_gauge() {
        let p = Placement {
            gauge_at_mm: [100.0, 50.0],
            prong_offset_mm: [30.0, -5.0],
            insert_z_mm: -2.0,
            travel_z_mm: 10.0,
            plunge_feed_mm_per_min: 300.0,
        };
        assert_eq!(p.head_over_gauge_mm(), [70.0, 55.0]);
        let lower = p.lower_program();
        assert!(lower.contains("M5 S0\nG0 Z10.0000\nG0 X70.0000 Y55.0000\nG1 Z-2.0000"));
        assert!(!lower.contains("M3") && !lower.contains("M4"));
        assert!(p.lift_program().ends_with("M5 S0\nG0 Z10.0000\n"));
        let bad = Placement {
            insert_z_mm: f64::NAN,
            ..p
        };
        assert!(bad.check().is_err());
    }

    fn layout() -> Layout {
        Layout {
            bed_mm: [600.0, 400.0],
            plan_box_mm: [[0.0, 0.0], [96.0, 96.0]],
            gauge_extent_mm: GAUGE,
            margin_mm: 5.0,
        }
    }

    fn at(gauge_at_mm: [f64; 2], prong_offset_mm: [f64; 2]) -> Placement {
        Placement {
            gauge_at_mm,
            prong_offset_mm,
            insert_z_mm: -2.0,
            travel_z_mm: 10.0,
            plunge_feed_mm_per_min: 300.0,
        }
    }

    fn refusal(p: Placement, layout: &Layout) -> String {
        p.check_layout(layout).unwrap_err().to_string()
    }

    #[test]
    fn the_gauge_beside_the_plan_on_the_bed_is_accepted() {
        let l = layout();
        let spot = free_spot_mm(l.plan_box_mm, GAUGE, l.bed_mm, l.margin_mm).unwrap();
        assert_eq!(spot, [131.0, 30.0]);
        at(spot, [20.0, -5.0]).check_layout(&l).unwrap();
        at([300.0, 200.0], [0.0, 0.0]).check_layout(&l).unwrap();
    }

    #[test]
    fn a_gauge_over_or_beside_the_plan_within_the_margin_is_refused() {
        let l = layout();
        let over = refusal(at([30.0, 30.0], [0.0, 0.0]), &l);
        assert!(over.contains("within 5 mm of the plan"), "{over}");
        assert!(over.contains("--gauge-at-mm"), "{over}");
        // 4 mm right of the plan: inside the margin.
        assert!(at([130.0, 30.0], [0.0, 0.0]).check_layout(&l).is_err());
    }

    #[test]
    fn a_gauge_the_plan_or_the_head_off_the_bed_is_refused() {
        let l = layout();
        for gauge_at in [[-500.0, 30.0], [5000.0, 30.0], [300.0, 390.0]] {
            let off = refusal(at(gauge_at, [0.0, 0.0]), &l);
            assert!(off.contains("off the 600 × 400 mm bed"), "{off}");
        }
        let head = refusal(at([131.0, 30.0], [1000.0, 1000.0]), &l);
        assert!(head.contains("X-869.0 Y-970.0"), "{head}");
        assert!(head.contains("--prong-offset-mm"), "{head}");
        let plan = Layout {
            plan_box_mm: [[500.0, 0.0], [700.0, 96.0]],
            ..l
        };
        let off = refusal(at([300.0, 200.0], [0.0, 0.0]), &plan);
        assert!(off.contains("--origin-mm"), "{off}");
    }

    #[test]
    fn an_insert_z_not_below_the_travel_z_is_refused() {
        let p = at([300.0, 200.0], [0.0, 0.0]);
        for insert_z_mm in [50.0, 10.0] {
            let up = Placement { insert_z_mm, ..p };
            let e = up.check().unwrap_err().to_string();
            assert!(e.contains("must be below the travel Z"), "{e}");
            assert!(up.check_layout(&layout()).is_err());
        }
    }

    #[test]
    fn only_decimation_lets_a_flagged_measurement_through() {
        assert!(stopping_flags(QualityFlags::DECIMATED).is_empty());
        let mut f = QualityFlags::DECIMATED;
        f.insert(QualityFlags::NOISY_HOLD);
        assert_eq!(stopping_flags(f), QualityFlags::NOISY_HOLD);
    }
}
