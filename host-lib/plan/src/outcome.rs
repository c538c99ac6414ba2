//! What a dilation found and did, shared by the SVG and DXF paths, plus the units to assume for
//! files that do not say, and the dilated cuts themselves with the colour and layer each was
//! drawn with (what G-code is made from, see [`crate::gcode`]).

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use crate::compensation::{AppliedCompensation, FoundCompensation};
use crate::geom::Pline;
use crate::rules::Rgb;

/// What a cut was drawn with that can choose its cut settings: its stroke colour (SVG) or
/// colour (DXF, resolved through its layer), and its layer (DXF layer, Inkscape layer).
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, Serialize)]
pub struct CutGroup {
    /// The colour, when the file gives one.
    pub color: Option<Rgb>,
    /// The layer's name, when the cut is on one (Inkscape: its label, else its id).
    pub layer: Option<String>,
}

impl fmt::Display for CutGroup {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.color, &self.layer) {
            (Some(c), Some(l)) => write!(f, "colour {c} on layer \"{l}\""),
            (Some(c), None) => write!(f, "colour {c}"),
            (None, Some(l)) => write!(f, "layer \"{l}\""),
            (None, None) => f.write_str("no colour or layer"),
        }
    }
}

/// A dilated closed cut (document space, mm), with where it came from.
#[derive(Debug, Clone)]
pub struct CutPath {
    /// The contour as it is to be cut.
    pub pline: Pline,
    /// How to name it in messages.
    pub label: String,
    /// Its colour and layer.
    pub group: CutGroup,
}

/// The length of one drawing unit when the file does not say (an SVG without absolute
/// `width`/`height`, a DXF with `$INSUNITS` 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AssumedUnits {
    /// Millimetres.
    Mm,
    /// Centimetres.
    Cm,
    /// Inches.
    In,
    /// Points (1/72 in).
    Pt,
    /// CSS pixels, 96 per inch (Inkscape, browsers).
    Px96,
    /// Pixels at 72 per inch (older Illustrator exports).
    Px72,
}

impl AssumedUnits {
    /// Every unit, in the order a user is offered them.
    pub const ALL: [AssumedUnits; 6] = [
        AssumedUnits::Mm,
        AssumedUnits::Cm,
        AssumedUnits::In,
        AssumedUnits::Pt,
        AssumedUnits::Px96,
        AssumedUnits::Px72,
    ];

    /// Its name as a user writes it (and as it is serialized): `mm`, `px96`, ….
    pub fn name(self) -> &'static str {
        match self {
            AssumedUnits::Mm => "mm",
            AssumedUnits::Cm => "cm",
            AssumedUnits::In => "in",
            AssumedUnits::Pt => "pt",
            AssumedUnits::Px96 => "px96",
            AssumedUnits::Px72 => "px72",
        }
    }

    /// What it is, in words.
    pub fn describe(self) -> &'static str {
        match self {
            AssumedUnits::Mm => "Millimetres",
            AssumedUnits::Cm => "Centimetres",
            AssumedUnits::In => "Inches",
            AssumedUnits::Pt => "Points (1/72 in)",
            AssumedUnits::Px96 => "CSS pixels, 96 per inch (Inkscape, browsers)",
            AssumedUnits::Px72 => "Pixels at 72 per inch (older Illustrator exports)",
        }
    }

    /// One unit, mm.
    pub fn mm(self) -> f64 {
        match self {
            AssumedUnits::Mm => 1.0,
            AssumedUnits::Cm => 10.0,
            AssumedUnits::In => 25.4,
            AssumedUnits::Pt => 25.4 / 72.0,
            AssumedUnits::Px96 => 25.4 / 96.0,
            AssumedUnits::Px72 => 25.4 / 72.0,
        }
    }
}

impl FromStr for AssumedUnits {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        AssumedUnits::ALL
            .into_iter()
            .find(|u| u.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                let names: Vec<&str> = AssumedUnits::ALL.map(AssumedUnits::name).to_vec();
                format!("unknown unit `{s}` (one of {})", names.join(", "))
            })
    }
}

/// An open cut path: it cannot be dilated and is left as drawn.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OpenPath {
    /// The element or entity: an SVG id (or tag and line), a DXF handle.
    pub id: String,
    /// Where it starts, mm (document space).
    pub start_mm: [f64; 2],
    /// Where it ends, mm.
    pub end_mm: [f64; 2],
}

impl fmt::Display for OpenPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} from ({:.3}, {:.3}) to ({:.3}, {:.3}) mm",
            self.id, self.start_mm[0], self.start_mm[1], self.end_mm[0], self.end_mm[1]
        )
    }
}

/// What a dilation of one plan found and did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PlanSummary {
    /// `svg` or `dxf`.
    pub format: String,
    /// Length of one drawing unit, mm: in an SVG the root's user unit (what its `viewBox`
    /// makes of the `width`), in a DXF the `$INSUNITS` (or `--units`) unit.
    pub mm_per_unit: f64,
    /// Elements (SVG) or entities (DXF) that are cuts by the rules.
    pub cut_elements: usize,
    /// Elements or entities rewritten with dilated geometry.
    pub changed_elements: usize,
    /// Closed contours dilated.
    pub contours_dilated: usize,
    /// Parts (an outer contour with its holes).
    pub parts: usize,
    /// Holes (shrunk).
    pub holes: usize,
    /// Parts lying in another part's hole (grown again).
    pub islands: usize,
    /// Smallest and largest kerf used, µm.
    pub kerf_range_um: Option<[f64; 2]>,
    /// Open cut paths, left untouched.
    pub open_paths: Vec<OpenPath>,
    /// Elements that are not cuts and pass through untouched, counted by reason.
    pub passed_through: BTreeMap<String, usize>,
    /// Anything else worth knowing.
    pub notes: Vec<String>,
    /// A compensation the plan says it already carries (boxes.py's burn, this tool's record).
    pub compensation_found: Option<FoundCompensation>,
    /// What this run applied, as recorded in the output.
    pub compensation_applied: Option<AppliedCompensation>,
}

impl PlanSummary {
    pub(crate) fn pass(&mut self, reason: impl Into<String>) {
        *self.passed_through.entry(reason.into()).or_default() += 1;
    }

    pub(crate) fn record_parts(&mut self, d: &super::dilate::Dilation) {
        self.contours_dilated = d.contours.len();
        self.parts = d.parts.len();
        self.holes = d.parts.iter().map(|p| p.holes.len()).sum();
        self.islands = d.parts.iter().filter(|p| p.depth > 0).count();
        self.kerf_range_um = d.parts.iter().fold(None, |acc, p| {
            Some(match acc {
                None => [p.kerf_um, p.kerf_um],
                Some([lo, hi]) => [lo.min(p.kerf_um), hi.max(p.kerf_um)],
            })
        });
    }
}
