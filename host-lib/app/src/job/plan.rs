//! The job's plan: its outputs checked before anything moves, its cut settings, its cuts read at
//! kerf 0 (checked, and boxed as placed on the machine), and its dilation by the measured kerf
//! into the dilated plan's bytes and the job's G-code.

use std::path::{Path, PathBuf};

use kerfmeter::files::{ensure_not_input, ensure_writable, same_file};
use kerfmeter_plan::compensation::{IfCompensated, check_before_measuring};
use kerfmeter_plan::gcode::{GcodeOptions, Mapping, Provenance, placed_box, plan_program};
use kerfmeter_plan::profile::{CutSettings, Profile};
use kerfmeter_plan::{PlanError, PlanFormat, dilate_file, dilate_file_cuts};

use super::{JobFiles, JobRequest, JobSetupError};
use crate::dilate::{Dilation, plan_output_format};
use crate::gauge::GAUGE_SETTINGS;
use crate::gcode::CutFlags;

type Result<T, E = JobSetupError> = std::result::Result<T, E>;

/// Check the two outputs before anything moves: the dilated plan in the input's format, neither
/// output the input nor each other, both in a directory that exists and takes a new file. The
/// G-code's path is handed back.
pub(super) fn check_outputs(files: &JobFiles) -> Result<PathBuf> {
    plan_output_format(&files.input, &files.output)?;
    let gcode_out = match &files.gcode_out {
        Some(p) => p.clone(),
        None => files.output.with_extension("gcode"),
    };
    ensure_not_input(&files.input, &gcode_out)?;
    if same_file(&files.output, &gcode_out) {
        return Err(JobSetupError::Invalid(format!(
            "the dilated plan (-o) and the job's G-code (--gcode-out) are the same file {}: the \
             G-code would overwrite the plan; give --gcode-out another path (or leave it out: -o \
             with .gcode)",
            gcode_out.display()
        )));
    }
    for output in [&files.output, &gcode_out] {
        kerfmeter_plan::ownership::ensure_replaceable(output, files.force)?;
        ensure_writable(output)?;
    }
    Ok(gcode_out)
}

/// The cut settings the request gives, if any; both the feed and the power are needed.
pub fn cut_settings(r: &JobRequest) -> Result<Option<CutSettings>, PlanError> {
    CutFlags {
        feed_mm_per_min: r.feed_mm_per_min,
        power_percent: r.power_percent,
        passes: r.passes,
    }
    .settings()
}

/// The job's cut settings: the profile (with the request's settings as its default), the
/// request's settings, or the gauge's first try ([`GAUGE_SETTINGS`]: the gauge is cut with the
/// job's default settings when it has some).
pub(super) fn job_profile(r: &JobRequest, file: Option<&Path>) -> Result<Profile> {
    let settings = cut_settings(r)?;
    Ok(match (file, settings) {
        (Some(path), settings) => {
            let mut profile = Profile::load(path)?;
            if settings.is_some() {
                profile.default = settings;
            }
            profile
        }
        (None, Some(s)) => Profile::uniform(s)?,
        (None, None) => Profile::uniform(GAUGE_SETTINGS)?,
    })
}

/// Read and check the plan (its cuts at kerf 0, as `gcode` would refuse them, and the
/// compensation it records) and give back the bounding box of its cuts as placed on the
/// machine, mm.
pub(super) fn placed_plan_box(
    r: &JobRequest,
    input: &Path,
    options: &GcodeOptions,
) -> Result<[[f64; 2]; 2]> {
    // Read as drawn whatever it records (the kerf is not measured yet), then judged by the
    // job's own rule.
    let dilation = Dilation {
        if_compensated: IfCompensated::DilateAnyway,
        ..r.dilation(0.0)
    };
    let (_, kerf) = dilation.kerf()?;
    let dilate_options = dilation.options(true, Default::default())?;
    let (format, cuts, summary) = dilate_file_cuts(input, &kerf, &dilate_options)?;
    // At kerf 0 a gauge drawing passes and a compensation is only found: refused now, before
    // anything moves, as the dilation by the measured kerf would refuse it after the gauge.
    check_before_measuring(summary.compensation_found.as_ref(), r.if_compensated())
        .map_err(|e| e.in_file(input))?;
    let plines = || cuts.iter().map(|c| &c.pline);
    let mapping = Mapping::for_plan(plines(), format == PlanFormat::Svg, options.origin_mm);
    placed_box(plines(), &mapping).ok_or_else(|| {
        PlanError::InvalidArgument("the plan has no closed cut contours: nothing to cut".into())
            .in_file(input)
            .into()
    })
}

/// The plan at `input` dilated by `kerf_um` (the file's bytes) and its G-code with `profile`
/// and `options`; the kerf was `measured` (else it is a dry run's, and the G-code's header says
/// so).
pub(super) fn dilated(
    r: &JobRequest,
    input: &Path,
    (profile, options): (&Profile, &GcodeOptions),
    kerf_um: f64,
    measured: bool,
) -> Result<(Vec<u8>, String)> {
    let dilation = r.dilation(kerf_um);
    let (_, kerf) = dilation.kerf()?;
    let dilate_options = dilation.options(true, Default::default())?;
    let (bytes, _) = dilate_file(input, &kerf, &dilate_options)?;
    let (format, cuts, _) = dilate_file_cuts(input, &kerf, &dilate_options)?;
    let provenance = Provenance {
        source: input.display().to_string(),
        kerf: if measured {
            format!("{kerf_um:.1} um, measured by kerfmeter job")
        } else {
            format!("{kerf_um:.1} um, not measured: a dry run")
        },
    };
    let (program, _) = plan_program(
        &cuts,
        format == PlanFormat::Svg,
        profile,
        options,
        &provenance,
    )
    .map_err(|e| e.in_file(input))?;
    Ok((bytes, program.to_text()))
}
