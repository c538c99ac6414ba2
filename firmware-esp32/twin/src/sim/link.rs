//! The host's side of the link: bytes and requests from the client, the other host's bursts,
//! and the board's rule for serving them, a frame budget a pass with the core's clock moved on by
//! each frame's work and each flash operation (see the module docs, "Time").

use kerfmeter_firmware::device::WithMotor;
use kerfmeter_firmware::fakes::flash::FlashClock;
use kerfmeter_firmware::fakes::pins::{FakeOutput, FakePwm};
use kerfmeter_firmware::fakes::rng::Rng;
use kerfmeter_firmware::link::{FRAMES_PER_TICK, Handler, Link};
use kerfmeter_protocol::{Request, ResetReason, Response, RunState};

use super::{Twin, TwinDevice, TwinMotor};
use crate::gauge_trace::TracedGaugeSlot;
use crate::options::{InjectedFault, TwinOptions};
use crate::plant::{Cutter, Plant};
use crate::timing::SimWatchdog;
use crate::truth::TruthLog;

impl Twin {
    /// True while the injected `host-silent` fault swallows the host's bytes.
    fn host_muted(&self) -> bool {
        self.options.fault == Some(InjectedFault::HostSilent)
            && self.fault_struck
            && !matches!(self.device.controller().run_state(), RunState::Fault(_))
    }

    /// Bytes from the host: handled by the firmware's link, [`FRAMES_PER_TICK`] frames a pass
    /// (the twin runs the ticks until the last frame's turn comes); responses go to `transmit` —
    /// none if the device reset before it could send them (its watchdog, during a flash stall).
    pub fn receive(&mut self, bytes: &[u8], mut transmit: impl FnMut(&[u8])) {
        if self.host_muted() {
            return;
        }
        self.queue_burst();
        let mut rest = bytes;
        loop {
            let budget = self.client_turn();
            let mut out = Vec::new();
            let Some(done) = self.serve_host(Sender::Client, |handler, link| {
                link.receive_frames(rest, budget, handler, |frame| out.push(frame.to_vec()))
            }) else {
                return;
            };
            self.pass_frames += done.frames;
            out.iter().for_each(|frame| transmit(frame));
            rest = &rest[done.consumed..];
            if rest.is_empty() {
                return;
            }
        }
    }

    /// A request without framing (in-process tests), costing one frame's link work.
    ///
    /// # Panics
    ///
    /// If the device resets before answering (see [`try_request`](Self::try_request)).
    pub fn request(&mut self, request: &Request) -> Response {
        self.try_request(request)
            .expect("the device's watchdog reset it before it answered")
    }

    /// A request without framing, handled when its turn comes (a frame of the pass's budget);
    /// `None` when the device reset before answering (its watchdog fired during a flash stall)
    /// and rebooted.
    pub fn try_request(&mut self, request: &Request) -> Option<Response> {
        self.queue_burst();
        self.client_turn();
        // Heard, then handled, as the link does with every request it receives.
        let response = self.serve_host(Sender::Client, |handler, _| {
            handler.host_activity();
            handler.handle(request)
        })?;
        self.pass_frames += 1;
        Some(response)
    }

    /// The client's frames arrive: with them the other host's burst due, if its last one is
    /// gone, queued in front of them (and served at once if this pass has budget left).
    fn queue_burst(&mut self) {
        if self.burst_backlog.is_empty() {
            self.burst_backlog = self.bursts.take_due(self.now_us);
            self.serve_backlog();
        }
    }

    /// Runs passes (ticks, each serving the queue) until the other host's queued frames are
    /// through and a pass has budget left for the client's next frames; that budget.
    ///
    /// A pass whose link work ran longer than a period (a flash stall) takes no more frames:
    /// on the board its answers leave only once it has ended, and the board's ticker then
    /// restarts, so whatever the host sends on hearing them is served after the next pass's
    /// step, a period later (a run started then does not take the stall for an overrun of its
    /// own steps).
    fn client_turn(&mut self) -> u32 {
        while !self.burst_backlog.is_empty()
            || self.pass_frames >= FRAMES_PER_TICK
            || self.ticks.overran(self.now_us)
        {
            self.tick();
        }
        FRAMES_PER_TICK - self.pass_frames
    }

    /// The other host's queued frames, within what is left of this pass's budget.
    pub(super) fn serve_backlog(&mut self) {
        if self.burst_backlog.is_empty() || self.pass_frames >= FRAMES_PER_TICK {
            return;
        }
        let budget = FRAMES_PER_TICK - self.pass_frames;
        let bytes = core::mem::take(&mut self.burst_backlog);
        // `None`: the device reset (and rebooted, its queue lost).
        if let Some(done) = self.serve_host(Sender::Burst, |handler, link| {
            link.receive_frames(&bytes, budget, handler, |_| {})
        }) {
            self.pass_frames += done.frames;
            self.burst_backlog = bytes[done.consumed..].to_vec();
        }
    }

    /// Host traffic goes through the twin's handler (which acts out how the device is used) on
    /// the sender's link, on the core's clock: each frame costs link work, flash operations
    /// stall the core, and a stall that reaches the watchdog resets the device (`None`: no
    /// answer). A `ClearFault` among it repairs the injected fault afterwards.
    fn serve_host<R>(
        &mut self,
        sender: Sender,
        serve: impl FnOnce(&mut TwinHandler<'_>, &mut Link) -> R,
    ) -> Option<R> {
        let link = match sender {
            Sender::Client => &mut self.link,
            Sender::Burst => &mut self.burst_link,
        };
        let frames_before = frames_seen(link);
        let mut core = CoreWork {
            now_us: self.now_us,
            frame_cost_us: self.options.plant.frame_cost_us.round() as u64,
            handled: 0,
            reset: false,
            bridge_safe_at_us: None,
        };
        let mut repair = false;
        let result = serve(
            &mut TwinHandler {
                device: &mut self.device,
                motor: &mut self.hardware.motor,
                pwm: &self.pwm,
                slp: &self.slp,
                watchdog: &self.watchdog,
                plant: &mut self.plant,
                gauge_rng: &mut self.gauge_rng,
                cutter: &self.cutter,
                traced_gauge: &self.traced_gauge,
                options: &self.options,
                run_started: &mut self.run_started_us,
                truths: &self.truths,
                repair: &mut repair,
                flash: &self.flash,
                core: &mut core,
            },
            link,
        );
        // Frames that never reached the handler (retries answered from memory, broken frames)
        // cost link work too.
        let unhandled = (frames_seen(link) - frames_before).saturating_sub(core.handled);
        core.now_us += u64::from(unhandled) * core.frame_cost_us;
        let deadline_us = self.watchdog.deadline_us();
        // The device put the bridge safe before a flash operation: from then on the plant runs
        // with it so.
        if let Some(at_us) = core.bridge_safe_at_us {
            self.advance_to(at_us.min(deadline_us));
            self.bridge = self.bridge_inputs();
        }
        if core.reset || core.now_us >= deadline_us {
            self.advance_to(deadline_us);
            // A power cut during a flash operation, or the watchdog.
            let reason = if self.flash.is_cut() {
                ResetReason::PowerOn
            } else {
                ResetReason::Watchdog
            };
            self.reset_by(reason);
            return None;
        }
        self.advance_to(core.now_us);
        if sender == Sender::Client {
            self.last_request_us = self.now_us;
        }
        if repair {
            self.repair();
        }
        Some(result)
    }
}

/// Who sends host traffic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sender {
    /// The real client (a test, or the host on the serial port).
    Client,
    /// The other host's bursts.
    Burst,
}

/// Frames a link has taken so far, intact or not.
fn frames_seen(link: &Link) -> u32 {
    let frames = link.stats().frames;
    frames.frames_ok + frames.frames_dropped
}

/// The core's clock during one pass of link work.
struct CoreWork {
    now_us: u64,
    frame_cost_us: u64,
    /// Requests handed to the handler.
    handled: u32,
    /// The watchdog fired: nothing after it happens.
    reset: bool,
    /// When the device first put a driven bridge safe in this pass (before a flash operation).
    bridge_safe_at_us: Option<u64>,
}

/// The device as the link sees it inside the twin, acting out how the device is used: a freshly
/// cut gauge is under the prongs when a run starts; the prongs are out of it (the head has moved
/// on) for a reset or a self-test. Each request costs a frame's link work and stalls the core
/// for the flash operations it does.
struct TwinHandler<'a> {
    device: &'a mut TwinDevice,
    /// The motor driver, which the device puts safe before writing flash.
    motor: &'a mut TwinMotor,
    pwm: &'a FakePwm,
    slp: &'a FakeOutput,
    watchdog: &'a SimWatchdog,
    plant: &'a mut Plant,
    gauge_rng: &'a mut Rng,
    cutter: &'a Cutter,
    traced_gauge: &'a TracedGaugeSlot,
    options: &'a TwinOptions,
    run_started: &'a mut Option<u64>,
    truths: &'a TruthLog,
    repair: &'a mut bool,
    flash: &'a FlashClock,
    core: &'a mut CoreWork,
}

impl TwinHandler<'_> {
    /// The device handles `request` on the core's clock; `None` if its watchdog reset it first.
    fn timed(&mut self, request: &Request) -> Option<Response> {
        let core = &mut *self.core;
        if core.reset {
            return None;
        }
        core.handled += 1;
        core.now_us += core.frame_cost_us;
        let driven = self.pwm.duty() > 0.0 && self.slp.is_high();
        self.watchdog.begin(core.now_us);
        let response = WithMotor {
            device: &mut *self.device,
            motor: &mut *self.motor,
        }
        .handle(request);
        let handled_at_us = core.now_us;
        core.now_us = self.watchdog.end();
        if driven && !(self.pwm.duty() > 0.0 && self.slp.is_high()) {
            // Before any flash operation of this request.
            core.bridge_safe_at_us.get_or_insert(handled_at_us);
        }
        core.reset = self.flash.is_cut() || core.now_us >= self.watchdog.deadline_us();
        (!core.reset).then_some(response)
    }
}

impl Handler for TwinHandler<'_> {
    fn host_activity(&mut self) {
        if !self.core.reset {
            self.device.host_activity();
        }
    }

    fn handle(&mut self, request: &Request) -> Response {
        // After a watchdog reset the answer is never sent: any will do.
        let Some(response) = self.timed(request) else {
            return Response::Ok;
        };
        if response != Response::Ok {
            return response;
        }
        match request {
            Request::Run(params) => {
                match self.traced_gauge.get() {
                    Some((geometry, cut)) => self.plant.place_gauge_of(geometry, cut),
                    None => self.plant.place_gauge(self.cutter.cut(self.gauge_rng)),
                }
                let run_id = self.device.controller().run_id();
                self.truths.record(run_id, self.plant.truth_um(params));
                if self.options.fault == Some(InjectedFault::NoInset) {
                    self.plant.lift_prongs();
                }
                *self.run_started = Some(self.core.now_us);
            }
            // The head has moved away from the last gauge: the prongs turn freely back to zero.
            Request::Reset | Request::SelfTest => self.plant.lift_prongs(),
            // Whoever clears a fault is taken to have fixed its cause (put the magnet back,
            // removed the short, ...): the injected fault is gone from now on.
            Request::ClearFault => *self.repair = true,
            _ => {}
        }
        response
    }
}
