//! The supply and the driver's electrical faults as the firmware meets them on the twin: a supply
//! that sags into the G2's under-voltage lockout, and FLT shared by the lockout and the injected
//! `driver-fault`.

use kerfmeter_protocol::{
    Conditions, DeviceConfig, ErrorCode, Fault, Request, Response, RunParams, RunState,
};
use kerfmeter_twin::plant::PlantParams;
use kerfmeter_twin::{InjectedFault, Twin, TwinOptions};

/// A twin on a weak supply: 9.5 V, inside the rated range, through 2 Ω sags below the 5.8 V
/// lockout once the bridge drives the motor with more than about 4.8 V (duty × bus), some
/// 0.32 N·m: less than [`WEAK_SUPPLY_RUN`] asks for.
fn weak_supply_twin() -> Twin {
    let mut t = Twin::new(TwinOptions {
        kerf_um: 150.0,
        seed: 3,
        plant: PlantParams {
            supply_v: 9.5,
            supply_source_ohm: 2.0,
            ..PlantParams::default()
        },
        ..TwinOptions::default()
    });
    t.advance_ticks(5);
    t
}

/// A run whose torque cap (0.35 N·m) the weak supply reaches at idle (it needs 5.3 V), but not
/// under its own load.
const WEAK_SUPPLY_RUN: RunParams = RunParams {
    max_torque_nm: 0.35,
    ..RunParams::DEFAULT
};

/// Tick until the controller latches a fault (polling like a host), or give up after 5 s.
fn run_until_fault(t: &mut Twin) -> Option<Fault> {
    for _ in 0..500 {
        t.advance_ticks(10);
        t.request(&Request::GetStatus);
        if let RunState::Fault(f) = t.device().controller().run_state() {
            return Some(f);
        }
    }
    None
}

#[test]
fn a_supply_sagging_into_the_lockout_faults_as_driver_fault_and_recovers() {
    let mut t = weak_supply_twin();
    assert!(!t.plant().driver_fault(), "idle, the bus is at the supply");
    assert_eq!(t.request(&Request::Run(WEAK_SUPPLY_RUN)), Response::Ok);
    assert_eq!(run_until_fault(&mut t), Some(Fault::DriverFault));
    assert!(t.motor_safe());
    // The bridge asleep, the bus recovers and the driver releases FLT: the fault clears and
    // stays cleared.
    t.advance_ticks(1);
    assert!(!t.plant().driver_fault());
    assert_eq!(t.request(&Request::ClearFault), Response::Ok);
    t.advance_ticks(100);
    assert_eq!(t.device().controller().run_state(), RunState::Idle);
}

#[test]
fn a_supply_below_the_release_level_holds_flt_low_from_power_up() {
    let mut t = Twin::new(TwinOptions {
        plant: PlantParams {
            supply_v: 6.0,
            ..PlantParams::default()
        },
        ..TwinOptions::default()
    });
    // The supply is converted one tick in ten, as on the board: its first reading comes at the
    // eleventh tick.
    t.advance_ticks(15);
    assert!(t.plant().driver_fault());
    // An idle condition, not a latched fault: reported, blocking a run, not the configuration.
    let Response::Status(status) = t.request(&Request::GetStatus) else {
        panic!("a status")
    };
    assert_eq!(status.state, RunState::Idle);
    let both = Conditions::DRIVER_FAULT.union(Conditions::SUPPLY_OUT_OF_RANGE);
    assert_eq!(status.conditions, both);
    // 6 V and a 1 % gain error, filtered from a first noisy reading a few ticks ago.
    assert!(status.supply_v.is_some_and(|v| v < 6.3), "{status:?}");
    assert_eq!(
        t.request(&Request::Run(RunParams::DEFAULT)),
        Response::Error(ErrorCode::Blocked(both))
    );
    assert!(matches!(
        t.request(&Request::SetConfig(DeviceConfig::DEFAULT)),
        Response::Config(_)
    ));
    t.advance_ticks(100);
    assert!(t.motor_safe());
    assert_eq!(t.device().controller().run_state(), RunState::Idle);
}

#[test]
fn repairing_the_injected_driver_fault_does_not_release_a_locked_out_driver() {
    // Both hold FLT low; a repair (which `ClearFault` does) removes only the injected one.
    let mut t = Twin::new(TwinOptions {
        fault: Some(InjectedFault::DriverFault),
        plant: PlantParams {
            supply_v: 6.0,
            ..PlantParams::default()
        },
        ..TwinOptions::default()
    });
    // Past the first supply conversion (one tick in ten).
    t.advance_ticks(15);
    assert_eq!(t.request(&Request::ClearFault), Response::Ok);
    t.advance_ticks(5);
    assert_eq!(t.options().fault, None, "the injection is repaired");
    assert!(t.plant().driver_fault(), "still locked out");
    let controller = t.device().controller();
    assert_eq!(controller.run_state(), RunState::Idle, "nothing re-latched");
    assert_eq!(
        controller.conditions(),
        Conditions::DRIVER_FAULT.union(Conditions::SUPPLY_OUT_OF_RANGE)
    );
}
