//! `kerfmeter-bench-rv32`: how many RV32IMC instructions the firmware's hot path takes.
//!
//! A bare-metal program for qemu's `virt` machine (`qemu-system-riscv32 -machine virt -bios none
//! -icount shift=0`) that links the real `kerfmeter-firmware` library, built for
//! `riscv32imc-unknown-none-elf` (no FPU: every `f32` operation is a soft-float library call, as
//! on the ESP32-C3) with the firmware image's profile. It measures, with the `minstret` and
//! `mcycle` counters read just before and just after each call:
//!
//! 1. the kerf solve, [`kerf_from_angle`] (the gauge model in `kerfmeter-protocol`) on the paper's
//!    gauge, at several hub angles;
//! 2. one [`Controller::step`] in every state a run passes through (Idle, Engaging, Ramping,
//!    Jammed, Releasing, Done, Resetting), driven by synthetic encoder angles through complete runs
//!    to several jam angles, with the encoder diagnostics supplied every
//!    [`DIAGNOSTICS_PERIOD_TICKS`] ticks as on the board;
//! 3. the parts a Ramping step is made of, to show where its instructions go: [`kerf_step`] (one
//!    step of the kerf solve, the ramp's inset angle each tick: one `asinf` in [`play_deg`]),
//!    [`torque_for_force_nm`], adding an angle to a full [`SlopeWindow`] and reading its
//!    least-squares slope (running integer sums: both O(1)), and the hold's median over a full
//!    [`HoldWindow`] (once per run, when the hold ends, with the kerf solve).
//!
//! The bracket's own cost (measured with nothing inside it) is subtracted. Under `-icount
//! shift=0` qemu counts retired instructions exactly; its `mcycle` is the same instruction count
//! (qemu has no pipeline model), so cycles on a real core follow from an assumed CPI. The program
//! checks the counter's exactness on a loop of known length before measuring.
//!
//! Output, one record a line on the virt UART (parsed by `cargo xtask bench-step`):
//!
//! ```text
//! CAL overhead=<instret> loop=<instret> expected=<instret>
//! KERF angle_deg=<deg> kerf_um=<µm> converged=<bool>
//! STAT kerf <name> calls=<n> sum=<instret> min=<instret> max=<instret> cycles_sum=<n> cycles_min=<n> cycles_max=<n>
//! STAT step <state> calls=… (same fields)
//! STAT part <name> calls=… (same fields)
//! RUN hold_deg=<deg> kerf_um=<µm> flags=<bits> ticks=<n>
//! DONE
//! ```
//!
//! The program ends through qemu's `sifive_test` device: exit status 0 on success, non-zero
//! after a panic or a trap.

#![no_std]
#![no_main]

use core::arch::asm;
use core::fmt::{self, Write};
use core::hint::black_box;
use core::panic::PanicInfo;

use kerfmeter_firmware::controller::{
    Controller, DiagnosticsReading, Inputs, PERIOD_US, WINDING_CHECK_READINGS,
};
use kerfmeter_firmware::hardware::DIAGNOSTICS_PERIOD_TICKS;
use kerfmeter_firmware::jam::{HOLD_TICKS, HoldWindow, JAM_WINDOW_TICKS, SlopeWindow};
use kerfmeter_protocol::spiral::{kerf_from_angle, kerf_step, play_deg, torque_for_force_nm};
use kerfmeter_protocol::{DeviceConfig, GaugeGeometry, RunParams, RunState};

/// qemu virt's NS16550A UART: transmit holding register.
const UART_THR: *mut u8 = 0x1000_0000 as *mut u8;
/// qemu virt's NS16550A UART: line status register.
const UART_LSR: *const u8 = 0x1000_0005 as *const u8;
/// LSR bit: the transmit holding register is empty.
const UART_LSR_THR_EMPTY: u8 = 0x20;
/// qemu virt's `sifive_test` device: writing to it ends qemu.
const SIFIVE_TEST: *mut u32 = 0x0010_0000 as *mut u32;
/// `sifive_test`: exit with status 0.
const SIFIVE_TEST_PASS: u32 = 0x5555;
/// `sifive_test`: exit with the status in the upper 16 bits.
const SIFIVE_TEST_FAIL: u32 = 0x3333;

/// Hub angles of the kerf-solve measurement, degrees (zero kerf is ≈ 4.5°; 155° is the paper
/// gauge's disengage angle).
const KERF_ANGLES_DEG: [f32; 8] = [5.0, 10.0, 20.0, 45.0, 90.0, 120.0, 150.0, 160.0];
/// Kerf solves measured per angle.
const KERF_CALLS_PER_ANGLE: u32 = 100;

/// Calls measured per part of the step.
const PART_CALLS: u32 = 100;

/// The jam angles of the measured runs, degrees (one run each).
const HOLD_ANGLES_DEG: [f32; 4] = [20.0, 45.0, 90.0, 130.0];
/// A light run on a 24 V supply, jamming at this angle: its jam's duty is too low for the
/// current sense, so the run ends with the winding check after the probe (its ticks, the
/// estimate's among them, are in the figures).
const LIGHT_HOLD_DEG: f32 = 60.0;
/// The light run's force, N, and supply, V.
const LIGHT_FORCE_N: f32 = 30.0;
const LIGHT_SUPPLY_V: f32 = 24.0;
/// Idle steps before each run.
const IDLE_TICKS: u32 = 500;
/// Done steps after each run.
const DONE_TICKS: u32 = 50;
/// The host's keep-alive period (a request between steps, outside the measurement), ticks.
const KEEPALIVE_TICKS: u32 = 100;
/// Hub motion while engaging, degrees per tick (60 °/s, the engaging speed target).
const ENGAGE_DEG_PER_TICK: f32 = 0.06;
/// Hub motion while ramping towards the jam, degrees per tick (50 °/s).
const RAMP_DEG_PER_TICK: f32 = 0.05;
/// Hub motion while backing off after the release, degrees per tick (30 °/s, the back-off's
/// speed target), until the prongs meet the holes' far faces [`BACK_OFF_SHORT_DEG`] short of
/// both sides of the model's play: a measured play the result takes.
const BACK_OFF_DEG_PER_TICK: f32 = 0.03;
/// How much shorter than the model's two sides of play the scripted back-off turn is, degrees.
const BACK_OFF_SHORT_DEG: f32 = 1.0;
/// A run that has not reached Done after this many steps has gone wrong.
const MAX_RUN_TICKS: u32 = 9_000;
/// A reset that has not reached Idle after this many steps has gone wrong.
const MAX_RESET_TICKS: u32 = 500;
/// One AS5048A count, degrees.
const LSB_DEG: f32 = 360.0 / 16384.0;
/// Encoder noise added to the synthetic angle, in counts, cycling with the tick.
const NOISE_COUNTS: [i32; 4] = [0, 1, 0, -1];
/// The CORDIC magnitude reported with the periodic diagnostics (mid-band).
const DIAG_MAGNITUDE: u16 = 4000;
/// Loop iterations of the counter's calibration.
const CAL_LOOP_ITERATIONS: u32 = 1000;
/// Instructions the calibration loop retires: `li` + `CAL_LOOP_ITERATIONS` × (`addi` + `bnez`).
const CAL_LOOP_INSTRUCTIONS: u32 = 1 + 2 * CAL_LOOP_ITERATIONS;

/// The step states measured, in report order.
const STATES: [&str; 7] = [
    "idle",
    "engaging",
    "ramping",
    "jammed",
    "releasing",
    "done",
    "resetting",
];

/// Blocking writer to the virt UART.
struct Uart;

impl Write for Uart {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for byte in s.bytes() {
            // SAFETY: the NS16550A's registers on qemu virt; byte accesses, no other user.
            unsafe {
                while core::ptr::read_volatile(UART_LSR) & UART_LSR_THR_EMPTY == 0 {}
                core::ptr::write_volatile(UART_THR, byte);
            }
        }
        Ok(())
    }
}

macro_rules! say {
    ($($arg:tt)*) => {{
        // The UART writer never fails.
        let _ = writeln!(Uart, $($arg)*);
    }};
}

/// End qemu with `status` (0 = success) through the `sifive_test` device.
fn exit(status: u16) -> ! {
    let word = if status == 0 {
        SIFIVE_TEST_PASS
    } else {
        (u32::from(status) << 16) | SIFIVE_TEST_FAIL
    };
    // SAFETY: the sifive_test device on qemu virt; the write ends the emulation.
    unsafe { core::ptr::write_volatile(SIFIVE_TEST, word) };
    loop {
        core::hint::spin_loop();
    }
}

/// Fail the benchmark with a message.
fn fail(args: fmt::Arguments) -> ! {
    say!("FAIL {args}");
    exit(2)
}

/// Retired instructions and cycles, low 32 bits (every measured span is far shorter than 2³²).
#[derive(Clone, Copy)]
struct Counters {
    instret: u32,
    cycles: u32,
}

impl Counters {
    /// Read `minstret`, then `mcycle`. The asm is a compiler barrier (it may touch memory), so no
    /// memory access of the measured code moves across it.
    #[inline(always)]
    fn read() -> Self {
        let instret: u32;
        let cycles: u32;
        // SAFETY: reading machine-mode counters; the program runs in machine mode.
        unsafe {
            asm!(
                "csrr {i}, minstret",
                "csrr {c}, mcycle",
                i = out(reg) instret,
                c = out(reg) cycles,
                options(nostack, preserves_flags),
            );
        }
        Self { instret, cycles }
    }

    /// `self − earlier`.
    fn since(self, earlier: Self) -> Self {
        Self {
            instret: self.instret.wrapping_sub(earlier.instret),
            cycles: self.cycles.wrapping_sub(earlier.cycles),
        }
    }

    /// `self − overhead`, never below zero.
    fn less(self, overhead: Self) -> Self {
        Self {
            instret: self.instret.saturating_sub(overhead.instret),
            cycles: self.cycles.saturating_sub(overhead.cycles),
        }
    }
}

/// Run `f(input)` between two counter reads. `input` is passed through `black_box` after the
/// first read and the result through `black_box` before the second, so the compiler can neither
/// hoist the work above the bracket nor sink it below.
#[inline(always)]
fn measure<T, R>(input: T, f: impl FnOnce(T) -> R) -> (R, Counters) {
    let start = Counters::read();
    let output = black_box(f(black_box(input)));
    let end = Counters::read();
    (output, end.since(start))
}

/// Mean, minimum and maximum of measured calls.
#[derive(Clone, Copy)]
struct Stat {
    calls: u32,
    sum: u64,
    min: u32,
    max: u32,
    cycles_sum: u64,
    cycles_min: u32,
    cycles_max: u32,
}

impl Stat {
    const EMPTY: Self = Self {
        calls: 0,
        sum: 0,
        min: u32::MAX,
        max: 0,
        cycles_sum: 0,
        cycles_min: u32::MAX,
        cycles_max: 0,
    };

    fn add(&mut self, c: Counters) {
        self.calls += 1;
        self.sum += u64::from(c.instret);
        self.min = self.min.min(c.instret);
        self.max = self.max.max(c.instret);
        self.cycles_sum += u64::from(c.cycles);
        self.cycles_min = self.cycles_min.min(c.cycles);
        self.cycles_max = self.cycles_max.max(c.cycles);
    }

    fn print(&self, group: &str, name: &str) {
        if self.calls == 0 {
            fail(format_args!("no {group} {name} call was measured"));
        }
        say!(
            "STAT {group} {name} calls={} sum={} min={} max={} cycles_sum={} cycles_min={} cycles_max={}",
            self.calls,
            self.sum,
            self.min,
            self.max,
            self.cycles_sum,
            self.cycles_min,
            self.cycles_max
        );
    }
}

/// The measured state of a step, by the state the controller was in when it was called.
fn state_index(state: RunState) -> Option<usize> {
    match state {
        RunState::Idle => Some(0),
        RunState::Engaging => Some(1),
        RunState::Ramping => Some(2),
        RunState::Jammed => Some(3),
        RunState::Releasing => Some(4),
        RunState::Done => Some(5),
        RunState::Resetting => Some(6),
        RunState::SelfTest | RunState::Fault(_) => None,
    }
}

/// The controller, its clock and the step statistics.
struct StepBench {
    controller: Controller,
    now_us: u64,
    tick: u32,
    overhead: Counters,
    by_state: [Stat; STATES.len()],
    all: Stat,
    /// The duty of the last step's output (the current a step reads is what it drove).
    last_duty: f32,
    /// The supply the steps read, V (varied a little about it).
    supply_v: f32,
}

/// The winding's resistance the default configuration implies, Ω: the benchmark's motor is the
/// one the configuration describes, cold.
fn reference_ohm() -> f32 {
    let c = DeviceConfig::DEFAULT;
    c.torque_per_amp_nm * 12.0 / c.torque_per_duty_nm
}

impl StepBench {
    /// One measured step with the hub at `angle_deg`; the state afterwards.
    fn step(&mut self, angle_deg: f32) -> RunState {
        let diagnostics = self
            .tick
            .is_multiple_of(DIAGNOSTICS_PERIOD_TICKS)
            .then_some(Ok(DiagnosticsReading {
                magnitude: DIAG_MAGNITUDE,
                marginal: false,
            }));
        let supply_v = self.supply_v - 0.1 + 0.02 * (self.tick % 8) as f32;
        let inputs = Inputs {
            angle_deg: Ok(angle_deg),
            diagnostics,
            // What the last output's duty drives through the winding at standstill, so that
            // the winding's estimate at the jam runs as on a motor (and finds it cold).
            current_a: Some(self.last_duty * supply_v / reference_ohm()),
            driver_fault: false,
            // A measured supply, as a board with its supply sense wired has: the filter and the
            // duty's scaling are part of every step. Varied a little, like a real reading.
            supply_v: Some(supply_v),
        };
        let before = self.controller.run_state();
        let Some(index) = state_index(before) else {
            fail(format_args!("step in unexpected state {before:?}"));
        };
        let now_us = self.now_us;
        let controller = &mut self.controller;
        let (output, spent) = measure(inputs, |inputs| controller.step(now_us, &inputs));
        self.last_duty = if output.awake { output.duty } else { 0.0 };
        let spent = spent.less(self.overhead);
        self.by_state[index].add(spent);
        self.all.add(spent);

        self.now_us += PERIOD_US;
        self.tick += 1;
        if self.tick.is_multiple_of(KEEPALIVE_TICKS) {
            self.controller.host_activity(self.now_us);
        }
        let after = self.controller.run_state();
        if let RunState::Fault(fault) = after {
            fail(format_args!(
                "the controller faulted ({fault:?}) at tick {} in {before:?}, angle {angle_deg}",
                self.tick
            ));
        }
        after
    }

    /// One run with `params` from zero to a jam at `hold_deg`, through release, then a reset
    /// back to Idle; its ticks in `Jammed` (the hold, the probe, a winding check).
    fn run(&mut self, hold_deg: f32, params: &RunParams) -> u32 {
        for _ in 0..IDLE_TICKS {
            self.step(0.0);
        }
        self.controller.host_activity(self.now_us);
        if let Err(e) = self.controller.start_run(params) {
            fail(format_args!("Run refused: {e:?}"));
        }
        let mut deg = 0.0f32;
        let (mut ticks, mut jammed_ticks) = (0, 0);
        let faces_deg = hold_deg - 2.0 * kerf_from_angle(&params.gauge, hold_deg).play_deg
            + BACK_OFF_SHORT_DEG;
        loop {
            let state = self.step(encoder_deg(deg, self.tick));
            ticks += 1;
            match state {
                RunState::Engaging => deg += ENGAGE_DEG_PER_TICK,
                RunState::Ramping => deg = (deg + RAMP_DEG_PER_TICK).min(hold_deg),
                // The hold, the probe and (on the light run) the winding check.
                RunState::Jammed => jammed_ticks += 1,
                // The release, then the back-off: the hub turns back while pulled.
                RunState::Releasing if self.controller.status().torque_nm < 0.0 => {
                    deg = (deg - BACK_OFF_DEG_PER_TICK).max(faces_deg);
                }
                RunState::Releasing => {}
                RunState::Done => break,
                other => fail(format_args!("unexpected state {other:?} during a run")),
            }
            if ticks > MAX_RUN_TICKS {
                fail(format_args!(
                    "no result after {ticks} ticks (hold {hold_deg}°)"
                ));
            }
        }
        for _ in 0..DONE_TICKS {
            self.step(encoder_deg(deg, self.tick));
        }
        let Some(result) = self.controller.result().copied() else {
            fail(format_args!("Done without a result"));
        };
        // The back-off's stall is one of the steps measured: the play must be the scripted one.
        let scripted_play_deg = (hold_deg - faces_deg) / 2.0;
        if (result.play_deg - scripted_play_deg).abs() > 0.1 {
            fail(format_args!(
                "the back-off did not measure the play: {} against {scripted_play_deg}",
                result.play_deg
            ));
        }
        say!(
            "RUN hold_deg={hold_deg} kerf_um={} flags={:#06x} ticks={ticks} jammed_ticks={jammed_ticks}",
            result.kerf_um,
            result.flags.0
        );

        self.controller.host_activity(self.now_us);
        if let Err(e) = self.controller.start_reset() {
            fail(format_args!("Reset refused: {e:?}"));
        }
        let mut reset_ticks = 0;
        while self.step(0.0) != RunState::Idle {
            reset_ticks += 1;
            if reset_ticks > MAX_RESET_TICKS {
                fail(format_args!("reset did not settle"));
            }
        }
        jammed_ticks
    }
}

/// The encoder's reading of a hub at `deg`: whole counts, plus a count of noise by tick.
fn encoder_deg(deg: f32, tick: u32) -> f32 {
    let counts = (deg / LSB_DEG) as i32 + NOISE_COUNTS[tick as usize % NOISE_COUNTS.len()];
    counts as f32 * LSB_DEG
}

/// The bracket's own cost, and a check that the counter is exact (qemu with `-icount shift=0`).
fn calibrate() -> Counters {
    let mut overhead = Counters {
        instret: u32::MAX,
        cycles: u32::MAX,
    };
    for _ in 0..100 {
        let (_, c) = measure(0u32, |x| x);
        overhead.instret = overhead.instret.min(c.instret);
        overhead.cycles = overhead.cycles.min(c.cycles);
    }
    let start = Counters::read();
    // SAFETY: a register-only countdown loop.
    unsafe {
        asm!(
            "li {n}, {iterations}",
            "2:",
            "addi {n}, {n}, -1",
            "bnez {n}, 2b",
            n = out(reg) _,
            iterations = const CAL_LOOP_ITERATIONS,
            options(nostack, nomem),
        );
    }
    let loop_instret = Counters::read().since(start).instret;
    let bare_start = Counters::read();
    let bare = Counters::read().since(bare_start).instret;
    let counted = loop_instret.wrapping_sub(bare);
    say!(
        "CAL overhead={} loop={counted} expected={CAL_LOOP_INSTRUCTIONS}",
        overhead.instret
    );
    if counted != CAL_LOOP_INSTRUCTIONS {
        fail(format_args!(
            "minstret counted {counted} instructions for a loop of {CAL_LOOP_INSTRUCTIONS}: \
             not exact (run qemu with -icount shift=0)"
        ));
    }
    overhead
}

#[riscv_rt::entry]
fn main() -> ! {
    say!("kerfmeter-bench-rv32: Controller::step and kerf_from_angle on RV32IMC (soft-float)");
    let overhead = calibrate();

    // The kerf solve. The gauge goes through `black_box` so that its constants are not folded
    // into the code (on the device they come with the run's parameters).
    let gauge = black_box(GaugeGeometry::PAPER);
    let mut kerf_all = Stat::EMPTY;
    for angle_deg in KERF_ANGLES_DEG {
        let mut stat = Stat::EMPTY;
        let mut solution = None;
        for _ in 0..KERF_CALLS_PER_ANGLE {
            let (s, spent) = measure(angle_deg, |a| kerf_from_angle(&gauge, a));
            stat.add(spent.less(overhead));
            kerf_all.add(spent.less(overhead));
            solution = Some(s);
        }
        if let Some(s) = solution {
            say!(
                "KERF angle_deg={angle_deg} kerf_um={} converged={}",
                s.kerf_um,
                s.converged
            );
        }
        let mut name = heapless_name::<16>();
        let _ = write!(name, "angle={angle_deg}");
        stat.print("kerf", name.as_str());
    }
    kerf_all.print("kerf", "all");

    measure_parts(overhead);

    // The control step through whole runs.
    let mut bench = StepBench {
        controller: Controller::new(DeviceConfig::DEFAULT),
        now_us: 0,
        tick: 0,
        overhead,
        by_state: [Stat::EMPTY; STATES.len()],
        all: Stat::EMPTY,
        last_duty: 0.0,
        supply_v: 12.0,
    };
    let mut default_jammed_ticks = 0;
    for hold_deg in HOLD_ANGLES_DEG {
        default_jammed_ticks = bench.run(hold_deg, &RunParams::DEFAULT);
    }
    bench.supply_v = LIGHT_SUPPLY_V;
    let light = RunParams {
        target_force_n: LIGHT_FORCE_N,
        ..RunParams::DEFAULT
    };
    let light_jammed_ticks = bench.run(LIGHT_HOLD_DEG, &light);
    if light_jammed_ticks < default_jammed_ticks + WINDING_CHECK_READINGS {
        fail(format_args!(
            "the light run held {light_jammed_ticks} ticks: no winding check was measured"
        ));
    }
    for (stat, name) in bench.by_state.iter().zip(STATES) {
        stat.print("step", name);
    }
    bench.all.print("step", "all");
    say!("DONE");
    exit(0)
}

/// The parts of a Ramping step, each measured alone on realistic data.
fn measure_parts(overhead: Counters) {
    let params = black_box(RunParams::DEFAULT);
    let mut stat = Stat::EMPTY;
    for _ in 0..PART_CALLS {
        let (_, spent) = measure(0.0f32, |kerf_um| play_deg(&params.gauge, kerf_um));
        stat.add(spent.less(overhead));
    }
    stat.print("part", "play_deg");

    let mut stat = Stat::EMPTY;
    for _ in 0..PART_CALLS {
        let (_, spent) = measure(40.0f32, |angle_deg| {
            kerf_step(&params.gauge, angle_deg, 97.0)
        });
        stat.add(spent.less(overhead));
    }
    stat.print("part", "kerf_step");

    let mut stat = Stat::EMPTY;
    for _ in 0..PART_CALLS {
        let (_, spent) = measure(40.0f32, |inset_deg| {
            torque_for_force_nm(&params, params.target_force_n, inset_deg)
        });
        stat.add(spent.less(overhead));
    }
    stat.print("part", "torque_for_force_nm");

    // A hub turning at 50 °/s, as read by the encoder.
    let mut slope = SlopeWindow::new();
    for tick in 0..JAM_WINDOW_TICKS as u32 {
        slope.push(encoder_deg(30.0 + RAMP_DEG_PER_TICK * tick as f32, tick));
    }
    let mut stat = Stat::EMPTY;
    for tick in 0..PART_CALLS {
        let angle_deg = encoder_deg(31.0 + RAMP_DEG_PER_TICK * tick as f32, tick);
        let (_, spent) = measure(angle_deg, |angle_deg| slope.push(angle_deg));
        stat.add(spent.less(overhead));
    }
    stat.print("part", "slope_push");

    let mut stat = Stat::EMPTY;
    for _ in 0..PART_CALLS {
        let (_, spent) = measure(&slope, |window| window.slope_deg_per_tick());
        stat.add(spent.less(overhead));
    }
    stat.print("part", "slope_regression");

    // A held jam, a count of noise around 45°.
    let mut hold = HoldWindow::new();
    for tick in 0..HOLD_TICKS as u32 {
        hold.push(encoder_deg(45.0, tick));
    }
    let mut stat = Stat::EMPTY;
    for _ in 0..PART_CALLS {
        let (_, spent) = measure(&hold, |window| window.median_and_spread());
        stat.add(spent.less(overhead));
    }
    stat.print("part", "hold_median");
}

/// A short stack string for record names.
fn heapless_name<const N: usize>() -> kerfmeter_protocol::heapless::String<N> {
    kerfmeter_protocol::heapless::String::new()
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    say!("PANIC {info}");
    exit(1)
}

/// Any exception (an illegal instruction, such as a hard-float one on this FPU-less machine):
/// report it and fail.
#[unsafe(export_name = "ExceptionHandler")]
extern "C" fn exception_handler(trap_frame: &riscv_rt::TrapFrame) -> ! {
    let cause: usize;
    let pc: usize;
    // SAFETY: reading machine-mode trap CSRs.
    unsafe {
        asm!("csrr {0}, mcause", "csrr {1}, mepc", out(reg) cause, out(reg) pc, options(nomem, nostack));
    }
    say!(
        "TRAP mcause={cause:#x} mepc={pc:#x} ra={:#x}",
        trap_frame.ra
    );
    exit(3)
}

/// No interrupt is enabled; one arriving is a bug.
#[unsafe(export_name = "DefaultHandler")]
extern "C" fn default_handler() -> ! {
    say!("TRAP unexpected interrupt");
    exit(4)
}
