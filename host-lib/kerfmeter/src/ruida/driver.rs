//! The Ruida driver ([`RuidaCutter`]) on the protocol crate's [`UdpLink`]: connect (the status
//! read, the bed size, the head), the head's and the prongs' direct moves, a program's packets,
//! busy/idle polling, and the stop (`D8 01`, then an idle status read) that every failure ends
//! with: [`CutterError::Stopped`] when the controller confirms it, [`CutterError::NotStopped`]
//! (THE LASER MAY STILL BE ON, exit 5) when it cannot be confirmed.

use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use kerfmeter_ruida::link::UdpLink;
use kerfmeter_ruida::register::{MachineStatus, Register, value_to_mm};
use kerfmeter_ruida::{Command, MAGIC};

use super::RuidaFailure;
use super::address::{ProngAxis, RuidaAddress};
use crate::grbl::extent::Start;
use crate::grbl::offsets::{Modal, Offsets};
use crate::grbl::travel::{Reach, Travel, TravelSource};
use crate::grbl::{CutterError, StreamProgress, StreamReport};

/// How long each answer is waited for, and how many times a repeatable packet is sent.
#[derive(Debug, Clone, Copy)]
pub struct Timing {
    /// Per answer.
    pub reply_timeout: Duration,
    /// Sends of a repeatable packet.
    pub tries: usize,
    /// Between status reads while a job runs.
    pub poll: Duration,
    /// How long a stop is given to show an idle machine.
    pub stop_confirm: Duration,
    /// How long an idle machine may stand elsewhere than where a step ends before the step is
    /// taken as not run (a controller slow to start it shows idle at first).
    pub start_grace: Duration,
}

impl Default for Timing {
    fn default() -> Self {
        Self {
            reply_timeout: Duration::from_millis(500),
            tries: 3,
            poll: Duration::from_millis(100),
            stop_confirm: Duration::from_secs(5),
            start_grace: Duration::from_secs(10),
        }
    }
}

/// A connected Ruida controller.
pub struct RuidaCutter {
    pub(super) link: UdpLink,
    pub(super) address: String,
    pub(super) travel: Travel,
    pub(super) axis: ProngAxis,
    pub(super) timing: Timing,
    #[cfg(feature = "sim")]
    pub(super) twin: Option<kerfmeter_ruida::twin::RuidaTwin>,
}

impl RuidaCutter {
    /// Connect to the controller at `address`.
    pub fn open(address: &RuidaAddress, timing: Timing) -> Result<Self, CutterError> {
        let text = format!("ruida:{}:{}", address.host, address.port);
        let open_error = |reason: String| CutterError::Open {
            address: text.clone(),
            reason,
        };
        let addr: SocketAddr = (address.host.as_str(), address.port)
            .to_socket_addrs()
            .map_err(|e| open_error(e.to_string()))?
            .next()
            .ok_or_else(|| open_error("the name resolves to no address".into()))?;
        Self::connect(addr, text, address, timing)
    }

    /// Connect to the controller at `addr` (named `text` in messages).
    pub fn connect(
        addr: SocketAddr,
        text: String,
        address: &RuidaAddress,
        timing: Timing,
    ) -> Result<Self, CutterError> {
        let link = UdpLink::connect_from(
            address.local_port,
            addr,
            MAGIC,
            timing.reply_timeout,
            timing.tries,
        )
        .map_err(|e| CutterError::Open {
            address: text.clone(),
            reason: format!(
                "{e} (answers come to local UDP port {}: is another program, LightBurn or \
                 RDWorks, listening there?)",
                address.local_port
            ),
        })?;
        let mut cutter = Self {
            link,
            address: text,
            travel: placeholder_travel(),
            axis: address.prong_axis,
            timing,
            #[cfg(feature = "sim")]
            twin: None,
        };
        let status = cutter.machine_status("connecting")?;
        if status.is_busy() {
            return Err(cutter.busy(status));
        }
        let bed_mm = cutter.bed_mm(address.bed_mm, address.fallback_bed_mm)?;
        let head_mm = cutter.head_mm()?;
        cutter.travel = travel(bed_mm, address.z_travel_mm, head_mm);
        Ok(cutter)
    }

    /// The address as messages name it.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// The machine's travel: the bed from its registers (or the address), the prongs' axis
    /// from the address; where the head stood when last read.
    pub fn travel(&self) -> Travel {
        self.travel.clone()
    }

    pub(super) fn busy(&self, status: MachineStatus) -> CutterError {
        RuidaFailure::Busy {
            address: self.address.clone(),
            status: status.0,
        }
        .into()
    }

    /// Read `register` while `doing`.
    fn read(&self, register: Register, doing: &'static str) -> Result<u64, CutterError> {
        self.link
            .read(register)
            .map_err(|e| RuidaFailure::from_link(&self.address, doing, e))
    }

    /// The status register.
    pub fn machine_status(&self, doing: &'static str) -> Result<MachineStatus, CutterError> {
        self.read(Register::MachineStatus, doing).map(MachineStatus)
    }

    /// A length or position register, mm.
    pub(super) fn read_mm(
        &self,
        register: Register,
        doing: &'static str,
    ) -> Result<f64, CutterError> {
        let value = self.read(register, doing)?;
        value_to_mm(value).ok_or_else(|| {
            RuidaFailure::Protocol {
                address: self.address.clone(),
                doing,
                reason: format!("{register:?} reads {value:#x}, beyond 32 bits"),
            }
            .into()
        })
    }

    /// The bed as the registers give it, checked against the address's (`given`); when they
    /// read none, the address's, else the front end's `fallback`.
    fn bed_mm(
        &self,
        given: Option<[f64; 2]>,
        fallback: Option<[f64; 2]>,
    ) -> Result<[f64; 2], CutterError> {
        let doing = "reading the bed size";
        let read_mm = [
            self.read_mm(Register::BedSizeX, doing)?,
            self.read_mm(Register::BedSizeY, doing)?,
        ];
        let readable = read_mm.iter().all(|v| *v > 0.0);
        let address = self.address.clone();
        match (readable, given) {
            (true, Some(g)) if (0..2).any(|i| (g[i] - read_mm[i]).abs() > 0.5) => {
                Err(RuidaFailure::BedMismatch {
                    address,
                    given_mm: g,
                    read_mm,
                }
                .into())
            }
            (true, _) => Ok(read_mm),
            (false, Some(g)) => Ok(g),
            (false, None) => {
                fallback.ok_or_else(|| RuidaFailure::NoBed { address, read_mm }.into())
            }
        }
    }

    /// The head's X, Y and the prongs' axis, mm.
    pub fn head_mm(&self) -> Result<[f64; 3], CutterError> {
        let doing = "reading the head's position";
        let axis = match self.axis {
            ProngAxis::Z => Register::PositionZ,
            ProngAxis::U => Register::PositionU,
        };
        Ok([
            self.read_mm(Register::PositionX, doing)?,
            self.read_mm(Register::PositionY, doing)?,
            self.read_mm(axis, doing)?,
        ])
    }

    /// Run `program` (the G-code Kerfmeter writes, read by [`steps`](super::steps)): refused with nothing sent
    /// when it cannot be read, leaves the travel or finds the controller busy; stopped on any
    /// failure after its first packet, and on `cancel`.
    pub fn stream(
        &mut self,
        program: &str,
        cancel: &AtomicBool,
        progress: &mut dyn FnMut(&StreamProgress),
    ) -> Result<StreamReport, CutterError> {
        let start = Instant::now();
        let head = self.head_mm()?;
        self.travel.start.head_mm = head;
        let (planned, lines) = self.plan(program, head)?;
        let status = self.machine_status("checking the controller is idle")?;
        if status.is_busy() {
            return Err(self.busy(status));
        }
        let total = planned.len();
        for (done, step) in planned.iter().enumerate() {
            if cancel.load(Ordering::Relaxed) {
                let answered = done;
                return Err(self.stop_after(CutterError::Cancelled { answered, total }));
            }
            if let Err(e) = self.run(step, cancel, done, total) {
                return Err(self.stop_after(e));
            }
            progress(&progress_of(done + 1, total));
        }
        let position_mm = Some(self.head_mm().map_err(|e| self.stop_after(e))?);
        Ok(StreamReport {
            lines,
            elapsed: start.elapsed(),
            max_unanswered_bytes: 0,
            position_mm,
        })
    }

    /// Stop now (`D8 01`) and confirm it: the status idle within [`Timing::stop_confirm`].
    pub fn stop(&mut self) -> Result<(), CutterError> {
        self.link
            .command(Command::StopProcess)
            .map_err(|e| RuidaFailure::from_link(&self.address, "stopping", e))?;
        let deadline = Instant::now() + self.timing.stop_confirm;
        loop {
            if !self.machine_status("confirming the stop")?.is_busy() {
                return Ok(());
            }
            if Instant::now() > deadline {
                return Err(RuidaFailure::StillBusy {
                    address: self.address.clone(),
                    waited_ms: self.timing.stop_confirm.as_millis() as u64,
                }
                .into());
            }
            std::thread::sleep(self.timing.poll);
        }
    }

    /// Stop after `cause`: [`CutterError::Stopped`], or [`CutterError::NotStopped`] when the
    /// stop cannot be confirmed.
    pub fn stop_after(&mut self, cause: CutterError) -> CutterError {
        let cause = Box::new(cause);
        match self.stop() {
            Ok(()) => CutterError::Stopped {
                cause,
                position_lost: false,
            },
            Err(stop) => CutterError::NotStopped {
                cause,
                stop: Box::new(stop),
            },
        }
    }
}

fn progress_of(answered: usize, total: usize) -> StreamProgress {
    StreamProgress {
        answered,
        total,
        unanswered_bytes: 0,
        status: None,
        checking: false,
    }
}

/// The travel of a bed of `bed_mm` from the origin, the prongs' axis within `z_mm`, the head at
/// `head_mm`; no work offsets (the moves are in machine coordinates).
fn travel(bed_mm: [f64; 2], z_mm: [f64; 2], head_mm: [f64; 3]) -> Travel {
    let between = |min_mm, max_mm| Reach::Between { min_mm, max_mm };
    Travel {
        travel_mm: [bed_mm[0], bed_mm[1], z_mm[1] - z_mm[0]],
        soft_limits: false,
        homing: false,
        reach: [
            between(0.0, bed_mm[0]),
            between(0.0, bed_mm[1]),
            between(z_mm[0], z_mm[1]),
        ],
        start: Start {
            head_mm,
            offsets: Offsets::default(),
            modal: Modal::after_reset(),
        },
        source: TravelSource::Ruida,
    }
}

/// A travel before the controller was read (replaced in [`RuidaCutter::connect`]).
fn placeholder_travel() -> Travel {
    travel([0.0; 2], [0.0; 2], [0.0; 3])
}
