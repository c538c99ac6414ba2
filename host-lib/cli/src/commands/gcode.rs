//! `kerfmeter gcode`: dilate a plan by the kerf (the `dilate` command's options and checks) and
//! write it as G-code for a GRBL 1.1 laser, with cut settings per colour or layer from a profile
//! or the same for every cut from flags. The program is `kerfmeter_plan::gcode`'s (its module doc
//! says what is written and assumed); this module turns the arguments into its options and writes
//! the file atomically, never over the input. The cut-setting flags and the `X,Y` placement are
//! shared with `kerfmeter gauge`.

use std::fmt;
use std::path::{Path, PathBuf};

use kerfmeter::files::{ensure_not_input, write_atomically};
use kerfmeter_plan::gcode::{
    DEFAULT_S_MAX, GcodeOptions, Mapping, ProgramStats, Provenance, plan_program,
};
use kerfmeter_plan::outcome::PlanSummary;
use kerfmeter_plan::profile::{CutSettings, Profile};
use kerfmeter_plan::{PlanError, PlanFormat, dilate_file_cuts};
use serde::Serialize;

use super::dilate::{DilationArgs, plural, write_compensation};
use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::progress::plan_progress;

type Result<T, E = CliError> = std::result::Result<T, E>;

/// Extensions of G-code files.
pub const GCODE_EXTENSIONS: [&str; 4] = ["gcode", "nc", "ngc", "gc"];

/// Whether `path` names a G-code file (by its extension).
pub fn is_gcode(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| GCODE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// `X,Y` in mm.
pub fn parse_xy(text: &str) -> std::result::Result<[f64; 2], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [x, y] = parts[..] else {
        return Err(format!(
            "`{text}` is not X,Y (two numbers in mm, e.g. 10,20)"
        ));
    };
    let num = |s: &str| {
        s.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not a number of mm"))
    };
    Ok([num(x)?, num(y)?])
}

/// The cut settings given as flags, and the controller's full-power `S`.
#[derive(Debug, Clone, clap::Args)]
pub struct CutArgs {
    /// Feed while cutting, mm/min (with --profile: for the contours it does not name).
    #[arg(long)]
    pub feed_mm_per_min: Option<f64>,
    /// Laser power, percent of full power (with --profile: for the contours it does not name).
    #[arg(long)]
    pub power_percent: Option<f64>,
    /// How many times each contour is cut [default: 1].
    #[arg(long)]
    pub passes: Option<u32>,
    /// The S value of full power: GRBL's $30.
    #[arg(long, default_value_t = DEFAULT_S_MAX)]
    pub s_max: f64,
}

impl CutArgs {
    /// The settings the flags give, if any; both the feed and the power are needed.
    pub fn settings(&self) -> Result<Option<CutSettings>> {
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
            _ => Err(PlanError::InvalidArgument(
                "give both --feed-mm-per-min and --power-percent (and --passes if more than one)"
                    .into(),
            )
            .into()),
        }
    }

    /// The profile: the file's, with the flags' settings as its default; or the flags' alone.
    pub fn profile(&self, file: Option<&Path>) -> Result<Profile> {
        let flags = self.settings()?;
        match (file, flags) {
            (Some(path), flags) => {
                let mut profile = Profile::load(path)?;
                if flags.is_some() {
                    profile.default = flags;
                }
                Ok(profile)
            }
            (None, Some(s)) => Ok(Profile::uniform(s)?),
            (None, None) => Err(PlanError::InvalidArgument(
                "say how to cut: --profile FILE.toml, or --feed-mm-per-min and --power-percent"
                    .into(),
            )
            .into()),
        }
    }
}

/// `kerfmeter gcode`: dilate a plan and write it as G-code.
#[derive(Debug, Clone, clap::Args)]
pub struct GcodeArgs {
    /// The plan: an .svg or .dxf file.
    #[arg(value_name = "PLAN")]
    pub input: PathBuf,
    /// Output G-code file (.gcode, .nc, .ngc or .gc).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Replace the output even if it exists and kerfmeter did not write it (by default only
    /// kerfmeter's own outputs are replaced: a typo must not replace a cutting plan).
    #[arg(long)]
    pub force: bool,
    /// The kerf, the cut rules and what to do with a compensated plan (as for `dilate`).
    #[command(flatten)]
    pub dilation: DilationArgs,
    /// Cut settings by colour or layer (TOML; see docs/plans.md, G-code).
    #[arg(long, value_name = "PROFILE.toml")]
    pub profile: Option<PathBuf>,
    /// Cut settings for every contour (or those the profile does not name).
    #[command(flatten)]
    pub cut: CutArgs,
    /// Where the lower-left corner of the cuts' bounding box goes on the machine, mm.
    #[arg(long, value_name = "X,Y", allow_hyphen_values = true, value_parser = parse_xy, default_value = "0,0")]
    pub origin_mm: [f64; 2],
}

/// What `gcode` wrote.
#[derive(Debug, Clone, Serialize)]
pub struct GcodeReport {
    /// The plan read.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub input: PathBuf,
    /// The G-code written.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub output: PathBuf,
    /// The plan's format (in JSON: the summary's `format`, not written twice).
    #[serde(skip)]
    pub format: PlanFormat,
    /// The kerf given, µm (with a map: at the reference cell).
    pub kerf_um: f64,
    /// The kerf map used.
    #[serde(serialize_with = "crate::output::lossy_path::option")]
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
                "  warning: the profile's {entry} sets no contour: misspelt, a layer entry takes its contours, or the cut rules leave that colour out (--cut-color)"
            )?;
        }
        for n in &self.summary.notes {
            writeln!(f, "  note: {n}")?;
        }
        Ok(())
    }
}

/// Dilate the plan named by `args` and write its G-code (see [`GcodeArgs`]).
pub fn run(g: &Global, args: &GcodeArgs) -> Result<GcodeReport> {
    PlanFormat::of(&args.input)?;
    if !is_gcode(&args.output) {
        return Err(PlanError::InvalidArgument(format!(
            "{}: the G-code file's name must end in .gcode, .nc, .ngc or .gc",
            args.output.display()
        ))
        .into());
    }
    ensure_not_input(&args.input, &args.output)?;
    kerfmeter_plan::ownership::ensure_replaceable(&args.output, args.force)?;
    let profile = args.cut.profile(args.profile.as_deref())?;
    let options = GcodeOptions {
        s_max: args.cut.s_max,
        origin_mm: args.origin_mm,
    };
    options.check()?;
    let (kerf_um, kerf) = args.dilation.kerf()?;
    let (progress, bar) = plan_progress(g.json);
    let dilate_options = args.dilation.options(true, progress)?;
    let read = dilate_file_cuts(&args.input, &kerf, &dilate_options);
    bar.finish_and_clear();
    let (format, cuts, summary) = read?;
    let provenance = Provenance {
        source: args.input.display().to_string(),
        kerf: match &args.dilation.map {
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
    .map_err(|e| e.in_file(&args.input))?;
    write_atomically(&args.output, program.to_text().as_bytes())?;
    let unused_profile_entries = profile.unused(&cuts);
    Ok(GcodeReport {
        input: args.input.clone(),
        output: args.output.clone(),
        format,
        kerf_um,
        map: args.dilation.map.clone(),
        profile,
        s_max: options.s_max,
        mapping,
        program: program.stats(),
        unused_profile_entries,
        summary,
    })
}

impl Report for GcodeReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placements_are_two_finite_numbers() {
        assert_eq!(parse_xy("10,20"), Ok([10.0, 20.0]));
        assert_eq!(parse_xy(" -5.5 , 3 "), Ok([-5.5, 3.0]));
        for bad in ["1", "1,2,3", "a,b", "inf,0", ""] {
            assert!(parse_xy(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn the_cut_flags_need_both_feed_and_power() {
        let flags = |feed, power, passes| CutArgs {
            feed_mm_per_min: feed,
            power_percent: power,
            passes,
            s_max: DEFAULT_S_MAX,
        };
        assert!(flags(None, None, None).settings().unwrap().is_none());
        assert!(flags(Some(600.0), None, None).settings().is_err());
        assert!(flags(None, None, Some(2)).settings().is_err());
        let s = flags(Some(600.0), Some(80.0), None)
            .settings()
            .unwrap()
            .unwrap();
        assert_eq!(s.passes, 1);
        assert!(flags(None, None, None).profile(None).is_err());
        assert!(flags(Some(600.0), Some(180.0), None).profile(None).is_err());
    }
}
