//! The cutter twin served by a thread of this process: on a pseudo-terminal (its client side is
//! an ordinary serial port, as a USB GRBL board is) or on a loopback TCP port (as FluidNC and
//! other networked controllers are). Simulated time runs in lock-step (fast) or at the wall
//! clock ([`Pace`]).
//!
//! It has its own loop rather than the device's [`kerfmeter_twin::serve()`]: a cutter speaks unprompted
//! (an `ok` once its planner frees a block, an alarm in the middle of a move), while the device
//! only answers what it receives.

use std::io::{self, Read, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

use super::machine::Grbl;
use super::options::CutterOptions;
use super::trace::CutterLog;
use kerfmeter_twin::serve::{Pace, is_hangup, is_timeout};

/// How long a read waits before simulated time moves on.
const READ_TIMEOUT: Duration = Duration::from_millis(1);
/// Simulated time per pass of a lock-stepped loop, µs.
const LOCK_STEP_US: u64 = 20_000;

/// Why a cutter twin could not be served.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// No pseudo-terminal could be opened.
    #[error("cannot set up a pseudo-terminal: {0}")]
    Pty(#[from] serialport::Error),
    /// The TCP port could not be bound, or the thread not started.
    #[error("cannot serve the cutter twin: {0}")]
    Io(#[from] io::Error),
}

/// A cutter twin served by a thread. Dropping it stops the twin.
pub struct CutterServer {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
    address: String,
    log: CutterLog,
}

impl CutterServer {
    /// Serve a new cutter on a pseudo-terminal; returns it and the terminal's client side. It
    /// stops when the client side is closed (every handle to it) or when it is dropped.
    pub fn pty(options: CutterOptions, pace: Pace) -> Result<(Self, TTYPort), ServeError> {
        let (mut master, client) = TTYPort::pair()?;
        master.set_timeout(READ_TIMEOUT)?;
        let address = client.name().unwrap_or_else(|| "<pty>".into());
        let server = Self::spawn(address, options, move |grbl, stop| {
            serve_cutter(&mut master, grbl, stop, pace)
        })?;
        Ok((server, client))
    }

    /// Serve a new cutter on `127.0.0.1:port` (0: any free port), one client at a time; the
    /// machine keeps its state between clients, and greets each with its banner.
    pub fn tcp(options: CutterOptions, pace: Pace, port: u16) -> Result<Self, ServeError> {
        Self::tcp_greeting(options, pace, port, true)
    }

    /// [`CutterServer::tcp`], greeting each client with the banner or (`greet` false) saying
    /// nothing until spoken to, as many networked controllers do.
    pub fn tcp_greeting(
        options: CutterOptions,
        pace: Pace,
        port: u16,
        greet: bool,
    ) -> Result<Self, ServeError> {
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, port))?;
        listener.set_nonblocking(true)?;
        let address = listener.local_addr()?.to_string();
        Ok(Self::spawn(address, options, move |grbl, stop| {
            accept_loop(&listener, grbl, stop, pace, greet)
        })?)
    }

    fn spawn(
        address: String,
        options: CutterOptions,
        run: impl FnOnce(&mut Grbl, &AtomicBool) -> io::Result<()> + Send + 'static,
    ) -> io::Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let log = CutterLog::default();
        let thread = {
            let (stop, log) = (stop.clone(), log.clone());
            std::thread::Builder::new()
                .name("kerfmeter-cutter-twin".into())
                .spawn(move || run(&mut Grbl::new(options, log), &stop))?
        };
        Ok(Self {
            stop,
            thread: Some(thread),
            address,
            log,
        })
    }

    /// The terminal's path, or the TCP address (`127.0.0.1:PORT`).
    pub fn address(&self) -> &str {
        &self.address
    }

    /// What the cutter did.
    pub fn log(&self) -> &CutterLog {
        &self.log
    }

    /// Ask the twin to stop serving (it does within a read timeout).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Wait until the twin stops serving; the serve loop's I/O error, if it ended in one.
    pub fn wait(mut self) -> io::Result<()> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(panic)) => std::panic::resume_unwind(panic),
            None => Ok(()),
        }
    }
}

impl Drop for CutterServer {
    fn drop(&mut self) {
        self.stop();
        if let Some(thread) = self.thread.take() {
            // Nobody is left to hear how the loop ended.
            let _ = thread.join();
        }
    }
}

/// Serve TCP clients one after the other until `stop`.
fn accept_loop(
    listener: &TcpListener,
    grbl: &mut Grbl,
    stop: &AtomicBool,
    pace: Pace,
    greet: bool,
) -> io::Result<()> {
    while !stop.load(Ordering::Relaxed) {
        match listener.accept() {
            Ok((stream, _)) => serve_client(stream, grbl, stop, pace, greet)?,
            Err(e) if is_timeout(&e) => std::thread::sleep(READ_TIMEOUT),
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

fn serve_client(
    mut stream: TcpStream,
    grbl: &mut Grbl,
    stop: &AtomicBool,
    pace: Pace,
    greet: bool,
) -> io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(READ_TIMEOUT))?;
    stream.set_nodelay(true)?;
    if greet {
        grbl.greet();
    } else {
        // What it said before this client came (its boot banner) is not this client's.
        grbl.take_output();
    }
    match serve_cutter(&mut stream, grbl, stop, pace) {
        Err(e) if e.kind() == io::ErrorKind::ConnectionReset => Ok(()),
        other => other,
    }
}

/// Serve `grbl` on `port` until `stop` or a hang-up: bytes in, replies out, time moving on.
pub fn serve_cutter<P: Read + Write + ?Sized>(
    port: &mut P,
    grbl: &mut Grbl,
    stop: &AtomicBool,
    pace: Pace,
) -> io::Result<()> {
    let mut buf = [0u8; 256];
    let started = Instant::now();
    let sim_start_us = grbl.now_us();
    while !stop.load(Ordering::Relaxed) {
        let out = grbl.take_output();
        if !out.is_empty() {
            match port.write_all(&out).and_then(|()| port.flush()) {
                Ok(()) => {}
                Err(e) if is_hangup(&e) => break,
                Err(e) => return Err(e),
            }
        }
        match port.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => grbl.receive(&buf[..n]),
            Err(e) if is_timeout(&e) => {}
            Err(e) if is_hangup(&e) => break,
            Err(e) => return Err(e),
        }
        let dt_us = match pace {
            Pace::LockStep => LOCK_STEP_US,
            Pace::RealTime => {
                let wall_us = started.elapsed().as_micros() as u64;
                (sim_start_us + wall_us).saturating_sub(grbl.now_us())
            }
        };
        grbl.advance_us(dt_us);
    }
    Ok(())
}
