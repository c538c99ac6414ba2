//! The G2's current-sense offset as the firmware learns it on the twin (issue 34): `CS` reads a
//! level of its own while the driver sleeps (`cs_sleep_delta_mv`), so the offset is learnt
//! awake and braking, before each run and each self-test, never from the sleeping driver's
//! readings, and the sleep level, whatever it is, neither trips nor skews anything.

use kerfmeter_protocol::{
    Fault, KerfResult, Request, Response, RunParams, RunState, SelfTestReport, TestOutcome,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{Twin, TwinOptions};

/// How close the learnt offset must come to the plant's awake offset, mV: the ADC's noise
/// (1 mV SD) averaged over a brake window's readings, and its 1 mV steps.
const OFFSET_TOLERANCE_MV: f32 = 1.0;

/// A twin with the G2's awake offset at `offset_mv` and its sleep level `delta_mv` from it,
/// idle (asleep) for a second.
fn idle_twin(offset_mv: f64, delta_mv: f64) -> Twin {
    let mut t = Twin::new(TwinOptions {
        kerf_um: 150.0,
        seed: 3,
        plant: PlantParams {
            cs_offset_mv: offset_mv,
            cs_sleep_delta_mv: delta_mv,
            ..PlantParams::default()
        },
        ..TwinOptions::default()
    });
    t.advance_ticks(1000);
    t
}

/// Tick until the bridge first drives (polling like a host every 10 ms), at most 200 ticks.
fn tick_until_driven(t: &mut Twin) {
    for tick in 0..200 {
        if t.motor_driven() {
            return;
        }
        if tick % 10 == 9 {
            t.request(&Request::GetStatus);
        }
        t.advance_ticks(1);
    }
    panic!("the bridge never drove");
}

/// Poll a started run like a host, every 10 ms: its result or its fault.
fn poll_run(t: &mut Twin) -> Result<KerfResult, Fault> {
    for _ in 0..3000 {
        t.advance_ticks(10);
        match t.request(&Request::GetStatus) {
            Response::Status(s) if s.state == RunState::Done => {
                let Response::Kerf(Some(k)) = t.request(&Request::GetKerf) else {
                    panic!("no result after Done");
                };
                return Ok(k);
            }
            Response::Status(s) => {
                if let RunState::Fault(f) = s.state {
                    return Err(f);
                }
            }
            other => panic!("{other:?}"),
        }
    }
    panic!("the run neither finished nor faulted in 30 s");
}

/// Poll a started self-test like a host until its report comes, at most 2 s.
fn poll_self_test(t: &mut Twin) -> SelfTestReport {
    for _ in 0..200 {
        t.advance_ticks(10);
        if let Response::SelfTest(Some(r)) = t.request(&Request::GetSelfTest) {
            return r;
        }
    }
    panic!("no self-test report in 2 s");
}

/// The learnt offset is the awake one, within [`OFFSET_TOLERANCE_MV`].
fn assert_awake_offset(t: &Twin, offset_mv: f64, when: &str) {
    let learnt = t.current_sense().offset_mv();
    assert!(
        (learnt - offset_mv as f32).abs() <= OFFSET_TOLERANCE_MV,
        "{when}: learnt {learnt} mV, the G2's offset awake is {offset_mv} mV (asleep {} mV)",
        t.plant().params().cs_offset_mv + t.plant().params().cs_sleep_delta_mv
    );
}

/// A run from a sleeping driver: by the time the bridge first drives, the offset is the awake
/// one, learnt in the brake before it; the run measures as well as at any sleep level. With the
/// old rule (every idle reading within 30–80 mV taken for the offset) the first, second and
/// last cases learn the sleep level (70, 75 and 80 mV), and the current reads 3–10 A low at the
/// duty floor (0.6–2 A at full duty).
#[test]
fn a_run_learns_the_offset_awake_not_from_the_sleeping_driver() {
    for (offset_mv, delta_mv) in [(58.0, 12.0), (45.0, 30.0), (50.0, -50.0), (40.0, 40.0)] {
        let mut t = idle_twin(offset_mv, delta_mv);
        assert_eq!(t.device().controller().fault(), None, "{delta_mv} mV idle");
        assert_eq!(t.request(&Request::Run(RunParams::DEFAULT)), Response::Ok);
        tick_until_driven(&mut t);
        assert_awake_offset(&t, offset_mv, &format!("{delta_mv} mV, first drive"));
        let k = poll_run(&mut t).unwrap_or_else(|f| panic!("{delta_mv} mV: {f:?}"));
        let truth = t.plant().truth_um(&RunParams::DEFAULT);
        assert!(
            (f64::from(k.kerf_um) - truth).abs() < 3.0,
            "{delta_mv} mV: {} vs {truth}",
            k.kerf_um
        );
        assert_awake_offset(&t, offset_mv, &format!("{delta_mv} mV, after the run"));
        assert!(t.motor_safe());
    }
}

/// While the driver sleeps, `CS` is no current and no offset: at either end of the sleep
/// level's range an idle device neither latches `OverCurrent` (the old rule ignored a sleep
/// level above its band, and read 105 mV as 13.75 A at the duty floor) nor moves its offset.
#[test]
fn the_sleep_level_neither_trips_nor_becomes_the_offset() {
    for (offset_mv, delta_mv) in [(65.0, 40.0), (40.0, -65.0), (50.0, 10.0)] {
        let mut t = idle_twin(offset_mv, delta_mv);
        for _ in 0..100 {
            t.advance_ticks(10);
            t.request(&Request::GetStatus);
        }
        assert_eq!(
            t.device().controller().run_state(),
            RunState::Idle,
            "{delta_mv} mV"
        );
        // Nothing awake yet: the offset is the nominal one it started with.
        let learnt = t.current_sense().offset_mv();
        assert_eq!(learnt, 50.0, "{delta_mv} mV");
    }
}

/// The self-test learns the offset in its encoder phase, braking, before the direction check
/// drives; its torque constant passes at either end of the sleep level's range.
#[test]
fn a_self_test_learns_the_offset_awake_before_it_drives() {
    for (offset_mv, delta_mv) in [(45.0, 30.0), (60.0, -60.0)] {
        let mut t = idle_twin(offset_mv, delta_mv);
        assert_eq!(t.request(&Request::SelfTest), Response::Ok);
        tick_until_driven(&mut t);
        assert_awake_offset(&t, offset_mv, &format!("{delta_mv} mV, first drive"));
        let report = poll_self_test(&mut t);
        assert_eq!(
            report.torque_per_duty_nm.outcome,
            TestOutcome::Pass,
            "{delta_mv} mV: {report:?}"
        );
    }
}
