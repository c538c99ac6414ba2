//! `kerfmeter gcode`: dilate a plan by the kerf (the `dilate` command's options and checks) and
//! write it as G-code for a GRBL 1.1 laser, with cut settings per colour or layer from a profile
//! or the same for every cut from flags. The program is `kerfmeter_plan::gcode`'s (its module doc
//! says what is written and assumed); this module turns the arguments into its options and writes
//! the file atomically, never over the input. The cut-setting flags and the `X,Y` placement are
//! shared with `kerfmeter gauge`.

use std::path::PathBuf;

pub use kerfmeter_app::gcode::GcodeReport;
use kerfmeter_app::gcode::{CutFlags, GcodeRequest, write_gcode};
use kerfmeter_plan::gcode::DEFAULT_S_MAX;
use kerfmeter_plan::profile::CutSettings;

use super::dilate::DilationArgs;
use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::progress::plan_progress;

type Result<T, E = CliError> = std::result::Result<T, E>;

pub use kerfmeter_app::gcode::{GCODE_EXTENSIONS, is_gcode};

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
    /// The settings these flags give.
    pub fn flags(&self) -> CutFlags {
        CutFlags {
            feed_mm_per_min: self.feed_mm_per_min,
            power_percent: self.power_percent,
            passes: self.passes,
        }
    }

    /// The settings the flags give, if any; both the feed and the power are needed.
    pub fn settings(&self) -> Result<Option<CutSettings>> {
        Ok(self.flags().settings()?)
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

/// Dilate the plan named by `args` and write its G-code (see [`GcodeArgs`]), with a progress
/// bar on a terminal.
pub fn run(g: &Global, args: &GcodeArgs) -> Result<GcodeReport> {
    let request = GcodeRequest {
        input: args.input.clone(),
        output: args.output.clone(),
        force: args.force,
        dilation: args.dilation.dilation(),
        profile: args.profile.clone(),
        cut: args.cut.flags(),
        s_max: args.cut.s_max,
        origin_mm: args.origin_mm,
    };
    let (progress, bar) = plan_progress(g.json);
    let written = write_gcode(&request, progress);
    bar.finish_and_clear();
    Ok(written?)
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
        assert!(flags(None, None, None).flags().profile(None).is_err());
        assert!(
            flags(Some(600.0), Some(180.0), None)
                .flags()
                .profile(None)
                .is_err()
        );
    }
}
