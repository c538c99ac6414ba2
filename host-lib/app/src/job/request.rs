//! A job asked for: everything `kerfmeter job` takes that names no file and is not the command
//! line's own ([`JobRequest`]), and the files a front end names beside it ([`JobFiles`]). The
//! CLI's flags, the server's `job` params (deserialized straight into it) and any other front end
//! all become these two.

use std::path::PathBuf;

use kerfmeter::params::DEFAULT_THICKNESS_MM;
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::gcode::DEFAULT_S_MAX;
use kerfmeter_plan::outcome::AssumedUnits;
use serde::{Deserialize, Serialize};

use crate::dilate::{DEFAULT_CUT_MAX_WIDTH_MM, Dilation, if_compensated};

/// Z that keeps the prongs clear of the work while the head travels, by default, mm.
pub const DEFAULT_TRAVEL_Z_MM: f64 = 10.0;
/// Feed of the plunge into the gauge by default, mm/min.
pub const DEFAULT_PLUNGE_FEED_MM_PER_MIN: f64 = 300.0;

/// A job: the joint, where the gauge and the plan go, how the prongs reach the gauge, how to
/// cut, which lines are cuts. Every field has `kerfmeter job`'s default; points and sizes are
/// `[x, y]`, mm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JobRequest {
    /// Sheet thickness, mm.
    pub thickness_mm: f64,
    /// Assembly force of the joint, N (`None`: 18.3 N per finger).
    pub force_n: Option<f64>,
    /// Where the gauge's spiral centre goes on the bed, mm (`None`: a free spot beside the plan).
    pub gauge_at_mm: Option<[f64; 2]>,
    /// The bed's size from the work origin, mm (`None`: the controller's X and Y travel, 600 ×
    /// 400 mm when it reports none, and on a dry run).
    pub bed_mm: Option<[f64; 2]>,
    /// The prongs' axis relative to the laser nozzle, mm.
    pub prong_offset_mm: [f64; 2],
    /// Z that lowers the prongs into the gauge's holes, mm.
    pub insert_z_mm: f64,
    /// Z that keeps the prongs clear of the work while the head travels, mm.
    pub travel_z_mm: f64,
    /// Feed of the plunge into the gauge, mm/min.
    pub plunge_feed_mm_per_min: f64,
    /// Where the lower-left corner of the plan's cuts goes on the machine, mm.
    pub origin_mm: [f64; 2],
    /// Feed while cutting, mm/min (with a profile: for the contours it does not name).
    pub feed_mm_per_min: Option<f64>,
    /// Laser power, percent of full power (with a profile: for the contours it does not name).
    pub power_percent: Option<f64>,
    /// How many times each contour is cut (`None`: 1).
    pub passes: Option<u32>,
    /// The S value of full power: GRBL's `$30`.
    pub s_max: f64,
    /// Colours that mean "cut" (`cut_color`: one, or a list; CSS syntax or an ACI number).
    #[serde(rename = "cut_color", deserialize_with = "names::one_or_many")]
    pub cut_colors: Vec<String>,
    /// Widest stroke (SVG) or lineweight (DXF) that is still a cut line, mm.
    pub cut_max_width_mm: f64,
    /// DXF: the entities on these layers are the cuts (`cut_layer`: one, or a list).
    #[serde(rename = "cut_layer", deserialize_with = "names::one_or_many")]
    pub cut_layers: Vec<String>,
    /// What one drawing unit is, for files that do not say.
    #[serde(deserialize_with = "names::units")]
    pub units: Option<AssumedUnits>,
    /// Dilate a plan that says it is already compensated by the full kerf on top anyway.
    pub already_compensated_ok: bool,
    /// Undo the compensation the plan records and apply the measured kerf instead.
    pub recompensate: bool,
    /// Unlock a cutter that is in alarm (`$X`) instead of refusing it.
    pub unlock: bool,
    /// What is measured, for the history (material, cutter).
    #[serde(deserialize_with = "names::label")]
    pub label: Option<String>,
}

impl Default for JobRequest {
    fn default() -> Self {
        Self {
            thickness_mm: DEFAULT_THICKNESS_MM,
            force_n: None,
            gauge_at_mm: None,
            bed_mm: None,
            prong_offset_mm: [0.0, 0.0],
            insert_z_mm: 0.0,
            travel_z_mm: DEFAULT_TRAVEL_Z_MM,
            plunge_feed_mm_per_min: DEFAULT_PLUNGE_FEED_MM_PER_MIN,
            origin_mm: [0.0, 0.0],
            feed_mm_per_min: None,
            power_percent: None,
            passes: None,
            s_max: DEFAULT_S_MAX,
            cut_colors: Vec::new(),
            cut_max_width_mm: DEFAULT_CUT_MAX_WIDTH_MM,
            cut_layers: Vec::new(),
            units: None,
            already_compensated_ok: false,
            recompensate: false,
            unlock: false,
            label: None,
        }
    }
}

impl JobRequest {
    /// What to do with a plan already compensated.
    pub fn if_compensated(&self) -> IfCompensated {
        if_compensated(self.recompensate, self.already_compensated_ok)
    }

    /// The plan's dilation by `kerf_um` with the request's cut rules.
    pub fn dilation(&self, kerf_um: f64) -> Dilation {
        Dilation {
            kerf_um,
            map: None,
            cut_colors: self.cut_colors.clone(),
            cut_max_width_mm: self.cut_max_width_mm,
            cut_layers: self.cut_layers.clone(),
            units: self.units,
            if_compensated: self.if_compensated(),
        }
    }

    /// What does not fit together, or the label the history would refuse (a front end's own
    /// parser may have said so already, in its own words).
    pub fn check(&self) -> Result<(), String> {
        if self.already_compensated_ok && self.recompensate {
            return Err(
                "`already_compensated_ok` and `recompensate` exclude each other: \
                        dilate on top of the plan's compensation, or undo it, not both"
                    .into(),
            );
        }
        if let Some(label) = &self.label {
            crate::history::parse_label(label)?;
        }
        Ok(())
    }
}

/// The files of a job: the plan read, the outputs written, the cut profile read.
#[derive(Debug, Clone, PartialEq)]
pub struct JobFiles {
    /// The plan: an .svg or .dxf file.
    pub input: PathBuf,
    /// The dilated plan, same format as the input (never the input itself).
    pub output: PathBuf,
    /// The job's G-code as streamed (`None`: the output with the extension .gcode).
    pub gcode_out: Option<PathBuf>,
    /// Cut settings by colour or layer (TOML), for the job; the gauge takes its default.
    pub profile: Option<PathBuf>,
    /// Replace the outputs even if they exist and kerfmeter did not write them.
    pub force: bool,
}

/// Serde helpers for the request's names: colours and layers, units, the label.
mod names {
    use kerfmeter_plan::outcome::AssumedUnits;
    use serde::{Deserialize, Deserializer, de::Error};

    /// A colour or a layer as given: its text, or a number (an ACI colour, a layer named `0`).
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Name {
        Text(String),
        Number(serde_json::Number),
    }

    impl Name {
        fn text(self) -> String {
            match self {
                Name::Text(t) => t,
                Name::Number(n) => n.to_string(),
            }
        }
    }

    /// One name or a list of them.
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum OneOrMany {
        One(Name),
        Many(Vec<Name>),
    }

    /// Names given one (`"red"`) or as a list (`["red", 5]`), each kept whole: a comma inside
    /// (`rgb(255,0,0)`, a layer `Cut, 3 mm`) separates nothing.
    pub fn one_or_many<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
        match Option::<OneOrMany>::deserialize(d) {
            Ok(None) => Ok(Vec::new()),
            Ok(Some(OneOrMany::One(name))) => Ok(vec![name.text()]),
            Ok(Some(OneOrMany::Many(names))) => Ok(names.into_iter().map(Name::text).collect()),
            Err(_) => Err(D::Error::custom("expected a string or a list of strings")),
        }
    }

    /// A unit by its name (`mm`, `px96`, ...).
    pub fn units<'de, D: Deserializer<'de>>(d: D) -> Result<Option<AssumedUnits>, D::Error> {
        let Some(name) = Option::<String>::deserialize(d)? else {
            return Ok(None);
        };
        let names = AssumedUnits::ALL.map(AssumedUnits::name);
        match AssumedUnits::ALL.into_iter().find(|u| u.name() == name) {
            Some(units) => Ok(Some(units)),
            None => Err(D::Error::custom(format!(
                "unknown unit `{name}` (one of {})",
                names.join(", ")
            ))),
        }
    }

    /// A label the history takes.
    pub fn label<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
        match Option::<String>::deserialize(d)? {
            None => Ok(None),
            Some(label) => crate::history::parse_label(&label)
                .map(Some)
                .map_err(D::Error::custom),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::request::from_params;
    use serde_json::json;

    #[test]
    fn the_defaults_are_kerfmeter_jobs() {
        let asked: JobRequest = from_params(json!({})).unwrap();
        assert_eq!(asked, JobRequest::default());
        assert_eq!(asked.travel_z_mm, 10.0);
        assert!(asked.check().is_ok());
    }

    #[test]
    fn points_are_pairs_and_names_one_or_many() {
        let asked: JobRequest = from_params(json!({
            "origin_mm": [10, 20.5],
            "cut_color": ["rgb(255,0,0)", 5],
            "cut_layer": "Cut, 3 mm",
            "units": "px96",
        }))
        .unwrap();
        assert_eq!(asked.origin_mm, [10.0, 20.5]);
        assert_eq!(asked.cut_colors, ["rgb(255,0,0)", "5"]);
        assert_eq!(asked.cut_layers, ["Cut, 3 mm"]);
        assert_eq!(asked.units, Some(AssumedUnits::Px96));
    }

    #[test]
    fn a_bad_or_unknown_parameter_is_named() {
        for (bad, name) in [
            (json!({"origin_mm": [1]}), "origin_mm"),
            (json!({"units": "furlong"}), "units"),
            (json!({"label": " "}), "label"),
            (json!({"cut_color": {"r": 1}}), "cut_color"),
            (json!({"passes": -1}), "passes"),
        ] {
            let e = from_params::<JobRequest>(bad.clone()).unwrap_err();
            assert_eq!(e.name.as_deref(), Some(name), "{bad}: {e}");
        }
        let e = from_params::<JobRequest>(json!({"profile": "x"})).unwrap_err();
        assert!(e.to_string().contains("`profile`"), "{e}");
        let both = JobRequest {
            already_compensated_ok: true,
            recompensate: true,
            ..JobRequest::default()
        };
        assert!(both.check().is_err());
    }
}
