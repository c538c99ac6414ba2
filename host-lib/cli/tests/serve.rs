//! `kerfmeter serve` as its clients see it: the calls over the WebSocket and over HTTP, the
//! notifications, one run at a time, abort, a client that leaves mid-run, a device that
//! vanishes and comes back, and the security rules (token, origin, host, body size, malformed
//! requests). Each test starts its own server on a free loopback port (`--listen 127.0.0.1:0`).
//! Unix only: the vanishing device is a pseudo-terminal behind a symbolic link, and Ctrl-C is
//! sent with `kill -INT`.
#![cfg(unix)]

use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// The longest any test waits for one thing.
const PATIENCE: Duration = Duration::from_secs(60);

/// A running `kerfmeter serve`, stopped when dropped.
struct Server {
    child: Child,
    /// `127.0.0.1:PORT`.
    addr: String,
}

/// A history database of the test's own (never the user's).
fn temp_db() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("history.sqlite3");
    (dir, db)
}

impl Server {
    /// `kerfmeter [global] serve --listen 127.0.0.1:0 [serve_args]`, once it listens, with a
    /// history database of its own that lives as long as the test process's temporary folder.
    fn start(global: &[&str], serve_args: &[&str]) -> Server {
        let (dir, db) = temp_db();
        // Kept until the process ends: the server may write to it until it is dropped.
        std::mem::forget(dir);
        Server::start_with_db(global, serve_args, &db)
    }

    /// As [`Server::start`], recording into `db`.
    fn start_with_db(global: &[&str], serve_args: &[&str], db: &std::path::Path) -> Server {
        let mut child = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
            .env("KERFMETER_DB", db)
            .args(global)
            .args(["serve", "--listen", "127.0.0.1:0"])
            .args(serve_args)
            .env_remove("KERFMETER_PORT")
            .env_remove("KERFMETER_TOKEN")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("the kerfmeter binary runs");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let addr = line
            .trim()
            .strip_prefix("Listening on http://")
            .and_then(|rest| rest.strip_suffix('/'))
            .unwrap_or_else(|| panic!("no address printed: {line:?}"))
            .to_owned();
        Server { child, addr }
    }

    /// The simulated device's server (the twin in real time when `realtime`, so that a run
    /// lasts long enough to be caught mid-way).
    fn sim(realtime: bool) -> Server {
        if realtime {
            Server::start(&["--sim", "--sim-realtime"], &[])
        } else {
            Server::start(&["--sim"], &[])
        }
    }

    /// A WebSocket client with these extra headers.
    fn ws_with(&self, path: &str, headers: &[(&str, &str)]) -> Result<Ws, tungstenite::Error> {
        let mut request = format!("ws://{}{path}", self.addr)
            .into_client_request()
            .unwrap();
        for (name, value) in headers {
            let name: tungstenite::http::HeaderName = name.parse().unwrap();
            request.headers_mut().insert(name, value.parse().unwrap());
        }
        let stream = TcpStream::connect(&self.addr).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_millis(100)))
            .unwrap();
        match tungstenite::client(request, stream) {
            Ok((socket, _)) => Ok(Ws {
                socket,
                next_id: 1,
                pending: VecDeque::new(),
            }),
            Err(tungstenite::HandshakeError::Failure(e)) => Err(e),
            Err(tungstenite::HandshakeError::Interrupted(_)) => panic!("handshake timed out"),
        }
    }

    /// A WebSocket client on `/rpc`, as a non-browser program connects (no Origin).
    fn ws(&self) -> Ws {
        self.ws_with("/rpc", &[]).expect("the WebSocket opens")
    }

    /// One HTTP request; its status and body (JSON, or `null`).
    fn http(
        &self,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &[u8],
    ) -> (u16, Value) {
        let mut stream = TcpStream::connect(&self.addr).unwrap();
        let mut head = format!(
            "{method} {path} HTTP/1.1\r\nConnection: close\r\nContent-Length: {}\r\n",
            body.len()
        );
        if !headers
            .iter()
            .any(|(name, _)| name.eq_ignore_ascii_case("host"))
        {
            head.push_str(&format!("Host: {}\r\n", self.addr));
        }
        for (name, value) in headers {
            head.push_str(&format!("{name}: {value}\r\n"));
        }
        head.push_str("\r\n");
        stream.write_all(head.as_bytes()).unwrap();
        // The server may answer (413) before reading a large body, and close.
        let _ = stream.write_all(body);
        let mut response = Vec::new();
        let _ = stream.read_to_end(&mut response);
        let text = String::from_utf8_lossy(&response);
        let status = text
            .split(' ')
            .nth(1)
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("not an HTTP response: {text:?}"));
        let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
        (status, serde_json::from_str(body).unwrap_or(Value::Null))
    }

    fn get(&self, path: &str) -> (u16, Value) {
        self.http("GET", path, &[], b"")
    }

    fn post(&self, path: &str, body: &str) -> (u16, Value) {
        self.http(
            "POST",
            path,
            &[("Content-Type", "application/json")],
            body.as_bytes(),
        )
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A blocking JSON-RPC client over a WebSocket.
struct Ws {
    socket: WebSocket<TcpStream>,
    next_id: u64,
    /// Messages read while waiting for another, oldest first.
    pending: VecDeque<Value>,
}

impl Ws {
    /// Send a request; its id.
    fn send(&mut self, method: &str, params: Value) -> u64 {
        let id = self.next_id;
        self.next_id += 1;
        let request = json!({ "jsonrpc": "2.0", "id": id, "method": method, "params": params });
        self.send_text(&request.to_string());
        id
    }

    fn send_text(&mut self, text: &str) {
        self.socket.send(Message::text(text)).unwrap();
    }

    /// The first message that `wanted` accepts (others are kept for later), within
    /// [`PATIENCE`].
    fn until(&mut self, mut wanted: impl FnMut(&Value) -> bool) -> Value {
        if let Some(i) = self.pending.iter().position(&mut wanted) {
            return self.pending.remove(i).unwrap();
        }
        let deadline = Instant::now() + PATIENCE;
        while Instant::now() < deadline {
            match self.socket.read() {
                Ok(Message::Text(text)) => {
                    let value: Value = serde_json::from_str(&text).unwrap();
                    if wanted(&value) {
                        return value;
                    }
                    self.pending.push_back(value);
                }
                Ok(_) => {}
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => panic!("the WebSocket failed: {e}"),
            }
        }
        panic!("nothing wanted came within {PATIENCE:?}");
    }

    /// The next response (a message with an id).
    fn answer(&mut self) -> Value {
        self.until(|m| m.get("id").is_some())
    }

    /// The response to request `id`.
    fn response(&mut self, id: u64) -> Value {
        self.until(|m| m["id"] == id)
    }

    /// Call `method` and wait for its response.
    fn call(&mut self, method: &str, params: Value) -> Value {
        let id = self.send(method, params);
        self.response(id)
    }

    /// The next notification `method`.
    fn notification(&mut self, method: &str) -> Value {
        self.until(|m| m["method"] == method)["params"].clone()
    }
}

/// The result of a response, or a panic with its error.
fn result(response: &Value) -> &Value {
    assert!(response.get("error").is_none(), "{response}");
    &response["result"]
}

/// The error code of a response.
fn code(response: &Value) -> i64 {
    response["error"]["code"]
        .as_i64()
        .unwrap_or_else(|| panic!("no error: {response}"))
}

#[test]
fn the_three_calls_work_over_the_websocket_with_progress() {
    let server = Server::sim(false);
    let mut ws = server.ws();
    let info = ws.call("info", json!({}));
    assert!(result(&info)["boot_id"].is_u64(), "{info}");
    assert!(result(&ws.call("reset_kerfmeter", json!(null)))["reset"] == true);
    assert_eq!(result(&ws.call("get_kerf_value", json!({}))), &Value::Null);

    let params = json!({ "thickness_mm": 3.0, "samples": 2, "label": "mdf 3mm" });
    let id = ws.send("run_kerfmeter", params);
    let started = ws.notification("run_started");
    assert_eq!(started, json!({ "label": "mdf 3mm", "by": "rpc" }));
    let progress = ws.notification("progress");
    assert_eq!(progress["samples"], 2);
    assert!(
        progress["torque_nm"].is_number() && progress["state"].is_string(),
        "{progress}"
    );
    let response = ws.response(id);
    let run = result(&response);
    let kerf_um = run["kerf_um"].as_f64().unwrap();
    assert!((100.0..220.0).contains(&kerf_um), "{run}");
    assert_eq!(run["summary"]["n"], 2);
    assert_eq!(run["runs"].as_array().unwrap().len(), 2);
    assert_eq!(run["label"], "mdf 3mm");
    assert!((run["thickness_mm"].as_f64().unwrap() - 3.0).abs() < 1e-6);
    let points = run["curve"]["points"].as_array().unwrap();
    assert!(
        points.len() > 10 && points[0].as_array().unwrap().len() == 2,
        "{run}"
    );
    assert_eq!(run["curve"]["run_id"], run["runs"][1]["run_id"]);
    let finished = ws.notification("run_finished");
    assert_eq!(finished["kerf_um"].as_f64(), Some(kerf_um));
    assert_eq!(finished["error"], Value::Null);

    let last = ws.call("get_kerf_value", json!({}));
    assert_eq!(result(&last)["run_id"], run["runs"][1]["run_id"]);
    assert!(result(&last)["kerf_um"].is_number());
    let status = ws.call("status", json!({}));
    assert_eq!(result(&status)["state"], "done", "{status}");
}

#[test]
fn the_three_calls_work_over_http() {
    let server = Server::sim(false);
    let (code, info) = server.get("/api/info");
    assert_eq!(code, 200, "{info}");
    assert!(info["supply_v"].is_number() || info["supply_v"].is_null());
    assert!(info["firmware"].is_object(), "{info}");
    let (code, run) = server.post("/api/run", r#"{"force_n": 50, "label": "ply"}"#);
    assert_eq!(code, 200, "{run}");
    assert!(run["kerf_um"].as_f64().unwrap() > 100.0, "{run}");
    assert!(
        (run["force_n"].as_f64().unwrap() - 50.0).abs() < 1e-3,
        "{run}"
    );
    let (code, kerf) = server.get("/api/kerf");
    assert_eq!(code, 200);
    assert_eq!(kerf["run_id"], run["runs"][0]["run_id"]);
    let (code, reset) = server.post("/api/reset", "");
    assert_eq!((code, reset), (200, json!({ "reset": true })));
    assert_eq!(server.get("/api/kerf"), (200, Value::Null));
    let (code, status) = server.get("/api/status");
    assert_eq!(code, 200);
    assert_eq!(status["state"], "idle");
    // Errors are the JSON-RPC error object, with an HTTP status.
    let (code, e) = server.post("/api/run", r#"{"samples": 0}"#);
    assert_eq!(code, 400);
    assert_eq!(e["error"]["code"], -32602);
    assert!(
        e["error"]["message"].as_str().unwrap().contains("samples"),
        "{e}"
    );
    assert_eq!(server.get("/api/nothing").0, 404);
    // A method a route does not take, or no route at all: the same error object.
    let (code, e) = server.http("DELETE", "/api/info", &[], b"");
    assert_eq!(code, 405, "{e}");
    assert!(
        e["error"]["message"].as_str().unwrap().contains("GET"),
        "{e}"
    );
    let (code, e) = server.get("/nowhere");
    assert_eq!(code, 404, "{e}");
    assert_eq!(e["error"]["code"], -32600, "{e}");
    assert_eq!(server.get("/api/run").0, 404);
}

#[test]
fn two_clients_racing_to_run_get_one_result_and_one_busy() {
    let server = Server::sim(true);
    let (mut a, mut b) = (server.ws(), server.ws());
    let ida = a.send("run_kerfmeter", json!({}));
    let idb = b.send("run_kerfmeter", json!({}));
    let (ra, rb) = (a.response(ida), b.response(idb));
    let results = [&ra, &rb]
        .iter()
        .filter(|r| r.get("result").is_some())
        .count();
    let busy = [&ra, &rb]
        .iter()
        .filter(|r| r.get("error").is_some())
        .count();
    assert_eq!((results, busy), (1, 1), "{ra}\n{rb}");
    let refused = if ra.get("error").is_some() { &ra } else { &rb };
    assert_eq!(code(refused), -32001, "{refused}");
    assert!(
        refused["error"]["message"]
            .as_str()
            .unwrap()
            .contains("already going")
    );
}

#[test]
fn a_second_client_aborts_a_run_and_every_client_hears_of_it() {
    let server = Server::sim(true);
    let (mut a, mut b) = (server.ws(), server.ws());
    let id = a.send("run_kerfmeter", json!({ "label": "a's run" }));
    assert_eq!(b.notification("run_started")["label"], "a's run");
    b.notification("progress");
    // While the run goes, a call that writes to the device is refused, not queued behind it; a
    // read is answered from the run's polls, with their age.
    assert_eq!(code(&b.call("clear_fault", json!({}))), -32001);
    let during = result(&b.call("status", json!({}))).clone();
    assert!(during["poll_age_ms"].is_u64(), "{during}");
    assert_ne!(during["state"], "idle", "{during}");
    assert_eq!(
        result(&b.call("abort", json!({}))),
        &json!({ "aborted": true })
    );
    let aborted = a.response(id);
    assert_eq!(code(&aborted), -32002, "{aborted}");
    assert_eq!(b.notification("run_finished")["error"]["code"], -32002);
    let status = result(&b.call("status", json!({}))).clone();
    assert_eq!(status["state"], "idle", "{status}");
    assert_eq!(status["torque_nm"], 0.0, "{status}");
    // Abort works with nothing running too.
    assert_eq!(result(&b.call("abort", json!({})))["aborted"], true);
}

#[test]
fn a_client_that_disconnects_mid_run_leaves_the_device_idle_and_safe() {
    let server = Server::sim(true);
    let mut watcher = server.ws();
    let mut runner = server.ws();
    runner.send("run_kerfmeter", json!({}));
    runner.notification("progress");
    drop(runner);
    let finished = watcher.notification("run_finished");
    assert_eq!(finished["error"]["code"], -32002, "{finished}");
    let status = result(&watcher.call("status", json!({}))).clone();
    assert_eq!(status["state"], "idle", "{status}");
    assert_eq!(status["torque_nm"], 0.0, "{status}");
    assert_eq!(status["fault"], Value::Null, "{status}");
}

#[test]
fn an_http_client_that_hangs_up_mid_run_aborts_it() {
    let server = Server::sim(true);
    let mut watcher = server.ws();
    let mut stream = TcpStream::connect(&server.addr).unwrap();
    let request = format!(
        "POST /api/run HTTP/1.1\r\nHost: {}\r\nContent-Length: 2\r\n\r\n{{}}",
        server.addr
    );
    stream.write_all(request.as_bytes()).unwrap();
    watcher.notification("progress");
    drop(stream);
    let finished = watcher.notification("run_finished");
    assert_eq!(finished["error"]["code"], -32002, "{finished}");
}

#[test]
fn malformed_requests_get_json_rpc_errors() {
    let server = Server::sim(false);
    let mut ws = server.ws();
    ws.send_text("{not json");
    assert_eq!(code(&ws.answer()), -32700);
    ws.send_text(r#"[{"jsonrpc":"2.0","id":1,"method":"info"}]"#);
    assert_eq!(code(&ws.answer()), -32600);
    ws.send_text(r#"{"jsonrpc":"1.0","id":7,"method":"info"}"#);
    let old = ws.answer();
    assert_eq!((code(&old), &old["id"]), (-32600, &json!(7)));
    assert_eq!(code(&ws.call("make_coffee", json!({}))), -32601);
    let bad = ws.call("run_kerfmeter", json!({ "thickness_mm": "thick" }));
    assert_eq!(code(&bad), -32602);
    assert!(
        bad["error"]["message"]
            .as_str()
            .unwrap()
            .contains("thickness_mm"),
        "{bad}"
    );
    let unknown = ws.call("run_kerfmeter", json!({ "thicknes_mm": 3 }));
    assert!(
        unknown["error"]["message"]
            .as_str()
            .unwrap()
            .contains("thicknes_mm"),
        "{unknown}"
    );
    let range = ws.call("run_kerfmeter", json!({ "thickness_mm": -3 }));
    assert_eq!(code(&range), -32602, "{range}");
    assert_eq!(code(&ws.call("job", json!({}))), -32004);
    let (status, body) = server.post("/api/run", "{oops");
    assert_eq!((status, code(&body)), (400, -32700), "{body}");
    // The connection still serves after all that.
    assert!(result(&ws.call("status", json!({})))["state"].is_string());
}

#[test]
fn oversized_bodies_are_refused() {
    let server = Server::sim(false);
    let big = format!(r#"{{"label": "{}"}}"#, "x".repeat(17 * 1024 * 1024));
    let (status, body) = server.post("/api/run", &big);
    assert_eq!(status, 413, "{body}");
    let mut ws = server.ws();
    let _ = ws.socket.send(Message::text(big));
    let deadline = Instant::now() + PATIENCE;
    loop {
        match ws.socket.read() {
            Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Ok(Message::Text(t)) => panic!("answered an oversized message: {t}"),
            Ok(_) | Err(_) => break,
        }
        assert!(
            Instant::now() < deadline,
            "the oversized message was not refused"
        );
    }
}

#[test]
fn a_foreign_origin_is_refused_for_the_websocket_and_posts() {
    let server = Server::sim(false);
    let evil = [("Origin", "http://evil.example")];
    let refused = server.ws_with("/rpc", &evil).err().expect("refused");
    match refused {
        tungstenite::Error::Http(response) => assert_eq!(response.status(), 403),
        other => panic!("{other}"),
    }
    let (status, body) = server.http("POST", "/api/run", &evil, b"{}");
    assert_eq!(status, 403, "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("Origin")
    );
    // A rebinding page's own host name is not the server's, even without an Origin.
    let (status, _) = server.http("GET", "/api/status", &[("Host", "evil.example")], b"");
    assert_eq!(status, 403);
    // The server's own origin, under either loopback name, passes.
    let own = format!("http://{}", server.addr);
    let port = server.addr.rsplit(':').next().unwrap();
    let localhost = format!("http://localhost:{port}");
    server
        .ws_with("/rpc", &[("Origin", &own)])
        .expect("own origin");
    let host = format!("localhost:{port}");
    let mut ws = server
        .ws_with("/rpc", &[("Origin", &localhost), ("Host", &host)])
        .expect("localhost origin");
    assert!(result(&ws.call("status", json!({})))["state"].is_string());
    let (status, _) = server.http("POST", "/api/abort", &[("Origin", &own)], b"");
    assert_eq!(status, 200);
}

#[test]
fn an_allowed_origin_passes() {
    let server = Server::start(&["--sim"], &["--allow-origin", "http://tool.example:5173/"]);
    let origin = [("Origin", "http://tool.example:5173")];
    server.ws_with("/rpc", &origin).expect("allowed");
    assert_eq!(server.http("POST", "/api/abort", &origin, b"").0, 200);
    let other = [("Origin", "http://tool.example:5174")];
    assert_eq!(server.http("POST", "/api/abort", &other, b"").0, 403);
    // A browser's cross-site request without an Origin (none does that today) is refused too.
    let cross = [("Sec-Fetch-Site", "cross-site")];
    assert_eq!(server.http("POST", "/api/abort", &cross, b"").0, 403);
}

#[test]
fn a_non_loopback_listen_needs_a_token() {
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(["--sim", "serve", "--listen", "0.0.0.0:0"])
        .env_remove("KERFMETER_TOKEN")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("without --token"), "{stderr}");
}

#[test]
fn with_a_token_only_the_right_token_is_served() {
    let server = Server::start(&["--sim"], &["--token", "s3cret-T0ken-long-enough"]);
    assert_eq!(server.get("/api/status").0, 401);
    let wrong = [("Authorization", "Bearer s3cret-T0ken-long-enougj")];
    assert_eq!(server.http("GET", "/api/status", &wrong, b"").0, 401);
    let right = [("Authorization", "Bearer s3cret-T0ken-long-enough")];
    assert_eq!(server.http("GET", "/api/status", &right, b"").0, 200);
    assert_eq!(
        server.get("/api/status?token=s3cret-T0ken-long-enough").0,
        200
    );
    assert!(server.ws_with("/rpc", &[]).is_err());
    assert!(server.ws_with("/rpc?token=nope", &[]).is_err());
    let mut ws = server
        .ws_with("/rpc?token=s3cret-T0ken-long-enough", &[])
        .unwrap();
    assert!(result(&ws.call("info", json!({})))["boot_id"].is_u64());
    // The page itself holds no secret.
    assert_eq!(server.get("/").0, 200);
}

#[test]
fn the_page_is_served() {
    let server = Server::sim(false);
    let mut stream = TcpStream::connect(&server.addr).unwrap();
    let request = format!(
        "GET / HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n",
        server.addr
    );
    stream.write_all(request.as_bytes()).unwrap();
    let mut page = String::new();
    stream.read_to_string(&mut page).unwrap();
    assert!(page.starts_with("HTTP/1.1 200"), "{page}");
    let lower = page.to_ascii_lowercase();
    assert!(lower.contains("content-type: text/html"), "{page}");
    // No other site may frame the page (a click on Measure through an invisible frame).
    assert!(lower.contains("x-frame-options: deny"), "{page}");
    assert!(lower.contains("frame-ancestors 'none'"), "{page}");
    assert!(lower.contains("x-content-type-options: nosniff"), "{page}");
}

#[test]
fn a_short_token_is_refused_at_startup() {
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args([
            "--sim",
            "serve",
            "--listen",
            "127.0.0.1:0",
            "--token",
            "abc123",
        ])
        .env_remove("KERFMETER_TOKEN")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("at least 16 characters"), "{stderr}");
}

#[test]
fn a_label_the_history_would_refuse_is_refused_before_the_motor_moves() {
    let server = Server::sim(false);
    let mut ws = server.ws();
    let bad = ws.call("run_kerfmeter", json!({ "label": "birch\n4mm" }));
    assert_eq!(code(&bad), -32602, "{bad}");
    assert!(bad["error"]["message"].as_str().unwrap().contains("label"));
    let status = ws.call("status", json!({}));
    assert_eq!(result(&status)["state"], "idle", "nothing ran: {status}");
}

/// `kerfmeter-twin` serving the simulated device on a pseudo-terminal, and its path.
fn pty_twin(args: &[&str]) -> (Child, String) {
    let mut twin = Command::new(env!("CARGO_BIN_EXE_kerfmeter-twin"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("the kerfmeter-twin binary runs");
    let mut path = String::new();
    BufReader::new(twin.stdout.take().unwrap())
        .read_line(&mut path)
        .unwrap();
    (twin, path.trim().to_owned())
}

/// Point the symbolic link `link` at `target` (atomically, as udev re-creates a device link).
fn point(link: &std::path::Path, target: &str) {
    let fresh = link.with_extension("new");
    let _ = std::fs::remove_file(&fresh);
    std::os::unix::fs::symlink(target, &fresh).unwrap();
    std::fs::rename(&fresh, link).unwrap();
}

#[test]
fn a_device_that_vanishes_is_reported_and_reopened_when_it_comes_back() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("kerfmeter");
    let (mut twin, path) = pty_twin(&[]);
    point(&link, &path);
    let server = Server::start(&["--port", link.to_str().unwrap()], &[]);
    let mut ws = server.ws();
    assert!(result(&ws.call("info", json!({})))["boot_id"].is_u64());

    twin.kill().unwrap();
    twin.wait().unwrap();
    let gone = ws.until(|m| m["method"] == "device" && m["params"]["connected"] == false);
    let gone = &gone["params"];
    assert_eq!(gone["connected"], false, "{gone}");
    assert!(
        gone["message"].as_str().is_some_and(|m| !m.is_empty()),
        "{gone}"
    );
    assert_eq!(code(&ws.call("status", json!({}))), -32003);
    let (status, body) = server.get("/api/status");
    assert_eq!((status, code(&body)), (503, -32003), "{body}");

    let (mut twin, path) = pty_twin(&[]);
    point(&link, &path);
    ws.until(|m| m["method"] == "device" && m["params"]["connected"] == true);
    let info = ws.call("info", json!({}));
    assert!(result(&info)["boot_id"].is_u64(), "{info}");
    let run = ws.call("run_kerfmeter", json!({}));
    assert!(result(&run)["kerf_um"].is_number(), "{run}");
    // The twin behind a PTY is still the twin: its measurement is recorded, as simulated, and
    // the server lists those.
    assert!(result(&run)["history"]["id"].is_number(), "{run}");
    let listed = ws.call("history", json!({}));
    let records = result(&listed)["records"].as_array().unwrap().clone();
    assert_eq!(records.len(), 1, "{listed}");
    assert_eq!(records[0]["simulated"], true, "{listed}");
    drop(server);
    let _ = twin.kill();
    let _ = twin.wait();
}

#[test]
fn ctrl_c_during_a_run_aborts_it_leaves_the_motor_safe_and_stops_the_server() {
    let (mut twin, path) = pty_twin(&["--realtime"]);
    let mut server = Server::start(&["--port", &path], &[]);
    let mut ws = server.ws();
    let id = ws.send("run_kerfmeter", json!({}));
    ws.notification("progress");
    let pid = server.child.id().to_string();
    let killed = Command::new("kill").args(["-INT", &pid]).status().unwrap();
    assert!(killed.success());
    let deadline = Instant::now() + PATIENCE;
    let exit = loop {
        if let Some(exit) = server.child.try_wait().unwrap() {
            break exit;
        }
        assert!(Instant::now() < deadline, "the server did not stop");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(exit.success(), "{exit}");
    // The run's client never got a result.
    while let Ok(message) = ws.socket.read() {
        if let Message::Text(text) = message {
            let m: Value = serde_json::from_str(&text).unwrap();
            assert!(m["id"] != id || m.get("result").is_none(), "{m}");
        }
    }
    // The device was told to abort: idle, no torque, and no fault (a host that had just gone
    // silent would have left it in a HostSilent fault).
    let out = Command::new(env!("CARGO_BIN_EXE_kerfmeter"))
        .args(["--port", &path, "--json", "status"])
        .output()
        .unwrap();
    let status: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(status["state"], "idle", "{status}");
    assert_eq!(status["fault"], Value::Null, "{status}");
    assert_eq!(status["torque_nm"], 0.0, "{status}");
    let _ = twin.kill();
    let _ = twin.wait();
}

#[test]
fn a_plan_is_dilated_by_the_last_kerf_from_its_text() {
    let server = Server::sim(false);
    let fixture = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../plan/tests/fixtures/box_generator.svg");
    let plan = std::fs::read_to_string(fixture).unwrap();
    let mut ws = server.ws();
    let last = json!({ "plan": plan, "format": "svg", "kerf_um": "last" });
    let none = ws.call("dilate", last.clone());
    assert_eq!(code(&none), -32602, "{none}");
    assert!(
        none["error"]["message"]
            .as_str()
            .unwrap()
            .contains("measure first")
    );
    let run = ws.call("run_kerfmeter", json!({}));
    let kerf_um = result(&run)["kerf_um"].as_f64().unwrap();
    let (status, dilated) = server.post("/api/dilate", &last.to_string());
    assert_eq!(status, 200, "{dilated}");
    assert!(
        (dilated["kerf_um"].as_f64().unwrap() - kerf_um).abs() < 0.01,
        "{dilated}"
    );
    assert_eq!(dilated["format"], "svg");
    let content = dilated["content"].as_str().unwrap();
    assert!(content.contains("kerfmeter:compensation") && content != plan);
    assert!(dilated["report"]["cut_rules"].is_string(), "{dilated}");
    // Its own output again: a plan error whose data says what compensation it found.
    let twice = ws.call(
        "dilate",
        json!({ "plan": content, "format": "svg", "kerf_um": 150 }),
    );
    assert_eq!(code(&twice), -32005, "{twice}");
    assert_eq!(
        twice["error"]["data"]["compensation_found"]["by"], "kerfmeter",
        "{twice}"
    );
    let bad = ws.call(
        "dilate",
        json!({ "plan": "<svg", "format": "svg", "kerf_um": 150 }),
    );
    assert_eq!(code(&bad), -32005, "{bad}");
    // A bad kerf is a bad param (-32602), not a plan error.
    let negative = ws.call(
        "dilate",
        json!({ "plan": plan, "format": "svg", "kerf_um": -5 }),
    );
    assert_eq!(code(&negative), -32602, "{negative}");
    let empty = ws.call(
        "dilate",
        json!({ "plan": " \n", "format": "svg", "kerf_um": 150 }),
    );
    assert_eq!(code(&empty), -32602, "{empty}");
    assert!(
        empty["error"]["message"]
            .as_str()
            .unwrap()
            .contains("empty"),
        "{empty}"
    );
    let no_format = ws.call("dilate", json!({ "plan": plan, "kerf_um": 150 }));
    assert!(
        no_format["error"]["message"]
            .as_str()
            .unwrap()
            .contains("format"),
        "{no_format}"
    );
    let dxf = ws.call(
        "dilate",
        json!({ "plan_base64": "%%%", "format": "dxf", "kerf_um": 150 }),
    );
    assert!(
        dxf["error"]["message"]
            .as_str()
            .unwrap()
            .contains("plan_base64"),
        "{dxf}"
    );
}

#[test]
fn the_gauge_is_drawn_as_the_gauge_command_draws_it() {
    let server = Server::sim(false);
    let mut ws = server.ws();
    let svg = ws.call("gauge", json!({ "label": true, "radius_mm": 12 }));
    let svg = result(&svg);
    assert_eq!(svg["format"], "svg");
    assert!(svg["content"].as_str().unwrap().contains("<svg"), "{svg}");
    assert!(svg["report"]["spiral_arcs"].as_u64().unwrap() > 10, "{svg}");
    assert!(svg["report"].get("output").is_none(), "{svg}");
    let dxf = ws.call("gauge", json!({ "format": "dxf", "jam_direction": "ccw" }));
    assert!(
        result(&dxf)["content"]
            .as_str()
            .unwrap()
            .contains("SECTION")
    );
    let bad = ws.call("gauge", json!({ "radius_mm": "big" }));
    assert_eq!(code(&bad), -32602, "{bad}");
    let unknown = ws.call("gauge", json!({ "output": "/etc/passwd" }));
    assert!(
        unknown["error"]["message"]
            .as_str()
            .unwrap()
            .contains("`output`"),
        "{unknown}"
    );
    // The params are the application layer's GaugeRequest: a bad value is named by its field,
    // and the G-code (cut by `job`) is not drawn here.
    let message = |answer: &Value| answer["error"]["message"].as_str().unwrap().to_owned();
    assert!(message(&bad).contains("`radius_mm`"), "{bad}");
    let gcode = ws.call("gauge", json!({ "format": "gcode" }));
    assert_eq!(code(&gcode), -32602, "{gcode}");
    assert!(message(&gcode).contains("`format`"), "{gcode}");
    // A test piece without its kerf is refused in the server's words (the parameter's name,
    // not the CLI's flag).
    let piece = ws.call("gauge", json!({ "test_piece": true }));
    assert!(
        message(&piece).contains("test_piece needs test_piece_kerf_um"),
        "{piece}"
    );
    assert!(!message(&piece).contains("--"), "{piece}");
}

#[test]
fn self_test_and_clear_fault_answer_as_the_cli_does() {
    let server = Server::start(&["--sim", "--sim-fault", "motor-disconnected"], &[]);
    let mut ws = server.ws();
    let failed = ws.call("self_test", json!({}));
    let failed = result(&failed);
    assert_eq!(failed["passed"], false, "{failed}");
    let reasons: Vec<&str> = failed["failures"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["item"].as_str().unwrap())
        .collect();
    assert!(reasons.contains(&"direction"), "{failed}");
    assert_eq!(
        result(&ws.call("clear_fault", json!({}))),
        &json!({ "ok": true })
    );
    let healthy = Server::sim(false);
    let passed = healthy.ws().call("self_test", json!({}));
    assert_eq!(result(&passed)["passed"], true, "{passed}");
}

#[test]
fn a_motor_shaft_device_is_confirmed_at_its_mark_over_rpc() {
    let server = Server::start(&["--sim", "--sim-encoder-on-motor-shaft"], &[]);
    let mut ws = server.ws();
    let status = ws.call("status", json!({}));
    assert_eq!(result(&status)["conditions"], json!(["hub-turn-unknown"]));
    let refused = ws.call("run_kerfmeter", json!({}));
    let message = refused["error"]["message"].as_str().unwrap_or_default();
    assert!(
        message.contains("the `confirm_hub_at_zero` method"),
        "{refused}"
    );
    assert_eq!(
        result(&ws.call("confirm_hub_at_zero", json!({}))),
        &json!({ "ok": true })
    );
    let status = ws.call("status", json!({}));
    assert_eq!(result(&status)["conditions"], json!([]), "{status}");
}

/// A small plan: a plate with a hole.
const PLATE: &str = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" viewBox="0 0 100 50">
  <rect x="5" y="5" width="40" height="30" fill="none" stroke="red" stroke-width="0.01"/>
  <circle cx="25" cy="20" r="5" fill="none" stroke="red" stroke-width="0.01"/>
</svg>"#;

#[test]
fn a_job_runs_on_the_servers_ruida_cutter() {
    let server = Server::start(
        &["--sim", "--sim-kerf-um", "180"],
        &["--cutter", "ruida-sim"],
    );
    let mut ws = server.ws();
    let params = json!({"plan": PLATE, "format": "svg", "prong_offset_mm": [30, -10]});
    let id = ws.send("job", params);
    let response = ws.response(id);
    let job = result(&response);
    let kerf_um = job["kerf_um"].as_f64().unwrap();
    assert!((170.0..200.0).contains(&kerf_um), "{job}");
    let cutter = job["report"]["cutter"].as_str().unwrap();
    assert!(cutter.starts_with("ruida-sim"), "{job}");
}

#[test]
fn a_job_runs_on_the_servers_cutter_with_its_stages_told() {
    let server = Server::start(&["--sim", "--sim-kerf-um", "180"], &["--cutter", "sim"]);
    let mut ws = server.ws();
    let params = json!({
        "plan": PLATE, "format": "svg", "label": "plate", "prong_offset_mm": [30, -10],
    });
    let id = ws.send("job", params);
    let first = ws.notification("stage");
    assert_eq!(first["stage"], "cut-gauge");
    assert_eq!(first["state"], "started");
    let response = ws.response(id);
    let job = result(&response);
    let kerf_um = job["kerf_um"].as_f64().unwrap();
    assert!((170.0..200.0).contains(&kerf_um), "{job}");
    assert_eq!(job["label"], "plate");
    assert!(job["content"].as_str().unwrap().contains("<svg"), "{job}");
    assert!(
        job["gcode"]
            .as_str()
            .unwrap()
            .contains("measured by kerfmeter job")
    );
    // Where the server keeps its copy is not the caller's business.
    let gcode = job["gcode"].as_str().unwrap();
    assert!(
        gcode.contains("(source: the plan sent to kerfmeter serve)"),
        "{gcode:.400}"
    );
    assert!(!gcode.contains("/tmp"), "{gcode:.400}");
    assert!(job["report"].get("input").is_none(), "{job}");
    let stages: Vec<&str> = job["report"]["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(stages.len(), 7, "{job}");
    let mut done = Vec::new();
    while done.len() < 7 {
        let stage = ws.notification("stage");
        if stage["state"] == "done" {
            done.push(stage["stage"].as_str().unwrap().to_owned());
        }
    }
    assert_eq!(done, stages);
    // Clearing the controller's alarm is for someone at the machine, unless the server says
    // (then the request goes on to its other params: here a bad one, so nothing runs).
    let allowing = Server::start(&["--sim"], &["--cutter", "sim", "--allow-unlock"]);
    let passed = allowing.ws().call(
        "job",
        json!({ "plan": PLATE, "format": "svg", "unlock": true, "profile": "x" }),
    );
    let message = passed["error"]["message"].as_str().unwrap().to_owned();
    assert!(
        message.contains("`profile`") && !message.contains("--allow-unlock"),
        "{passed}"
    );
    let unlock = ws.call(
        "job",
        json!({ "plan": PLATE, "format": "svg", "unlock": true }),
    );
    assert_eq!(code(&unlock), -32602, "{unlock}");
    assert!(
        unlock["error"]["message"]
            .as_str()
            .unwrap()
            .contains("--allow-unlock"),
        "{unlock}"
    );
    // Without --cutter, and with a bad plan, it is refused before anything moves.
    let plain = Server::sim(false);
    let refused = plain
        .ws()
        .call("job", json!({ "plan": PLATE, "format": "svg" }));
    assert_eq!(code(&refused), -32004, "{refused}");
    let bad = ws.call(
        "job",
        json!({ "plan": PLATE, "format": "svg", "profile": "/etc/x" }),
    );
    assert!(
        bad["error"]["message"]
            .as_str()
            .unwrap()
            .contains("`profile`"),
        "{bad}"
    );
    // The params are the application layer's JobRequest: a bad value is named by its field,
    // options that exclude each other are refused, and nothing runs.
    let before = result(&ws.call("status", json!({})))["run_id"].clone();
    let mut job = |extra: Value| {
        let mut params = json!({ "plan": PLATE, "format": "svg" });
        params
            .as_object_mut()
            .unwrap()
            .extend(extra.as_object().unwrap().clone());
        ws.call("job", params)
    };
    let point = job(json!({ "origin_mm": [1] }));
    assert_eq!(code(&point), -32602, "{point}");
    assert!(
        point["error"]["message"]
            .as_str()
            .unwrap()
            .contains("`origin_mm`"),
        "{point}"
    );
    let both = job(json!({ "recompensate": true, "already_compensated_ok": true }));
    assert_eq!(code(&both), -32602, "{both}");
    let status = ws.call("status", json!({}));
    assert_eq!(result(&status)["run_id"], before, "nothing ran: {status}");
}

#[test]
fn measurements_are_recorded_and_the_history_survives_a_restart() {
    let (_dir, db) = temp_db();
    let kerf_um = {
        let server = Server::start_with_db(&["--sim"], &[], &db);
        let mut ws = server.ws();
        let params = json!({ "label": "birch 4mm" });
        let run = result(&ws.call("run_kerfmeter", params)).clone();
        assert!(run["history"]["id"].is_i64(), "{run}");
        assert!(
            run["history"].get("db").is_none(),
            "no file path is given out: {run}"
        );
        assert!(run["history"]["error"].is_null(), "{run}");
        let (code, _) = server.post("/api/run", r#"{"label": "mdf"}"#);
        assert_eq!(code, 200);
        run["kerf_um"].as_f64().unwrap()
    };
    // A new server on the same database.
    let server = Server::start_with_db(&["--sim"], &[], &db);
    let mut ws = server.ws();
    let listing = result(&ws.call("history", json!({}))).clone();
    let records = listing["records"].as_array().unwrap();
    assert_eq!(records.len(), 2, "{listing}");
    assert_eq!(records[0]["label"], "mdf", "newest first: {listing}");
    assert_eq!(records[1]["label"], "birch 4mm");
    assert!((records[1]["kerf_um"].as_f64().unwrap() - kerf_um).abs() < 1e-6);
    assert_eq!(records[1]["simulated"], true);
    assert!(
        listing.get("db").is_none(),
        "no file path is given out: {listing}"
    );
    let (status, birch) = server.get("/api/history?label=birch%204mm&limit=5");
    assert_eq!(status, 200, "{birch}");
    assert_eq!(birch["records"].as_array().unwrap().len(), 1, "{birch}");
    let bad = ws.call("history", json!({ "limit": 0 }));
    assert_eq!(code(&bad), -32602);
    assert_eq!(server.get("/api/history?limit=many").0, 400);
}

#[test]
fn a_client_that_vanishes_without_closing_has_its_run_aborted() {
    let server = Server::sim(true);
    let mut gone = server.ws();
    let mut watcher = server.ws();
    // Fifty gauges in real time: far longer than the server waits for a silent client.
    gone.send("run_kerfmeter", json!({ "samples": 50 }));
    watcher.notification("run_started");
    // `gone` never reads again, so it answers no ping: as a laptop that went to sleep.
    let finished = watcher.notification("run_finished");
    assert_eq!(finished["error"]["code"], -32002, "{finished}");
    let status = watcher.call("status", json!({}));
    assert_eq!(result(&status)["torque_nm"], 0.0, "{status}");
    drop(gone);
}

/// A server stopped mid-run (SIGTERM) aborts the run and answers its caller so, and tells
/// `run_finished`, before its connections close.
#[test]
fn a_server_stopped_mid_run_answers_the_run_aborted_before_it_closes() {
    let server = Server::sim(true);
    let mut ws = server.ws();
    let id = ws.send("run_kerfmeter", json!({ "samples": 5 }));
    ws.notification("run_started");
    let killed = Command::new("kill")
        .args(["-TERM", &server.child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let answer = ws.response(id);
    assert_eq!(code(&answer), -32002, "{answer}");
    ws.notification("run_finished");
}

/// A reset clears a latched fault: its answer names the fault, so that it does not vanish
/// unseen.
#[test]
fn a_reset_names_the_fault_it_cleared() {
    let server = Server::start(&["--sim", "--sim-fault", "no-inset"], &[]);
    let mut ws = server.ws();
    let run = ws.call("run_kerfmeter", json!({}));
    assert_eq!(code(&run), -32000, "{run}");
    let fault = run["error"]["data"]["fault"].clone();
    assert!(fault.is_string(), "{run}");
    let reset = ws.call("reset_kerfmeter", json!({}));
    assert_eq!(result(&reset)["cleared_fault"], fault, "{reset}");
    // A second reset has nothing to clear.
    let again = ws.call("reset_kerfmeter", json!({}));
    assert_eq!(result(&again), &json!({ "reset": true }), "{again}");
}
