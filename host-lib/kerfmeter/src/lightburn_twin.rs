//! A LightBurn twin: the part of LightBurn's REST API that [`crate::lightburn`] uses, served on
//! loopback from a thread, so that `kerfmeter --sim lightburn pair|apply` and the tests run with
//! no LightBurn installed. Written from LightBurn's published API description, as the client:
//!
//! * `POST /api/connect` pairs when asked for `project_write` (the consent dialog says yes, unless
//!   [`LightBurnTwinOptions::declines`]) and gives the twin's secret;
//! * every other request must carry `Authorization: Bearer hex(HMAC-SHA256(secret, minute))` for
//!   this or the previous Unix minute (computed here, not by the client's code), else 401;
//! * `GET /api/units`, `GET /api/layers`, `GET /api/cuts` describe a small project: a Line layer
//!   `C00`, a Fill layer `Engrave`, a Fill layer `Badge, 3 mm` (a name with a comma) with a Line sub-layer, an unused Line
//!   layer `Old` already offset by 0.05 mm, a tool layer and an image;
//! * `POST /api/cuts/{index}` changes the entry's `params` and its sub-layers' (what a later
//!   `GET /api/cuts` shows), or answers 409 while the "cut settings editor" is open.
//!
//! What a real LightBurn adds (other capabilities, the rest of the project) is left out. Every
//! change is also kept in order ([`LightBurnTwin::posts`]), and a failure can be injected
//! ([`LightBurnTwinOptions::fail_post`]), for tests.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use hmac::{Hmac, KeyInit, Mac};
use serde_json::{Value, json};
use sha2::Sha256;

use crate::lightburn::LightBurnError;

/// The secret the twin hands out when it pairs.
const SECRET: &str = "twin-3dE7fG9hJ1kL5m";

/// Longest request head and body the twin reads, bytes.
const MAX_REQUEST_BYTES: usize = 1 << 20;

/// Longest time a client may take to send its whole request.
const REQUEST_DEADLINE: Duration = Duration::from_secs(5);

/// How the twin behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct LightBurnTwinOptions {
    /// LightBurn's speed units, which give its distance units (`mm/s`, `mm/min`, `in/s`,
    /// `in/min`).
    pub units: &'static str,
    /// The cut settings editor is open: every change is refused with 409.
    pub editor_open: bool,
    /// The user declines the pairing.
    pub declines: bool,
    /// Fail the change made after this many succeeded, with this HTTP status (0: drop the
    /// connection unanswered).
    pub fail_post: Option<(usize, u16)>,
}

impl Default for LightBurnTwinOptions {
    fn default() -> Self {
        LightBurnTwinOptions {
            units: "mm/s",
            editor_open: false,
            declines: false,
            fail_post: None,
        }
    }
}

/// What the twin holds and has been asked.
struct State {
    options: LightBurnTwinOptions,
    cuts: Value,
    posts: Vec<(String, Value)>,
}

/// A running LightBurn twin; it stops serving when dropped. Each connection is served on a
/// thread of its own, so a slow client delays only itself.
pub struct LightBurnTwin {
    host: String,
    state: Arc<Mutex<State>>,
    stop: Arc<AtomicBool>,
}

impl Drop for LightBurnTwin {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        // Wake the accepting thread so that it sees the flag.
        let _ = TcpStream::connect(&self.host);
    }
}

impl LightBurnTwin {
    /// Serve a twin on a free loopback port.
    pub fn start(options: LightBurnTwinOptions) -> Result<LightBurnTwin, LightBurnError> {
        Self::serve(options).map_err(|source| LightBurnError::TwinFailed { source })
    }

    fn serve(options: LightBurnTwinOptions) -> std::io::Result<LightBurnTwin> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let host = listener.local_addr()?.to_string();
        let state = Arc::new(Mutex::new(State {
            options,
            cuts: project_cuts(),
            posts: Vec::new(),
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let (served, stopped) = (Arc::clone(&state), Arc::clone(&stop));
        std::thread::Builder::new()
            .name("lightburn-twin".into())
            .spawn(move || accept(&listener, &served, &stopped))?;
        Ok(LightBurnTwin { host, state, stop })
    }

    /// Its address, `127.0.0.1:PORT`.
    pub fn host(&self) -> &str {
        &self.host
    }

    /// The secret it gives when it pairs.
    pub fn secret(&self) -> &'static str {
        SECRET
    }

    /// Change how it behaves from now on.
    pub fn set_options(&self, change: impl FnOnce(&mut LightBurnTwinOptions)) {
        change(&mut self.lock().options);
    }

    /// Every change made, in order: the path and the body.
    pub fn posts(&self) -> Vec<(String, Value)> {
        self.lock().posts.clone()
    }

    /// The cut entries as `GET /api/cuts` gives them now.
    pub fn cuts(&self) -> Value {
        self.lock().cuts.clone()
    }

    /// Change the project's cut entries (what the user does in LightBurn between two calls),
    /// e.g. to give two layers one name.
    pub fn edit_cuts(&self, change: impl FnOnce(&mut Value)) {
        change(&mut self.lock().cuts);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The project's cut entries.
fn project_cuts() -> Value {
    let normal = |index: i64, name: &str, mode: &str, kerf: f64, subs: Value| {
        json!({ "index": index, "name": name, "kind": "normal", "layer_index": index,
                "enabled": true, "priority": 0, "mode": mode,
                "params": { "speed": 10, "max_power": 60, "kerf": kerf }, "sub_layers": subs })
    };
    json!({ "product": "lightburn", "cuts": [
        normal(0, "C00", "cut", 0.0, json!([])),
        normal(1, "Engrave", "scan", 0.0, json!([])),
        normal(2, "Badge, 3 mm", "scan", 0.0,
               json!([{ "index": 1, "name": "", "enabled": true, "mode": "cut",
                        "params": { "speed": 5, "kerf": 0.0 } }])),
        normal(3, "Old", "cut", 0.05, json!([])),
        { "index": 4, "name": "T1", "kind": "normal", "layer_index": 30, "enabled": true,
          "priority": 0, "mode": "tool", "params": {} },
        { "index": 5, "name": "Photo", "kind": "image", "layer_index": 0, "enabled": true,
          "priority": 0, "params": { "speed": 100, "max_power": 20, "dpi": 254 } },
    ]})
}

/// The project's layers (`Old` is not in use).
fn project_layers() -> Value {
    let layer = |i: i64, in_use: bool| {
        json!({ "index": i, "name": "", "color": "#000000", "type": "normal", "hidden": false,
                "in_use": in_use })
    };
    json!({ "active_index": 0,
            "layers": [layer(0, true), layer(1, true), layer(2, true), layer(3, false)] })
}

/// The bearer token for `minute`.
fn token(minute: u64) -> String {
    let mut mac = Hmac::<Sha256>::new_from_slice(SECRET.as_bytes()).expect("any key length");
    mac.update(minute.to_string().as_bytes());
    hex::encode(mac.finalize().into_bytes())
}

/// Whether `auth` is a valid bearer token for this or the previous minute.
fn signed(auth: Option<&str>) -> bool {
    let minute = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() / 60);
    let valid = [token(minute), token(minute.saturating_sub(1))].map(|t| format!("Bearer {t}"));
    auth.is_some_and(|a| valid.iter().any(|t| t == a))
}

/// The answer to one request: an HTTP status (0: none at all) and a JSON body.
fn answer(
    state: &Mutex<State>,
    method: &str,
    path: &str,
    auth: Option<&str>,
    body: &[u8],
) -> (u16, Value) {
    let mut s = state.lock().unwrap_or_else(PoisonError::into_inner);
    let body: Value = serde_json::from_slice(body).unwrap_or(Value::Null);
    if (method, path) == ("POST", "/api/connect") {
        return connect(&s.options, &body);
    }
    if !signed(auth) {
        return (401, json!({ "error": "Unauthorized" }));
    }
    match (method, path) {
        ("GET", "/api/units") => (200, json!({ "units": s.options.units })),
        ("GET", "/api/cuts") => (200, s.cuts.clone()),
        ("GET", "/api/layers") => (200, project_layers()),
        ("POST", p) if p.starts_with("/api/cuts/") => change_cut(&mut s, p, body),
        _ => (404, json!({ "error": "not found" })),
    }
}

/// `POST /api/connect`: the consent dialog.
fn connect(options: &LightBurnTwinOptions, request: &Value) -> (u16, Value) {
    let caps = request["capabilities"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let named = request["application_name"]
        .as_str()
        .is_some_and(|n| !n.is_empty());
    if !named || caps.is_empty() {
        return (400, json!({ "error": "bad request" }));
    }
    if options.declines || !caps.contains(&json!("project_write")) {
        return (403, json!({ "error": "declined" }));
    }
    (200, json!({ "status": "ok", "secret": SECRET }))
}

/// `POST /api/cuts/{index}`: merge the body's `params` and sub-layers' `params` into the entry.
fn change_cut(s: &mut State, path: &str, body: Value) -> (u16, Value) {
    if s.options.editor_open {
        return (409, json!({ "error": "Cut settings editor is open" }));
    }
    if let Some((after, status)) = s.options.fail_post
        && s.posts.len() == after
    {
        return (status, json!({ "error": "refused by the twin" }));
    }
    let index = path.trim_start_matches("/api/cuts/").parse::<i64>().ok();
    let cuts = s.cuts["cuts"]
        .as_array_mut()
        .expect("the twin's project has cuts");
    let Some(cut) = cuts
        .iter_mut()
        .find(|c| index.is_some_and(|i| c["index"] == i))
    else {
        return (404, json!({ "error": "no such cut" }));
    };
    if let Some(params) = cut.get_mut("params") {
        merge(params, &body["params"]);
    }
    for sub in body["sub_layers"].as_array().into_iter().flatten() {
        let subs = cut.get_mut("sub_layers").and_then(Value::as_array_mut);
        let target = subs
            .into_iter()
            .flatten()
            .find(|t| t["index"] == sub["index"]);
        if let Some(params) = target.and_then(|t| t.get_mut("params")) {
            merge(params, &sub["params"]);
        }
    }
    s.posts.push((path.to_owned(), body));
    (200, json!({}))
}

/// Copy the fields of `from` (an object) into `into`.
fn merge(into: &mut Value, from: &Value) {
    if let (Some(into), Some(from)) = (into.as_object_mut(), from.as_object()) {
        for (k, v) in from {
            into.insert(k.clone(), v.clone());
        }
    }
}

/// Take connections until `stop`, each served on its own thread.
fn accept(listener: &TcpListener, state: &Arc<Mutex<State>>, stop: &AtomicBool) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        match stream {
            Ok(stream) => {
                let state = Arc::clone(state);
                // A client that sends garbage only loses its own connection.
                let _ = std::thread::Builder::new()
                    .name("lightburn-twin-request".into())
                    .spawn(move || serve(stream, &state));
            }
            // Out of file handles, say: wait rather than spin.
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

/// Read one request from `stream` (within [`REQUEST_DEADLINE`]) and answer it.
fn serve(stream: TcpStream, state: &Mutex<State>) -> std::io::Result<()> {
    let deadline = Instant::now() + REQUEST_DEADLINE;
    let mut reader = BufReader::new(Deadlined {
        stream: stream.try_clone()?,
        deadline,
    });
    let head = read_head(&mut reader)?;
    let mut headers = [httparse::EMPTY_HEADER; 32];
    let mut request = httparse::Request::new(&mut headers);
    let bad = |e: String| std::io::Error::new(std::io::ErrorKind::InvalidData, e);
    request.parse(&head).map_err(|e| bad(e.to_string()))?;
    let (method, path) = (request.method.unwrap_or(""), request.path.unwrap_or(""));
    let header = |name: &str| {
        request
            .headers
            .iter()
            .find(|h| h.name.eq_ignore_ascii_case(name))
            .and_then(|h| std::str::from_utf8(h.value).ok())
    };
    let length: usize = header("content-length")
        .map_or(Ok(0), str::parse)
        .map_err(|e| bad(format!("{e}")))?;
    if length > MAX_REQUEST_BYTES {
        return Err(bad("body too large".into()));
    }
    let mut body = vec![0; length];
    reader.read_exact(&mut body)?;
    let (status, value) = answer(state, method, path, header("authorization"), &body);
    if status == 0 {
        return Ok(()); // the link is lost: no answer
    }
    let text = value.to_string();
    let mut stream = stream;
    // A client that does not read its answer cannot hold the thread either.
    stream.set_write_timeout(Some(REQUEST_DEADLINE))?;
    write!(
        stream,
        "HTTP/1.1 {status} {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{text}",
        reason(status),
        text.len()
    )
}

/// A stream whose reads all end by one deadline: a client cannot hold its connection open by
/// sending a byte now and then.
struct Deadlined {
    stream: TcpStream,
    deadline: Instant,
}

impl Read for Deadlined {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(std::io::ErrorKind::TimedOut.into());
        }
        self.stream.set_read_timeout(Some(left))?;
        self.stream.read(buf)
    }
}

/// The request's head, up to and including its blank line.
fn read_head(reader: &mut impl BufRead) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::new();
    loop {
        let before = head.len();
        reader
            .by_ref()
            .take(MAX_REQUEST_BYTES as u64)
            .read_until(b'\n', &mut head)?;
        let line = &head[before..];
        if line.is_empty() || head.len() > MAX_REQUEST_BYTES {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        if line == b"\r\n" || line == b"\n" {
            return Ok(head);
        }
    }
}

/// The reason phrase of the statuses the twin answers.
fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        409 => "Conflict",
        _ => "Error",
    }
}
