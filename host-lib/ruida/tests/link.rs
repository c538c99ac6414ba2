//! The driver's UDP link against the simulated controller: a program sent whole, a NAK and a
//! dropped read sent again, a dropped program packet never sent again (the caller stops the
//! machine instead), a refusal and a late answer named.

use std::time::Duration;

use kerfmeter_ruida::link::{LinkError, UdpLink};
use kerfmeter_ruida::register::{Register, value_to_mm};
use kerfmeter_ruida::twin::{RuidaTwin, TwinConfig};
use kerfmeter_ruida::{Command, CutLayer, MAGIC, Program};

fn link(twin: &RuidaTwin, timeout_ms: u64) -> UdpLink {
    UdpLink::connect(twin.addr(), MAGIC, Duration::from_millis(timeout_ms), 3).unwrap()
}

/// Many short paths: a program of several packets.
fn program() -> Program {
    let paths = (0..200)
        .map(|i| vec![[i as f64, 10.0], [i as f64, 30.0]])
        .collect();
    Program::new(&[CutLayer {
        speed_mm_per_s: 50.0,
        min_power_percent: 20.0,
        max_power_percent: 20.0,
        paths_mm: paths,
    }])
    .unwrap()
}

#[test]
fn a_program_goes_whole_and_the_head_is_read_where_it_ended() {
    let twin = RuidaTwin::start(TwinConfig::default()).unwrap();
    let link = link(&twin, 1000);
    assert!(program().packets(MAGIC).unwrap().len() > 2);
    link.send_program(&program()).unwrap();
    assert_eq!(twin.log().programs_run, 1);
    assert_eq!(twin.log().strokes.len(), 400);
    assert_eq!(
        value_to_mm(link.read(Register::PositionX).unwrap()),
        Some(199.0)
    );
    assert_eq!(
        value_to_mm(link.read(Register::PositionY).unwrap()),
        Some(30.0)
    );
}

/// A dropped read (its packet, then its answer's packet) is sent again and read.
#[test]
fn a_dropped_read_is_sent_again() {
    let config = TwinConfig {
        drop_datagrams: vec![0, 2],
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let link = link(&twin, 500);
    link.command(Command::RapidMoveXy {
        x_um: 42_000,
        y_um: 1_000,
    })
    .unwrap();
    assert_eq!(
        value_to_mm(link.read(Register::PositionX).unwrap()),
        Some(42.0)
    );
    assert_eq!(twin.log().dropped, 2);
}

/// A program packet that goes unanswered is not sent again: the link says so, and the caller
/// stops the controller, which then holds no half program.
#[test]
fn a_dropped_program_packet_is_not_sent_again() {
    let config = TwinConfig {
        drop_datagrams: vec![1],
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let link = link(&twin, 500);
    let err = link.send_program(&program()).unwrap_err();
    assert!(matches!(err, LinkError::NoAnswer { tries: 1, .. }), "{err}");
    link.command(Command::StopProcess).unwrap();
    link.send_program(&program()).unwrap();
    let log = twin.log();
    assert_eq!(
        (log.programs_run, log.stops, log.strokes.len()),
        (1, 1, 400)
    );
}

#[test]
fn a_busy_controller_refuses_a_program() {
    let config = TwinConfig {
        busy_reads: 5,
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let link = link(&twin, 1000);
    link.send_program(&program()).unwrap();
    assert!(matches!(
        link.send_program(&program()),
        Err(LinkError::Refused)
    ));
    assert_eq!(twin.log().programs_run, 1);
}

/// Answers later than the timeout: each send is tried again, then the link says so; the late
/// answers that arrive afterwards are not taken for the next exchange's.
#[test]
fn late_answers_are_named_then_discarded() {
    let config = TwinConfig {
        reply_delay: Duration::from_millis(150),
        ..TwinConfig::default()
    };
    let twin = RuidaTwin::start(config).unwrap();
    let mut link = link(&twin, 40);
    let err = link.command(Command::KeepAlive).unwrap_err();
    assert!(matches!(err, LinkError::NoAnswer { tries: 3, .. }), "{err}");
    // Three ACKs, 150 ms apart, arrive after the link gave up.
    std::thread::sleep(Duration::from_millis(900));
    link.set_timeout(Duration::from_secs(2));
    link.command(Command::RapidMoveXy {
        x_um: 7_000,
        y_um: 8_000,
    })
    .unwrap();
    assert_eq!(
        value_to_mm(link.read(Register::PositionX).unwrap()),
        Some(7.0)
    );
}
