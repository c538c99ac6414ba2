//! A twin served on a pseudo-terminal by a thread of this process: the client side is an
//! ordinary serial port (a path such as `/dev/pts/3`), so a program talks to the twin exactly as
//! it talks to hardware. The host's `--sim` and the `kerfmeter-twin` binary both start it here.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};

use crate::options::{InvalidOptions, TwinOptions};
use crate::serve::serve;
use crate::sim::Twin;
use crate::truth::TruthLog;

/// How long a read of the terminal waits before simulated time moves on.
const READ_TIMEOUT: Duration = Duration::from_millis(1);

/// Why a twin could not be started.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The options are out of range.
    #[error(transparent)]
    Options(#[from] InvalidOptions),
    /// No pseudo-terminal could be opened or set up.
    #[error("cannot set up a pseudo-terminal: {0}")]
    Pty(#[from] serialport::Error),
    /// The serving thread could not be started.
    #[error("cannot start the twin's thread: {0}")]
    Thread(#[from] io::Error),
}

/// A running twin on a pseudo-terminal. Dropping it stops the twin.
pub struct PtyTwin {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<()>>>,
    path: String,
    truths: TruthLog,
}

impl PtyTwin {
    /// Validate `options`, open a pseudo-terminal and serve a new twin on its master side at the
    /// options' pace. Returns the twin and the terminal's client side.
    ///
    /// The twin stops when the client side is closed (every handle to it, including clones and
    /// whoever opened its path) or when it is dropped or [stopped](PtyTwin::stop).
    pub fn start(options: TwinOptions) -> Result<(Self, TTYPort), StartError> {
        options.validate()?;
        let (mut master, client) = TTYPort::pair()?;
        master.set_timeout(READ_TIMEOUT)?;
        let path = client.name().unwrap_or_else(|| "<pty>".into());
        let stop = Arc::new(AtomicBool::new(false));
        let truths = TruthLog::default();
        let thread = {
            let stop = stop.clone();
            let truths = truths.clone();
            std::thread::Builder::new()
                .name("kerfmeter-twin".into())
                .spawn(move || {
                    let mut twin = Twin::with_truth_log(options, truths);
                    serve(&mut master, &mut twin, &stop, options.pace())
                })?
        };
        let twin = Self {
            stop,
            thread: Some(thread),
            path,
            truths,
        };
        Ok((twin, client))
    }

    /// Path of the terminal's client side.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The truth of each run the twin has started.
    pub fn truths(&self) -> &TruthLog {
        &self.truths
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

impl Drop for PtyTwin {
    fn drop(&mut self) {
        self.stop();
        if let Some(thread) = self.thread.take() {
            // Whatever ended the loop has no one to be reported to but the client, which sees
            // the port vanish.
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc;

    use super::*;

    #[test]
    fn out_of_range_options_are_refused_before_a_terminal_is_opened() {
        let options = TwinOptions {
            kerf_um: 5000.0,
            ..TwinOptions::default()
        };
        assert!(matches!(
            PtyTwin::start(options),
            Err(StartError::Options(InvalidOptions::Kerf(_)))
        ));
    }

    #[test]
    fn the_twin_stops_serving_when_its_client_hangs_up() {
        let (twin, client) = PtyTwin::start(TwinOptions::default()).unwrap();
        assert!(twin.path().starts_with("/dev/"), "{}", twin.path());
        drop(client);
        let (done, result) = mpsc::channel();
        std::thread::spawn(move || done.send(twin.wait().map_err(|e| e.to_string())));
        let served = result.recv_timeout(Duration::from_secs(10));
        assert_eq!(served, Ok(Ok(())));
    }
}
