//! The server's plan methods: `dilate` takes a plan as text (or base64) in the request, never a
//! path, dilates it with the same options and library call as `kerfmeter dilate`, and gives the
//! dilated plan back as text; `gauge` draws the gauge as `kerfmeter gauge` does (its options are
//! the command's flags, read by the command's own parser, so the defaults and checks are the
//! same) and gives the drawing back instead of writing a file. The work runs on a blocking
//! thread of its own, so it neither holds the device nor stalls the other clients.

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use kerfmeter_app::dilate::{DilateTextRequest, KerfGiven, dilate_text};
use kerfmeter_app::request::BadParam;
use kerfmeter_plan::PlanFormat;
use serde::Serialize;
use serde_json::Value;

use super::rpc::{Caller, INTERNAL_ERROR, INVALID_PARAMS, Params, RpcError};
use super::worker::{Call, Device};
use crate::error::CliError;
use kerfmeter_app::gauge::{GaugeFormat, GaugeReport, GaugeRequest, draw};
use kerfmeter_app::history::listing::{ListRequest, list};

/// `dilate` {plan | plan_base64, format, kerf_um: number | "last", cut_colors, cut_max_width_mm,
/// cut_layers, units, strict, already_compensated_ok, recompensate}: a [`DilateTextRequest`].
pub async fn dilate(device: &Device, p: Params, by: Caller) -> Result<Value, RpcError> {
    let asked: DilateTextRequest = p.into_request()?;
    let plan = asked.plan_bytes().map_err(bad_param)?;
    let kerf_um = match asked.kerf_um {
        KerfGiven::Um(kerf_um) => kerf_um,
        KerfGiven::Last(_) => last_kerf_um(device, by).await?,
    };
    let dilation = asked.dilation(kerf_um).map_err(bad_param)?;
    let (format, strict) = (asked.format, asked.strict);
    let work = move || {
        dilate_text(plan, format, &dilation, strict)
            .map(|a| to_value(&a))
            .map_err(CliError::from)
    };
    plan_work("the dilation", work).await
}

/// A parameter the request's own checks refused, as -32602.
fn bad_param(e: BadParam) -> RpcError {
    RpcError::new(INVALID_PARAMS, e.to_string())
}

/// An answer as JSON.
fn to_value(answer: &impl Serialize) -> Value {
    serde_json::to_value(answer).expect("answers serialize")
}

/// `kerf_um: "last"`: the device's last result.
async fn last_kerf_um(device: &Device, by: Caller) -> Result<f64, RpcError> {
    let last = device.call(Call::Kerf, by).await?;
    last["kerf_um"].as_f64().ok_or_else(|| {
        RpcError::new(
            INVALID_PARAMS,
            "parameter `kerf_um`: \"last\", but the device has no result: measure first",
        )
    })
}

/// The plan: `plan` (text) or `plan_base64`, exactly one, not empty.
pub(super) fn plan_bytes(p: &mut Params) -> Result<Vec<u8>, RpcError> {
    let (plan, plan_base64) = (p.string("plan")?, p.string("plan_base64")?);
    kerfmeter_app::dilate::plan_bytes(plan.as_deref(), plan_base64.as_deref()).map_err(bad_param)
}

/// `format`: "svg" or "dxf" (required: there is no file name to tell).
pub(super) fn format(p: &mut Params) -> Result<PlanFormat, RpcError> {
    match p.string("format")?.as_deref() {
        Some("svg") => Ok(PlanFormat::Svg),
        Some("dxf") => Ok(PlanFormat::Dxf),
        Some(other) => Err(RpcError::param(
            "format",
            format!("\"svg\" or \"dxf\", not {other:?}"),
        )),
        None => Err(RpcError::param("format", "missing: \"svg\" or \"dxf\"")),
    }
}

/// The drawing sent back: its format, the report (`gauge --json`'s, without a file name) and
/// the content as text (or base64 when it is binary).
#[derive(Serialize)]
struct GaugeAnswer {
    format: GaugeFormat,
    report: GaugeReport,
    #[serde(skip_serializing_if = "Option::is_none")]
    content: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    content_base64: Option<String>,
}

/// `gauge` {format: "svg"|"dxf", ... `kerfmeter gauge`'s options}: a [`GaugeRequest`], drawn
/// and sent back. Its G-code is left out: the gauge's G-code is cut by `job`.
pub async fn gauge(p: Params) -> Result<Value, RpcError> {
    let asked: GaugeRequest = p.into_request()?;
    if asked.format == GaugeFormat::Gcode {
        let why = "\"svg\" or \"dxf\" (the gauge's G-code is cut by `job`)";
        return Err(RpcError::param("format", why));
    }
    let work = move || draw(&asked).map_err(CliError::from);
    let (content, report) = plan_work("the drawing", work).await?;
    let (content, content_base64) = match String::from_utf8(content) {
        Ok(text) => (Some(text), None),
        Err(binary) => (None, Some(BASE64.encode(binary.into_bytes()))),
    };
    let answer = GaugeAnswer {
        format: report.format,
        report,
        content,
        content_base64,
    };
    Ok(to_value(&answer))
}

/// Plans read, dilated or drawn at once, server-wide: each may take many times its plan's size in
/// memory (16 MiB bodies, 16 requests per connection, any number of connections), and a
/// server killed for want of memory mid-run could not stop its motor. The rest wait their turn.
static PLAN_WORK: tokio::sync::Semaphore = tokio::sync::Semaphore::const_new(2);

/// Run `work` (plan reading, dilation or drawing; `what`, for a message) on a blocking thread
/// when [`PLAN_WORK`] lets it. Its error is answered as [`RpcError::from`] says; a panic in it
/// (a bug) as -32603, "`what` failed".
pub(super) async fn plan_work<T, E>(
    what: &str,
    work: impl FnOnce() -> Result<T, E> + Send + 'static,
) -> Result<T, RpcError>
where
    T: Send + 'static,
    E: Send + 'static,
    for<'e> RpcError: From<&'e E>,
{
    let _permit = PLAN_WORK
        .acquire()
        .await
        .expect("the semaphore is never closed");
    match tokio::task::spawn_blocking(work).await {
        Ok(done) => done.map_err(|e| RpcError::from(&e)),
        Err(e) => Err(RpcError::new(INTERNAL_ERROR, format!("{what} failed: {e}"))),
    }
}

/// `history` {label, limit (1..=100000, default 50)}: the newest records of the server's history
/// database (the simulated ones when the server runs the twin), newest first, with the drift
/// warnings; the same listing as `kerfmeter history --json`, without the database's path.
pub async fn history(device: &Device, p: Params) -> Result<Value, RpcError> {
    let asked: ListRequest = p.into_request()?;
    asked
        .checked()
        .map_err(|e| RpcError::new(INVALID_PARAMS, e.to_string()))?;
    let g = device.global().clone();
    // The twin behind a PTY records its measurements as simulated: list those.
    let simulated = g.sim || device.is_twin();
    let work = move || list(g.db.as_deref(), &asked, simulated, false).map_err(CliError::from);
    let report = plan_work("the history", work).await?;
    let mut answer = serde_json::to_value(&report).expect("reports serialize");
    if let Some(fields) = answer.as_object_mut() {
        fields.remove("db");
    }
    Ok(answer)
}

/// Take the history database's path (`history.db`) out of a measurement's answer: where the
/// server keeps its files is not the clients' business.
pub fn hide_history_db(answer: &mut Value) {
    if let Some(history) = answer.get_mut("history").and_then(Value::as_object_mut) {
        history.remove("db");
    }
}
