//! Every state transition and every fault, with scripted inputs (the twin covers them with
//! physics in `tests/twin_runs.rs`).

use kerfmeter_protocol::{
    Conditions, DeviceConfig, ErrorCode, Fault, KerfResult, QualityFlags, REFERENCE_SUPPLY_V,
    RunParams, RunState,
};

use super::*;
use kerfmeter_protocol::spiral::{kerf_from_angle, torque_for_force_nm};

mod wake;

/// A controller and a clock, fed scripted hub angles.
struct Script {
    c: Controller,
    now_us: u64,
    angle_deg: f32,
    /// The supply reading every tick gets (`None`: not measured).
    supply_v: Option<f32>,
    /// The scripted winding's resistance over the calibration's: the current a tick reads is
    /// what the last output's duty drives through it at standstill.
    winding_factor: f32,
    /// The last output.
    last_out: MotorOutput,
}

/// The winding's resistance the default configuration implies, Ω (0.157 · 12 / 0.88).
fn reference_ohm() -> f32 {
    let c = DeviceConfig::DEFAULT;
    c.torque_per_amp_nm * REFERENCE_SUPPLY_V / c.torque_per_duty_nm
}

impl Script {
    fn new() -> Self {
        let mut s = Self {
            c: Controller::new(DeviceConfig::DEFAULT),
            now_us: 0,
            angle_deg: 0.0,
            supply_v: None,
            winding_factor: 1.0,
            last_out: MotorOutput::SAFE,
        };
        s.tick();
        s
    }

    fn inputs(&self) -> Inputs {
        Inputs {
            angle_deg: Ok(self.angle_deg),
            diagnostics: None,
            current_a: Some(self.current_a()),
            driver_fault: false,
            supply_v: self.supply_v,
        }
    }

    /// The current the last output drives through the scripted winding at standstill, A.
    fn current_a(&self) -> f32 {
        let out = self.last_out;
        if !out.awake {
            return 0.0;
        }
        let supply_v = self.supply_v.unwrap_or(REFERENCE_SUPPLY_V);
        out.duty * supply_v / (self.winding_factor * reference_ohm())
    }

    fn tick(&mut self) -> MotorOutput {
        let inputs = self.inputs();
        self.tick_with(&inputs)
    }

    fn tick_with(&mut self, inputs: &Inputs) -> MotorOutput {
        self.tick_after(PERIOD_US, inputs)
    }

    /// A step `gap_us` after the last one.
    fn tick_after(&mut self, gap_us: u64, inputs: &Inputs) -> MotorOutput {
        self.now_us += gap_us;
        let out = self.c.step(self.now_us, inputs);
        self.last_out = out;
        // A host that polls every 10 ms.
        if (self.now_us / PERIOD_US).is_multiple_of(10) {
            self.c.host_activity(self.now_us);
        }
        out
    }

    /// The controller, a request from the host having just arrived (the device notes host
    /// activity for every request before it carries the request out).
    fn host(&mut self) -> &mut Controller {
        self.c.host_activity(self.now_us);
        &mut self.c
    }

    fn state(&self) -> RunState {
        self.c.run_state()
    }

    fn start(&mut self, params: RunParams) {
        assert_eq!(self.host().start_run(&params), Ok(()));
    }
}

#[test]
fn a_scripted_run_goes_through_every_run_state_to_a_result() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let mut seen = [RunState::Idle; 0].to_vec();
    // The hub turns 0.06°/tick until the "gap" closes at 60°, then stands still.
    for _ in 0..5000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            s.angle_deg += 0.06;
        }
        let out = s.tick();
        let st = s.state();
        if seen.last() != Some(&st) {
            seen.push(st);
        }
        if st == RunState::Done {
            assert!(out.is_safe());
            break;
        }
    }
    assert_eq!(
        seen,
        [
            RunState::Engaging,
            RunState::Ramping,
            RunState::Jammed,
            RunState::Releasing,
            RunState::Done
        ]
    );
    let r = s.c.result().unwrap();
    let expected = kerf_from_angle(&kerfmeter_protocol::GaugeGeometry::PAPER, 60.0).kerf_um;
    assert!((r.kerf_um - expected).abs() < 0.01);
    assert!((r.force_at_jam_n - 55.0).abs() < 0.5);
    // Reset: to Resetting, back to zero, then Idle with the result gone.
    assert_eq!(s.host().start_reset(), Ok(()));
    assert_eq!(s.state(), RunState::Resetting);
    for _ in 0..3000 {
        let out = s.tick();
        if out.awake && out.duty > 0.0 {
            // The scripted hub follows the drive back.
            s.angle_deg = (s.angle_deg - 0.09).max(0.0);
        }
        if s.state() == RunState::Idle {
            break;
        }
    }
    assert_eq!(s.state(), RunState::Idle);
    assert_eq!(s.host().result(), None);
}

#[test]
fn a_slipping_jam_goes_back_to_ramping() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    for _ in 0..5000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            s.angle_deg += 0.06;
        }
        s.tick();
        if s.state() == RunState::Jammed {
            break;
        }
    }
    assert_eq!(s.state(), RunState::Jammed);
    s.angle_deg += 2.0 * JAM_SLIP_DEG;
    s.tick();
    assert_eq!(s.state(), RunState::Ramping);
}

fn run_until_fault(s: &mut Script, mut script: impl FnMut(&mut Script, u32) -> Inputs) -> Fault {
    for i in 0..20_000 {
        let inputs = script(s, i);
        let out = s.tick_with(&inputs);
        if let RunState::Fault(f) = s.state() {
            assert!(
                out.is_safe() && !out.awake,
                "motor safe in the fault's own tick"
            );
            return f;
        }
    }
    panic!("no fault");
}

#[test]
fn max_run_time() {
    let mut s = Script::new();
    s.start(RunParams {
        max_time_ms: 100,
        ..RunParams::DEFAULT
    });
    // The hub creeps on and never jams.
    let f = run_until_fault(&mut s, |s, _| {
        s.angle_deg += 0.01;
        s.inputs()
    });
    assert_eq!(f, Fault::MaxRunTime);
}

#[test]
fn overtravel() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let f = run_until_fault(&mut s, |s, _| {
        s.angle_deg += 0.09;
        s.inputs()
    });
    assert_eq!(f, Fault::Overtravel);
    assert!(s.angle_deg > 160.0);
}

#[test]
fn no_motion() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    assert_eq!(run_until_fault(&mut s, |s, _| s.inputs()), Fault::NoMotion);
}

#[test]
fn reverse_motion() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let f = run_until_fault(&mut s, |s, i| {
        s.angle_deg = if i < 300 { i as f32 * 0.06 } else { 18.0 - 3.0 };
        s.inputs()
    });
    assert_eq!(f, Fault::ReverseMotion);
}

#[test]
fn consecutive_encoder_errors_fault_but_a_few_are_ridden_through() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let f = run_until_fault(&mut s, |s, i| {
        s.angle_deg += 0.06;
        let mut inputs = s.inputs();
        // Isolated errors first (ridden through), then a burst.
        if i.is_multiple_of(7) || i >= 200 {
            inputs.angle_deg = Err(EncoderFault::Parity);
        }
        inputs
    });
    assert_eq!(f, Fault::EncoderErrors);
    assert!(s.c.status().encoder_errors >= MAX_CONSECUTIVE_ENCODER_ERRORS + 20);
}

#[test]
fn diagnostics_faults_are_typed_during_a_run() {
    for (diag, fault) in [
        (DiagnosticFault::Chip, Fault::EncoderDiagnostics),
        (DiagnosticFault::Magnet, Fault::Magnet),
    ] {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        s.tick();
        let mut inputs = s.inputs();
        inputs.diagnostics = Some(Err(diag));
        let out = s.tick_with(&inputs);
        assert_eq!(s.state(), RunState::Fault(fault));
        assert_eq!(out, MotorOutput::SAFE, "safe the tick it latches");
    }
}

const GOOD_DIAGNOSTICS: DiagnosticsReading = DiagnosticsReading {
    magnitude: 4000,
    marginal: false,
};

/// Every blocking idle condition, from its input, refuses a run, a reset and a self-test with
/// `Blocked` naming it, latches nothing, and clears when the input goes away.
#[test]
fn idle_conditions_block_without_latching_and_clear() {
    type Cause = fn(&mut Inputs);
    let cases: [(Cause, Cause, Conditions); 4] = [
        (
            |i| i.diagnostics = Some(Err(DiagnosticFault::Magnet)),
            |i| i.diagnostics = Some(Ok(GOOD_DIAGNOSTICS)),
            Conditions::NO_MAGNET,
        ),
        (
            |i| i.diagnostics = Some(Err(DiagnosticFault::Chip)),
            |i| i.diagnostics = Some(Ok(GOOD_DIAGNOSTICS)),
            Conditions::ENCODER_DIAGNOSTICS,
        ),
        (
            |i| i.angle_deg = Err(EncoderFault::Parity),
            |_| {},
            Conditions::ENCODER_UNREADABLE,
        ),
        (|i| i.driver_fault = true, |_| {}, Conditions::DRIVER_FAULT),
    ];
    for (cause, cure, condition) in cases {
        let mut s = Script::new();
        let mut bad = s.inputs();
        cause(&mut bad);
        for _ in 0..MAX_CONSECUTIVE_ENCODER_ERRORS + 1 {
            assert_eq!(s.tick_with(&bad), MotorOutput::SAFE);
        }
        assert_eq!(s.state(), RunState::Idle, "{condition:?} latched nothing");
        assert_eq!(s.c.status().conditions, condition);
        let blocked = Err(ErrorCode::Blocked(condition));
        assert_eq!(s.host().start_run(&RunParams::DEFAULT), blocked);
        assert_eq!(s.host().start_reset(), blocked);
        assert_eq!(s.host().start_self_test(), blocked);
        assert_eq!(s.host().set_config(DeviceConfig::DEFAULT), Ok(()));
        // Diagnostics stand until the next reading; the others go with their input.
        let mut good = s.inputs();
        cure(&mut good);
        s.tick_with(&good);
        assert_eq!(
            s.c.status().conditions,
            Conditions::empty(),
            "{condition:?}"
        );
        s.start(RunParams::DEFAULT);
    }
}

#[test]
fn status_reports_the_supply_and_the_tick_timing() {
    let mut s = Script::new();
    let mut inputs = s.inputs();
    inputs.supply_v = Some(11.5);
    s.now_us += 2 * PERIOD_US;
    s.tick_with(&inputs);
    s.c.step_finished(s.now_us + 230);
    let status = s.c.status();
    assert_eq!(status.supply_v, Some(11.5));
    assert_eq!(status.longest_gap_us, 3 * PERIOD_US as u32);
    assert_eq!(status.longest_step_us, 230);
    s.tick();
    assert_eq!(
        s.c.status().supply_v,
        Some(11.5),
        "a tick without a reading keeps the filtered supply"
    );
}

/// A script on a supply of `supply_v`, the filter settled on it; above the reference G2
/// 18v17's safe maximum, with a 24 V driver (the G2 24v21).
fn on_supply(supply_v: f32) -> Script {
    let mut s = Script::new();
    if supply_v > kerfmeter_protocol::G2Variant::V18v17.supply_max_v() {
        s.c.set_driver(kerfmeter_protocol::G2Variant::V24v21);
    }
    s.supply_v = Some(supply_v);
    s.tick();
    s
}

/// The hub scripted to turn 0.06°/tick while driven, until it jams at `jam_deg`; then
/// `at_ramp` is called on the first ramping tick. The run's last output and its result.
fn scripted_run(
    s: &mut Script,
    params: RunParams,
    jam_deg: f32,
    mut at_ramp: impl FnMut(&mut Script),
) -> Option<KerfResult> {
    s.start(params);
    let mut ramping = false;
    for _ in 0..5000 {
        if s.angle_deg < jam_deg && s.c.torque_nm > 0.0 {
            s.angle_deg += 0.06;
        }
        s.tick();
        if !ramping && s.state() == RunState::Ramping {
            ramping = true;
            at_ramp(s);
        }
        if s.state() == RunState::Done {
            break;
        }
    }
    s.c.result().copied()
}

#[test]
fn the_duty_is_scaled_by_the_measured_supply() {
    // The same scripted engage on each supply: the same torque, so the same duty × supply.
    let drive = |supply_v: Option<f32>| {
        let mut s = Script::new();
        if supply_v.is_some_and(|v| v > kerfmeter_protocol::G2Variant::V18v17.supply_max_v()) {
            s.c.set_driver(kerfmeter_protocol::G2Variant::V24v21);
        }
        s.supply_v = supply_v;
        s.tick();
        // A cap that 9 V can deliver (the default's 0.8 N·m needs 11.4 V).
        s.start(RunParams {
            max_torque_nm: 0.6,
            ..RunParams::DEFAULT
        });
        let mut out = MotorOutput::SAFE;
        // Past the brake that wakes the driver.
        for _ in 0..60 + crate::board::current::OFFSET_WINDOW_TICKS {
            out = s.tick();
        }
        assert!(out.awake && out.duty > 0.05, "{out:?}");
        out.duty
    };
    let unmeasured = drive(None);
    assert_eq!(
        drive(Some(12.0)),
        unmeasured,
        "the reference supply: unscaled"
    );
    for supply_v in [9.0, 24.0, 26.0] {
        let duty = drive(Some(supply_v));
        assert!(
            (duty * supply_v - unmeasured * 12.0).abs() < 1e-4,
            "{supply_v} V: duty {duty} vs {unmeasured} at 12 V"
        );
    }
}

#[test]
fn a_run_whose_torque_the_supply_cannot_deliver_is_refused_with_the_figures() {
    // The default run may ask for 0.8 N·m (its cap): 0.04 + 0.8/0.88 of full duty at 12 V,
    // which needs 11.39 V.
    let mut s = on_supply(10.0);
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::SupplyTooLow {
            supply_mv: 10_000,
            needed_mv: 11_389,
        })
    );
    assert_eq!(s.state(), RunState::Idle);
    assert!(s.tick().is_safe(), "the motor did not move");
    // A cap the supply can deliver, or a supply that delivers the cap, runs.
    let capped = RunParams {
        max_torque_nm: 0.6,
        ..RunParams::DEFAULT
    };
    s.start(capped);
    let mut s = on_supply(11.4);
    s.start(RunParams::DEFAULT);
    // Not measured: never refused for the supply.
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
}

#[test]
fn a_supply_outside_the_rated_range_at_rest_blocks_without_latching() {
    // 0 V: the motor supply off (first bench check 3), read as such, not as "not measured".
    for bad_v in [0.0, 8.3, 27.1] {
        // (Beyond the range by more than the sense's tolerance: 2 % and 0.46 V.)
        let mut s = on_supply(bad_v);
        let blocked = Err(ErrorCode::Blocked(Conditions::SUPPLY_OUT_OF_RANGE));
        assert_eq!(s.c.status().conditions, Conditions::SUPPLY_OUT_OF_RANGE);
        assert_eq!(s.host().start_run(&RunParams::DEFAULT), blocked);
        assert_eq!(s.host().start_reset(), blocked);
        assert_eq!(s.host().start_self_test(), blocked);
        assert_eq!(s.host().set_config(DeviceConfig::DEFAULT), Ok(()));
        assert_eq!(s.state(), RunState::Idle, "nothing latched");
        // Back in range: the condition goes once the filter has followed.
        s.supply_v = Some(12.0);
        for _ in 0..300 {
            s.tick();
        }
        assert_eq!(s.c.status().conditions, Conditions::empty(), "{bad_v} V");
        s.start(RunParams::DEFAULT);
    }
}

#[test]
fn a_supply_sagging_mid_run_holds_the_torque_to_full_duty_and_flags_the_result() {
    // Healthy: no flag, the jam at the target force.
    let mut s = on_supply(12.0);
    let healthy = scripted_run(&mut s, RunParams::DEFAULT, 60.0, |_| {}).unwrap();
    assert!(
        healthy.flags.distrusting().is_empty(),
        "{:?}",
        healthy.flags
    );
    assert!((healthy.force_at_jam_n - 55.0).abs() < 0.5);
    // The supply sags to 8.2 V as the ramp starts: no fault and no condition (the run goes on),
    // but full duty gives only (8.2/12 − 0.04) × 0.88 = 0.566 N·m, less than the 0.635 N·m the
    // jam at 60° needs (and at rest 8.2 V is out of range, beyond the sense's tolerance).
    let mut s = on_supply(12.0);
    let mut duties = Vec::new();
    let sagged = scripted_run(&mut s, RunParams::DEFAULT, 60.0, |s| s.supply_v = Some(8.2));
    for _ in 0..3 {
        duties.push(s.tick().duty);
    }
    let sagged = sagged.unwrap();
    assert!(
        sagged.flags.contains(QualityFlags::SUPPLY_LIMITED),
        "{:?}",
        sagged.flags
    );
    assert!(!sagged.flags.contains(QualityFlags::TORQUE_LIMITED));
    let full_duty_nm = (8.2 / 12.0 - 0.04) * 0.88;
    assert!(
        (sagged.torque_at_jam_nm - full_duty_nm).abs() < 0.005,
        "{sagged:?}"
    );
    assert!(sagged.force_at_jam_n < 52.0, "{sagged:?}");
    assert_eq!(
        s.c.status().conditions,
        Conditions::SUPPLY_OUT_OF_RANGE,
        "at rest again"
    );
    assert!(duties.iter().all(|d| *d == 0.0), "done: safe");
}

#[test]
fn over_current_and_driver_fault() {
    for (current_a, flt, fault) in [
        (7.0, false, Fault::OverCurrent),
        (0.5, true, Fault::DriverFault),
    ] {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        let f = run_until_fault(&mut s, |s, i| {
            s.angle_deg += 0.06;
            let mut inputs = s.inputs();
            if i > 100 {
                inputs.current_a = Some(current_a);
                inputs.driver_fault = flt;
            }
            inputs
        });
        assert_eq!(f, fault);
    }
}

#[test]
fn an_unknown_current_faults_as_over_current_in_any_state() {
    // At rest...
    let mut s = Script::new();
    let mut inputs = s.inputs();
    inputs.current_a = None;
    s.tick_with(&inputs);
    assert_eq!(s.state(), RunState::Fault(Fault::OverCurrent));
    // ...and mid-run, with the motor safe in the same tick.
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let f = run_until_fault(&mut s, |s, i| {
        s.angle_deg += 0.06;
        let mut inputs = s.inputs();
        if i > 100 {
            inputs.current_a = None;
        }
        inputs
    });
    assert_eq!(f, Fault::OverCurrent);
}

#[test]
fn host_silence_during_a_run() {
    let mut s = Script::new();
    s.start(RunParams {
        host_timeout_ms: 200,
        ..RunParams::DEFAULT
    });
    let mut f = None;
    for _ in 0..1000 {
        s.angle_deg += 0.06;
        // No requests: step directly, bypassing the script's polling.
        s.now_us += PERIOD_US;
        let out = s.c.step(s.now_us, &s.inputs());
        if let RunState::Fault(fault) = s.state() {
            assert!(!out.awake);
            f = Some(fault);
            break;
        }
    }
    assert_eq!(f, Some(Fault::HostSilent));
}

/// A step `late_us` late, then the steps it delayed, which the ticker runs at once (20 µs
/// apart), as embassy's `Ticker` does; the hub keeps turning by `deg_per_tick` a period.
fn late_tick(s: &mut Script, late_us: u64, deg_per_tick: f32) {
    s.angle_deg += deg_per_tick * (late_us / PERIOD_US) as f32;
    let inputs = s.inputs();
    s.tick_after(PERIOD_US + late_us, &inputs);
    for _ in 0..late_us / PERIOD_US {
        s.tick_after(20, &inputs);
    }
}

/// A scripted run: the hub turns 0.06° a period until it jams at 60°; `late` may put in a late
/// tick (it gets the script and the tick count). The run's end: its result or its fault.
fn run_with_late_steps(
    s: &mut Script,
    mut late: impl FnMut(&mut Script, u32),
) -> Result<f32, Fault> {
    s.start(RunParams::DEFAULT);
    for tick in 0..5000 {
        let deg_per_tick = if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            0.06
        } else {
            0.0
        };
        s.angle_deg += deg_per_tick;
        s.tick();
        late(s, tick);
        match s.state() {
            RunState::Done => return Ok(s.c.result().unwrap().kerf_um),
            RunState::Fault(f) => return Err(f),
            _ => {}
        }
    }
    panic!("the run did not end");
}

#[test]
fn a_late_step_in_idle_is_harmless() {
    let mut s = Script::new();
    // Idle: a late step is harmless (the board writes flash while idle).
    s.now_us += 50 * PERIOD_US;
    s.tick();
    assert_eq!(s.state(), RunState::Idle);
    let inputs = s.inputs();
    s.tick_after(500 * PERIOD_US, &inputs);
    assert_eq!(s.state(), RunState::Idle);
}

#[test]
fn a_single_late_step_is_ridden_through_without_a_kick() {
    let mut s = Script::new();
    let on_time = run_with_late_steps(&mut s, |_, _| {}).unwrap();
    let mut s = Script::new();
    let mut seen = None;
    let late = run_with_late_steps(&mut s, |s, tick| {
        if tick == 300 {
            assert_eq!(s.state(), RunState::Ramping);
            let before_nm = s.c.torque_nm;
            // The hub barely moves meanwhile (the speed loop does not hold the torque back).
            let late_us = (MAX_GAP_PERIODS - 1) * PERIOD_US;
            let inputs = s.inputs();
            s.tick_after(PERIOD_US + late_us, &inputs);
            // The late step integrates two periods of the ramp at most.
            let rise_nm = s.c.torque_nm - before_nm;
            let ramp_nm = RunParams::DEFAULT.ramp_rate_nm_per_s * 2e-3;
            seen = Some((rise_nm, ramp_nm));
            for _ in 0..late_us / PERIOD_US {
                s.tick_after(20, &inputs);
            }
        }
    })
    .unwrap();
    let (rise_nm, ramp_nm) = seen.expect("the late step came in the ramp");
    assert!(rise_nm <= ramp_nm * 1.0001, "{rise_nm} N·m in one step");
    assert!((late - on_time).abs() < 0.01, "{late} µm vs {on_time} µm");
    assert_eq!(
        s.c.tick_timing().longest_gap_us(),
        MAX_GAP_PERIODS * PERIOD_US
    );
}

#[test]
fn a_step_after_a_longer_gap_is_an_overrun() {
    let mut s = Script::new();
    let end = run_with_late_steps(&mut s, |s, tick| {
        if tick == 300 {
            late_tick(s, MAX_GAP_PERIODS * PERIOD_US, 0.06);
        }
    });
    assert_eq!(end, Err(Fault::StepOverrun));
    assert!(!s.c.output().awake, "safe from that step on");
}

#[test]
fn frequent_late_steps_are_an_overrun() {
    // A step 5 ms late every 30 ms: each one alone would be ridden through.
    let mut s = Script::new();
    let end = run_with_late_steps(&mut s, |s, tick| {
        if tick % 30 == 29 {
            late_tick(s, 5 * PERIOD_US, 0.06);
        }
    });
    assert_eq!(end, Err(Fault::StepOverrun));
    // One every 100 ms is rare: the run ends with its result.
    let mut s = Script::new();
    let end = run_with_late_steps(&mut s, |s, tick| {
        if tick % 100 == 99 {
            late_tick(s, 5 * PERIOD_US, 0.0);
        }
    });
    assert!(end.is_ok(), "{end:?}");
}

#[test]
fn a_late_step_in_a_reset_is_ridden_through() {
    let mut s = Script::new();
    s.angle_deg = 30.0;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    for tick in 0..3000 {
        let out = s.tick();
        if out.awake && out.duty > 0.0 {
            s.angle_deg = (s.angle_deg - 0.09).max(0.0);
        }
        if tick == 100 {
            late_tick(&mut s, 5 * PERIOD_US, 0.0);
        }
        if s.state() != RunState::Resetting {
            break;
        }
    }
    assert_eq!(s.state(), RunState::Idle);
}

/// A reset that drives the hub away from zero (a motor or encoder sense set wrong) faults as
/// soon as the hub is well past where it started, not after the whole timeout's turns.
#[test]
fn a_reset_driving_the_wrong_way_faults_at_once() {
    let mut s = Script::new();
    s.angle_deg = 10.0;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    let mut ticks = 0;
    let f = run_until_fault(&mut s, |s, _| {
        ticks += 1;
        // Driven towards zero, the hub turns away.
        s.angle_deg += 0.1;
        s.inputs()
    });
    assert_eq!(f, Fault::ReverseMotion);
    assert!(ticks < 400, "{ticks} ticks");
}

#[test]
fn a_blocked_reset_fails_with_a_typed_fault() {
    let mut s = Script::new();
    s.angle_deg = 40.0;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    // The hub never moves.
    assert_eq!(
        run_until_fault(&mut s, |s, _| s.inputs()),
        Fault::ResetFailed
    );
}

#[test]
fn faults_latch_until_cleared_and_refuse_runs_meanwhile() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    s.tick();
    let mut inputs = s.inputs();
    inputs.driver_fault = true;
    assert_eq!(s.tick_with(&inputs), MotorOutput::SAFE);
    assert_eq!(s.state(), RunState::Fault(Fault::DriverFault));
    // Latched: the cause going away changes nothing.
    s.tick();
    assert_eq!(s.state(), RunState::Fault(Fault::DriverFault));
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::Faulted(Fault::DriverFault))
    );
    assert_eq!(
        s.host().start_self_test(),
        Err(ErrorCode::Faulted(Fault::DriverFault))
    );
    assert_eq!(
        s.host().set_config(DeviceConfig::DEFAULT),
        Ok(()),
        "configurable while faulted"
    );
    s.host().abort();
    assert_eq!(
        s.state(),
        RunState::Fault(Fault::DriverFault),
        "Abort does not clear a fault"
    );
    // The cause is back: cleared, the fault does not latch again at rest; it blocks instead.
    s.tick_with(&inputs);
    s.host().clear_fault();
    assert_eq!(s.state(), RunState::Idle);
    s.tick_with(&inputs);
    assert_eq!(s.state(), RunState::Idle, "no re-latch at rest");
    assert_eq!(
        s.host().start_reset(),
        Err(ErrorCode::Blocked(Conditions::DRIVER_FAULT))
    );
    // Reset also leaves a fault (and drives to zero).
    s.tick();
    s.start(RunParams::DEFAULT);
    s.tick_with(&inputs);
    assert_eq!(s.state(), RunState::Fault(Fault::DriverFault));
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    assert_eq!(s.state(), RunState::Resetting);
}

#[test]
fn abort_is_safe_in_the_next_tick_from_every_active_state() {
    for ticks in [5, 200, 1200] {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        for _ in 0..ticks {
            if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
                s.angle_deg += 0.06;
            }
            s.tick();
        }
        assert!(s.c.is_active());
        s.host().abort();
        let out = s.tick();
        assert!(!out.awake && out.duty == 0.0, "after {ticks} ticks");
        assert_eq!(s.state(), RunState::Idle);
    }
}

#[test]
fn invalid_params_and_out_of_order_requests_are_refused() {
    let mut s = Script::new();
    let bad = RunParams {
        target_force_n: f32::NAN,
        ..RunParams::DEFAULT
    };
    assert_eq!(
        s.host().start_run(&bad),
        Err(ErrorCode::InvalidParam(
            kerfmeter_protocol::ParamField::TargetForceN
        ))
    );
    assert_eq!(s.host().sample_chunk(0), Err(ErrorCode::NoSamples));
    s.angle_deg = 5.0;
    s.tick();
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::NotAtZero)
    );
    s.angle_deg = 0.0;
    s.tick();
    s.start(RunParams::DEFAULT);
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::Busy)
    );
    assert_eq!(s.host().start_reset(), Err(ErrorCode::Busy));
    assert_eq!(s.c.set_config(DeviceConfig::DEFAULT), Err(ErrorCode::Busy));
}

#[test]
fn the_motor_is_driven_in_the_gauges_sense() {
    for (jam_direction, expect_dir_high) in [
        (kerfmeter_protocol::JamDirection::Clockwise, true),
        (kerfmeter_protocol::JamDirection::CounterClockwise, false),
    ] {
        let mut s = Script::new();
        let mut params = RunParams::DEFAULT;
        params.gauge.jam_direction = jam_direction;
        s.start(params);
        let mut out = MotorOutput::SAFE;
        for _ in 0..50 {
            out = s.tick();
        }
        assert!(out.awake && out.duty > 0.0);
        assert_eq!(out.dir_high, expect_dir_high, "{jam_direction:?}");
    }
}

#[test]
fn the_controller_keeps_the_longest_gap_and_step_since_boot() {
    let mut s = Script::new();
    s.c.step_finished(s.now_us + 120);
    for _ in 0..5 {
        s.tick();
        s.c.step_finished(s.now_us + 80);
    }
    // A late tick while idle (no fault then) still counts.
    s.now_us += 4 * PERIOD_US;
    s.tick();
    s.c.step_finished(s.now_us + 300);
    s.tick();
    let timing = s.c.tick_timing();
    assert_eq!(timing.longest_gap_us(), 5 * PERIOD_US);
    assert_eq!(timing.longest_step_us(), 300);
    assert_eq!(s.state(), RunState::Idle);
}

#[test]
fn a_run_that_ends_while_its_log_halves_itself_keeps_every_sample() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    // A slow hub: the log fills (2048 ticks) long before any jam.
    while s.c.log.ticks_per_sample() == 1 {
        if s.c.torque_nm > 0.0 {
            s.angle_deg += 0.02;
        }
        s.tick();
        assert!(
            matches!(s.state(), RunState::Engaging | RunState::Ramping),
            "{:?}",
            s.state()
        );
    }
    s.angle_deg += 0.02;
    s.tick();
    assert!(
        s.c.samples().len() < s.c.log.len(),
        "the halving is under way"
    );
    s.host().abort();
    s.tick();
    let samples = s.c.samples();
    assert_eq!(samples.len(), s.c.log.len());
    assert!(samples.len() > 1000);
    for w in samples.windows(2) {
        assert_eq!(w[1].t_ms - w[0].t_ms, 2);
    }
    // GetSamples agrees with it.
    let chunk = s.c.sample_chunk(0).unwrap();
    assert_eq!(&samples[..chunk.samples.len()], chunk.samples.as_slice());
}

#[test]
fn a_reset_settles_at_its_tolerance_edge_despite_encoder_noise() {
    let mut s = Script::new();
    s.angle_deg = 0.29;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    // The hub stands just inside the tolerance; noise carries every third reading just out of it.
    for i in 0..RESET_TIMEOUT_TICKS {
        s.angle_deg = if i % 3 == 0 { 0.32 } else { 0.28 };
        s.tick();
        if s.state() != RunState::Resetting {
            break;
        }
    }
    assert_eq!(s.state(), RunState::Idle);
}

#[test]
fn a_settled_reset_drives_again_once_the_hub_leaves_the_wider_band() {
    let mut s = Script::new();
    s.angle_deg = 0.2;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    for _ in 0..RESET_SETTLE_TICKS / 2 {
        s.tick();
        assert_eq!(s.c.torque_nm, 0.0, "settled: braking");
    }
    // Within the release band: still settled.
    s.angle_deg = RESET_RELEASE_DEG - 0.05;
    s.tick();
    assert_eq!(s.c.torque_nm, 0.0);
    // Beyond it: driven back towards zero, and the settle count starts again.
    s.angle_deg = RESET_RELEASE_DEG + 0.2;
    for _ in 0..RESET_SETTLE_TICKS {
        s.tick();
        assert!(s.c.torque_nm < 0.0, "{}", s.c.torque_nm);
    }
    assert_eq!(s.state(), RunState::Resetting);
}

#[test]
fn a_motor_shaft_encoder_setting_changes_only_at_zero() {
    use kerfmeter_protocol::EncoderPlacement;
    let motor_shaft = DeviceConfig {
        encoder_placement: EncoderPlacement::MotorShaft,
        ..DeviceConfig::DEFAULT
    };
    let mut s = Script::new();
    s.angle_deg = 150.0;
    s.tick();
    // Away from zero: unrelated fields change; an output-shaft encoder's settings too.
    let limits = DeviceConfig {
        max_current_a: 5.0,
        ..DeviceConfig::DEFAULT
    };
    assert_eq!(s.host().set_config(limits), Ok(()));
    let zero = DeviceConfig {
        encoder_zero_raw: 100,
        ..DeviceConfig::DEFAULT
    };
    assert_eq!(s.host().set_config(zero), Ok(()));
    // A motor-shaft encoder's settings: refused away from zero, taken at zero.
    assert_eq!(s.host().set_config(motor_shaft), Err(ErrorCode::NotAtZero));
    s.angle_deg = 0.5;
    s.tick();
    assert_eq!(s.host().set_config(motor_shaft), Ok(()));
    // Once on the motor shaft: unrelated fields change anywhere, its settings only at zero.
    s.angle_deg = 150.0;
    s.tick();
    let warmer = DeviceConfig {
        max_current_a: 5.0,
        ..motor_shaft
    };
    assert_eq!(s.host().set_config(warmer), Ok(()));
    let rezeroed = DeviceConfig {
        encoder_zero_raw: 100,
        ..warmer
    };
    assert_eq!(s.host().set_config(rezeroed), Err(ErrorCode::NotAtZero));
    assert_eq!(s.c.config(), &warmer);
    // With the encoder failing, "at zero" cannot be shown.
    s.angle_deg = 0.0;
    s.tick();
    let mut inputs = s.inputs();
    inputs.angle_deg = Err(EncoderFault::Bus);
    s.tick_with(&inputs);
    assert_eq!(s.host().set_config(rezeroed), Err(ErrorCode::NotAtZero));
}

#[test]
fn a_motor_shaft_encoder_blocks_runs_from_power_up_until_the_hub_is_confirmed() {
    let motor_shaft = DeviceConfig {
        encoder_placement: EncoderPlacement::MotorShaft,
        ..DeviceConfig::DEFAULT
    };
    let mut s = Script::new();
    s.c = Controller::new(motor_shaft);
    s.tick();
    let unknown = Conditions::HUB_TURN_UNKNOWN;
    assert_eq!(s.c.conditions(), unknown);
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::Blocked(unknown))
    );
    // A reset and a self-test need no known turn.
    assert_eq!(s.host().start_reset(), Ok(()));
    s.host().abort();
    // Confirmed: the encoder's count restarts (a new epoch) and, once the hub has been read
    // again, a run may start.
    let epoch = s.c.encoder_epoch();
    assert_eq!(s.host().confirm_hub_at_zero(), Ok(()));
    assert_eq!(s.c.encoder_epoch(), epoch.wrapping_add(1));
    assert!(s.c.conditions().is_empty());
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::NotAtZero)
    );
    s.tick();
    assert_eq!(s.host().start_run(&RunParams::DEFAULT), Ok(()));
    // Not while the motor may be driven.
    assert_eq!(s.host().confirm_hub_at_zero(), Err(ErrorCode::Busy));
    // An output-shaft encoder: nothing to confirm, at boot or after a change to it.
    assert!(
        Controller::new(DeviceConfig::DEFAULT)
            .conditions()
            .is_empty()
    );
    let mut c = Controller::new(motor_shaft);
    assert_eq!(c.set_config(DeviceConfig::DEFAULT), Ok(()));
    assert!(c.conditions().is_empty());
    assert_eq!(c.confirm_hub_at_zero(), Ok(()));
    assert_eq!(c.encoder_epoch(), 0);
}

#[test]
fn a_change_onto_the_motor_shaft_needs_the_hub_confirmed() {
    // Output → motor shaft "at zero" by the output-shaft settings, which read any whole motor
    // turn as zero: the hub's turn is unknown until the user confirms it.
    let motor_shaft = DeviceConfig {
        encoder_placement: EncoderPlacement::MotorShaft,
        ..DeviceConfig::DEFAULT
    };
    let mut s = Script::new();
    assert_eq!(s.host().set_config(motor_shaft), Ok(()));
    assert_eq!(s.c.conditions(), Conditions::HUB_TURN_UNKNOWN);
    // Not cleared by a round trip through the output shaft either.
    assert_eq!(s.host().set_config(DeviceConfig::DEFAULT), Ok(()));
    assert!(s.c.conditions().is_empty());
    assert_eq!(s.host().set_config(motor_shaft), Ok(()));
    assert_eq!(s.c.conditions(), Conditions::HUB_TURN_UNKNOWN);
    // Confirmed, a change of another field or of its own settings at zero keeps it confirmed.
    assert_eq!(s.host().confirm_hub_at_zero(), Ok(()));
    s.tick();
    let rezeroed = DeviceConfig {
        encoder_zero_raw: 100,
        ..motor_shaft
    };
    assert_eq!(s.host().set_config(rezeroed), Ok(()));
    assert!(s.c.conditions().is_empty());
}

#[test]
fn a_reset_keeps_what_its_speed_loop_learnt_across_the_settle_band() {
    let mut s = Script::new();
    s.angle_deg = 0.6;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    // Stuck outside the tolerance (a weak motor at breakaway): the integral builds up.
    for _ in 0..1000 {
        s.tick();
    }
    let stuck_nm = s.c.torque_nm;
    assert!(stuck_nm < -0.02, "{stuck_nm}");
    // A lurch into the band (brake), then out beyond the release band again: the drive resumes
    // with what it needed to move the hub, not from nothing.
    s.angle_deg = 0.25;
    for _ in 0..RESET_SETTLE_TICKS - 10 {
        s.tick();
        assert_eq!(s.c.torque_nm, 0.0);
    }
    s.angle_deg = 0.6;
    s.tick();
    assert!(
        s.c.torque_nm < stuck_nm * 0.6,
        "{} vs {stuck_nm}",
        s.c.torque_nm
    );
}

/// After a magnet fault is cleared, the condition stands until the encoder's next diagnostics
/// reading says the magnet is back: a run asked for meanwhile is refused with it, not driven on
/// an encoder that was failing; a good reading clears it.
#[test]
fn clear_fault_keeps_the_encoders_conditions_until_a_good_reading() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    s.tick();
    let mut lost = s.inputs();
    lost.diagnostics = Some(Err(DiagnosticFault::Magnet));
    s.tick_with(&lost);
    assert_eq!(s.state(), RunState::Fault(Fault::Magnet));
    assert_eq!(s.c.conditions(), Conditions::NO_MAGNET);
    s.host().clear_fault();
    assert_eq!(s.state(), RunState::Idle);
    s.tick();
    assert_eq!(
        s.c.conditions(),
        Conditions::NO_MAGNET,
        "until the next reading"
    );
    assert_eq!(
        s.host().start_run(&RunParams::DEFAULT),
        Err(ErrorCode::Blocked(Conditions::NO_MAGNET))
    );
    let mut back = s.inputs();
    back.diagnostics = Some(Ok(GOOD_DIAGNOSTICS));
    s.tick_with(&back);
    assert_eq!(s.c.conditions(), Conditions::empty());
    assert_eq!(s.host().start_reset(), Ok(()));
}

/// The self-test's torque-constant item from scripted currents: a winding of the resistance the
/// configuration implies (R = torque_per_amp · 12 V / torque_per_duty), fed by the pulse's duty
/// at `supply_v` against the back-EMF of a hub turning at `hub_deg_per_s` while it drives.
fn self_test_torque_estimate(supply_v: f32, hub_deg_per_s: f32) -> f32 {
    let config = DeviceConfig::DEFAULT;
    let r_ohm = config.torque_per_amp_nm * REFERENCE_SUPPLY_V / config.torque_per_duty_nm;
    let mut s = Script::new();
    assert_eq!(s.host().start_self_test(), Ok(()));
    let mut out = MotorOutput::SAFE;
    for _ in 0..2000 {
        let pulse = matches!(s.c.state, State::SelfTest(SelfTestPhase::Pulse { .. }));
        let emf_v = if pulse && out.duty > 0.0 {
            s.angle_deg -= hub_deg_per_s * PERIOD_US as f32 * 1e-6;
            config.torque_per_amp_nm * hub_deg_per_s.to_radians()
        } else {
            0.0
        };
        let mut inputs = s.inputs();
        inputs.supply_v = Some(supply_v);
        inputs.current_a = Some(((out.duty * supply_v - emf_v) / r_ohm).max(0.0));
        out = s.tick_with(&inputs);
        if let Some(report) = s.c.self_test_report() {
            return report.torque_per_duty_nm.value;
        }
    }
    panic!("the self-test did not end");
}

#[test]
fn the_self_tests_torque_constant_is_right_at_any_supply_and_despite_back_emf() {
    let configured = DeviceConfig::DEFAULT.torque_per_duty_nm;
    for supply_v in [9.0, 12.0, 24.0] {
        let still = self_test_torque_estimate(supply_v, 0.0);
        assert!(
            (still / configured - 1.0).abs() < 0.01,
            "{supply_v} V: {still}"
        );
        // A hub that starts turning takes current away; the estimate puts it back.
        let turning = self_test_torque_estimate(supply_v, 200.0 * supply_v / 12.0);
        assert!(
            (turning / configured - 1.0).abs() < 0.02,
            "{supply_v} V: {turning}"
        );
    }
}

#[test]
fn over_current_trips_on_the_mean_of_four_readings_or_one_twice_the_limit() {
    let max_a = DeviceConfig::DEFAULT.max_current_a;
    // (currents fed from tick 100 on, one a tick; the tick the fault latches, counted from then)
    for (currents, trips_at) in [
        (vec![max_a * 1.5, 0.5, 0.5, 0.5, 0.5], None),
        (vec![max_a * 1.1; 4], Some(3)),
        (vec![max_a * 2.1], Some(0)),
    ] {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        let mut latched = None;
        for i in 0..110 {
            s.angle_deg += 0.06;
            let mut inputs = s.inputs();
            if i >= 100 {
                inputs.current_a = Some(*currents.get(i - 100).unwrap_or(&0.5));
            }
            s.tick_with(&inputs);
            if s.state() == RunState::Fault(Fault::OverCurrent) {
                latched = Some(i - 100);
                break;
            }
        }
        assert_eq!(latched, trips_at, "{currents:?}");
    }
}

/// A scripted run on a winding `winding_factor` times as resistive as at calibration, on 12 V,
/// jamming at 60°: the duty 10 ticks into the hold, and the result.
fn run_on_winding(s: &mut Script, winding_factor: f32) -> (f32, KerfResult) {
    s.winding_factor = winding_factor;
    s.start(RunParams::DEFAULT);
    let mut held = None;
    let mut jammed_ticks = 0;
    for _ in 0..5000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            s.angle_deg += 0.06;
        }
        let out = s.tick();
        if s.state() == RunState::Jammed {
            jammed_ticks += 1;
            if jammed_ticks == 10 {
                held = Some(out.duty);
            }
        }
        if s.state() == RunState::Done {
            break;
        }
    }
    (held.expect("a hold"), *s.c.result().expect("a result"))
}

/// Back to zero, as the reset would: the scripted hub is put there.
fn back_to_zero(s: &mut Script) {
    s.angle_deg = 0.0;
    for _ in 0..30 {
        s.tick();
    }
}

#[test]
fn a_warm_winding_is_measured_at_the_jam_and_the_duty_scaled_by_it() {
    let mut cold = on_supply(12.0);
    let (cold_duty, cold_result) = run_on_winding(&mut cold, 1.0);
    assert!(
        cold_result.flags.distrusting().is_empty(),
        "{:?}",
        cold_result.flags
    );
    assert!((cold.c.winding.factor() - 1.0).abs() < 0.01);
    // 30 % more resistance (a winding at 102 °C): measured at the settle, the hold of the same
    // run drives 30 % more duty for the same commanded torque.
    let mut warm = on_supply(12.0);
    let (warm_duty, warm_result) = run_on_winding(&mut warm, 1.3);
    let factor = warm.c.winding.factor();
    assert!((factor - 1.3).abs() < 0.01, "{factor}");
    assert!(
        (warm_duty / cold_duty - 1.3).abs() < 0.01,
        "{warm_duty} vs {cold_duty}"
    );
    assert!(
        warm_result.flags.distrusting().is_empty(),
        "{:?}",
        warm_result.flags
    );
    assert!((warm_result.torque_at_jam_nm - cold_result.torque_at_jam_nm).abs() < 1e-3);
    // Kept for the next run, whose engage starts from it; and the winding cooling back is
    // measured again.
    back_to_zero(&mut warm);
    warm.start(RunParams::DEFAULT);
    let mut engage = MotorOutput::SAFE;
    for _ in 0..60 {
        engage = warm.tick();
    }
    back_to_zero(&mut cold);
    cold.start(RunParams::DEFAULT);
    let mut cold_engage = MotorOutput::SAFE;
    for _ in 0..60 {
        cold_engage = cold.tick();
    }
    assert!(
        (engage.duty / cold_engage.duty - 1.3).abs() < 0.01,
        "{engage:?} vs {cold_engage:?}"
    );
    warm.host().abort();
    back_to_zero(&mut warm);
    let (cooled_duty, _) = run_on_winding(&mut warm, 1.1);
    assert!((warm.c.winding.factor() - 1.1).abs() < 0.01);
    assert!((cooled_duty / cold_duty - 1.1).abs() < 0.01);
}

#[test]
fn a_current_that_disagrees_with_the_duty_flags_a_torque_mismatch() {
    // Twice the resistance the configuration implies (or a torque constant half the
    // configured one): more than warmth and gain errors explain.
    for (factor, held) in [(2.0, 1.61), (0.7, 0.76)] {
        let mut s = on_supply(12.0);
        let (_, result) = run_on_winding(&mut s, factor);
        assert!(
            result.flags.contains(QualityFlags::TORQUE_MISMATCH),
            "{factor}: {:?}",
            result.flags
        );
        assert_eq!(s.c.winding.factor(), held, "held to the plausible range");
        // The calibration corrected: the factor measured against the wrong one is forgotten,
        // so the next ramp drives what the new calibration says, not 1.61 or 0.76 times it.
        let corrected = DeviceConfig {
            torque_per_duty_nm: s.c.config().torque_per_duty_nm / factor,
            ..*s.c.config()
        };
        back_to_zero(&mut s);
        assert_eq!(s.host().set_config(corrected), Ok(()));
        assert_eq!(s.c.winding.factor(), 1.0);
        assert!(
            (s.c.supply.duty_scale() - 1.0).abs() < 0.05,
            "{}",
            s.c.supply.duty_scale()
        );
    }
    // Near the range's edges: explained, no mismatch (on 24 V, where full duty gives the
    // torque). A winding cooler than the factor the run started from was driven too hard at the
    // first settle: that overshoot is kept by the spiral, and flagged FORCE_SENSITIVE.
    for (factor, overshoot) in [(0.8, true), (1.55, false)] {
        let mut s = on_supply(24.0);
        let (_, result) = run_on_winding(&mut s, factor);
        let expected = if overshoot {
            QualityFlags::FORCE_SENSITIVE
        } else {
            QualityFlags::empty()
        };
        assert_eq!(result.flags.distrusting(), expected, "{factor}");
    }
}

/// A scripted run on 12 V into a contact at 60° that yields `deg_per_nm` degrees per N·m of
/// torque past 60°, with the hub creeping on `creep_deg_per_tick` a tick while the jam is held.
fn run_on_contact(deg_per_nm: f32, creep_deg_per_tick: f32) -> KerfResult {
    run_on_scripted_contact(deg_per_nm, creep_deg_per_tick, u32::MAX, false)
}

/// [`run_on_contact`], the creep stopping after `creep_ticks` ticks of it; with `sticky`, the
/// hub does not move once the jam is first held (static friction holds it against the probe).
fn run_on_scripted_contact(
    deg_per_nm: f32,
    creep_deg_per_tick: f32,
    creep_ticks: u32,
    sticky: bool,
) -> KerfResult {
    let contact = (deg_per_nm, creep_deg_per_tick, creep_ticks, sticky);
    run_on_supply_into_contact(12.0, RunParams::DEFAULT, contact)
}

/// [`run_on_scripted_contact`] on `supply_v` with `params`; `contact` is its four arguments.
fn run_on_supply_into_contact(
    supply_v: f32,
    params: RunParams,
    contact: (f32, f32, u32, bool),
) -> KerfResult {
    timed_run_into_contact(supply_v, params, contact).0
}

/// [`run_on_supply_into_contact`], and when the run first held its jam, ms from its start.
fn timed_run_into_contact(
    supply_v: f32,
    params: RunParams,
    contact: (f32, f32, u32, bool),
) -> (KerfResult, u32) {
    run_into_contact(&mut on_supply(supply_v), params, contact)
}

/// [`timed_run_into_contact`] on the script `s` (its supply, its winding), from the hub where
/// it stands.
fn run_into_contact(
    s: &mut Script,
    params: RunParams,
    (deg_per_nm, creep_deg_per_tick, creep_ticks, sticky): (f32, f32, u32, bool),
) -> (KerfResult, u32) {
    s.start(params);
    let mut creep_deg = 0.0;
    let mut crept = 0;
    let mut held = false;
    let mut jam_ms = 0;
    for tick in 0..8000u32 {
        let contact_deg = 60.0 + deg_per_nm * s.c.torque_nm + creep_deg;
        if s.angle_deg < contact_deg && s.c.torque_nm > 0.0 && !(sticky && held) {
            s.angle_deg = (s.angle_deg + 0.06).min(contact_deg);
        }
        if matches!(s.c.state, State::Jammed { .. }) {
            if !held {
                jam_ms = tick * 1000 / u32::from(CONTROL_RATE_HZ);
            }
            held = true;
            if crept < creep_ticks {
                creep_deg += creep_deg_per_tick;
                crept += 1;
            }
        }
        s.tick();
        if s.state() == RunState::Done {
            break;
        }
    }
    (*s.c.result().expect("a result"), jam_ms)
}

#[test]
fn a_contact_the_probe_moves_far_is_flagged_force_sensitive() {
    // Rigid: the probe moves nothing.
    let rigid = run_on_contact(0.0, 0.0);
    assert_eq!(rigid.flags.distrusting(), QualityFlags::empty());
    // 1°/N·m: the probe's 10 % (some 0.05 N·m) turns the hub 0.05°, 0.14 µm: a stiff contact.
    let stiff = run_on_contact(1.0, 0.0);
    assert_eq!(stiff.flags.distrusting(), QualityFlags::empty());
    // 40°/N·m: 2°, 5.6 µm for 10 % of torque, past the 3 µm the device vouches for.
    let soft = run_on_contact(40.0, 0.0);
    assert_eq!(soft.flags.distrusting(), QualityFlags::FORCE_SENSITIVE);
}

/// The run of [`an_unmeasured_winding_allows_for_a_hot_windings_torque_shortfall`]: 60 % of the
/// default force (0.37 N·m at the jam), ramped slowly enough that the scripted hub keeps up
/// with a contact of 12°/N·m.
const LIGHT_RUN: RunParams = RunParams {
    target_force_n: RunParams::DEFAULT.target_force_n * 0.6,
    ramp_rate_nm_per_s: 0.25,
    ..RunParams::DEFAULT
};

/// The contact of [`LIGHT_RUN`]: 12°/N·m, no creep.
const LIGHT_CONTACT: (f32, f32, u32, bool) = (12.0, 0.0, 0, false);

#[test]
fn an_unmeasured_winding_allows_for_a_hot_windings_torque_shortfall() {
    // The probe's 10 % turns the hub 0.42°, 1.2 µm. On 12 V (duty 0.46) the settle measures
    // the winding, the torque is known to 10 %, and that is within what the device vouches for.
    let measured = run_on_supply_into_contact(12.0, LIGHT_RUN, LIGHT_CONTACT);
    assert_eq!(measured.flags.distrusting(), QualityFlags::empty());
    // On 26 V the settle's duty (0.21) is too low to measure it, and the run's cap (just over
    // the jam's torque) leaves no room to check it after the probe: the winding may be at
    // 130 °C, 29 % less torque, 3.5 µm on this contact (20 %, the hot side left out, said
    // 2.3 µm).
    let capped = RunParams {
        max_torque_nm: 0.4,
        ..LIGHT_RUN
    };
    let unmeasured = run_on_supply_into_contact(26.0, capped, LIGHT_CONTACT);
    assert_eq!(
        unmeasured.flags.distrusting(),
        QualityFlags::FORCE_SENSITIVE
    );
}

/// `flags` without the advisory ones (`DECIMATED`: the light runs, slow and with the winding
/// check at their end, outgrow the log; `PLAY_MODELLED`: the scripted hub does not back off).
fn distrusting(flags: QualityFlags) -> QualityFlags {
    flags.distrusting()
}

#[test]
fn a_winding_the_settle_cannot_measure_is_checked_after_the_probe() {
    // On 26 V, room under the cap: after the probe the torque is raised to a duty the current
    // sense reads. A winding as calibrated: the hold's torque was right, nothing to flag.
    let mut cold = on_supply(26.0);
    let (result, _) = run_into_contact(&mut cold, LIGHT_RUN, LIGHT_CONTACT);
    assert_eq!(distrusting(result.flags), QualityFlags::empty());
    assert!((cold.c.winding.factor() - 1.0).abs() < 0.01);
    // 30 % more resistance: the check finds the hold short of its torque by (1/1.3 − 1)(1 +
    // b·k/τ), 25 % (3.4 µm on this contact, with the sense's 10 %: 4.8 µm), flags the reading,
    // reports the torque really held and keeps the factor...
    let mut hot = on_supply(26.0);
    hot.winding_factor = 1.3;
    let (first, _) = run_into_contact(&mut hot, LIGHT_RUN, LIGHT_CONTACT);
    assert_eq!(distrusting(first.flags), QualityFlags::FORCE_SENSITIVE);
    assert!((hot.c.winding.factor() - 1.3).abs() < 0.01);
    // ...so the next run drives the hot winding's duty (0.27), which its own settle measures.
    back_to_zero(&mut hot);
    let (second, _) = run_into_contact(&mut hot, LIGHT_RUN, LIGHT_CONTACT);
    assert!(hot.c.run.winding_measured);
    assert_eq!(distrusting(second.flags), QualityFlags::empty());
    let c = DeviceConfig::DEFAULT;
    let breakaway_nm = c.breakaway_duty * c.torque_per_duty_nm;
    let expected = 1.0 + (1.0 / 1.3 - 1.0) * (1.0 + breakaway_nm / second.torque_at_jam_nm);
    let ratio = first.torque_at_jam_nm / second.torque_at_jam_nm;
    assert!(
        (ratio - expected).abs() < 0.01,
        "{ratio} against {expected}"
    );
}

#[test]
fn a_check_whose_estimate_is_implausible_leaves_the_torque_unknown() {
    // Twice the resistance the calibration implies, read at a fraction of an amp: as likely the
    // sense's noise as a wrong calibration, so the factor stands, nothing says `torque-mismatch`,
    // and the hold's torque stays as commanded and uncertain by 30 %.
    let mut s = on_supply(26.0);
    s.winding_factor = 2.0;
    let (result, _) = run_into_contact(&mut s, LIGHT_RUN, LIGHT_CONTACT);
    assert_eq!(distrusting(result.flags), QualityFlags::FORCE_SENSITIVE);
    assert!(s.c.run.winding_checked && s.c.run.hold_torque_error.is_none());
    assert_eq!(s.c.winding.factor(), 1.0);
    let (cold, _) = run_into_contact(&mut on_supply(26.0), LIGHT_RUN, LIGHT_CONTACT);
    assert!((result.torque_at_jam_nm - cold.torque_at_jam_nm).abs() < 1e-6);
}

#[test]
fn a_contact_giving_way_under_the_check_has_its_torque_dropped_at_once() {
    // Under the check the scripted hub runs on, racing (200°/s) or crushing slowly (20°/s), far
    // past what the contact's compliance (12°/N·m) allows for the check's extra torque: the
    // torque goes to zero the tick after, the run releases and reads, flagged, and the winding
    // stays unmeasured.
    for deg_per_tick in [0.2, 0.02] {
        let mut s = on_supply(26.0);
        s.start(LIGHT_RUN);
        let mut checking_ticks = 0;
        let mut torque_after_check = Vec::new();
        for _ in 0..20_000 {
            let checking = matches!(s.c.state, State::CheckingWinding { .. });
            if checking {
                checking_ticks += 1;
                s.angle_deg += deg_per_tick;
            } else if checking_ticks == 0 {
                let contact_deg = 60.0 + 12.0 * s.c.torque_nm;
                if s.angle_deg < contact_deg && s.c.torque_nm > 0.0 {
                    s.angle_deg = (s.angle_deg + 0.06).min(contact_deg);
                }
            }
            s.tick();
            if checking_ticks > 0 && !matches!(s.c.state, State::CheckingWinding { .. }) {
                torque_after_check.push(s.c.torque_nm);
            }
            if s.state() == RunState::Done {
                break;
            }
        }
        // The allowance at the check's torque: 0.3° and twice 12°/N·m over its extra 0.08 N·m,
        // some 2.2° (less on the way up).
        let allowed_ticks = (2.5 / deg_per_tick) as u32;
        assert!(
            checking_ticks > 0 && checking_ticks <= allowed_ticks,
            "{deg_per_tick}: {checking_ticks}"
        );
        assert_eq!(torque_after_check.first(), Some(&0.0));
        assert!(!s.c.run.winding_checked);
        let result = s.c.result().expect("a result");
        assert!(result.flags.contains(QualityFlags::FORCE_SENSITIVE));
    }
}

#[test]
fn no_check_where_it_would_press_past_twice_the_force_or_outrun_the_run() {
    // A third of the default force on 26 V: the check's torque (0.45 N·m) is over twice the
    // held one (0.19).
    let feather = RunParams {
        target_force_n: RunParams::DEFAULT.target_force_n * 0.3,
        ..LIGHT_RUN
    };
    let mut s = on_supply(26.0);
    let (result, _) = run_into_contact(&mut s, feather, LIGHT_CONTACT);
    assert_eq!(s.c.run.check_compliance_deg_per_nm, 0.0, "no check started");
    assert!(result.flags.contains(QualityFlags::FORCE_SENSITIVE));
    // The light run with time left for its hold and probe but not for the check (its ramp,
    // 200 ms, the release and 100 ms): no check, and no `MaxRunTime` either.
    let (_, jam_ms) = timed_run_into_contact(26.0, LIGHT_RUN, LIGHT_CONTACT);
    let hurried = RunParams {
        max_time_ms: jam_ms + 500,
        ..LIGHT_RUN
    };
    let mut s = on_supply(26.0);
    let (result, _) = run_into_contact(&mut s, hurried, LIGHT_CONTACT);
    assert_eq!(s.c.run.check_compliance_deg_per_nm, 0.0, "no check started");
    assert!(result.flags.contains(QualityFlags::FORCE_SENSITIVE));
}

#[test]
fn abort_is_safe_in_the_next_tick_of_the_winding_check() {
    let mut s = on_supply(26.0);
    s.start(LIGHT_RUN);
    for _ in 0..20_000 {
        let contact_deg = 60.0 + 12.0 * s.c.torque_nm;
        if s.angle_deg < contact_deg && s.c.torque_nm > 0.0 {
            s.angle_deg = (s.angle_deg + 0.06).min(contact_deg);
        }
        s.tick();
        if matches!(s.c.state, State::CheckingWinding { .. }) {
            break;
        }
    }
    assert!(
        matches!(s.c.state, State::CheckingWinding { .. }),
        "no check reached"
    );
    s.host().abort();
    let out = s.tick();
    assert!(!out.awake && out.duty == 0.0);
    assert_eq!(s.state(), RunState::Idle);
}

#[test]
fn a_hold_that_drifts_is_noisy_and_a_noisy_still_one_is_not() {
    // 0.0035° a tick: still by the regression's band, 0.14° (6.4 LSB) between the hold's halves.
    // It never stops: the hold is taken again (`HOLD_CREEP_LSB`) until the retries run out, then
    // read and flagged (and, the hub having turned on that far, force-sensitive too).
    let creeping = run_on_contact(0.0, 0.0035);
    assert!(
        creeping.flags.contains(QualityFlags::NOISY_HOLD),
        "{:?}",
        creeping.flags
    );
    // ±5 LSB of noise on a still jam: a spread of 10 LSB (flagged before protocol 2.3), no drift.
    let mut s = on_supply(12.0);
    s.start(RunParams::DEFAULT);
    let lsb_deg = 360.0 / f32::from(COUNTS_PER_TURN);
    for i in 0..5000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            s.angle_deg = (s.angle_deg + 0.06).min(60.0);
        }
        let mut inputs = s.inputs();
        if s.state() == RunState::Jammed {
            let noise = if i % 2 == 0 { 5.0 } else { -5.0 };
            inputs.angle_deg = Ok(s.angle_deg + noise * lsb_deg);
        }
        s.tick_with(&inputs);
        if s.state() == RunState::Done {
            break;
        }
    }
    assert_eq!(
        s.c.result().expect("a result").flags.distrusting(),
        QualityFlags::empty()
    );
}

#[test]
fn a_creep_that_stops_is_waited_out_and_read_where_the_hub_came_to_rest() {
    // 0.002° a tick for 120 ticks of the jam (0.24°, 0.67 µm): the first hold drifts 3.6 LSB,
    // it is taken again, and the reading is the resting angle, unflagged.
    let result = run_on_scripted_contact(0.0, 0.002, 120, false);
    assert_eq!(result.flags.distrusting(), QualityFlags::empty());
    assert!(
        (result.angle_deg - 60.24).abs() < 0.01,
        "{}",
        result.angle_deg
    );
}

#[test]
fn a_creep_that_cannot_be_waited_out_for_want_of_time_is_flagged() {
    // The creep of the test above, on a run whose time limit leaves no room to take the hold
    // again: it is read creeping, so flagged, not read short without a flag.
    let contact = (0.0, 0.002, 120, false);
    let (unhurried, at_jam_ms) = timed_run_into_contact(12.0, RunParams::DEFAULT, contact);
    assert_eq!(unhurried.flags.distrusting(), QualityFlags::empty());
    let hurried = RunParams {
        max_time_ms: at_jam_ms + HOLD_RETRY_RESERVE_MS - 100,
        ..RunParams::DEFAULT
    };
    let read = run_on_supply_into_contact(12.0, hurried, contact);
    assert!(
        read.flags.contains(QualityFlags::NOISY_HOLD),
        "{:?}",
        read.flags
    );
}

#[test]
fn a_soft_contact_that_static_friction_holds_against_the_probe_is_force_sensitive() {
    // The hub follows the contact while the torque ramps, and not at all once the jam is held:
    // the probe sees a rigid contact, the approach a soft one (40°/N·m: 5.6 µm for 10 % of
    // torque).
    let soft = run_on_scripted_contact(40.0, 0.0, 0, true);
    assert_eq!(soft.flags.distrusting(), QualityFlags::FORCE_SENSITIVE);
    // A stiff one (1°/N·m, 0.14 µm) is not.
    let stiff = run_on_scripted_contact(1.0, 0.0, 0, true);
    assert_eq!(stiff.flags.distrusting(), QualityFlags::empty());
}

/// A scripted run that jams at 60°, then, backing off, turns back 0.03° a tick while pulled
/// back, until it stalls `stall_deg` behind where the release left it (`None`: never). The
/// result and the ticks spent after the release.
fn run_backing_off(s: &mut Script, stall_deg: Option<f32>) -> (KerfResult, u32) {
    s.start(RunParams::DEFAULT);
    let mut released_at: Option<(f32, u32)> = None;
    for tick in 0..8000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 && released_at.is_none() {
            s.angle_deg += 0.06;
        }
        if matches!(s.c.state, State::BackingOff { .. }) {
            let from_deg = *released_at.get_or_insert((s.angle_deg, tick));
            let face_deg = stall_deg.map_or(f32::NEG_INFINITY, |d| from_deg.0 - d);
            if s.c.torque_nm < 0.0 && s.angle_deg - 0.03 >= face_deg {
                s.angle_deg -= 0.03;
            }
        }
        s.tick();
        match s.state() {
            RunState::Done => {
                let spent = released_at.map_or(0, |(_, at)| tick - at);
                return (*s.c.result().unwrap(), spent);
            }
            RunState::Fault(f) => panic!("fault {f:?}"),
            _ => {}
        }
    }
    panic!("the run did not end");
}

/// A scripted run with `params` that jams at 60° (the scripted hub does not turn back), stepped
/// to its end (`Done` or a fault); whether it backed off on the way.
fn run_to_the_end(s: &mut Script, params: RunParams) -> bool {
    s.start(params);
    let mut backed_off = false;
    for _ in 0..8000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            s.angle_deg += 0.06;
        }
        s.tick();
        backed_off |= matches!(s.c.state, State::BackingOff { .. });
        if matches!(s.state(), RunState::Done | RunState::Fault(_)) {
            return backed_off;
        }
    }
    panic!("the run did not end");
}

/// A scripted run that jams at 60°, stepped until it has been backing off `ticks` ticks (the
/// scripted hub does not turn back).
fn run_into_back_off(s: &mut Script, ticks: u32) {
    s.start(RunParams::DEFAULT);
    for _ in 0..8000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 {
            s.angle_deg += 0.06;
        }
        s.tick();
        if matches!(s.c.state, State::BackingOff { ticks: t, .. } if t >= ticks) {
            return;
        }
    }
    panic!("the run did not back off");
}

#[test]
fn backing_off_measures_the_play_and_reads_the_kerf_with_it() {
    let gauge = kerfmeter_protocol::GaugeGeometry::PAPER;
    let model = kerf_from_angle(&gauge, 60.0);
    // The far faces are 1.2° nearer than the model's two plays: each side 0.6° shorter.
    let turn_deg = 2.0 * model.play_deg - 1.2;
    let mut s = Script::new();
    let (r, _) = run_backing_off(&mut s, Some(turn_deg));
    assert!((r.play_deg - turn_deg / 2.0).abs() < 0.05, "{r:?}");
    let expected_um = gauge.pitch_um_per_deg * (60.0 - turn_deg / 2.0);
    assert!(
        (r.kerf_um - expected_um).abs() < 0.15,
        "{r:?} vs {expected_um}"
    );
    assert!(r.kerf_um > model.kerf_um + 1.0, "{r:?}");
    assert!(!r.flags.contains(QualityFlags::PLAY_MODELLED), "{r:?}");
    // The back-off's turn is not in the sweep: its angles all stay at the jam's side.
    assert!(s.c.samples().iter().all(|x| x.torque_nm >= 0.0));
    // The motor is safe once it is done.
    assert!(s.tick().is_safe());
}

#[test]
fn no_stall_or_one_outside_the_window_keeps_the_models_play_flagged() {
    let model = kerf_from_angle(&kerfmeter_protocol::GaugeGeometry::PAPER, 60.0);
    let modelled = |r: &KerfResult| {
        (r.play_deg - model.play_deg).abs() < 0.01
            && (r.kerf_um - model.kerf_um).abs() < 0.01
            && r.flags.contains(QualityFlags::PLAY_MODELLED)
    };
    // An inset that gives way: the hub turns back on, past the longest play it may find.
    let (r, spent) = run_backing_off(&mut Script::new(), None);
    assert!(modelled(&r), "{r:?}");
    assert!(spent < BACK_OFF_MAX_TICKS, "{spent}");
    // A stall far short of the model's play (a hub caught on something).
    let short_deg = 2.0 * (model.play_deg - BACK_OFF_MAX_SHORTER_DEG) - 0.5;
    let (r, _) = run_backing_off(&mut Script::new(), Some(short_deg));
    assert!(modelled(&r), "{r:?}");
    // A stall past the model's play by more than the cut can lengthen it (an inset that
    // slipped back under the pull, then held): it would read the kerf low.
    let long_deg = 2.0 * (model.play_deg + BACK_OFF_MAX_LONGER_DEG) + 0.5;
    let (r, _) = run_backing_off(&mut Script::new(), Some(long_deg));
    assert!(modelled(&r), "{r:?}");
    // A little longer than the model's, within the window: taken.
    let (r, _) = run_backing_off(&mut Script::new(), Some(2.0 * model.play_deg + 0.4));
    assert!((r.play_deg - (model.play_deg + 0.2)).abs() < 0.05, "{r:?}");
    assert!(!r.flags.contains(QualityFlags::PLAY_MODELLED), "{r:?}");
}

#[test]
fn the_back_off_starts_where_the_hub_comes_to_rest_after_the_release() {
    // The hub springs back 0.6° over 30 ticks after the release, unpulled; the back-off's turn
    // is counted from where it came to rest, so the play is the faces' and not 0.3° longer.
    let model = kerf_from_angle(&kerfmeter_protocol::GaugeGeometry::PAPER, 60.0);
    let turn_deg = 2.0 * model.play_deg - 1.0;
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let (mut released, mut relaxed, mut rest_deg) = (false, 0, None);
    for _ in 0..8000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 && !released {
            s.angle_deg += 0.06;
        }
        if matches!(s.c.state, State::BackingOff { .. }) {
            released = true;
            if relaxed < 30 {
                relaxed += 1;
                s.angle_deg -= 0.02;
            } else {
                let rest = *rest_deg.get_or_insert(s.angle_deg);
                if s.c.torque_nm < 0.0 && s.angle_deg - 0.03 >= rest - turn_deg {
                    s.angle_deg -= 0.03;
                }
            }
        }
        s.tick();
        if s.state() == RunState::Done {
            break;
        }
    }
    let r = s.c.result().unwrap();
    assert!((r.play_deg - turn_deg / 2.0).abs() < 0.05, "{r:?}");
}

#[test]
fn the_result_is_published_when_the_run_ends_and_a_fault_keeps_it_modelled() {
    // While backing off the result is not out yet (it changes when the play is measured); a
    // fault during the back-off ends the run with the result read with the model's play.
    let model = kerf_from_angle(&kerfmeter_protocol::GaugeGeometry::PAPER, 60.0);
    let mut s = Script::new();
    run_into_back_off(&mut s, 40);
    assert!(s.c.result().is_none());
    let inputs = Inputs {
        driver_fault: true,
        ..s.inputs()
    };
    assert!(s.tick_with(&inputs).is_safe());
    assert_eq!(s.state(), RunState::Fault(Fault::DriverFault));
    let r = s.c.result().expect("the reading stays");
    assert!(r.flags.contains(QualityFlags::PLAY_MODELLED), "{r:?}");
    assert!((r.kerf_um - model.kerf_um).abs() < 0.01, "{r:?}");
}

#[test]
fn no_back_off_after_a_light_hold_or_with_the_encoder_on_the_motor() {
    // A light hold's pull could drag the inset out; an encoder on the motor shaft would count
    // the gearbox's backlash into the turn: the model's play, flagged.
    let light = RunParams {
        target_force_n: 10.0,
        ..RunParams::DEFAULT
    };
    let motor_shaft = DeviceConfig {
        encoder_placement: kerfmeter_protocol::EncoderPlacement::MotorShaft,
        ..DeviceConfig::DEFAULT
    };
    for (config, params) in [
        (DeviceConfig::DEFAULT, light),
        (motor_shaft, RunParams::DEFAULT),
    ] {
        let mut s = Script::new();
        s.c = Controller::new(config);
        // The scripted hub stands at its mark (a motor-shaft encoder's turn, confirmed).
        assert_eq!(s.c.confirm_hub_at_zero(), Ok(()));
        s.tick();
        assert!(!run_to_the_end(&mut s, params));
        assert_eq!(s.state(), RunState::Done);
        let r = s.c.result().unwrap();
        assert!(r.flags.contains(QualityFlags::PLAY_MODELLED), "{r:?}");
    }
}

#[test]
fn a_hub_that_stands_still_without_the_full_pull_is_not_a_stall() {
    // Turning back, the hub sticks 1° short of the far faces (the model's two plays): from there
    // it moves only while pulled at the cap, 0.25° at a time, and stands still in between while
    // the pull builds up again. Those stops are not stalls: the play is taken at the faces.
    let model = kerf_from_angle(&kerfmeter_protocol::GaugeGeometry::PAPER, 60.0);
    let faces_deg = 2.0 * model.play_deg;
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    let mut from_deg = None;
    for _ in 0..8000 {
        if s.angle_deg < 60.0 && s.c.torque_nm > 0.0 && from_deg.is_none() {
            s.angle_deg += 0.06;
        }
        if matches!(s.c.state, State::BackingOff { .. }) {
            let from = *from_deg.get_or_insert(s.angle_deg);
            let turned = from - s.angle_deg;
            let pulled_full = s.c.torque_nm <= -BACK_OFF_STALL_SHARE * BACK_OFF_MAX_TORQUE_NM;
            if s.c.torque_nm < 0.0 && turned < faces_deg - 1.0 {
                s.angle_deg -= 0.03;
            } else if pulled_full && turned + 0.25 <= faces_deg {
                s.angle_deg -= 0.25;
            }
        }
        s.tick();
        if s.state() == RunState::Done {
            break;
        }
    }
    let r = s.c.result().unwrap();
    assert!(
        (r.play_deg - model.play_deg).abs() < 0.15,
        "{r:?} vs {model:?}"
    );
}

#[test]
fn no_back_off_without_the_run_time_for_it_and_abort_stops_it_safe() {
    // A run whose time left cannot hold the longest back-off ends without one.
    let mut s = Script::new();
    let short = RunParams {
        max_time_ms: 2_000,
        ..RunParams::DEFAULT
    };
    assert!(!run_to_the_end(&mut s, short));
    assert_eq!(s.state(), RunState::Done);
    // Abort while backing off: safe at once, and the result read so far stays.
    let mut s = Script::new();
    run_into_back_off(&mut s, 50);
    s.host().abort();
    assert!(s.tick().is_safe());
    assert!(s.c.result().is_some());
}

#[test]
fn a_contact_that_crushed_on_the_way_in_is_flagged_force_sensitive() {
    // The hub meets the contact at 30°, where the ramp's target is high; the contact crushes:
    // the hub presses on at 30°/s while the torque stands over 0.3 N·m, until 80°, where the
    // falling target holds it. The contact bore far more than the hold's torque and keeps it:
    // the probe cannot move the hub. Flagged; a rigid contact met at 80° is not.
    let run = |crush: bool| {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        for _ in 0..20_000 {
            let free = s.angle_deg < 30.0 && s.c.torque_nm > 0.0;
            let crushing = crush && s.angle_deg < 80.0 && s.c.torque_nm > 0.3;
            let reaching = !crush && s.angle_deg < 80.0 && s.c.torque_nm > 0.0;
            if free || reaching {
                s.angle_deg += 0.06;
            } else if crushing && matches!(s.c.state, State::Ramping) {
                s.angle_deg += 0.03;
            }
            s.tick();
            if matches!(s.state(), RunState::Done | RunState::Fault(_)) {
                break;
            }
        }
        *s.c.result().expect("a result")
    };
    let crushed = run(true);
    assert!(
        crushed.flags.contains(QualityFlags::FORCE_SENSITIVE),
        "{:?}",
        crushed.flags
    );
    let rigid = run(false);
    assert_eq!(
        rigid.flags.distrusting(),
        QualityFlags::empty(),
        "{rigid:?}"
    );
}

#[test]
fn a_contact_that_gave_way_at_the_runs_force_along_the_spiral_is_flagged_force_sensitive() {
    // The hub meets the contact at 30°, where it gives way (crushing past its yield): from there
    // the hub turns on, too fast for the pressing test (60 °/s), whenever the torque stands at
    // 90 % of the target for the run's force at its angle, to 60°, where the contact holds. The
    // target falls along the spiral, so the torque hardly rises from the approach's start to
    // the hold, while the force rises by a fifth over 30° of turn: a compliance far past the
    // limit, which the probe (held by static friction) cannot see. Flagged (it was not: on the
    // twin, a contact yielding at 178 N read 38 µm high, unflagged). Not flagged: a contact
    // that holds at 30°, and the same turn where the probe then moves the hub (0.2°, some 10
    // LSB: the probe measured the contact, and a free hub crawling to the jam turns as far).
    let run = |gives_way: bool, probe_moves: bool| {
        let mut s = Script::new();
        let params = RunParams::DEFAULT;
        s.start(params);
        let mut probed_deg = 0.0;
        for _ in 0..20_000 {
            let inset_deg = s.angle_deg - s.c.run.zero_kerf_play_deg;
            let target_nm = torque_for_force_nm(&params, params.target_force_n, inset_deg);
            let ramping = matches!(s.c.state, State::Ramping);
            let free = s.angle_deg < 30.0 && s.c.torque_nm > 0.0;
            let giving = gives_way && ramping && s.angle_deg < 60.0;
            if free || (giving && s.c.torque_nm >= 0.9 * target_nm) {
                s.angle_deg += 0.06;
            }
            if probe_moves && matches!(s.c.state, State::Probing { .. }) && probed_deg < 0.2 {
                s.angle_deg += 0.01;
                probed_deg += 0.01;
            }
            s.tick();
            if matches!(s.state(), RunState::Done | RunState::Fault(_)) {
                break;
            }
        }
        *s.c.result().expect("a result")
    };
    let gave_way = run(true, false);
    assert!(
        gave_way.flags.contains(QualityFlags::FORCE_SENSITIVE),
        "{gave_way:?}"
    );
    for (gives_way, probe_moves) in [(false, false), (true, true)] {
        let r = run(gives_way, probe_moves);
        assert_eq!(
            r.flags.distrusting(),
            QualityFlags::empty(),
            "gives way {gives_way}, probe moves {probe_moves}: {r:?}"
        );
    }
}

#[test]
fn a_contact_that_gave_way_after_the_first_settle_is_flagged_force_sensitive() {
    // A warm winding (30 % more resistive than calibrated): the first settle's estimate raises
    // the factor, and the ramp takes the real torque on up. The contact at 60° bears the first
    // settle; with `gives_way_to`, once the drive stands 6 % above the settle's it crushes and
    // the hub runs on at 100 °/s (faster than the pressing test looks) to where it holds. The
    // turn since the first settle over the force's rise is a compliance far past the limit:
    // flagged, whether the hold's drive ends above the settle's (85°) or, the target falling
    // along the spiral, below it (95°). The same run into a contact that holds at 60° is not.
    let run = |gives_way_to: Option<f32>| {
        let mut s = on_supply(12.0);
        s.winding_factor = 1.3;
        s.start(RunParams::DEFAULT);
        let mut crushed = false;
        for _ in 0..20_000 {
            let drive_v = s.last_out.duty * 12.0;
            let settle_v = s.c.run.first_settle.map(|settle| settle.drive_v);
            crushed |= gives_way_to.is_some() && settle_v.is_some_and(|v| drive_v > 1.06 * v);
            let stop_deg = gives_way_to.filter(|_| crushed).unwrap_or(60.0);
            if s.angle_deg < stop_deg && s.c.torque_nm > 0.0 {
                s.angle_deg = (s.angle_deg + 0.1).min(stop_deg);
            }
            s.tick();
            if matches!(s.state(), RunState::Done | RunState::Fault(_)) {
                break;
            }
        }
        assert_eq!(crushed, gives_way_to.is_some(), "the contact gave way");
        *s.c.result().expect("a result")
    };
    for stop_deg in [85.0, 95.0] {
        let gave_way = run(Some(stop_deg));
        assert!(
            gave_way.flags.contains(QualityFlags::FORCE_SENSITIVE),
            "{stop_deg}: {gave_way:?}"
        );
    }
    let held = run(None);
    assert_eq!(held.flags.distrusting(), QualityFlags::empty(), "{held:?}");
}

#[test]
fn a_pause_short_of_the_contact_is_not_a_give_way() {
    // The hub pauses at 58.5° for 8 ticks at its target torque (static friction in the drive
    // train: the run's first settle is taken there), then creeps on at 10 °/s into a contact
    // that holds at 60°. The force at the hold is the target's, as at the pause: the turn since
    // the first settle measures nothing, and the reading is not flagged (the 1.5° over a rise
    // floored at 5 % would have read as a compliance of 8 µm per 10 % of torque).
    let mut s = on_supply(12.0);
    s.start(RunParams::DEFAULT);
    let mut paused = 0;
    for _ in 0..20_000 {
        let settled = s.c.run.first_settle.is_some();
        if settled && paused < 8 {
            paused += 1;
        } else if s.c.torque_nm > 0.0 {
            let step_deg = if s.angle_deg < 58.5 { 0.06 } else { 0.01 };
            let stop_deg = if settled { 60.0 } else { 58.5 };
            s.angle_deg = (s.angle_deg + step_deg).min(stop_deg);
        }
        s.tick();
        if matches!(s.state(), RunState::Done | RunState::Fault(_)) {
            break;
        }
    }
    let settle_deg = s.c.run.first_settle.expect("a first settle").angle_deg;
    assert!((settle_deg - 58.5).abs() < 0.1, "{settle_deg}");
    let result = s.c.result().expect("a result");
    assert!(result.angle_deg > 59.5, "{result:?}");
    assert_eq!(
        result.flags.distrusting(),
        QualityFlags::empty(),
        "{result:?}"
    );
}
