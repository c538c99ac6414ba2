//! The server's plan methods: `dilate` takes a plan as text (or base64) in the request, never a
//! path, dilates it with the same options and library call as `kerfmeter dilate`, and gives the
//! dilated plan back as text; `gauge` draws the gauge as `kerfmeter gauge` does (its options are
//! the command's flags, read by the command's own parser, so the defaults and checks are the
//! same) and gives the drawing back instead of writing a file. The work runs on a blocking
//! thread of its own, so it neither holds the device nor stalls the other clients.

use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::progress::Progress;
use kerfmeter_plan::{PlanFormat, dilate_bytes};
use serde::Serialize;
use serde_json::{Value, json};

use super::rpc::{Caller, INTERNAL_ERROR, INVALID_PARAMS, Params, RpcError};
use super::worker::{Call, Device};
use crate::commands::dilate::DilationArgs;
use crate::commands::gauge::{GaugeArgs, draw};
use crate::commands::history;
use crate::error::CliError;

/// What `dilate` reports beside the plan: the kerf, the cut rules, and what was found and done
/// (the fields of `kerfmeter dilate --json` that are not about files).
#[derive(Serialize)]
struct PlanReport {
    /// The kerf applied, µm.
    kerf_um: f64,
    /// The cut rules, in words.
    cut_rules: String,
    /// What was found and done.
    #[serde(flatten)]
    summary: PlanSummary,
}

/// `dilate` {plan | plan_base64, format, kerf_um: number | "last", cut_colors, cut_max_width_mm,
/// cut_layers, units, strict, already_compensated_ok, recompensate}.
pub async fn dilate(device: &Device, mut p: Params, by: Caller) -> Result<Value, RpcError> {
    let plan = plan_bytes(&mut p)?;
    let format = format(&mut p)?;
    let kerf_um = kerf_um(device, &mut p, by).await?;
    let defaults = DilationArgs {
        kerf_um,
        map: None,
        cut_colors: Vec::new(),
        cut_max_width_mm: 0.3,
        cut_layers: Vec::new(),
        units: None,
        already_compensated_ok: false,
        recompensate: false,
    };
    let args = DilationArgs {
        cut_colors: p.strings("cut_colors")?.unwrap_or_default(),
        cut_max_width_mm: p
            .f64("cut_max_width_mm")?
            .unwrap_or(defaults.cut_max_width_mm),
        cut_layers: p.strings("cut_layers")?.unwrap_or_default(),
        units: units(&mut p)?,
        already_compensated_ok: p.bool("already_compensated_ok")?.unwrap_or(false),
        recompensate: p.bool("recompensate")?.unwrap_or(false),
        ..defaults
    };
    let strict = p.bool("strict")?.unwrap_or(false);
    p.finish()?;
    let work = move || dilate_plan(plan, format, &args, strict);
    plan_work("the dilation", work).await
}

/// Dilate `plan` as `args` say: the answer of `dilate`.
fn dilate_plan(
    plan: Vec<u8>,
    format: PlanFormat,
    args: &DilationArgs,
    strict: bool,
) -> Result<Value, CliError> {
    let (kerf_um, kerf) = args.kerf()?;
    let options = args.options(strict, Progress::default())?;
    let (output, summary) = dilate_bytes(plan, format, &kerf, &options)?;
    let report = PlanReport {
        kerf_um,
        cut_rules: options.rules.describe(),
        summary,
    };
    let mut answer = json!({ "kerf_um": kerf_um, "format": format, "report": report });
    match String::from_utf8(output) {
        Ok(text) => answer["content"] = Value::String(text),
        Err(binary) => answer["content_base64"] = BASE64.encode(binary.into_bytes()).into(),
    }
    Ok(answer)
}

/// The plan: `plan` (text) or `plan_base64`, exactly one.
pub(super) fn plan_bytes(p: &mut Params) -> Result<Vec<u8>, RpcError> {
    let bytes = given_plan(p)?;
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(RpcError::param("plan", "empty: there is no drawing in it"));
    }
    Ok(bytes)
}

/// The plan as given, `plan` (text) or `plan_base64`.
fn given_plan(p: &mut Params) -> Result<Vec<u8>, RpcError> {
    match (p.string("plan")?, p.string("plan_base64")?) {
        (Some(text), None) => Ok(text.into_bytes()),
        (None, Some(b64)) => BASE64
            .decode(b64.trim())
            .map_err(|e| RpcError::param("plan_base64", format!("not base64: {e}"))),
        (Some(_), Some(_)) => Err(RpcError::param(
            "plan",
            "give `plan` or `plan_base64`, not both",
        )),
        (None, None) => Err(RpcError::param(
            "plan",
            "missing: the plan's text (or `plan_base64`)",
        )),
    }
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

/// `units`: one of the names of [`AssumedUnits`].
fn units(p: &mut Params) -> Result<Option<AssumedUnits>, RpcError> {
    let Some(name) = p.string("units")? else {
        return Ok(None);
    };
    name.parse().map(Some).map_err(|_| {
        let names: Vec<&str> = AssumedUnits::ALL.iter().map(|u| u.name()).collect();
        RpcError::param("units", format!("one of {}", names.join(", ")))
    })
}

/// `kerf_um`: a number, or "last": the device's last result.
async fn kerf_um(device: &Device, p: &mut Params, by: Caller) -> Result<f64, RpcError> {
    let value = p.0.remove("kerf_um").unwrap_or(Value::Null);
    match value {
        Value::Number(n) => n
            .as_f64()
            .ok_or_else(|| RpcError::param("kerf_um", "not a finite number")),
        Value::String(s) if s == "last" => {
            let last = device.call(Call::Kerf, by).await?;
            last["kerf_um"].as_f64().ok_or_else(|| {
                RpcError::new(
                    INVALID_PARAMS,
                    "parameter `kerf_um`: \"last\", but the device has no result: measure first",
                )
            })
        }
        Value::Null => Err(RpcError::param(
            "kerf_um",
            "missing: a number (µm) or \"last\"",
        )),
        other => Err(RpcError::param(
            "kerf_um",
            format!("a number (µm) or \"last\", not {other}"),
        )),
    }
}

/// The `gauge` parameters: those of `kerfmeter gauge`'s flags that make sense without a file
/// (the G-code flags are left out: the gauge's G-code is cut by `job`).
const GAUGE_PARAMS: &[&str] = &[
    "pitch_um_per_deg",
    "radius_mm",
    "prong_radius_mm",
    "hole_radius_mm",
    "hole_distance_mm",
    "jam_direction",
    "disengage_deg",
    "test_piece",
    "thickness_mm",
    "finger_width_mm",
    "test_piece_kerf_um",
    "label",
];

/// `gauge` {format: "svg"|"dxf", ... `kerfmeter gauge`'s options}: `{"format", "content",
/// "report"}`, the report being `gauge --json`'s without the file name.
pub async fn gauge(p: Params) -> Result<Value, RpcError> {
    let args = gauge_args(p)?;
    let format = if args.output.extension().is_some_and(|e| e == "dxf") {
        "dxf"
    } else {
        "svg"
    };
    let work = move || draw(&args);
    let (content, report) = plan_work("the drawing", work).await?;
    let mut report = serde_json::to_value(&report).expect("reports serialize");
    if let Some(fields) = report.as_object_mut() {
        fields.remove("output");
    }
    let mut answer = json!({ "format": format, "report": report });
    match String::from_utf8(content) {
        Ok(text) => answer["content"] = Value::String(text),
        Err(binary) => answer["content_base64"] = BASE64.encode(binary.into_bytes()).into(),
    }
    Ok(answer)
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
pub async fn history(device: &Device, mut p: Params) -> Result<Value, RpcError> {
    let label = p.label()?;
    let limit = p.u32_in("limit", 1..=100_000)?.unwrap_or(50);
    p.finish()?;
    let g = device.global().clone();
    // The twin behind a PTY records its measurements as simulated: list those.
    let simulated = g.sim || device.is_twin();
    let work = move || history::list(&g, simulated, label, limit);
    let report = plan_work("the history", work).await?;
    let mut answer = serde_json::to_value(&report).expect("reports serialize");
    if let Some(fields) = answer.as_object_mut() {
        fields.remove("db");
    }
    Ok(answer)
}

/// The gauge's options, read by `kerfmeter gauge`'s own parser from the params turned into flags.
fn gauge_args(mut p: Params) -> Result<GaugeArgs, RpcError> {
    /// `kerfmeter gauge`'s flags alone.
    #[derive(clap::Parser)]
    struct Gauge {
        #[command(flatten)]
        args: GaugeArgs,
    }
    let format = match p.string("format")?.as_deref() {
        None | Some("svg") => "svg",
        Some("dxf") => "dxf",
        Some(other) => {
            return Err(RpcError::param(
                "format",
                format!("\"svg\" or \"dxf\", not {other:?}"),
            ));
        }
    };
    // The name only chooses the format: nothing is written.
    let mut argv = vec![
        "gauge".to_owned(),
        "-o".to_owned(),
        format!("gauge.{format}"),
    ];
    argv.extend(flags(&mut p, GAUGE_PARAMS)?);
    p.finish()?;
    <Gauge as clap::Parser>::try_parse_from(argv)
        .map(|g| g.args)
        .map_err(|e| clap_error("gauge", &e))
}

/// The params named in `allowed` as the command-line flags they stand for (`radius_mm: 12` is
/// `--radius-mm=12`, `true` a bare flag, `[x, y]` `--name=x,y` for a point or a size
/// ([`POINT_PARAMS`]), any other list `["a", "b"]` `--name=a --name=b`: each its own flag, so
/// that an item's own commas, as in `rgb(255,0,0)` or a layer named `Cut, 3 mm`, are never read
/// as separators). A value is always joined to its flag by `=`, so that a value such as `"-o"`
/// or `"--port=/dev/ttyUSB0"` is read as the value it is, never as a flag of its own.
fn flags(p: &mut Params, allowed: &[&str]) -> Result<Vec<String>, RpcError> {
    let mut argv = Vec::new();
    for name in allowed {
        let flag = format!("--{}", name.replace('_', "-"));
        let item = |v: &Value| match v {
            Value::Number(n) => Ok(n.to_string()),
            Value::String(s) => Ok(s.clone()),
            other => Err(RpcError::param(name, format!("not {other}"))),
        };
        match p.0.remove(*name) {
            None | Some(Value::Null) | Some(Value::Bool(false)) => {}
            Some(Value::Bool(true)) => argv.push(flag),
            Some(Value::Array(items)) => {
                let values: Vec<String> = items.iter().map(item).collect::<Result<_, _>>()?;
                if POINT_PARAMS.contains(name) {
                    // A point or a size: one value, `X,Y`.
                    argv.push(format!("{flag}={}", values.join(",")));
                } else {
                    argv.extend(values.iter().map(|v| format!("{flag}={v}")));
                }
            }
            Some(other) => argv.push(format!("{flag}={}", item(&other)?)),
        }
    }
    Ok(argv)
}

/// A clap refusal of the params of `command`, as -32602.
fn clap_error(command: &str, e: &clap::Error) -> RpcError {
    let why = e.render().to_string();
    let first = why
        .lines()
        .next()
        .unwrap_or_default()
        .trim_start_matches("error: ");
    let why = format!(
        "{command}: {first} (the params are the flags of `kerfmeter {command}`, written with _)"
    );
    RpcError::new(INVALID_PARAMS, why)
}

/// The params that are one point or size given as `[x, y]` (`--name=x,y`).
const POINT_PARAMS: &[&str] = &["gauge_at_mm", "bed_mm", "prong_offset_mm", "origin_mm"];

/// Take the history database's path (`history.db`) out of a measurement's answer: where the
/// server keeps its files is not the clients' business.
pub fn hide_history_db(answer: &mut Value) {
    if let Some(history) = answer.get_mut("history").and_then(Value::as_object_mut) {
        history.remove("db");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_of_strings_is_one_flag_each_and_a_point_one_value() {
        let Value::Object(map) = json!({
            "cut_color": ["rgb(255,0,0)", "blue"],
            "origin_mm": [10, 20.5],
            "cut_layer": "Cut, 3 mm",
            "unlock": true,
        }) else {
            unreachable!("an object")
        };
        let job = ["origin_mm", "cut_color", "cut_layer", "unlock"];
        let argv = flags(&mut Params(map), &job).unwrap();
        assert_eq!(
            argv,
            [
                "--origin-mm=10,20.5",
                "--cut-color=rgb(255,0,0)",
                "--cut-color=blue",
                "--cut-layer=Cut, 3 mm",
                "--unlock"
            ]
        );
    }
}
