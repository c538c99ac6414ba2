//! The HTTP side of a LightBurn twin: each connection on a thread of its own, one request read
//! within a deadline (a client that trickles bytes or never reads its answer holds only its own
//! thread, and not for long), answered as JSON and closed.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::State;

/// Longest request head and body the twin reads, bytes.
const MAX_REQUEST_BYTES: usize = 1 << 20;

/// Longest time a client may take to send its whole request.
const REQUEST_DEADLINE: Duration = Duration::from_secs(5);

/// One request as the twin's routing sees it.
pub(super) struct Request<'a> {
    pub method: &'a str,
    pub path: &'a str,
    /// The `Authorization` header.
    pub authorization: Option<&'a str>,
    pub body: &'a [u8],
    /// It came from this computer.
    pub from_loopback: bool,
}

/// Take connections until `stop`, each served on its own thread by `answer`.
pub(super) fn accept(
    listener: &TcpListener,
    state: &Arc<Mutex<State>>,
    stop: &AtomicBool,
    answer: fn(&Mutex<State>, &Request) -> (u16, Value),
) {
    for stream in listener.incoming() {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        match stream {
            Ok(stream) => {
                let state = Arc::clone(state);
                // A client that sends garbage only loses its own connection.
                let _ = std::thread::Builder::new()
                    .name("lightburn-twin-request".into())
                    .spawn(move || serve(stream, &state, answer));
            }
            // Out of file handles, say: wait rather than spin.
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
}

/// Read one request from `stream` (within [`REQUEST_DEADLINE`]) and answer it.
fn serve(
    stream: TcpStream,
    state: &Mutex<State>,
    answer: fn(&Mutex<State>, &Request) -> (u16, Value),
) -> std::io::Result<()> {
    let deadline = Instant::now() + REQUEST_DEADLINE;
    let from_loopback = stream.peer_addr()?.ip().is_loopback();
    let mut reader = BufReader::new(Deadlined {
        stream: stream.try_clone()?,
        deadline,
    });
    let head = read_head(&mut reader)?;
    let mut headers = [httparse::EMPTY_HEADER; 32];
    let mut request = httparse::Request::new(&mut headers);
    let bad = |e: String| std::io::Error::new(std::io::ErrorKind::InvalidData, e);
    request.parse(&head).map_err(|e| bad(e.to_string()))?;
    let header = |name: &str| {
        request
            .headers
            .iter()
            .find(|h| h.name.eq_ignore_ascii_case(name))
            .and_then(|h| std::str::from_utf8(h.value).ok())
    };
    let length: usize = header("content-length")
        .map_or(Ok(0), str::parse)
        .map_err(|e| bad(format!("{e}")))?;
    if length > MAX_REQUEST_BYTES {
        return Err(bad("body too large".into()));
    }
    let mut body = vec![0; length];
    reader.read_exact(&mut body)?;
    let request = Request {
        method: request.method.unwrap_or(""),
        path: request.path.unwrap_or(""),
        authorization: header("authorization"),
        body: &body,
        from_loopback,
    };
    let (status, value) = answer(state, &request);
    if status == 0 {
        return Ok(()); // the link is lost: no answer
    }
    let text = value.to_string();
    let mut stream = stream;
    // A client that does not read its answer cannot hold the thread either.
    stream.set_write_timeout(Some(REQUEST_DEADLINE))?;
    write!(
        stream,
        "HTTP/1.1 {status} {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{text}",
        reason(status),
        text.len()
    )
}

/// A stream whose reads all end by one deadline: a client cannot hold its connection open by
/// sending a byte now and then.
struct Deadlined {
    stream: TcpStream,
    deadline: Instant,
}

impl Read for Deadlined {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(std::io::ErrorKind::TimedOut.into());
        }
        self.stream.set_read_timeout(Some(left))?;
        self.stream.read(buf)
    }
}

/// The request's head, up to and including its blank line.
fn read_head(reader: &mut impl BufRead) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::new();
    loop {
        let before = head.len();
        reader
            .by_ref()
            .take(MAX_REQUEST_BYTES as u64)
            .read_until(b'\n', &mut head)?;
        let line = &head[before..];
        if line.is_empty() || head.len() > MAX_REQUEST_BYTES {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        if line == b"\r\n" || line == b"\n" {
            return Ok(head);
        }
    }
}

/// The reason phrase of the statuses the twin answers.
fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        400 => "Bad Request",
        401 => "Unauthorized",
        403 => "Forbidden",
        404 => "Not Found",
        409 => "Conflict",
        _ => "Error",
    }
}
