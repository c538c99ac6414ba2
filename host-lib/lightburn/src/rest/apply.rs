//! `kerfmeter lightburn apply`: choose LightBurn's Line layers, refuse those already compensated
//! unless told otherwise, and write each one's Kerf Offset with one `POST /api/cuts/{index}`,
//! confirmed by the entry LightBurn answers.
//!
//! A layer is named by its slot (`layer_index`, the number LightBurn shows) or its name; the
//! request goes to its entry's `index` (its position in the cut list). The two differ (the spec
//! promises nothing of their order, and image cuts carry their layer's slot at another
//! position), so each is used for what it means, and LightBurn's answer must name the entry and
//! the slot asked for.

use std::collections::BTreeSet;

use kerfmeter_plan::selectors;
use serde::Serialize;

use super::wire::{self, CutChange, CutEntry, KerfOnly, Kind, Mode, SubLayerChange};
use super::{Client, LightBurnError, Pairing, Result, parse, protocol, refused};

/// Two Kerf Offsets closer than this (display units) are the same: LightBurn may keep a value
/// in single precision (7 digits), and a Kerf Offset is far above a millionth of a mm or inch.
const SAME_OFFSET: f64 = 1e-6;

/// What to do with a layer that already has a Kerf Offset.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ExistingOffset {
    /// Refuse: the project is already compensated (the default).
    #[default]
    Refuse,
    /// Replace it by this kerf's.
    Replace,
    /// Add this kerf's to it.
    Add,
}

/// A layer whose Kerf Offset was set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LayerSet {
    /// The cut entry's global index (`/api/cuts/{index}`).
    pub cut_index: i64,
    /// The layer's slot.
    pub layer_index: i64,
    /// Its name.
    pub name: String,
    /// Its line passes' Kerf Offsets before, display units (base first, then sub-layers).
    pub before: Vec<f64>,
    /// Its line passes' Kerf Offsets now, display units, as LightBurn answered the change.
    pub after: Vec<f64>,
}

/// What `apply` did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Applied {
    /// The kerf, µm.
    pub kerf_um: f64,
    /// The display distance unit of the values (`mm` or `in`).
    pub unit: &'static str,
    /// The Kerf Offset for it in that unit: half the kerf, positive (outward).
    pub kerf_offset: f64,
    /// The layers set.
    pub layers: Vec<LayerSet>,
    /// LightBurn's project is modified and not saved: each change marks it so, and is in the
    /// next job sent from LightBurn, not in one already sent (`cut-settings.md` § How a change
    /// is applied).
    pub project_modified: bool,
}

/// A Line pass of a cut entry: `None` for the layer's own, else the sub-layer's index.
struct LinePass {
    sub_layer: Option<i64>,
    kerf: f64,
}

/// A layer's normal cut entry and its Line passes (none: not a Line layer).
struct LineCut {
    index: i64,
    layer_index: i64,
    name: String,
    passes: Vec<LinePass>,
}

/// Set the Kerf Offset of LightBurn's Line layers for `kerf_um`: the layers named in `layers`
/// (slot index or name), or every Line layer in use.
pub fn apply_kerf(
    client: &Client,
    pairing: &Pairing,
    kerf_um: f64,
    layers: &[String],
    existing: ExistingOffset,
) -> Result<Applied> {
    let secret = pairing.secret.as_str();
    let units: wire::UnitsReply = client.get(secret, "GET /api/units")?;
    let (unit, per_mm) = units.units.distance();
    let cuts = line_cuts(client, secret)?;
    let chosen = choose(client, secret, cuts, layers)?;
    refuse_compensated(&chosen, existing, unit, per_mm)?;
    let offset = kerf_um / 2000.0 * per_mm;
    let mut set = Vec::new();
    for cut in chosen {
        let want: Vec<f64> = cut
            .passes
            .iter()
            .map(|p| match existing {
                ExistingOffset::Add => p.kerf + offset,
                _ => offset,
            })
            .collect();
        let before = cut.passes.iter().map(|p| p.kerf).collect();
        let layer = |after| LayerSet {
            cut_index: cut.index,
            layer_index: cut.layer_index,
            name: cut.name.clone(),
            before,
            after,
        };
        match post_cut(client, secret, &cut, &want) {
            Ok(after) => set.push(layer(after)),
            Err(cause @ LightBurnError::NotConfirmed { .. }) => {
                // Changed, but not as asked: it counts among the layers changed.
                set.push(layer(want));
                return Err(partly_applied(cause, &set, unit));
            }
            Err(cause) => return Err(partly_applied(cause, &set, unit)),
        }
    }
    Ok(Applied {
        kerf_um,
        unit,
        kerf_offset: offset,
        project_modified: !set.is_empty(),
        layers: set,
    })
}

/// `POST /api/cuts/{index}` setting the Line passes of `cut` to `want`; their Kerf Offsets in
/// the entry LightBurn answers.
fn post_cut(client: &Client, secret: &str, cut: &LineCut, want: &[f64]) -> Result<Vec<f64>> {
    let request = format!("POST /api/cuts/{}", cut.index);
    let answer = client.signed_call(secret, &request, Some(&change(cut, want)))?;
    match answer.status {
        200 => confirm(&request, cut, want, &parse(&request, &answer.text)?),
        409 => Err(LightBurnError::EditorOpen),
        401 | 403 => Err(LightBurnError::Unauthorized {
            status: answer.status,
        }),
        status => Err(refused(&request, status, &answer.text)),
    }
}

/// The Kerf Offsets `entry` (LightBurn's answer to a change of `cut`) holds for `cut`'s Line
/// passes, if it is `cut`'s entry and they are `want`.
fn confirm(request: &str, cut: &LineCut, want: &[f64], entry: &CutEntry) -> Result<Vec<f64>> {
    let differs = |message: String| LightBurnError::NotConfirmed {
        request: request.into(),
        message,
    };
    if (entry.index, entry.layer_index) != (cut.index, cut.layer_index) {
        return Err(differs(format!(
            "it is entry {} of layer {}, not entry {} of layer {}",
            entry.index, entry.layer_index, cut.index, cut.layer_index
        )));
    }
    let mut held = Vec::new();
    for (pass, &w) in cut.passes.iter().zip(want) {
        let (what, kerf) = match pass.sub_layer {
            None => ("the layer's Kerf Offset".to_string(), entry.params.kerf),
            Some(i) => (
                format!("sub-layer {i}'s Kerf Offset"),
                entry
                    .sub_layers
                    .iter()
                    .find(|s| s.index == i)
                    .and_then(|s| s.params.kerf),
            ),
        };
        match kerf {
            Some(k) if (k - w).abs() <= SAME_OFFSET => held.push(k),
            Some(k) => return Err(differs(format!("{what} is {k}, not {w}"))),
            None => return Err(differs(format!("{what} is missing"))),
        }
    }
    Ok(held)
}

/// `cause`, saying which layers of `set` were changed before it and what they held (as is when
/// none were).
fn partly_applied(cause: LightBurnError, set: &[LayerSet], unit: &str) -> LightBurnError {
    if set.is_empty() {
        return cause;
    }
    let each: Vec<String> = set
        .iter()
        .map(|l| {
            let before: Vec<String> = l.before.iter().map(f64::to_string).collect();
            format!(
                "layer {} \"{}\" (was {} {unit})",
                l.layer_index,
                l.name,
                before.join(", ")
            )
        })
        .collect();
    LightBurnError::PartlyApplied {
        done: each.join(", "),
        cause: Box::new(cause),
    }
}

/// Every layer's normal cut entry from `GET /api/cuts`, with its Line passes (mode `cut`). The
/// internal cut (`layer_index` -1) is no layer; image cuts are not Line passes.
fn line_cuts(client: &Client, secret: &str) -> Result<Vec<LineCut>> {
    const REQ: &str = "GET /api/cuts";
    let text = client.get_text(secret, REQ)?;
    let product: wire::Product = parse(REQ, &text)?;
    if product.product != "lightburn" {
        return Err(protocol(
            REQ,
            "not LightBurn's cut list (product is not \"lightburn\")",
        ));
    }
    let list: wire::CutList = parse(REQ, &text)?;
    let line = |mode: Option<Mode>| mode == Some(Mode::Cut);
    Ok(list
        .cuts
        .into_iter()
        .filter(|c| c.kind == Kind::Normal && c.layer_index >= 0)
        .map(|c| {
            let mut passes = Vec::new();
            if line(c.mode) {
                passes.push(LinePass {
                    sub_layer: None,
                    kerf: c.params.kerf.unwrap_or(0.0),
                });
            }
            for s in c.sub_layers.iter().filter(|s| line(Some(s.mode))) {
                passes.push(LinePass {
                    sub_layer: Some(s.index),
                    kerf: s.params.kerf.unwrap_or(0.0),
                });
            }
            LineCut {
                index: c.index,
                layer_index: c.layer_index,
                name: c.name,
                passes,
            }
        })
        .collect())
}

/// The cuts to set: those `layers` name (by slot index or whole name, or a comma-separated list
/// of them), or every Line layer in use.
fn choose(
    client: &Client,
    secret: &str,
    cuts: Vec<LineCut>,
    layers: &[String],
) -> Result<Vec<LineCut>> {
    if layers.is_empty() {
        let answer: wire::LayersReply = client.get(secret, "GET /api/layers")?;
        // `/api/layers` numbers slots: a cut's `layer_index`, not its `index`.
        let in_use: BTreeSet<i64> = answer
            .layers
            .iter()
            .filter(|l| l.in_use)
            .map(|l| l.index)
            .collect();
        let chosen: Vec<LineCut> = cuts
            .into_iter()
            .filter(|c| !c.passes.is_empty() && in_use.contains(&c.layer_index))
            .collect();
        if chosen.is_empty() {
            return Err(LightBurnError::Layers(
                "the open LightBurn project uses no Line layer: nothing to set".into(),
            ));
        }
        return Ok(chosen);
    }
    let mut problems = Vec::new();
    let matches = |c: &LineCut, s: &str| c.layer_index.to_string() == s.trim() || c.name == s;
    // A value names one layer whole (a name may hold a comma), or lists several by commas: the
    // rule `kerfmeter dilate --layers` applies to a project file.
    let wanted = selectors::layer_selectors(layers, |w| cuts.iter().any(|c| matches(c, w)))
        .map_err(|e| LightBurnError::Layers(format!("--layers: {e}")))?;
    let hint = match layers.iter().any(|v| v.contains(',')) {
        true => format!(" ({})", selectors::SPLIT_HINT),
        false => String::new(),
    };
    for &s in &wanted {
        // Every cut entry it names is set, so every one must be a Line layer (two layers may
        // share a name).
        let mut hits = cuts.iter().filter(|c| matches(c, s)).peekable();
        if hits.peek().is_none() {
            problems.push(format!("no layer has the index or name \"{s}\"{hint}"));
        }
        for c in hits.filter(|c| c.passes.is_empty()) {
            let problem = format!(
                "layer {} \"{}\" is not a Line layer: LightBurn applies a Kerf Offset to Line passes only",
                c.layer_index, c.name
            );
            if !problems.contains(&problem) {
                problems.push(problem);
            }
        }
    }
    if !problems.is_empty() {
        return Err(LightBurnError::Layers(format!(
            "--layers: {}",
            problems.join("; ")
        )));
    }
    Ok(cuts
        .into_iter()
        .filter(|c| wanted.iter().any(|s| matches(c, s)))
        .collect())
}

/// Refuse layers that already have a Kerf Offset, unless told what to do with it; `unit` is the
/// display unit, `per_mm` of it in a millimetre.
fn refuse_compensated(
    chosen: &[LineCut],
    existing: ExistingOffset,
    unit: &str,
    per_mm: f64,
) -> Result<()> {
    let found: Vec<String> = chosen
        .iter()
        .filter(|c| c.passes.iter().any(|p| p.kerf != 0.0))
        .map(|c| {
            let v: Vec<String> = c.passes.iter().map(|p| p.kerf.to_string()).collect();
            format!(
                "layer {} \"{}\": {} {unit}",
                c.layer_index,
                c.name,
                v.join(", ")
            )
        })
        .collect();
    if found.is_empty() || existing != ExistingOffset::Refuse {
        return Ok(());
    }
    let offsets_um = chosen
        .iter()
        .flat_map(|c| &c.passes)
        .filter(|p| p.kerf != 0.0)
        .map(|p| p.kerf / per_mm * 1000.0)
        .collect();
    Err(LightBurnError::AlreadyCompensated { found, offsets_um })
}

/// The body of `POST /api/cuts/{index}`: the new Kerf Offset of each Line pass, sub-layers by
/// their own `index`.
fn change(cut: &LineCut, want: &[f64]) -> CutChange {
    let mut change = CutChange::default();
    for (p, &kerf) in cut.passes.iter().zip(want) {
        match p.sub_layer {
            None => change.params = Some(KerfOnly { kerf }),
            Some(index) => change.sub_layers.push(SubLayerChange {
                index,
                params: KerfOnly { kerf },
            }),
        }
    }
    change
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Layer 2's entry at position 27, a Fill layer whose sub-layer 2 is a Line pass.
    fn badge() -> LineCut {
        LineCut {
            index: 27,
            layer_index: 2,
            name: "Badge".into(),
            passes: vec![LinePass {
                sub_layer: Some(2),
                kerf: 0.0,
            }],
        }
    }

    fn answered(index: i64, layer_index: i64, sub_kerf: &str) -> CutEntry {
        let text = format!(
            r#"{{"index": {index}, "name": "Badge", "kind": "normal", "layer_index": {layer_index},
                "enabled": true, "priority": 0, "mode": "scan", "params": {{"kerf": 0}},
                "sub_layers": [{{"index": 1, "name": "", "enabled": true, "mode": "scan", "params": {{"kerf": 0}}}},
                               {{"index": 2, "name": "", "enabled": true, "mode": "cut", "params": {sub_kerf}}}]}}"#
        );
        serde_json::from_str(&text).unwrap()
    }

    #[test]
    fn the_answered_entry_must_be_the_one_changed_holding_what_was_written() {
        let cut = badge();
        let held = confirm(
            "POST",
            &cut,
            &[0.075],
            &answered(27, 2, r#"{"kerf": 0.075}"#),
        );
        assert_eq!(held.unwrap(), [0.075]);
        // Single precision is the same offset.
        let f32_kerf = f64::from(0.075_f32);
        let held = confirm(
            "POST",
            &cut,
            &[0.075],
            &answered(27, 2, &format!(r#"{{"kerf": {f32_kerf}}}"#)),
        );
        assert_eq!(held.unwrap(), [f32_kerf]);
        for (entry, says) in [
            (
                answered(2, 2, r#"{"kerf": 0.075}"#),
                "entry 2 of layer 2, not entry 27",
            ),
            (
                answered(27, 27, r#"{"kerf": 0.075}"#),
                "entry 27 of layer 27, not entry 27 of layer 2",
            ),
            (
                answered(27, 2, r#"{"kerf": 0.08}"#),
                "sub-layer 2's Kerf Offset is 0.08, not 0.075",
            ),
            (
                answered(27, 2, "{}"),
                "sub-layer 2's Kerf Offset is missing",
            ),
        ] {
            let e = confirm("POST", &cut, &[0.075], &entry).unwrap_err();
            assert!(matches!(e, LightBurnError::NotConfirmed { .. }), "{e}");
            assert!(e.to_string().contains(says), "{e}");
        }
    }

    #[test]
    fn a_sub_layer_is_addressed_by_its_own_index() {
        let body = serde_json::to_value(change(&badge(), &[0.1])).unwrap();
        assert_eq!(
            body,
            serde_json::json!({ "sub_layers": [{ "index": 2, "params": { "kerf": 0.1 } }] })
        );
    }
}
