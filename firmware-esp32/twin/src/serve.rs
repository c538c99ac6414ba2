//! One serve loop for everything the host talks to through a byte stream: a twin (physics and
//! all) or a bare link and request handler (protocol tests). Bytes read from the port go in;
//! the frames that come out are written back; between reads, simulated time runs at the chosen
//! [`Pace`].

use std::io::{self, ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use kerfmeter_firmware::controller::PERIOD_US;
use kerfmeter_firmware::link::{Handler, Link};

use crate::sim::Twin;

/// Ticks a lock-stepped twin runs per pass of the loop at most, so requests are answered
/// promptly.
const LOCK_STEP_BATCH_TICKS: u64 = 50;

/// How simulated time relates to the wall clock when serving a twin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// As fast as possible, but never more than [`crate::sim::MAX_LEAD_MS`] past the host's last
    /// request: a polling host never looks silent.
    LockStep,
    /// One simulated millisecond per real millisecond.
    RealTime,
}

/// What a serve loop serves: bytes in, frames out, and a clock that may run between reads.
pub trait Served {
    /// Bytes from the host; every frame to send back goes to `transmit`.
    fn receive(&mut self, bytes: &[u8], transmit: &mut dyn FnMut(&[u8]));

    /// Simulated time, µs (something without a clock stays at 0).
    fn now_us(&self) -> u64 {
        0
    }

    /// When its next control tick starts, µs (at [`now_us`](Self::now_us) unless said).
    fn next_tick_us(&self) -> u64 {
        self.now_us()
    }

    /// Control ticks it may run before it must wait for the host (none without a clock).
    fn lead_ticks(&self) -> u64 {
        0
    }

    /// Run `ticks` control ticks (nothing without a clock).
    fn advance_ticks(&mut self, ticks: u64) {
        let _ = ticks;
    }
}

impl Served for Twin {
    fn receive(&mut self, bytes: &[u8], transmit: &mut dyn FnMut(&[u8])) {
        Twin::receive(self, bytes, transmit);
    }

    fn now_us(&self) -> u64 {
        Twin::now_us(self)
    }

    fn next_tick_us(&self) -> u64 {
        Twin::next_tick_us(self)
    }

    fn lead_ticks(&self) -> u64 {
        Twin::lead_ticks(self)
    }

    fn advance_ticks(&mut self, ticks: u64) {
        Twin::advance_ticks(self, ticks);
    }
}

/// A link and a request handler, without physics or time: the protocol alone.
pub struct LinkServer<H> {
    link: Link,
    handler: H,
}

impl<H: Handler> LinkServer<H> {
    /// A fresh link in front of `handler`.
    pub fn new(handler: H) -> Self {
        Self {
            link: Link::new(),
            handler,
        }
    }
}

impl<H: Handler> Served for LinkServer<H> {
    fn receive(&mut self, bytes: &[u8], transmit: &mut dyn FnMut(&[u8])) {
        self.link.receive(bytes, &mut self.handler, transmit);
    }
}

/// Serve `served` on `port` until `stop` is set or the other side hangs up, running its clock at
/// `pace` between reads.
///
/// `port` must time out its reads after a few milliseconds so that `stop` is noticed and the
/// simulation keeps going. A hang-up (end of file, or `EIO` on a pseudo-terminal master whose
/// slave was closed) ends the loop normally; other I/O errors are returned.
pub fn serve<P: Read + Write + ?Sized>(
    port: &mut P,
    served: &mut impl Served,
    stop: &AtomicBool,
    pace: Pace,
) -> io::Result<()> {
    let mut buf = [0u8; 256];
    let mut out = Vec::new();
    let started = Instant::now();
    let sim_start_us = served.now_us();
    while !stop.load(Ordering::Relaxed) {
        let n = match port.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if is_timeout(&e) => 0,
            Err(e) if is_hangup(&e) => break,
            Err(e) => return Err(e),
        };
        if n > 0 {
            out.clear();
            served.receive(&buf[..n], &mut |frame| out.extend_from_slice(frame));
            if !out.is_empty() {
                match port.write_all(&out).and_then(|()| port.flush()) {
                    Ok(()) => {}
                    Err(e) if is_hangup(&e) => break,
                    Err(e) => return Err(e),
                }
            }
        }
        let ticks = match pace {
            Pace::LockStep => served.lead_ticks().min(LOCK_STEP_BATCH_TICKS),
            // Every tick that starts by the wall clock (ticks come about a period apart; a
            // flash stall holds them back until the wall clock catches up).
            Pace::RealTime => {
                let wall_us = started.elapsed().as_micros() as u64;
                match (sim_start_us + wall_us).checked_sub(served.next_tick_us()) {
                    Some(behind_us) => behind_us / PERIOD_US + 1,
                    None => 0,
                }
            }
        };
        served.advance_ticks(ticks);
    }
    Ok(())
}

/// A read that found nothing in time (or was interrupted): try again.
pub(crate) fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
    )
}

/// A pseudo-terminal master reports `EIO` once the slave side is closed.
pub(crate) fn is_hangup(e: &io::Error) -> bool {
    e.raw_os_error() == Some(5)
        || matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::UnexpectedEof)
}
