//! The project a LightBurn twin holds, and how LightBurn's REST API shows it: the fixed list of
//! cut entries (`GET /api/cuts`, `GET /api/cuts/{index}`), the 32 layer slots (`GET
//! /api/layers`), the project's metadata (`GET /api/project`) and the display units every cut
//! value is given in (`GET /api/units`).
//!
//! Values are kept in mm and mm/s and shown in the display units, as the spec has it
//! (`cut-settings.md` § Units: "LightBurn cut values: the user's display units"; "`POST` takes
//! values in the same units `GET` reports").

use serde_json::{Map, Value, json};

/// Cut layers at the head of the cut list (`cut-settings.md` § Reading cuts › LightBurn).
pub const CUT_LAYERS: usize = 30;
/// Tool layers after them (same section: `mode: "tool"`, not editable).
pub const TOOL_LAYERS: usize = 2;
/// Image cuts at the end of the list (same section: `kind: "image"`).
pub const IMAGE_CUTS: usize = 30;
/// The position of the internal virtual-array cut (`layer_index: -1`, not editable): after the
/// cut and tool layers (same section).
pub const INTERNAL_CUT: usize = CUT_LAYERS + TOOL_LAYERS;
/// The layer slots `GET /api/layers` gives, every one of them (`openapi.yaml`
/// `paths./api/layers.get`: "All 32 layer definitions").
pub const LAYER_SLOTS: usize = 32;

/// LightBurn's display units as `GET /api/units` names them: exactly the spec's enum
/// (`openapi.yaml` `paths./api/units.get`, and `JogSettings.units`: `mm/s`, `mm/min`,
/// `in/min`; there is no `in/s`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum DisplayUnits {
    /// Millimetres, speeds in mm/s.
    #[default]
    MmPerS,
    /// Millimetres, speeds in mm/min.
    MmPerMin,
    /// Inches, speeds in in/min.
    InPerMin,
}

impl DisplayUnits {
    /// The wire string.
    pub fn wire(self) -> &'static str {
        match self {
            DisplayUnits::MmPerS => "mm/s",
            DisplayUnits::MmPerMin => "mm/min",
            DisplayUnits::InPerMin => "in/min",
        }
    }

    /// The distance unit, as `GET /api/project` `units.distance` names it.
    pub fn distance(self) -> &'static str {
        match self {
            DisplayUnits::InPerMin => "in",
            _ => "mm",
        }
    }

    /// Display distance units in one mm.
    fn per_mm(self) -> f64 {
        match self {
            DisplayUnits::InPerMin => 1.0 / 25.4,
            _ => 1.0,
        }
    }

    /// Display speed units in one mm/s.
    fn per_mm_s(self) -> f64 {
        match self {
            DisplayUnits::MmPerS => 1.0,
            DisplayUnits::MmPerMin => 60.0,
            DisplayUnits::InPerMin => 60.0 / 25.4,
        }
    }

    /// How many display units one stored unit (mm, or mm/s) of `field` is; 1 for a field that
    /// is not a distance or a speed.
    pub(super) fn factor(self, field: &str) -> f64 {
        match field {
            "kerf" | "z_offset" => self.per_mm(),
            "speed" => self.per_mm_s(),
            _ => 1.0,
        }
    }
}

/// A pass's mode (`openapi.yaml` `LaserCut.mode`: `cut` is LightBurn's Line, `scan` its Fill).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Line.
    Cut,
    /// Fill.
    Scan,
    /// Offset Fill.
    Offset,
    /// Image.
    Image,
    /// A tool layer.
    Tool,
}

impl Mode {
    /// The wire string.
    pub fn wire(self) -> &'static str {
        match self {
            Mode::Cut => "cut",
            Mode::Scan => "scan",
            Mode::Offset => "offset",
            Mode::Image => "image",
            Mode::Tool => "tool",
        }
    }

    /// The mode a `POST` may set (`openapi.yaml` `paths./api/cuts/{index}.post` body: `mode`
    /// is one of `cut`, `scan`, `offset`).
    pub(super) fn editable(wire: &str) -> Option<Mode> {
        match wire {
            "cut" => Some(Mode::Cut),
            "scan" => Some(Mode::Scan),
            "offset" => Some(Mode::Offset),
            _ => None,
        }
    }
}

/// A pass's parameters by their wire names, distances in mm and speeds in mm/s.
pub type Params = Map<String, Value>;

/// A sub-layer: a pass beyond the layer's own (`openapi.yaml` `LaserCut.sub_layers` items).
#[derive(Debug, Clone, PartialEq)]
pub struct SubLayer {
    /// Its position within the cut, from 1 (the base layer is 0).
    pub index: i64,
    /// Its name (may be empty).
    pub name: String,
    /// Whether it is output.
    pub enabled: bool,
    /// Its mode.
    pub mode: Mode,
    /// Its `LaserCutParams`.
    pub params: Params,
}

/// What kind of entry a cut is.
#[derive(Debug, Clone, PartialEq)]
pub enum CutKind {
    /// `kind: "normal"`: a layer's vector settings, with its base pass's mode and its sub-layers.
    Normal {
        /// The base pass's mode.
        mode: Mode,
        /// The passes beyond it.
        sub_layers: Vec<SubLayer>,
    },
    /// `kind: "image"`: a layer's image settings.
    Image,
}

/// One entry of the cut list.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    /// The layer slot it belongs to (-1: the internal cut).
    pub layer_index: i64,
    /// Its name.
    pub name: String,
    /// Whether it is output.
    pub enabled: bool,
    /// Its output order.
    pub priority: i64,
    /// Normal or image.
    pub kind: CutKind,
    /// Its params: `LaserCutParams` for a normal cut, the image params for an image cut.
    pub params: Params,
}

impl Cut {
    /// Whether the spec lets no `POST` change it: a tool layer or the internal cut
    /// (`cut-settings.md` § What can be changed: "Tool layers and the internal virtual-array
    /// cut are rejected with `400`").
    pub(super) fn not_editable(&self) -> Option<&'static str> {
        match &self.kind {
            _ if self.layer_index < 0 => Some("the internal virtual-array cut is not editable"),
            CutKind::Normal {
                mode: Mode::Tool, ..
            } => Some("tool layers are not editable"),
            _ => None,
        }
    }
}

/// A layer slot's own state (its name and mode are its normal cut's).
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// `#RRGGBB`.
    pub color: String,
    /// Hidden in LightBurn's view.
    pub hidden: bool,
    /// Shapes on it; in use when not 0.
    pub shape_count: u32,
}

/// What the twin's LightBurn has open.
#[derive(Debug, Clone, PartialEq)]
pub struct Project {
    /// The project's file name.
    pub filename: String,
    /// Changed since it was saved (`POST /api/cuts/{index}` sets it).
    pub modified: bool,
    /// The undo steps changes have made ("Change cut settings", one a `POST`).
    pub undo_steps: usize,
    /// The cut list, in the spec's fixed order: its position is each entry's `index`.
    pub cuts: Vec<Cut>,
    /// The 32 layer slots.
    pub layers: Vec<Layer>,
}

/// Every `LaserCutParams` field at a new layer's values (mm, mm/s): "Source and pulse fields
/// are always present" (`openapi.yaml` `LaserCutParams`).
fn line_params(speed_mm_s: f64, max_power: f64) -> Params {
    let v = json!({
        "speed": speed_mm_s, "min_power": 10.0, "max_power": max_power, "num_passes": 1,
        "z_offset": 0.0, "frequency": 20000, "kerf": 0.0, "bi_directional": true,
        "cross_hatch": false, "min_power_2": 10.0, "max_power_2": max_power,
        "laser1_enabled": true, "laser2_enabled": false, "alt_source": false,
        "q_pulse_width": 200.0, "fiber_pulse_width": 200,
    });
    v.as_object().cloned().expect("an object")
}

/// The image params (`openapi.yaml` `LaserCut.params`, the image branch: speed, power, dpi,
/// dither mode, and the source and pulse fields but `min_power_2`).
fn image_params() -> Params {
    let v = json!({
        "speed": 150.0, "max_power": 20.0, "dpi": 254.0, "dither_mode": "Stucki",
        "max_power_2": 20.0, "laser1_enabled": true, "laser2_enabled": false,
        "alt_source": false, "q_pulse_width": 200.0, "fiber_pulse_width": 200,
    });
    v.as_object().cloned().expect("an object")
}

/// A new Line layer in `slot`, named as LightBurn names them (`C00` …).
fn line_layer(slot: usize) -> Cut {
    Cut {
        layer_index: slot as i64,
        name: format!("C{slot:02}"),
        enabled: true,
        priority: slot as i64,
        kind: CutKind::Normal {
            mode: Mode::Cut,
            sub_layers: Vec::new(),
        },
        params: line_params(100.0, 20.0),
    }
}

impl Project {
    /// The twin's project: the spec's fixed list of 63 cut entries, in which these layers are
    /// set up (the rest are unused Line layers `C05` … `C29`):
    ///
    /// | slot | name | mode | in use |
    /// |------|------|------|--------|
    /// | 0 | `C00` | Line | 3 shapes |
    /// | 1 | `Engrave` | Fill | 1 shape |
    /// | 2 | `Badge, 3 mm` (a comma in the name) | Fill, sub-layer 1 Fill, sub-layer 2 Line | 2 shapes |
    /// | 3 | `Old` | Line, Kerf Offset 0.05 mm | no |
    /// | 4 | `Photo` | Image | 1 shape |
    /// | 30 | `T1` | tool | 1 shape |
    /// | 31 | `T2` | tool | no |
    pub fn example() -> Project {
        let mut cuts: Vec<Cut> = (0..CUT_LAYERS).map(line_layer).collect();
        let mut fill = |slot: usize, name: &str, mode: Mode, sub_layers: Vec<SubLayer>| {
            let cut = &mut cuts[slot];
            cut.name = name.into();
            cut.kind = CutKind::Normal { mode, sub_layers };
        };
        fill(1, "Engrave", Mode::Scan, Vec::new());
        let sub = |index: i64, name: &str, mode: Mode| SubLayer {
            index,
            name: name.into(),
            enabled: true,
            mode,
            params: line_params(20.0, 40.0),
        };
        fill(
            2,
            "Badge, 3 mm",
            Mode::Scan,
            vec![sub(1, "Fill 2", Mode::Scan), sub(2, "Outline", Mode::Cut)],
        );
        fill(3, "Old", Mode::Cut, Vec::new());
        fill(4, "Photo", Mode::Image, Vec::new());
        cuts[3].params.insert("kerf".into(), json!(0.05));
        for (i, slot) in (CUT_LAYERS..CUT_LAYERS + TOOL_LAYERS).enumerate() {
            cuts.push(Cut {
                layer_index: slot as i64,
                name: format!("T{}", i + 1),
                enabled: true,
                priority: 0,
                kind: CutKind::Normal {
                    mode: Mode::Tool,
                    sub_layers: Vec::new(),
                },
                params: line_params(100.0, 0.0),
            });
        }
        // The spec gives the internal cut's `layer_index` only; its name and mode are the
        // twin's (a Line mode, so that a client which does not skip `layer_index: -1` tries to
        // change it and is refused).
        cuts.push(Cut {
            layer_index: -1,
            name: String::new(),
            enabled: true,
            priority: 0,
            kind: CutKind::Normal {
                mode: Mode::Cut,
                sub_layers: Vec::new(),
            },
            params: line_params(100.0, 20.0),
        });
        for slot in 0..IMAGE_CUTS {
            let name = cuts[slot].name.clone();
            cuts.push(Cut {
                layer_index: slot as i64,
                name,
                enabled: true,
                priority: slot as i64,
                kind: CutKind::Image,
                params: image_params(),
            });
        }
        let layers = (0..LAYER_SLOTS)
            .map(|slot| Layer {
                // Any `#RRGGBB` (`openapi.yaml` `/api/layers` `color.pattern`); not LightBurn's
                // palette.
                color: format!("#{:06X}", (slot as u32 * 0x0011_3355) & 0xFF_FFFF),
                hidden: false,
                shape_count: match slot {
                    0 => 3,
                    1 | 4 | 30 => 1,
                    2 => 2,
                    _ => 0,
                },
            })
            .collect();
        Project {
            filename: "twin.lbrn2".into(),
            modified: false,
            undo_steps: 0,
            cuts,
            layers,
        }
    }

    /// Entry `index` as `GET /api/cuts/{index}` gives it: the `LaserCut` schema, values in
    /// `units` (`openapi.yaml` `LaserCut`: `mode` and `sub_layers` only when `kind ==
    /// "normal"`; `sub_layers` empty when there are none).
    pub fn cut_json(&self, index: usize, units: DisplayUnits) -> Option<Value> {
        let cut = self.cuts.get(index)?;
        let mut entry = json!({
            "index": index, "name": cut.name, "layer_index": cut.layer_index,
            "enabled": cut.enabled, "priority": cut.priority,
            "params": shown(&cut.params, units),
        });
        match &cut.kind {
            CutKind::Normal { mode, sub_layers } => {
                entry["kind"] = json!("normal");
                entry["mode"] = json!(mode.wire());
                let subs: Vec<Value> = sub_layers
                    .iter()
                    .map(|s| {
                        json!({ "index": s.index, "name": s.name, "enabled": s.enabled,
                                "mode": s.mode.wire(), "params": shown(&s.params, units) })
                    })
                    .collect();
                entry["sub_layers"] = Value::Array(subs);
            }
            CutKind::Image => entry["kind"] = json!("image"),
        }
        Some(entry)
    }

    /// `GET /api/cuts`: `LaserCuts` (`openapi.yaml`), `product: "lightburn"`.
    pub fn cuts_json(&self, units: DisplayUnits) -> Value {
        let cuts: Vec<Value> = (0..self.cuts.len())
            .filter_map(|i| self.cut_json(i, units))
            .collect();
        json!({ "product": "lightburn", "cuts": cuts })
    }

    /// The name of layer `slot`: its normal cut's.
    fn layer_name(&self, slot: usize) -> String {
        self.cuts
            .iter()
            .find(|c| matches!(c.kind, CutKind::Normal { .. }) && c.layer_index == slot as i64)
            .map_or_else(String::new, |c| c.name.clone())
    }

    /// `GET /api/layers`: every slot, in use or not, with its `shape_count`
    /// (`openapi.yaml` `paths./api/layers.get`).
    pub fn layers_json(&self) -> Value {
        let layers: Vec<Value> = self
            .layers
            .iter()
            .enumerate()
            .map(|(slot, l)| {
                json!({ "index": slot, "name": self.layer_name(slot), "color": l.color,
                        "type": if slot < CUT_LAYERS { "normal" } else { "tool" },
                        "hidden": l.hidden, "in_use": l.shape_count > 0,
                        "shape_count": l.shape_count })
            })
            .collect();
        json!({ "active_index": 0, "layers": layers })
    }

    /// `GET /api/project` (`openapi.yaml` `paths./api/project.get`): `workspace` in mm always
    /// (`CHANGELOG.md` § Unreleased › Clarified), `units` the display units.
    pub fn project_json(&self, units: DisplayUnits) -> Value {
        let shapes: u32 = self.layers.iter().map(|l| l.shape_count).sum();
        json!({
            "filename": self.filename, "modified": self.modified, "shape_count": shapes,
            "units": { "distance": units.distance(), "speed": units.wire() },
            "workspace": { "machine_size": { "x": 400.0, "y": 300.0 },
                           "workpiece_size": { "x": 400.0, "y": 300.0 },
                           "workpiece_offset": { "x": 0.0, "y": 0.0 }, "machine_view": false },
            "device": { "name": "LightBurn twin", "supports_z": false,
                        "laser": { "controller": "GRBL", "galvo": false, "flying_galvo": false,
                                   "uv": false, "sources": 1, "sources_enabled": 1,
                                   "mopa_source": 0, "laser1_fiber": false,
                                   "laser2_fiber": false } },
        })
    }
}

/// `params` (mm, mm/s) in the display units.
fn shown(params: &Params, units: DisplayUnits) -> Value {
    let shown: Params = params
        .iter()
        .map(|(k, v)| {
            let factor = units.factor(k);
            match v.as_f64() {
                Some(x) if factor != 1.0 => (k.clone(), json!(x * factor)),
                _ => (k.clone(), v.clone()),
            }
        })
        .collect();
    Value::Object(shown)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cut_list_is_the_specs_fixed_layout() {
        let p = Project::example();
        let cuts = p.cuts_json(DisplayUnits::MmPerS);
        let cuts = cuts["cuts"].as_array().unwrap();
        assert_eq!(cuts.len(), CUT_LAYERS + TOOL_LAYERS + 1 + IMAGE_CUTS);
        for (i, c) in cuts.iter().enumerate() {
            assert_eq!(c["index"], i, "index is the position");
        }
        assert!(cuts[..30].iter().all(|c| c["kind"] == "normal"));
        assert!(cuts[30..32].iter().all(|c| c["mode"] == "tool"));
        assert_eq!(cuts[32]["layer_index"], -1);
        assert!(cuts[33..].iter().all(|c| c["kind"] == "image"));
        assert!(cuts[33..].iter().all(|c| c.get("mode").is_none()));
        assert_eq!(cuts[35]["layer_index"], 2, "image cuts follow their slots");
        assert_eq!(p.layers_json()["layers"].as_array().unwrap().len(), 32);
    }

    #[test]
    fn values_are_shown_in_the_display_units() {
        let p = Project::example();
        let old = p.cut_json(3, DisplayUnits::InPerMin).unwrap();
        assert!((old["params"]["kerf"].as_f64().unwrap() - 0.05 / 25.4).abs() < 1e-15);
        assert!((old["params"]["speed"].as_f64().unwrap() - 6000.0 / 25.4).abs() < 1e-9);
        assert_eq!(
            old["params"]["max_power"], 20.0,
            "powers are percent in any units"
        );
    }
}
