//! The digital twin (feature `twin`, std): the device's firmware served over a real byte stream
//! on the host, for tests and for the host CLI's `--sim`.
//!
//! [`serve`] runs the same [`Link`] and handler the board binary runs, reading and writing any
//! `Read + Write` port — in practice the master end of a pseudo-terminal pair, whose slave end the
//! host library opens as an ordinary serial port.

pub mod as5048a;
pub mod flash;
pub mod pins;
pub mod rng;

use std::io::{self, ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::link::{Handler, Link, LinkStats};

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
