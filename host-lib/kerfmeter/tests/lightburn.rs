//! The LightBurn bridge against the LightBurn twin (`kerfmeter::lightburn_twin`), written from
//! LightBurn's published REST API description: it checks every request's signature
//! (HMAC-SHA256 of the Unix minute, computed by its own code), pairs only when asked for
//! `project_write`, answers 409 while its "cut settings editor" is open and 403 when its user
//! declines.

use std::net::TcpListener;

use kerfmeter::lightburn::{Client, ExistingOffset, LightBurnError, Pairing, apply_kerf};
use kerfmeter::lightburn_twin::{LightBurnTwin, LightBurnTwinOptions};
use serde_json::json;

/// A LightBurn twin with its defaults, and its address.
fn fake_lightburn() -> (String, LightBurnTwin) {
    let twin = LightBurnTwin::start(LightBurnTwinOptions::default()).unwrap();
    (twin.host().to_owned(), twin)
}

fn paired(host: &str) -> Pairing {
    Client::pair(host).unwrap()
}

#[test]
fn pairing_then_apply_sets_every_line_pass_in_use_to_half_the_kerf() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    assert_eq!(pairing.secret, fake.secret());
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
    let applied = apply_kerf(
        &Client::new(&host),
        &pairing,
        150.0,
        &[],
        ExistingOffset::Refuse,
    )
    .unwrap();
    assert_eq!(applied.kerf_offset, 0.075);
    assert_eq!(applied.unit, "mm");
    // What LightBurn now holds.
    let cuts = fake.cuts();
    assert_eq!(cuts["cuts"][0]["params"]["kerf"], 0.075);
    assert_eq!(cuts["cuts"][2]["sub_layers"][0]["params"]["kerf"], 0.075);
    assert_eq!(
        cuts["cuts"][1]["params"]["kerf"], 0.0,
        "a Fill layer is left alone"
    );
    let posts = fake.posts();
    assert_eq!(
        posts,
        [
            (
                "/api/cuts/0".to_string(),
                json!({ "params": { "kerf": 0.075 } })
            ),
            (
                "/api/cuts/2".to_string(),
                json!({ "sub_layers": [{ "index": 1, "params": { "kerf": 0.075 } }] })
            ),
        ]
    );
}

#[test]
fn the_offset_is_written_in_the_display_units() {
    let (host, fake) = fake_lightburn();
    fake.set_options(|o| o.units = "in/min");
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
    assert_eq!(fake.posts().len(), 1);
}

#[test]
fn a_value_lists_layers_by_commas_unless_it_is_a_whole_name_with_one() {
    let (host, _fake) = fake_lightburn();
    let set = |values: &[&str]| {
        let values: Vec<String> = values.iter().map(|v| v.to_string()).collect();
        let client = Client::new(&host);
        apply_kerf(
            &client,
            &paired(&host),
            150.0,
            &values,
            ExistingOffset::Replace,
        )
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
}

#[test]
fn an_open_editor_a_bad_signature_and_a_declined_pairing_are_clear_errors() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.set_options(|o| o.editor_open = true);
    let e = apply_kerf(
        &Client::new(&host),
        &pairing,
        150.0,
        &[],
        ExistingOffset::Refuse,
    )
    .unwrap_err();
    assert!(matches!(e, LightBurnError::EditorOpen), "{e}");
    assert!(e.to_string().ends_with("close it and run again"), "{e}");

    let forged = Pairing {
        secret: "not the secret".into(),
        ..pairing
    };
    let e = apply_kerf(
        &Client::new(&host),
        &forged,
        150.0,
        &[],
        ExistingOffset::Refuse,
    )
    .unwrap_err();
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
        let e = apply_kerf(
            &Client::new(&host),
            &pairing,
            150.0,
            &[],
            ExistingOffset::Refuse,
        )
        .unwrap_err();
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
        assert!(
            text.contains("again with --recompensate"),
            "{status}: {text}"
        );
        assert!(
            !text.contains("--already-compensated-ok"),
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
    let client = Client::new(&host);
    fake.edit_cuts(|cuts| cuts["cuts"][1]["name"] = "C00".into());
    let e = apply_kerf(
        &client,
        &pairing,
        150.0,
        &["C00".into()],
        ExistingOffset::Refuse,
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("layer 1 \"C00\" is not a Line layer"),
        "{e}"
    );
    assert!(fake.posts().is_empty());
    // By its index, the Line layer alone is chosen and set.
    let applied = apply_kerf(
        &client,
        &pairing,
        150.0,
        &["0".into()],
        ExistingOffset::Refuse,
    )
    .unwrap();
    assert_eq!(applied.layers.len(), 1);
    assert_eq!(fake.posts().len(), 1);
}

#[test]
fn layers_asked_for_must_be_line_layers_and_not_already_compensated() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    let client = Client::new(&host);
    let e = apply_kerf(
        &client,
        &pairing,
        150.0,
        &["Engrave".into()],
        ExistingOffset::Refuse,
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("layer 1 \"Engrave\" is not a Line layer"),
        "{e}"
    );
    let e = apply_kerf(
        &client,
        &pairing,
        150.0,
        &["3".into()],
        ExistingOffset::Refuse,
    )
    .unwrap_err();
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
    let a = apply_kerf(
        &client,
        &pairing,
        150.0,
        &["Old".into()],
        ExistingOffset::Add,
    )
    .unwrap();
    assert!((a.layers[0].after[0] - 0.125).abs() < 1e-12);
    apply_kerf(
        &client,
        &pairing,
        150.0,
        &["Old".into()],
        ExistingOffset::Replace,
    )
    .unwrap();
    let posts = fake.posts();
    assert_eq!(posts[1].1, json!({ "params": { "kerf": 0.075 } }));
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
