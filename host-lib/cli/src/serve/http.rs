//! The routes of `kerfmeter serve`: the WebSocket (`GET /rpc`, JSON-RPC 2.0 in text frames,
//! notifications pushed), the HTTP JSON API (`/api/...`, each route one JSON-RPC method), and
//! the page's files, embedded in the binary.
//!
//! An HTTP success is `200` with the method's result as the body; a failure is a 4xx/5xx status
//! with `{"error": {code, message, data}}`, the JSON-RPC error object (see [`status_of`]).
//!
//! On the WebSocket each request is carried out in its own task, so a client can `abort` its
//! own run while it goes; the tasks end with the connection, and a run whose client went away
//! is aborted (see [`super::worker`]). A client that answers no ping for [`SILENCE_LIMIT`] has
//! gone away, even if its connection was never closed.

use std::sync::Arc;
use std::time::Duration;

use tokio::time::Instant;

use axum::Json;
use axum::Router;
use axum::body::Body;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Value, json};
use tokio::sync::{broadcast, mpsc};
use tokio::task::JoinSet;

use super::MAX_BODY_BYTES;
use super::rpc::{self, Caller, Params, RpcError};
use super::security::{Security, guard};
use super::worker::Device;

/// The page's files: path, content type, content. The page is built in `web/`.
const PAGE_FILES: &[(&str, &str, &str)] = &[
    (
        "/",
        "text/html; charset=utf-8",
        include_str!("../../web/index.html"),
    ),
    (
        "/app.js",
        "text/javascript; charset=utf-8",
        include_str!("../../web/app.js"),
    ),
    (
        "/style.css",
        "text/css; charset=utf-8",
        include_str!("../../web/style.css"),
    ),
];

/// How often the server pings each WebSocket client (browsers and WebSocket libraries answer by
/// themselves).
const PING_INTERVAL: Duration = Duration::from_secs(5);

/// A WebSocket client heard from (a message or a pong) less recently than this has gone: its
/// connection is closed and a run it started is aborted.
const SILENCE_LIMIT: Duration = Duration::from_secs(15);

/// Requests one WebSocket client may have going at once; more are answered "busy".
const MAX_IN_FLIGHT: usize = 16;

/// What every route shares.
#[derive(Clone)]
pub struct AppState {
    /// The device.
    pub device: Device,
}

/// Every route, behind the security middleware.
pub fn router(device: Device, security: Arc<Security>) -> Router {
    let mut router = Router::new()
        .route("/rpc", get(upgrade))
        .route("/api/{name}", get(api_get).post(api_post));
    for &(path, content_type, content) in PAGE_FILES {
        let page = move || async move { ([(header::CONTENT_TYPE, content_type)], content) };
        router = router.route(path, get(page));
    }
    router
        .method_not_allowed_fallback(method_not_allowed)
        .fallback(not_found)
        .layer(axum::middleware::from_fn_with_state(security, guard))
        .with_state(AppState { device })
}

/// A route asked with a method it does not take (`DELETE /api/info`): said as every other
/// failure is, `{"error": …}`.
async fn method_not_allowed() -> Response {
    let why = "this route takes GET (reads) or POST (actions) only";
    error_response(
        StatusCode::METHOD_NOT_ALLOWED,
        &RpcError::new(rpc::INVALID_REQUEST, why),
    )
}

/// No such route: said as every other failure is.
async fn not_found() -> Response {
    let why = "no such route: the page is at /, the API at /api/NAME and /rpc";
    error_response(
        StatusCode::NOT_FOUND,
        &RpcError::new(rpc::INVALID_REQUEST, why),
    )
}

/// The HTTP status for a JSON-RPC error code.
pub fn status_of(code: i32) -> StatusCode {
    match code {
        rpc::METHOD_NOT_FOUND => StatusCode::NOT_FOUND,
        rpc::BUSY | rpc::ABORTED => StatusCode::CONFLICT,
        rpc::NOT_CONNECTED => StatusCode::SERVICE_UNAVAILABLE,
        rpc::NO_CUTTER => StatusCode::NOT_IMPLEMENTED,
        rpc::PLAN_ERROR => StatusCode::UNPROCESSABLE_ENTITY,
        rpc::DEVICE_ERROR => StatusCode::BAD_GATEWAY,
        rpc::HISTORY_ERROR | rpc::INTERNAL_ERROR => StatusCode::INTERNAL_SERVER_ERROR,
        _ => StatusCode::BAD_REQUEST,
    }
}

/// `{"error": …}` with `status`.
pub fn error_response(status: StatusCode, error: &RpcError) -> Response {
    (status, Json(json!({ "error": error }))).into_response()
}

/// The HTTP response for a method's outcome.
fn respond(outcome: Result<Value, RpcError>) -> Response {
    match outcome {
        Ok(result) => Json(result).into_response(),
        Err(e) => error_response(status_of(e.code), &e),
    }
}

/// The method behind `/api/NAME` for `get` or POST; `None`: no such route.
fn api_method(name: &str, get: bool) -> Option<&'static str> {
    Some(match (name, get) {
        ("info", true) => "info",
        ("status", true) => "status",
        ("kerf", true) => "get_kerf_value",
        ("history", true) => "history",
        ("run", false) => "run_kerfmeter",
        ("reset", false) => "reset_kerfmeter",
        ("abort", false) => "abort",
        ("dilate", false) => "dilate",
        _ => return None,
    })
}

/// `GET /api/NAME[?k=v&...]`: a method whose parameters, if any, are the query's, as strings
/// (`GET /api/history?label=birch&limit=10`), but `token`.
async fn api_get(
    State(state): State<AppState>,
    Path(name): Path<String>,
    Query(query): Query<Vec<(String, String)>>,
) -> Response {
    let Some(method) = api_method(&name, true) else {
        return no_route(&name);
    };
    // `token` is the security layer's, already checked.
    let params = query
        .into_iter()
        .filter(|(k, _)| k != "token")
        .map(|(k, v)| (k, Value::String(v)));
    let params = Params(params.collect());
    respond(rpc::dispatch(&state.device, method, params, Caller::Http).await)
}

/// `POST /api/NAME`: a method whose parameters are the body (a JSON object; empty: none).
async fn api_post(State(state): State<AppState>, Path(name): Path<String>, body: Body) -> Response {
    let Some(method) = api_method(&name, false) else {
        return no_route(&name);
    };
    let Ok(bytes) = axum::body::to_bytes(body, MAX_BODY_BYTES).await else {
        let why = format!("the request body is larger than {MAX_BODY_BYTES} bytes");
        let e = RpcError::new(rpc::INVALID_REQUEST, why);
        return error_response(StatusCode::PAYLOAD_TOO_LARGE, &e);
    };
    let params = if bytes.iter().all(u8::is_ascii_whitespace) {
        Ok(Params::default())
    } else {
        params_of(&bytes)
    };
    match params {
        Ok(params) => respond(rpc::dispatch(&state.device, method, params, Caller::Http).await),
        Err(e) => respond(Err(e)),
    }
}

/// A POST body's parameters: a JSON object.
fn params_of(body: &[u8]) -> Result<Params, RpcError> {
    match serde_json::from_slice(body) {
        Ok(Value::Object(map)) => Ok(Params(map)),
        Ok(_) => Err(RpcError::new(
            rpc::INVALID_PARAMS,
            "the body must be a JSON object of named parameters",
        )),
        Err(e) => Err(RpcError::new(rpc::PARSE_ERROR, format!("not JSON: {e}"))),
    }
}

/// 404 for `/api/NAME` with the wrong name or verb.
fn no_route(name: &str) -> Response {
    let e = RpcError::new(
        rpc::METHOD_NOT_FOUND,
        format!("no route /api/{name} for this method (GET or POST)"),
    );
    error_response(StatusCode::NOT_FOUND, &e)
}

/// `GET /rpc`: become a WebSocket speaking JSON-RPC (messages up to [`MAX_BODY_BYTES`]). The
/// client hears every notification sent once its handshake is answered: it subscribes before.
async fn upgrade(State(state): State<AppState>, ws: WebSocketUpgrade) -> Response {
    let events = state.device.subscribe();
    ws.max_message_size(MAX_BODY_BYTES)
        .max_frame_size(MAX_BODY_BYTES)
        .on_upgrade(move |socket| connection(socket, state.device, events))
}

/// One WebSocket client: its requests in, their answers and every notification out.
async fn connection(
    mut socket: WebSocket,
    device: Device,
    mut events: broadcast::Receiver<Arc<str>>,
) {
    let (answers, mut to_send) = mpsc::unbounded_channel::<String>();
    let mut tasks = JoinSet::new();
    let mut ping = tokio::time::interval(PING_INTERVAL);
    let mut heard = Instant::now();
    loop {
        let out: String = tokio::select! {
            message = socket.recv() => {
                heard = Instant::now();
                match message {
                    Some(Ok(Message::Text(text))) => {
                        request(&device, text.as_bytes(), &answers, &mut tasks);
                        continue;
                    }
                    Some(Ok(Message::Binary(_))) => rpc::response(Value::Null, Err(RpcError::new(
                        rpc::INVALID_REQUEST, "send JSON-RPC requests as text frames",
                    ))),
                    Some(Ok(_)) => continue,
                    None | Some(Err(_)) => break,
                }
            }
            _ = ping.tick() => {
                // A client that vanished without closing (Wi-Fi gone, laptop asleep) answers no
                // ping: it is gone, and so is any run it started.
                if heard.elapsed() > SILENCE_LIMIT {
                    break;
                }
                if !sent(&mut socket, Message::Ping(Default::default())).await {
                    break;
                }
                continue;
            }
            Some(answer) = to_send.recv() => answer,
            event = events.recv() => match event {
                Ok(text) => text.to_string(),
                Err(broadcast::error::RecvError::Lagged(_)) => continue,
                Err(broadcast::error::RecvError::Closed) => break,
            },
            Some(_) = tasks.join_next() => continue,
        };
        if !sent(&mut socket, Message::Text(out.into())).await {
            break;
        }
    }
    // Dropping the tasks drops a run this client started: it is aborted, its motor stops.
    tasks.abort_all();
}

/// Send `message`; false when the client is gone, or reads nothing for [`SILENCE_LIMIT`] (its
/// buffers full: a client that vanished without closing).
async fn sent(socket: &mut WebSocket, message: Message) -> bool {
    matches!(
        tokio::time::timeout(SILENCE_LIMIT, socket.send(message)).await,
        Ok(Ok(()))
    )
}

/// Start carrying out one request from a WebSocket client; its answer goes to `answers`.
fn request(
    device: &Device,
    text: &[u8],
    answers: &mpsc::UnboundedSender<String>,
    tasks: &mut JoinSet<()>,
) {
    let request = match rpc::parse(text) {
        Ok(request) => request,
        Err((id, e)) => {
            let _ = answers.send(rpc::response(id, Err(e)));
            return;
        }
    };
    if tasks.len() >= MAX_IN_FLIGHT {
        let e = RpcError::new(rpc::BUSY, "too many requests in flight on this connection");
        let _ = answers.send(rpc::response(request.id.unwrap_or(Value::Null), Err(e)));
        return;
    }
    let (device, answers) = (device.clone(), answers.clone());
    tasks.spawn(async move {
        let rpc::Request { id, method, params } = request;
        let outcome = rpc::dispatch(&device, &method, params, Caller::Rpc).await;
        if let Some(id) = id {
            let _ = answers.send(rpc::response(id, outcome));
        }
    });
}
