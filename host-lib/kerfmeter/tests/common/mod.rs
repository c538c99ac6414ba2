//! Set-up shared by the host library's tests: client options fast enough for tests, what a
//! serial line can do to the device's responses (noise before them, responses lost), and the
//! device side of a pseudo-terminal served in a thread that stops when the test is done.

// Each test binary uses the part it needs.
#![allow(dead_code)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use kerfmeter::Options;

/// What a device prints on the line besides frames: a boot banner, flow-control bytes, binary
/// junk and a stray frame delimiter.
pub const NOISE: &[u8] = b"\r\nESP-ROM:esp32c3\x13\x11garbage\r\n\xff\xfe\x01\x02\x00junk\x07";

/// Client options for tests: a short response timeout `timeout_ms`, 3 retries, quick polls.
pub fn fast_options(timeout_ms: u64) -> Options {
    Options {
        timeout: Duration::from_millis(timeout_ms),
        retries: 3,
        poll_interval: Duration::from_millis(5),
    }
}

/// What the line does to the device's responses; tests switch these while the device serves.
#[derive(Debug, Default)]
pub struct LineFaults {
    /// Put [`NOISE`] before every response.
    pub garbage: AtomicBool,
    /// Lose this many of the next responses.
    pub drop_responses: AtomicU32,
    /// Responses delivered with [`NOISE`] before them.
    pub noisy_responses: AtomicU32,
}

impl LineFaults {
    /// The bytes that reach the host for `response`: none when it is lost, noise first when
    /// garbage is on.
    pub fn deliver(&self, response: &[u8]) -> Vec<u8> {
        let lost = self
            .drop_responses
            .fetch_update(Ordering::SeqCst, Ordering::SeqCst, |n| n.checked_sub(1))
            .is_ok();
        if lost {
            return Vec::new();
        }
        let mut out = Vec::new();
        if self.garbage.load(Ordering::SeqCst) {
            out.extend_from_slice(NOISE);
            self.noisy_responses.fetch_add(1, Ordering::SeqCst);
        }
        out.extend_from_slice(response);
        out
    }
}

/// The device side, served in a thread until [`Server::stop`] is set; dropping the server stops
/// it and waits for it (and fails the test if the thread panicked).
pub struct Server<T> {
    /// Set to make the serve loop end (as if the device were unplugged).
    pub stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<T>>,
}

impl<T: Send + 'static> Server<T> {
    /// Run `serve` in a thread; it gets the stop flag to poll.
    pub fn spawn(serve: impl FnOnce(Arc<AtomicBool>) -> T + Send + 'static) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        Self {
            stop,
            thread: Some(std::thread::spawn(move || serve(flag))),
        }
    }

    /// Stop serving and get what the serve loop returned.
    pub fn finish(mut self) -> T {
        self.stop.store(true, Ordering::SeqCst);
        let thread = self.thread.take().expect("joined only once");
        thread.join().expect("the server thread does not panic")
    }
}

impl<T> Drop for Server<T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let panicked = thread.join().is_err();
            assert!(
                !panicked || std::thread::panicking(),
                "the server thread panicked"
            );
        }
    }
}
