//! The digital twin (feature `twin`, std): the device's firmware and a physics model of what it
//! drives, on the host, for tests and for the host CLI's `--sim`.
//!
//! - [`sim`]: the [`Twin`] — the real link, device, controller and drivers on fake peripherals
//!   ([`as5048a`], [`pins`], [`flash`]), lock-stepped with the [`plant`]; named fault injection.
//! - [`serve_twin`] serves a twin on any `Read + Write` port — in practice the master end of a
//!   pseudo-terminal, whose slave end the host opens as an ordinary serial port.
//! - [`serve`] serves just a link and handler (no physics), for protocol-level tests.

pub mod plant;
pub mod sim;

pub use sim::{InjectedFault, Twin, TwinOptions, UnknownFault};

use std::io::{self, ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};

use kerfmeter_firmware::link::{Handler, Link, LinkStats};

/// Serve the protocol on `port` until `stop` is set or the other side hangs up.
///
/// `port` must return from `read` periodically (a read timeout) so that `stop` is noticed.
/// A hang-up (end of file, or `EIO` on a pseudo-terminal master whose slave was closed) ends the
/// loop normally; other I/O errors are returned.
pub fn serve<P: Read + Write + ?Sized>(
    port: &mut P,
    handler: &mut impl Handler,
    stop: &AtomicBool,
) -> io::Result<LinkStats> {
    let mut link = Link::new();
    let mut buf = [0u8; 256];
    let mut out = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let n = match port.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                continue;
            }
            Err(e) if is_hangup(&e) => break,
            Err(e) => return Err(e),
        };
        out.clear();
        link.receive(&buf[..n], handler, |frame| out.extend_from_slice(frame));
        if !out.is_empty() {
            match port.write_all(&out).and_then(|()| port.flush()) {
                Ok(()) => {}
                Err(e) if is_hangup(&e) => break,
                Err(e) => return Err(e),
            }
        }
    }
    Ok(link.stats())
}

/// A pseudo-terminal master reports `EIO` once the slave side is closed.
fn is_hangup(e: &io::Error) -> bool {
    e.raw_os_error() == Some(5)
        || matches!(e.kind(), ErrorKind::BrokenPipe | ErrorKind::UnexpectedEof)
}

/// How simulated time relates to the wall clock when serving a twin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pace {
    /// As fast as possible, but never more than [`sim::MAX_LEAD_MS`] past the host's last
    /// request: a polling host never looks silent.
    LockStep,
    /// One simulated millisecond per real millisecond.
    RealTime,
}

/// Serve `twin` on `port` until `stop` is set or the other side hangs up.
///
/// `port` must time out its reads after a few milliseconds so that the simulation keeps going.
pub fn serve_twin<P: Read + Write + ?Sized>(
    port: &mut P,
    twin: &mut Twin,
    stop: &AtomicBool,
    pace: Pace,
) -> io::Result<()> {
    let mut buf = [0u8; 256];
    let mut out = Vec::new();
    let started = std::time::Instant::now();
    let sim_start_us = twin.now_us();
    while !stop.load(Ordering::Relaxed) {
        match port.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                out.clear();
                twin.receive(&buf[..n], |frame| out.extend_from_slice(frame));
                if !out.is_empty() {
                    match port.write_all(&out).and_then(|()| port.flush()) {
                        Ok(()) => {}
                        Err(e) if is_hangup(&e) => break,
                        Err(e) => return Err(e),
                    }
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) if is_hangup(&e) => break,
            Err(e) => return Err(e),
        }
        let ticks = match pace {
            // Keep each batch short so requests are answered promptly.
            Pace::LockStep => twin.lead_ticks().min(50),
            Pace::RealTime => {
                let wall_us = started.elapsed().as_micros() as u64;
                (sim_start_us + wall_us).saturating_sub(twin.now_us())
                    / kerfmeter_firmware::controller::PERIOD_US
            }
        };
        twin.advance_ticks(ticks);
    }
    Ok(())
}
