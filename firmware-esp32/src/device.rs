//! The device behind the link: the controller, the configuration and what `GetInfo` says.
//!
//! [`Device::step`] runs one control tick; [`Device::handle`] (the link's [`Handler`]) answers
//! each request at the time of the last tick. The whole request table is here, one arm per
//! request: every request first counts as host activity for the [`Controller`]'s communication
//! watchdog, then runs, resets, self-tests and their reports go to the controller's typed
//! methods, while `GetInfo` and the configuration are answered here. A new configuration is
//! validated, refused while the motor runs (accepted while a fault is latched or an idle
//! condition stands: the motor is at rest then, and a fault may well be cured by the new
//! configuration), stored through [`ConfigPersist`] *before* it is
//! applied and acknowledged, and a failed store leaves the old configuration in force
//! (`ErrorCode::Storage`). A store may apply a configuration without saving it (no flash
//! partition, or one that holds a newer firmware's record): [`Device::config_saved`] then says
//! so.
//!
//! # Flash only with the motor asleep
//!
//! A save stalls the core for up to hundreds of milliseconds, and no tick runs meanwhile: the
//! bridge holds whatever the last tick applied. So the device saves only when the last tick left
//! the driver asleep. Between ticks the controller may already be at rest while the bridge is
//! still driven (an `Abort` just before the `SetConfig`, in the same pass of link work): the
//! board and the twin hand requests to the device through [`WithMotor`], which then puts the
//! bridge safe itself — the step's worth of output the next tick would apply — before the
//! device saves. Without the motor at hand (a bare [`Device`] as the handler), such a
//! `SetConfig` is refused with `Busy` until a tick has put the driver to sleep.

use kerfmeter_protocol::{
    Conditions, ConfigReport, DeviceConfig, DeviceInfo, Diagnostics, ErrorCode, G2Variant, Request,
    Response, Status,
};

use crate::config_store::{ConfigPersist, ConfigSource, Persisted};
use crate::controller::{Controller, Inputs};
use crate::health::{BootFacts, Health, SenseFacts};
use crate::link::Handler;
use crate::motor::{G2Motor, MotorError, MotorOutput};

/// The device's state and request handler, generic over how the configuration is persisted.
pub struct Device<S: ConfigPersist = ()> {
    info: DeviceInfo,
    controller: Controller,
    source: ConfigSource,
    /// The configuration in force is the one in flash.
    saved: bool,
    store: S,
    now_us: u64,
    /// The last tick left the driver asleep (or nothing has driven it since boot).
    motor_asleep: bool,
    /// What `GetDiagnostics` reports.
    health: Health,
}

impl Device<()> {
    /// A device with the default configuration and no persistence (tests, fuzzing).
    pub fn new(board: &str, boot_id: u32) -> Self {
        Self::with_config(
            board,
            boot_id,
            DeviceConfig::DEFAULT,
            ConfigSource::Missing,
            (),
        )
    }
}

impl<S: ConfigPersist> Device<S> {
    /// A device named `board`, booted with `boot_id`, running `config` (loaded from `source`),
    /// saving new configurations to `store`.
    pub fn with_config(
        board: &str,
        boot_id: u32,
        config: DeviceConfig,
        source: ConfigSource,
        store: S,
    ) -> Self {
        Self {
            info: crate::build::device_info(board, boot_id),
            controller: Controller::new(config),
            source,
            saved: !source.defaults_in_use(),
            store,
            now_us: 0,
            motor_asleep: true,
            health: Health::new(),
        }
    }

    /// What the board read at boot: the last reset, the chip, the ADC's calibration, the
    /// brown-out detector (`GetDiagnostics`; an uncalibrated ADC also stands as
    /// `Conditions::ADC_UNCALIBRATED` in `Status`).
    pub fn set_boot_facts(&mut self, boot: BootFacts) {
        self.health.boot = boot;
    }

    /// The motor driver this device drives: its current-sense gain (which `Hardware::tick`
    /// takes from here) and its safe maximum supply (the controller's supply check).
    pub fn set_driver(&mut self, driver: G2Variant) {
        self.health.driver = driver;
        self.controller.set_driver(driver);
    }

    /// The motor driver (see [`Device::set_driver`]).
    pub fn driver(&self) -> G2Variant {
        self.health.driver
    }

    /// What the last control tick saw of the sensors (`Hardware::tick`).
    pub fn note_sense(&mut self, sense: SenseFacts) {
        self.health.sense = sense;
    }

    /// An ADC conversion was given up and the driver opened again.
    pub fn note_adc_restart(&mut self) {
        self.health.adc_restarts = self.health.adc_restarts.saturating_add(1);
    }

    /// What `GetDiagnostics` answers.
    pub fn diagnostics(&self) -> Diagnostics {
        self.health.diagnostics(&self.controller.status())
    }

    /// What `GetStatus` answers: the controller's, with the conditions the board's facts add.
    pub fn status(&self) -> Status {
        let mut status = self.controller.status();
        let uncalibrated = self.health.boot.adc_uncalibrated();
        status
            .conditions
            .set(Conditions::ADC_UNCALIBRATED, uncalibrated);
        status
    }

    /// What `GetInfo` answers.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// Give back the configuration store (a simulated reboot keeps its flash).
    pub fn into_store(self) -> S {
        self.store
    }

    /// True when the configuration in force is the one in flash: loaded from it, or saved by
    /// the last `SetConfig`. False when it was applied but not saved (it lasts until reboot).
    /// `ConfigReport::saved` reports it, so that `SetConfig` can say "applied but not saved".
    pub fn config_saved(&self) -> bool {
        self.saved
    }

    /// The controller (for inspection).
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// One control tick at `now_us`.
    pub fn step(&mut self, now_us: u64, inputs: &Inputs) -> MotorOutput {
        self.now_us = now_us;
        let out = self.controller.step(now_us, inputs);
        self.motor_asleep = !out.awake;
        out
    }

    /// The last control tick's work ended at `end_us` (see [`Controller::step_finished`]).
    pub fn step_finished(&mut self, end_us: u64) {
        self.controller.step_finished(end_us);
    }

    fn config_report(&self) -> Response {
        Response::Config(ConfigReport {
            config: *self.controller.config(),
            defaults_in_use: self.source.defaults_in_use(),
            saved: self.saved,
        })
    }

    fn set_config(&mut self, config: &DeviceConfig) -> Response {
        if let Err(field) = config.validate() {
            return Response::Error(ErrorCode::InvalidParam(field));
        }
        // A latched fault does not refuse it: the motor is safe then, and asleep by the rule
        // below. At rest, but the last tick's output may still drive the bridge (see the module docs).
        if self.controller.is_active() || !self.motor_asleep {
            return Response::Error(ErrorCode::Busy);
        }
        // Before saving: a refused configuration must not be the one found at the next boot.
        if let Err(e) = self.controller.check_config_change(config) {
            return Response::Error(e);
        }
        let Ok(persisted) = self.store.save(config) else {
            return Response::Error(ErrorCode::Storage);
        };
        match self.controller.set_config(*config) {
            Ok(()) => {
                self.source = ConfigSource::Stored;
                self.saved = persisted == Persisted::Yes;
                self.config_report()
            }
            Err(e) => Response::Error(e),
        }
    }
}

impl<S: ConfigPersist> Handler for Device<S> {
    fn host_activity(&mut self) {
        self.controller.host_activity(self.now_us);
    }

    fn handle(&mut self, request: &Request) -> Response {
        let controller = &mut self.controller;
        match request {
            Request::GetInfo => Response::Info(self.info.clone()),
            Request::Run(params) => started(controller.start_run(params)),
            Request::GetStatus => Response::Status(self.status()),
            Request::GetSamples { from } => match controller.sample_chunk(*from) {
                Ok(chunk) => Response::Samples(chunk),
                Err(e) => Response::Error(e),
            },
            Request::GetKerf => Response::Kerf(controller.result().copied()),
            Request::Reset => started(controller.start_reset()),
            Request::Abort => {
                controller.abort();
                Response::Ok
            }
            Request::ClearFault => {
                controller.clear_fault();
                Response::Ok
            }
            Request::SelfTest => started(controller.start_self_test()),
            Request::GetConfig => self.config_report(),
            Request::SetConfig(config) => self.set_config(config),
            Request::GetSelfTest => Response::SelfTest(controller.self_test_report().copied()),
            Request::ConfirmHubAtZero => started(controller.confirm_hub_at_zero()),
            Request::GetDiagnostics => Response::Diagnostics(self.diagnostics()),
        }
    }
}

/// The motor driver as the device needs it between ticks: put in its safe state at once.
pub trait MotorSafe {
    /// Duty 0, driver asleep.
    fn safe(&mut self) -> Result<(), MotorError>;
}

impl<PWM, DIR, SLP, FLT> MotorSafe for G2Motor<PWM, DIR, SLP, FLT>
where
    PWM: embedded_hal::pwm::SetDutyCycle,
    DIR: embedded_hal::digital::OutputPin,
    SLP: embedded_hal::digital::OutputPin,
    FLT: embedded_hal::digital::InputPin,
{
    fn safe(&mut self) -> Result<(), MotorError> {
        G2Motor::safe(self)
    }
}

/// The device with the motor driver at hand, as the link sees it between ticks: a `SetConfig`
/// that the device would carry out puts the bridge safe first, so that its flash operations
/// never run with the motor driven (see the module docs).
pub struct WithMotor<'a, S: ConfigPersist, M: MotorSafe> {
    /// The device.
    pub device: &'a mut Device<S>,
    /// The motor driver the last tick applied its output to.
    pub motor: &'a mut M,
}

impl<S: ConfigPersist, M: MotorSafe> Handler for WithMotor<'_, S, M> {
    fn handle(&mut self, request: &Request) -> Response {
        let device = &mut *self.device;
        // At rest, the next tick's output is the safe state anyway: apply it now. A driver that
        // fails to go safe leaves the flag down, and the device refuses the save.
        if matches!(request, Request::SetConfig(_))
            && !device.controller.is_active()
            && !device.motor_asleep
        {
            device.motor_asleep = self.motor.safe().is_ok();
        }
        device.handle(request)
    }

    fn host_activity(&mut self) {
        self.device.host_activity();
    }
}

/// `Ok` once started, or why not.
fn started(result: Result<(), ErrorCode>) -> Response {
    match result {
        Ok(()) => Response::Ok,
        Err(e) => Response::Error(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config_store::StoreError;
    use kerfmeter_protocol::ParamField;

    #[test]
    fn answers_info() {
        let mut d = Device::new("twin", 0x1234);
        match d.handle(&Request::GetInfo) {
            Response::Info(i) => {
                assert_eq!(i.boot_id, 0x1234);
                assert_eq!(i.hardware.board.as_str(), "twin");
                assert_eq!(i.protocol, kerfmeter_protocol::PROTOCOL_VERSION);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn every_request_has_an_answer_other_than_unsupported() {
        let mut d = Device::new("twin", 1);
        let requests = [
            Request::GetInfo,
            Request::Run(kerfmeter_protocol::RunParams::DEFAULT),
            Request::GetStatus,
            Request::GetSamples { from: 0 },
            Request::GetKerf,
            Request::Reset,
            Request::Abort,
            Request::ClearFault,
            Request::SelfTest,
            Request::GetConfig,
            Request::SetConfig(DeviceConfig::DEFAULT),
            Request::GetSelfTest,
            Request::ConfirmHubAtZero,
            Request::GetDiagnostics,
        ];
        for r in &requests {
            let answer = d.handle(r);
            assert_ne!(answer, Response::Error(ErrorCode::Unsupported), "{r:?}");
            assert_ne!(answer, Response::Error(ErrorCode::UnknownRequest), "{r:?}");
        }
    }

    #[test]
    fn every_request_feeds_the_communication_watchdog() {
        use crate::controller::{Inputs, PERIOD_US};
        use kerfmeter_protocol::{Fault, RunParams, RunState};

        let timeout_ticks = u64::from(RunParams::DEFAULT.host_timeout_ms) * 1000 / PERIOD_US;
        // Requests that are not the controller's keep a run alive too; no requests do not.
        for keep_alive in [Some(Request::GetInfo), Some(Request::GetConfig), None] {
            let mut d = Device::new("twin", 1);
            let mut inputs = Inputs {
                angle_deg: Ok(0.0),
                diagnostics: None,
                current_a: Some(0.5),
                driver_fault: false,
                supply_v: None,
            };
            d.step(PERIOD_US, &inputs);
            assert_eq!(d.handle(&Request::Run(RunParams::DEFAULT)), Response::Ok);
            for tick in 2..2 * timeout_ticks {
                // A hub creeping on, slowly enough to stay in the run throughout.
                inputs.angle_deg = Ok(tick as f32 * 0.01);
                d.step(tick * PERIOD_US, &inputs);
                if let Some(request) = &keep_alive
                    && tick % 100 == 0
                {
                    // As the link gives every request it receives.
                    d.host_activity();
                    d.handle(request);
                }
            }
            let state = d.controller().run_state();
            match keep_alive {
                Some(_) => assert!(d.controller().is_active(), "{keep_alive:?}: {state:?}"),
                None => assert_eq!(state, RunState::Fault(Fault::HostSilent)),
            }
        }
    }

    #[test]
    fn config_is_validated_stored_and_reported() {
        struct Failing(bool);
        impl ConfigPersist for Failing {
            fn save(&mut self, _: &DeviceConfig) -> Result<Persisted, StoreError> {
                if self.0 {
                    Err(StoreError)
                } else {
                    Ok(Persisted::Yes)
                }
            }
        }
        let mut d = Device::with_config(
            "twin",
            1,
            DeviceConfig::DEFAULT,
            ConfigSource::Corrupt,
            Failing(true),
        );
        match d.handle(&Request::GetConfig) {
            Response::Config(r) => assert!(r.defaults_in_use),
            other => panic!("{other:?}"),
        }
        let new = DeviceConfig {
            gear_ratio: 30.0,
            ..DeviceConfig::DEFAULT
        };
        assert_eq!(
            d.handle(&Request::SetConfig(new)),
            Response::Error(ErrorCode::Storage)
        );
        assert_eq!(
            d.controller().config().gear_ratio,
            21.0,
            "a failed store changes nothing"
        );
        d.store.0 = false;
        match d.handle(&Request::SetConfig(new)) {
            Response::Config(r) => {
                assert_eq!(r.config, new);
                assert!(!r.defaults_in_use);
            }
            other => panic!("{other:?}"),
        }
        assert!(d.config_saved());
        let bad = DeviceConfig {
            gear_ratio: 0.0,
            ..DeviceConfig::DEFAULT
        };
        assert_eq!(
            d.handle(&Request::SetConfig(bad)),
            Response::Error(ErrorCode::InvalidParam(ParamField::GearRatio))
        );
    }

    /// Inputs of a still hub at zero.
    fn still() -> Inputs {
        Inputs {
            angle_deg: Ok(0.0),
            diagnostics: None,
            current_a: Some(0.2),
            driver_fault: false,
            supply_v: None,
        }
    }

    /// A store that records, at each save, whether the fake bridge was safe then.
    struct Watching {
        slp: crate::fakes::pins::FakeOutput,
        saves: Vec<bool>,
    }

    impl ConfigPersist for Watching {
        fn save(&mut self, _: &DeviceConfig) -> Result<Persisted, StoreError> {
            self.saves.push(!self.slp.is_high());
            Ok(Persisted::Yes)
        }
    }

    type FakeMotor = G2Motor<
        crate::fakes::pins::FakePwm,
        crate::fakes::pins::FakeOutput,
        crate::fakes::pins::FakeOutput,
        crate::fakes::pins::FakeInput,
    >;

    /// A device whose run drives a fake motor, just aborted: the controller at rest, the bridge
    /// still driven by the last tick.
    fn aborted_mid_run() -> (Device<Watching>, FakeMotor, crate::fakes::pins::FakeOutput) {
        use crate::fakes::pins::{FakeInput, FakeOutput, FakePwm};
        let slp = FakeOutput::new(false);
        let (mut motor, _) = G2Motor::new(
            FakePwm::new(2047),
            FakeOutput::new(false),
            slp.clone(),
            FakeInput::new(true),
        );
        let store = Watching {
            slp: slp.clone(),
            saves: Vec::new(),
        };
        let mut d = Device::with_config(
            "twin",
            1,
            DeviceConfig::DEFAULT,
            ConfigSource::Stored,
            store,
        );
        let mut now_us = PERIOD_US;
        d.step(now_us, &still());
        assert_eq!(d.handle(&Request::Run(RunParams::DEFAULT)), Response::Ok);
        for _ in 0..50 {
            now_us += PERIOD_US;
            motor.apply(&d.step(now_us, &still())).unwrap();
        }
        assert!(slp.is_high(), "the run drives the motor");
        assert_eq!(d.handle(&Request::Abort), Response::Ok);
        (d, motor, slp)
    }

    use crate::controller::PERIOD_US;
    use kerfmeter_protocol::RunParams;

    #[test]
    fn set_config_is_refused_while_a_run_a_reset_or_a_self_test_is_active() {
        let starts = [
            Request::Run(RunParams::DEFAULT),
            Request::Reset,
            Request::SelfTest,
        ];
        for start in starts {
            let mut d = Device::new("twin", 1);
            d.step(PERIOD_US, &still());
            assert_eq!(d.handle(&start), Response::Ok, "{start:?}");
            assert_eq!(
                d.handle(&Request::SetConfig(DeviceConfig::DEFAULT)),
                Response::Error(ErrorCode::Busy),
                "{start:?}"
            );
        }
    }

    #[test]
    fn a_save_right_after_abort_waits_for_a_tick_that_puts_the_motor_to_sleep() {
        let (mut d, mut motor, slp) = aborted_mid_run();
        let new = DeviceConfig {
            gear_ratio: 30.0,
            ..DeviceConfig::DEFAULT
        };
        assert_eq!(
            d.handle(&Request::SetConfig(new)),
            Response::Error(ErrorCode::Busy)
        );
        assert!(
            d.store.saves.is_empty(),
            "nothing written with the motor driven"
        );
        motor.apply(&d.step(100 * PERIOD_US, &still())).unwrap();
        assert!(!slp.is_high());
        assert!(matches!(
            d.handle(&Request::SetConfig(new)),
            Response::Config(_)
        ));
        assert_eq!(d.store.saves, [true]);
    }

    #[test]
    fn with_the_motor_at_hand_a_save_right_after_abort_puts_the_bridge_safe_first() {
        let (mut d, mut motor, slp) = aborted_mid_run();
        let mut handler = WithMotor {
            device: &mut d,
            motor: &mut motor,
        };
        assert!(matches!(
            handler.handle(&Request::SetConfig(DeviceConfig::DEFAULT)),
            Response::Config(_)
        ));
        assert!(!slp.is_high());
        assert_eq!(
            d.store.saves,
            [true],
            "the bridge was safe when the flash was written"
        );
    }

    #[test]
    fn with_the_motor_at_hand_a_run_is_still_not_interrupted_by_a_save() {
        let (mut d, mut motor, slp) = aborted_mid_run();
        // A new run, driving the motor again.
        let mut now_us = 200 * PERIOD_US;
        motor.apply(&d.step(now_us, &still())).unwrap();
        assert_eq!(d.handle(&Request::Run(RunParams::DEFAULT)), Response::Ok);
        for _ in 0..50 {
            now_us += PERIOD_US;
            motor.apply(&d.step(now_us, &still())).unwrap();
        }
        assert!(slp.is_high());
        let mut handler = WithMotor {
            device: &mut d,
            motor: &mut motor,
        };
        assert_eq!(
            handler.handle(&Request::SetConfig(DeviceConfig::DEFAULT)),
            Response::Error(ErrorCode::Busy)
        );
        assert!(slp.is_high(), "the run's output is left alone");
        assert!(d.store.saves.is_empty());
    }

    #[test]
    fn set_config_is_accepted_and_saved_with_a_fault_latched_once_the_motor_sleeps() {
        let (mut d, mut motor, slp) = aborted_mid_run();
        // A new run that faults on the driver's FLT: the controller latches, safe that tick.
        let mut now_us = 200 * PERIOD_US;
        motor.apply(&d.step(now_us, &still())).unwrap();
        assert_eq!(d.handle(&Request::Run(RunParams::DEFAULT)), Response::Ok);
        now_us += PERIOD_US;
        motor.apply(&d.step(now_us, &still())).unwrap();
        let flt = Inputs {
            driver_fault: true,
            ..still()
        };
        now_us += PERIOD_US;
        motor.apply(&d.step(now_us, &flt)).unwrap();
        assert!(d.controller().fault().is_some());
        assert!(!slp.is_high());
        match d.handle(&Request::SetConfig(DeviceConfig::DEFAULT)) {
            Response::Config(r) => assert!(r.saved, "{r:?}"),
            other => panic!("{other:?}"),
        }
        assert_eq!(d.store.saves, [true], "saved with the driver asleep");
    }

    #[test]
    fn a_config_applied_without_persistence_is_not_claimed_saved() {
        let mut d =
            Device::with_config("twin", 1, DeviceConfig::DEFAULT, ConfigSource::Missing, ());
        assert!(!d.config_saved());
        let new = DeviceConfig {
            gear_ratio: 30.0,
            ..DeviceConfig::DEFAULT
        };
        match d.handle(&Request::SetConfig(new)) {
            Response::Config(r) => {
                assert_eq!(r.config, new);
                assert!(!r.saved, "the report says it was not saved");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(d.controller().config().gear_ratio, 30.0, "applied");
        assert!(!d.config_saved(), "but not saved");
        // A configuration loaded from flash is the saved one.
        let d = Device::with_config("twin", 1, new, ConfigSource::Stored, ());
        assert!(d.config_saved());
    }
}
