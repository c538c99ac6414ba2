//! A program's steps made ready and sent ([`RuidaCutter::stream`]'s body): the G-code read and
//! checked against the travel before anything goes, each step sent, and each waited for. A
//! controller may show idle for a moment before it starts a move or a program, so idle alone
//! does not say a step is done: a direct move is done when the machine is idle with the head at
//! its target; a cut program when the machine was seen busy and is idle again, or is idle with
//! the head on the program's last point (a controller set to go back to its origin after a job
//! leaves it elsewhere). A machine that stays idle otherwise did not run the step (it refused it
//! without a word, or waits for it to be started): [`RuidaFailure::NotRun`], and a stop.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use kerfmeter_ruida::register::Register;
use kerfmeter_ruida::value::mm_to_um;
use kerfmeter_ruida::{Command, MAGIC, Packet, Program, RuidaError};

use super::address::ProngAxis;
use super::steps::{self, Step};
use super::{RuidaCutter, RuidaFailure};
use crate::grbl::CutterError;

/// A register read back within this of the value sent, mm (one µm step and its rounding).
const THERE_MM: f64 = 0.0015;

/// A step made ready to send, and where it leaves the head.
pub(super) struct Planned {
    sending: Sending,
    /// The registers that must read these values (mm) once it is done.
    ends_at: Vec<(Register, f64)>,
    /// A cut program: done too once the machine was seen busy and is idle again.
    done_when_seen_busy: bool,
    what: &'static str,
}

enum Sending {
    Move(Command),
    Cut(Vec<Packet>),
}

impl RuidaCutter {
    /// Read, check and encode `program` before anything is sent; with its G-code line count.
    pub(super) fn plan(
        &self,
        program: &str,
        head: [f64; 3],
    ) -> Result<(Vec<Planned>, usize), CutterError> {
        let bad = |line: usize, reason: String| CutterError::BadProgram { line, reason };
        let read = steps::read(program, [head[0], head[1]]).map_err(|e| bad(e.line, e.reason))?;
        self.check_travel(program)?;
        let planned = read
            .steps
            .iter()
            .map(|step| self.plan_step(step).map_err(|e| bad(0, e.to_string())))
            .collect::<Result<_, _>>()?;
        Ok((planned, read.lines))
    }

    fn plan_step(&self, step: &Step) -> Result<Planned, RuidaError> {
        let at = |register, mm: f64| (register, f64::from(mm_to_um("end", mm).unwrap_or(0)) / 1e3);
        Ok(match step {
            Step::MoveXy([x, y]) => Planned {
                sending: Sending::Move(Command::RapidMoveXy {
                    x_um: mm_to_um("x_mm", *x)?,
                    y_um: mm_to_um("y_mm", *y)?,
                }),
                ends_at: vec![at(Register::PositionX, *x), at(Register::PositionY, *y)],
                done_when_seen_busy: false,
                what: "move of the head",
            },
            Step::MoveZ(z) => {
                let (command, register) = match self.axis {
                    ProngAxis::Z => (
                        Command::RapidMoveZ {
                            z_um: mm_to_um("z_mm", *z)?,
                        },
                        Register::PositionZ,
                    ),
                    ProngAxis::U => (
                        Command::RapidMoveU {
                            u_um: mm_to_um("u_mm", *z)?,
                        },
                        Register::PositionU,
                    ),
                };
                Planned {
                    sending: Sending::Move(command),
                    ends_at: vec![at(register, *z)],
                    done_when_seen_busy: false,
                    what: "move of the prongs' axis",
                }
            }
            Step::Cut(layers) => {
                let end = layers
                    .last()
                    .and_then(|l| l.paths_mm.last())
                    .and_then(|p| p.last());
                let ends_at = end.map_or_else(Vec::new, |&[x, y]| {
                    vec![at(Register::PositionX, x), at(Register::PositionY, y)]
                });
                Planned {
                    sending: Sending::Cut(Program::new(layers)?.packets(MAGIC)?),
                    ends_at,
                    done_when_seen_busy: true,
                    what: "cut program",
                }
            }
        })
    }

    /// Every move of `program` within the travel, as the GRBL driver checks it.
    fn check_travel(&self, program: &str) -> Result<(), CutterError> {
        let lines =
            crate::grbl::protocol::prepare(program).map_err(|b| CutterError::BadProgram {
                line: b.number,
                reason: b.reason,
            })?;
        let extent = self
            .travel
            .extent(&lines)
            .map_err(|u| CutterError::Unbounded {
                line: u.line,
                written: u.written,
                reason: u.reason,
            })?;
        self.travel
            .check(&extent)
            .map_err(|beyond| CutterError::BeyondTravel { beyond })
    }

    /// Send one step and wait until it is done.
    pub(super) fn run(
        &self,
        step: &Planned,
        cancel: &AtomicBool,
        done: usize,
        total: usize,
    ) -> Result<(), CutterError> {
        let cancelled = || CutterError::Cancelled {
            answered: done,
            total,
        };
        match &step.sending {
            Sending::Move(command) => self
                .link
                .command(*command)
                .map_err(|e| RuidaFailure::from_link(&self.address, "moving the head", e))?,
            Sending::Cut(packets) => {
                for packet in packets {
                    if cancel.load(Ordering::Relaxed) {
                        return Err(cancelled());
                    }
                    self.link.send(packet, false).map_err(|e| {
                        RuidaFailure::from_link(&self.address, "sending a cut program", e)
                    })?;
                }
            }
        }
        self.wait_done(step, cancel)
            .map_err(|e| e.unwrap_or_else(cancelled))
    }

    /// Poll until the machine is idle with the head where `step` ends; `Err(None)` on `cancel`.
    fn wait_done(&self, step: &Planned, cancel: &AtomicBool) -> Result<(), Option<CutterError>> {
        let mut idle_elsewhere: Option<Instant> = None;
        let mut seen_busy = false;
        loop {
            if cancel.load(Ordering::Relaxed) {
                return Err(None);
            }
            let busy = self.machine_status("waiting for the job to end")?.is_busy();
            seen_busy |= busy;
            if busy {
                idle_elsewhere = None;
            } else if seen_busy && step.done_when_seen_busy {
                return Ok(());
            } else {
                let Some(wrong) = self.not_there(step)? else {
                    return Ok(());
                };
                let since = *idle_elsewhere.get_or_insert_with(Instant::now);
                if since.elapsed() > self.timing.start_grace {
                    return Err(Some(wrong.into()));
                }
            }
            std::thread::sleep(self.timing.poll);
        }
    }

    /// `None` when every register `step` ends at reads its value; else the failure to tell.
    fn not_there(&self, step: &Planned) -> Result<Option<RuidaFailure>, CutterError> {
        for &(register, expected_mm) in &step.ends_at {
            let read_mm = self.read_mm(register, "reading where the head stands")?;
            if (read_mm - expected_mm).abs() > THERE_MM {
                return Ok(Some(RuidaFailure::NotRun {
                    address: self.address.clone(),
                    what: step.what,
                    register: format!("{register:?}"),
                    expected_mm,
                    read_mm,
                    waited_ms: self.timing.start_grace.as_millis() as u64,
                }));
            }
        }
        Ok(None)
    }
}
