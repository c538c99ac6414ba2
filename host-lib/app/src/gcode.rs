//! A plan dilated into G-code for a GRBL 1.1 laser (`kerfmeter gcode`): the dilation's options
//! ([`Dilation`]), cut settings per colour or layer from a profile or the same for every cut
//! ([`CutFlags`]), the program written atomically, never over the input, and its report
//! ([`GcodeReport`]).

use std::fmt;
use std::path::{Path, PathBuf};

use kerfmeter::files::{ensure_not_input, write_atomically};
use kerfmeter::protocol::advice::Advice;
use kerfmeter_plan::gcode::{GcodeOptions, Mapping, ProgramStats, Provenance, plan_program};
use kerfmeter_plan::outcome::PlanSummary;
use kerfmeter_plan::profile::{CutSettings, Profile};
use kerfmeter_plan::progress::Progress;
use kerfmeter_plan::{PlanError, PlanFormat, dilate_file_cuts};
use serde::Serialize;

use crate::Error;
use crate::dilate::{Dilation, plural, write_compensation};

/// Extensions of G-code files.
pub const GCODE_EXTENSIONS: [&str; 4] = ["gcode", "nc", "ngc", "gc"];

/// Whether `path` names a G-code file (by its extension).
pub fn is_gcode(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| GCODE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Cut settings given for every cut (or those a profile does not name).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CutFlags {
    /// Feed while cutting, mm/min.
    pub feed_mm_per_min: Option<f64>,
    /// Laser power, percent of full power.
    pub power_percent: Option<f64>,
    /// How many times each contour is cut (default 1).
    pub passes: Option<u32>,
}

impl CutFlags {
    /// The settings given, if any; both the feed and the power are needed.
    pub fn settings(&self) -> Result<Option<CutSettings>, PlanError> {
        match (self.feed_mm_per_min, self.power_percent) {
            (None, None) if self.passes.is_none() => Ok(None),
            (Some(feed_mm_per_min), Some(power_percent)) => {
                let s = CutSettings {
                    feed_mm_per_min,
                    power_percent,
                    passes: self.passes.unwrap_or(1),
                };
                s.check("the cut settings")?;
                Ok(Some(s))
            }
            _ => Err(PlanError::InvalidArgument(format!(
                "give both {} and {} (and {} if more than one)",
                Advice::Param("feed_mm_per_min"),
                Advice::Param("power_percent"),
                Advice::Param("passes")
            ))),
        }
    }

    /// The profile: `file`'s, with these settings as its default; or these alone.
    pub fn profile(&self, file: Option<&Path>) -> Result<Profile, PlanError> {
        let given = self.settings()?;
        match (file, given) {
            (Some(path), given) => {
                let mut profile = Profile::load(path)?;
                if given.is_some() {
                    profile.default = given;
                }
                Ok(profile)
            }
            (None, Some(s)) => Profile::uniform(s),
            (None, None) => Err(PlanError::InvalidArgument(format!(
                "say how to cut: {} FILE.toml, or {} and {}",
                Advice::Param("profile"),
                Advice::Param("feed_mm_per_min"),
                Advice::Param("power_percent")
            ))),
        }
    }
}

/// Dilate the plan `input` and write it as G-code to `output`.
#[derive(Debug, Clone)]
pub struct GcodeRequest {
    /// The plan: an .svg or .dxf file.
    pub input: PathBuf,
    /// The G-code file (.gcode, .nc, .ngc or .gc).
    pub output: PathBuf,
    /// Replace the output even if kerfmeter did not write it.
    pub force: bool,
    /// The kerf, the cut rules and what to do with a compensated plan.
    pub dilation: Dilation,
    /// Cut settings by colour or layer (TOML).
    pub profile: Option<PathBuf>,
    /// Cut settings for every contour (or those the profile does not name).
    pub cut: CutFlags,
    /// The S value of full power: GRBL's $30.
    pub s_max: f64,
    /// Where the lower-left corner of the cuts' bounding box goes on the machine, mm.
    pub origin_mm: [f64; 2],
}

/// What `gcode` wrote.
#[derive(Debug, Clone, Serialize)]
pub struct GcodeReport {
    /// The plan read.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub input: PathBuf,
    /// The G-code written.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub output: PathBuf,
    /// The plan's format (in JSON: the summary's `format`, not written twice).
    #[serde(skip)]
    pub format: PlanFormat,
    /// The kerf given, µm (with a map: at the reference cell).
    pub kerf_um: f64,
    /// The kerf map used.
    #[serde(serialize_with = "crate::lossy_path::option")]
    pub map: Option<PathBuf>,
    /// The cut settings.
    pub profile: Profile,
    /// The S of full power ($30).
    pub s_max: f64,
    /// Plan mm → machine mm.
    pub mapping: Mapping,
    /// What the program cuts and travels.
    pub program: ProgramStats,
    /// Profile entries that chose no contour's settings (see `Profile::unused`).
    pub unused_profile_entries: Vec<String>,
    /// What the dilation found and did.
    #[serde(flatten)]
    pub summary: PlanSummary,
}

impl fmt::Display for GcodeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = &self.program;
        writeln!(
            f,
            "wrote {} from {} ({}) dilated by {} µm: {} contour{} in {} part{}, {:.1} mm cut, {:.1} mm travel",
            self.output.display(),
            self.input.display(),
            self.format,
            self.kerf_um,
            p.contours,
            plural(p.contours),
            self.summary.parts,
            plural(self.summary.parts),
            p.cut_mm,
            p.travel_mm
        )?;
        writeln!(f, "  settings: {}", self.profile.describe())?;
        let [x, y] = self.mapping.offset_mm;
        writeln!(
            f,
            "  machine = plan{} + ({x:.4}, {y:.4}) mm; needs GRBL $32=1 (laser mode), $30={}",
            if self.mapping.flip_y {
                " with y flipped"
            } else {
                ""
            },
            self.s_max
        )?;
        write_compensation(f, &self.summary)?;
        for (reason, n) in &self.summary.passed_through {
            writeln!(f, "  not cut: {n} × {reason}")?;
        }
        for entry in &self.unused_profile_entries {
            writeln!(
                f,
                "  warning: the profile's {entry} sets no contour: misspelt, a layer entry takes its contours, or the cut rules leave that colour out ({})",
                Advice::Param("cut_color")
            )?;
        }
        for n in &self.summary.notes {
            writeln!(f, "  note: {n}")?;
        }
        Ok(())
    }
}

/// Dilate the plan `req` names and write its G-code, reporting to `progress`.
pub fn write_gcode(req: &GcodeRequest, progress: Progress) -> Result<GcodeReport, Error> {
    PlanFormat::of(&req.input)?;
    if !is_gcode(&req.output) {
        return Err(PlanError::InvalidArgument(format!(
            "{}: the G-code file's name must end in .gcode, .nc, .ngc or .gc",
            req.output.display()
        ))
        .into());
    }
    ensure_not_input(&req.input, &req.output)?;
    kerfmeter_plan::ownership::ensure_replaceable(&req.output, req.force)?;
    let profile = req.cut.profile(req.profile.as_deref())?;
    let options = GcodeOptions {
        s_max: req.s_max,
        origin_mm: req.origin_mm,
    };
    options.check()?;
    let (kerf_um, kerf) = req.dilation.kerf()?;
    let dilate_options = req.dilation.options(true, progress)?;
    let (format, cuts, summary) = dilate_file_cuts(&req.input, &kerf, &dilate_options)?;
    let provenance = Provenance {
        source: req.input.display().to_string(),
        kerf: match &req.dilation.map {
            None => format!("{kerf_um} um"),
            Some(_) => format!("{kerf_um} um at the map's reference, per part"),
        },
    };
    let (program, mapping) = plan_program(
        &cuts,
        format == PlanFormat::Svg,
        &profile,
        &options,
        &provenance,
    )
    .map_err(|e| e.in_file(&req.input))?;
    write_atomically(&req.output, program.to_text().as_bytes())?;
    let unused_profile_entries = profile.unused(&cuts);
    Ok(GcodeReport {
        input: req.input.clone(),
        output: req.output.clone(),
        format,
        kerf_um,
        map: req.dilation.map.clone(),
        profile,
        s_max: options.s_max,
        mapping,
        program: program.stats(),
        unused_profile_entries,
        summary,
    })
}
