//! The device behind the link: the controller, the configuration and what `GetInfo` says.
//!
//! [`Device::step`] runs one control tick; [`Device::handle`] (the link's [`Handler`]) answers
//! each request at the time of the last tick. The whole request table is here, one arm per
//! request: every request first counts as host activity for the [`Controller`]'s communication
//! watchdog, then runs, resets, self-tests and their reports go to the controller's typed
//! methods, while `GetInfo` and the configuration are answered here. A new configuration is
//! validated, refused while the motor runs, stored through [`ConfigPersist`] *before* it is
//! applied and acknowledged, and a failed store leaves the old configuration in force
//! (`ErrorCode::Storage`).

use kerfmeter_protocol::{ConfigReport, DeviceConfig, DeviceInfo, ErrorCode, Request, Response};

use crate::config_store::{ConfigPersist, ConfigSource};
use crate::controller::{Controller, Inputs};
use crate::link::Handler;
use crate::motor::MotorOutput;

/// The device's state and request handler, generic over how the configuration is persisted.
pub struct Device<S: ConfigPersist = ()> {
    info: DeviceInfo,
    controller: Controller,
    source: ConfigSource,
    store: S,
    now_us: u64,
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
            store,
            now_us: 0,
        }
    }

    /// What `GetInfo` answers.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// Give back the configuration store (a simulated reboot keeps its flash).
    pub fn into_store(self) -> S {
        self.store
    }

    /// The controller (for inspection).
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// One control tick at `now_us`.
    pub fn step(&mut self, now_us: u64, inputs: &Inputs) -> MotorOutput {
        self.now_us = now_us;
        self.controller.step(now_us, inputs)
    }

    fn config_report(&self) -> Response {
        Response::Config(ConfigReport {
            config: *self.controller.config(),
            defaults_in_use: self.source.defaults_in_use(),
        })
    }

    fn set_config(&mut self, config: &DeviceConfig) -> Response {
        if let Err(field) = config.validate() {
            return Response::Error(ErrorCode::InvalidParam(field));
        }
        if let Some(f) = self.controller.fault() {
            return Response::Error(ErrorCode::Faulted(f));
        }
        if self.controller.is_active() {
            return Response::Error(ErrorCode::Busy);
        }
        // Before saving: a refused configuration must not be the one found at the next boot.
        if let Err(e) = self.controller.check_config_change(config) {
            return Response::Error(e);
        }
        if self.store.save(config).is_err() {
            return Response::Error(ErrorCode::Storage);
        }
        match self.controller.set_config(*config) {
            Ok(()) => {
                self.source = ConfigSource::Stored;
                self.config_report()
            }
            Err(e) => Response::Error(e),
        }
    }
}

impl<S: ConfigPersist> Handler for Device<S> {
    fn handle(&mut self, request: &Request) -> Response {
        self.controller.host_activity(self.now_us);
        let controller = &mut self.controller;
        match request {
            Request::GetInfo => Response::Info(self.info.clone()),
            Request::Run(params) => started(controller.start_run(params)),
            Request::GetStatus => Response::Status(controller.status()),
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
        }
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
            fn save(&mut self, _: &DeviceConfig) -> Result<(), StoreError> {
                if self.0 { Err(StoreError) } else { Ok(()) }
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
        let bad = DeviceConfig {
            gear_ratio: 0.0,
            ..DeviceConfig::DEFAULT
        };
        assert_eq!(
            d.handle(&Request::SetConfig(bad)),
            Response::Error(ErrorCode::InvalidParam(ParamField::GearRatio))
        );
    }
}
