//! A simulated Ruida controller on UDP (127.0.0.1), as unkind as a real one: it checks each
//! packet's checksum (NAK on a mismatch), ACKs it, and can drop packets without a word, answer
//! late, stay busy after a program and refuse what it does not understand. It records what it
//! would have cut: every straight line the head went along, with the laser on or off, the speed
//! and the power.
//!
//! Its model of a controller, where a real one's behaviour is not known here (`docs/ruida.md`):
//! a program runs when its `D7` arrives and keeps the machine busy for [`TwinConfig::busy_reads`]
//! status reads; a program packet that arrives while it is busy, one with a command this crate
//! does not decode, or a program whose file sum is wrong, is answered `CD` (ERR) and the whole
//! program is dropped, nothing cut. Register answers are sent as a separate datagram,
//! swizzled, without a checksum.
//!
//! Faults can also be injected while it runs ([`RuidaTwin::inject`], [`Faults`]), for a driver's
//! tests mid-job: the next program packets lost, every answer late from the next program packet
//! on, a later program refused, a program ACKed and not run, a busy machine, stops that do not
//! stop it. It keeps every datagram it received ([`TwinLog::received`]), so that a test can hand
//! the streams a driver sent to a decoder.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::packet::Packet;
use crate::register::Register;
use crate::swizzle::swizzle;
use crate::{Command, MAGIC, Reply};

/// The machine status the twin reports at rest, and while a program runs (MeerK40t's emulator's
/// values).
pub const STATUS_IDLE: u64 = 22;
/// See [`STATUS_IDLE`].
pub const STATUS_RUNNING: u64 = 21;

/// How unkind the twin is.
#[derive(Debug, Clone)]
pub struct TwinConfig {
    /// The swizzle magic.
    pub magic: u8,
    /// Which received datagrams (counted from 0) are dropped: no answer, nothing done.
    pub drop_datagrams: Vec<usize>,
    /// How long it waits before each answer.
    pub reply_delay: Duration,
    /// How many status reads report "running" after a program starts.
    pub busy_reads: u32,
    /// The bed, µm (the bed-size registers).
    pub bed_um: [i32; 2],
}

impl Default for TwinConfig {
    fn default() -> Self {
        Self {
            magic: MAGIC,
            drop_datagrams: Vec::new(),
            reply_delay: Duration::ZERO,
            busy_reads: 0,
            bed_um: [600_000, 400_000],
        }
    }
}

/// Faults injected while the twin runs, for a driver's tests mid-job ([`RuidaTwin::inject`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    /// Drop this many of the next datagrams that carry a program's commands, without a word.
    pub drop_program_packets: usize,
    /// Answer every datagram this late from the next program packet on (a late ACK mid-job).
    pub late_from_program: Option<Duration>,
    /// Refuse a program at its end of file (ERR), nothing of it cut: the one after this many
    /// programs from now (`Some(0)`: the next).
    pub refuse_program: Option<usize>,
    /// Report a job running for this many status reads from now (another job, a busy machine).
    pub busy_reads: u32,
    /// Stay busy after a stop (`D8 01`) as long as `busy_reads` says: a stop not confirmed.
    pub ignore_stops: bool,
    /// ACK the next program whole but run none of it (a controller that waits for it to be
    /// started at its panel, or drops it without a word).
    pub skip_next_program: bool,
}

/// A straight line the head went along.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stroke {
    /// Where it started, µm (X, Y).
    pub from_um: [i32; 2],
    /// Where it ended, µm.
    pub to_um: [i32; 2],
    /// Whether the laser fired.
    pub laser_on: bool,
    /// The speed set, µm/s (0 for a move outside a program).
    pub speed_um_per_s: u32,
    /// The minimum and maximum power set, 2^14ths.
    pub power_steps: [u16; 2],
}

/// What the twin saw and did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TwinLog {
    /// Every stroke of every program run and every direct move, in order.
    pub strokes: Vec<Stroke>,
    /// Programs run to their end.
    pub programs_run: usize,
    /// Programs refused (ERR), with why.
    pub refused: Vec<String>,
    /// Packets NAKed (checksum mismatch or a bad length).
    pub naks: usize,
    /// Datagrams dropped on purpose.
    pub dropped: usize,
    /// Stops received.
    pub stops: usize,
    /// Z and U, µm.
    pub zu_um: [i32; 2],
    /// Every datagram received, as received (swizzled, checksum first), dropped ones included.
    pub received: Vec<Vec<u8>>,
}

/// The machine's state between datagrams.
#[derive(Debug, Default)]
struct Machine {
    log: TwinLog,
    position_um: [i32; 2],
    program: Vec<Command>,
    busy_reads_left: u32,
    datagrams: usize,
    faults: Faults,
    /// A program packet came since `late_from_program` was injected.
    late: bool,
}

/// A running twin; dropped, it stops.
pub struct RuidaTwin {
    addr: SocketAddr,
    machine: Arc<Mutex<Machine>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl RuidaTwin {
    /// Start a twin on an ephemeral port of 127.0.0.1.
    pub fn start(config: TwinConfig) -> std::io::Result<Self> {
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        socket.set_read_timeout(Some(Duration::from_millis(20)))?;
        let addr = socket.local_addr()?;
        let machine = Arc::new(Mutex::new(Machine::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let (m, s) = (Arc::clone(&machine), Arc::clone(&stop));
        let thread = std::thread::spawn(move || serve(&socket, &config, &m, &s));
        Ok(Self {
            addr,
            machine,
            stop,
            thread: Some(thread),
        })
    }

    /// Where it listens (its "port 50200").
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// What it saw and did so far.
    pub fn log(&self) -> TwinLog {
        lock(&self.machine).log.clone()
    }

    /// Make it unkind from now on, as `faults` say (replacing any faults injected before).
    pub fn inject(&self, faults: Faults) {
        let mut machine = lock(&self.machine);
        machine.busy_reads_left = machine.busy_reads_left.max(faults.busy_reads);
        machine.faults = faults;
        machine.late = false;
    }
}

impl Drop for RuidaTwin {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

fn lock(machine: &Mutex<Machine>) -> MutexGuard<'_, Machine> {
    machine.lock().unwrap_or_else(|e| e.into_inner())
}

/// Answer datagrams until `stop`.
fn serve(socket: &UdpSocket, config: &TwinConfig, machine: &Mutex<Machine>, stop: &AtomicBool) {
    let mut buf = [0u8; 2048];
    while !stop.load(Ordering::Relaxed) {
        let Ok((len, from)) = socket.recv_from(&mut buf) else {
            continue;
        };
        let (answers, delay) = {
            let mut m = lock(machine);
            let answers = m.receive(&buf[..len], config);
            let late = m.late.then_some(m.faults.late_from_program).flatten();
            (answers, late.unwrap_or(config.reply_delay))
        };
        std::thread::sleep(delay);
        for answer in answers {
            let _ = socket.send_to(&answer, from);
        }
    }
}

impl Machine {
    /// The datagrams answering one received datagram.
    fn receive(&mut self, datagram: &[u8], config: &TwinConfig) -> Vec<Vec<u8>> {
        let index = self.datagrams;
        self.datagrams += 1;
        self.log.received.push(datagram.to_vec());
        self.late |= self.faults.late_from_program.is_some() && carries_program(datagram, config);
        if config.drop_datagrams.contains(&index) || self.drop_program_packet(datagram, config) {
            self.log.dropped += 1;
            return Vec::new();
        }
        let reply = |r: Reply| vec![r.swizzled(config.magic)];
        let payload = match Packet::open(datagram, config.magic) {
            Ok(payload) => payload,
            Err(_) => {
                self.log.naks += 1;
                return vec![reply(Reply::Nak)];
            }
        };
        match Command::decode_all(&payload) {
            Ok(commands) => {
                let mut answers = vec![reply(Reply::Ack)];
                match self.run_all(&commands, config) {
                    Ok(register_answers) => answers.extend(
                        register_answers
                            .iter()
                            .map(|c| swizzle(&c.to_bytes(), config.magic)),
                    ),
                    Err(why) => answers = vec![self.refuse(why, config)],
                }
                answers
            }
            Err(e) => vec![self.refuse(e.to_string(), config)],
        }
    }

    /// Whether `datagram` carries a program's commands and a fault says to drop it.
    fn drop_program_packet(&mut self, datagram: &[u8], config: &TwinConfig) -> bool {
        if self.faults.drop_program_packets == 0 {
            return false;
        }
        let program = carries_program(datagram, config);
        self.faults.drop_program_packets -= usize::from(program);
        program
    }

    /// Drop the program being received and answer ERR.
    fn refuse(&mut self, why: String, config: &TwinConfig) -> Vec<u8> {
        self.program.clear();
        self.log.refused.push(why);
        vec![Reply::Err.swizzled(config.magic)]
    }

    /// Act on a packet's commands; the register answers to send, or why the program is refused.
    fn run_all(
        &mut self,
        commands: &[Command],
        config: &TwinConfig,
    ) -> Result<Vec<Command>, String> {
        let mut answers = Vec::new();
        for &command in commands {
            match command {
                Command::ReadRegister { address } => answers.push(self.read(address, config)),
                Command::StopProcess => {
                    self.log.stops += 1;
                    if !self.faults.ignore_stops {
                        self.busy_reads_left = 0;
                    }
                    self.program.clear();
                }
                Command::KeepAlive | Command::StartProcess => {}
                Command::RapidMoveXy { x_um, y_um } => self.go([x_um, y_um], false, 0, [0, 0]),
                Command::RapidMoveZ { z_um } => self.log.zu_um[0] = z_um,
                Command::RapidMoveU { u_um } => self.log.zu_um[1] = u_um,
                Command::RegisterValue { .. } => {
                    return Err("a register answer sent to the controller".into());
                }
                Command::EndOfFile => self.end_of_file(command, config)?,
                program_command => {
                    if self.busy_reads_left > 0 {
                        return Err("busy: a program is running".into());
                    }
                    self.program.push(program_command);
                }
            }
        }
        Ok(answers)
    }

    /// `D7`: check the file sum, then run the program.
    fn end_of_file(&mut self, eof: Command, config: &TwinConfig) -> Result<(), String> {
        if self.busy_reads_left > 0 {
            return Err("busy: a program is running".into());
        }
        let program = std::mem::take(&mut self.program);
        match self.faults.refuse_program {
            Some(0) => {
                self.faults.refuse_program = None;
                return Err("a job refused (an injected fault)".into());
            }
            Some(n) => self.faults.refuse_program = Some(n - 1),
            None => {}
        }
        let Some((Command::FileSum { sum }, body)) = program.split_last() else {
            return Err("no file sum before the end of file".into());
        };
        let mut bytes = Vec::new();
        body.iter().chain([&eof]).for_each(|c| c.encode(&mut bytes));
        let computed: u32 = bytes.iter().map(|&b| u32::from(b)).sum();
        if computed != *sum {
            return Err(format!(
                "file sum {sum}, the program's bytes sum to {computed}"
            ));
        }
        if std::mem::take(&mut self.faults.skip_next_program) {
            return Ok(());
        }
        self.run_program(body, config.busy_reads);
        Ok(())
    }

    /// Cut `program`: record each stroke, leave the head at its end.
    fn run_program(&mut self, program: &[Command], busy_reads: u32) {
        let (mut speed, mut power) = (0, [0, 0]);
        for &command in program {
            match command {
                Command::Speed { speed_um_per_s } => speed = speed_um_per_s,
                Command::MinPower { power_steps } => power[0] = power_steps,
                Command::MaxPower { power_steps } => power[1] = power_steps,
                Command::MoveAbs { x_um, y_um } => self.go([x_um, y_um], false, speed, power),
                Command::CutAbs { x_um, y_um } => self.go([x_um, y_um], true, speed, power),
                _ => {}
            }
        }
        self.log.programs_run += 1;
        self.busy_reads_left = busy_reads;
    }

    fn go(&mut self, to_um: [i32; 2], laser_on: bool, speed_um_per_s: u32, power_steps: [u16; 2]) {
        self.log.strokes.push(Stroke {
            from_um: self.position_um,
            to_um,
            laser_on,
            speed_um_per_s,
            power_steps,
        });
        self.position_um = to_um;
    }

    /// The answer to reading the register at `address` (0 for one it does not model).
    fn read(&mut self, address: [u8; 2], config: &TwinConfig) -> Command {
        let um = |v: i32| u64::from(v as u32);
        let value = match Register::from_address(address) {
            Some(Register::PositionX) => um(self.position_um[0]),
            Some(Register::PositionY) => um(self.position_um[1]),
            Some(Register::PositionZ) => um(self.log.zu_um[0]),
            Some(Register::PositionU) => um(self.log.zu_um[1]),
            Some(Register::BedSizeX) => um(config.bed_um[0]),
            Some(Register::BedSizeY) => um(config.bed_um[1]),
            Some(Register::MachineStatus) if self.busy_reads_left > 0 => {
                self.busy_reads_left -= 1;
                STATUS_RUNNING
            }
            Some(Register::MachineStatus) => STATUS_IDLE,
            Some(Register::CardId) | None => 0,
        };
        Command::RegisterValue { address, value }
    }
}

/// Whether `datagram` carries a cut program's commands.
fn carries_program(datagram: &[u8], config: &TwinConfig) -> bool {
    Packet::open(datagram, config.magic)
        .ok()
        .and_then(|payload| Command::decode_all(&payload).ok())
        .is_some_and(|commands| commands.iter().any(|c| is_program_command(*c)))
}

/// Whether `command` belongs to a cut program (rather than a direct command).
fn is_program_command(command: Command) -> bool {
    !matches!(
        command,
        Command::ReadRegister { .. }
            | Command::RegisterValue { .. }
            | Command::StopProcess
            | Command::StartProcess
            | Command::KeepAlive
            | Command::RapidMoveXy { .. }
            | Command::RapidMoveZ { .. }
            | Command::RapidMoveU { .. }
    )
}
