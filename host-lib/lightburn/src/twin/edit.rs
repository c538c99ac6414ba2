//! `POST /api/cuts/{index}` on a LightBurn twin: the body is checked whole against the spec
//! (`openapi.yaml` `paths./api/cuts/{index}.post`; `cut-settings.md` § Changing a cut) and then
//! applied whole, or refused with 400 and nothing changed.

use serde_json::{Map, Value};

use super::project::{Cut, CutKind, DisplayUnits, Mode, Params, Project};

/// What a field of `params` holds (`openapi.yaml` `LaserCutParams` types; `cut-settings.md` §
/// What can be changed, "Value ranges").
#[derive(Debug, Clone, Copy)]
enum Field {
    Number,
    Integer,
    Boolean,
    /// A power, 0–100.
    Power,
    /// `q_pulse_width`: greater than 0.
    Positive,
    /// `fiber_pulse_width`: a positive integer.
    PositiveInteger,
    /// `dither_mode`: one of the strings `GET` reports.
    DitherMode,
}

/// Every `LaserCutParams` field: what a normal cut's `params` and its sub-layers' may change
/// ("`params` — any `LaserCutParams` field", `cut-settings.md` § What can be changed).
const LASER_CUT_PARAMS: [(&str, Field); 16] = [
    ("speed", Field::Number),
    ("min_power", Field::Power),
    ("max_power", Field::Power),
    ("num_passes", Field::Integer),
    ("z_offset", Field::Number),
    ("frequency", Field::Integer),
    ("kerf", Field::Number),
    ("bi_directional", Field::Boolean),
    ("cross_hatch", Field::Boolean),
    ("min_power_2", Field::Power),
    ("max_power_2", Field::Power),
    ("laser1_enabled", Field::Boolean),
    ("laser2_enabled", Field::Boolean),
    ("alt_source", Field::Boolean),
    ("q_pulse_width", Field::Positive),
    ("fiber_pulse_width", Field::PositiveInteger),
];

/// What an image cut's `params` may change: "`params.speed`, `params.max_power`,
/// `params.dither_mode` …, plus the source and pulse fields" (`cut-settings.md` § What can be
/// changed), which the image params have but `min_power_2` (`openapi.yaml` `LaserCut.params`);
/// `dpi` is read-only.
const IMAGE_PARAMS: [(&str, Field); 9] = [
    ("speed", Field::Number),
    ("max_power", Field::Power),
    ("dither_mode", Field::DitherMode),
    ("max_power_2", Field::Power),
    ("laser1_enabled", Field::Boolean),
    ("laser2_enabled", Field::Boolean),
    ("alt_source", Field::Boolean),
    ("q_pulse_width", Field::Positive),
    ("fiber_pulse_width", Field::PositiveInteger),
];

/// The dither modes the twin's image cuts may take. The spec names `Stucki` only ("one of the
/// strings `GET` reports, e.g. `Stucki`"); the rest are the image modes of LightBurn's user
/// documentation, their wire spelling unverified.
const DITHER_MODES: [&str; 10] = [
    "Threshold",
    "Ordered",
    "Atkinson",
    "Dither",
    "Stucki",
    "Jarvis",
    "Newsprint",
    "Halftone",
    "Sketch",
    "Grayscale",
];

/// A checked change, ready to apply.
#[derive(Default)]
struct Change {
    name: Option<String>,
    enabled: Option<bool>,
    mode: Option<Mode>,
    /// Values in mm and mm/s.
    params: Params,
    /// Each by its position in the cut's `sub_layers`.
    sub_layers: Vec<(usize, SubChange)>,
}

#[derive(Default)]
struct SubChange {
    name: Option<String>,
    enabled: Option<bool>,
    mode: Option<Mode>,
    params: Params,
}

/// Change entry `index` of `project` by `body` (values in `units`; Kerf Offsets kept to
/// `kerf_resolution_mm` when given): `Ok(())` once applied, or the reason it is refused (400),
/// with nothing changed.
pub(super) fn change_cut(
    project: &mut Project,
    index: usize,
    body: &[u8],
    units: DisplayUnits,
    kerf_resolution_mm: Option<f64>,
) -> Result<(), String> {
    let cut = &project.cuts[index];
    // "Tool layers and internal cuts are rejected with 400" (`openapi.yaml` POST description).
    if let Some(why) = cut.not_editable() {
        return Err(why.into());
    }
    let body: Value = serde_json::from_slice(body).map_err(|e| format!("Invalid JSON: {e}"))?;
    let change = check(cut, &body, units)?;
    // All or nothing: checked whole above, applied whole here (`cut-settings.md` § How a
    // change is applied). One undo step, and the project is modified (same section).
    apply(&mut project.cuts[index], change, kerf_resolution_mm);
    project.modified = true;
    project.undo_steps += 1;
    Ok(())
}

/// `body` checked against `cut`: the whole body, before anything changes.
fn check(cut: &Cut, body: &Value, units: DisplayUnits) -> Result<Change, String> {
    let body = body.as_object().ok_or("the body must be a JSON object")?;
    let normal = match &cut.kind {
        CutKind::Normal { sub_layers, .. } => Some(sub_layers),
        CutKind::Image => None,
    };
    let mut change = Change::default();
    for (key, value) in body {
        match key.as_str() {
            // `name: { type: string, minLength: 1 }`.
            "name" => change.name = Some(non_empty_string(value, "name")?),
            "enabled" => change.enabled = Some(boolean(value, "enabled")?),
            // Image cuts: "`name`, `enabled`, and `params` …" only.
            "mode" if normal.is_some() => change.mode = Some(mode(value, "mode")?),
            "params" => {
                let allowed: &[(&str, Field)] = match normal {
                    Some(_) => &LASER_CUT_PARAMS,
                    None => &IMAGE_PARAMS,
                };
                change.params = params(value, allowed, "params", units)?;
            }
            "sub_layers" => match normal {
                Some(existing) => change.sub_layers = sub_layers(value, existing, units)?,
                None => return Err("an image cut has no sub_layers".into()),
            },
            "settings" => return Err("'settings' is MillMage's, not LightBurn's".into()),
            // `additionalProperties: false`.
            other => {
                return Err(format!(
                    "'{other}' is not a field of a cut that can be changed"
                ));
            }
        }
    }
    Ok(change)
}

/// The `sub_layers` of a body: each an existing sub-layer, addressed by its `index`
/// (`additionalProperties: false`, `required: [index]`, `index` ≥ 1; "Sub-layers can't be added
/// or removed", `cut-settings.md` § What can be changed).
fn sub_layers(
    value: &Value,
    existing: &[super::project::SubLayer],
    units: DisplayUnits,
) -> Result<Vec<(usize, SubChange)>, String> {
    let items = value.as_array().ok_or("'sub_layers' must be an array")?;
    let mut out = Vec::new();
    for item in items {
        let item = item.as_object().ok_or("a sub-layer must be an object")?;
        let index = item
            .get("index")
            .ok_or("a sub-layer must give its 'index'")?;
        let index = integer(index, "sub_layers[].index")?;
        if index < 1 {
            return Err(format!(
                "sub-layer index {index}: the base layer is 0, sub-layers count from 1"
            ));
        }
        let at = existing
            .iter()
            .position(|s| s.index == index)
            .ok_or_else(|| {
                format!("the cut has no sub-layer {index} (sub-layers cannot be added)")
            })?;
        let mut sub = SubChange::default();
        for (key, value) in item {
            let field = format!("sub_layers[{index}].{key}");
            match key.as_str() {
                "index" => {}
                "name" => sub.name = Some(string(value, &field)?),
                "enabled" => sub.enabled = Some(boolean(value, &field)?),
                "mode" => sub.mode = Some(mode(value, &field)?),
                "params" => sub.params = params(value, &LASER_CUT_PARAMS, &field, units)?,
                other => {
                    return Err(format!(
                        "'{other}' is not a field of a sub-layer that can be changed"
                    ));
                }
            }
        }
        out.push((at, sub));
    }
    Ok(out)
}

/// A `params` object whose every field is in `allowed` and holds a value of its kind,
/// converted from the display units to mm and mm/s.
fn params(
    value: &Value,
    allowed: &[(&str, Field)],
    at: &str,
    units: DisplayUnits,
) -> Result<Params, String> {
    let given = value
        .as_object()
        .ok_or_else(|| format!("'{at}' must be an object"))?;
    let mut out = Map::new();
    for (key, v) in given {
        let name = format!("{at}.{key}");
        let Some(&(_, kind)) = allowed.iter().find(|(k, _)| k == key) else {
            return Err(match key.as_str() {
                "dpi" => format!("'{name}' is read-only"),
                _ => format!("'{name}' cannot be changed here"),
            });
        };
        let checked = match kind {
            Field::Number => {
                let x = number(v, &name)?;
                Value::from(x / units.factor(key))
            }
            Field::Integer => Value::from(integer(v, &name)?),
            Field::Boolean => Value::from(boolean(v, &name)?),
            Field::Power => {
                let x = number(v, &name)?;
                if !(0.0..=100.0).contains(&x) {
                    return Err(format!("'{name}' is a power, 0 to 100: not {x}"));
                }
                Value::from(x)
            }
            Field::Positive => {
                let x = number(v, &name)?;
                if x <= 0.0 {
                    return Err(format!("'{name}' must be greater than 0"));
                }
                Value::from(x)
            }
            Field::PositiveInteger => {
                let n = integer(v, &name)?;
                if n <= 0 {
                    return Err(format!("'{name}' must be a positive integer"));
                }
                Value::from(n)
            }
            Field::DitherMode => {
                let s = string(v, &name)?;
                if !DITHER_MODES.contains(&s.as_str()) {
                    return Err(format!("'{name}': unknown dither mode {s:?}"));
                }
                Value::from(s)
            }
        };
        out.insert(key.clone(), checked);
    }
    Ok(out)
}

fn number(v: &Value, name: &str) -> Result<f64, String> {
    v.as_f64()
        .ok_or_else(|| format!("'{name}' must be a number"))
}

/// A JSON Schema `integer`: a number with no fraction.
fn integer(v: &Value, name: &str) -> Result<i64, String> {
    match (v.as_i64(), v.as_f64()) {
        (Some(n), _) => Ok(n),
        (None, Some(x)) if x.fract() == 0.0 && x.abs() < 9e15 => Ok(x as i64),
        _ => Err(format!("'{name}' must be an integer")),
    }
}

fn boolean(v: &Value, name: &str) -> Result<bool, String> {
    v.as_bool()
        .ok_or_else(|| format!("'{name}' must be true or false"))
}

fn string(v: &Value, name: &str) -> Result<String, String> {
    v.as_str()
        .map(str::to_owned)
        .ok_or_else(|| format!("'{name}' must be a string"))
}

fn non_empty_string(v: &Value, name: &str) -> Result<String, String> {
    let s = string(v, name)?;
    match s.is_empty() {
        true => Err(format!("'{name}' must not be empty")),
        false => Ok(s),
    }
}

/// `mode: { enum: [cut, scan, offset] }`.
fn mode(v: &Value, name: &str) -> Result<Mode, String> {
    v.as_str()
        .and_then(Mode::editable)
        .ok_or_else(|| format!("'{name}' must be \"cut\", \"scan\" or \"offset\""))
}

/// Apply a checked change: "Only the fields present in the body change".
fn apply(cut: &mut Cut, change: Change, kerf_resolution_mm: Option<f64>) {
    let keep = |mut params: Params| {
        if let (Some(step), Some(kerf)) = (kerf_resolution_mm, params.get_mut("kerf"))
            && let Some(mm) = kerf.as_f64()
        {
            *kerf = Value::from((mm / step).round() * step);
        }
        params
    };
    if let Some(name) = change.name {
        cut.name = name;
    }
    if let Some(enabled) = change.enabled {
        cut.enabled = enabled;
    }
    cut.params.extend(keep(change.params));
    if let CutKind::Normal { mode, sub_layers } = &mut cut.kind {
        if let Some(m) = change.mode {
            *mode = m;
        }
        for (at, sub) in change.sub_layers {
            let target = &mut sub_layers[at];
            if let Some(name) = sub.name {
                target.name = name;
            }
            if let Some(enabled) = sub.enabled {
                target.enabled = enabled;
            }
            if let Some(m) = sub.mode {
                target.mode = m;
            }
            target.params.extend(keep(sub.params));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::project::INTERNAL_CUT;
    use super::*;

    fn change(index: usize, body: &str) -> (Result<(), String>, Project) {
        let mut p = Project::example();
        let r = change_cut(&mut p, index, body.as_bytes(), DisplayUnits::MmPerS, None);
        (r, p)
    }

    #[test]
    fn a_body_with_one_bad_field_changes_nothing() {
        let before = Project::example();
        for body in [
            r#"{"params": {"kerf": 0.1, "max_power": 101}}"#,
            r#"{"params": {"kerf": 0.1}, "colour": 1}"#,
            r#"{"params": {"kerf": 0.1, "kerf_mm": 0.1}}"#,
            r#"{"params": {"kerf": "0.1"}}"#,
            r#"{"params": {"kerf": 0.1}, "name": ""}"#,
            r#"{"params": {"num_passes": 1.5}}"#,
            r#"{"params": {"q_pulse_width": 0}}"#,
            r#"{"params": {"fiber_pulse_width": -1}}"#,
            r#"{"params": {"kerf": 0.1}, "sub_layers": [{"index": 3, "params": {"kerf": 0.1}}]}"#,
            r#"{"sub_layers": [{"params": {"kerf": 0.1}}]}"#,
            r#"{"sub_layers": [{"index": 0, "params": {"kerf": 0.1}}]}"#,
            r#"{"sub_layers": [{"index": 2, "kerf": 0.1}]}"#,
            r#"{"mode": "image"}"#,
            r#"{"settings": {}}"#,
            "[]",
            "kerf",
        ] {
            let (r, p) = change(2, body);
            assert!(r.is_err(), "{body}");
            assert_eq!(p, before, "{body}: nothing changed");
        }
    }

    #[test]
    fn tool_layers_the_internal_cut_and_image_only_fields_are_refused() {
        let (r, _) = change(30, r#"{"params": {"kerf": 0.1}}"#);
        assert!(r.unwrap_err().contains("tool layers"));
        let (r, _) = change(INTERNAL_CUT, r#"{"params": {"kerf": 0.1}}"#);
        assert!(r.unwrap_err().contains("internal"));
        let (r, _) = change(33, r#"{"params": {"kerf": 0.1}}"#);
        assert!(r.is_err(), "an image cut has no Kerf Offset");
        let (r, _) = change(33, r#"{"params": {"dpi": 300}}"#);
        assert!(r.unwrap_err().contains("read-only"));
        let (r, _) = change(33, r#"{"params": {"min_power_2": 1}}"#);
        assert!(r.is_err());
        let (r, p) = change(
            33,
            r#"{"params": {"dither_mode": "Jarvis", "max_power": 30}}"#,
        );
        r.unwrap();
        assert_eq!(p.cuts[33].params["dither_mode"], "Jarvis");
    }

    #[test]
    fn a_good_body_changes_what_it_names_in_mm() {
        let mut p = Project::example();
        let body = br#"{"sub_layers": [{"index": 2, "params": {"kerf": 0.003}}], "name": "B"}"#;
        change_cut(&mut p, 2, body, DisplayUnits::InPerMin, None).unwrap();
        let CutKind::Normal { sub_layers, .. } = &p.cuts[2].kind else {
            panic!("normal")
        };
        assert!((sub_layers[1].params["kerf"].as_f64().unwrap() - 0.0762).abs() < 1e-12);
        assert_eq!(
            sub_layers[0].params["kerf"], 0.0,
            "sub-layer 1 is left alone"
        );
        assert_eq!(p.cuts[2].params["kerf"], 0.0, "so is the base layer");
        assert_eq!(p.cuts[2].name, "B");
        assert!(p.modified);
        assert_eq!(p.undo_steps, 1);
    }
}
