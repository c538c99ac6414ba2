//! Which lines of a plan are *cuts*: rules by stroke colour and width (SVG), by colour or layer
//! (DXF).
//!
//! Laser software has no single convention, so the defaults cover the common ones and every rule
//! is configurable (`--cut-color`, `--cut-max-width-mm`, `--cut-layer`):
//!
//! | source | cut | not a cut |
//! |---|---|---|
//! | Epilog / Trotec / ULS drivers, university labs (Purdue BIDC) | red `#FF0000` hairline | black fill = raster engrave; thick lines engrave (ULS: ≥ 0.2 mm) |
//! | boxes.py (`Color.OUTER_CUT` / `INNER_CUT`) | black `#000000` outer cuts, blue `#0000FF` inner cuts | red annotations, green etching, cyan deep etching |
//! | Ponoko, Purdue ("blue/green for inner cuts first") | blue `#0000FF` | red = vector engrave at Ponoko |
//! | Glowforge | any *outlined* (unfilled) vector | filled shapes and bitmaps = engrave |
//! | LightBurn, xTool Creative Space | colour → layer, the user picks each layer's mode (LightBurn's palette starts black `00`, blue `01`, red `02`) | |
//!
//! **Defaults:** an element is a cut when it is rendered, *stroked* in red, blue or black, with a
//! stroke no wider than 0.3 mm (Inkscape's default 1 px = 0.265 mm passes), and *not filled*.
//! Everything else — green/cyan/other strokes (scores, etching), filled shapes (raster engrave),
//! thick strokes, text, images — passes through untouched. Ponoko users, whose red lines are
//! vector *engraves*, pass `--cut-color blue`; shops with "blue = score" pass
//! `--cut-color red,black`.
//!
//! DXF has no fills: an entity is a cut when its colour (its own, or its layer's for BYLAYER) is
//! a cut colour — or, when `--cut-layer` names are given, exactly when it lies on one of those
//! layers. A positive DXF lineweight wider than the maximum width also makes it a non-cut.
//! `--cut-color` takes an ACI number (1–255) as well as a CSS colour, and colours are compared
//! as RGB both ways: an ACI index stands for its colour in the palette of the `aci` module (ACI
//! 1 = red, 5 = blue, 7 = black on the laser's white sheet, 8 = `#808080`, …), so ACI 8 is cut by
//! `--cut-color 8` and by `--cut-color '#808080'`, and a true-colour entity (group 420) of
//! `#808080` by either too.

use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use crate::error::{PlanError, Result};
use crate::selectors;

/// The widest stroke `--cut-max-width-mm` may name, mm: no cut line is a metre wide, and a
/// limit past it is a typo.
pub const MAX_CUT_WIDTH_MM: f64 = 1000.0;

/// An sRGB colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct Rgb(pub u8, pub u8, pub u8);

impl Rgb {
    /// Pure red.
    pub const RED: Rgb = Rgb(255, 0, 0);
    /// Pure blue.
    pub const BLUE: Rgb = Rgb(0, 0, 255);
    /// Black.
    pub const BLACK: Rgb = Rgb(0, 0, 0);

    /// Parse any CSS colour (`red`, `#f00`, `#FF0000`, `rgb(255,0,0)`) or an ACI number
    /// (`1`–`255`, the colour [`Rgb::from_aci`] gives it).
    pub fn parse(text: &str) -> Result<Rgb> {
        let t = text.trim();
        if !t.is_empty() && t.bytes().all(|b| b.is_ascii_digit()) {
            return t.parse::<u8>().ok().and_then(Rgb::from_aci).ok_or_else(|| {
                PlanError::InvalidArgument(format!(
                    "`{text}` is not an ACI colour: ACI numbers run from 1 to 255 (0 is \
                         BYBLOCK, 256 BYLAYER: no colour of their own)"
                ))
            });
        }
        let c = svgtypes::Color::from_str(t).map_err(|e| {
            PlanError::InvalidArgument(format!(
                "`{text}` is not a colour ({e}); use a name like red, a hex code like #FF0000, \
                 rgb(255,0,0) or an ACI number from 1 to 255"
            ))
        })?;
        Ok(Rgb(c.red, c.green, c.blue))
    }

    /// The colour of an AutoCAD colour index, 1–255 (see the `aci` module: 7 is black on a
    /// laser's white sheet); `None` for 0 (BYBLOCK).
    pub fn from_aci(index: u8) -> Option<Rgb> {
        match index {
            0 => None,
            7 => Some(Rgb::BLACK),
            i => {
                let c = crate::aci::ACI_RGB[usize::from(i)];
                Some(Rgb((c >> 16) as u8, (c >> 8) as u8, c as u8))
            }
        }
    }
}

impl fmt::Display for Rgb {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{:02X}{:02X}{:02X}", self.0, self.1, self.2)
    }
}

/// The rules that decide which lines are cuts (see the module doc for the defaults).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CutRules {
    /// Stroke colours that mean "cut".
    pub colors: Vec<Rgb>,
    /// Widest stroke that is still a cut line, mm.
    pub max_width_mm: f64,
    /// DXF layers whose entities are cuts (case-insensitive); when non-empty, colours are not
    /// used for DXF.
    pub layers: Vec<String>,
}

impl Default for CutRules {
    fn default() -> Self {
        Self {
            colors: vec![Rgb::RED, Rgb::BLUE, Rgb::BLACK],
            max_width_mm: 0.3,
            layers: Vec::new(),
        }
    }
}

/// What the rules say about one element.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// A cut: dilate it.
    Cut,
    /// Not a cut, and why (a short phrase used to group the passed-through elements).
    Keep(String),
}

impl CutRules {
    /// Rules from option values: colours (CSS syntax), maximum width, DXF layers; a value may
    /// list several, separated by commas ([`selectors`]).
    pub fn new(colors: &[String], max_width_mm: f64, layers: &[String]) -> Result<Self> {
        let mut rules = Self::default();
        let colors = selectors::split_lists(colors)
            .map_err(|e| PlanError::InvalidArgument(format!("--cut-color: {e}")))?;
        if !colors.is_empty() {
            rules.colors = colors.into_iter().map(Rgb::parse).collect::<Result<_>>()?;
        }
        if !(max_width_mm.is_finite() && (0.0..=MAX_CUT_WIDTH_MM).contains(&max_width_mm)) {
            return Err(PlanError::InvalidArgument(format!(
                "--cut-max-width-mm must be a width from 0 to {MAX_CUT_WIDTH_MM} mm, got {}",
                kerfmeter_protocol::Shown(max_width_mm)
            )));
        }
        rules.max_width_mm = max_width_mm;
        // Kept as given: a value is a layer's whole name (one may hold a comma) or a list of them,
        // which only the drawing's layers can tell ([`CutRules::for_layers`]).
        selectors::split_lists(layers)
            .map_err(|e| PlanError::InvalidArgument(format!("--cut-layer: {e}")))?;
        rules.layers = layers.to_vec();
        Ok(rules)
    }

    /// Classify an SVG element from its resolved stroke (colour, width in mm) and whether it is
    /// filled.
    pub fn classify_svg(&self, stroke: Option<(Rgb, f64)>, filled: bool) -> Verdict {
        let Some((color, width_mm)) = stroke else {
            return Verdict::Keep(if filled {
                "filled, no stroke (engrave)".into()
            } else {
                "no stroke".into()
            });
        };
        if filled {
            return Verdict::Keep("filled (engrave)".into());
        }
        if !self.colors.contains(&color) {
            return Verdict::Keep(format!("stroke {color} (not a cut colour)"));
        }
        if width_mm > self.max_width_mm + 1e-9 {
            return Verdict::Keep(format!(
                "stroke wider than {} mm (engrave)",
                self.max_width_mm
            ));
        }
        Verdict::Cut
    }

    /// Classify a DXF entity from its resolved colour, layer and lineweight (mm, when set).
    pub fn classify_dxf(
        &self,
        color: Option<Rgb>,
        layer: &str,
        lineweight_mm: Option<f64>,
    ) -> Verdict {
        if !self.layers.is_empty() {
            return if self.layers.iter().any(|l| l.eq_ignore_ascii_case(layer)) {
                Verdict::Cut
            } else {
                Verdict::Keep(format!("layer {layer} (not a cut layer)"))
            };
        }
        let Some(color) = color else {
            return Verdict::Keep(
                "no colour (BYBLOCK outside a block, or a layer missing or turned off): choose \
                 its layer with --cut-layer"
                    .into(),
            );
        };
        if !self.colors.contains(&color) {
            return Verdict::Keep(format!(
                "colour {color} (not a cut colour: --cut-color '{color}' or its ACI number cuts it)"
            ));
        }
        if let Some(w) = lineweight_mm
            && w > self.max_width_mm + 1e-9
        {
            return Verdict::Keep(format!(
                "lineweight {w} mm, wider than {} mm: an engraving; raise --cut-max-width-mm, \
                 or choose the cuts with --cut-layer",
                self.max_width_mm
            ));
        }
        Verdict::Cut
    }

    /// These rules for a drawing whose layers `is_layer` recognises: each `--cut-layer` value is
    /// a layer's whole name, or else a comma-separated list of them ([`selectors`]).
    pub fn for_layers(&self, is_layer: impl Fn(&str) -> bool) -> Result<CutRules> {
        let names = selectors::layer_selectors(&self.layers, is_layer)
            .map_err(|e| PlanError::InvalidArgument(format!("--cut-layer: {e}")))?;
        let mut layers: Vec<String> = Vec::new();
        for name in names {
            if !layers.iter().any(|l| l == name) {
                layers.push(name.to_string());
            }
        }
        Ok(CutRules {
            layers,
            ..self.clone()
        })
    }

    /// One line describing the rules, for reports.
    pub fn describe(&self) -> String {
        let colors: Vec<String> = self.colors.iter().map(Rgb::to_string).collect();
        let mut s = format!(
            "unfilled lines in {} up to {} mm wide",
            colors.join(", "),
            self.max_width_mm
        );
        if !self.layers.is_empty() {
            let names: Vec<String> = self.layers.iter().map(|l| format!("{l:?}")).collect();
            s.push_str(&format!("; DXF layers {}", names.join(", ")));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_follow_the_laser_conventions() {
        let r = CutRules::default();
        assert_eq!(r.classify_svg(Some((Rgb::RED, 0.01)), false), Verdict::Cut);
        assert_eq!(r.classify_svg(Some((Rgb::BLUE, 0.1)), false), Verdict::Cut);
        assert_eq!(
            r.classify_svg(Some((Rgb::BLACK, 0.265)), false),
            Verdict::Cut
        );
        assert!(matches!(
            r.classify_svg(Some((Rgb(0, 255, 0), 0.01)), false),
            Verdict::Keep(_)
        ));
        assert!(matches!(
            r.classify_svg(Some((Rgb::RED, 0.5)), false),
            Verdict::Keep(_)
        ));
        assert!(matches!(
            r.classify_svg(Some((Rgb::BLACK, 0.1)), true),
            Verdict::Keep(_)
        ));
        assert!(matches!(r.classify_svg(None, true), Verdict::Keep(_)));
        assert_eq!(r.classify_dxf(Rgb::from_aci(1), "0", None), Verdict::Cut);
        assert!(matches!(
            r.classify_dxf(Rgb::from_aci(3), "0", None),
            Verdict::Keep(_)
        ));
    }

    #[test]
    fn a_value_may_list_colours_and_layers_and_keeps_a_colours_own_commas() {
        let colors = ["rgb(255,0,0), #00f".to_string(), "black".to_string()];
        let r = CutRules::new(&colors, 0.1, &["Cut, 3 mm".into()]).unwrap();
        assert_eq!(r.colors, vec![Rgb::RED, Rgb::BLUE, Rgb::BLACK]);
        let kept = |r: &CutRules, layer| !matches!(r.classify_dxf(None, layer, None), Verdict::Cut);
        // A drawing with a layer of that whole name (DXF allows a comma): that layer alone.
        let whole = r.for_layers(|n| n == "Cut, 3 mm").unwrap();
        assert!(!kept(&whole, "Cut, 3 mm"));
        assert!(kept(&whole, "Cut") && kept(&whole, "3 mm"));
        // One without: the value is a list.
        let listed = r.for_layers(|n| n == "Cut").unwrap();
        assert!(!kept(&listed, "Cut") && !kept(&listed, "3 mm"));
        assert_eq!(
            listed.describe(),
            "unfilled lines in #FF0000, #0000FF, #000000 up to 0.1 mm wide; DXF layers \"Cut\", \"3 mm\""
        );
        // A value that names nothing is refused, not read as "no rule".
        assert!(CutRules::new(&[" ".into()], 0.1, &[]).is_err());
        assert!(CutRules::new(&[], 0.1, &[",".into()]).is_err());
    }

    #[test]
    fn options_replace_the_defaults() {
        let r = CutRules::new(&["#00f".into()], 0.1, &["CUT".into()]).unwrap();
        assert_eq!(r.colors, vec![Rgb::BLUE]);
        assert!(matches!(
            r.classify_svg(Some((Rgb::RED, 0.01)), false),
            Verdict::Keep(_)
        ));
        assert_eq!(r.classify_dxf(None, "cut", None), Verdict::Cut);
        assert!(matches!(
            r.classify_dxf(Rgb::from_aci(1), "ENGRAVE", None),
            Verdict::Keep(_)
        ));
        assert!(CutRules::new(&["nonsense-colour".into()], 0.1, &[]).is_err());
        assert!(CutRules::new(&[], -1.0, &[]).is_err());
        assert_eq!(Rgb::parse("rgb(255, 0, 0)").unwrap().to_string(), "#FF0000");
    }
}
