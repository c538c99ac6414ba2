//! The simulated Ruida controller driven by a client over UDP, as a driver will drive a real
//! one: packets ACKed, a corrupted one NAKed, a dropped one sent again, a late answer waited
//! for, a busy controller and a refused program, register reads; and what it cut compared with
//! the plan.

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use kerfmeter_ruida::register::{MachineStatus, Register, value_to_mm};
use kerfmeter_ruida::twin::{RuidaTwin, TwinConfig};
use kerfmeter_ruida::{Command, CutLayer, MAGIC, Packet, Program, Reply};

/// A client of the twin: one socket, answers awaited for `timeout`.
struct Client {
    socket: UdpSocket,
}

impl Client {
    fn new(twin: &RuidaTwin, timeout: Duration) -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket.connect(twin.addr()).unwrap();
        socket.set_read_timeout(Some(timeout)).unwrap();
        Self { socket }
    }

    /// The next datagram, or `None` on a timeout.
    fn receive(&self) -> Option<Vec<u8>> {
        let mut buf = [0u8; 2048];
        let len = self.socket.recv(&mut buf).ok()?;
        Some(buf[..len].to_vec())
    }

    /// Send `packet` once; its reply, or `None` on a timeout.
    fn send(&self, packet: &[u8]) -> Option<Reply> {
        self.socket.send(packet).unwrap();
        let answer = self.receive()?;
        assert_eq!(answer.len(), 1, "a reply is one byte");
        Some(Reply::from_swizzled(answer[0], MAGIC).unwrap())
    }

    /// Send `packet` until it is answered (at most `tries` times).
    fn send_until_answered(&self, packet: &Packet, tries: usize) -> Reply {
        (0..tries)
            .find_map(|_| self.send(packet.as_bytes()))
            .expect("no answer")
    }

    fn send_program(&self, program: &Program) -> Vec<Reply> {
        let packets = program.packets(MAGIC).unwrap();
        packets
            .iter()
            .map(|p| self.send_until_answered(p, 3))
            .collect()
    }

    fn read(&self, register: Register) -> u64 {
        let packet = Packet::new(&register.read().to_bytes(), MAGIC).unwrap();
        assert_eq!(self.send_until_answered(&packet, 3), Reply::Ack);
        let answer = self.receive().expect("no register answer");
        register.parse_reply(&answer, MAGIC).unwrap()
    }
}

fn plan() -> Vec<CutLayer> {
    let square = |x: f64| {
        vec![
            [x, 5.0],
            [x + 10.0, 5.0],
            [x + 10.0, 15.0],
            [x, 15.0],
            [x, 5.0],
        ]
    };
    let scattered = (0..120).map(|i| vec![[i as f64, 100.0], [i as f64 + 0.5, 120.0]]);
    vec![
        CutLayer {
            speed_mm_per_s: 15.0,
            min_power_percent: 10.0,
            max_power_percent: 35.0,
            paths_mm: vec![square(20.0), square(250.0)],
        },
        CutLayer {
            speed_mm_per_s: 80.0,
            min_power_percent: 0.0,
            max_power_percent: 100.0,
            paths_mm: scattered.collect(),
        },
    ]
}

fn um(p: [f64; 2]) -> [i32; 2] {
    p.map(|v| (v * 1000.0).round() as i32)
}

/// What the twin cut is the plan: each travel with the laser off, each cut along a path with
/// its layer's speed and powers; the head rests on the last point.
#[test]
fn the_twin_cuts_the_plan_and_nothing_else() {
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let client = Client::new(&twin, Duration::from_secs(2));
    let layers = plan();
    let program = Program::new(&layers).unwrap();
    let replies = client.send_program(&program);
    assert!(replies.len() > 1, "the plan fills several packets");
    assert!(replies.iter().all(|r| *r == Reply::Ack));
    let log = twin.log();
    assert_eq!(log.programs_run, 1);
    let mut strokes = log.strokes.iter();
    for layer in &layers {
        for path in &layer.paths_mm {
            let travel = strokes.next().unwrap();
            assert!(!travel.laser_on, "a travel with the laser on: {travel:?}");
            assert_eq!(travel.to_um, um(path[0]));
            for pair in path.windows(2) {
                let cut = strokes.next().unwrap();
                assert!(cut.laser_on);
                assert_eq!((cut.from_um, cut.to_um), (um(pair[0]), um(pair[1])));
                assert_eq!(f64::from(cut.speed_um_per_s), layer.speed_mm_per_s * 1000.0);
                let power = cut.power_steps.map(|p| f64::from(p) * 100.0 / 16384.0);
                assert!((power[0] - layer.min_power_percent).abs() <= 100.0 / 16384.0);
                assert!((power[1] - layer.max_power_percent).abs() <= 100.0 / 16384.0);
            }
        }
    }
    assert_eq!(strokes.next(), None);
    assert_eq!(value_to_mm(client.read(Register::PositionX)), Some(119.5));
    assert_eq!(value_to_mm(client.read(Register::PositionY)), Some(120.0));
    assert_eq!(value_to_mm(client.read(Register::BedSizeX)), Some(600.0));
}

#[test]
fn a_corrupted_packet_is_naked_and_its_resend_acked() {
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let client = Client::new(&twin, Duration::from_secs(2));
    let packet = Packet::new(
        &Command::RapidMoveXy {
            x_um: 5_000,
            y_um: 6_000,
        }
        .to_bytes(),
        MAGIC,
    )
    .unwrap();
    let mut corrupted = packet.as_bytes().to_vec();
    corrupted[4] ^= 0x10;
    assert_eq!(client.send(&corrupted), Some(Reply::Nak));
    assert!(
        twin.log().strokes.is_empty(),
        "a NAKed packet moved the head"
    );
    assert_eq!(client.send(packet.as_bytes()), Some(Reply::Ack));
    assert_eq!(twin.log().naks, 1);
    assert_eq!(value_to_mm(client.read(Register::PositionX)), Some(5.0));
}

/// A dropped packet gets no answer; sent again, it is ACKed and the program is whole, once.
#[test]
fn a_dropped_packet_is_sent_again() {
    let config = TwinConfig {
        drop_datagrams: vec![1],
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let client = Client::new(&twin, Duration::from_millis(200));
    let program = Program::new(&plan()).unwrap();
    let replies = client.send_program(&program);
    assert!(replies.iter().all(|r| *r == Reply::Ack));
    let log = twin.log();
    assert_eq!((log.dropped, log.programs_run), (1, 1));
    let cuts = plan()
        .iter()
        .flat_map(|l| &l.paths_mm)
        .map(|p| p.len())
        .sum::<usize>();
    assert_eq!(log.strokes.len(), cuts);
}

/// A late answer: a client that waits long enough gets it; one that does not, times out.
#[test]
fn a_late_answer_is_waited_for_or_timed_out() {
    let config = TwinConfig {
        reply_delay: Duration::from_millis(300),
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let keep_alive = Packet::new(&Command::KeepAlive.to_bytes(), MAGIC).unwrap();
    let impatient = Client::new(&twin, Duration::from_millis(50));
    assert_eq!(impatient.send(keep_alive.as_bytes()), None);
    let patient = Client::new(&twin, Duration::from_secs(2));
    let start = Instant::now();
    assert_eq!(patient.send(keep_alive.as_bytes()), Some(Reply::Ack));
    assert!(start.elapsed() >= Duration::from_millis(250));
}

/// Busy while a program runs: its status says so, a second program is refused (ERR) and
/// nothing of it is cut; once idle, the same program runs.
#[test]
fn a_busy_controller_refuses_a_program_until_idle() {
    let config = TwinConfig {
        busy_reads: 2,
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let client = Client::new(&twin, Duration::from_secs(2));
    let square = Program::new(&plan()[..1]).unwrap();
    assert_eq!(client.send_program(&square), [Reply::Ack]);
    assert!(MachineStatus(client.read(Register::MachineStatus)).is_busy());
    assert_eq!(client.send_program(&square), [Reply::Err]);
    assert!(twin.log().refused[0].contains("busy"));
    assert!(MachineStatus(client.read(Register::MachineStatus)).is_busy());
    assert!(!MachineStatus(client.read(Register::MachineStatus)).is_busy());
    assert_eq!(client.send_program(&square), [Reply::Ack]);
    assert_eq!(twin.log().programs_run, 2);
}

/// A program with a command the controller does not take, or a wrong file sum, is refused
/// whole: nothing is cut.
#[test]
fn a_program_the_controller_cannot_take_is_refused_and_nothing_cut() {
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let client = Client::new(&twin, Duration::from_secs(2));
    let mut payload = Program::new(&plan()[..1]).unwrap().payload();
    // A relative move (89) slipped in before the end.
    let end = payload.len() - 8;
    payload.splice(end..end, [0x89, 0x00, 0x10, 0x00, 0x10]);
    let packet = Packet::new(&payload, MAGIC).unwrap();
    assert_eq!(client.send(packet.as_bytes()), Some(Reply::Err));
    let mut wrong_sum = Program::new(&plan()[..1]).unwrap().payload();
    let at = wrong_sum.len() - 2;
    wrong_sum[at] ^= 0x01;
    let packet = Packet::new(&wrong_sum, MAGIC).unwrap();
    assert_eq!(client.send(packet.as_bytes()), Some(Reply::Err));
    let log = twin.log();
    assert_eq!((log.programs_run, log.strokes.len()), (0, 0));
    assert!(log.refused[1].contains("file sum"), "{:?}", log.refused);
}

#[test]
fn z_u_and_stop_are_acted_on() {
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let client = Client::new(&twin, Duration::from_secs(2));
    for command in [
        Command::RapidMoveZ { z_um: -3_000 },
        Command::RapidMoveU { u_um: 1_500 },
        Command::StopProcess,
    ] {
        let packet = Packet::new(&command.to_bytes(), MAGIC).unwrap();
        assert_eq!(client.send(packet.as_bytes()), Some(Reply::Ack));
    }
    assert_eq!(value_to_mm(client.read(Register::PositionZ)), Some(-3.0));
    assert_eq!(value_to_mm(client.read(Register::PositionU)), Some(1.5));
    assert_eq!(twin.log().stops, 1);
}
