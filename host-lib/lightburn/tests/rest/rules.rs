//! Each rule of LightBurn's REST spec the twin enforces, asked of it over HTTP with no client
//! code between (the file and section of the spec are cited in the twin's source).

use kerfmeter_lightburn::twin::{DisplayUnits, LightBurnTwin, LightBurnTwinOptions};
use serde_json::{Value, json};

use crate::{fake_lightburn, pair_for, raw, settle, token};

/// A twin and a secret with every capability.
fn twin_and_secret() -> (String, LightBurnTwin, String) {
    let (host, twin) = fake_lightburn();
    let (status, secret) = pair_for(&host, json!(["state", "project", "project_write"]));
    assert_eq!(status, 200);
    (host, twin, secret)
}

#[test]
fn pairing_wants_a_name_and_a_non_empty_list_of_known_capabilities() {
    let (host, twin) = fake_lightburn();
    for body in [
        json!({ "capabilities": ["project"] }),
        json!({ "application_name": "t" }),
        json!({ "application_name": "t", "capabilities": [] }),
        json!({ "application_name": "t", "capabilities": ["project", "admin"] }),
        json!({ "application_name": "t", "capabilities": [1] }),
        json!({ "application_name": "t", "capabilities": "project" }),
    ] {
        let (status, answer) = raw(&host, "POST", "/api/connect", None, Some(&body.to_string()));
        assert_eq!(status, 400, "{body}");
        assert!(answer["error"].is_string(), "{body}: an ErrorResponse");
    }
    assert!(twin.authorisations().is_empty(), "no dialog was shown");
}

#[test]
fn any_list_of_known_capabilities_goes_to_the_dialog_and_gets_its_own_secret() {
    let (host, twin) = fake_lightburn();
    let mut secrets = Vec::new();
    for caps in [
        json!(["project"]),
        json!(["upload"]),
        json!(["state"]),
        json!(["project_write"]),
        json!(["state", "project", "project_write"]),
        json!(["state", "project", "project_write"]),
    ] {
        let (status, secret) = pair_for(&host, caps.clone());
        assert_eq!(status, 200, "{caps}");
        assert!(!secrets.contains(&secret), "{caps}: a distinct secret");
        secrets.push(secret);
    }
    assert_eq!(twin.authorisations().len(), 6, "none revoked by the next");
    twin.set_options(|o| o.declines = true);
    assert_eq!(pair_for(&host, json!(["project"])).0, 403);
    // A LightBurn from before `project_write` does not know it.
    twin.set_options(|o| {
        o.declines = false;
        o.before_project_write = true;
    });
    assert_eq!(pair_for(&host, json!(["project", "project_write"])).0, 400);
    assert_eq!(pair_for(&host, json!(["project"])).0, 200);
}

#[test]
fn every_authorisation_failure_is_the_same_bare_401() {
    settle();
    let (host, twin, secret) = twin_and_secret();
    let (_, project_only) = pair_for(&host, json!(["project"]));
    let (_, revoked) = pair_for(&host, json!(["state", "project"]));
    assert!(twin.revoke(&revoked));
    let get_cuts = |t: Option<&str>| raw(&host, "GET", "/api/cuts", t, None);
    assert_eq!(get_cuts(Some(&token(&secret, 0))).0, 200);
    let failures = [
        get_cuts(None),
        get_cuts(Some("")),
        get_cuts(Some(&token("not the secret", 0))),
        get_cuts(Some(&token(&revoked, 0))),
        get_cuts(Some(&token(&secret, -2))),
        get_cuts(Some(&token(&secret, 1))),
        // Outside the granted capabilities: `state` and `project_write`.
        raw(
            &host,
            "GET",
            "/api/units",
            Some(&token(&project_only, 0)),
            None,
        ),
        raw(
            &host,
            "POST",
            "/api/cuts/0",
            Some(&token(&project_only, 0)),
            Some(r#"{"params": {"kerf": 0.1}}"#),
        ),
    ];
    for (status, body) in &failures {
        assert_eq!(*status, 401);
        assert_eq!(body, &failures[0].1, "no failure says more than another");
    }
    assert_eq!(twin.project().cuts[0].params["kerf"], 0.0);
}

#[test]
fn a_token_is_good_for_the_twins_current_and_previous_minute_only() {
    settle();
    let (host, twin, secret) = twin_and_secret();
    let get_units = |minutes| {
        raw(
            &host,
            "GET",
            "/api/units",
            Some(&token(&secret, minutes)),
            None,
        )
        .0
    };
    // The twin's clock a whole minute behind this computer's: this computer's minute is one
    // LightBurn has not reached; its previous one is LightBurn's current.
    twin.set_options(|o| o.clock_offset_s = -60);
    assert_eq!(get_units(0), 401);
    assert_eq!(get_units(-1), 200);
    assert_eq!(get_units(-2), 200);
    assert_eq!(get_units(-3), 401);
}

#[test]
fn project_write_alone_changes_cuts_but_reads_nothing() {
    let (host, _twin) = fake_lightburn();
    let (_, write_only) = pair_for(&host, json!(["project_write"]));
    let t = token(&write_only, 0);
    let (status, entry) = raw(
        &host,
        "POST",
        "/api/cuts/0",
        Some(&t),
        Some(r#"{"enabled": false}"#),
    );
    assert_eq!(status, 200);
    assert_eq!(entry["enabled"], false);
    assert_eq!(raw(&host, "GET", "/api/cuts/0", Some(&t), None).0, 401);
    assert_eq!(raw(&host, "GET", "/api/layers", Some(&t), None).0, 401);
}

#[test]
fn the_cut_list_is_fixed_30_cut_2_tool_1_internal_30_image() {
    let (host, _twin, secret) = twin_and_secret();
    let (status, list) = raw(&host, "GET", "/api/cuts", Some(&token(&secret, 0)), None);
    assert_eq!(status, 200);
    assert_eq!(list["product"], "lightburn");
    let cuts = list["cuts"].as_array().unwrap();
    assert_eq!(cuts.len(), 63);
    for (i, c) in cuts.iter().enumerate() {
        for field in [
            "index",
            "name",
            "kind",
            "layer_index",
            "enabled",
            "priority",
            "params",
        ] {
            assert!(c.get(field).is_some(), "entry {i} has its {field}");
        }
        assert_eq!(c["index"], i, "index is the position in the list");
        let normal = c["kind"] == "normal";
        assert_eq!(
            c.get("mode").is_some(),
            normal,
            "entry {i}: mode only on normal cuts"
        );
        assert_eq!(
            c.get("sub_layers").is_some(),
            normal,
            "entry {i}: sub_layers likewise"
        );
    }
    let kinds: Vec<(&str, &str, i64)> = cuts
        .iter()
        .map(|c| {
            let mode = c["mode"].as_str().unwrap_or("-");
            (
                c["kind"].as_str().unwrap(),
                mode,
                c["layer_index"].as_i64().unwrap(),
            )
        })
        .collect();
    assert!(kinds[..30].iter().all(|k| k.0 == "normal" && k.1 != "tool"));
    assert_eq!(
        &kinds[30..32],
        [("normal", "tool", 30), ("normal", "tool", 31)]
    );
    assert_eq!(kinds[32].2, -1, "the internal cut");
    assert!(
        kinds[33..]
            .iter()
            .enumerate()
            .all(|(s, k)| k.0 == "image" && k.2 == s as i64)
    );
    // Every `LaserCutParams` field, the source and pulse ones included.
    let params = cuts[0]["params"].as_object().unwrap();
    assert_eq!(params.len(), 16, "{params:?}");
    let sub = &cuts[2]["sub_layers"][1];
    assert_eq!(
        (sub["index"].clone(), sub["mode"].clone()),
        (json!(2), json!("cut"))
    );
    assert_eq!(sub["params"].as_object().unwrap().len(), 16);
    // One entry, bare; out of range 404; not an index 400.
    let one = raw(&host, "GET", "/api/cuts/35", Some(&token(&secret, 0)), None);
    assert_eq!(one, (200, cuts[35].clone()));
    assert_eq!(
        raw(&host, "GET", "/api/cuts/63", Some(&token(&secret, 0)), None).0,
        404
    );
    assert_eq!(
        raw(&host, "GET", "/api/cuts/-1", Some(&token(&secret, 0)), None).0,
        400
    );
}

#[test]
fn layers_are_all_32_slots_with_their_shape_counts() {
    let (host, _twin, secret) = twin_and_secret();
    let (_, answer) = raw(&host, "GET", "/api/layers", Some(&token(&secret, 0)), None);
    let layers = answer["layers"].as_array().unwrap();
    assert_eq!(layers.len(), 32);
    for (slot, l) in layers.iter().enumerate() {
        assert_eq!(l["index"], slot);
        let count = l["shape_count"].as_u64().unwrap();
        assert_eq!(l["in_use"], count > 0, "slot {slot}");
        let colour = l["color"].as_str().unwrap();
        assert!(colour.len() == 7 && colour.starts_with('#'), "{colour}");
    }
    let in_use: Vec<u64> = layers
        .iter()
        .filter(|l| l["in_use"] == true)
        .map(|l| l["index"].as_u64().unwrap())
        .collect();
    assert_eq!(in_use, [0, 1, 2, 4, 30]);
    assert_eq!(layers[30]["type"], "tool");
}

#[test]
fn units_are_the_specs_enum_and_cut_values_follow_them() {
    let (host, twin, secret) = twin_and_secret();
    let t = token(&secret, 0);
    for (units, wire) in [
        (DisplayUnits::MmPerS, "mm/s"),
        (DisplayUnits::MmPerMin, "mm/min"),
        (DisplayUnits::InPerMin, "in/min"),
    ] {
        twin.set_options(|o| o.units = units);
        assert_eq!(
            raw(&host, "GET", "/api/units", Some(&t), None).1,
            json!({ "units": wire })
        );
    }
    let old = raw(&host, "GET", "/api/cuts/3", Some(&t), None).1;
    assert!((old["params"]["kerf"].as_f64().unwrap() - 0.05 / 25.4).abs() < 1e-15);
    let project = raw(&host, "GET", "/api/project", Some(&t), None).1;
    assert_eq!(
        project["units"],
        json!({ "distance": "in", "speed": "in/min" })
    );
}

#[test]
fn a_change_is_checked_whole_and_refused_whole() {
    let (host, twin, secret) = twin_and_secret();
    let before = twin.project();
    let post = |index: &str, body: &str| {
        raw(
            &host,
            "POST",
            &format!("/api/cuts/{index}"),
            Some(&token(&secret, 0)),
            Some(body),
        )
    };
    for (index, body) in [
        // Tool layers and the internal cut.
        ("30", r#"{"params": {"kerf": 0.1}}"#),
        ("32", r#"{"params": {"kerf": 0.1}}"#),
        // additionalProperties: false, at the top and in a sub-layer.
        ("0", r#"{"params": {"kerf": 0.1}, "kerf": 0.1}"#),
        ("2", r#"{"sub_layers": [{"index": 2, "kerf": 0.1}]}"#),
        // A sub-layer that is not there, or not addressed.
        (
            "0",
            r#"{"sub_layers": [{"index": 1, "params": {"kerf": 0.1}}]}"#,
        ),
        ("2", r#"{"sub_layers": [{"params": {"kerf": 0.1}}]}"#),
        // Good fields with one bad value: nothing of it applies.
        (
            "2",
            r#"{"params": {"kerf": 0.1}, "sub_layers": [{"index": 2, "params": {"max_power": 120}}]}"#,
        ),
        ("0", r#"{"params": {"kerf": 0.1, "speed": "fast"}}"#),
        // An image cut has no Kerf Offset, its dpi is read-only.
        ("35", r#"{"params": {"kerf": 0.1}}"#),
        ("35", r#"{"params": {"dpi": 600}}"#),
        ("0", "not JSON"),
    ] {
        let (status, answer) = post(index, body);
        assert_eq!(status, 400, "{index} {body}: {answer}");
        assert!(answer["error"].is_string());
    }
    assert_eq!(
        twin.project(),
        before,
        "nothing changed, the project is not modified"
    );
    assert!(twin.posts().is_empty());
    assert_eq!(post("63", r#"{"enabled": false}"#).0, 404);
    twin.set_options(|o| o.editor_open = true);
    assert_eq!(post("0", r#"{"params": {"kerf": 0.1}}"#).0, 409);
    assert_eq!(twin.project(), before);
}

#[test]
fn a_change_answers_the_updated_entry_and_marks_the_project_modified() {
    let (host, twin, secret) = twin_and_secret();
    let t = token(&secret, 0);
    let body = r#"{"name": "Badge", "sub_layers": [{"index": 2, "params": {"kerf": 0.1}}]}"#;
    let (status, answered) = raw(&host, "POST", "/api/cuts/2", Some(&t), Some(body));
    assert_eq!(status, 200);
    let (_, entry) = raw(&host, "GET", "/api/cuts/2", Some(&t), None);
    assert_eq!(answered, entry, "the entry as GET gives it");
    assert_eq!(entry["name"], "Badge");
    assert_eq!(entry["sub_layers"][1]["params"]["kerf"], 0.1);
    assert_eq!(entry["sub_layers"][0]["params"]["kerf"], 0.0);
    let project: Value = raw(&host, "GET", "/api/project", Some(&t), None).1;
    assert_eq!(project["modified"], true);
    assert_eq!(twin.project().undo_steps, 1);
}

#[test]
fn the_list_position_and_the_layer_slot_are_told_apart() {
    // The spec promises no order between `index` and `layer_index`: with the cut layers listed
    // last slot first, a change sent to a layer's slot number reaches another layer.
    let (host, twin, secret) = twin_and_secret();
    twin.edit_project(|p| p.cuts[..30].reverse());
    let t = token(&secret, 0);
    let (_, entry) = raw(
        &host,
        "POST",
        "/api/cuts/0",
        Some(&t),
        Some(r#"{"params": {"kerf": 0.1}}"#),
    );
    assert_eq!(
        (entry["index"].clone(), entry["layer_index"].clone()),
        (json!(0), json!(29))
    );
    // And as LightBurn lists them, the image cut of slot 2 is entry 35, not 2.
    let fresh = LightBurnTwin::start(LightBurnTwinOptions::default()).unwrap();
    let (_, s) = pair_for(fresh.host(), json!(["project"]));
    let (_, image) = raw(
        fresh.host(),
        "GET",
        "/api/cuts/35",
        Some(&token(&s, 0)),
        None,
    );
    assert_eq!(
        (image["kind"].clone(), image["layer_index"].clone()),
        (json!("image"), json!(2))
    );
}
