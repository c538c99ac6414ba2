//! Who may call a LightBurn twin: pairing (`POST /api/connect`), the secrets it has handed out
//! and their capabilities, the bearer token of each request, and the capability each endpoint
//! needs. Every rule is the spec's, cited where it is applied; the token is computed here from
//! the spec's formula, not by the client's code.

use hmac::{Hmac, KeyInit, Mac};
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

/// A capability a secret grants (`capabilities.md` § The four capabilities).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Capability {
    /// Read-only machine and job state.
    State,
    /// Read-only project data.
    Project,
    /// Submit files for import.
    Upload,
    /// Change project data.
    ProjectWrite,
}

impl Capability {
    /// The wire string.
    pub fn wire(self) -> &'static str {
        match self {
            Capability::State => "state",
            Capability::Project => "project",
            Capability::Upload => "upload",
            Capability::ProjectWrite => "project_write",
        }
    }

    /// The capability `wire` names, among those a LightBurn knows: the four of the spec, or
    /// the three of its 1.0 release when `before_project_write` (`CHANGELOG.md` § Unreleased ›
    /// Added: "`project_write` capability").
    fn known(wire: &str, before_project_write: bool) -> Option<Capability> {
        [
            Capability::State,
            Capability::Project,
            Capability::Upload,
            Capability::ProjectWrite,
        ]
        .into_iter()
        .filter(|c| !(before_project_write && *c == Capability::ProjectWrite))
        .find(|c| c.wire() == wire)
    }
}

/// A pairing the twin's user approved: what LightBurn lists in its "Manage authorizations"
/// dialog (`authentication.md` § Clients that run on another machine).
#[derive(Debug, Clone, PartialEq)]
pub struct Authorisation {
    /// The name the application gave.
    pub application_name: String,
    /// What it may call, "immutable for the life of the secret" (`authentication.md` § 1).
    pub capabilities: Vec<Capability>,
    /// The shared secret.
    pub secret: String,
}

/// How the twin's consent dialog goes.
#[derive(Debug, Clone, Copy)]
pub(super) struct Dialog {
    /// The user declines (or lets the 30 s pass).
    pub declines: bool,
    /// The twin is a LightBurn from before `project_write`.
    pub before_project_write: bool,
    /// The request comes from this computer.
    pub from_loopback: bool,
}

/// The answer to a refused request: its status and an `ErrorResponse` (`openapi.yaml`
/// `components.schemas.ErrorResponse`).
fn refused(status: u16, error: &str) -> (u16, Value) {
    (status, json!({ "error": error }))
}

/// `POST /api/connect`: the pairing request and its consent dialog. On approval, the new
/// authorisation to keep and the answer.
pub(super) fn connect(
    body: &[u8],
    dialog: Dialog,
    serial: u64,
) -> Result<(Authorisation, Value), (u16, Value)> {
    // "Only accepts connections from localhost"; 403 otherwise (`openapi.yaml`
    // `paths./api/connect.post`, response 403; `authentication.md` § Failure modes).
    if !dialog.from_loopback {
        return Err(refused(403, "Pairing is only allowed from localhost"));
    }
    let request: Value =
        serde_json::from_slice(body).map_err(|_| refused(400, "Invalid JSON body"))?;
    // `application_name` and `capabilities` are required (`openapi.yaml` requestBody
    // `required: [application_name, capabilities]`).
    let Some(name) = request["application_name"].as_str() else {
        return Err(refused(400, "Missing 'application_name'"));
    };
    let Some(asked) = request["capabilities"].as_array() else {
        return Err(refused(400, "Missing 'capabilities'"));
    };
    // "Must be a non-empty array of known wire strings; unknown entries fail with 400"
    // (`openapi.yaml` `capabilities`, `minItems: 1`); "rejected (`400`) before any dialog"
    // (`authentication.md` § 1, Notes; `capabilities.md`, first paragraph).
    if asked.is_empty() {
        return Err(refused(400, "'capabilities' must not be empty"));
    }
    let mut capabilities = Vec::new();
    for c in asked {
        let known = c
            .as_str()
            .and_then(|w| Capability::known(w, dialog.before_project_write));
        match known {
            Some(k) if !capabilities.contains(&k) => capabilities.push(k),
            Some(_) => {}
            None => return Err(refused(400, &format!("Unknown capability {c}"))),
        }
    }
    // Any such list goes to the consent dialog, which names the application and the
    // capabilities; declined or timed out: 403 (`openapi.yaml` `paths./api/connect.post`).
    if dialog.declines {
        return Err(refused(403, "Connection rejected by user"));
    }
    // "Each approval produces a distinct secret" (same place; `authentication.md` § 1).
    let secret = new_secret(serial);
    let answer = json!({ "status": "ok", "secret": secret });
    let authorisation = Authorisation {
        application_name: name.to_owned(),
        capabilities,
        secret,
    };
    Ok((authorisation, answer))
}

/// A secret no other pairing has had: distinct by its serial, unguessable enough for a twin by
/// the clock's nanoseconds.
fn new_secret(serial: u64) -> String {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let digest = Sha256::digest(format!("lightburn-twin {serial} {nanos}").as_bytes());
    hex::encode(&digest[..12])
}

/// `hex(HMAC-SHA256(secret, floor(unix_time / 60)))`, the minute written in decimal
/// (`authentication.md` § 2, and its Python snippet: `str(int(time.time()) // 60)`).
pub(super) fn token(secret: &str, minute: i64) -> String {
    let mut mac = Hmac::<Sha256>::new_from_slice(secret.as_bytes()).expect("any key length");
    mac.update(minute.to_string().as_bytes());
    hex::encode(mac.finalize().into_bytes())
}

/// The authorisation `authorization` (the request's header) signs for at `unix_s` (the twin's
/// clock), if any: a `Bearer` token of one of `granted`'s secrets for the current or the
/// previous minute, no other (`openapi.yaml` `info.description` § Authentication;
/// `authentication.md` § 2 and § 3).
pub(super) fn signer<'a>(
    granted: &'a [Authorisation],
    authorization: Option<&str>,
    unix_s: i64,
) -> Option<&'a Authorisation> {
    let token_sent = authorization?.strip_prefix("Bearer ")?;
    let minute = unix_s.div_euclid(60);
    granted.iter().find(|a| {
        [minute, minute - 1]
            .iter()
            .any(|&m| token(&a.secret, m) == token_sent)
    })
}

/// The capability the endpoint `method path` needs, for the endpoints the twin serves
/// (`capabilities.md` § The four capabilities; `openapi.yaml` `paths./api/connect.post`,
/// Capability values). `None`: not one of them.
pub(super) fn needs(method: &str, path: &str) -> Option<Capability> {
    let one_cut = path
        .strip_prefix("/api/cuts/")
        .is_some_and(|i| !i.is_empty() && !i.contains('/'));
    match (method, path) {
        ("GET", "/api/units" | "/api/status") => Some(Capability::State),
        ("GET", "/api/project" | "/api/layers" | "/api/cuts") => Some(Capability::Project),
        ("GET", _) if one_cut => Some(Capability::Project),
        // `project_write` alone; it is independent of `project` (`capabilities.md`).
        ("POST", _) if one_cut => Some(Capability::ProjectWrite),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_follows_the_specs_snippet() {
        // Python: hmac.new(b"aB3dE7fG9hJ1kL5m", b"29410833", hashlib.sha256).hexdigest()
        assert_eq!(
            token("aB3dE7fG9hJ1kL5m", 1_764_650_000 / 60),
            "6bba041e2d03749ae477c4772aeccc3a0dc25e76149ec7fbf93d271c0a819737"
        );
    }

    #[test]
    fn pairing_is_for_this_computer_only() {
        let dialog = Dialog {
            declines: false,
            before_project_write: false,
            from_loopback: false,
        };
        let body = br#"{"application_name": "t", "capabilities": ["project"]}"#;
        let (status, _) = connect(body, dialog, 1).unwrap_err();
        assert_eq!(status, 403);
        let here = Dialog {
            from_loopback: true,
            ..dialog
        };
        let (one, _) = connect(body, here, 1).unwrap();
        let (two, _) = connect(body, here, 2).unwrap();
        assert_ne!(one.secret, two.secret, "each approval a distinct secret");
    }

    #[test]
    fn a_token_signs_for_its_minute_and_the_next_only() {
        let granted = [Authorisation {
            application_name: "t".into(),
            capabilities: vec![Capability::Project],
            secret: "s".into(),
        }];
        let bearer = |minute| format!("Bearer {}", token("s", minute));
        let at = |minute: i64, now_s: i64| signer(&granted, Some(&bearer(minute)), now_s);
        assert!(at(100, 100 * 60).is_some());
        assert!(at(100, 101 * 60 + 59).is_some(), "the previous minute");
        assert!(at(100, 102 * 60).is_none(), "two minutes back");
        assert!(at(101, 100 * 60 + 59).is_none(), "a minute ahead");
        assert!(
            signer(&granted, Some(&token("s", 100)), 100 * 60).is_none(),
            "no Bearer"
        );
    }
}
