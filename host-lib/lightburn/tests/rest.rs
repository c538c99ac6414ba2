//! The LightBurn client against the LightBurn twin (`kerfmeter_lightburn::twin`), which is
//! written from LightBurn's published REST spec, not from the client: the fixed cut list of 63
//! entries (`index` is not `layer_index`), all 32 layer slots, scope enforced with a bare 401,
//! bodies checked whole and applied all or nothing, the updated entry answered.
//!
//! Here, the client's flows; in `rest/rules.rs`, each of the twin's rules asked of it
//! directly over HTTP; in `rest/gaps.rs`, the client's fixes of issue 37 (the token
//! recomputed once, the change read back, `index` and `layer_index` kept apart).

#[path = "rest/gaps.rs"]
mod gaps;
#[path = "rest/rules.rs"]
mod rules;

use std::net::TcpListener;

use kerfmeter_lightburn::rest::{Client, ExistingOffset, LightBurnError, Pairing, apply_kerf};
use kerfmeter_lightburn::twin::{DisplayUnits, LightBurnTwin, LightBurnTwinOptions};
use kerfmeter_protocol::advice::Advice;
use serde_json::{Value, json};

/// A LightBurn twin with its defaults, and its address.
pub fn fake_lightburn() -> (String, LightBurnTwin) {
    let twin = LightBurnTwin::start(LightBurnTwinOptions::default()).unwrap();
    (twin.host().to_owned(), twin)
}

pub fn paired(host: &str) -> Pairing {
    Client::pair(host).unwrap()
}

/// Set the Kerf Offsets of `layers` (all Line layers in use when empty) for a 150 µm kerf.
pub fn apply_150(
    host: &str,
    pairing: &Pairing,
    layers: &[&str],
    existing: ExistingOffset,
) -> Result<kerfmeter_lightburn::rest::Applied, LightBurnError> {
    let layers: Vec<String> = layers.iter().map(|s| s.to_string()).collect();
    apply_kerf(&Client::new(host), pairing, 150.0, &layers, existing)
}

/// The Kerf Offset of layer `slot`'s normal cut as the twin holds it, mm (its base pass, or
/// sub-layer `sub`).
pub fn kerf_mm(twin: &LightBurnTwin, slot: i64, sub: Option<i64>) -> f64 {
    use kerfmeter_lightburn::twin::CutKind;
    let project = twin.project();
    let cut = project
        .cuts
        .iter()
        .find(|c| c.layer_index == slot && matches!(c.kind, CutKind::Normal { .. }))
        .unwrap();
    let params = match (sub, &cut.kind) {
        (None, _) => &cut.params,
        (Some(i), CutKind::Normal { sub_layers, .. }) => {
            &sub_layers.iter().find(|s| s.index == i).unwrap().params
        }
        _ => unreachable!(),
    };
    params["kerf"].as_f64().unwrap()
}

#[test]
fn pairing_then_apply_sets_every_line_pass_in_use_to_half_the_kerf() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    assert_eq!(fake.authorisations()[0].secret, pairing.secret);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("sub/lightburn.json");
    pairing.save(&file).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&file).unwrap().permissions().mode();
        assert_eq!(
            mode & 0o777,
            0o600,
            "the secret is readable by its owner only"
        );
    }
    let pairing = Pairing::load(&file).unwrap();
    let applied = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap();
    assert_eq!(applied.kerf_offset, 0.075);
    assert_eq!(applied.unit, "mm");
    assert!(applied.project_modified);
    // What LightBurn now holds: C00's Line pass and Badge's Line sub-layer (its 2nd).
    assert_eq!(kerf_mm(&fake, 0, None), 0.075);
    assert_eq!(kerf_mm(&fake, 2, Some(2)), 0.075);
    assert_eq!(
        kerf_mm(&fake, 2, Some(1)),
        0.0,
        "a Fill sub-layer is left alone"
    );
    assert_eq!(kerf_mm(&fake, 1, None), 0.0, "a Fill layer is left alone");
    assert_eq!(kerf_mm(&fake, 5, None), 0.0, "a Line layer not in use too");
    assert_eq!(
        fake.posts(),
        [
            (
                "/api/cuts/0".to_string(),
                json!({ "params": { "kerf": 0.075 } })
            ),
            (
                "/api/cuts/2".to_string(),
                json!({ "sub_layers": [{ "index": 2, "params": { "kerf": 0.075 } }] })
            ),
        ]
    );
    let project = fake.project();
    assert!(project.modified, "LightBurn's project is now modified");
    assert_eq!(project.undo_steps, 2, "one undo step a layer");
}

#[test]
fn the_offset_is_written_in_the_display_units() {
    let (host, fake) = fake_lightburn();
    fake.set_options(|o| o.units = DisplayUnits::InPerMin);
    let layers = ["C00".to_string()];
    let a = apply_kerf(
        &Client::new(&host),
        &paired(&host),
        254.0,
        &layers,
        ExistingOffset::Refuse,
    )
    .unwrap();
    assert_eq!(a.unit, "in");
    assert!((a.kerf_offset - 0.005).abs() < 1e-12);
    assert!((a.layers[0].after[0] - 0.005).abs() < 1e-12, "read back");
    // The twin keeps mm: 0.005 in is 0.127 mm, not 0.005 mm.
    assert!((kerf_mm(&fake, 0, None) - 0.127).abs() < 1e-12);
    assert_eq!(fake.posts().len(), 1);
}

#[test]
fn a_value_lists_layers_by_commas_unless_it_is_a_whole_name_with_one() {
    let (host, _fake) = fake_lightburn();
    let set = |values: &[&str]| {
        apply_150(&host, &paired(&host), values, ExistingOffset::Replace)
            .map(|a| a.layers.iter().map(|l| l.layer_index).collect::<Vec<_>>())
    };
    // The twin's layer 2 is named `Badge, 3 mm`.
    assert_eq!(set(&["Badge, 3 mm"]).unwrap(), [2]);
    assert_eq!(set(&["0,2"]).unwrap(), [0, 2]);
    assert_eq!(set(&["C00", "Badge, 3 mm"]).unwrap(), [0, 2]);
    // Split, `Badge` and `3 mm` name no layer.
    let e = set(&["C00, Badge, 3 mm"]).unwrap_err().to_string();
    assert!(e.contains("\"Badge\" (a value is split"), "{e}");
    // A value that names nothing (an empty shell variable) is refused, not "no layer at all".
    let e = set(&[" , "]).unwrap_err().to_string();
    assert!(e.contains("names nothing"), "{e}");
    // The rule is the one `kerfmeter dilate --layers` applies to a project file
    // (`kerfmeter_plan::selectors`): a comma inside parentheses does not split.
    let e = set(&["C00,(a,b)"]).unwrap_err().to_string();
    assert!(
        e.contains("no layer has the index or name \"(a,b)\""),
        "{e}"
    );
}

#[test]
fn an_open_editor_a_bad_signature_and_a_declined_pairing_are_clear_errors() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.set_options(|o| o.editor_open = true);
    let e = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap_err();
    assert!(matches!(e, LightBurnError::EditorOpen), "{e}");
    assert!(e.to_string().ends_with("close it and run again"), "{e}");

    let forged = Pairing {
        secret: "not the secret".into(),
        ..pairing
    };
    let e = apply_150(&host, &forged, &[], ExistingOffset::Refuse).unwrap_err();
    assert!(
        matches!(e, LightBurnError::Unauthorized { status: 401 }),
        "{e}"
    );
    assert!(e.to_string().contains("kerfmeter lightburn pair"));

    fake.set_options(|o| o.declines = true);
    let e = Client::pair(&host).unwrap_err();
    assert!(matches!(e, LightBurnError::Declined), "{e}");
    assert!(fake.posts().is_empty());
}

#[test]
fn a_failure_after_a_layer_was_set_names_it_and_says_to_replace() {
    // 400, 401, 404, 409 and a lost link on the second layer (C00 is set, Badge is not).
    for status in [400, 401, 404, 409, 0] {
        let (host, fake) = fake_lightburn();
        let pairing = paired(&host);
        fake.set_options(|o| o.fail_post = Some((1, status)));
        let e = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap_err();
        let text = e.to_string();
        assert!(
            matches!(e, LightBurnError::PartlyApplied { .. }),
            "{status}: {text}"
        );
        assert!(
            text.contains("layer 0 \"C00\" (was 0 mm) had already been set"),
            "{status}: {text}"
        );
        assert!(!text.contains("Badge"), "{status}: {text}");
        // The advice in the library's own words (a front end words it its way: the CLI's
        // `--recompensate`).
        assert!(
            text.contains(&format!("again with {}", Advice::Recompensate)),
            "{status}: {text}"
        );
        assert!(
            !text.contains(&Advice::AlreadyCompensatedOk.to_string()),
            "{status}: {text}"
        );
        assert_eq!(fake.posts().len(), 1);
    }
}

#[test]
fn a_name_shared_by_a_line_layer_and_another_is_refused_whole() {
    // Every entry a name selects is set, so the Fill layer that shares the Line layer's name
    // must stop the change, not be skipped while the Line layer is set.
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.edit_project(|p| p.cuts[1].name = "C00".into());
    let e = apply_150(&host, &pairing, &["C00"], ExistingOffset::Refuse).unwrap_err();
    assert!(
        e.to_string()
            .contains("layer 1 \"C00\" is not a Line layer"),
        "{e}"
    );
    assert!(fake.posts().is_empty());
    // By its index, the Line layer alone is chosen and set.
    let applied = apply_150(&host, &pairing, &["0"], ExistingOffset::Refuse).unwrap();
    assert_eq!(applied.layers.len(), 1);
    assert_eq!(fake.posts().len(), 1);
}

#[test]
fn layers_asked_for_must_be_line_layers_and_not_already_compensated() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    for (layer, says) in [
        ("Engrave", "layer 1 \"Engrave\" is not a Line layer"),
        ("Photo", "layer 4 \"Photo\" is not a Line layer"),
        // A tool layer is not one either, and the internal cut is no layer at all.
        ("T1", "layer 30 \"T1\" is not a Line layer"),
        ("-1", "no layer has the index or name \"-1\""),
    ] {
        let e = apply_150(&host, &pairing, &[layer], ExistingOffset::Refuse).unwrap_err();
        assert!(e.to_string().contains(says), "{layer}: {e}");
    }
    let e = apply_150(&host, &pairing, &["3"], ExistingOffset::Refuse).unwrap_err();
    assert!(e.to_string().contains("layer 3 \"Old\": 0.05 mm"), "{e}");
    match &e {
        LightBurnError::AlreadyCompensated { found, offsets_um } => {
            assert_eq!(found, &["layer 3 \"Old\": 0.05 mm"]);
            assert_eq!(offsets_um.len(), 1);
            assert!((offsets_um[0] - 50.0).abs() < 1e-9, "{offsets_um:?}");
        }
        other => panic!("{other:?}"),
    }
    assert!(fake.posts().is_empty());
    let a = apply_150(&host, &pairing, &["Old"], ExistingOffset::Add).unwrap();
    assert!((a.layers[0].after[0] - 0.125).abs() < 1e-12);
    assert!((kerf_mm(&fake, 3, None) - 0.125).abs() < 1e-12);
    apply_150(&host, &pairing, &["Old"], ExistingOffset::Replace).unwrap();
    let posts = fake.posts();
    assert_eq!(posts[1].1, json!({ "params": { "kerf": 0.075 } }));
    assert_eq!(kerf_mm(&fake, 3, None), 0.075);
}

#[test]
fn no_lightburn_and_no_pairing_are_clear_errors() {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let host = format!("127.0.0.1:{port}");
    let e = Client::pair(&host).unwrap_err();
    assert!(matches!(e, LightBurnError::NotRunning { .. }), "{e}");
    let dir = tempfile::tempdir().unwrap();
    let e = Pairing::load(&dir.path().join("none.json")).unwrap_err();
    assert!(e.to_string().contains("not paired with LightBurn"), "{e}");
}

/// One raw request to the twin: the status and the JSON answer (`Null` when none).
pub fn raw(
    host: &str,
    method: &str,
    path: &str,
    token: Option<&str>,
    body: Option<&str>,
) -> (u16, Value) {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let url = format!("http://{host}{path}");
    let auth = token.map(|t| format!("Bearer {t}"));
    let mut response = match method {
        "POST" => {
            let mut r = agent.post(&url).header("Content-Type", "application/json");
            if let Some(a) = &auth {
                r = r.header("Authorization", a);
            }
            r.send(body.unwrap_or(""))
        }
        _ => {
            let mut r = agent.get(&url);
            if let Some(a) = &auth {
                r = r.header("Authorization", a);
            }
            r.call()
        }
    }
    .unwrap();
    let text = response.body_mut().read_to_string().unwrap();
    (
        response.status().as_u16(),
        serde_json::from_str(&text).unwrap_or(Value::Null),
    )
}

/// Pair with the twin for `capabilities`: the status and the secret (empty when refused).
pub fn pair_for(host: &str, capabilities: Value) -> (u16, String) {
    let body = json!({ "application_name": "test", "capabilities": capabilities }).to_string();
    let (status, answer) = raw(host, "POST", "/api/connect", None, Some(&body));
    (status, answer["secret"].as_str().unwrap_or("").to_string())
}

/// The token for `secret` now (this computer's clock), plus `minutes`.
pub fn token(secret: &str, minutes: i64) -> String {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs() as i64;
    kerfmeter_lightburn::rest::bearer_token(secret, (now + 60 * minutes) as u64)
}

/// Wait, if need be, until this computer's clock is at least 3 s away from the next minute: a
/// test that signs for a chosen minute then sees LightBurn's minute as it expects.
pub fn settle() {
    let second = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs()
        % 60;
    if second >= 57 {
        std::thread::sleep(std::time::Duration::from_secs(61 - second));
    }
}
