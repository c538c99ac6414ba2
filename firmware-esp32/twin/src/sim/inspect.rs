//! What a test or the serve loop reads of the twin (its clock, plant, device, flash, truths and
//! options; whether the motor is safe or driven), and what a person does to it by hand: a traced
//! gauge placed under the prongs, the magnet moved to the motor shaft, the hub turned.

use kerfmeter_firmware::board::current::MotorCurrent;
use kerfmeter_firmware::fakes::flash::FlashClock;

use super::{Twin, TwinDevice};
use crate::gauge_trace::{GaugeTraceError, TracedGaugeSlot};
use crate::options::TwinOptions;
use crate::plant::{Cutter, GaugeCut, Plant};
use crate::traced::Segment;
use crate::truth::TruthLog;

impl Twin {
    /// The gauge a cutter cut around `at_mm` on its bed, as the laser traced it (`segments`, a
    /// cutter twin's record of its segments, `kerfmeter::grbl::twin::CutterRecord`), goes under the
    /// prongs, which come down over `at_mm`: every run from now on measures it (its physical
    /// pitch, sense, holes and centre, from the trace; its kerf, contact and the machine's
    /// repeatability from this twin's [`Cutter`]), while the device keeps the nominal geometry
    /// its `RunParams` give it. The cut drawn for it, or why no gauge the device can measure was
    /// cut there ([`crate::gauge_trace`]); a refused trace leaves the gauges as they were.
    pub fn place_traced_gauge(
        &mut self,
        segments: &[Segment],
        at_mm: [f64; 2],
    ) -> Result<GaugeCut, GaugeTraceError> {
        let cutter = self.cutter;
        self.place_traced_gauge_cut_by(segments, at_mm, &cutter)
    }

    /// [`place_traced_gauge`](Self::place_traced_gauge), the gauge cut by `cutter` (a cutter
    /// twin's, from its options' kerf, `kerfmeter::grbl::twin::CutterOptions::kerf`) instead of this
    /// twin's own.
    pub fn place_traced_gauge_cut_by(
        &mut self,
        segments: &[Segment],
        at_mm: [f64; 2],
        cutter: &Cutter,
    ) -> Result<GaugeCut, GaugeTraceError> {
        self.traced_gauge.place(
            segments,
            &self.options.gauge,
            at_mm,
            cutter,
            &mut self.gauge_rng,
        )
    }

    /// This twin's traced-gauge slot (see [`place_traced_gauge`](Self::place_traced_gauge)).
    pub fn traced_gauges(&self) -> &TracedGaugeSlot {
        &self.traced_gauge
    }

    /// This twin, its runs measuring whatever gauge `slot` holds (shared with its caller).
    pub fn with_traced_gauges(self, slot: TracedGaugeSlot) -> Self {
        Self {
            traced_gauge: slot,
            ..self
        }
    }

    /// How many times the device rebooted ([`reboot`](Self::reboot) or its watchdog).
    pub fn reboots(&self) -> u32 {
        self.boots
    }

    /// The flash's clock: its erases and writes so far (for checks).
    pub fn flash(&self) -> &FlashClock {
        &self.flash
    }

    /// Simulated time on the core's clock, µs: the last tick, or the end of the link work
    /// (frames, flash stalls) after it. The plant has run until it.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// When the next control tick will run, µs (later if more link work comes first).
    pub fn next_tick_us(&self) -> u64 {
        self.ticks.next_tick_us(self.now_us)
    }

    /// The plant (for checks).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The device (for checks).
    pub fn device(&self) -> &TwinDevice {
        &self.device
    }

    /// The next ADC conversion started never finishes, as when the ESP32-C3's ADC misses a
    /// one-shot start pulse: the firmware gives it up after three ticks and opens the ADC again
    /// (`board::conversion`), which `GetDiagnostics` counts (`adc_restarts`).
    pub fn stall_next_adc_conversion(&mut self) {
        self.adc.stall_next();
    }

    /// ADC conversions that stalled since boot.
    pub fn adc_stalls(&self) -> u32 {
        self.adc.stalls()
    }

    /// The firmware's current-sense conversion, its learnt offset included (for checks).
    pub fn current_sense(&self) -> &MotorCurrent {
        self.hardware.current()
    }

    /// The truth of each run started (shared: a clone follows this twin).
    pub fn truths(&self) -> &TruthLog {
        &self.truths
    }

    /// The options it was built with.
    pub fn options(&self) -> &TwinOptions {
        &self.options
    }

    /// Move the encoder's magnet to the motor shaft (`true`: it turns `gear_ratio` times per hub
    /// turn) or back to the output shaft. The device's configuration must say so too
    /// (`encoder_placement`): this is the mechanics, not the firmware.
    pub fn set_magnet_on_motor_shaft(&mut self, on_motor: bool) {
        self.magnet_on_motor_shaft = on_motor;
    }

    /// Someone turns the hub by hand to `cw_deg` (clockwise-positive seen from above), prongs
    /// lifted ([`Plant::turn_hub_by_hand`]); between requests, with the motor at rest.
    pub fn turn_hub_by_hand(&mut self, cw_deg: f64) {
        self.plant.turn_hub_by_hand(cw_deg);
    }

    /// True when the motor bridge is in its safe state: duty 0 and the driver asleep (either
    /// alone leaves the bridge able to brake or to drive on the next write).
    pub fn motor_safe(&self) -> bool {
        self.pwm.duty() == 0.0 && !self.slp.is_high()
    }

    /// True when the bridge drives the motor: the driver awake at a duty above 0 (what a test
    /// that a run drives it asks; a bridge braking awake at duty 0 is neither this nor safe).
    pub fn motor_driven(&self) -> bool {
        self.pwm.duty() > 0.0 && self.slp.is_high()
    }

    /// True when the bridge applies no drive torque: duty 0 (braking) or the driver asleep, as
    /// the controller's [`MotorOutput::is_safe`](kerfmeter_firmware::motor::MotorOutput::is_safe)
    /// says of its output.
    pub(super) fn motor_torque_free(&self) -> bool {
        self.pwm.duty() == 0.0 || !self.slp.is_high()
    }
}
