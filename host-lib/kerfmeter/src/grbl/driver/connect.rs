//! Connecting: the port or socket opened, GRBL's banner awaited (through an ESP32's boot log),
//! a silent controller woken with a soft reset unless it is busy, the alarm, version, settings,
//! laser mode and `S` max checked, and the travel read.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use kerfmeter_grbl::realtime::{self, SOFT_RESET};
use kerfmeter_grbl::settings::{LASER_MODE, MAX_POWER_S};
use kerfmeter_grbl::{codes, commands};

use super::super::error::CutterError;
use super::super::protocol::{
    MachineState, Reply, declared_s_max, parse_reply, rx_buffer_from_build_info, window_for,
};
use super::super::transport::{CutterAddress, Link, open_serial, open_tcp};
use super::{BOOT_LOG_MAX, BOOT_LOG_QUIET, ConnectOptions, Cutter, SEEN_KEPT};

impl Cutter {
    /// Connect to the cutter at `address` (see [`CutterAddress`]).
    pub fn open(address: &CutterAddress, options: ConnectOptions) -> Result<Self, CutterError> {
        Self::open_cancellable(address, options, Arc::new(AtomicBool::new(false)))
    }

    /// [`Cutter::open`], given up with [`CutterError::ConnectCancelled`] as soon as `cancel` is
    /// set (Ctrl-C while a name resolves or a controller boots).
    pub fn open_cancellable(
        address: &CutterAddress,
        options: ConnectOptions,
        cancel: Arc<AtomicBool>,
    ) -> Result<Self, CutterError> {
        let link = match address {
            CutterAddress::Serial { path, baud } => open_serial(path, *baud)?,
            CutterAddress::Tcp { host_port } => open_tcp(host_port, &cancel)?,
            #[cfg(feature = "sim")]
            CutterAddress::Sim => {
                return Self::sim_cancellable(Default::default(), options, cancel);
            }
            #[cfg(not(feature = "sim"))]
            CutterAddress::Sim => {
                return Err(CutterError::Sim(
                    "this program was built without the `sim` feature".into(),
                ));
            }
            // A Ruida controller speaks no GRBL: `crate::ruida::RuidaCutter` drives it.
            CutterAddress::Ruida { .. } | CutterAddress::RuidaSim => {
                return Err(CutterError::BadAddress(address.to_string()));
            }
        };
        Self::connect_cancellable(link, address.to_string(), options, cancel)
    }

    /// Talk to a controller on an open byte stream (reads must time out within milliseconds):
    /// wait for its banner (or wake it with a soft reset), refuse or unlock an alarm, and check
    /// laser mode, as [`ConnectOptions`] say.
    pub fn connect(
        link: Box<dyn Link>,
        address: String,
        options: ConnectOptions,
    ) -> Result<Self, CutterError> {
        Self::connect_cancellable(link, address, options, Arc::new(AtomicBool::new(false)))
    }

    /// [`Cutter::connect`], given up as soon as `cancel` is set.
    pub fn connect_cancellable(
        link: Box<dyn Link>,
        address: String,
        options: ConnectOptions,
        cancel: Arc<AtomicBool>,
    ) -> Result<Self, CutterError> {
        let mut cutter = Self {
            link,
            address,
            incoming: Vec::new(),
            options,
            version: String::new(),
            settings: std::collections::BTreeMap::new(),
            notes: Vec::new(),
            in_job: false,
            alarm_before_banner: None,
            flavour: None,
            window: super::super::protocol::RX_BUFFER_LEN,
            travel: None,
            cancel,
            connecting: true,
            #[cfg(feature = "sim")]
            sim: None,
        };
        cutter.handshake()?;
        cutter.connecting = false;
        Ok(cutter)
    }

    pub(super) fn handshake(&mut self) -> Result<(), CutterError> {
        // The wait for a banner is extended while a controller prints its boot log: the error
        // says how long it really was.
        let started = Instant::now();
        let mut seen = Vec::new();
        if !self.await_banner(self.options.banner_wait, &mut seen)? {
            // A networked controller need not greet, and may be running another client's job:
            // a reset would abort it, so ask first.
            self.refuse_if_busy(&mut seen)?;
            self.write(&[SOFT_RESET])?;
            if !self.await_banner(self.options.reply_timeout, &mut seen)? {
                return Err(CutterError::NoBanner {
                    address: self.address.clone(),
                    waited_ms: started.elapsed().as_millis() as u64,
                    seen,
                });
            }
        }
        self.check_version()?;
        let mut status = self.status()?;
        if status.state == MachineState::Alarm {
            if !self.options.unlock {
                return Err(self.tagged(self.alarm_at_connect()));
            }
            self.command(commands::UNLOCK)?;
            status = self.status()?;
        }
        if status.state != MachineState::Idle {
            return Err(CutterError::NotIdle {
                state: status.state.to_string(),
            });
        }
        self.read_settings()?;
        self.read_build_info();
        self.check_laser_mode()?;
        self.read_travel()
    }

    /// The character-counting window from `$I`'s receive-buffer size; GRBL's 128 when it does
    /// not say (or refuses `$I`).
    pub(super) fn read_build_info(&mut self) {
        let rx_buffer = self
            .command(commands::BUILD_INFO)
            .ok()
            .and_then(|lines| lines.iter().find_map(|l| rx_buffer_from_build_info(l)));
        self.window = window_for(rx_buffer);
    }

    /// Before waking a silent controller with a reset: refuse one that reports it is busy (a
    /// job, a hold, homing), without resetting it.
    pub(super) fn refuse_if_busy(&mut self, seen: &mut Vec<String>) -> Result<(), CutterError> {
        self.write(&[realtime::STATUS_REPORT])?;
        let deadline = Instant::now() + self.options.reply_timeout;
        while let Some(line) = self.read_line(deadline)? {
            if let Reply::Status(status) = parse_reply(&line) {
                return match status.state {
                    MachineState::Idle | MachineState::Alarm | MachineState::Sleep => Ok(()),
                    state => Err(CutterError::NotIdle {
                        state: state.to_string(),
                    }),
                };
            }
            if seen.len() < SEEN_KEPT {
                seen.push(line);
            }
        }
        Ok(())
    }

    /// Why the controller is in alarm, from what it said since the banner.
    pub(super) fn alarm_at_connect(&self) -> CutterError {
        let code = self.notes.iter().rev().find_map(|n| match parse_reply(n) {
            Reply::Alarm(code) => Some(code),
            _ => None,
        });
        let reason = match code {
            Some(code) => codes::describe_alarm(code).to_owned(),
            None => "it starts locked (homing is enabled, or it was stopped abruptly)".to_owned(),
        };
        CutterError::AlarmAtConnect { code, reason }
    }

    /// `error`, marked as read with GRBL 1.1's meanings when the controller is another
    /// firmware and the error gives a code's meaning.
    pub(super) fn tagged(&self, error: CutterError) -> CutterError {
        match self.flavour {
            Some(flavour) if error.has_code() => CutterError::OtherFlavour {
                flavour,
                error: Box::new(error),
            },
            _ => error,
        }
    }

    /// Refuse a GRBL older than 1.1 (grblHAL and FluidNC, 1.1 and later, pass).
    pub(super) fn check_version(&self) -> Result<(), CutterError> {
        let mut numbers = self.version.split(|c: char| !c.is_ascii_digit());
        let mut next = || numbers.next().and_then(|n| n.parse::<u32>().ok());
        match (next(), next()) {
            (Some(major), Some(minor)) if (major, minor) >= (1, 1) => Ok(()),
            _ => Err(CutterError::OldVersion {
                version: self.version.clone(),
            }),
        }
    }

    pub(super) fn read_settings(&mut self) -> Result<(), CutterError> {
        for line in self.command(commands::SETTINGS)? {
            if let Reply::Setting(number, value) = parse_reply(&line) {
                self.settings.insert(number, value);
            }
        }
        Ok(())
    }

    /// Refuse a program that declares ([`declared_s_max`]) another `S` of full power than this
    /// controller's `$30` (as read at connect): every power in it would be scaled wrong. A
    /// program that declares none is not checked.
    pub fn check_s_max(&self, program: &str) -> Result<(), CutterError> {
        let declared = declared_s_max(program).map_err(|bad| CutterError::BadProgram {
            line: bad.number,
            reason: bad.reason,
        })?;
        let Some(program_s_max) = declared else {
            return Ok(());
        };
        let controller = self.settings.get(&MAX_POWER_S).copied();
        if controller.is_some_and(|c| (c - program_s_max).abs() <= 1e-6 * c.abs().max(1.0)) {
            return Ok(());
        }
        Err(CutterError::SMaxMismatch {
            program: program_s_max,
            controller: controller.map_or("?".into(), |v| v.to_string()),
        })
    }

    pub(super) fn check_laser_mode(&self) -> Result<(), CutterError> {
        let laser_mode = self.settings.get(&LASER_MODE);
        if laser_mode == Some(&1.0) || self.options.allow_without_laser_mode {
            return Ok(());
        }
        Err(CutterError::LaserModeOff {
            value: laser_mode.map_or("?".into(), |v| v.to_string()),
        })
    }

    /// Read until the banner comes (true) or `wait` passes with nothing said for
    /// [`BOOT_LOG_QUIET`] (false): an ESP32 controller prints seconds of boot log before its
    /// banner, so each line extends the wait (by at most [`BOOT_LOG_MAX`] in all). Other lines go
    /// to `seen`.
    pub(super) fn await_banner(
        &mut self,
        wait: Duration,
        seen: &mut Vec<String>,
    ) -> Result<bool, CutterError> {
        let started = Instant::now();
        let latest = started + wait + BOOT_LOG_MAX;
        let mut deadline = started + wait;
        let mut alarm = None;
        while let Some(line) = self.read_line(deadline)? {
            deadline = deadline.max((Instant::now() + BOOT_LOG_QUIET).min(latest));
            match parse_reply(&line) {
                Reply::Banner(version) => {
                    self.version = version;
                    self.flavour = flavour_of(&line);
                    self.notes.clear();
                    self.alarm_before_banner = alarm;
                    return Ok(true);
                }
                Reply::Alarm(code) => {
                    alarm = Some(code);
                    self.note(line.clone());
                }
                Reply::Message(_) => self.note(line.clone()),
                _ => {}
            }
            if seen.len() < SEEN_KEPT {
                seen.push(line);
            }
        }
        Ok(false)
    }
}

/// The firmware a banner names, when it is not GRBL itself.
fn flavour_of(banner: &str) -> Option<&'static str> {
    if banner.starts_with("GrblHAL") {
        Some("grblHAL")
    } else if banner.contains("FluidNC") {
        Some("FluidNC")
    } else {
        None
    }
}
