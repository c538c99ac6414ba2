//! A LightBurn twin: the part of LightBurn's REST API that [`crate::rest`] uses, served on
//! loopback from a thread, so that `kerfmeter --sim lightburn pair|apply` and the tests run with
//! no LightBurn installed.
//!
//! **Written from the spec, not from the client.** Its source is LightBurn Software's published
//! REST repository, `LightBurnSoftware/LightBurn-REST`, at [`SPEC_REVISION`]: `docs/openapi.yaml`,
//! `docs/authentication.md`, `docs/capabilities.md`, `docs/cut-settings.md`,
//! `docs/versioning.md` and `CHANGELOG.md`. Each rule below is applied where the code cites its
//! file and section:
//!
//! * **Pairing** (`POST /api/connect`, in `auth`): from this computer only (403 otherwise);
//!   `application_name` and a non-empty `capabilities` list of known wire strings (`state`,
//!   `project`, `upload`, `project_write`) are required, anything else is 400 before any dialog;
//!   any such list goes to the consent dialog, which approves (200, a new distinct secret bound
//!   to those capabilities) or declines (403, [`LightBurnTwinOptions::declines`]). Secrets
//!   handed out stay authorised until revoked ([`LightBurnTwin::revoke`], LightBurn's "Manage
//!   authorizations" dialog); nothing revokes them on re-pairing.
//! * **Signing and scope**: every other endpoint wants `Authorization: Bearer
//!   hex(HMAC-SHA256(secret, floor(unix_time / 60)))` for the twin clock's current or previous
//!   minute (the clock can be set off this computer's: [`LightBurnTwinOptions::clock_offset_s`]),
//!   from a secret whose capabilities cover the endpoint. Any failure, whatever its reason, is the
//!   same bare 401.
//! * **The cut list** (in `project`): fixed, 63 entries whatever is in use: 30 cut layers, 2 tool
//!   layers (`mode: "tool"`), 1 internal cut (`layer_index: -1`), then 30 image cuts; `index` is
//!   the position in the list, `layer_index` the layer slot. The spec promises no order between
//!   the two, so tests may list the cut layers in another order ([`LightBurnTwin::edit_project`]).
//! * **`GET /api/layers`**: all 32 slots with `in_use` and `shape_count`.
//! * **Units**: the spec's enum only (`mm/s`, `mm/min`, `in/min`: [`DisplayUnits`]); cut values
//!   are read and written in them (kept in mm inside).
//! * **`POST /api/cuts/{index}`** (in `edit`): `project_write` needed; 404 out of range; 409
//!   while the cut settings editor is open ([`LightBurnTwinOptions::editor_open`]); the body is
//!   checked whole (`additionalProperties: false`, types, power 0–100, the fields each kind may
//!   change, existing sub-layers only, 400 for tool layers and the internal cut) and applied
//!   whole or not at all; a change is one undo step, marks the project modified, and the answer
//!   is the updated entry.
//!
//! What it leaves out: the endpoints kerfmeter does not call (positions, jogging, events,
//! uploads, the material library: 404 here), MillMage, the network listener (it binds loopback
//! only), and everything the spec does not say (the internal cut's name and mode, LightBurn's
//! layer colours, the exact text of its errors; see the docs/lightburn.md for what stays
//! unverified without a real LightBurn). For tests, every request is recorded
//! ([`LightBurnTwin::served`]), so is every change made ([`LightBurnTwin::posts`]), and a failure
//! can be injected ([`LightBurnTwinOptions::fail_post`]).

mod auth;
mod edit;
mod http;
mod project;

use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{SystemTime, UNIX_EPOCH};

use serde_json::{Value, json};

pub use auth::{Authorisation, Capability};
pub use project::{
    CUT_LAYERS, Cut, CutKind, DisplayUnits, IMAGE_CUTS, INTERNAL_CUT, LAYER_SLOTS, Layer, Mode,
    Params, Project, SubLayer, TOOL_LAYERS,
};

use crate::rest::LightBurnError;
use http::Request;

/// The revision of LightBurn's REST repository the twin follows (the client's).
pub use crate::rest::SPEC_REVISION;

/// How the twin behaves.
#[derive(Debug, Clone, PartialEq)]
pub struct LightBurnTwinOptions {
    /// LightBurn's display units, which every cut value is given in.
    pub units: DisplayUnits,
    /// The cut settings editor is open: every change is refused with 409.
    pub editor_open: bool,
    /// The user declines the pairing.
    pub declines: bool,
    /// A LightBurn from before the `project_write` capability (the spec's 1.0): pairing asked
    /// for it is refused with 400, as an unknown capability.
    pub before_project_write: bool,
    /// The twin's clock minus this computer's, seconds.
    pub clock_offset_s: i64,
    /// LightBurn keeps a Kerf Offset to this resolution, mm (`None`: as sent). The spec says
    /// nothing of it; a test option, to see a client confirm what it wrote.
    pub kerf_resolution_mm: Option<f64>,
    /// Fail the change made after this many succeeded, with this HTTP status (0: drop the
    /// connection unanswered).
    pub fail_post: Option<(usize, u16)>,
}

impl Default for LightBurnTwinOptions {
    fn default() -> Self {
        LightBurnTwinOptions {
            units: DisplayUnits::MmPerS,
            editor_open: false,
            declines: false,
            before_project_write: false,
            clock_offset_s: 0,
            kerf_resolution_mm: None,
            fail_post: None,
        }
    }
}

/// A request the twin answered.
#[derive(Debug, Clone, PartialEq)]
pub struct Served {
    /// `GET`, `POST` …
    pub method: String,
    /// The path.
    pub path: String,
    /// The status answered (0: none, the link was dropped).
    pub status: u16,
}

/// What the twin holds and has been asked.
struct State {
    options: LightBurnTwinOptions,
    project: Project,
    granted: Vec<Authorisation>,
    pairings: u64,
    posts: Vec<(String, Value)>,
    served: Vec<Served>,
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
    /// Serve a twin of [`Project::example`] on a free loopback port.
    pub fn start(options: LightBurnTwinOptions) -> Result<LightBurnTwin, LightBurnError> {
        Self::serve(options).map_err(|source| LightBurnError::TwinFailed { source })
    }

    fn serve(options: LightBurnTwinOptions) -> std::io::Result<LightBurnTwin> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let host = listener.local_addr()?.to_string();
        let state = Arc::new(Mutex::new(State {
            options,
            project: Project::example(),
            granted: Vec::new(),
            pairings: 0,
            posts: Vec::new(),
            served: Vec::new(),
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let (served, stopped) = (Arc::clone(&state), Arc::clone(&stop));
        std::thread::Builder::new()
            .name("lightburn-twin".into())
            .spawn(move || http::accept(&listener, &served, &stopped, answer))?;
        Ok(LightBurnTwin { host, state, stop })
    }

    /// Its address, `127.0.0.1:PORT`.
    pub fn host(&self) -> &str {
        &self.host
    }

    /// Change how it behaves from now on.
    pub fn set_options(&self, change: impl FnOnce(&mut LightBurnTwinOptions)) {
        change(&mut self.lock().options);
    }

    /// The pairings approved and not revoked, oldest first.
    pub fn authorisations(&self) -> Vec<Authorisation> {
        self.lock().granted.clone()
    }

    /// Revoke the pairing whose secret is `secret`, as the user does in LightBurn's "Manage
    /// authorizations" dialog; false if there was none.
    pub fn revoke(&self, secret: &str) -> bool {
        let granted = &mut self.lock().granted;
        let before = granted.len();
        granted.retain(|a| a.secret != secret);
        granted.len() != before
    }

    /// Every change applied, in order: the path and the body.
    pub fn posts(&self) -> Vec<(String, Value)> {
        self.lock().posts.clone()
    }

    /// Every request answered, in order.
    pub fn served(&self) -> Vec<Served> {
        self.lock().served.clone()
    }

    /// The cut entries as `GET /api/cuts` gives them now (in the display units).
    pub fn cuts(&self) -> Value {
        let s = self.lock();
        s.project.cuts_json(s.options.units)
    }

    /// The project as it is now (values in mm and mm/s).
    pub fn project(&self) -> Project {
        self.lock().project.clone()
    }

    /// Change the project (what the user does in LightBurn between two calls), e.g. give two
    /// layers one name, or list the cut layers in another order than their slots.
    pub fn edit_project(&self, change: impl FnOnce(&mut Project)) {
        change(&mut self.lock().project);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The twin's clock, Unix seconds.
fn twin_now_s(offset_s: i64) -> i64 {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64);
    now + offset_s
}

/// An `ErrorResponse` (`openapi.yaml` `components.schemas.ErrorResponse`).
fn error(status: u16, message: &str) -> (u16, Value) {
    (status, json!({ "error": message }))
}

/// The answer to one request (status 0: none at all), recorded.
fn answer(state: &Mutex<State>, request: &Request) -> (u16, Value) {
    let mut s = state.lock().unwrap_or_else(PoisonError::into_inner);
    let (status, body) = route(&mut s, request);
    s.served.push(Served {
        method: request.method.into(),
        path: request.path.into(),
        status,
    });
    (status, body)
}

fn route(s: &mut State, request: &Request) -> (u16, Value) {
    let (method, path) = (request.method, request.path);
    if (method, path) == ("POST", "/api/connect") {
        let dialog = auth::Dialog {
            declines: s.options.declines,
            before_project_write: s.options.before_project_write,
            from_loopback: request.from_loopback,
        };
        s.pairings += 1;
        return match auth::connect(request.body, dialog, s.pairings) {
            Ok((authorisation, answer)) => {
                s.granted.push(authorisation);
                (200, answer)
            }
            Err(refused) => refused,
        };
    }
    let Some(needed) = auth::needs(method, path) else {
        return error(404, "Not found");
    };
    let now_s = twin_now_s(s.options.clock_offset_s);
    let signer = auth::signer(&s.granted, request.authorization, now_s);
    // "Every authorization failure on a gated endpoint returns a bare `401`, whether the token
    // is absent, expired, revoked, lacking the capability, or arriving from a disallowed
    // origin" (`authentication.md` § Failure modes); the body is the spec's example for every
    // one of them (`openapi.yaml` `components.responses.Unauthorized`).
    if !signer.is_some_and(|a| a.capabilities.contains(&needed)) {
        return error(401, "Unauthorized");
    }
    let units = s.options.units;
    match (method, path) {
        ("GET", "/api/units") => (200, json!({ "units": units.wire() })),
        ("GET", "/api/status") => (
            200,
            json!({ "connected": false, "device_name": "LightBurn twin", "supports_z": false,
                    "supports_overrides": false }),
        ),
        ("GET", "/api/project") => (200, s.project.project_json(units)),
        ("GET", "/api/layers") => (200, s.project.layers_json()),
        ("GET", "/api/cuts") => (200, s.project.cuts_json(units)),
        ("GET", _) => match cut_index(s, path) {
            Ok(i) => (200, s.project.cut_json(i, units).expect("in range")),
            Err(refused) => refused,
        },
        _ => change_cut(s, path, request.body),
    }
}

/// The entry `/api/cuts/{index}` names: 400 when `index` is not an integer ≥ 0 (`openapi.yaml`:
/// `schema: { type: integer, minimum: 0 }`), 404 when out of range ("Cut index out of range").
fn cut_index(s: &State, path: &str) -> Result<usize, (u16, Value)> {
    let text = path.trim_start_matches("/api/cuts/");
    let index: usize = text
        .parse()
        .map_err(|_| error(400, &format!("Invalid cut index '{text}'")))?;
    match index < s.project.cuts.len() {
        true => Ok(index),
        false => Err(error(404, "Cut index out of range")),
    }
}

/// `POST /api/cuts/{index}` (`openapi.yaml` `paths./api/cuts/{index}.post`;
/// `cut-settings.md` § Changing a cut).
fn change_cut(s: &mut State, path: &str, body: &[u8]) -> (u16, Value) {
    if let Some((after, status)) = s.options.fail_post
        && s.posts.len() == after
    {
        return error(status, "refused by the twin");
    }
    let index = match cut_index(s, path) {
        Ok(i) => i,
        Err(refused) => return refused,
    };
    // "If the cut settings or operation editor is open in the application, the request fails
    // with `409`" (`cut-settings.md` § How a change is applied).
    if s.options.editor_open {
        return error(409, "The cut settings editor is open");
    }
    let (units, resolution) = (s.options.units, s.options.kerf_resolution_mm);
    if let Err(why) = edit::change_cut(&mut s.project, index, body, units, resolution) {
        return error(400, &why);
    }
    let sent = serde_json::from_slice(body).unwrap_or(Value::Null);
    s.posts.push((path.to_owned(), sent));
    // "200: Updated; the body is the updated entry, same shape as `GET /api/cuts/{index}`"
    // (`cut-settings.md` § Responses).
    (200, s.project.cut_json(index, units).expect("in range"))
}
