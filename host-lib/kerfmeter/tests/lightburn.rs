//! The LightBurn bridge against a fake LightBurn written from its published REST API
//! specification: the fake checks every request's signature (HMAC-SHA256 of the Unix minute,
//! computed here independently of the client), pairs only when asked for `project_write`, answers
//! 409 while its "cut settings editor" is open and 403 when its user declines.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::{SystemTime, UNIX_EPOCH};

use hmac::{Hmac, KeyInit, Mac};
use kerfmeter::lightburn::{Client, ExistingOffset, LightBurnError, Pairing, apply_kerf};
use serde_json::{Value, json};
use sha2::Sha256;

const SECRET: &str = "aB3dE7fG9hJ1kL5m";

/// What the fake LightBurn holds and has been asked.
struct Fake {
    units: &'static str,
    editor_open: bool,
    declines: bool,
    /// Fail the POST made after this many succeeded with this status (0: drop the connection).
    fail_post: Option<(usize, u16)>,
    posts: Vec<(String, Value)>,
}

fn token(minute: u64) -> String {
    let mut mac = Hmac::<Sha256>::new_from_slice(SECRET.as_bytes()).unwrap();
    mac.update(minute.to_string().as_bytes());
    hex::encode(mac.finalize().into_bytes())
}

/// Whether `auth` is a valid bearer token for this or the previous minute.
fn signed(auth: Option<&str>) -> bool {
    let minute = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_secs()
        / 60;
    let ok = [token(minute), token(minute - 1)].map(|t| format!("Bearer {t}"));
    auth.is_some_and(|a| ok.iter().any(|t| t == a))
}

fn cuts() -> Value {
    let normal = |index: i64, name: &str, mode: &str, kerf: f64, subs: Value| {
        json!({ "index": index, "name": name, "kind": "normal", "layer_index": index,
                "enabled": true, "priority": 0, "mode": mode,
                "params": { "speed": 10, "max_power": 60, "kerf": kerf }, "sub_layers": subs })
    };
    json!({ "product": "lightburn", "cuts": [
        normal(0, "C00", "cut", 0.0, json!([])),
        normal(1, "Engrave", "scan", 0.0, json!([])),
        normal(2, "Badge", "scan", 0.0,
               json!([{ "index": 1, "name": "", "enabled": true, "mode": "cut",
                        "params": { "speed": 5, "kerf": 0.0 } }])),
        normal(3, "Old", "cut", 0.05, json!([])),
        { "index": 4, "name": "T1", "kind": "normal", "layer_index": 30, "enabled": true,
          "priority": 0, "mode": "tool", "params": {} },
        { "index": 5, "name": "Photo", "kind": "image", "layer_index": 0, "enabled": true,
          "priority": 0, "params": { "speed": 100, "max_power": 20, "dpi": 254 } },
    ]})
}

fn layers() -> Value {
    let l = |i: i64, in_use: bool| {
        json!({ "index": i, "name": "", "color": "#000000",
                                           "type": "normal", "hidden": false, "in_use": in_use })
    };
    json!({ "active_index": 0, "layers": [l(0, true), l(1, true), l(2, true), l(3, false)] })
}

/// The fake's answer to one request.
fn answer(
    fake: &Mutex<Fake>,
    method: &str,
    path: &str,
    auth: Option<&str>,
    body: &str,
) -> (u16, Value) {
    let mut f = fake.lock().unwrap();
    if (method, path) == ("POST", "/api/connect") {
        let req: Value = serde_json::from_str(body).unwrap_or(Value::Null);
        let caps = req["capabilities"].as_array().cloned().unwrap_or_default();
        if req["application_name"].as_str().is_none_or(str::is_empty) || caps.is_empty() {
            return (400, json!({ "error": "bad request" }));
        }
        if f.declines || !caps.contains(&json!("project_write")) {
            return (403, json!({ "error": "declined" }));
        }
        return (200, json!({ "status": "ok", "secret": SECRET }));
    }
    if !signed(auth) {
        return (401, json!({ "error": "Unauthorized" }));
    }
    match (method, path) {
        ("GET", "/api/units") => (200, json!({ "units": f.units })),
        ("GET", "/api/cuts") => (200, cuts()),
        ("GET", "/api/layers") => (200, layers()),
        ("POST", p) if p.starts_with("/api/cuts/") => {
            if f.editor_open {
                return (409, json!({ "error": "Cut settings editor is open" }));
            }
            if let Some((after, status)) = f.fail_post
                && f.posts.len() == after
            {
                return (status, json!({ "error": "refused by the test" }));
            }
            let body: Value = serde_json::from_str(body).unwrap();
            f.posts.push((p.to_string(), body));
            (200, json!({}))
        }
        _ => (404, json!({ "error": "not found" })),
    }
}

fn handle(mut stream: TcpStream, fake: &Mutex<Fake>) {
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    let mut line = String::new();
    reader.read_line(&mut line).unwrap();
    let mut parts = line.split_whitespace();
    let (method, path) = (
        parts.next().unwrap_or("").to_string(),
        parts.next().unwrap_or("").to_string(),
    );
    let (mut length, mut auth) = (0, None);
    loop {
        let mut h = String::new();
        reader.read_line(&mut h).unwrap();
        if h.trim().is_empty() {
            break;
        }
        let (k, v) = h.split_once(':').unwrap();
        match k.trim().to_ascii_lowercase().as_str() {
            "content-length" => length = v.trim().parse().unwrap(),
            "authorization" => auth = Some(v.trim().to_string()),
            _ => {}
        }
    }
    let mut body = vec![0; length];
    reader.read_exact(&mut body).unwrap();
    let body = String::from_utf8(body).unwrap();
    let (status, value) = answer(fake, &method, &path, auth.as_deref(), &body);
    if status == 0 {
        return; // the link is lost: no answer
    }
    let text = value.to_string();
    write!(
        stream,
        "HTTP/1.1 {status} X\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{text}",
        text.len()
    )
    .unwrap();
}

/// A fake LightBurn on a free port: its address and its state.
fn fake_lightburn() -> (String, Arc<Mutex<Fake>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let host = listener.local_addr().unwrap().to_string();
    let fake = Arc::new(Mutex::new(Fake {
        units: "mm/s",
        editor_open: false,
        declines: false,
        fail_post: None,
        posts: Vec::new(),
    }));
    let served = fake.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            handle(stream, &served);
        }
    });
    (host, fake)
}

fn paired(host: &str) -> Pairing {
    Client::pair(host).unwrap()
}

#[test]
fn pairing_then_apply_sets_every_line_pass_in_use_to_half_the_kerf() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    assert_eq!(pairing.secret, SECRET);
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
    let posts = fake.lock().unwrap().posts.clone();
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
    fake.lock().unwrap().units = "in/min";
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
    assert_eq!(fake.lock().unwrap().posts.len(), 1);
}

#[test]
fn an_open_editor_a_bad_signature_and_a_declined_pairing_are_clear_errors() {
    let (host, fake) = fake_lightburn();
    let pairing = paired(&host);
    fake.lock().unwrap().editor_open = true;
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

    fake.lock().unwrap().declines = true;
    let e = Client::pair(&host).unwrap_err();
    assert!(matches!(e, LightBurnError::Declined), "{e}");
    assert!(fake.lock().unwrap().posts.is_empty());
}

#[test]
fn a_failure_after_a_layer_was_set_names_it_and_says_to_replace() {
    // 400, 401, 404, 409 and a lost link on the second layer (C00 is set, Badge is not).
    for status in [400, 401, 404, 409, 0] {
        let (host, fake) = fake_lightburn();
        let pairing = paired(&host);
        fake.lock().unwrap().fail_post = Some((1, status));
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
        assert_eq!(fake.lock().unwrap().posts.len(), 1);
    }
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
    assert!(fake.lock().unwrap().posts.is_empty());
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
    let posts = fake.lock().unwrap().posts.clone();
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
