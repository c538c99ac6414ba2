//! Kerfmeter's digital twin (std): the device's real firmware on the host, driving a physics
//! model of what it drives, for tests, for the host's `--sim` and for the `kerfmeter-twin`
//! binary.
//!
//! - [`sim`]: the [`Twin`] — the firmware's own link, request handler, controller, AS5048A and G2
//!   drivers and control tick, wired to the firmware's fake peripherals (`kerfmeter_firmware::fakes`)
//!   and lock-stepped with the [`plant`]; named fault injection.
//! - [`options`]: [`TwinOptions`], the one description of a twin, validated here.
//! - [`serve`](mod@serve): one serve loop for a twin or a bare link on any `Read + Write` port.
//! - [`timing`]: when the core runs its ticks (the board's ticker, jitter, late ticks), the
//!   watchdog they feed, and the host's bursts of frames.
//! - [`truth`]: [`TruthLog`], the truth of each run (what an ideal device reads on its gauge).
//! - [`encoder`]: [`encoder::EncoderErrors`], the AS5048A's non-linearity and the magnet's
//!   eccentricity, added to the hub's angle before the fake chip reads it.
//! - [`sense`]: what the firmware's ADC channels read: the G2's current sense as the chip produces
//!   it, and the motor supply through its divider.
//! - [`pty`]: [`PtyTwin`], a twin served on a pseudo-terminal by a thread, whose client side is an
//!   ordinary serial port.
//! - [`study`]: many twins in-process: the robustness sweep and the paper's fit study.
//! - [`traced`]: what a cutter's laser traced ([`traced::Segment`]), as the cutter twin (a
//!   simulated GRBL 1.1 laser cutter, in the `kerfmeter` library's `grbl::twin`, feature `sim`)
//!   records it.
//! - [`gauge_trace`]: the gauge a cutter cut, recovered from what its laser traced (spiral
//!   centre, pitch and sense, holes), for the device twin to measure
//!   ([`Twin::place_traced_gauge`]); refused with the reason when the device could not.
//!
//! # What the twin models
//!
//! A twin must be as unkind as hardware: one that hands the firmware a perfect world passes
//! firmware a real board fails. So every physical parameter has a realistic default, with its
//! source and plausible range ([`plant::PlantParams`]), and can be set from outside.
//!
//! - The supply: its source resistance, so the bus sags by the average supply current (the duty
//!   times the motor current); the G2's under-voltage lockout (outputs off, FLT low, released
//!   0.3 V above the threshold), which the firmware sees as `DriverFault`.
//! - The motor and G2 bridge: back-EMF, winding resistance, braking at duty 0, coasting asleep;
//!   the driver's current limiting (chopping: the current held at the limit, a shorter drive
//!   phase); gearbox ratio, efficiency and stick–slip (Karnopp) friction.
//! - The winding's temperature: I²R heating against a thermal resistance to ambient, and the
//!   copper's resistance rising 0.39 %/°C with it (less current, so less torque, per duty).
//! - The gauge as a real cutter cuts it ([`plant::GaugeCut`], drawn per gauge from the seed): the
//!   hole play with each hole's centre displaced by the cutter's repeatability and the hub's axis
//!   off the gauge's centre (the head returning over it), the first prong to touch its face
//!   dragging the inset; the inset's friction on the table; the spiral's gap with a kerf tapered
//!   through the sheet, so that the contact spreads down the face (quadratic, then linear at the
//!   face's stiffness), self-locking; the contact's stiffness and μ spread gauge to gauge; a
//!   prong slipping out of its hole; prongs let down off the holes riding the gauge's face until
//!   they drop in (a hub whose zero is a motor turn out).
//! - The encoder: the AS5048A's SPI protocol (parity, error flag and register, pipelined
//!   replies), its integral non-linearity (1st–3rd harmonics) and a magnet's eccentricity (a
//!   once-per-turn error), drawn once per twin, relative to the zero the user set; 14-bit
//!   quantisation and a few LSB of noise; the chip-select setup and hold times each frame
//!   carries. The magnet sits on the output shaft, or on the motor shaft
//!   (`Twin::set_magnet_on_motor_shaft`, turning `gear_ratio` times per hub turn;
//!   `TwinOptions::encoder_on_motor_shaft` boots a twin so configured in its flash).
//! - The current sense as the G2 produces it: the current only in the drive phase of each 20 kHz
//!   PWM period (about zero while braking or chopping), through the board's RC filter on the pin
//!   (`cs_filter_tau_us`, 1 ms by default; 0 removes it), sampled once per tick, one conversion
//!   behind as the board does, at an instant that drifts through the period; gain error, the
//!   offset's spread from board to board, noise and the 1 mV steps of the calibrated ADC. The firmware gets the pin's millivolts and does
//!   the rest (its `board::current` conversion, inside the shared control tick).
//! - The supply sense: the bus through a divider into the ADC, with gain error, noise and 1 mV
//!   steps (handed to the firmware, which scales the duty by it).
//! - The configuration flash: NOR rules (erase to 0xFF, writes only clear bits), kept across a
//!   reboot, opened at boot under the board's partition policy. Erases and writes take their
//!   time (`flash_erase_ms`, `flash_write_ms`), stalling the core: no tick runs meanwhile.
//! - The core's timing: ticks at the board's ticker schedule plus a jitter (`tick_jitter_us`)
//!   and occasional late ticks (`late_ticks_per_s`, `late_tick_ms`); every frame's link work
//!   costs core time (`frame_cost_us`) in the same loop as the tick, at most the firmware's
//!   `link::FRAMES_PER_TICK` frames a pass, the rest queued; a host that sends bursts of
//!   status requests with its own (`host_burst_frames`, `host_burst_period_ms`); the board's
//!   watchdog, fed by each tick and lengthened by the firmware around each flash operation as on
//!   the board, which resets the chip when a stall reaches it, the operation under way left
//!   torn.
//! - The cutter: a bias of the kerf where this twin's gauges are cut (drawn once per twin) and a
//!   gauge-to-gauge Gaussian spread of the kerf. A gauge the cutter twin traced keeps the
//!   geometry it was traced with (pitch, sense, holes, centre): a wrong G-code is measured wrong.
//! - The truth of a run ([`plant::Plant::truth_um`]): the closure of the spiral at which this
//!   gauge's contact carries the run's target torque; the holes', prongs' and encoder's errors
//!   are the device's to correct, not part of it.
//! - Faults, by name ([`InjectedFault`]): encoder parity errors, magnet lost, MISO stuck, no inset,
//!   motor disconnected, driver FLT, over-current, host silent, prong slip.
//!
//! Time is simulated on the core's clock, deterministic for a seed: a control tick about every
//! 1 ms, when the core gets to it, and the plant integrated over whatever time passes between
//! two ticks with the bridge held ([`plant::Plant::run_us`]); served, it runs ahead of the host
//! in lock-step or follows the wall clock ([`Pace`]).
//!
//! # What it does not model
//!
//! The motor's inductance (its L/R is far below a tick, though above a PWM period: the current is
//! taken as continuous, with no ripple); the bus capacitance (the bus follows the load at once, so
//! a supply that sags into the lockout stays locked while the load is asked for, rather than
//! hiccuping); the current-sense waveform between two samples (the bridge's state at the end of
//! the last tick stands for the whole tick); the G2's other fault, a short circuit (the 18v17
//! reports no over-temperature on FLT); the control step's own execution time (a tick takes no
//! core time, so the ticks that catch up after a late one come at once), the chip's boot time,
//! and the USB link's own latency and flow control; the encoder's register writes and a magnet
//! tilted or at the wrong air gap; the inset's inertia, and its sliding within the spiral's gap
//! before the gap closes (it turns about the gauge's centre); a hub axis tilted against the
//! sheet; a hole out of round, or a kerf that varies around the spiral rather than through the
//! sheet; the zero the user sets being quantised to one LSB.

pub mod adc;
pub mod encoder;
pub mod gauge_trace;
pub mod options;
pub mod plant;
pub mod pty;
pub mod sense;
pub mod serve;
pub mod sim;
pub mod study;
pub mod timing;
pub mod traced;
pub mod truth;

pub use options::{InjectedFault, InvalidOptions, TwinOptions, UnknownFault};
pub use pty::{MotorEdge, PtyTwin, StartError};
pub use serve::{LinkServer, Pace, Served, serve};
pub use sim::Twin;
pub use truth::TruthLog;
