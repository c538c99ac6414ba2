//! The client's gaps of issue 37, each closed and checked against the strict twin: the token
//! recomputed once on a 401 (a clock a minute ahead still signs), the entry a change answers
//! read back, a pairing without `project_write` or before it, and `index` never taken for
//! `layer_index`.

use kerfmeter_lightburn::rest::{Client, ExistingOffset, LightBurnError, Pairing};
use kerfmeter_lightburn::twin::Served;
use serde_json::json;

use crate::{apply_150, fake_lightburn, kerf_mm, pair_for, paired, settle};

/// The statuses of the requests the twin answered on `path`.
fn statuses(served: &[Served], path: &str) -> Vec<u16> {
    served
        .iter()
        .filter(|s| s.path == path)
        .map(|s| s.status)
        .collect()
}

#[test]
fn on_a_401_the_token_is_recomputed_once_for_the_minute_before() {
    settle();
    // This computer's clock a whole minute ahead of LightBurn's: every first token is for a
    // minute LightBurn has not reached, every second one is LightBurn's current minute.
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.set_options(|o| o.clock_offset_s = -60);
    let applied = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap();
    assert_eq!(applied.layers.len(), 2);
    let served = fake.served();
    for path in [
        "/api/units",
        "/api/cuts",
        "/api/layers",
        "/api/cuts/0",
        "/api/cuts/2",
    ] {
        assert_eq!(statuses(&served, path), [401, 200], "{path}");
    }
    // A minute behind: the first token is good.
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.set_options(|o| o.clock_offset_s = 60);
    apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap();
    assert!(fake.served().iter().all(|s| s.status == 200));
    // Two minutes ahead: once recomputed, no more; nothing is changed.
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.set_options(|o| o.clock_offset_s = -120);
    let e = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap_err();
    assert!(
        matches!(e, LightBurnError::Unauthorized { status: 401 }),
        "{e}"
    );
    assert!(
        e.to_string().contains("clock is more than a minute off"),
        "{e}"
    );
    assert_eq!(statuses(&fake.served(), "/api/units"), [401, 401]);
    assert_eq!(fake.served().len(), 3, "the pairing and two tries");
}

#[test]
fn a_revoked_pairing_is_tried_twice_then_said_to_pair_again() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    assert!(fake.revoke(&pairing.secret));
    let e = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap_err();
    assert!(
        e.to_string()
            .contains("pair again with `kerfmeter lightburn pair`"),
        "{e}"
    );
    assert!(e.to_string().contains("revoked"), "{e}");
    assert_eq!(statuses(&fake.served(), "/api/units"), [401, 401]);
}

#[test]
fn a_pairing_without_project_write_changes_nothing() {
    let (host, fake) = fake_lightburn();
    let (_, secret) = pair_for(&host, json!(["state", "project"]));
    let pairing = Pairing {
        host: host.clone(),
        secret,
        capabilities: vec!["state".into(), "project".into()],
    };
    let e = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap_err();
    assert!(matches!(e, LightBurnError::Unauthorized { .. }), "{e}");
    assert!(e.to_string().contains("lacks a capability"), "{e}");
    assert_eq!(statuses(&fake.served(), "/api/cuts/0"), [401, 401]);
    assert!(fake.posts().is_empty());
    assert_eq!(kerf_mm(&fake, 0, None), 0.0);
}

#[test]
fn a_lightburn_from_before_project_write_is_said_to_need_an_update() {
    let (host, fake) = fake_lightburn();
    fake.set_options(|o| o.before_project_write = true);
    let e = Client::pair(&host).unwrap_err();
    assert!(matches!(e, LightBurnError::PairingRefused { .. }), "{e}");
    assert!(e.to_string().contains("update LightBurn"), "{e}");
    assert!(fake.authorisations().is_empty());
}

#[test]
fn the_entry_a_change_answers_is_read_back() {
    // A LightBurn that keeps Kerf Offsets to 0.02 mm holds 0.08 mm for the 0.075 mm written:
    // said, and the layer counted as changed.
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.set_options(|o| o.kerf_resolution_mm = Some(0.02));
    let e = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, LightBurnError::PartlyApplied { .. }), "{text}");
    assert!(
        text.contains("POST /api/cuts/0 with an entry that does not hold"),
        "{text}"
    );
    assert!(
        text.contains("the layer's Kerf Offset is 0.08, not 0.075"),
        "{text}"
    );
    assert!(
        text.contains("layer 0 \"C00\" (was 0 mm) had already been set"),
        "{text}"
    );
    assert_eq!(fake.posts().len(), 1, "it stops there");
    // What LightBurn answers is what is reported.
    let (host, fake) = fake_lightburn();
    fake.set_options(|o| o.kerf_resolution_mm = Some(1e-9));
    let applied = apply_150(&host, &paired(&host), &["0"], ExistingOffset::Refuse).unwrap();
    assert_eq!(applied.layers[0].after, [kerf_mm(&fake, 0, None)]);
}

#[test]
fn mixing_up_index_and_layer_index_fails() {
    // The spec promises no order between a cut's position (`index`) and its layer slot
    // (`layer_index`): listed last slot first, layer 0 is entry 29 and layer 2 entry 27. A
    // client that sent a change to the slot number, matched `/api/layers`' slots against
    // `index`, or took `--layers 0` for entry 0, would set C29, C28, C27 … instead.
    let (host, fake) = fake_lightburn();
    fake.edit_project(|p| p.cuts[..30].reverse());
    let pairing = paired(&host);
    let applied = apply_150(&host, &pairing, &[], ExistingOffset::Refuse).unwrap();
    let chosen: Vec<(i64, i64)> = applied
        .layers
        .iter()
        .map(|l| (l.cut_index, l.layer_index))
        .collect();
    assert_eq!(chosen, [(27, 2), (29, 0)]);
    let paths: Vec<String> = fake.posts().into_iter().map(|p| p.0).collect();
    assert_eq!(paths, ["/api/cuts/27", "/api/cuts/29"]);
    assert_eq!(kerf_mm(&fake, 0, None), 0.075);
    assert_eq!(kerf_mm(&fake, 2, Some(2)), 0.075);
    for unused in [27, 28, 29, 25] {
        assert_eq!(kerf_mm(&fake, unused, None), 0.0, "layer {unused}");
    }
    // `--layers 3` is layer slot 3, the already offset `Old` at entry 26.
    let e = apply_150(&host, &pairing, &["3"], ExistingOffset::Refuse).unwrap_err();
    assert!(e.to_string().contains("layer 3 \"Old\": 0.05 mm"), "{e}");
    let a = apply_150(&host, &pairing, &["3"], ExistingOffset::Replace).unwrap();
    assert_eq!((a.layers[0].cut_index, a.layers[0].layer_index), (26, 3));
    assert_eq!(kerf_mm(&fake, 3, None), 0.075);
}
