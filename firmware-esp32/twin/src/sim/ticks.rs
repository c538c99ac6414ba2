//! Simulated time: the control ticks on the core's clock, each one the firmware's step with the
//! plant integrated up to it under the bridge as the firmware last left it, and how far the twin
//! may run ahead of the host.

use kerfmeter_firmware::controller::PERIOD_US;
use kerfmeter_firmware::watchdog::{WATCHDOG_TIMEOUT_MS, Watchdog};

use super::{MAX_LEAD_MS, Twin};
use crate::options::InjectedFault;
use crate::plant::Bridge;

impl Twin {
    /// Ticks the twin may run before it must wait for the host (lock-step mode): those that
    /// start before [`MAX_LEAD_MS`] past the host's last answer.
    pub fn lead_ticks(&self) -> u64 {
        let limit = self.last_request_us + MAX_LEAD_MS * 1000;
        let host_silent =
            self.options.fault == Some(InjectedFault::HostSilent) && self.fault_struck;
        if host_silent {
            return u64::MAX;
        }
        match limit.checked_sub(self.next_tick_us()) {
            Some(lead_us) if lead_us > 0 => (lead_us - 1) / PERIOD_US + 1,
            _ => 0,
        }
    }

    /// Run the plant until `t_us` with the bridge held; the core's clock moves there.
    pub(super) fn advance_to(&mut self, t_us: u64) {
        if t_us > self.now_us {
            self.plant.run_us(&self.bridge, t_us - self.now_us);
            self.now_us = t_us;
        }
    }

    /// The next pass of the board's control loop, when the core gets to it: the plant runs
    /// until then, then sensors → firmware tick (feeding the watchdog) → bridge, then the link's
    /// work on the other host's queued frames, within the pass's budget. (The client's frames
    /// are served when it sends them: [`receive`](Self::receive).)
    pub fn tick(&mut self) {
        let tick_us = self.ticks.start_tick(self.now_us);
        self.step_at(tick_us);
        self.pass_frames = 0;
        self.serve_backlog();
    }

    /// The control step of a pass, at `tick_us`: the plant runs until then, then sensors →
    /// firmware tick (feeding the watchdog) → bridge.
    fn step_at(&mut self, tick_us: u64) {
        self.advance_to(tick_us);
        self.strike_faults();
        let hub_cw_deg = self.plant.hub_cw_deg();
        let magnet_cw_deg = if self.magnet_on_motor_shaft {
            hub_cw_deg * self.plant.params().gear_ratio
        } else {
            hub_cw_deg
        };
        let cw = self.encoder_errors.measured_deg(magnet_cw_deg);
        self.hardware.encoder.bus_mut().set_angle_deg(cw);
        self.flt
            .set_high(!self.flt_injected && !self.plant.driver_fault());
        // The conversion started at the end of the last tick, as the board collects it (the
        // first tick after boot has none yet).
        let readings = self.conversions.read(&mut self.adc);
        let out = self.hardware.tick(
            self.now_us,
            readings.cs_mv,
            readings.supply_v,
            &mut self.device,
        );
        if readings.restart {
            // A conversion that never finished: the board opens its driver again.
            self.device.note_adc_restart();
            self.adc.restart();
        }
        // The next conversion, started just after the output was applied: it sees the bridge
        // as it was until now. The pins are sampled every tick (their filters run on).
        let sensed = self.sense.sample(
            &self.plant.electrical(),
            self.now_us,
            self.over_current,
            &mut self.rng,
        );
        self.adc.set_pins(sensed);
        self.conversions.start_next(&mut self.adc);
        // The control tick, and only it, feeds the watchdog at the normal timeout.
        self.watchdog.begin(self.now_us);
        self.watchdog.feed_ms(WATCHDOG_TIMEOUT_MS);
        self.watchdog.end();
        // The board reports when each step's work ended; the twin does not model the step's own
        // execution time (crate docs), so its steps end as they start and `Status` shows a
        // longest step of 0 µs here.
        self.device.step_finished(self.now_us);
        debug_assert_eq!(out.is_safe(), self.motor_torque_free());
        self.bridge = self.bridge_inputs();
    }

    /// The bridge's inputs as the pins hold them, in the jam frame.
    pub(super) fn bridge_inputs(&self) -> Bridge {
        let cw_sign = if self.dir.is_high() { 1.0 } else { -1.0 };
        let jam_sign = match self.options.gauge.jam_direction {
            kerfmeter_protocol::JamDirection::Clockwise => 1.0,
            kerfmeter_protocol::JamDirection::CounterClockwise => -1.0,
        };
        // Swapped motor leads turn the hub against `DIR`.
        let leads_sign = if self.options.motor_leads_swapped {
            -1.0
        } else {
            1.0
        };
        Bridge {
            duty: f64::from(self.pwm.duty()),
            direction: cw_sign * jam_sign * leads_sign,
            awake: self.slp.is_high(),
        }
    }

    /// Run `n` ticks.
    pub fn advance_ticks(&mut self, n: u64) {
        for _ in 0..n {
            self.tick();
        }
    }

    /// Run every tick that starts by `t_us` (real-time pacing).
    pub fn advance_until(&mut self, t_us: u64) {
        while self.next_tick_us() <= t_us {
            self.tick();
        }
    }
}
