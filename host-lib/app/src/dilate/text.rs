//! A plan sent as text (or base64) dilated into text: the server's `dilate`. The request is
//! deserialized straight from the call's params; it names no file, so it takes no kerf map.

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::progress::Progress;
use kerfmeter_plan::{PlanFormat, dilate_bytes};
use serde::{Deserialize, Serialize};

use super::{DEFAULT_CUT_MAX_WIDTH_MM, Dilation, if_compensated};
use crate::Error;
use crate::request::{BadParam, OneOrMany};

/// The kerf to dilate by: a number of µm, or `"last"`, the device's last result (which the
/// front end that holds the device reads).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum KerfGiven {
    /// This kerf, µm.
    Um(f64),
    /// The device's last result.
    Last(LastKerf),
}

/// The word `"last"`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LastKerf {
    /// The device's last result.
    Last,
}

/// `dilate` {plan | plan_base64, format, kerf_um, cut_colors, cut_max_width_mm, cut_layers,
/// units, strict, already_compensated_ok, recompensate}.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DilateTextRequest {
    /// The plan's text.
    #[serde(default)]
    pub plan: Option<String>,
    /// The plan's bytes in base64 (a binary DXF), instead of `plan`.
    #[serde(default)]
    pub plan_base64: Option<String>,
    /// "svg" or "dxf" (there is no file name to tell).
    pub format: PlanFormat,
    /// The kerf.
    pub kerf_um: KerfGiven,
    /// Colours that mean "cut" (one, or a list).
    #[serde(default)]
    pub cut_colors: OneOrMany,
    /// Widest stroke or lineweight that is still a cut line, mm.
    #[serde(default = "default_cut_max_width_mm")]
    pub cut_max_width_mm: f64,
    /// DXF: the layers that are the cuts (one, or a list).
    #[serde(default)]
    pub cut_layers: OneOrMany,
    /// What one drawing unit is, for files that do not say.
    #[serde(default)]
    pub units: Option<String>,
    /// Open cut paths are an error.
    #[serde(default)]
    pub strict: bool,
    /// Dilate a compensated plan by the full kerf anyway.
    #[serde(default)]
    pub already_compensated_ok: bool,
    /// Undo a compensated plan's compensation and apply the kerf instead.
    #[serde(default)]
    pub recompensate: bool,
}

fn default_cut_max_width_mm() -> f64 {
    DEFAULT_CUT_MAX_WIDTH_MM
}

/// What `dilate` answers: the kerf, the format, the report, and the dilated plan as text (or
/// base64 when it is binary).
#[derive(Debug, Clone, Serialize)]
pub struct DilateTextAnswer {
    /// The kerf applied, µm.
    pub kerf_um: f64,
    /// The format.
    pub format: PlanFormat,
    /// What was found and done.
    pub report: PlanReport,
    /// The dilated plan (text).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub content: Option<String>,
    /// The dilated plan (binary DXF), base64.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub content_base64: Option<String>,
}

/// What `dilate` reports beside the plan: the fields of `kerfmeter dilate --json` that are not
/// about files.
#[derive(Debug, Clone, Serialize)]
pub struct PlanReport {
    /// The kerf applied, µm.
    pub kerf_um: f64,
    /// The cut rules, in words.
    pub cut_rules: String,
    /// What was found and done.
    #[serde(flatten)]
    pub summary: PlanSummary,
}

impl DilateTextRequest {
    /// The plan's bytes, checked: `plan` or `plan_base64`, exactly one, not empty.
    pub fn plan_bytes(&self) -> Result<Vec<u8>, BadParam> {
        plan_bytes(self.plan.as_deref(), self.plan_base64.as_deref())
    }

    /// The dilation by `kerf_um` (the `kerf_um` given, or the device's last), its units checked.
    pub fn dilation(&self, kerf_um: f64) -> Result<Dilation, BadParam> {
        let units = match &self.units {
            None => None,
            Some(name) => Some(name.parse::<AssumedUnits>().map_err(|_| {
                let names: Vec<&str> = AssumedUnits::ALL.iter().map(|u| u.name()).collect();
                BadParam::named("units", format!("one of {}", names.join(", ")))
            })?),
        };
        Ok(Dilation {
            kerf_um,
            map: None,
            cut_colors: self.cut_colors.0.clone(),
            cut_max_width_mm: self.cut_max_width_mm,
            cut_layers: self.cut_layers.0.clone(),
            units,
            if_compensated: if_compensated(self.recompensate, self.already_compensated_ok),
        })
    }
}

/// Dilate `plan` (of `format`) as `dilation` says: the answer of `dilate`.
pub fn dilate_text(
    plan: Vec<u8>,
    format: PlanFormat,
    dilation: &Dilation,
    strict: bool,
) -> Result<DilateTextAnswer, Error> {
    let (kerf_um, kerf) = dilation.kerf()?;
    let options = dilation.options(strict, Progress::default())?;
    let (output, summary) = dilate_bytes(plan, format, &kerf, &options)?;
    let report = PlanReport {
        kerf_um,
        cut_rules: options.rules.describe(),
        summary,
    };
    let (content, content_base64) = match String::from_utf8(output) {
        Ok(text) => (Some(text), None),
        Err(binary) => (None, Some(BASE64.encode(binary.into_bytes()))),
    };
    Ok(DilateTextAnswer {
        kerf_um,
        format,
        report,
        content,
        content_base64,
    })
}

/// A plan sent as text: `plan` (its text) or `plan_base64` (its bytes, a binary DXF), exactly
/// one, not empty. The server's `dilate` and `job` take a plan so.
pub fn plan_bytes(plan: Option<&str>, plan_base64: Option<&str>) -> Result<Vec<u8>, BadParam> {
    let bytes = match (plan, plan_base64) {
        (Some(text), None) => text.as_bytes().to_vec(),
        (None, Some(b64)) => BASE64
            .decode(b64.trim())
            .map_err(|e| BadParam::named("plan_base64", format!("not base64: {e}")))?,
        (Some(_), Some(_)) => {
            return Err(BadParam::named(
                "plan",
                "give `plan` or `plan_base64`, not both",
            ));
        }
        (None, None) => {
            return Err(BadParam::named(
                "plan",
                "missing: the plan's text (or `plan_base64`)",
            ));
        }
    };
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(BadParam::named("plan", "empty: there is no drawing in it"));
    }
    Ok(bytes)
}
