//! `kerfmeter serve`: the Kerfmeter server. It runs on the computer wired to the device and lets
//! any program (a browser page, a design tool, a Python or Node script) drive it: the paper's
//! three calls and the rest of what the CLI does, over a WebSocket speaking JSON-RPC 2.0 and
//! over plain HTTP JSON. The results are built by the same code as the CLI's `--json` reports.
//!
//! # Transport
//!
//! * `GET /rpc`: a WebSocket; JSON-RPC 2.0 requests and responses in text frames, and
//!   notifications pushed to every client. A message is at most [`MAX_BODY_BYTES`].
//! * HTTP JSON: `GET /api/info`, `GET /api/status`, `GET /api/kerf`,
//!   `GET /api/history[?label=L&limit=N]`, `POST /api/run`,
//!   `POST /api/reset`, `POST /api/abort`, `POST /api/dilate` (a POST's body is the method's params, a JSON object,
//!   at most [`MAX_BODY_BYTES`]; an empty body is `{}`). Success is `200` with the result as
//!   the body; a failure is 4xx/5xx with `{"error": {"code", "message", "data"}}`.
//! * `GET /`: the page, embedded in the binary.
//!
//! # Methods
//!
//! Params are objects; every field is optional. An unknown field is refused (-32602, naming it).
//!
//! | method | params | result |
//! |---|---|---|
//! | `info` | | `kerfmeter info --json` |
//! | `status` | | `kerfmeter status --json` |
//! | `run_kerfmeter` | `thickness_mm`, `force_n`, `fingers`, `finger_length_mm`, `samples` (1..=50), `label` | `kerfmeter run --json` (`kerf_um` at the top level, `summary`, `runs`, `force_n`, `thickness_mm`, `label`, `history`: where it was recorded and its drift warning, ...) plus `curve`: `{"run_id", "points": [[torque_nm, angle_deg], ...]}` of the last run, or `null` with `curve_error` when it could not be read (the kerf stands); each of `runs` has its quality flags as bits (`flags`) and by name (`flag_names`) |
//! | `get_kerf_value` | | the device's last result (`kerf_um` at its top level, `flag_names`), or `null` |
//! | `reset_kerfmeter` | | `{"reset": true}`, with `cleared_fault` (its name) when a fault was latched, and a `warning` when the hub's zero is only the encoder count's (hub-turn-unknown) |
//! | `abort` | | `{"aborted": true}`, at any time, also during another client's run |
//! | `clear_fault` | | `kerfmeter clear-fault --json` (`{"ok": true}`) |
//! | `confirm_hub_at_zero` | | `kerfmeter confirm-zero --json` (`{"ok": true}`): the hub stands at its zero mark (encoder on the motor shaft, after power-up) |
//! | `self_test` | | `kerfmeter self-test --json` (a failed item is `passed: false`, not an error) |
//! | `dilate` | `plan` (text) or `plan_base64`, `format` (`"svg"`/`"dxf"`, required), `kerf_um` (µm, or `"last"`: the device's last result; required), and `kerfmeter dilate`'s rules: `cut_colors`, `cut_max_width_mm`, `cut_layers`, `units`, `strict`, `already_compensated_ok`, `recompensate` | `{"kerf_um", "format", "content": the dilated plan's text, "report": {"kerf_um", "cut_rules", ... what `dilate --json` says was found and done}}` |
//! | `gauge` | `format` (`"svg"` default, `"dxf"`), and `kerfmeter gauge`'s options with `_` for `-`: `pitch_um_per_deg`, `radius_mm`, `prong_radius_mm`, `hole_radius_mm`, `hole_distance_mm`, `jam_direction` (`"cw"`/`"ccw"`), `disengage_deg`, `test_piece`, `thickness_mm`, `finger_width_mm`, `test_piece_kerf_um`, `label` | `{"format", "content": the drawing's text, "report": gauge --json's report without the file}` |
//! | `history` | `label`, `limit` (1..=100000, default 50) | `{"simulated", "records": [{id, time, device_id, firmware, label, thickness_mm, force_n, kerf_um, ci95_um, flags, simulated}, ...] newest first, "drift": [{label, kerf_um, usual_mean_um, usual_sd_um, message}, ...]}`: `kerfmeter history --json` without the database's path; the server's `--db` (or the user's data directory); the simulated records when the server runs the twin |
//! | `job` | `plan` or `plan_base64`, `format` (required), and a `kerfmeter_app::job::JobRequest` (`kerfmeter job`'s flags that name no file, with `_`, as JSON values; `null` is not given): `label`, `thickness_mm`, `force_n`, `gauge_at_mm` (`[x, y]`), `bed_mm` (`[w, h]`), `prong_offset_mm` (`[dx, dy]`), `insert_z_mm`, `travel_z_mm`, `plunge_feed_mm_per_min`, `origin_mm` (`[x, y]`), `feed_mm_per_min`, `power_percent`, `passes`, `s_max`, `cut_color` (one or a list), `cut_max_width_mm`, `cut_layer` (one or a list), `units`, `already_compensated_ok`, `recompensate`, `unlock` (only when the server was started with `--allow-unlock`) | the whole loop on the cutter given to `serve --cutter` (else -32004): `{"kerf_um", "label", "report": job --json's report without file names, "content": the dilated plan, "gcode": the job as streamed}`; `stage` notifications as it goes |
//!
//! With `samples` above 1 the gauges are measured one after the other without a prompt, as
//! `kerfmeter run --yes` does: on hardware, something must place each fresh gauge.
//!
//! # Notifications
//!
//! * `progress` `{sample, samples, state, torque_nm, angle_deg, elapsed_ms}` while a run goes
//!   (at most one per 50 ms, and at every change of state);
//! * `stage` `{stage, state: "started"|"done"|"failed", elapsed_ms}` during a job;
//! * `run_started` `{label, by: "rpc"|"http"}`, `run_finished` `{kerf_um|null, error|null}`
//!   (for runs and jobs);
//! * `device` `{connected, message}` when the device vanishes or comes back.
//!
//! # Errors
//!
//! -32700 not JSON; -32600 not a JSON-RPC request (also: body too large, token or origin
//! refused, with HTTP 413, 401 or 403); -32601 no such method; -32602 bad params (the message
//! names the field); -32000 the device refused or failed (`data.kind`, `data.fault`,
//! `data.conditions`); -32001 busy: a run, reset or self-test is going; -32002 aborted; -32003
//! the device is not connected; -32004 no cutter configured; -32005 a plan error
//! (`data.compensation_found` when the plan is already compensated); -32006 the
//! history database could not be read (HTTP 500); -32603 the server failed inside the call (a
//! bug: the device was told to stop, and is opened afresh for the next call).
//!
//! # One device, one run
//!
//! See [`worker`]: one thread owns the device; a second run is refused at once; `abort` is
//! heard within one status poll; a client that disconnects mid-run aborts it; a vanished device
//! is re-opened when it answers again. Ctrl-C (or SIGTERM, or SIGHUP) aborts whatever runs (its
//! caller is answered "aborted", -32002, and every client told `run_finished`), waits for the
//! device to be safe, and stops the server.
//!
//! # Security
//!
//! See [`security`]: loopback by default, a token off loopback, no cross-site requests.
//!
//! # Notes for clients
//!
//! * While a run, reset, self-test or job goes, every other device call (`status`, `info`,
//!   `get_kerf_value`, ...) is refused with -32001 rather than made to wait for it: a page
//!   follows the run through `progress`, `stage` and `run_finished`, and asks for the status
//!   after. `abort`, `gauge` and `dilate` (with a number for `kerf_um`) are always answered.
//! * `progress.state` is the device state's name as the library spells it: `Engaging`,
//!   `Ramping`, `Jammed`, `Releasing`, `Done`, ..., `Fault(NoMotion)`.
//! * The token, origin and body-size refusals are -32600 with HTTP 401, 403 and 413.
//!
//! # Adding a method
//!
//! A method is one arm of [`rpc::dispatch`] (and, for a device call, of the worker's `Call`);
//! its HTTP route is one line of the table in [`http`].

mod http;
mod job;
mod latest;
mod plans;
mod rpc;
mod security;
mod worker;

use std::future::IntoFuture;
use std::net::SocketAddr;
use std::sync::Arc;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::print_line;
use crate::words::SERVER;
use kerfmeter_protocol::advice::word_this_thread;
pub use security::Security;
use worker::Device;

/// The largest request body or WebSocket message, bytes (16 MiB: room for a large plan as
/// text or base64).
pub const MAX_BODY_BYTES: usize = 16 * 1024 * 1024;

/// How long stopping waits for the clients' tasks to end.
const SHUTDOWN_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// The laser cutter `job` runs on, as `serve --cutter` and `--allow-unlock` give it.
#[derive(Debug, Clone)]
pub struct Cutter {
    /// Its address (`sim`, `grbl:PATH`, `grbl+tcp://HOST:PORT`, `ruida:HOST?z-mm=MIN,MAX`,
    /// `ruida-sim`).
    pub address: String,
    /// Whether a client's `job` may clear the controller's alarm (`unlock`).
    pub allow_unlock: bool,
}

/// Serve until Ctrl-C (or SIGTERM, or SIGHUP): open the device as `g` says, listen on `listen` under
/// `security`'s rules, print the address, and answer; `job` runs on `cutter`.
pub fn serve(
    g: &Global,
    listen: SocketAddr,
    security: Security,
    cutter: Option<Cutter>,
) -> Result<(), CliError> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        // What its threads answer, they word as the server's clients do it (methods, not flags).
        .on_thread_start(|| word_this_thread(&SERVER))
        .enable_all()
        .build()
        .map_err(|e| CliError::Usage(format!("cannot start the server's runtime: {e}")))?;
    let (device, thread) = Device::start(g.clone(), cutter);
    let served = runtime.block_on(listen_and_serve(device.clone(), listen, security));
    // Whatever ended the serving, nothing may keep the motor turning: stop the call going and
    // let the device thread finish it (it aborts the device) before the process ends.
    device.shut_down();
    drop(device);
    runtime.shutdown_timeout(SHUTDOWN_WAIT);
    let _ = thread.join();
    served
}

/// Bind, print the URL, and serve until a stop signal.
async fn listen_and_serve(
    device: Device,
    listen: SocketAddr,
    security: Security,
) -> Result<(), CliError> {
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(|e| CliError::Usage(format!("cannot listen on {listen}: {e}")))?;
    let bound = listener
        .local_addr()
        .map_err(|e| CliError::Usage(format!("cannot listen on {listen}: {e}")))?;
    let security = Arc::new(security.bound_to(bound));
    print_line(&format!("Listening on http://{bound}/"));
    for warning in security.warnings() {
        eprintln!("warning: {warning}");
    }
    let app = http::router(device.clone(), security);
    let serving = axum::serve(listener, app).into_future();
    tokio::pin!(serving);
    tokio::select! {
        served = &mut serving => {
            return served.map_err(|e| CliError::Usage(format!("the server stopped: {e}")));
        }
        () = stop_signal() => {}
    }
    // Abort what runs while still serving, so that its caller hears the answer ("aborted") and
    // `run_finished` before the connections close.
    device.stop_running();
    let answered = async {
        while device.is_busy() {
            tokio::time::sleep(BUSY_POLL).await;
        }
        tokio::time::sleep(ANSWER_FLUSH).await;
    };
    tokio::select! {
        _ = &mut serving => {}
        _ = tokio::time::timeout(SHUTDOWN_WAIT, answered) => {}
    }
    Ok(())
}

/// How often a stopping server looks whether the call it aborted has ended.
const BUSY_POLL: std::time::Duration = std::time::Duration::from_millis(20);

/// How long a stopping server goes on serving once the aborted call has ended, for its answer
/// and notifications to be written.
const ANSWER_FLUSH: std::time::Duration = std::time::Duration::from_millis(150);

/// Ctrl-C, or SIGTERM or SIGHUP (the terminal closed) where there are such: each stops the
/// server safely rather than killing it mid-run.
async fn stop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let (Ok(mut term), Ok(mut hup)) = (
            signal(SignalKind::terminate()),
            signal(SignalKind::hangup()),
        ) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
                _ = hup.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}
