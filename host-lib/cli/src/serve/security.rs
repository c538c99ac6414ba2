//! Who may talk to `kerfmeter serve`: it can turn a motor and, with a cutter, fire a laser, so
//! any web page the user visits must not be able to, nor anyone else on the network.
//!
//! * **Loopback by default.** Listening on any other address needs `--token`; without one the
//!   server refuses to start ([`Security::new`]).
//! * **Token.** With `--token T`, `/rpc` and every `/api/...` route need
//!   `Authorization: Bearer T` or `?token=T` (browsers cannot set headers on a WebSocket), else
//!   401. The comparison takes the same time wherever the tokens differ. The page's own files
//!   (`/`, `/app.js`, ...) hold no secret and are served without it; the page takes the token
//!   from its own address (`/?token=T`), keeps it for its tab and takes it out of the address.
//! * **Origin.** A WebSocket upgrade and every POST whose `Origin` is not the server's own, nor
//!   one given with `--allow-origin`, is refused (403): browsers send `Origin` with both, so
//!   another site's page cannot start a run. An `--allow-origin` must be `http(s)://HOST[:PORT]`:
//!   `null`, which sandboxed frames and `file:` pages send, and `*` are refused at startup. The
//!   server's own origins: `http://` + the address listened on, and `http://` + the `Host`
//!   header: on loopback when that names a loopback host (`localhost`, `127.0.0.1`, `[::1]`,
//!   with any port), off loopback (with a token) whatever name the page reached the server by,
//!   so that its own page works at `http://myhost.lan:7878/?token=…` on a `0.0.0.0` listen.
//!   A request without `Origin` comes
//!   from a program, not a browser: it is let through (on loopback it is local; elsewhere it
//!   carries the token).
//! * **Host.** On loopback, a request whose `Host` is not a loopback name is refused (403): a
//!   DNS-rebinding page (`evil.example` re-pointed at 127.0.0.1) is same-origin for the browser
//!   and sends no `Origin` with a GET, but it sends its own `Host`.
//! * **No framing.** Every answer carries `X-Frame-Options: DENY` and a Content-Security-Policy
//!   (`frame-ancestors 'none'`, the page's own scripts and WebSocket only): otherwise another
//!   site could show the page in an invisible frame and get a click on Measure (clickjacking),
//!   which every check above would let through, the frame being the server's own origin.
//! * **Tokens** are at least [`MIN_TOKEN_CHARS`] characters. Off loopback they travel in clear
//!   over HTTP: use a trusted network, or an SSH tunnel to the loopback server.
//! * Bodies are bounded (see [`super::MAX_BODY_BYTES`]) and no request names a file: plans
//!   travel as text, results as JSON.

use std::net::SocketAddr;

use axum::extract::{Request, State};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use subtle::ConstantTimeEq;

use super::http::error_response;
use super::rpc::{INVALID_REQUEST, RpcError};
use crate::error::CliError;

/// The rules, fixed at startup.
#[derive(Debug, Clone)]
pub struct Security {
    /// The address listened on (with the port actually bound).
    listen: SocketAddr,
    /// The token, if one was given.
    token: Option<String>,
    /// Origins allowed besides the server's own, lower-case, without a trailing `/`.
    allowed_origins: Vec<String>,
}

/// The shortest token accepted: a short one could be guessed by anyone on the network, and
/// nothing limits how often they try.
pub const MIN_TOKEN_CHARS: usize = 16;

/// The headers every answer carries, so that no other site can frame the page (and get a click
/// on Measure through an invisible frame), and nothing the server sends is run as a page of its
/// own but its own files: `(name, value)`; the CSP's `connect-src` is completed per request.
const SAFETY_HEADERS: [(&str, &str); 3] = [
    ("x-frame-options", "DENY"),
    ("x-content-type-options", "nosniff"),
    ("referrer-policy", "no-referrer"),
];

/// The Content-Security-Policy for a request to `host` (a loopback name, or any name when a
/// token guards the server): the page's own files only, no frames, its own WebSocket.
fn content_security_policy(host: Option<&str>) -> String {
    let host_safe = |c: char| c.is_ascii_alphanumeric() || ".:-[]".contains(c);
    let socket = match host.filter(|h| !h.is_empty() && h.chars().all(host_safe)) {
        Some(h) => format!(" ws://{h} wss://{h}"),
        None => String::new(),
    };
    format!(
        "default-src 'self'; connect-src 'self'{socket}; img-src 'self' data: blob:; \
         object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
    )
}

/// Add the safety headers to `response` (for a request to `host`).
fn with_safety_headers(mut response: Response, host: Option<&str>) -> Response {
    let headers = response.headers_mut();
    for (name, value) in SAFETY_HEADERS {
        headers.insert(name, HeaderValue::from_static(value));
    }
    if let Ok(csp) = HeaderValue::from_str(&content_security_policy(host)) {
        headers.insert(header::CONTENT_SECURITY_POLICY, csp);
    }
    response
}

impl Security {
    /// The rules for listening on `listen`; refuses a non-loopback address without a token, and
    /// an empty token.
    pub fn new(
        listen: SocketAddr,
        token: Option<String>,
        allow_origins: &[String],
    ) -> Result<Self, CliError> {
        let url_safe = |c: char| c.is_ascii_alphanumeric() || "-._~".contains(c);
        if token
            .as_deref()
            .is_some_and(|t| t.len() < MIN_TOKEN_CHARS || !t.chars().all(url_safe))
        {
            return Err(CliError::Usage(format!(
                "--token must be at least {MIN_TOKEN_CHARS} characters, made of letters, digits \
                 and - . _ ~ (it travels in URLs as ?token=); e.g. \
                 `--token $(head -c 18 /dev/urandom | base64 | tr +/ -_)`"
            )));
        }
        if !listen.ip().is_loopback() && token.is_none() {
            return Err(CliError::Usage(format!(
                "refusing to listen on {listen} without --token: anyone who can reach that \
                 address could turn the motor (and fire the laser). Give --token SECRET (clients \
                 send `Authorization: Bearer SECRET` or `?token=SECRET`), or listen on \
                 127.0.0.1"
            )));
        }
        let allowed_origins = allow_origins
            .iter()
            .map(|o| allowed_origin(o))
            .collect::<Result<_, _>>()?;
        Ok(Security {
            listen,
            token,
            allowed_origins,
        })
    }

    /// What the user should know about these rules before trusting them, for the server to print
    /// as it starts: a listener beyond this machine speaks plain HTTP (the token and every call
    /// readable by whoever sees the traffic), and an `http:` page allowed from another machine
    /// is only as safe as the network's name resolution (a spoofed name serves a page with that
    /// origin).
    pub fn warnings(&self) -> Vec<String> {
        let mut warnings = Vec::new();
        if !self.listen.ip().is_loopback() {
            warnings.push(format!(
                "listening on {}, beyond this machine, over plain HTTP: the token and every call \
                 travel unencrypted, and whoever can read the network's traffic can take the token \
                 and turn the motor (and, with --cutter, fire the laser). Serve so only on a \
                 network you trust, or behind an HTTPS reverse proxy",
                self.listen
            ));
        }
        for origin in &self.allowed_origins {
            let host = origin.strip_prefix("http://").unwrap_or_default();
            if !host.is_empty() && !is_loopback_host(host) {
                warnings.push(format!(
                    "--allow-origin {origin} is a plain-HTTP page on another machine: anyone on \
                     the network who can answer for that name (a spoofed DNS or mDNS reply) can \
                     serve a page with that origin and drive this server from your browser; \
                     prefer an https:// origin"
                ));
            }
        }
        warnings
    }

    /// The same rules, once the port is bound (`--listen ...:0` picks one).
    pub fn bound_to(mut self, listen: SocketAddr) -> Self {
        self.listen = listen;
        self
    }

    /// Whether the request carries the token (always, without one).
    fn token_ok(&self, headers: &HeaderMap, query: Option<&str>) -> bool {
        let Some(token) = &self.token else {
            return true;
        };
        let bearer = headers
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "));
        let in_query = query
            .into_iter()
            .flat_map(|q| q.split('&'))
            .find_map(|pair| pair.strip_prefix("token="));
        [bearer, in_query]
            .into_iter()
            .flatten()
            .any(|given| bool::from(given.as_bytes().ct_eq(token.as_bytes())))
    }

    /// Whether a request with `Host: host` may be served (anything, off loopback).
    fn host_ok(&self, host: Option<&str>) -> bool {
        if !self.listen.ip().is_loopback() {
            return true;
        }
        host.is_some_and(is_loopback_host)
    }

    /// Whether `origin` is the server's own or an allowed one.
    fn origin_ok(&self, origin: &str, host: Option<&str>) -> bool {
        let origin = normalize(origin);
        let own = format!("http://{}", self.listen);
        // The page's own origin is also `http://` + the `Host` it was asked by: on loopback a
        // loopback name (any other is refused, [`Self::host_ok`]); off loopback any name the
        // server is reached by (its host name, any of its addresses, for a `0.0.0.0` listen),
        // as the token guards every call there: a page that reached the server by another name,
        // a DNS-rebinding one included, cannot act without it.
        let via_host = host
            .filter(|h| self.token.is_some() || is_loopback_host(h))
            .map(|h| format!("http://{}", h.to_ascii_lowercase()));
        origin == own
            || via_host.is_some_and(|o| o == origin)
            || self.allowed_origins.contains(&origin)
    }
}

/// `origin` in lower case, without a trailing `/`.
fn normalize(origin: &str) -> String {
    origin.trim().trim_end_matches('/').to_ascii_lowercase()
}

/// An `--allow-origin` as the browser sends it (`http://host[:port]` or `https://…`, without
/// the scheme's default port, which browsers leave out), or why it cannot be one. `null` (sent
/// by sandboxed frames, `file:` pages and some redirects: any page can make its requests carry
/// it) and `*` would open the server to every page.
fn allowed_origin(origin: &str) -> Result<String, CliError> {
    let o = normalize(origin);
    let o = match (o.strip_suffix(":80"), o.strip_suffix(":443")) {
        (Some(bare), _) if bare.starts_with("http://") => bare.to_owned(),
        (_, Some(bare)) if bare.starts_with("https://") => bare.to_owned(),
        _ => o,
    };
    let host = o
        .strip_prefix("http://")
        .or_else(|| o.strip_prefix("https://"));
    match host {
        Some(host) if !host.is_empty() && !host.contains(['/', '?', '#', '@', '*', ' ']) => Ok(o),
        _ => Err(CliError::Usage(format!(
            "--allow-origin {origin:?} is not an origin a browser sends: give \
             `http://HOST[:PORT]` or `https://HOST[:PORT]`, with no path (`null` and `*` would \
             let any page in)"
        ))),
    }
}

/// Whether a `Host` header (`name[:port]`) names this machine's loopback.
fn is_loopback_host(host: &str) -> bool {
    let name = match host.strip_prefix('[') {
        Some(v6) => v6.split(']').next().unwrap_or_default(),
        None => host.rsplit_once(':').map_or(host, |(name, _)| name),
    };
    let name = name.to_ascii_lowercase();
    name == "localhost"
        || name.ends_with(".localhost")
        || name
            .parse::<std::net::IpAddr>()
            .is_ok_and(|ip| ip.is_loopback())
}

/// The middleware: host, token and origin, in that order, before any route; the safety headers
/// on every answer.
pub async fn guard(
    State(security): State<std::sync::Arc<Security>>,
    request: Request,
    next: Next,
) -> Response {
    let host = request
        .headers()
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .map(str::to_owned);
    let response = check(&security, request, host.as_deref(), next).await;
    with_safety_headers(response, host.as_deref())
}

/// The checks of [`guard`], then the route.
async fn check(security: &Security, request: Request, host: Option<&str>, next: Next) -> Response {
    let headers = request.headers();
    let path = request.uri().path();
    let refuse = |status: StatusCode, why: &str| {
        error_response(status, &RpcError::new(INVALID_REQUEST, why)).into_response()
    };
    if !security.host_ok(host) {
        let why = "this server answers only to loopback host names (localhost, 127.0.0.1, [::1])";
        return refuse(StatusCode::FORBIDDEN, why);
    }
    let api = path == "/rpc" || path.starts_with("/api/");
    if api && !security.token_ok(headers, request.uri().query()) {
        let why = "missing or wrong token: send `Authorization: Bearer TOKEN` or `?token=TOKEN`";
        return refuse(StatusCode::UNAUTHORIZED, why);
    }
    let needs_origin = request.method() == Method::POST || path == "/rpc";
    let origin = headers
        .get(header::ORIGIN)
        .map(|v| v.to_str().unwrap_or("?"));
    // Browsers say where a request comes from twice: `Origin`, and `Sec-Fetch-Site`.
    let cross_site = headers
        .get("sec-fetch-site")
        .is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"cross-site"));
    let foreign = origin.is_some_and(|o| !security.origin_ok(o, host));
    if needs_origin && (foreign || cross_site && origin.is_none()) {
        let why = "cross-site request refused: this Origin is not the server's own; start the \
                   server with --allow-origin ORIGIN to allow it";
        return refuse(StatusCode::FORBIDDEN, why);
    }
    next.run(request).await
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loopback() -> Security {
        Security::new(
            "127.0.0.1:7878".parse().unwrap(),
            None,
            &["http://Tool.example/".into()],
        )
        .unwrap()
    }

    #[test]
    fn a_wide_listener_and_a_plain_http_origin_elsewhere_are_warned_of() {
        assert_eq!(loopback().warnings().len(), 1, "http://tool.example");
        let quiet = Security::new(
            "127.0.0.1:7878".parse().unwrap(),
            None,
            &[
                "https://tool.example".into(),
                "http://localhost:3000".into(),
            ],
        )
        .unwrap();
        assert!(quiet.warnings().is_empty(), "{:?}", quiet.warnings());
        let wide = Security::new(
            "0.0.0.0:7878".parse().unwrap(),
            Some("a-long-enough-secret".into()),
            &[],
        )
        .unwrap();
        let warnings = wide.warnings();
        assert_eq!(warnings.len(), 1);
        assert!(warnings[0].contains("plain HTTP"), "{warnings:?}");
    }

    #[test]
    fn loopback_host_names_are_recognised() {
        for host in [
            "localhost:7878",
            "127.0.0.1:7878",
            "[::1]:7878",
            "LOCALHOST",
            "127.1.2.3",
        ] {
            assert!(is_loopback_host(host), "{host}");
        }
        for host in [
            "evil.example:7878",
            "192.168.1.2:7878",
            "[2001:db8::1]:80",
            "",
        ] {
            assert!(!is_loopback_host(host), "{host}");
        }
    }

    #[test]
    fn only_the_servers_own_and_the_allowed_origins_pass() {
        let s = loopback();
        assert!(s.origin_ok("http://127.0.0.1:7878", Some("127.0.0.1:7878")));
        assert!(s.origin_ok("http://localhost:7878", Some("localhost:7878")));
        assert!(s.origin_ok("http://tool.example", None));
        assert!(!s.origin_ok("http://evil.example", Some("127.0.0.1:7878")));
        assert!(!s.origin_ok("http://localhost:9999", Some("localhost:7878")));
        assert!(!s.origin_ok("null", Some("127.0.0.1:7878")));
    }

    /// Off loopback the page is opened by whatever name reaches the server (a `0.0.0.0`
    /// listen has no address of its own to compare with); the token guards it there.
    #[test]
    fn off_loopback_the_page_s_own_origin_is_the_host_it_was_asked_by() {
        let s = Security::new(
            "0.0.0.0:7878".parse().unwrap(),
            Some("abcdefghijklmnop1234".into()),
            &[],
        )
        .unwrap();
        assert!(s.origin_ok("http://192.0.2.2:7878", Some("192.0.2.2:7878")));
        assert!(s.origin_ok("http://MyHost.lan:7878", Some("myhost.lan:7878")));
        assert!(!s.origin_ok("http://evil.example", Some("myhost.lan:7878")));
        assert!(!s.origin_ok("http://myhost.lan:7878", None));
        // On loopback without a token, only loopback names count.
        assert!(!loopback().origin_ok("http://evil.example:7878", Some("evil.example:7878")));
    }

    #[test]
    fn allowed_origins_must_be_real_origins() {
        let at = "127.0.0.1:7878".parse().unwrap();
        for bad in [
            "null",
            "*",
            "tool.example",
            "http://",
            "http://a.example/app",
            "file://x",
        ] {
            let e = Security::new(at, None, &[bad.into()]).unwrap_err();
            assert!(e.to_string().contains("--allow-origin"), "{bad}: {e}");
        }
        for good in ["http://localhost:5173", "https://Tool.example/"] {
            assert!(Security::new(at, None, &[good.into()]).is_ok(), "{good}");
        }
        // A default port is left out, as the browser leaves it out of `Origin`.
        let s = Security::new(at, None, &["https://tool.example:443".into()]).unwrap();
        assert!(s.origin_ok("https://tool.example", Some("127.0.0.1:7878")));
    }

    #[test]
    fn a_non_loopback_listen_needs_a_token() {
        let any = "0.0.0.0:7878".parse().unwrap();
        let e = Security::new(any, None, &[]).unwrap_err();
        assert!(e.to_string().contains("without --token"), "{e}");
        assert!(Security::new(any, Some("s3cret-long-enough".into()), &[]).is_ok());
        assert!(Security::new(any, Some(" ".into()), &[]).is_err());
        // Too short to resist guessing over the network.
        assert!(Security::new(any, Some("s3cret".into()), &[]).is_err());
    }

    #[test]
    fn the_token_is_taken_from_the_header_or_the_query() {
        const TOKEN: &str = "abc-0123456789-xyz";
        let s = Security::new("127.0.0.1:1".parse().unwrap(), Some(TOKEN.into()), &[]).unwrap();
        let mut headers = HeaderMap::new();
        assert!(!s.token_ok(&headers, None));
        assert!(s.token_ok(&headers, Some(&format!("x=1&token={TOKEN}"))));
        assert!(!s.token_ok(&headers, Some(&format!("token={TOKEN}d"))));
        assert!(!s.token_ok(
            &headers,
            Some(&format!("token={}", &TOKEN[..TOKEN.len() - 1]))
        ));
        headers.insert(
            header::AUTHORIZATION,
            format!("Bearer {TOKEN}").parse().unwrap(),
        );
        assert!(s.token_ok(&headers, None));
        headers.insert(
            header::AUTHORIZATION,
            format!("Bearer {TOKEN}x").parse().unwrap(),
        );
        assert!(!s.token_ok(&headers, None));
    }
}
