//! Dilating a plan: the options that `dilate`, `gcode` and a job share ([`Dilation`]), a plan
//! file dilated into a file ([`DilateFileRequest`], whose [`DilateReport`] the CLI prints and
//! Python returns), and a plan sent as text dilated into text ([`DilateTextRequest`], the
//! server's `dilate`).

mod file;
mod report;
mod text;

use std::path::PathBuf;
use std::sync::Arc;

use kerfmeter::map::KerfMap;
use kerfmeter_plan::DilateOptions;
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::outcome::AssumedUnits;
use kerfmeter_plan::progress::Progress;
use kerfmeter_plan::rules::CutRules;

pub use file::{DilateFileRequest, dilate_file, plan_output_format};
pub use report::{DilateReport, plural, write_compensation};
pub use text::{DilateTextAnswer, DilateTextRequest, KerfGiven, dilate_text, plan_bytes};

use crate::Error;

/// The widest stroke (SVG) or lineweight (DXF) that is still a cut line by default, mm.
pub const DEFAULT_CUT_MAX_WIDTH_MM: f64 = 0.3;

/// How to dilate a plan: the kerf, the cut rules, and what to do with a plan that is already
/// compensated.
#[derive(Debug, Clone, PartialEq)]
pub struct Dilation {
    /// Kerf (full cut width), µm; every cut moves by half of it. With a map: the kerf measured at
    /// the map's reference cell.
    pub kerf_um: f64,
    /// Kerf map (JSON from `kerfmeter map`): each part uses the kerf at its centroid.
    pub map: Option<PathBuf>,
    /// Colours that mean "cut" (empty: red, blue, black).
    pub cut_colors: Vec<String>,
    /// Widest stroke or lineweight that is still a cut line, mm.
    pub cut_max_width_mm: f64,
    /// DXF: the entities on these layers are the cuts (instead of the colour rules).
    pub cut_layers: Vec<String>,
    /// What one drawing unit is, for files that do not say.
    pub units: Option<AssumedUnits>,
    /// What to do with a plan that says it is already compensated.
    pub if_compensated: IfCompensated,
}

impl Dilation {
    /// A dilation by `kerf_um` with the default rules.
    pub fn by(kerf_um: f64) -> Self {
        Self {
            kerf_um,
            map: None,
            cut_colors: Vec::new(),
            cut_max_width_mm: DEFAULT_CUT_MAX_WIDTH_MM,
            cut_layers: Vec::new(),
            units: None,
            if_compensated: IfCompensated::Refuse,
        }
    }

    /// The kerf, checked: uniform, or from the kerf map.
    pub fn kerf(&self) -> Result<(f64, KerfSource), Error> {
        let kerf_um = KerfSource::check_kerf_um(self.kerf_um)?;
        let kerf = match &self.map {
            None => KerfSource::Uniform(kerf_um),
            Some(path) => {
                let map = KerfMap::load(path)?;
                KerfSource::Map(Arc::new(move |x_mm, y_mm| {
                    map.kerf_at_um(kerf_um, x_mm, y_mm)
                }))
            }
        };
        Ok((kerf_um, kerf))
    }

    /// The plan library's options, reporting to `progress`.
    pub fn options(&self, strict: bool, progress: Progress) -> Result<DilateOptions, Error> {
        Ok(DilateOptions {
            rules: CutRules::new(&self.cut_colors, self.cut_max_width_mm, &self.cut_layers)?,
            assume_units: self.units,
            strict,
            if_compensated: self.if_compensated,
            progress,
        })
    }
}

/// What to do with a plan already compensated, from the two yes-or-no options the CLI and the
/// server take (`recompensate` wins; the CLI refuses both at once).
pub fn if_compensated(recompensate: bool, already_compensated_ok: bool) -> IfCompensated {
    if recompensate {
        IfCompensated::Recompensate
    } else if already_compensated_ok {
        IfCompensated::DilateAnyway
    } else {
        IfCompensated::Refuse
    }
}
