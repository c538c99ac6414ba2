//! A twin served on a pseudo-terminal by a thread of this process: the client side is an
//! ordinary serial port (a path such as `/dev/pts/3`), so a program talks to the twin exactly as
//! it talks to hardware. The host's `--sim` and the `kerfmeter-twin` binary both start it here.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};

use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_protocol::GaugeGeometry;

use crate::gauge_trace::{GaugeTraceError, TracedGaugeSlot};
use crate::options::{InvalidOptions, TwinOptions};
use crate::plant::{Cutter, GaugeCut};
use crate::serve::{Served, serve};
use crate::sim::Twin;
use crate::traced::Segment;
use crate::truth::TruthLog;

/// Mixed into the seed of the stream that draws the cuts of the traced gauges placed from the
/// caller's side.
const TRACED_STREAM: u64 = 0x7472_6163_6564_0000;

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
    traced: TracedGaugeSlot,
    /// The served twin's cutter (its location bias depends on the seed alone) and gauge.
    cutter: Cutter,
    gauge: GaugeGeometry,
    traced_rng: Mutex<Rng>,
}

impl PtyTwin {
    /// Validate `options`, open a pseudo-terminal and serve a new twin on its master side at the
    /// options' pace. Returns the twin and the terminal's client side.
    ///
    /// The twin stops when the client side is closed (every handle to it, including clones and
    /// whoever opened its path) or when it is dropped or [stopped](PtyTwin::stop).
    pub fn start(options: TwinOptions) -> Result<(Self, TTYPort), StartError> {
        Self::start_watched(options, None)
    }

    /// [`PtyTwin::start`], telling `motor` of every change of the motor bridge between its safe
    /// state and any other (see [`MotorEdge`]): what a scope on the G2's PWM and SLP pins shows
    /// a bench, for tests in another process that must see when the motor stopped.
    pub fn start_watched(
        options: TwinOptions,
        motor: Option<Sender<MotorEdge>>,
    ) -> Result<(Self, TTYPort), StartError> {
        options.validate()?;
        let (mut master, client) = TTYPort::pair()?;
        master.set_timeout(READ_TIMEOUT)?;
        let path = client.name().unwrap_or_else(|| "<pty>".into());
        let stop = Arc::new(AtomicBool::new(false));
        let truths = TruthLog::default();
        let traced = TracedGaugeSlot::default();
        let thread = {
            let stop = stop.clone();
            let truths = truths.clone();
            let traced = traced.clone();
            std::thread::Builder::new()
                .name("kerfmeter-twin".into())
                .spawn(move || {
                    let twin = Twin::with_truth_log(options, truths).with_traced_gauges(traced);
                    let mut watched = Watched::new(twin, motor);
                    serve(&mut master, &mut watched, &stop, options.pace())
                })?
        };
        let twin = Self {
            stop,
            thread: Some(thread),
            path,
            truths,
            traced,
            cutter: Cutter::for_twin(
                options.plant,
                options.kerf_um,
                options.kerf_sd_um,
                options.seed,
            ),
            gauge: options.gauge,
            traced_rng: Mutex::new(Rng::new(options.seed ^ TRACED_STREAM)),
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

    /// The gauge the laser traced around `at_mm` (`segments`) goes under the prongs for the
    /// served twin's following runs, cut by `cutter` (a cutter twin's, or `None`: the served
    /// twin's own): see [`Twin::place_traced_gauge`]. The cut, or why it was refused.
    pub fn place_traced_gauge(
        &self,
        segments: &[Segment],
        at_mm: [f64; 2],
        cutter: Option<&Cutter>,
    ) -> Result<GaugeCut, GaugeTraceError> {
        let mut rng = self
            .traced_rng
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let cutter = cutter.unwrap_or(&self.cutter);
        self.traced
            .place(segments, &self.gauge, at_mm, cutter, &mut rng)
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

/// A change of the motor bridge seen by a watched twin ([`PtyTwin::start_watched`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MotorEdge {
    /// Simulated time of the pass that made the change, µs since boot.
    pub at_us: u64,
    /// True when the bridge entered its safe state (duty 0 and the driver asleep), false when it
    /// left it.
    pub safe: bool,
}

/// A twin whose bridge is compared after every pass with the last one told.
struct Watched {
    twin: Twin,
    motor: Option<Sender<MotorEdge>>,
    safe: bool,
}

impl Watched {
    fn new(twin: Twin, motor: Option<Sender<MotorEdge>>) -> Self {
        let safe = twin.motor_safe();
        Self { twin, motor, safe }
    }

    /// Tell the watcher if the bridge changed (a watcher that left is forgotten).
    fn check(&mut self) {
        let safe = self.twin.motor_safe();
        if safe == self.safe {
            return;
        }
        self.safe = safe;
        let edge = MotorEdge {
            at_us: self.twin.now_us(),
            safe,
        };
        if let Some(motor) = &self.motor
            && motor.send(edge).is_err()
        {
            self.motor = None;
        }
    }
}

impl Served for Watched {
    fn receive(&mut self, bytes: &[u8], transmit: &mut dyn FnMut(&[u8])) {
        self.twin.receive(bytes, transmit);
        self.check();
    }

    fn now_us(&self) -> u64 {
        self.twin.now_us()
    }

    fn next_tick_us(&self) -> u64 {
        self.twin.next_tick_us()
    }

    fn lead_ticks(&self) -> u64 {
        self.twin.lead_ticks()
    }

    fn advance_ticks(&mut self, ticks: u64) {
        // Pass by pass, so that no edge is missed inside a batch.
        for _ in 0..ticks {
            self.twin.advance_ticks(1);
            self.check();
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
    fn a_trace_with_no_gauge_is_refused_with_where_it_was_looked_for() {
        let (twin, _client) = PtyTwin::start(TwinOptions::default()).unwrap();
        let err = twin
            .place_traced_gauge(&[], [30.0, 40.0], None)
            .unwrap_err();
        assert!(err.to_string().contains("of (30.000, 40.000) mm"), "{err}");
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
