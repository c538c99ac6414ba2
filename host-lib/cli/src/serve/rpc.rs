//! JSON-RPC 2.0 for `kerfmeter serve`: the envelope (parsing a request, writing a response or a
//! notification), the error object and its codes, the parameters (each field checked by name),
//! and the one method table that the WebSocket and the HTTP routes share ([`dispatch`]).
//!
//! Only single requests are taken: a batch (a JSON array) is an invalid request. A request
//! without an `id` is a notification: it is carried out and not answered.

use kerfmeter::Category;
use kerfmeter_app::measure::MeasureRequest;
use kerfmeter_app::request::from_params;
use kerfmeter_protocol::advice::in_words_of;
use serde::Serialize;
use serde_json::{Map, Value, json};

use super::worker::{Call, Device, RunCall};
use crate::error::CliError;
use crate::words::SERVER;

/// Not JSON.
pub const PARSE_ERROR: i32 = -32700;
/// JSON, but not a JSON-RPC 2.0 request (or refused before it was read: size, token, origin).
pub const INVALID_REQUEST: i32 = -32600;
/// No such method.
pub const METHOD_NOT_FOUND: i32 = -32601;
/// A parameter is unknown, of the wrong type or out of range; the message names it.
pub const INVALID_PARAMS: i32 = -32602;
/// The device refused, faulted or failed (`data.kind`, `data.fault`, `data.conditions`).
pub const DEVICE_ERROR: i32 = -32000;
/// A run (or reset, or self-test) is already going.
pub const BUSY: i32 = -32001;
/// The call was aborted (`abort`, a client that went away, the server stopping).
pub const ABORTED: i32 = -32002;
/// The device is not connected (it vanished; the server re-opens it when it comes back).
pub const NOT_CONNECTED: i32 = -32003;
/// `job` without a cutter given to `kerfmeter serve --cutter`.
pub const NO_CUTTER: i32 = -32004;
/// A plan could not be read, drawn or dilated.
pub const PLAN_ERROR: i32 = -32005;
/// The history database could not be opened or read (e.g. made by a newer version).
pub const HISTORY_ERROR: i32 = -32006;
/// JSON-RPC's internal error: the server failed inside the call (a bug); the device was told to
/// abort.
pub const INTERNAL_ERROR: i32 = -32603;

/// A JSON-RPC error object: `{"code": N, "message": "...", "data": {...}}`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RpcError {
    /// One of the codes above.
    pub code: i32,
    /// What went wrong, in words, with what to do.
    pub message: String,
    /// Details for programs (the device error's kind, fault and conditions).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data: Option<Value>,
}

impl RpcError {
    /// An error with `code` and `message`, without data.
    pub fn new(code: i32, message: impl Into<String>) -> Self {
        RpcError {
            code,
            message: message.into(),
            data: None,
        }
    }

    /// A parameter that is wrong: `name: why`.
    pub fn param(name: &str, why: impl std::fmt::Display) -> Self {
        Self::new(INVALID_PARAMS, format!("parameter `{name}`: {why}"))
    }

    /// Another client's run holds the device.
    pub fn busy() -> Self {
        Self::new(
            BUSY,
            "a run is already going: wait for it to finish, or abort it",
        )
    }
}

impl From<&CliError> for RpcError {
    fn from(e: &CliError) -> Self {
        let message = in_words_of(&SERVER, || e.to_string());
        match e {
            CliError::Meter(kerfmeter::Error::Cancelled) => RpcError::new(ABORTED, message),
            CliError::Meter(m) if m.category() == Category::Communication => {
                RpcError::new(NOT_CONNECTED, message)
            }
            CliError::Meter(kerfmeter::Error::InvalidArgument(_))
            | CliError::Plan(kerfmeter_plan::PlanError::InvalidArgument(_))
            | CliError::Usage(_) => RpcError::new(INVALID_PARAMS, message),
            CliError::Plan(_) => RpcError {
                data: e
                    .compensation_found()
                    .map(|found| json!({ "compensation_found": found })),
                ..RpcError::new(PLAN_ERROR, message)
            },
            CliError::History(_) => RpcError::new(HISTORY_ERROR, message),
            CliError::Meter(m) => RpcError {
                data: Some(json!({
                    "kind": variant_name(m),
                    "fault": e.fault(),
                    "conditions": e.conditions(),
                })),
                ..RpcError::new(DEVICE_ERROR, message)
            },
            // What the job measured before it stopped (where the server keeps files is not the
            // caller's business: no paths).
            CliError::JobAfterMeasuring { so_far, .. } => RpcError {
                data: Some(json!({
                    "kind": "Job",
                    "fault": e.fault(),
                    "kerf_um": so_far.kerf_um,
                    "history_id": so_far.history.as_ref().and_then(|h| h.id),
                })),
                ..RpcError::new(DEVICE_ERROR, message)
            },
            _ => RpcError {
                data: Some(json!({ "kind": variant_name(e), "fault": e.fault() })),
                ..RpcError::new(DEVICE_ERROR, message)
            },
        }
    }
}

/// The name of an error's variant (`Fault`, `RunTimeout`, ...), from its `Debug` form.
fn variant_name(e: &impl std::fmt::Debug) -> String {
    let debug = format!("{e:?}");
    debug
        .split(|c: char| !c.is_alphanumeric() && c != '_')
        .next()
        .unwrap_or_default()
        .to_owned()
}

/// A request as read: its id (`None`: a notification), method and parameters.
#[derive(Debug)]
pub struct Request {
    /// The id to answer with; `None` for a notification.
    pub id: Option<Value>,
    /// The method's name.
    pub method: String,
    /// The parameters (an empty object when none were given).
    pub params: Params,
}

/// Read one request from `text`. A failure carries the id to answer with (`null` when the id
/// could not be read).
pub fn parse(text: &[u8]) -> Result<Request, (Value, RpcError)> {
    let value: Value = serde_json::from_slice(text).map_err(|e| {
        (
            Value::Null,
            RpcError::new(PARSE_ERROR, format!("not JSON: {e}")),
        )
    })?;
    let Value::Object(mut object) = value else {
        let why = "a request is a JSON object (batches are not supported)";
        return Err((Value::Null, RpcError::new(INVALID_REQUEST, why)));
    };
    let id = object.remove("id");
    let answer_id = id.clone().unwrap_or(Value::Null);
    let invalid = |why: &str| (answer_id.clone(), RpcError::new(INVALID_REQUEST, why));
    if !matches!(
        &id,
        None | Some(Value::Null | Value::Number(_) | Value::String(_))
    ) {
        return Err(invalid("`id` must be a number, a string or null"));
    }
    if object.get("jsonrpc") != Some(&Value::String("2.0".into())) {
        return Err(invalid("`jsonrpc` must be \"2.0\""));
    }
    let Some(Value::String(method)) = object.remove("method") else {
        return Err(invalid("`method` must be a string"));
    };
    let params = match object.remove("params") {
        None | Some(Value::Null) => Map::new(),
        Some(Value::Object(map)) => map,
        Some(_) => {
            let e = RpcError::new(INVALID_PARAMS, "`params` must be an object of named fields");
            return Err((answer_id, e));
        }
    };
    Ok(Request {
        id,
        method,
        params: Params(params),
    })
}

/// The response to a request with `id`.
pub fn response(id: Value, outcome: Result<Value, RpcError>) -> String {
    let value = match outcome {
        Ok(result) => json!({ "jsonrpc": "2.0", "id": id, "result": result }),
        Err(error) => json!({ "jsonrpc": "2.0", "id": id, "error": error }),
    };
    value.to_string()
}

/// A notification (`method` with `params`, no id).
pub fn notification(method: &str, params: Value) -> String {
    json!({ "jsonrpc": "2.0", "method": method, "params": params }).to_string()
}

/// A request's named parameters, taken one by one; what is left at the end is unknown.
#[derive(Debug, Default)]
pub struct Params(pub Map<String, Value>);

impl Params {
    /// The string `name`.
    pub fn string(&mut self, name: &str) -> Result<Option<String>, RpcError> {
        match self.0.remove(name) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s)),
            Some(other) => Err(RpcError::param(
                name,
                format!("expected a string, got {other}"),
            )),
        }
    }

    /// All the parameters as the request `T` (unknown ones refused, each named).
    pub fn into_request<T: serde::de::DeserializeOwned>(self) -> Result<T, RpcError> {
        from_params(Value::Object(self.0)).map_err(|e| RpcError::new(INVALID_PARAMS, e.to_string()))
    }

    /// Refuse any parameter not taken yet.
    pub fn finish(self) -> Result<(), RpcError> {
        match self.0.keys().next() {
            None => Ok(()),
            Some(name) => Err(RpcError::param(name, "no such parameter for this method")),
        }
    }
}

/// Who called: a WebSocket client or an HTTP request (said in `run_started`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Caller {
    /// A JSON-RPC request on the WebSocket.
    Rpc,
    /// An HTTP request to `/api/...`.
    Http,
}

impl Caller {
    /// Its name in notifications.
    pub fn name(self) -> &'static str {
        match self {
            Caller::Rpc => "rpc",
            Caller::Http => "http",
        }
    }
}

/// Carry out `method` with `params` on `device`: the one method table of the server.
pub async fn dispatch(
    device: &Device,
    method: &str,
    mut params: Params,
    by: Caller,
) -> Result<Value, RpcError> {
    let call = match method {
        "info" => Call::Info,
        "status" => Call::Status,
        "get_kerf_value" => Call::Kerf,
        "reset_kerfmeter" => Call::Reset,
        "clear_fault" => Call::ClearFault,
        "confirm_hub_at_zero" => Call::ConfirmZero,
        "self_test" => Call::SelfTest,
        "run_kerfmeter" => Call::Run(run_call(std::mem::take(&mut params))?),
        "abort" => {
            params.finish()?;
            return device.abort().await;
        }
        "dilate" => return super::plans::dilate(device, params, by).await,
        "gauge" => return super::plans::gauge(params).await,
        "history" => return super::plans::history(device, params).await,
        "job" => {
            let Some(cutter) = device.cutter() else {
                let why =
                    "no cutter configured: start the server with `kerfmeter serve --cutter ...`";
                return Err(RpcError::new(NO_CUTTER, why));
            };
            let job = super::job::job_call(params, cutter).await?;
            return device.call(Call::Job(Box::new(job)), by).await;
        }
        _ => {
            let why = format!("no method `{method}`");
            return Err(RpcError::new(METHOD_NOT_FOUND, why));
        }
    };
    params.finish()?;
    device.call(call, by).await
}

/// The parameters of `run_kerfmeter` (a [`MeasureRequest`]), checked as `kerfmeter run` checks
/// its flags.
fn run_call(p: Params) -> Result<RunCall, RpcError> {
    let asked: MeasureRequest = p.into_request()?;
    let params = asked
        .checked()
        .map_err(|e| RpcError::new(INVALID_PARAMS, e.to_string()))?;
    Ok(RunCall {
        params,
        samples: asked.samples as usize,
        label: asked.label,
    })
}
