//! The brake that starts every run, in which the current sense learns its offset awake
//! (`board::current`): it never drives the motor, it lasts its window, and a fault or an abort
//! during it leaves the motor as anywhere else in a run.

use super::*;
use crate::board::current::OFFSET_WINDOW_TICKS;

/// A run started: each tick of the window brakes, awake, at duty 0, reported as `Engaging`;
/// the first tick after it engages.
#[test]
fn a_run_brakes_awake_for_the_offset_window_before_it_drives() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    for tick in 0..OFFSET_WINDOW_TICKS {
        let out = s.tick();
        assert_eq!(out, MotorOutput::BRAKE, "tick {tick}");
        assert_eq!(s.state(), RunState::Engaging, "tick {tick}");
        assert_eq!(
            s.c.status().elapsed_ms,
            0,
            "the window is not the run's time"
        );
    }
    let out = s.tick();
    assert!(out.awake && out.duty > 0.0, "{out:?}");
}

/// A fault in the window latches, typed, with the motor safe (asleep, duty 0) from that tick:
/// the driver's FLT, an over-current, a current unknown.
#[test]
fn a_fault_while_waking_latches_with_the_motor_safe() {
    type Spoil = fn(&mut Inputs);
    let faults: [(Fault, Spoil); 3] = [
        (Fault::DriverFault, |i| i.driver_fault = true),
        (Fault::OverCurrent, |i| i.current_a = None),
        (Fault::OverCurrent, |i| i.current_a = Some(100.0)),
    ];
    for (fault, spoil) in faults {
        let mut s = Script::new();
        s.start(RunParams::DEFAULT);
        for _ in 0..OFFSET_WINDOW_TICKS / 2 {
            assert_eq!(s.tick(), MotorOutput::BRAKE);
        }
        let mut inputs = s.inputs();
        spoil(&mut inputs);
        assert_eq!(s.tick_with(&inputs), MotorOutput::SAFE, "{fault:?}");
        assert_eq!(s.state(), RunState::Fault(fault));
        assert_eq!(s.tick(), MotorOutput::SAFE, "{fault:?} stays latched");
    }
}

/// An abort in the window ends the run before it drove; no result, the motor safe.
#[test]
fn an_abort_while_waking_leaves_the_motor_safe() {
    let mut s = Script::new();
    s.start(RunParams::DEFAULT);
    s.tick();
    s.host().abort();
    assert_eq!(s.tick(), MotorOutput::SAFE);
    assert_eq!(s.state(), RunState::Idle);
    assert!(s.c.result().is_none());
}

/// A reset from a sleeping driver starts with the same brake (reported as `Resetting`), then
/// drives the hub back.
#[test]
fn a_reset_brakes_awake_for_the_offset_window_before_it_drives() {
    let mut s = Script::new();
    s.angle_deg = 20.0;
    s.tick();
    assert_eq!(s.host().start_reset(), Ok(()));
    for tick in 0..OFFSET_WINDOW_TICKS {
        assert_eq!(s.tick(), MotorOutput::BRAKE, "tick {tick}");
        assert_eq!(s.state(), RunState::Resetting, "tick {tick}");
    }
    let mut driven = false;
    for _ in 0..50 {
        let out = s.tick();
        driven |= out.awake && out.duty > 0.0;
    }
    assert!(driven);
}
