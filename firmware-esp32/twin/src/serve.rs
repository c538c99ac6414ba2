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

/// How far a real-time twin catches up at once, µs. A twin thread descheduled for longer (a
/// loaded machine) would otherwise run the whole gap in one burst after taking the host's
/// waiting bytes, so the device would see the host silent for as long as the twin was (a
/// `HostSilent` fault that a device, which is never descheduled, could not have). The excess is
/// dropped: simulated time falls behind the wall clock by it.
const MAX_CATCH_UP_US: u64 = 100_000;

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
    // Wall time dropped from the simulation (see MAX_CATCH_UP_US), µs.
    let mut dropped_us = 0;
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
                let wall_us = started.elapsed().as_micros() as u64 - dropped_us;
                match (sim_start_us + wall_us).checked_sub(served.next_tick_us()) {
                    Some(behind_us) => {
                        let excess_us = behind_us.saturating_sub(MAX_CATCH_UP_US);
                        dropped_us += excess_us;
                        (behind_us - excess_us) / PERIOD_US + 1
                    }
                    None => 0,
                }
            }
        };
        served.advance_ticks(ticks);
    }
    Ok(())
}

/// A read that found nothing in time (or was interrupted): try again.
pub fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
    )
}

/// A pseudo-terminal master reports `EIO` once the slave side is closed.
pub fn is_hangup(e: &io::Error) -> bool {
    e.raw_os_error() == Some(5)
        || matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::UnexpectedEof)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A clock that counts the ticks it is told to run.
    #[derive(Default)]
    struct Clock {
        ticks: u64,
    }

    impl Served for Clock {
        fn receive(&mut self, _: &[u8], _: &mut dyn FnMut(&[u8])) {}

        fn now_us(&self) -> u64 {
            self.ticks * PERIOD_US
        }

        fn advance_ticks(&mut self, ticks: u64) {
            self.ticks += ticks;
        }
    }

    /// A port whose reads time out, but whose third read stalls for `stall` (the serving thread
    /// descheduled), and which hangs up after `reads` reads.
    struct StallingPort {
        reads: u32,
        stall: Duration,
    }

    impl Read for StallingPort {
        fn read(&mut self, _: &mut [u8]) -> io::Result<usize> {
            self.reads = self.reads.saturating_sub(1);
            match self.reads {
                0 => Ok(0),
                3 => {
                    std::thread::sleep(self.stall);
                    Err(ErrorKind::TimedOut.into())
                }
                _ => {
                    std::thread::sleep(Duration::from_millis(2));
                    Err(ErrorKind::TimedOut.into())
                }
            }
        }
    }

    impl Write for StallingPort {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            Ok(buf.len())
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_real_time_twin_descheduled_for_long_does_not_run_the_gap_at_once() {
        let mut port = StallingPort {
            reads: 6,
            stall: Duration::from_millis(600),
        };
        let mut clock = Clock::default();
        let started = Instant::now();
        serve(
            &mut port,
            &mut clock,
            &AtomicBool::new(false),
            Pace::RealTime,
        )
        .unwrap();
        let wall_ms = started.elapsed().as_millis() as u64;
        let sim_ms = clock.now_us() / 1000;
        // The 600 ms stall is run as 100 ms (the catch-up allowed), not in full: the simulation
        // ends some 500 ms behind the wall clock, and it did run the 100 ms.
        assert!(
            sim_ms + 450 < wall_ms,
            "simulated {sim_ms} ms in {wall_ms} ms of wall time with a 600 ms stall"
        );
        assert!(sim_ms >= 100, "{sim_ms}");
    }
}
