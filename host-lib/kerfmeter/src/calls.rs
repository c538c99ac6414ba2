//! The calls: the paper's three — [`Kerfmeter::run_kerfmeter`], [`Kerfmeter::get_kerf_value`],
//! [`Kerfmeter::reset_kerfmeter`] — and the rest of what the device does.
//!
//! Long calls (a run, a reset, a self-test) block, polling the device's status every
//! [`Options::poll_interval`](crate::Options::poll_interval). Every poll is a request, and every
//! request feeds the device's communication watchdog: if this program stops (or the port
//! vanishes) mid-run, the device stops its motor on its own within the run's
//! `host_timeout_ms`.
//!
//! A run starts only with the hub at its zero position: [`Kerfmeter::prepare_for_run`] resets it
//! first when it is further from zero than the firmware's own start tolerance.

use std::ops::ControlFlow;
use std::time::{Duration, Instant};

// The device refuses to start a run further than this from zero; the host resets beyond it.
use kerfmeter_protocol::START_TOLERANCE_DEG;

use kerfmeter_protocol::{
    Conditions, ConfigReport, DeviceConfig, Diagnostics, ErrorCode, KerfResult, Request, Response,
    RunParams, RunState, Sample, SelfTestReport, Status,
};
use serde::Serialize;

use crate::client::Kerfmeter;
use crate::error::{Error, Result};

/// What a long call reports while it runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Progress {
    /// The device's state.
    pub state: RunState,
    /// Commanded output torque, N·m.
    pub torque_nm: f32,
    /// Hub angle from zero, degrees.
    pub angle_deg: f32,
    /// Time since the run started, ms.
    pub elapsed_ms: u32,
    /// The whole status this poll read (supply, conditions, timing, ...), for a caller that
    /// shows more than the progress (`kerfmeter serve` answers `status` from it during a run).
    #[serde(skip)]
    pub status: Status,
}

impl From<&Status> for Progress {
    fn from(s: &Status) -> Self {
        Self {
            state: s.state,
            torque_nm: s.torque_nm,
            angle_deg: s.angle_deg,
            elapsed_ms: s.elapsed_ms,
            status: *s,
        }
    }
}

/// The (time, torque, angle) curve of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Curve {
    /// The run.
    pub run_id: u32,
    /// Control ticks (ms) between samples (more than 1 when a long run was decimated).
    pub ticks_per_sample: u16,
    /// The samples, oldest first.
    pub samples: Vec<Sample>,
}

impl Curve {
    /// The kerf at another assembly force read off this run's sweep (`params` are the run's,
    /// `play_deg` its result's hole play, `None` without a result), µm; `None` beyond the force
    /// the run reached. See [`kerfmeter_protocol::spiral::kerf_at_force_um`].
    pub fn kerf_at_force_um(
        &self,
        params: &RunParams,
        play_deg: Option<f32>,
        force_n: f32,
    ) -> Option<f32> {
        kerfmeter_protocol::spiral::kerf_at_force_um(params, &self.samples, play_deg, force_n)
    }
}

/// Repeated measurements and their summary (see [`Kerfmeter::measure`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Measurement {
    /// Every run's result, in order.
    pub runs: Vec<KerfResult>,
    /// Mean, SD, 95 % confidence interval and outliers of their kerf.
    pub summary: crate::stats::Summary,
}

/// How long a reset may take before the host gives up waiting (the device faults by itself
/// after 5 s).
const RESET_DEADLINE: Duration = Duration::from_secs(10);
/// How long a self-test may take.
const SELF_TEST_DEADLINE: Duration = Duration::from_secs(10);
/// Slack on top of the run's own time limit.
const RUN_SLACK: Duration = Duration::from_secs(5);
/// How long a stop waits for the device to report its motor at rest after the abort (the
/// firmware makes it safe within one control tick; this is for the link's round trips).
const AT_REST_DEADLINE: Duration = Duration::from_secs(1);

fn unexpected(request: &'static str, response: &Response) -> Error {
    crate::client::unexpected(request, response)
}

/// What one status poll decided: keep polling, or the call's outcome.
type Poll<T> = Result<Option<T>>;

impl Kerfmeter {
    /// The device's state, torque and angle.
    pub fn status(&mut self) -> Result<Status> {
        match self.call(Request::GetStatus)? {
            Response::Status(s) => Ok(s),
            other => Err(unexpected("GetStatus", &other)),
        }
    }

    /// What the device knows about its own health since boot (protocol 2.6): the last reset's
    /// reason, the chip, the ADC's calibration, the brown-out detector, the current sense and
    /// encoder diagnostics, the worst timing. `None` from an older device, which answers
    /// `UnknownRequest` (everything else works with it).
    pub fn diagnostics(&mut self) -> Result<Option<Diagnostics>> {
        match self.call(Request::GetDiagnostics) {
            Ok(Response::Diagnostics(d)) => Ok(Some(d)),
            Ok(other) => Err(unexpected("GetDiagnostics", &other)),
            Err(Error::Device {
                code: ErrorCode::UnknownRequest,
                ..
            }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Measure the kerf: start a run with `params` and block until the device has a result.
    ///
    /// `progress` is called after every status poll with the state, torque and angle. The hub
    /// must be at its zero position (call [`Kerfmeter::reset_kerfmeter`] first). A fault ends the
    /// call with [`Error::Fault`]; a device that restarted with [`Error::DeviceReset`]. A fault
    /// latched while the device backs off after the hold (the reading already taken) also ends
    /// it with [`Error::Fault`]: a device that faulted is not trusted with a job, whatever it
    /// read before. That reading stays in [`Kerfmeter::get_kerf_value`] (flagged
    /// `play-modelled`) for whoever wants to see it.
    ///
    /// ```no_run
    /// use kerfmeter::{Kerfmeter, JointSpec, protocol::GaugeGeometry};
    /// let mut meter = Kerfmeter::open("/dev/ttyACM0")?;
    /// let params = JointSpec::default().run_params(GaugeGeometry::PAPER)?;
    /// meter.reset_kerfmeter()?;
    /// let result = meter.run_kerfmeter(&params, |p| eprintln!("{:?} {:.3} N·m", p.state, p.torque_nm))?;
    /// println!("kerf {:.1} µm", result.kerf_um);
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn run_kerfmeter(
        &mut self,
        params: &RunParams,
        mut progress: impl FnMut(&Progress),
    ) -> Result<KerfResult> {
        self.run_kerfmeter_until(params, |p| {
            progress(p);
            ControlFlow::Continue(())
        })
    }

    /// [`Kerfmeter::run_kerfmeter`] that the caller can stop: when `progress` returns
    /// [`ControlFlow::Break`] (a Ctrl-C seen, a user's Stop button) the device is told to abort,
    /// so its motor is safe, and the call ends with [`Error::Cancelled`].
    ///
    /// ```no_run
    /// use std::ops::ControlFlow;
    /// use std::sync::atomic::{AtomicBool, Ordering};
    /// use kerfmeter::{Kerfmeter, JointSpec, protocol::GaugeGeometry};
    /// static STOP: AtomicBool = AtomicBool::new(false);
    /// let mut meter = Kerfmeter::open("/dev/ttyACM0")?;
    /// let params = JointSpec::default().run_params(GaugeGeometry::PAPER)?;
    /// meter.prepare_for_run()?;
    /// let stop = || if STOP.load(Ordering::Relaxed) { ControlFlow::Break(()) } else { ControlFlow::Continue(()) };
    /// let result = meter.run_kerfmeter_until(&params, |_| stop())?;
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn run_kerfmeter_until(
        &mut self,
        params: &RunParams,
        mut progress: impl FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<KerfResult> {
        crate::params::check(params)?;
        match self.call(Request::Run(*params))? {
            Response::Ok => {}
            other => return Err(unexpected("Run", &other)),
        }
        let limit = Duration::from_millis(u64::from(params.max_time_ms)) + RUN_SLACK;
        let mut run_id = None;
        self.poll_until(limit, |meter, status| {
            meter.stop_if(status, &mut progress)?;
            let id = *run_id.get_or_insert(status.run_id);
            match status.state {
                RunState::Done => match meter.get_kerf_value()? {
                    Some(result) if result.run_id == id => Ok(Some(result)),
                    _ => Err(Error::RunInterrupted),
                },
                RunState::Fault(fault) => Err(Error::Fault { fault }),
                RunState::Engaging | RunState::Ramping | RunState::Jammed | RunState::Releasing => {
                    Ok(None)
                }
                // Back to idle (or busy with something else) without a result: aborted by
                // another program, or the device restarted.
                RunState::Idle | RunState::Resetting | RunState::SelfTest => {
                    meter.info()?;
                    Err(Error::RunInterrupted)
                }
            }
        })
    }

    /// Make the device ready for a run: a latched fault ends the call with [`Error::Fault`] (clear
    /// it knowingly, with [`Kerfmeter::clear_fault`] or a reset); a device that is busy, or whose
    /// hub is further from zero than the firmware accepts for a start, is reset first.
    ///
    /// ```no_run
    /// use kerfmeter::{Kerfmeter, JointSpec, protocol::GaugeGeometry};
    /// let mut meter = Kerfmeter::open("/dev/ttyACM0")?;
    /// let params = JointSpec::default().run_params(GaugeGeometry::PAPER)?;
    /// meter.prepare_for_run()?;
    /// meter.run_kerfmeter(&params, |_| {})?;
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn prepare_for_run(&mut self) -> Result<()> {
        self.prepare_for_run_until(|_| ControlFlow::Continue(()))
    }

    /// [`Kerfmeter::prepare_for_run`] that the caller can stop during its reset, like
    /// [`Kerfmeter::reset_kerfmeter_until`].
    pub fn prepare_for_run_until(
        &mut self,
        progress: impl FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<()> {
        let status = self.status()?;
        if let RunState::Fault(fault) = status.state {
            return Err(Error::Fault { fault });
        }
        let blocking = status.conditions.intersection(Conditions::BLOCKING_RUN);
        if !blocking.is_empty() {
            // The run (and for most conditions the reset) would be refused: say so before
            // trying either.
            return Err(Error::Device {
                request: "Run",
                code: ErrorCode::Blocked(blocking),
            });
        }
        if status.angle_deg.abs() > START_TOLERANCE_DEG || status.state != RunState::Idle {
            self.reset_kerfmeter_until(progress)?;
        }
        Ok(())
    }

    /// When `progress` asks to stop at this `status`: tell the device to abort (its motor
    /// stops) and end the call with [`Error::Cancelled`], or with the abort's own error if the
    /// abort failed.
    fn stop_if(
        &mut self,
        status: &Status,
        progress: &mut impl FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<()> {
        if progress(&Progress::from(status)).is_break() {
            self.abort_until_at_rest()?;
            return Err(Error::Cancelled);
        }
        Ok(())
    }

    /// Stop the motor and wait until the device reports it at rest: idle, done or faulted, the
    /// states in which the firmware holds the bridge safe (duty 0, driver asleep). The status
    /// that said so. What a caller that was interrupted (Ctrl-C, a Stop button) calls before it
    /// tells the user the motor is stopped.
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// let status = meter.abort_until_at_rest()?;
    /// println!("stopped: {:?}", status.state);
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn abort_until_at_rest(&mut self) -> Result<Status> {
        self.abort()?;
        self.poll_until(AT_REST_DEADLINE, |_, status| {
            Ok(matches!(
                status.state,
                RunState::Idle | RunState::Done | RunState::Fault(_)
            )
            .then_some(*status))
        })
    }

    /// Poll the status every [`Options::poll_interval`](crate::Options::poll_interval) until
    /// `decide` returns an outcome or an error. Past `limit` the device is told to abort and the
    /// call ends with [`Error::RunTimeout`] naming `limit`.
    fn poll_until<T>(
        &mut self,
        limit: Duration,
        mut decide: impl FnMut(&mut Self, &Status) -> Poll<T>,
    ) -> Result<T> {
        let deadline = Instant::now() + limit;
        loop {
            let status = self.status()?;
            if let Some(outcome) = decide(self, &status)? {
                return Ok(outcome);
            }
            if Instant::now() > deadline {
                let _ = self.abort();
                return Err(Error::RunTimeout {
                    seconds: limit.as_secs(),
                });
            }
            std::thread::sleep(self.options().poll_interval);
        }
    }

    /// Measure `n` gauges (one fresh gauge each) and summarise: mean, SD, 95 % confidence interval,
    /// outliers. Before each gauge the hub is reset to zero and `before_gauge(i)` is called (on
    /// hardware: ask the person at the cutter to place gauge `i`, or move the head to it);
    /// `progress(i, …)` reports each run as it goes.
    ///
    /// ```no_run
    /// use kerfmeter::{JointSpec, Kerfmeter, protocol::GaugeGeometry};
    /// let mut meter = Kerfmeter::open("/dev/ttyACM0")?;
    /// let params = JointSpec::default().run_params(GaugeGeometry::PAPER)?;
    /// let m = meter.measure(&params, 3, |i| { println!("place gauge {}", i + 1); Ok(()) }, |_, _| {})?;
    /// println!("{:.1} ± {:.1} µm", m.summary.mean_um, m.summary.ci95_um.unwrap_or(0.0));
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn measure(
        &mut self,
        params: &RunParams,
        n: usize,
        before_gauge: impl FnMut(usize) -> Result<()>,
        mut progress: impl FnMut(usize, &Progress),
    ) -> Result<Measurement> {
        self.measure_until(params, n, before_gauge, |i, p| {
            progress(i, p);
            ControlFlow::Continue(())
        })
    }

    /// [`Kerfmeter::measure`] that can be stopped: when `progress` returns
    /// [`ControlFlow::Break`] (after any status poll, resetting or running), the device is told
    /// to abort, its motor is made safe, and the call ends with [`Error::Cancelled`].
    pub fn measure_until(
        &mut self,
        params: &RunParams,
        n: usize,
        mut before_gauge: impl FnMut(usize) -> Result<()>,
        mut progress: impl FnMut(usize, &Progress) -> ControlFlow<()>,
    ) -> Result<Measurement> {
        if n == 0 {
            return Err(Error::invalid("measure at least one gauge"));
        }
        let mut runs = Vec::with_capacity(n);
        for i in 0..n {
            self.prepare_for_run_until(|p| progress(i, p))?;
            before_gauge(i)?;
            runs.push(self.run_kerfmeter_until(params, |p| progress(i, p))?);
        }
        let kerfs: Vec<f64> = runs.iter().map(|r| f64::from(r.kerf_um)).collect();
        Ok(Measurement {
            summary: crate::stats::summarize(&kerfs),
            runs,
        })
    }

    /// The last result, or `None` after a reset or before the first run.
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// match meter.get_kerf_value()? {
    ///     Some(r) => println!("last kerf: {:.1} µm (run {})", r.kerf_um, r.run_id),
    ///     None => println!("no result yet"),
    /// }
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn get_kerf_value(&mut self) -> Result<Option<KerfResult>> {
        match self.call(Request::GetKerf)? {
            Response::Kerf(k) => Ok(k),
            other => Err(unexpected("GetKerf", &other)),
        }
    }

    /// Clear the last result and turn the hub back to its zero position (prongs aligned for the
    /// next gauge); blocks until it is there. Also clears a latched fault.
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// meter.reset_kerfmeter()?;
    /// assert!(meter.get_kerf_value()?.is_none());
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn reset_kerfmeter(&mut self) -> Result<()> {
        self.reset_kerfmeter_until(|_| ControlFlow::Continue(()))
    }

    /// [`Kerfmeter::reset_kerfmeter`] that the caller can stop: when `progress` returns
    /// [`ControlFlow::Break`] the device is told to abort and the call ends with
    /// [`Error::Cancelled`], as in [`Kerfmeter::run_kerfmeter_until`].
    pub fn reset_kerfmeter_until(
        &mut self,
        mut progress: impl FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<()> {
        match self.call(Request::Reset)? {
            Response::Ok => {}
            other => return Err(unexpected("Reset", &other)),
        }
        self.poll_until(RESET_DEADLINE, |meter, status| {
            meter.stop_if(status, &mut progress)?;
            match status.state {
                RunState::Idle => Ok(Some(())),
                RunState::Fault(fault) => Err(Error::Fault { fault }),
                RunState::Resetting => Ok(None),
                _ => Err(Error::RunInterrupted),
            }
        })
    }

    /// Stop the motor now and end the run, reset or self-test in progress.
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// meter.abort()?; // safe within one control tick
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn abort(&mut self) -> Result<()> {
        match self.call(Request::Abort)? {
            Response::Ok => Ok(()),
            other => Err(unexpected("Abort", &other)),
        }
    }

    /// Leave a latched fault (the motor stays safe; fix the cause first).
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// if let kerfmeter::protocol::RunState::Fault(f) = meter.status()?.state {
    ///     eprintln!("fault: {}", kerfmeter::describe_fault(f));
    ///     meter.clear_fault()?;
    /// }
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn clear_fault(&mut self) -> Result<()> {
        match self.call(Request::ClearFault)? {
            Response::Ok => Ok(()),
            other => Err(unexpected("ClearFault", &other)),
        }
    }

    /// Tell the device that the hub stands at its zero mark, within half a motor turn (protocol
    /// 2.5). With the encoder on the motor shaft a device refuses runs after power-up
    /// ([`Conditions::HUB_TURN_UNKNOWN`]) until told so, as it cannot know which motor turn the
    /// hub is on; its turn count restarts at the mark. Only the user can say it: turn the hub to
    /// its mark (by hand, prongs lifted) and look before calling this. Nothing changes with the
    /// encoder on the output shaft. An older device answers with `UnknownRequest`.
    pub fn confirm_hub_at_zero(&mut self) -> Result<()> {
        match self.call(Request::ConfirmHubAtZero)? {
            Response::Ok => Ok(()),
            other => Err(unexpected("ConfirmHubAtZero", &other)),
        }
    }

    /// Run the self-test (no gauge under the prongs: the hub turns a little each way) and return
    /// its report.
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// let report = meter.self_test(|_| {})?;
    /// println!("torque constant ≈ {:.2} N·m", report.torque_per_duty_nm.value);
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn self_test(&mut self, mut progress: impl FnMut(&Progress)) -> Result<SelfTestReport> {
        self.self_test_until(|p| {
            progress(p);
            ControlFlow::Continue(())
        })
    }

    /// [`Kerfmeter::self_test`] that the caller can stop: when `progress` returns
    /// [`ControlFlow::Break`] the device is told to abort and the call ends with
    /// [`Error::Cancelled`], as in [`Kerfmeter::run_kerfmeter_until`].
    pub fn self_test_until(
        &mut self,
        mut progress: impl FnMut(&Progress) -> ControlFlow<()>,
    ) -> Result<SelfTestReport> {
        match self.call(Request::SelfTest)? {
            Response::Ok => {}
            other => return Err(unexpected("SelfTest", &other)),
        }
        self.poll_until(SELF_TEST_DEADLINE, |meter, status| {
            meter.stop_if(status, &mut progress)?;
            match status.state {
                RunState::SelfTest => Ok(None),
                RunState::Fault(fault) => Err(Error::Fault { fault }),
                _ => Ok(Some(())),
            }
        })?;
        match self.call(Request::GetSelfTest)? {
            Response::SelfTest(Some(report)) => Ok(report),
            Response::SelfTest(None) => Err(Error::RunInterrupted),
            other => Err(unexpected("GetSelfTest", &other)),
        }
    }

    /// The device's configuration and whether it is the default.
    pub fn config(&mut self) -> Result<ConfigReport> {
        match self.call(Request::GetConfig)? {
            Response::Config(c) => Ok(c),
            other => Err(unexpected("GetConfig", &other)),
        }
    }

    /// Store and apply a new configuration (the motor must be at rest).
    ///
    /// ```no_run
    /// let mut meter = kerfmeter::Kerfmeter::open("/dev/ttyACM0")?;
    /// let mut config = meter.config()?.config;
    /// config.encoder_zero_raw = 8123;
    /// meter.set_config(&config)?; // validated, stored in flash, then applied
    /// # Ok::<(), kerfmeter::Error>(())
    /// ```
    pub fn set_config(&mut self, config: &DeviceConfig) -> Result<ConfigReport> {
        config
            .validate()
            .map_err(|field| Error::invalid(field.out_of_range(None).to_string()))?;
        match self.call(Request::SetConfig(*config))? {
            Response::Config(c) => Ok(c),
            other => Err(unexpected("SetConfig", &other)),
        }
    }

    /// The (time, torque, angle) curve of the last run, fetched in chunks.
    pub fn curve(&mut self) -> Result<Curve> {
        let mut samples = Vec::new();
        let mut first = None;
        loop {
            let from = samples.len() as u16;
            let chunk = match self.call(Request::GetSamples { from }) {
                Ok(Response::Samples(chunk)) => chunk,
                Ok(other) => return Err(unexpected("GetSamples", &other)),
                Err(Error::Device {
                    code: ErrorCode::NoSamples,
                    ..
                }) if samples.is_empty() => {
                    return Ok(Curve {
                        run_id: 0,
                        ticks_per_sample: 1,
                        samples,
                    });
                }
                Err(e) => return Err(e),
            };
            let (run_id, _) = *first.get_or_insert((chunk.run_id, chunk.ticks_per_sample));
            if chunk.run_id != run_id {
                // A new run started while reading: the curve would mix two runs.
                return Err(Error::RunInterrupted);
            }
            let done = chunk.samples.is_empty()
                || usize::from(chunk.total) <= samples.len() + chunk.samples.len();
            samples.extend_from_slice(&chunk.samples);
            if done {
                return Ok(Curve {
                    run_id,
                    ticks_per_sample: chunk.ticks_per_sample,
                    samples,
                });
            }
        }
    }
}
