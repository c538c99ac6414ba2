//! The device worker: the one thread that owns the device's [`Session`] (the library is
//! blocking), and the [`Device`] handle through which every client reaches it.
//!
//! * Requests reach the thread over a channel, one at a time, each with a reply channel.
//! * A *long* call (a run, a reset, a self-test, a job) holds the device: while it goes, the
//!   read-only calls (info, status, get_kerf_value) are answered from the device's latest poll,
//!   with its age ([`super::latest`]), and every other device call is refused at once with
//!   "busy" (-32001), never queued behind it. Short calls from several clients queue and are
//!   answered in turn.
//! * `abort` never waits: it raises a flag that the running call's progress closure checks at
//!   every status poll (about every 20 ms), so the device is told to abort and its motor stops;
//!   with nothing running it sends the device an `Abort` itself.
//! * A long call whose caller goes away (a WebSocket closed mid-run, an HTTP client that hung
//!   up) is aborted the same way: its future's drop raises the flag.
//! * While a run goes, its progress is broadcast to every client (`progress`, at most one per
//!   [`PROGRESS_INTERVAL`], and at every change of state), and every client hears of runs
//!   started and finished elsewhere (`run_started`, `run_finished`).
//! * A link error (the port vanished, the device stopped answering or restarted) drops the
//!   session and tells every client (`device`, `connected: false`); the thread then re-opens the
//!   device every [`WATCH_INTERVAL`] until it answers again (`device`, `connected: true`). An idle
//!   device is asked who it is every [`WATCH_INTERVAL`], so a vanished or restarted one (a new
//!   boot id) is noticed without a client asking.

use std::ops::ControlFlow;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use kerfmeter::Progress;
use kerfmeter::protocol::RunParams;
use serde::Serialize;
use serde_json::{Value, json};
use tokio::sync::{broadcast, oneshot};

use kerfmeter::job::{JobEvent, Stage};

use super::Cutter;
use super::job::{JobCall, job_answer};
use super::latest::{Latest, Query};
use super::plans::hide_history_db;
use super::rpc::{Caller, INTERNAL_ERROR, NOT_CONNECTED, RpcError, notification};
use crate::commands::{Done, confirm_zero, info, job, reset, self_test, status};
use crate::connection::{Global, Session};
use crate::error::CliError;
use crate::output::ResultJson;
use crate::words::SERVER;
use kerfmeter_app::history::is_twin;
use kerfmeter_app::measure::{RunReport, measure_and_record};
use kerfmeter_protocol::advice::in_words_of;

/// The shortest time between two `progress` notifications of the same state.
pub const PROGRESS_INTERVAL: Duration = Duration::from_millis(50);
/// How often an idle device is checked, and a vanished one looked for.
pub const WATCH_INTERVAL: Duration = Duration::from_secs(1);
/// How many notifications a slow client may fall behind before it misses some.
const EVENTS_BACKLOG: usize = 256;

/// What a client asks of the device.
#[derive(Debug)]
pub enum Call {
    /// `info`: the `kerfmeter info --json` report.
    Info,
    /// `status`: the `kerfmeter status --json` report.
    Status,
    /// `get_kerf_value`: the last result, or null.
    Kerf,
    /// `reset_kerfmeter` (long).
    Reset,
    /// `clear_fault`.
    ClearFault,
    /// `confirm_hub_at_zero`.
    ConfirmZero,
    /// `self_test` (long).
    SelfTest,
    /// Stop the motor (sent only when nothing long runs; see [`Device::abort`]).
    Abort,
    /// `run_kerfmeter` (long).
    Run(RunCall),
    /// `job`: the whole loop on the server's cutter (long).
    Job(Box<JobCall>),
}

impl Call {
    /// The read-only query this call is, if it is one (answered at any time).
    fn query(&self) -> Option<Query> {
        match self {
            Call::Info => Some(Query::Info),
            Call::Status => Some(Query::Status),
            Call::Kerf => Some(Query::Kerf),
            _ => None,
        }
    }

    /// Whether the call clears the device's result as it starts (a run, a job's run, a reset).
    fn clears_result(&self) -> bool {
        matches!(self, Call::Run(_) | Call::Job(_) | Call::Reset)
    }

    /// Whether the call holds the device while it goes.
    fn is_long(&self) -> bool {
        matches!(
            self,
            Call::Run(_) | Call::Job(_) | Call::Reset | Call::SelfTest
        )
    }

    /// Whether the call measures (announced with `run_started` and `run_finished`).
    fn measures(&self) -> bool {
        matches!(self, Call::Run(_) | Call::Job(_))
    }
}

/// A checked `run_kerfmeter` request.
#[derive(Debug)]
pub struct RunCall {
    /// The device's run parameters, from the joint asked for.
    pub params: RunParams,
    /// Gauges to measure (1..=50).
    pub samples: usize,
    /// The caller's label (material, cutter), returned with the result.
    pub label: Option<String>,
}

/// What a call answers.
pub type Reply = Result<Value, RpcError>;

/// A call on its way to the worker.
struct Job {
    call: Call,
    by: Caller,
    reply: oneshot::Sender<Reply>,
}

/// What the worker and the clients share.
struct Shared {
    /// Taken while `busy` and `stop` change together (a long call starting, an abort), so that
    /// an abort can never fall between a new call taking the device and clearing the old stop.
    gate: Mutex<()>,
    /// A long call holds the device.
    busy: AtomicBool,
    /// The long call going should stop.
    stop: Arc<AtomicBool>,
    /// The device answered last time it was asked.
    connected: AtomicBool,
    /// The device last opened is the digital twin (in process or behind a PTY).
    twin: AtomicBool,
    /// The server is stopping: the thread ends after the call it is doing.
    quit: AtomicBool,
    /// The device's state was logged once.
    logged: AtomicBool,
    /// Notifications to every client, as JSON-RPC text.
    events: broadcast::Sender<Arc<str>>,
    /// The cutter `job` runs on (`serve --cutter`), if any.
    cutter: Option<Cutter>,
    /// The flags the device was opened with (the history's database among them).
    global: Global,
    /// The device's last answers, for the read-only calls while a long call goes.
    latest: Latest,
}

impl Shared {
    /// Send a notification to every client (none listening is fine).
    fn notify(&self, method: &str, params: Value) {
        let _ = self.events.send(notification(method, params).into());
    }

    /// Record whether the device answers; tell every client, and the server's log (stderr),
    /// when that changes (a device that cannot be opened at startup is logged too).
    fn set_connected(&self, connected: bool, message: &str) {
        let first = !self.logged.swap(true, Ordering::SeqCst);
        let changed = self.connected.swap(connected, Ordering::SeqCst) != connected;
        if changed || first {
            eprintln!("device: {message}");
            let params = json!({ "connected": connected, "message": message });
            self.notify("device", params);
        }
    }

    /// The progress closure of a long call: keeps its poll for the read-only calls, and stops
    /// the call when asked to.
    fn polled(&self, p: &Progress) -> ControlFlow<()> {
        self.latest.polled(&p.status);
        self.stop_requested()
    }

    /// Whether the long call going should stop.
    fn stop_requested(&self) -> ControlFlow<()> {
        if self.stop.load(Ordering::SeqCst) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

/// The handle every client uses to reach the device.
#[derive(Clone)]
pub struct Device {
    shared: Arc<Shared>,
    jobs: mpsc::Sender<Job>,
}

impl Device {
    /// Open the device as `g` says and start its thread; the thread ends when every handle is
    /// dropped, after the call it is doing.
    pub fn start(g: Global, cutter: Option<Cutter>) -> (Device, JoinHandle<()>) {
        let (events, _) = broadcast::channel(EVENTS_BACKLOG);
        let shared = Arc::new(Shared {
            gate: Mutex::new(()),
            busy: AtomicBool::new(false),
            stop: Arc::new(AtomicBool::new(false)),
            connected: AtomicBool::new(false),
            twin: AtomicBool::new(false),
            quit: AtomicBool::new(false),
            logged: AtomicBool::new(false),
            events,
            cutter,
            global: g.clone(),
            latest: Latest::default(),
        });
        let (jobs, queue) = mpsc::channel();
        let worker = Worker {
            g,
            session: None,
            shared: Arc::clone(&shared),
        };
        let thread = std::thread::Builder::new()
            .name("kerfmeter-device".into())
            .spawn(move || in_words_of(&SERVER, || worker.work(queue)))
            .expect("a thread can be started");
        (Device { shared, jobs }, thread)
    }

    /// Whether the device last opened is the digital twin, whose measurements are recorded as
    /// simulated.
    pub fn is_twin(&self) -> bool {
        self.shared.twin.load(Ordering::SeqCst)
    }

    /// The cutter `job` runs on, if the server was given one.
    pub fn cutter(&self) -> Option<&Cutter> {
        self.shared.cutter.as_ref()
    }

    /// The flags the server was started with.
    pub fn global(&self) -> &Global {
        &self.shared.global
    }

    /// The notifications, from now on.
    pub fn subscribe(&self) -> broadcast::Receiver<Arc<str>> {
        self.shared.events.subscribe()
    }

    /// Carry out `call`. A long call while another goes is refused at once ("busy"); a long
    /// call whose future is dropped before its answer (the client went away) is aborted.
    pub async fn call(&self, call: Call, by: Caller) -> Reply {
        let long = call.is_long();
        let shared = &self.shared;
        if long {
            let _gate = shared.gate.lock().unwrap_or_else(PoisonError::into_inner);
            let taken =
                shared
                    .busy
                    .compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst);
            if taken.is_err() {
                return Err(RpcError::busy());
            }
            shared.stop.store(false, Ordering::SeqCst);
        } else if shared.busy.load(Ordering::SeqCst) && !matches!(call, Call::Abort) {
            // A read is answered from the long call's polls; an abort is never refused (one
            // that meets a run just started queues behind it).
            match call.query().map(|q| shared.latest.answer(q)) {
                Some(Some(answer)) => return Ok(answer),
                // A read before the long call's first poll was kept: queued, never refused.
                Some(None) => {}
                None => return Err(RpcError::busy()),
            }
        }
        let guard = long.then(|| AbortOnDrop(Arc::clone(shared)));
        let (reply, answer) = oneshot::channel();
        if self.jobs.send(Job { call, by, reply }).is_err() {
            // The worker is gone (the server is stopping): the device is not held.
            std::mem::forget(guard);
            shared.busy.store(false, Ordering::SeqCst);
            return Err(RpcError::new(NOT_CONNECTED, "the server is stopping"));
        }
        let outcome = answer.await;
        std::mem::forget(guard);
        outcome.unwrap_or_else(|_| Err(RpcError::new(NOT_CONNECTED, "the server is stopping")))
    }

    /// Stop the motor: the long call going is told to stop (its caller gets "aborted"); with
    /// none going, the device is sent an abort.
    pub async fn abort(&self) -> Reply {
        let running = {
            let _gate = self
                .shared
                .gate
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            self.stop_running();
            self.shared.busy.load(Ordering::SeqCst)
        };
        if !running {
            self.call(Call::Abort, Caller::Rpc).await?;
        }
        Ok(json!({ "aborted": true }))
    }

    /// Whether a long call (a run, reset, self-test or job) is going.
    pub fn is_busy(&self) -> bool {
        self.shared.busy.load(Ordering::SeqCst)
    }

    /// Tell the long call going, if any, to stop (without waiting).
    pub fn stop_running(&self) {
        self.shared.stop.store(true, Ordering::SeqCst);
    }

    /// Stop the call going and end the thread after it (the device is told to abort).
    pub fn shut_down(&self) {
        self.stop_running();
        self.shared.quit.store(true, Ordering::SeqCst);
    }
}

/// Raises the stop flag when a long call's future is dropped before its answer came.
struct AbortOnDrop(Arc<Shared>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.stop.store(true, Ordering::SeqCst);
    }
}

/// The thread's state: the flags to open the device with, and the open session.
struct Worker {
    g: Global,
    session: Option<Session>,
    shared: Arc<Shared>,
}

impl Worker {
    /// Serve jobs until the server stops (or every [`Device`] is dropped); watch the device in
    /// between.
    fn work(mut self, queue: mpsc::Receiver<Job>) {
        self.reconnect();
        while !self.shared.quit.load(Ordering::SeqCst) {
            match queue.recv_timeout(WATCH_INTERVAL) {
                Ok(job) => self.serve(job),
                Err(mpsc::RecvTimeoutError::Timeout) => self.watch(),
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        if let Some(s) = &mut self.session {
            // Leaving: whatever the device does, its motor stops.
            let _ = s.meter.abort();
        }
    }

    /// Open the device if it is not open; say so when that changes.
    fn reconnect(&mut self) {
        if self.session.is_some() {
            return;
        }
        match self.g.connect() {
            Ok(s) => {
                let message = format!("the device answers on {}", s.meter.path());
                let twin = is_twin(&s.meter);
                self.shared.twin.store(twin, Ordering::SeqCst);
                self.session = Some(s);
                self.shared.set_connected(true, &message);
            }
            Err(e) => self.shared.set_connected(false, &e.to_string()),
        }
    }

    /// An idle moment: check that the device still answers and has not restarted (its boot id,
    /// from `GetInfo`), or look for it again.
    fn watch(&mut self) {
        match &mut self.session {
            Some(s) => {
                if let Err(e) = s.meter.info() {
                    self.lost(&CliError::from(e));
                }
            }
            None => self.reconnect(),
        }
    }

    /// Drop the session after a link error, so that the device is re-opened.
    fn lost(&mut self, e: &CliError) {
        self.lost_link(e.category(), &e.to_string());
    }

    /// Drop the session if a failure of `category` (told as `message`) was the link's.
    fn lost_link(&mut self, category: kerfmeter::Category, message: &str) {
        if category == kerfmeter::Category::Communication {
            self.session = None;
            self.shared.set_connected(false, message);
        }
    }

    /// Carry out one job and answer it (the device is free again before the answer leaves).
    /// A run's `run_finished` is sent once the device is free, so that a client hearing it can
    /// start the next call at once.
    fn serve(&mut self, job: Job) {
        let long = job.call.is_long();
        let run = job.call.measures();
        let query = job.call.query();
        if long {
            self.before_long(job.call.clears_result());
        }
        let call = AssertUnwindSafe(|| self.reply(job.call, job.by));
        let reply = std::panic::catch_unwind(call).unwrap_or_else(|_| self.after_panic());
        if let (Some(query), Ok(answer)) = (query, &reply) {
            self.shared.latest.remember(query, answer);
        }
        if long {
            self.shared.busy.store(false, Ordering::SeqCst);
        }
        if run {
            let (kerf_um, error) = match &reply {
                Ok(served) => (served["kerf_um"].clone(), None),
                Err(e) => (Value::Null, Some(e)),
            };
            let finished = json!({ "kerf_um": kerf_um, "error": error });
            self.shared.notify("run_finished", finished);
        }
        let _ = job.reply.send(reply);
    }

    /// Before a long call: what the read-only calls will be answered with while it goes (the
    /// device's info, status and result now; no result once a run or reset starts).
    fn before_long(&mut self, clears_result: bool) {
        self.reconnect();
        let Some(s) = &mut self.session else { return };
        let latest = &self.shared.latest;
        if let Ok(report) = info::report(s) {
            latest.remember(Query::Info, &to_value(&report));
        }
        if let Ok(status) = s.meter.status() {
            latest.polled(&status);
        }
        if clears_result {
            latest.result_cleared();
        } else if let Ok(kerf) = s.meter.get_kerf_value() {
            latest.remember(Query::Kerf, &to_value(&kerf.as_ref().map(ResultJson::from)));
        }
    }

    /// A call panicked (a bug; the panic message is on stderr): whatever the device was doing, its
    /// motor stops, and it is opened afresh for the next call, its session's state being
    /// unknown. The server goes on serving: its thread is the only one that can stop the motor.
    fn after_panic(&mut self) -> Reply {
        if let Some(s) = &mut self.session {
            let _ = s.meter.abort();
        }
        self.session = None;
        let why = "the server failed inside this call (a bug: please report it with the message \
                   it printed); the device was told to stop";
        Err(RpcError::new(INTERNAL_ERROR, why))
    }

    /// The answer to `call`.
    fn reply(&mut self, call: Call, by: Caller) -> Reply {
        self.reconnect();
        let Some(s) = &mut self.session else {
            let why = "the device is not connected; the server opens it again when it answers";
            return Err(RpcError::new(NOT_CONNECTED, why));
        };
        let outcome = match call {
            Call::Run(run) => return self.run(run, by),
            Call::Job(job) => return self.job(&job, by),
            other => do_call(s, other, &self.shared),
        };
        outcome.map_err(|e| {
            self.lost(&e);
            RpcError::from(&e)
        })
    }

    /// A run: announced to every client, its progress broadcast.
    fn run(&mut self, run: RunCall, by: Caller) -> Reply {
        let label = run.label.clone();
        let params = json!({ "label": label, "by": by.name() });
        self.shared.notify("run_started", params);
        let Some(s) = &mut self.session else {
            return Err(RpcError::new(NOT_CONNECTED, "the device is not connected"));
        };
        match measure_and_report(&self.g, s, &run, &self.shared) {
            Ok(served) => {
                if let Some(e) = &served.report.curve_error {
                    self.lost_link(e.category, &e.message);
                }
                let mut answer = to_value(&served);
                hide_history_db(&mut answer);
                Ok(answer)
            }
            Err(e) => {
                self.lost(&e);
                Err(RpcError::from(&e))
            }
        }
    }
}

impl Worker {
    /// A job: announced like a run, each stage told to every client (`stage`), the device's
    /// progress too. An error ends the stage going as `failed`.
    fn job(&mut self, job: &JobCall, by: Caller) -> Reply {
        let params = json!({ "label": job.label(), "by": by.name() });
        self.shared.notify("run_started", params);
        let Some(s) = &mut self.session else {
            return Err(RpcError::new(NOT_CONNECTED, "the device is not connected"));
        };
        let shared = Arc::clone(&self.shared);
        let mut stages = Stages::default();
        let on_event = &mut |e: JobEvent<'_>| stages.event(&shared, e);
        let outcome = job::run_on(&self.g, &job.cutter, &job.setup, s, &shared.stop, on_event)
            .and_then(|report| job_answer(job, &report));
        outcome.map_err(|e| {
            stages.failed(&shared);
            self.lost(&e);
            RpcError::from(&e)
        })
    }
}

/// The stage a job is in, for its `stage` and `progress` notifications.
#[derive(Default)]
struct Stages {
    going: Option<(Stage, Instant)>,
    throttle: Throttle,
}

impl Stages {
    /// Tell every client of `e`.
    fn event(&mut self, shared: &Shared, e: JobEvent<'_>) {
        let stage = |stage: Stage, state: &str, elapsed: Duration| {
            let elapsed_ms = elapsed.as_millis() as u64;
            json!({ "stage": stage.name(), "state": state, "elapsed_ms": elapsed_ms })
        };
        match e {
            JobEvent::Started(s) => {
                self.going = Some((s, Instant::now()));
                shared.notify("stage", stage(s, "started", Duration::ZERO));
            }
            JobEvent::Finished(s, elapsed) => {
                self.going = None;
                shared.notify("stage", stage(s, "done", elapsed));
            }
            JobEvent::Device(p) => {
                shared.latest.polled(&p.status);
                if let Some(params) = self.throttle.progress(0, 1, p) {
                    shared.notify("progress", params);
                }
            }
            JobEvent::Cutter(..) => {}
        }
    }

    /// The job failed: the stage going failed.
    fn failed(&mut self, shared: &Shared) {
        if let Some((s, since)) = self.going.take() {
            let elapsed_ms = since.elapsed().as_millis() as u64;
            let params = json!({ "stage": s.name(), "state": "failed", "elapsed_ms": elapsed_ms });
            shared.notify("stage", params);
        }
    }
}

/// A short call, a reset or a self-test on the open session.
fn do_call(s: &mut Session, call: Call, shared: &Shared) -> Result<Value, CliError> {
    Ok(match call {
        Call::Info => to_value(&info::report(s)?),
        Call::Status => to_value(&status::StatusReport::from(s.meter.status()?)),
        Call::Kerf => to_value(&s.meter.get_kerf_value()?.as_ref().map(ResultJson::from)),
        Call::Reset => {
            let cleared_fault = reset::latched_fault(&mut s.meter)?;
            s.meter.reset_kerfmeter_until(|p| shared.polled(p))?;
            let mut answer = json!({ "reset": true });
            if let Some(w) = reset::warning(&mut s.meter)? {
                answer["warning"] = json!(w);
            }
            if let Some(fault) = cleared_fault {
                answer["cleared_fault"] = json!(format!("{fault:?}"));
            }
            answer
        }
        Call::ClearFault => {
            s.meter.clear_fault()?;
            to_value(&Done::new("fault cleared"))
        }
        Call::ConfirmZero => to_value(&confirm_zero::confirm(s, false)?),
        Call::SelfTest => to_value(&self_test::test(s, |p| shared.polled(p))?),
        Call::Abort => {
            s.meter.abort()?;
            json!({ "aborted": true })
        }
        Call::Run(_) | Call::Job(_) => unreachable!("runs and jobs are served by the worker"),
    })
}

/// What `run_kerfmeter` answers: `kerfmeter run --json`'s report (with the caller's label and
/// where it was recorded in the history) and the last run's torque–angle curve.
#[derive(Serialize)]
pub struct ServedRun {
    /// The report, its fields at the top level (`kerf_um`, `summary`, `runs`, ...).
    #[serde(flatten)]
    pub report: RunReport,
    /// The last run's curve (`null`, with `curve_error`, when it could not be read).
    pub curve: Option<CurvePoints>,
}

/// A run's curve as `[torque_nm, angle_deg]` pairs, oldest first.
#[derive(Serialize)]
pub struct CurvePoints {
    /// The run.
    pub run_id: u32,
    /// The samples.
    pub points: Vec<[f32; 2]>,
}

/// Measure as `run` says, broadcasting progress, then fetch the last run's curve.
fn measure_and_report(
    g: &Global,
    s: &mut Session,
    run: &RunCall,
    shared: &Shared,
) -> Result<ServedRun, CliError> {
    let mut throttle = Throttle::default();
    let report = measure_and_record(
        &mut s.meter,
        &run.params,
        run.samples,
        run.label.as_deref(),
        g.db.as_deref(),
        |_| Ok(()),
        |i, p| {
            if let Some(params) = throttle.progress(i, run.samples, p) {
                shared.notify("progress", params);
            }
            shared.polled(p)
        },
    )?;
    let mut report = s.with_twin_truth(report);
    let curve = s.meter.curve().map_err(CliError::from);
    // The kerf is measured and recorded: a curve that cannot be read does not hide it.
    let curve = match curve {
        Ok(curve) => Some(CurvePoints {
            run_id: curve.run_id,
            points: curve
                .samples
                .iter()
                .map(|x| [x.torque_nm, x.angle_deg])
                .collect(),
        }),
        Err(e) => {
            report.curve_failed(e.to_string(), e.category());
            None
        }
    };
    Ok(ServedRun { report, curve })
}

/// Lets a `progress` notification through at most once per [`PROGRESS_INTERVAL`], and at every
/// change of state or gauge.
#[derive(Default)]
struct Throttle {
    last: Option<(Instant, usize, String)>,
}

impl Throttle {
    /// The notification's params for `p` of gauge `i` of `n`, if one is due.
    fn progress(&mut self, i: usize, n: usize, p: &Progress) -> Option<Value> {
        let state = format!("{:?}", p.state);
        let now = Instant::now();
        let due = match &self.last {
            None => true,
            Some((at, gauge, last_state)) => {
                *gauge != i || *last_state != state || now - *at >= PROGRESS_INTERVAL
            }
        };
        if !due {
            return None;
        }
        let params = json!({
            "sample": i, "samples": n, "state": state, "torque_nm": p.torque_nm,
            "angle_deg": p.angle_deg, "elapsed_ms": p.elapsed_ms,
        });
        self.last = Some((now, i, state));
        Some(params)
    }
}

/// A report as JSON.
fn to_value(report: &impl Serialize) -> Value {
    serde_json::to_value(report).expect("reports serialize")
}
