//! LightBurn's local REST API (LightBurn 2.2 and later): pair with a running LightBurn and write
//! the measured kerf into the Kerf Offset of its Line layers, as `kerfmeter lightburn pair` and
//! `kerfmeter lightburn apply` do.
//!
//! Written from LightBurn's published specification (the "LightBurn / MillMage REST API"
//! documentation and `openapi.yaml` that LightBurn Software publishes):
//!
//! * the API listens on `http://localhost:19520` while LightBurn is open (loopback only unless
//!   "Allow API Access From Network" is on);
//! * **pairing**: `POST /api/connect` with `{"application_name", "capabilities"}` (localhost
//!   only); LightBurn shows a consent dialog and answers `200 {"status":"ok","secret":…}`, or
//!   `403` when declined or after its 30-second timeout. Each pairing gives a new secret, which
//!   the client keeps ([`Pairing`], in the user's config directory);
//! * **signing**: every other request carries `Authorization: Bearer <token>` with
//!   `token = hex(HMAC-SHA256(key = secret, message = decimal floor(unix_time / 60)))`; the
//!   server accepts the current and the previous minute ([`bearer_token`]);
//! * `GET /api/units` (capability `state`) gives the display units, which cut values use;
//!   `GET /api/layers` and `GET /api/cuts` (`project`) the layers in use and every cut entry
//!   with its global `index`; `POST /api/cuts/{index}` (`project_write`) changes the fields sent
//!   (here `params.kerf`, and the `kerf` of Line sub-layers), all or nothing, and answers `409`
//!   while the cut settings editor is open.
//!
//! The Kerf Offset written is LightBurn's convention, the same as the offline
//! `kerfmeter dilate project.lbrn2`: half the kerf, positive (outward), converted to the display
//! units (mm or inches). A layer already carrying a non-zero Kerf Offset is refused unless the
//! caller says to replace it or add to it ([`ExistingOffset`]).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use hmac::{Hmac, KeyInit, Mac};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use sha2::Sha256;

use crate::error::Category;
use crate::files::write_atomically_with_mode;

/// LightBurn's API address (the port is fixed per product).
pub const DEFAULT_HOST: &str = "127.0.0.1:19520";
/// The name LightBurn's consent dialog shows.
pub const APPLICATION_NAME: &str = "Kerfmeter";
/// What this program asks for: the units (`state`), the layers and cuts (`project`), and
/// changing cuts (`project_write`).
pub const CAPABILITIES: [&str; 3] = ["state", "project", "project_write"];
/// How long a request may take; pairing waits for the user (LightBurn gives up after 30 s).
const TIMEOUT_MS: u64 = 10_000;
const PAIRING_TIMEOUT_MS: u64 = 40_000;
/// Environment variable naming the pairing file instead of the user's config directory.
pub const PAIRING_FILE_ENV: &str = "KERFMETER_LIGHTBURN_PAIRING";

/// What went wrong talking to LightBurn; every message says what to do.
#[derive(Debug, thiserror::Error)]
pub enum LightBurnError {
    /// The LightBurn twin (`--sim`) could not start (no loopback port, no thread).
    #[error("the LightBurn twin could not start: {source}")]
    TwinFailed {
        /// Why.
        source: std::io::Error,
    },
    /// Nothing listens at the address.
    #[error(
        "LightBurn is not running at {host} (connection refused): start LightBurn 2.2 or later and try again"
    )]
    NotRunning {
        /// The address tried.
        host: String,
    },
    /// No pairing secret is stored.
    #[error(
        "this program is not paired with LightBurn ({}): run `kerfmeter lightburn pair` and approve the dialog in LightBurn",
        path.display()
    )]
    Unpaired {
        /// Where the secret was looked for.
        path: PathBuf,
    },
    /// The pairing was declined, or its dialog timed out.
    #[error(
        "LightBurn declined the pairing (refused in its dialog, not answered within 30 s, or not asked from this computer)"
    )]
    Declined,
    /// The secret was refused (revoked, or the clocks differ by more than a minute).
    #[error(
        "LightBurn refused this program's signature ({status}): its pairing was revoked or lacks a capability, or this computer's clock is more than a minute off; pair again with `kerfmeter lightburn pair`"
    )]
    Unauthorized {
        /// 401 or 403.
        status: u16,
    },
    /// A cut settings editor is open in LightBurn.
    #[error(
        "LightBurn's cut settings editor is open, so it changes no settings (409): close it and run again"
    )]
    EditorOpen,
    /// A request failed after some layers were set (layers are set one request at a time).
    ///
    /// Those layers now hold this kerf's Kerf Offset, so a plain re-run would refuse them as
    /// compensated, and adding on top would count the kerf twice: the way out is to replace.
    #[error(
        "{cause}; but {done} had already been set to this kerf's Kerf Offset: once that is fixed, run `kerfmeter lightburn apply` again with --recompensate (it replaces the Kerf Offsets this run set)"
    )]
    PartlyApplied {
        /// The layers set before the failure and their previous Kerf Offsets, e.g.
        /// `layer 0 "C00" (was 0 mm)`.
        done: String,
        /// The failure.
        cause: Box<LightBurnError>,
    },
    /// LightBurn refused a request for another reason.
    #[error("LightBurn refused {request} ({status}): {message}")]
    Refused {
        /// The request.
        request: String,
        /// The HTTP status.
        status: u16,
        /// Its `error` text.
        message: String,
    },
    /// The answer does not fit the specification.
    #[error("LightBurn answered {request} unexpectedly: {message}")]
    Protocol {
        /// The request.
        request: String,
        /// What was wrong.
        message: String,
    },
    /// The link failed (not a refused connection).
    #[error("cannot talk to LightBurn at {host}: {message}")]
    Link {
        /// The address.
        host: String,
        /// Why.
        message: String,
    },
    /// The layers asked for, or the offsets found, stop the change.
    #[error("{0}")]
    Layers(String),
    /// A chosen layer already has a Kerf Offset, and neither `--recompensate` nor
    /// `--already-compensated-ok` said what to do with it: nothing was changed.
    #[error(
        "Kerf Offsets already set ({}): the project is already compensated; nothing was changed. Replace them by this kerf's with --recompensate, or add this kerf's on top with --already-compensated-ok",
        found.join("; ")
    )]
    AlreadyCompensated {
        /// Each such layer with its passes' Kerf Offsets as LightBurn shows them, e.g.
        /// `layer 0 "Cut": 0.05 mm`.
        found: Vec<String>,
        /// Every non-zero Kerf Offset among them, µm (positive outwards).
        offsets_um: Vec<f64>,
    },
    /// The pairing file cannot be read or written.
    #[error("{}: {message}", path.display())]
    PairingFile {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
}

impl LightBurnError {
    /// What kind of failure this is.
    pub fn category(&self) -> Category {
        match self {
            LightBurnError::Layers(_)
            | LightBurnError::Unpaired { .. }
            | LightBurnError::AlreadyCompensated { .. } => Category::Usage,
            LightBurnError::PairingFile { .. } => Category::File,
            _ => Category::Communication,
        }
    }
}

type Result<T, E = LightBurnError> = std::result::Result<T, E>;

/// The bearer token for `secret` at `unix_s` (seconds since 1970): hex of HMAC-SHA256 keyed by
/// the secret over the decimal Unix minute.
pub fn bearer_token(secret: &str, unix_s: u64) -> String {
    let mut mac =
        Hmac::<Sha256>::new_from_slice(secret.as_bytes()).expect("HMAC takes any key length");
    mac.update((unix_s / 60).to_string().as_bytes());
    hex::encode(mac.finalize().into_bytes())
}

fn now_s() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

/// A pairing with LightBurn, as stored: the address and the secret it gave.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pairing {
    /// The API's address, `host:port`.
    pub host: String,
    /// The shared secret (keep it like a password).
    pub secret: String,
    /// The capabilities it grants.
    pub capabilities: Vec<String>,
}

impl Pairing {
    /// Where the pairing is kept: `$KERFMETER_LIGHTBURN_PAIRING`, else
    /// `<config dir>/kerfmeter/lightburn.json`.
    pub fn default_path() -> Option<PathBuf> {
        std::env::var_os(PAIRING_FILE_ENV)
            .map(PathBuf::from)
            .or_else(|| dirs::config_dir().map(|d| d.join("kerfmeter").join("lightburn.json")))
    }

    /// The pairing stored at `path`; [`LightBurnError::Unpaired`] when there is none.
    pub fn load(path: &Path) -> Result<Pairing> {
        let text = match std::fs::read_to_string(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(LightBurnError::Unpaired {
                    path: path.to_owned(),
                });
            }
            other => other.map_err(|e| pairing_file(path, e))?,
        };
        serde_json::from_str(&text).map_err(|e| pairing_file(path, e))
    }

    /// Store this pairing at `path` (atomically; readable by the user only on Unix).
    pub fn save(&self, path: &Path) -> Result<()> {
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| pairing_file(path, e))?;
        }
        let text = serde_json::to_string_pretty(self).expect("a pairing serializes");
        // Written 0600 from the start: the secret is never readable by others, even briefly.
        write_atomically_with_mode(path, text.as_bytes(), 0o600).map_err(|e| pairing_file(path, e))
    }
}

fn pairing_file(path: &Path, e: impl std::fmt::Display) -> LightBurnError {
    LightBurnError::PairingFile {
        path: path.to_owned(),
        message: e.to_string(),
    }
}

/// A blocking client of LightBurn's API at one address.
pub struct Client {
    agent: ureq::Agent,
    host: String,
}

impl Client {
    /// A client of the API at `host` (`host:port`), waiting at most `timeout_ms` per request.
    fn with_timeout(host: &str, timeout_ms: u64) -> Client {
        let config = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_millis(timeout_ms)))
            .build();
        Client {
            agent: config.into(),
            host: host.to_string(),
        }
    }

    /// A client of the API at `host` (`host:port`).
    pub fn new(host: &str) -> Client {
        Client::with_timeout(host, TIMEOUT_MS)
    }

    /// Pair: LightBurn asks its user; the pairing on approval.
    pub fn pair(host: &str) -> Result<Pairing> {
        let client = Client::with_timeout(host, PAIRING_TIMEOUT_MS);
        let body = json!({ "application_name": APPLICATION_NAME, "capabilities": CAPABILITIES });
        let (status, answer) = client.call("POST /api/connect", None, Some(body))?;
        match status {
            200 => {}
            403 => return Err(LightBurnError::Declined),
            _ => return Err(refused("POST /api/connect", status, &answer)),
        }
        let secret = answer["secret"]
            .as_str()
            .filter(|s| !s.is_empty())
            .ok_or_else(|| LightBurnError::Protocol {
                request: "POST /api/connect".into(),
                message: "no secret in the answer".into(),
            })?;
        Ok(Pairing {
            host: host.to_string(),
            secret: secret.to_string(),
            capabilities: CAPABILITIES.map(String::from).to_vec(),
        })
    }

    /// One request (`"METHOD /path"`), signed with `secret` when given: the status and the
    /// JSON answer (`Null` when the body is empty or not JSON).
    fn call(
        &self,
        request: &str,
        secret: Option<&str>,
        body: Option<Value>,
    ) -> Result<(u16, Value)> {
        let (method, path) = request.split_once(' ').unwrap_or(("GET", request));
        let url = format!("http://{}{path}", self.host);
        let auth = secret.map(|s| format!("Bearer {}", bearer_token(s, now_s())));
        let sent = match (method, body) {
            ("POST", body) => {
                let mut r = self.agent.post(&url);
                if let Some(a) = &auth {
                    r = r.header("Authorization", a);
                }
                r.send_json(body.unwrap_or(Value::Null))
            }
            _ => {
                let mut r = self.agent.get(&url);
                if let Some(a) = &auth {
                    r = r.header("Authorization", a);
                }
                r.call()
            }
        };
        let mut response = sent.map_err(|e| self.link_error(e))?;
        let status = response.status().as_u16();
        let text = response
            .body_mut()
            .read_to_string()
            .map_err(|e| self.link_error(e))?;
        Ok((status, serde_json::from_str(&text).unwrap_or(Value::Null)))
    }

    fn link_error(&self, e: ureq::Error) -> LightBurnError {
        let refused = match &e {
            ureq::Error::Io(io) => io.kind() == std::io::ErrorKind::ConnectionRefused,
            ureq::Error::ConnectionFailed => true,
            _ => false,
        };
        if refused {
            LightBurnError::NotRunning {
                host: self.host.clone(),
            }
        } else {
            LightBurnError::Link {
                host: self.host.clone(),
                message: e.to_string(),
            }
        }
    }

    /// A signed request whose only good answer is 200.
    fn signed(&self, secret: &str, request: &str, body: Option<Value>) -> Result<Value> {
        let (status, answer) = self.call(request, Some(secret), body)?;
        match status {
            200 => Ok(answer),
            401 | 403 => Err(LightBurnError::Unauthorized { status }),
            _ => Err(refused(request, status, &answer)),
        }
    }
}

fn refused(request: &str, status: u16, answer: &Value) -> LightBurnError {
    LightBurnError::Refused {
        request: request.into(),
        status,
        message: answer["error"].as_str().unwrap_or("no reason given").into(),
    }
}

fn protocol(request: &str, message: &str) -> LightBurnError {
    LightBurnError::Protocol {
        request: request.into(),
        message: message.into(),
    }
}

/// What to do with a layer that already has a Kerf Offset.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ExistingOffset {
    /// Refuse: the project is already compensated (the default).
    #[default]
    Refuse,
    /// Replace it by this kerf's.
    Replace,
    /// Add this kerf's to it.
    Add,
}

/// A layer whose Kerf Offset was set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LayerSet {
    /// The cut entry's global index (`/api/cuts/{index}`).
    pub cut_index: i64,
    /// The layer's slot.
    pub layer_index: i64,
    /// Its name.
    pub name: String,
    /// Its line passes' Kerf Offsets before, display units (base first, then sub-layers).
    pub before: Vec<f64>,
    /// The Kerf Offsets written, display units.
    pub after: Vec<f64>,
}

/// What `apply` did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Applied {
    /// The kerf, µm.
    pub kerf_um: f64,
    /// The display distance unit of the values (`mm` or `in`).
    pub unit: &'static str,
    /// The Kerf Offset for it in that unit: half the kerf, positive (outward).
    pub kerf_offset: f64,
    /// The layers set.
    pub layers: Vec<LayerSet>,
}

/// A Line pass of a cut entry: `None` for the layer's own, else the sub-layer's index.
struct LinePass {
    sub_layer: Option<i64>,
    kerf: f64,
}

/// A cut entry that has Line passes.
struct LineCut {
    index: i64,
    layer_index: i64,
    name: String,
    passes: Vec<LinePass>,
}

/// Set the Kerf Offset of LightBurn's Line layers for `kerf_um`: the layers named in `layers`
/// (slot index or name), or every Line layer in use.
pub fn apply_kerf(
    client: &Client,
    pairing: &Pairing,
    kerf_um: f64,
    layers: &[String],
    existing: ExistingOffset,
) -> Result<Applied> {
    let secret = pairing.secret.as_str();
    let (unit, per_mm) = distance_unit(&client.signed(secret, "GET /api/units", None)?)?;
    let cuts = line_cuts(&client.signed(secret, "GET /api/cuts", None)?)?;
    let chosen = choose(client, secret, cuts, layers)?;
    refuse_compensated(&chosen, existing, unit, per_mm)?;
    let offset = kerf_um / 2000.0 * per_mm;
    let mut set = Vec::new();
    for cut in chosen {
        let after: Vec<f64> = cut
            .passes
            .iter()
            .map(|p| match existing {
                ExistingOffset::Add => p.kerf + offset,
                _ => offset,
            })
            .collect();
        if let Err(cause) = post_cut(client, secret, &cut, &after) {
            return Err(partly_applied(cause, &set, unit));
        }
        set.push(LayerSet {
            cut_index: cut.index,
            layer_index: cut.layer_index,
            name: cut.name,
            before: cut.passes.iter().map(|p| p.kerf).collect(),
            after,
        });
    }
    Ok(Applied {
        kerf_um,
        unit,
        kerf_offset: offset,
        layers: set,
    })
}

/// `POST /api/cuts/{index}` setting the Line passes of `cut` to `after`.
fn post_cut(client: &Client, secret: &str, cut: &LineCut, after: &[f64]) -> Result<()> {
    let request = format!("POST /api/cuts/{}", cut.index);
    let (status, answer) = client.call(&request, Some(secret), Some(body(cut, after)))?;
    match status {
        200 => Ok(()),
        409 => Err(LightBurnError::EditorOpen),
        401 | 403 => Err(LightBurnError::Unauthorized { status }),
        _ => Err(refused(&request, status, &answer)),
    }
}

/// `cause`, saying which layers of `set` were changed before it and what they held (as is when
/// none were).
fn partly_applied(cause: LightBurnError, set: &[LayerSet], unit: &str) -> LightBurnError {
    if set.is_empty() {
        return cause;
    }
    let each: Vec<String> = set
        .iter()
        .map(|l| {
            let before: Vec<String> = l.before.iter().map(f64::to_string).collect();
            format!(
                "layer {} \"{}\" (was {} {unit})",
                l.layer_index,
                l.name,
                before.join(", ")
            )
        })
        .collect();
    LightBurnError::PartlyApplied {
        done: each.join(", "),
        cause: Box::new(cause),
    }
}

/// The distance unit of `GET /api/units` and how many of it make a mm.
fn distance_unit(answer: &Value) -> Result<(&'static str, f64)> {
    match answer["units"].as_str() {
        Some(u) if u.starts_with("mm") => Ok(("mm", 1.0)),
        Some(u) if u.starts_with("in") => Ok(("in", 1.0 / 25.4)),
        other => Err(protocol(
            "GET /api/units",
            &format!("unknown display units {other:?}"),
        )),
    }
}

/// The `normal` cut entries of `GET /api/cuts` that have Line passes (mode `cut`).
fn line_cuts(answer: &Value) -> Result<Vec<LineCut>> {
    const REQ: &str = "GET /api/cuts";
    if answer["product"] != "lightburn" {
        return Err(protocol(
            REQ,
            "not LightBurn's cut list (product is not \"lightburn\")",
        ));
    }
    let cuts = answer["cuts"]
        .as_array()
        .ok_or_else(|| protocol(REQ, "no cuts"))?;
    let mut out = Vec::new();
    for c in cuts
        .iter()
        .filter(|c| c["kind"] == "normal" && c["layer_index"].as_i64() >= Some(0))
    {
        let mut passes = Vec::new();
        if c["mode"] == "cut" {
            passes.push(LinePass {
                sub_layer: None,
                kerf: c["params"]["kerf"].as_f64().unwrap_or(0.0),
            });
        }
        for s in c["sub_layers"].as_array().into_iter().flatten() {
            if s["mode"] == "cut" {
                passes.push(LinePass {
                    sub_layer: s["index"].as_i64(),
                    kerf: s["params"]["kerf"].as_f64().unwrap_or(0.0),
                });
            }
        }
        out.push(LineCut {
            index: c["index"]
                .as_i64()
                .ok_or_else(|| protocol(REQ, "a cut has no index"))?,
            layer_index: c["layer_index"].as_i64().unwrap_or(-1),
            name: c["name"].as_str().unwrap_or("").to_string(),
            passes,
        });
    }
    Ok(out)
}

/// The cuts to set: those `layers` name (by slot index or whole name, or a comma-separated list
/// of them), or every Line layer in use.
fn choose(
    client: &Client,
    secret: &str,
    cuts: Vec<LineCut>,
    layers: &[String],
) -> Result<Vec<LineCut>> {
    if layers.is_empty() {
        let answer = client.signed(secret, "GET /api/layers", None)?;
        let in_use: BTreeSet<i64> = answer["layers"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|l| l["in_use"] == true)
            .filter_map(|l| l["index"].as_i64())
            .collect();
        let chosen: Vec<LineCut> = cuts
            .into_iter()
            .filter(|c| !c.passes.is_empty() && in_use.contains(&c.layer_index))
            .collect();
        if chosen.is_empty() {
            return Err(LightBurnError::Layers(
                "the open LightBurn project uses no Line layer: nothing to set".into(),
            ));
        }
        return Ok(chosen);
    }
    let mut problems = Vec::new();
    let matches = |c: &LineCut, s: &str| c.layer_index.to_string() == s.trim() || c.name == s;
    // A value names one layer whole (a name may hold a comma), or lists several by commas: the
    // rule of `kerfmeter dilate --layers` for project files (`kerfmeter_plan::selectors`, which
    // this crate does not depend on; LightBurn's names have no colours' parentheses to mind).
    let mut wanted: Vec<&str> = Vec::new();
    for v in layers {
        let whole = [v.as_str(), v.trim()]
            .into_iter()
            .find(|w| cuts.iter().any(|c| matches(c, w)));
        match whole {
            Some(whole) => wanted.push(whole),
            None => {
                let items: Vec<&str> = v
                    .split(',')
                    .map(str::trim)
                    .filter(|s| !s.is_empty())
                    .collect();
                if items.is_empty() {
                    problems.push(format!("{v:?} names nothing"));
                }
                wanted.extend(items);
            }
        }
    }
    let hint = match layers.iter().any(|v| v.contains(',')) {
        true => " (a value is split at its commas unless it is a layer's whole name)",
        false => "",
    };
    for &s in &wanted {
        // Every cut entry it names is set, so every one must be a Line layer (two layers may
        // share a name).
        let mut hits = cuts.iter().filter(|c| matches(c, s)).peekable();
        if hits.peek().is_none() {
            problems.push(format!("no layer has the index or name \"{s}\"{hint}"));
        }
        for c in hits.filter(|c| c.passes.is_empty()) {
            let problem = format!(
                "layer {} \"{}\" is not a Line layer: LightBurn applies a Kerf Offset to Line passes only",
                c.layer_index, c.name
            );
            if !problems.contains(&problem) {
                problems.push(problem);
            }
        }
    }
    if !problems.is_empty() {
        return Err(LightBurnError::Layers(format!(
            "--layers: {}",
            problems.join("; ")
        )));
    }
    Ok(cuts
        .into_iter()
        .filter(|c| wanted.iter().any(|s| matches(c, s)))
        .collect())
}

/// Refuse layers that already have a Kerf Offset, unless told what to do with it; `unit` is the
/// display unit, `per_mm` of it in a millimetre.
fn refuse_compensated(
    chosen: &[LineCut],
    existing: ExistingOffset,
    unit: &str,
    per_mm: f64,
) -> Result<()> {
    let found: Vec<String> = chosen
        .iter()
        .filter(|c| c.passes.iter().any(|p| p.kerf != 0.0))
        .map(|c| {
            let v: Vec<String> = c.passes.iter().map(|p| p.kerf.to_string()).collect();
            format!(
                "layer {} \"{}\": {} {unit}",
                c.layer_index,
                c.name,
                v.join(", ")
            )
        })
        .collect();
    if found.is_empty() || existing != ExistingOffset::Refuse {
        return Ok(());
    }
    let offsets_um = chosen
        .iter()
        .flat_map(|c| &c.passes)
        .filter(|p| p.kerf != 0.0)
        .map(|p| p.kerf / per_mm * 1000.0)
        .collect();
    Err(LightBurnError::AlreadyCompensated { found, offsets_um })
}

/// The body of `POST /api/cuts/{index}`: the new Kerf Offset of each Line pass.
fn body(cut: &LineCut, after: &[f64]) -> Value {
    let mut body = json!({});
    let mut subs = Vec::new();
    for (p, v) in cut.passes.iter().zip(after) {
        match p.sub_layer {
            None => body["params"] = json!({ "kerf": v }),
            Some(i) => subs.push(json!({ "index": i, "params": { "kerf": v } })),
        }
    }
    if !subs.is_empty() {
        body["sub_layers"] = Value::Array(subs);
    }
    body
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_is_the_hmac_of_the_unix_minute() {
        // Computed independently (Python's hmac) from the specification's formula.
        assert_eq!(
            bearer_token("aB3dE7fG9hJ1kL5m", 1_764_650_000),
            "6bba041e2d03749ae477c4772aeccc3a0dc25e76149ec7fbf93d271c0a819737"
        );
        assert_eq!(
            bearer_token("s", 120),
            bearer_token("s", 179),
            "one token per minute"
        );
        assert_ne!(bearer_token("s", 120), bearer_token("s", 180));
    }
}
