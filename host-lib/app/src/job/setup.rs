//! A job made ready before anything moves ([`JobSetup`]): the plan read and checked, the gauge
//! drawn, and, once the bed is known, the gauge placed with its G-code and every planned move
//! checked (against the machine's travel first, then the bed). Then the loop's dilate stage and
//! a dry run's programs.

use std::path::PathBuf;

use kerfmeter::JointSpec;
use kerfmeter::files::write_atomically;
use kerfmeter::grbl::travel::Travel;
use kerfmeter::job::{
    JobRequest as LoopRequest, Layout, Placement, Stage, check_plan_travel, check_travel,
    free_spot_mm,
};
use kerfmeter::protocol::{GaugeGeometry, RunParams};
use kerfmeter_plan::gauge::{GaugeDrawing, GaugeOptions, build};
use kerfmeter_plan::gcode::{
    GcodeOptions, Mapping, Provenance, gauge_cuts, gauge_program, placed_box,
};
use kerfmeter_plan::profile::Profile;

use super::plan::{check_outputs, dilated, job_profile, placed_plan_box};
use super::{DryRunReport, JobFiles, JobRequest, JobSetupError, StageGcode};
use crate::gauge::GAUGE_SETTINGS;

type Result<T, E = JobSetupError> = std::result::Result<T, E>;

/// Space kept between the plan and the gauge, mm.
pub const GAUGE_MARGIN_MM: f64 = 5.0;
/// The bed when neither the request nor the controller gives one, mm.
pub const DEFAULT_BED_MM: [f64; 2] = [600.0, 400.0];

/// What the loop needs, made from the request and its files before anything moves.
#[derive(Debug)]
pub struct JobSetup {
    request: JobRequest,
    files: JobFiles,
    /// Where the gauge goes and its G-code, when the bed was known before connecting (the
    /// request's `bed_mm`, or a dry run); else placed once the cutter reports its travel.
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
#[derive(Debug, Clone)]
pub struct Placed {
    /// The gauge's place and the prongs' moves.
    pub placement: Placement,
    /// The gauge's program.
    pub gauge_gcode: String,
}

impl JobSetup {
    /// Check the request, the outputs and the plan (read at kerf 0) before anything moves; when
    /// the bed is known (`bed_mm`, or a `dry_run`, on the default bed), place the gauge and
    /// write its G-code.
    pub fn new(request: JobRequest, files: JobFiles, dry_run: bool) -> Result<JobSetup> {
        request.check().map_err(JobSetupError::Invalid)?;
        let gcode_out = check_outputs(&files)?;
        let profile = job_profile(&request, files.profile.as_deref())?;
        let gcode_options = GcodeOptions {
            s_max: request.s_max,
            origin_mm: request.origin_mm,
        };
        gcode_options.check()?;
        let params = JointSpec {
            thickness_mm: request.thickness_mm,
            force_n: request.force_n,
            ..JointSpec::default()
        }
        .run_params(GaugeGeometry::PAPER)?;
        let drawing = build(&GaugeGeometry::PAPER, &GaugeOptions::default())?;
        let mut setup = JobSetup {
            placed: None,
            plan_box_mm: placed_plan_box(&request, &files.input, &gcode_options)?,
            gauge_extent_mm: gauge_extent_mm(&drawing)?,
            drawing,
            params,
            gcode_out,
            profile,
            gcode_options,
            request,
            files,
        };
        // The numbers and the Z order, wherever the gauge goes.
        let at = setup.request.gauge_at_mm.unwrap_or_default();
        setup.placement(at).check()?;
        let bed_now = setup.request.bed_mm.or(dry_run.then_some(DEFAULT_BED_MM));
        if let Some(bed_mm) = bed_now {
            setup.placed = Some(setup.place(bed_mm, None)?);
        }
        Ok(setup)
    }

    /// The request.
    pub fn request(&self) -> &JobRequest {
        &self.request
    }

    /// The files.
    pub fn files(&self) -> &JobFiles {
        &self.files
    }

    /// The job's G-code file (as given, or the output's with `.gcode`).
    pub fn gcode_out(&self) -> &PathBuf {
        &self.gcode_out
    }

    /// The device's run parameters for the request's joint.
    pub fn params(&self) -> RunParams {
        self.params
    }

    /// Where the job goes on the connected cutter whose travel is `travel`: as placed before
    /// connecting (`bed_mm`), or now on the travel's bed (600 × 400 mm without one). The travel
    /// is checked by the loop itself.
    pub fn on_machine(&self, travel: Option<&Travel>) -> Result<Placed> {
        match (&self.placed, travel) {
            (Some(placed), _) => Ok(placed.clone()),
            (None, Some(t)) => self.place(t.bed_mm(), Some(t)),
            (None, None) => self.place(DEFAULT_BED_MM, None),
        }
    }

    /// What the loop is asked to do with the gauge `placed`.
    pub fn loop_request<'a>(&self, placed: &'a Placed) -> LoopRequest<'a> {
        LoopRequest {
            gauge_gcode: &placed.gauge_gcode,
            placement: placed.placement,
            params: self.params,
            plan_box_mm: Some(self.plan_box_mm),
        }
    }

    /// Place the gauge on a `bed_mm` bed (at `gauge_at_mm`, or a free spot beside the plan) and
    /// check every move: against `travel` first (when known), then against the bed.
    fn place(&self, bed_mm: [f64; 2], travel: Option<&Travel>) -> Result<Placed> {
        if let Some(t) = travel {
            check_plan_travel(t, self.plan_box_mm, &self.params)?;
        }
        let layout = Layout {
            bed_mm,
            plan_box_mm: self.plan_box_mm,
            gauge_extent_mm: self.gauge_extent_mm,
            margin_mm: GAUGE_MARGIN_MM,
        };
        let gauge_at_mm = match self.request.gauge_at_mm {
            Some(at) => at,
            None => free_spot(&layout)?,
        };
        let placement = self.placement(gauge_at_mm);
        let placed = Placed {
            placement,
            gauge_gcode: self.gauge_gcode(gauge_at_mm)?,
        };
        if let Some(t) = travel {
            let request = LoopRequest {
                plan_box_mm: None,
                ..self.loop_request(&placed)
            };
            check_travel(t, &request)?;
        }
        placement.check_layout(&layout)?;
        Ok(placed)
    }

    /// The placement the request gives, with the gauge at `gauge_at_mm`.
    fn placement(&self, gauge_at_mm: [f64; 2]) -> Placement {
        let r = &self.request;
        Placement {
            gauge_at_mm,
            prong_offset_mm: r.prong_offset_mm,
            insert_z_mm: r.insert_z_mm,
            travel_z_mm: r.travel_z_mm,
            plunge_feed_mm_per_min: r.plunge_feed_mm_per_min,
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

    /// The job's dilated plan (the file's bytes) and G-code at `kerf_um`.
    fn dilated(&self, kerf_um: f64, measured: bool) -> Result<(Vec<u8>, String)> {
        let how = (&self.profile, &self.gcode_options);
        dilated(&self.request, &self.files.input, how, kerf_um, measured)
    }

    /// The loop's dilate stage: dilate by the measured `kerf_um`, write the plan and the
    /// G-code, hand the G-code back. Each file is named in `written` once it is.
    pub fn dilate_and_write(
        &self,
        kerf_um: f64,
        written: &mut Vec<PathBuf>,
    ) -> Result<String, String> {
        let (bytes, gcode) = self.dilated(kerf_um, true).map_err(|e| e.to_string())?;
        let output = &self.files.output;
        write_atomically(output, &bytes).map_err(|e| e.to_string())?;
        written.push(output.clone());
        write_atomically(&self.gcode_out, gcode.as_bytes()).map_err(|e| e.to_string())?;
        written.push(self.gcode_out.clone());
        Ok(gcode)
    }

    /// Every stage's program, moving nothing; the job's dilated by `kerf_um`.
    pub fn dry_run(&self, kerf_um: f64) -> Result<DryRunReport> {
        let (_, job) = self.dilated(kerf_um, false)?;
        let placed = self.on_machine(None)?;
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
            kerf_um,
            stages: programs
                .into_iter()
                .map(|(stage, gcode)| StageGcode { stage, gcode })
                .collect(),
        })
    }
}

/// The gauge's cuts relative to its spiral centre, mm.
fn gauge_extent_mm(drawing: &GaugeDrawing) -> Result<[[f64; 2]; 2]> {
    let gauge = gauge_cuts(drawing);
    let centred = Mapping {
        flip_y: false,
        offset_mm: [-drawing.center.x, -drawing.center.y],
    };
    placed_box(gauge.iter().map(|(_, p)| p), &centred)
        .ok_or_else(|| JobSetupError::Invalid("the gauge drawing has no cuts".into()))
}

/// A free spot on the bed for the gauge, beside the plan's cuts (as placed).
fn free_spot(layout: &Layout) -> Result<[f64; 2]> {
    layout.check_plan_on_bed()?;
    let gauge_box = layout.gauge_extent_mm;
    let plan_box = layout.plan_box_mm;
    free_spot_mm(plan_box, gauge_box, layout.bed_mm, layout.margin_mm).ok_or_else(|| {
        JobSetupError::Invalid(format!(
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
