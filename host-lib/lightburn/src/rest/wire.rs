//! LightBurn's REST messages as this client reads and writes them: typed, so that a reply
//! missing what the spec requires (a cut's `index`, a sub-layer's `index`, a layer's `in_use`)
//! is an error, not a default. Read leniently otherwise, as `versioning.md` § Guidance for
//! integrators asks ("ignore unknown fields, tolerate new enum values"): unknown fields are
//! skipped and an unknown `kind` or `mode` is a value of its own, never a Line pass.
//!
//! The shapes are `docs/openapi.yaml`'s (`LaserCuts`, `LaserCut`, `LaserCutParams`, the bodies
//! of `/api/connect`, `/api/units`, `/api/layers` and `POST /api/cuts/{index}`).

use serde::{Deserialize, Serialize};

/// The body of `POST /api/connect`.
#[derive(Debug, Serialize)]
pub(super) struct PairRequest<'a> {
    pub application_name: &'a str,
    pub capabilities: &'a [&'a str],
}

/// Its answer on approval.
#[derive(Debug, Deserialize)]
pub(super) struct PairReply {
    pub secret: String,
}

/// An `ErrorResponse`.
#[derive(Debug, Deserialize)]
pub(super) struct ErrorReply {
    pub error: Option<String>,
}

/// LightBurn's display units (`GET /api/units`: the enum `mm/s`, `mm/min`, `in/min`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub(super) enum DisplayUnits {
    #[serde(rename = "mm/s")]
    MmPerS,
    #[serde(rename = "mm/min")]
    MmPerMin,
    #[serde(rename = "in/min")]
    InPerMin,
}

impl DisplayUnits {
    /// The distance unit, and how many of it make a mm.
    pub fn distance(self) -> (&'static str, f64) {
        match self {
            DisplayUnits::MmPerS | DisplayUnits::MmPerMin => ("mm", 1.0),
            DisplayUnits::InPerMin => ("in", 1.0 / 25.4),
        }
    }
}

/// `GET /api/units`.
#[derive(Debug, Deserialize)]
pub(super) struct UnitsReply {
    pub units: DisplayUnits,
}

/// The `product` of `GET /api/cuts`, read first: MillMage's list has another shape.
#[derive(Debug, Deserialize)]
pub(super) struct Product {
    pub product: String,
}

/// `GET /api/cuts` from LightBurn (`LaserCuts`).
#[derive(Debug, Deserialize)]
pub(super) struct CutList {
    pub cuts: Vec<CutEntry>,
}

/// `kind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum Kind {
    Normal,
    Image,
    #[serde(other)]
    Other,
}

/// A pass's `mode`: `cut` is LightBurn's Line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub(super) enum Mode {
    Cut,
    Scan,
    Offset,
    Image,
    Tool,
    #[serde(other)]
    Other,
}

/// The params this client reads: the Kerf Offset, in display units (none in an image cut's).
#[derive(Debug, Deserialize)]
pub(super) struct Params {
    pub kerf: Option<f64>,
}

/// One entry of the cut list (`LaserCut`): `index` is its position in the list (what
/// `/api/cuts/{index}` takes), `layer_index` the layer slot it belongs to.
#[derive(Debug, Deserialize)]
pub(super) struct CutEntry {
    pub index: i64,
    pub name: String,
    pub kind: Kind,
    pub layer_index: i64,
    /// Only when `kind` is `normal`.
    pub mode: Option<Mode>,
    pub params: Params,
    /// Only when `kind` is `normal`; the base layer is not repeated in it.
    #[serde(default)]
    pub sub_layers: Vec<SubLayerEntry>,
}

/// A sub-layer (`index` from 1 is required: it is how a `POST` addresses it).
#[derive(Debug, Deserialize)]
pub(super) struct SubLayerEntry {
    pub index: i64,
    pub mode: Mode,
    pub params: Params,
}

/// `GET /api/layers`.
#[derive(Debug, Deserialize)]
pub(super) struct LayersReply {
    pub layers: Vec<LayerSlot>,
}

/// A layer slot: its index (a cut's `layer_index`) and whether any shape is on it.
#[derive(Debug, Deserialize)]
pub(super) struct LayerSlot {
    pub index: i64,
    pub in_use: bool,
}

/// The body of `POST /api/cuts/{index}` this client sends: the Kerf Offsets of Line passes.
#[derive(Debug, Default, Serialize)]
pub(super) struct CutChange {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub params: Option<KerfOnly>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sub_layers: Vec<SubLayerChange>,
}

/// `params` with the Kerf Offset only.
#[derive(Debug, Serialize)]
pub(super) struct KerfOnly {
    pub kerf: f64,
}

/// A sub-layer's change, addressed by its `index`.
#[derive(Debug, Serialize)]
pub(super) struct SubLayerChange {
    pub index: i64,
    pub params: KerfOnly,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sub_layer_without_its_index_is_refused_not_taken_for_the_base_layer() {
        let entry = |sub: &str| {
            format!(
                r#"{{"index": 2, "name": "B", "kind": "normal", "layer_index": 2, "enabled": true,
                    "priority": 0, "mode": "scan", "params": {{"kerf": 0}}, "sub_layers": [{sub}]}}"#
            )
        };
        let good = entry(
            r#"{"index": 1, "name": "", "enabled": true, "mode": "cut", "params": {"kerf": 0.1}}"#,
        );
        let read: CutEntry = serde_json::from_str(&good).unwrap();
        assert_eq!(read.sub_layers[0].index, 1);
        let bad = entry(r#"{"name": "", "enabled": true, "mode": "cut", "params": {"kerf": 0.1}}"#);
        let e = serde_json::from_str::<CutEntry>(&bad).unwrap_err();
        assert!(e.to_string().contains("missing field `index`"), "{e}");
    }

    #[test]
    fn units_outside_the_specs_enum_and_unknown_modes_are_read_as_such() {
        assert!(serde_json::from_str::<UnitsReply>(r#"{"units": "in/s"}"#).is_err());
        let u: UnitsReply = serde_json::from_str(r#"{"units": "in/min"}"#).unwrap();
        assert_eq!(u.units.distance().0, "in");
        let m: Mode = serde_json::from_str(r#""laser_weld""#).unwrap();
        assert_eq!(m, Mode::Other, "a new mode is not a Line pass");
    }
}
