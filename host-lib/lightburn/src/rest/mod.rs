//! LightBurn's local REST API: pair with a running LightBurn and write the measured kerf into
//! the Kerf Offset of its Line layers, as `kerfmeter lightburn pair` and `kerfmeter lightburn
//! apply` do ([`apply_kerf`], in `apply`).
//!
//! **Where each convention comes from.**
//!
//! * *LightBurn's REST spec* (`LightBurnSoftware/LightBurn-REST`, at the revision
//!   [`SPEC_REVISION`] names; the LightBurn twin, `crate::twin`, is written from it and
//!   cites it rule by rule):
//!   - the API listens on `localhost:19520` while LightBurn is open (`openapi.yaml` `servers`);
//!   - **pairing**: `POST /api/connect` with `{"application_name", "capabilities"}`, from this
//!     computer only; a non-empty list of known capabilities goes to a consent dialog, which
//!     answers `200 {"status":"ok","secret":…}`, or `403` when declined or after 30 s; an
//!     unknown capability is `400` (`openapi.yaml`; `authentication.md` § 1). Each pairing gives a
//!     new secret and leaves the earlier ones authorised until the user revokes them in
//!     LightBurn's "Manage authorizations" dialog (`authentication.md` § Clients that run on
//!     another machine): the client keeps the newest ([`Pairing`]);
//!   - **signing**: `Authorization: Bearer hex(HMAC-SHA256(secret, decimal floor(unix_time /
//!     60)))`, accepted for LightBurn's current and previous minute only (`authentication.md` §
//!     2; [`bearer_token`]). Every authorisation failure is one bare `401`, whatever its reason:
//!     "recompute the token once, and if it persists, re-pair" (§ Failure modes). This client
//!     recomputes it for the minute before its own: so a clock up to a minute ahead of
//!     LightBurn's, or up to a minute behind, always signs (without it, a clock `d` seconds
//!     ahead fails during the last `d` seconds of every minute);
//!   - **scope**: `GET /api/units` needs `state`; `GET /api/layers` and `GET /api/cuts`
//!     `project`; `POST /api/cuts/{index}` `project_write` (`capabilities.md`);
//!   - **the cut list** is fixed (30 cut layers, 2 tool layers, an internal cut with
//!     `layer_index: -1`, 30 image cuts); `index` is an entry's position, what
//!     `/api/cuts/{index}` takes, and `layer_index` its layer slot, what `/api/layers` and the
//!     user's `--layers 3` name (`cut-settings.md` § Reading cuts);
//!   - **a change** is checked whole and applied all or nothing, answers the updated entry
//!     (which this client reads back to confirm what it wrote), `409` while the cut settings
//!     editor is open, makes one undo step and marks the project modified: it is in the next
//!     job sent, not in one already sent (`cut-settings.md` § How a change is applied);
//!   - cut values are in the display units (`GET /api/units`: `mm/s`, `mm/min` or `in/min`).
//! * *LightBurn's user documentation*, not the REST spec (which says only `kerf: number`): what
//!   the Kerf Offset means. It moves the path so that the edge of the cut lies on the drawing:
//!   half the kerf, positive outward, on Line passes of closed shapes. So the value written is
//!   `kerf_um / 2`, positive, in the display unit: the same offset the offline `kerfmeter dilate
//!   project.lbrn2` writes ([`crate::project`]). A layer already carrying a non-zero
//!   Kerf Offset is refused unless the caller says to replace it or add to it
//!   ([`ExistingOffset`]).
//!
//! **What no release number guarantees.** The API reports no version and checks none; it is
//! pre-stable and its changelog ships breaking changes without a version bump (`versioning.md`
//! § Current state; `CHANGELOG.md` § Unreleased). `project_write` and `POST /api/cuts/{index}`
//! are in the changelog's "Unreleased" section: a LightBurn without them refuses the pairing
//! (400, unknown capability), which this client reports as such. Which LightBurn release has
//! them, and how a real LightBurn behaves where the spec is silent, is unverified here (the
//! docs/lightburn.md lists what).

mod apply;
mod wire;

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use hmac::{Hmac, KeyInit, Mac};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use sha2::Sha256;

use kerfmeter_protocol::advice::Advice;

use kerfmeter::Category;
use kerfmeter::files::write_atomically_with_mode;

pub use apply::{Applied, ExistingOffset, LayerSet, apply_kerf};

/// The revision of LightBurn's REST repository (`LightBurnSoftware/LightBurn-REST`) this client
/// and the LightBurn twin follow: `docs/openapi.yaml`, `docs/cut-settings.md`,
/// `docs/capabilities.md` and `CHANGELOG.md` at commit `3203c99de195`,
/// `docs/authentication.md` at `9b2911ff24ad`, `docs/versioning.md` at `706abec7e564`.
pub const SPEC_REVISION: &str = "LightBurnSoftware/LightBurn-REST 3203c99de195 (authentication.md 9b2911ff24ad, versioning.md 706abec7e564)";

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
        "LightBurn is not running at {host} (connection refused): start LightBurn and try again"
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
    /// LightBurn refused the pairing request itself (400): an unknown capability, most likely
    /// `project_write`, which LightBurn's REST API gained without a version number.
    #[error(
        "LightBurn refused the pairing request (400: {message}): a LightBurn whose REST API predates the `project_write` capability (changing cut settings) answers so; update LightBurn and pair again"
    )]
    PairingRefused {
        /// Its `error` text.
        message: String,
    },
    /// The signature was refused, also with the token recomputed once (LightBurn says no more:
    /// every reason is one bare 401).
    #[error(
        "LightBurn refused this program's signature ({status}, also with the token recomputed): its pairing was revoked in LightBurn, or lacks a capability this program needs (state, project, project_write), or this computer's clock is more than a minute off LightBurn's; pair again with `kerfmeter lightburn pair`"
    )]
    Unauthorized {
        /// 401 (or 403, which an earlier revision of the spec gave for a missing capability).
        status: u16,
    },
    /// A change was made, but the entry LightBurn answered does not hold what was written.
    #[error(
        "LightBurn answered {request} with an entry that does not hold what was written: {message}; check that layer in LightBurn"
    )]
    NotConfirmed {
        /// The request.
        request: String,
        /// What differs.
        message: String,
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
        "{cause}; but {done} had already been set to this kerf's Kerf Offset: once that is fixed, run {} again with {} (it replaces the Kerf Offsets this run set)",
        Advice::LightBurnApply,
        Advice::Recompensate
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
        "Kerf Offsets already set ({}): the project is already compensated; nothing was changed. Replace them by this kerf's with {}, or add this kerf's on top with {}",
        found.join("; "),
        Advice::Recompensate,
        Advice::AlreadyCompensatedOk
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

/// A request's answer: its status and body text.
struct Answer {
    status: u16,
    text: String,
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
        const REQ: &str = "POST /api/connect";
        let client = Client::with_timeout(host, PAIRING_TIMEOUT_MS);
        let body = wire::PairRequest {
            application_name: APPLICATION_NAME,
            capabilities: &CAPABILITIES,
        };
        let answer = client.call(REQ, None, Some(&body))?;
        match answer.status {
            200 => {}
            400 => {
                return Err(LightBurnError::PairingRefused {
                    message: error_text(&answer.text),
                });
            }
            403 => return Err(LightBurnError::Declined),
            status => return Err(refused(REQ, status, &answer.text)),
        }
        let reply: wire::PairReply = parse(REQ, &answer.text)?;
        if reply.secret.is_empty() {
            return Err(protocol(REQ, "an empty secret"));
        }
        Ok(Pairing {
            host: host.to_string(),
            secret: reply.secret,
            capabilities: CAPABILITIES.map(String::from).to_vec(),
        })
    }

    /// One request (`"METHOD /path"`), signed with `token` when given.
    fn call(
        &self,
        request: &str,
        token: Option<&str>,
        body: Option<&impl Serialize>,
    ) -> Result<Answer> {
        let (method, path) = request.split_once(' ').unwrap_or(("GET", request));
        let url = format!("http://{}{path}", self.host);
        let auth = token.map(|t| format!("Bearer {t}"));
        let sent = match method {
            "POST" => {
                let mut r = self.agent.post(&url);
                if let Some(a) = &auth {
                    r = r.header("Authorization", a);
                }
                match body {
                    Some(b) => r.send_json(b),
                    None => r.send_empty(),
                }
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
        Ok(Answer { status, text })
    }

    /// A request signed with `secret`. On a 401 the token is recomputed once, for the minute
    /// before this computer's (`authentication.md` § Failure modes: "on any `401`, recompute the
    /// token once"): LightBurn accepts its own current and previous minute only, so a clock
    /// running ahead of LightBurn's signs for a minute LightBurn has not reached yet during the
    /// last seconds of each minute. A 401 changed nothing, so sending a change again is safe.
    fn signed_call(
        &self,
        secret: &str,
        request: &str,
        body: Option<&impl Serialize>,
    ) -> Result<Answer> {
        let answer = self.call(request, Some(&bearer_token(secret, now_s())), body)?;
        if answer.status != 401 {
            return Ok(answer);
        }
        let earlier = bearer_token(secret, now_s().saturating_sub(60));
        self.call(request, Some(&earlier), body)
    }

    /// A signed `GET` whose only good answer is 200, read as `T`.
    fn get<T: DeserializeOwned>(&self, secret: &str, request: &str) -> Result<T> {
        parse(request, &self.get_text(secret, request)?)
    }

    /// A signed `GET` whose only good answer is 200: its body.
    fn get_text(&self, secret: &str, request: &str) -> Result<String> {
        let answer = self.signed_call(secret, request, None::<&()>)?;
        match answer.status {
            200 => Ok(answer.text),
            401 | 403 => Err(LightBurnError::Unauthorized {
                status: answer.status,
            }),
            status => Err(refused(request, status, &answer.text)),
        }
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
}

/// `text` read as `T` (one of the typed replies in `wire`); a reply that does not fit is a
/// protocol error naming `request` and where in the reply it went wrong (`cuts[3].sub_layers[0]:
/// missing field `index``).
fn parse<T: DeserializeOwned>(request: &str, text: &str) -> Result<T> {
    let mut reply = serde_json::Deserializer::from_str(text);
    let read = serde_path_to_error::deserialize(&mut reply).map_err(|e| {
        let path = e.path().to_string();
        let why = e.into_inner().to_string();
        match path.as_str() {
            "." => protocol(request, &why),
            _ => protocol(request, &format!("{path}: {why}")),
        }
    })?;
    reply.end().map_err(|e| protocol(request, &e.to_string()))?;
    Ok(read)
}

/// The `error` of an `ErrorResponse`, or a placeholder.
fn error_text(text: &str) -> String {
    serde_json::from_str::<wire::ErrorReply>(text)
        .ok()
        .and_then(|e| e.error)
        .unwrap_or_else(|| "no reason given".into())
}

fn refused(request: &str, status: u16, text: &str) -> LightBurnError {
    LightBurnError::Refused {
        request: request.into(),
        status,
        message: error_text(text),
    }
}

fn protocol(request: &str, message: &str) -> LightBurnError {
    LightBurnError::Protocol {
        request: request.into(),
        message: message.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reply_of_the_wrong_shape_names_what_is_missing_and_where() {
        let cuts = r#"{"product": "lightburn", "cuts": [{"index": 0, "name": "C00", "kind": "normal",
            "layer_index": 0, "mode": "scan", "params": {"kerf": 0},
            "sub_layers": [{"mode": "cut", "params": {"kerf": 0}}]}]}"#;
        let e = parse::<wire::CutList>("GET /api/cuts", cuts).unwrap_err();
        let said = e.to_string();
        assert!(
            said.contains("GET /api/cuts")
                && said.contains("cuts[0].sub_layers[0]: missing field `index`"),
            "{said}"
        );
        let e = parse::<wire::LayersReply>("GET /api/layers", r#"{"layers": [{"index": 0}]}"#);
        assert!(
            e.unwrap_err()
                .to_string()
                .contains("layers[0]: missing field `in_use`")
        );
        let e = parse::<wire::UnitsReply>("GET /api/units", r#"{"units": "mm/s"} x"#);
        assert!(e.unwrap_err().to_string().contains("trailing characters"));
    }

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
