//! The GRBL driver against the cutter twin, which enforces GRBL's 128-byte receive buffer and
//! records what its laser traced: streaming, refused lines, alarms, cancel, laser safety, and
//! the TCP transport.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use kerfmeter::grbl::twin::{CutterLog, CutterServer, SegmentKind};
use kerfmeter::grbl::{
    ConnectOptions, Cutter, CutterAddress, CutterError, SimCutterOptions, StreamProgress,
};
use kerfmeter_twin::Pace;

/// Quick to connect and to notice the end of motion.
fn options() -> ConnectOptions {
    ConnectOptions {
        banner_wait: Duration::from_millis(500),
        poll_interval: Duration::from_millis(20),
        ..ConnectOptions::default()
    }
}

fn sim(twin: SimCutterOptions) -> Cutter {
    Cutter::sim(twin, options()).unwrap()
}

/// A square of `side_mm` cut at 3000 mm/min, with travels between, `repeats` times.
fn squares(side_mm: u32, repeats: usize) -> String {
    let mut program = String::from("G21 G90 ; mm, absolute\nM4 S0\n");
    for i in 0..repeats {
        let x0 = 5 * i;
        let x1 = x0 + side_mm as usize;
        // The beam off for each travel (laser mode would keep it dark, but the twin records a
        // program that relies on that).
        program += &format!("M5\nG0 X{x0} Y0\nM4\nG1 X{x1} Y0 S800 F3000\nG1 X{x1} Y{side_mm}\n");
        program += &format!("G1 X{x0} Y{side_mm}\nG1 X{x0} Y0\n");
    }
    program + "M5\nG0 X0 Y0\nM2\n"
}

fn stream(
    cutter: &mut Cutter,
    program: &str,
) -> Result<kerfmeter::grbl::StreamReport, CutterError> {
    cutter.stream(program, &AtomicBool::new(false), &mut |_| {})
}

fn log(cutter: &Cutter) -> CutterLog {
    cutter.sim_log().unwrap().clone()
}

#[test]
fn a_program_streams_within_the_window_and_the_laser_traces_only_the_cuts() {
    let mut cutter = sim(SimCutterOptions::default());
    assert_eq!(cutter.version(), "1.1h");
    let program = squares(10, 12);
    let report = stream(&mut cutter, &program).unwrap();
    assert!(report.max_unanswered_bytes <= 128, "{report:?}");
    assert!(
        report.max_unanswered_bytes > 100,
        "the window is used: {report:?}"
    );
    assert_eq!(report.position_mm, Some([0.0, 0.0, 0.0]));
    let record = log(&cutter).snapshot();
    assert!(record.violations.is_empty(), "{:?}", record.violations);
    assert!(record.travel_firings.is_empty());
    assert!(
        record.blanked_travels.is_empty(),
        "{:?}",
        record.blanked_travels
    );
    let cuts = record.segments.iter().filter(|s| s.power_s > 0.0).count();
    assert_eq!(cuts, 4 * 12);
    assert!(record.segments.iter().all(|s| s.complete));
    assert!(
        record
            .segments
            .iter()
            .all(|s| (s.kind == SegmentKind::Travel) == (s.power_s == 0.0))
    );
    assert_eq!((record.state.as_str(), record.laser_power_s), ("Idle", 0.0));
}

#[test]
fn progress_tells_the_check_pass_from_the_cut() {
    let mut cutter = sim(SimCutterOptions::default());
    let mut phases = Vec::new();
    let mut on_progress = |p: &StreamProgress| {
        if phases.last() != Some(&p.checking) {
            phases.push(p.checking);
        }
    };
    cutter
        .stream(&squares(10, 2), &AtomicBool::new(false), &mut on_progress)
        .unwrap();
    assert_eq!(phases, [true, false], "checked, then cut");
}

#[test]
fn a_greedy_sender_is_caught_by_the_twin() {
    // The check the driver passes can fail: write a program without waiting for any `ok`.
    let (server, mut port) =
        CutterServer::pty(SimCutterOptions::default(), Pace::LockStep).unwrap();
    port.write_all(squares(10, 12).as_bytes()).unwrap();
    port.flush().unwrap();
    let mut buf = [0u8; 4096];
    let _ = port.read(&mut buf);
    std::thread::sleep(Duration::from_millis(200));
    assert!(!server.log().snapshot().violations.is_empty());
}

#[test]
fn a_program_for_another_s_max_is_refused_before_anything_is_sent() {
    // A diode laser with $30=255: a program written for S max 1000 would fire "25 %" at 98 %.
    let mut cutter = sim(SimCutterOptions {
        max_power_s: 255.0,
        ..SimCutterOptions::default()
    });
    assert_eq!(cutter.settings().get(&30), Some(&255.0));
    let program = format!(
        "(S_MAX=1000 must equal GRBL setting 30)\n{}",
        squares(10, 1)
    );
    let error = stream(&mut cutter, &program).unwrap_err();
    let CutterError::SMaxMismatch {
        program: 1000.0,
        ref controller,
    } = error
    else {
        panic!("{error}");
    };
    assert_eq!(controller, "255");
    let message = error.to_string();
    assert!(message.contains("--s-max 255"), "{message}");
    let record = log(&cutter).snapshot();
    assert!(record.segments.is_empty(), "{:?}", record.segments);
    // The same program declaring the controller's S max is cut.
    let program = program.replace("S_MAX=1000", "S_MAX=255");
    stream(&mut cutter, &program).unwrap();
    assert!(!log(&cutter).snapshot().segments.is_empty());
}

#[test]
fn a_refused_line_is_found_by_the_check_pass_before_anything_moves() {
    // The 7th G-code line (file line 8: the first is a comment) gets error:33.
    let mut cutter = sim(SimCutterOptions {
        error_on_line: Some((7, 33)),
        ..SimCutterOptions::default()
    });
    let program = format!("; a job\n{}", squares(10, 12));
    let error = stream(&mut cutter, &program).unwrap_err();
    assert!(matches!(error, CutterError::Stopped { .. }), "{error}");
    let CutterError::CheckRejected {
        line,
        ref text,
        code,
    } = *error.cause()
    else {
        panic!("{error}");
    };
    // Quoted as written in the file, spaces kept.
    assert_eq!((line, text.as_str(), code), (8, "G1 X10 Y10", 33));
    let message = error.to_string();
    assert!(
        message.contains("its end is not on its circle"),
        "{message}"
    );
    assert!(message.contains("Nothing was cut"), "{message}");
    let record = log(&cutter).snapshot();
    assert!(record.segments.is_empty(), "{:?}", record.segments);
    assert_eq!((record.state.as_str(), record.laser_power_s), ("Idle", 0.0));
}

#[test]
fn a_refused_line_while_cutting_is_reported_and_the_cutter_stopped() {
    // Without the check pass the refusal comes mid-job (the 20th G-code line, a cut).
    let mut cutter = Cutter::sim(
        SimCutterOptions {
            error_on_line: Some((20, 33)),
            ..SimCutterOptions::default()
        },
        ConnectOptions {
            check_first: false,
            ..options()
        },
    )
    .unwrap();
    let error = stream(&mut cutter, &squares(10, 12)).unwrap_err();
    let CutterError::Rejected {
        line: 20, code: 33, ..
    } = error.cause()
    else {
        panic!("{error}");
    };
    assert!(
        error
            .to_string()
            .ends_with("The cutter was stopped and the laser is off"),
        "{error}"
    );
    let record = log(&cutter).snapshot();
    assert_eq!(record.laser_power_s, 0.0);
    assert!(record.resets >= 1, "stopped with a soft reset");
    assert_ne!(record.state, "Run");
}

/// A cut, a spindle change that waits for it, and a travel that is refused: the lines behind it
/// are in GRBL's receive buffer already.
const REFUSED_TRAVEL: &str = "G21 G90\nM4 S0\nG0 X0 Y0\nG1 X10 S800 F3000\nM5\nG0 X50 Y50\nM4\nG1 X60 Y50 S800\nG1 X60 Y60\nM5\n";

#[test]
fn a_refused_travel_cuts_from_the_old_point_unless_the_check_pass_finds_it_first() {
    // Line 6, the travel to (50, 50), is refused.
    let twin = SimCutterOptions {
        error_on_line: Some((6, 20)),
        ..SimCutterOptions::default()
    };
    let collateral = |record: &kerfmeter::grbl::twin::CutterRecord| {
        record
            .segments
            .iter()
            .filter(|s| s.power_s > 0.0 && s.line > 6)
            .count()
    };
    // Streaming alone: GRBL parses on before the stop arrives, and the next cut starts from
    // (10, 0), across the work. The twin reproduces the hazard.
    let unchecked = ConnectOptions {
        check_first: false,
        ..options()
    };
    let mut cutter = Cutter::sim(twin, unchecked).unwrap();
    let error = stream(&mut cutter, REFUSED_TRAVEL).unwrap_err();
    assert!(
        matches!(error.cause(), CutterError::Rejected { line: 6, .. }),
        "{error}"
    );
    assert!(
        collateral(&log(&cutter).snapshot()) > 0,
        "the hazard is staged"
    );
    // With the check pass (the default) the refusal comes before anything moves.
    let mut cutter = sim(twin);
    let error = stream(&mut cutter, REFUSED_TRAVEL).unwrap_err();
    assert!(
        matches!(error.cause(), CutterError::CheckRejected { line: 6, .. }),
        "{error}"
    );
    let record = log(&cutter).snapshot();
    assert_eq!(collateral(&record), 0);
    assert!(record.segments.is_empty(), "{:?}", record.segments);
}

#[test]
fn a_controller_in_alarm_is_refused_unless_unlocking_is_asked_for() {
    let twin = SimCutterOptions {
        boot_in_alarm: true,
        ..SimCutterOptions::default()
    };
    let error = Cutter::sim(twin, options()).unwrap_err();
    assert!(
        matches!(error, CutterError::AlarmAtConnect { .. }),
        "{error}"
    );
    assert!(error.to_string().contains("--unlock"), "{error}");
    let mut cutter = Cutter::sim(
        twin,
        ConnectOptions {
            unlock: true,
            ..options()
        },
    )
    .unwrap();
    stream(&mut cutter, &squares(5, 1)).unwrap();
}

#[test]
fn a_controller_without_laser_mode_is_refused_because_it_would_fire_on_travels() {
    let twin = SimCutterOptions {
        laser_mode: false,
        ..SimCutterOptions::default()
    };
    let error = Cutter::sim(twin, options()).unwrap_err();
    assert!(matches!(error, CutterError::LaserModeOff { .. }), "{error}");
    // Overridden, the twin shows why: the beam stays on through the travels.
    let mut cutter = Cutter::sim(
        twin,
        ConnectOptions {
            allow_without_laser_mode: true,
            ..options()
        },
    )
    .unwrap();
    stream(&mut cutter, "M3 S500\nG1 X5 F3000\nG0 X0\nM5\n").unwrap();
    assert_eq!(log(&cutter).snapshot().travel_firings.len(), 1);
}

#[test]
fn an_alarm_mid_job_stops_and_is_reported_with_the_laser_off() {
    let mut cutter = sim(SimCutterOptions {
        hard_limit_after_ms: Some(1_500),
        ..SimCutterOptions::default()
    });
    let error = stream(&mut cutter, &squares(10, 12)).unwrap_err();
    let CutterError::Alarm {
        code: 1,
        after: Some((line, _)),
        last_position_mm: Some(_),
    } = error.cause()
    else {
        panic!("{error}");
    };
    assert!(*line > 3, "{error}");
    assert!(error.to_string().contains("hard limit"), "{error}");
    assert!(error.to_string().contains("had the head at X"), "{error}");
    assert!(error.to_string().ends_with("laser is off"), "{error}");
    let record = log(&cutter).snapshot();
    assert_eq!(record.laser_power_s, 0.0);
    assert_eq!(record.alarms, [1]);
    assert!(!record.segments.last().unwrap().complete);
}

/// An alarm whose `ALARM:N` line was lost shows only in the status reports: the stream ends on
/// it instead of waiting for an Idle that never comes.
#[test]
fn an_alarm_seen_only_in_the_status_ends_the_job() {
    // At the last line (the driver's closing M5, line 5): no line after it is refused for the
    // alarm (`error:9`), only the status reports can show it.
    let mut cutter = sim(SimCutterOptions {
        unannounced_alarm_on_line: Some(5),
        ..SimCutterOptions::default()
    });
    let program = "G21 G90\nM4 S0\nG1 X10 S800 F600\nG1 Y10\n";
    let error = stream(&mut cutter, program).unwrap_err();
    let CutterError::StoppedItself {
        state,
        after: Some((line, _)),
    } = error.cause()
    else {
        panic!("{error}");
    };
    assert_eq!((state.as_str(), *line), ("Alarm", 5), "{error}");
    assert!(error.to_string().ends_with("laser is off"), "{error}");
    let record = log(&cutter).snapshot();
    assert_eq!(record.laser_power_s, 0.0);
    assert_eq!(record.alarms, [2]);
}

#[test]
fn cancelling_mid_stream_stops_the_cutter_with_the_laser_off() {
    let mut cutter = sim(SimCutterOptions::default());
    let cancel = Arc::new(AtomicBool::new(false));
    let mut on_progress = |p: &StreamProgress| {
        if !p.checking && p.answered >= 20 {
            cancel.store(true, Ordering::Relaxed);
        }
    };
    let error = cutter
        .stream(&squares(10, 12), &cancel, &mut on_progress)
        .unwrap_err();
    assert!(
        matches!(error.cause(), CutterError::Cancelled { answered, total: 89 } if *answered >= 20),
        "{error}"
    );
    assert!(
        error.to_string().contains("stopped and the laser is off"),
        "{error}"
    );
    let record = log(&cutter).snapshot();
    assert_eq!(record.laser_power_s, 0.0);
    assert!(record.resets >= 1);
    assert!(
        record.segments.len() < 4 * 12 + 12,
        "the job did not run to its end"
    );
    assert!(
        record.alarms.is_empty(),
        "a completed hold keeps the position: no ALARM:3"
    );
    assert_eq!(record.state, "Idle");
}

#[test]
fn a_networked_controller_is_driven_over_tcp() {
    let server = CutterServer::tcp(SimCutterOptions::default(), Pace::LockStep, 0).unwrap();
    let address: CutterAddress = format!("grbl+tcp://{}", server.address()).parse().unwrap();
    let mut cutter = Cutter::open(&address, options()).unwrap();
    let report = stream(&mut cutter, &squares(10, 4)).unwrap();
    assert!(report.max_unanswered_bytes <= 128);
    let record = server.log().snapshot();
    assert!(record.violations.is_empty() && record.travel_firings.is_empty());
    assert!(
        record.blanked_travels.is_empty(),
        "{:?}",
        record.blanked_travels
    );
    assert_eq!(
        record.segments.iter().filter(|s| s.power_s > 0.0).count(),
        16
    );
}

#[test]
fn a_networked_controller_that_does_not_greet_is_woken_and_driven() {
    let server =
        CutterServer::tcp_greeting(SimCutterOptions::default(), Pace::LockStep, 0, false).unwrap();
    let address: CutterAddress = format!("grbl+tcp://{}", server.address()).parse().unwrap();
    let mut cutter = Cutter::open(&address, options()).unwrap();
    assert_eq!(cutter.version(), "1.1h");
    stream(&mut cutter, &squares(10, 1)).unwrap();
    let record = server.log().snapshot();
    assert_eq!(
        record.resets, 2,
        "asked its state, found idle, woken with a reset; then the one that leaves check mode"
    );
    assert_eq!(
        record.segments.iter().filter(|s| s.power_s > 0.0).count(),
        4
    );
}

#[test]
fn something_that_is_not_grbl_is_named_in_the_error() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = format!("grbl+tcp://{}", listener.local_addr().unwrap());
    let talker = std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        stream.write_all(b"SSH-2.0-OpenSSH\r\n").unwrap();
        // Hold the connection until the driver gives up and hangs up.
        let mut buf = [0u8; 64];
        while matches!(stream.read(&mut buf), Ok(n) if n > 0) {}
    });
    let quick = ConnectOptions {
        banner_wait: Duration::from_millis(100),
        reply_timeout: Duration::from_millis(200),
        ..options()
    };
    let error = Cutter::open(&address.parse().unwrap(), quick).unwrap_err();
    assert!(matches!(error, CutterError::NoBanner { .. }), "{error}");
    assert!(error.to_string().contains("SSH-2.0-OpenSSH"), "{error}");
    talker.join().unwrap();
}

/// A scripted controller for the failures the twin does not stage: it answers the connect like
/// GRBL, then, after `good_lines` program lines, restarts (`restart`) or falls silent for good.
struct Scripted {
    out: std::collections::VecDeque<u8>,
    /// Writes of the feed hold `!` fail, as on a port that times out a write.
    refuse_hold: bool,
    /// How long a feed hold takes to stop the machine (`Hold:1` until then; a reset before it
    /// raises `ALARM:3`), and when the hold began.
    hold_takes: Duration,
    held_at: Option<std::time::Instant>,
    /// The `$$` listing.
    settings: &'static str,
    /// The machine position its status reports give.
    mpos: &'static str,
    /// Status reports say `Run` (another client's job) instead of `Idle`.
    running: bool,
    /// Soft resets received (shared, to be read after the fake is moved into a driver).
    resets: Arc<std::sync::atomic::AtomicUsize>,
    /// The line being received.
    receiving: Vec<u8>,
    /// This program line is refused with `error:20`.
    refuse_line: Option<usize>,
    /// After this many program lines, the machine is held (as by its feed-hold button).
    hold_after_lines: Option<usize>,
    /// The first this many status requests are answered by a banner (a restart).
    banners_for_status: usize,
    /// Lines said later, at their time (a boot log).
    timed: std::collections::VecDeque<(std::time::Instant, &'static str)>,
    good_lines: usize,
    restart: bool,
    lines: usize,
    silent: bool,
}

impl Scripted {
    fn new(good_lines: usize, restart: bool) -> Self {
        let mut out = std::collections::VecDeque::new();
        out.extend(b"\r\nGrbl 1.1h ['$' for help]\r\n");
        Self {
            out,
            refuse_hold: false,
            hold_takes: Duration::ZERO,
            held_at: None,
            settings: "$32=1\r\n",
            mpos: "0.000,0.000,0.000",
            running: false,
            banners_for_status: 0,
            hold_after_lines: None,
            refuse_line: None,
            receiving: Vec::new(),
            resets: Arc::default(),
            timed: Default::default(),
            good_lines,
            restart,
            lines: 0,
            silent: false,
        }
    }

    fn state(&self) -> &'static str {
        match self.held_at {
            Some(at) if at.elapsed() < self.hold_takes => "Hold:1",
            Some(_) => "Hold:0",
            None if self.running => "Run",
            None => "Idle",
        }
    }

    fn say(&mut self, text: &str) {
        if !self.silent {
            self.out.extend(text.as_bytes());
        }
    }
}

impl Scripted {
    /// A realtime byte, acted on wherever it comes, as GRBL does.
    fn realtime(&mut self, byte: u8) -> std::io::Result<()> {
        match byte {
            b'?' if self.banners_for_status > 0 => {
                self.banners_for_status -= 1;
                self.say("\r\nGrbl 1.1h ['$' for help]\r\n");
            }
            b'?' => self.say(&format!("<{}|MPos:{}|FS:0,0>\r\n", self.state(), self.mpos)),
            b'!' if self.refuse_hold => return Err(std::io::ErrorKind::TimedOut.into()),
            b'!' => self.held_at = Some(std::time::Instant::now()),
            _ => {
                self.resets.fetch_add(1, Ordering::Relaxed);
                let alarm = if self.state() == "Hold:1" {
                    "ALARM:3\r\n"
                } else {
                    ""
                };
                self.held_at = None;
                self.receiving.clear();
                self.say(&format!("{alarm}\r\nGrbl 1.1h ['$' for help]\r\n"));
            }
        }
        Ok(())
    }

    /// A whole line (without its newline).
    fn line(&mut self, line: &[u8]) {
        match line {
            b"$G" => self.say("[GC:G1 G54 G17 G21 G90 G94 M5 M9 T0 F100 S0]\r\nok\r\n"),
            b"$I" => self.say("[VER:1.1h.20190825:]\r\n[OPT:V,15,128]\r\nok\r\n"),
            b"$$" => self.say(&format!("{}ok\r\n", self.settings)),
            _ => {
                self.lines += 1;
                if Some(self.lines) == self.hold_after_lines {
                    self.held_at = Some(std::time::Instant::now());
                }
                if Some(self.lines) == self.refuse_line {
                    self.say("error:20\r\n");
                } else if self.lines <= self.good_lines {
                    self.say("ok\r\n");
                } else if self.restart {
                    self.say("\r\nGrbl 1.1h ['$' for help]\r\n");
                } else {
                    self.silent = true;
                }
            }
        }
    }
}

impl Write for Scripted {
    /// Realtime bytes act wherever they are in a write; the rest is read into lines.
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        for &byte in bytes {
            match byte {
                b'?' | b'!' | 0x18 => self.realtime(byte)?,
                b'\n' => {
                    let line = std::mem::take(&mut self.receiving);
                    self.line(&line);
                }
                _ => self.receiving.push(byte),
            }
        }
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Read for Scripted {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        while let Some((at, text)) = self.timed.front()
            && at.elapsed() > Duration::ZERO
        {
            self.out.extend(text.as_bytes());
            self.timed.pop_front();
        }
        if self.out.is_empty() {
            std::thread::sleep(Duration::from_millis(1));
            return Err(std::io::ErrorKind::TimedOut.into());
        }
        let n = buf.len().min(self.out.len());
        for (slot, byte) in buf.iter_mut().zip(self.out.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

/// Quick to give up; no check pass (the fake does not emulate `$C`).
fn quick() -> ConnectOptions {
    ConnectOptions {
        reply_timeout: Duration::from_millis(200),
        silence_timeout: Duration::from_millis(300),
        check_first: false,
        ..options()
    }
}

fn scripted(good_lines: usize, restart: bool) -> Cutter {
    Cutter::connect(
        Box::new(Scripted::new(good_lines, restart)),
        "scripted".into(),
        quick(),
    )
    .unwrap()
}

#[test]
fn a_controller_that_restarts_mid_job_is_reported() {
    let mut cutter = scripted(3, true);
    let error = stream(&mut cutter, "G1X1F100\n".repeat(6).as_str()).unwrap_err();
    assert!(matches!(error.cause(), CutterError::Restarted), "{error}");
}

#[test]
fn a_controller_that_falls_silent_cannot_be_stopped_and_the_error_says_so() {
    let mut cutter = scripted(2, false);
    let error = stream(&mut cutter, "G1X1F100\n".repeat(20).as_str()).unwrap_err();
    let CutterError::NotStopped { cause, .. } = &error else {
        panic!("{error}");
    };
    assert!(matches!(**cause, CutterError::Silent { .. }), "{error}");
    assert!(error.laser_may_be_on());
    let message = error.to_string();
    assert!(
        message.starts_with("THE LASER MAY STILL BE ON: switch it off at the machine"),
        "{message}"
    );
    assert!(!message.contains("laser is off"), "{message}");
}

#[test]
fn a_failed_feed_hold_write_does_not_keep_the_reset_from_being_sent() {
    let mut fake = Scripted::new(usize::MAX, false);
    fake.refuse_hold = true;
    let mut cutter = Cutter::connect(Box::new(fake), "scripted".into(), quick()).unwrap();
    let cancel = AtomicBool::new(true);
    let error = cutter
        .stream("G1X1F100\n", &cancel, &mut |_| {})
        .unwrap_err();
    assert!(
        matches!(error, CutterError::Stopped { ref cause, .. } if matches!(**cause, CutterError::Cancelled { .. })),
        "{error}"
    );
}

#[test]
fn a_slow_feed_hold_is_waited_for_from_the_machines_rate_and_acceleration() {
    // 3000 mm/min at 10 mm/s²: up to 5 s to stop; this one takes 1 s, far past the reply
    // timeout (200 ms) the wait once was capped at, and the reset after it raises no ALARM:3.
    let mut fake = Scripted::new(usize::MAX, false);
    fake.hold_takes = Duration::from_secs(1);
    fake.settings = "$32=1\r\n$110=3000\r\n$111=3000\r\n$120=10\r\n$121=10\r\n";
    let mut cutter = Cutter::connect(Box::new(fake), "scripted".into(), quick()).unwrap();
    let error = cutter
        .stream("G1X1F100\n", &AtomicBool::new(true), &mut |_| {})
        .unwrap_err();
    assert!(
        matches!(
            error,
            CutterError::Stopped {
                position_lost: false,
                ..
            }
        ),
        "{error}"
    );
}

#[test]
fn a_reset_that_raises_alarm_3_says_the_position_may_be_lost() {
    // No rates in its settings: the hold is waited for only a reply's time, and it is still
    // stopping when the reset comes.
    let mut fake = Scripted::new(usize::MAX, false);
    fake.hold_takes = Duration::from_secs(60);
    let mut cutter = Cutter::connect(Box::new(fake), "scripted".into(), quick()).unwrap();
    let error = cutter
        .stream("G1X1F100\n", &AtomicBool::new(true), &mut |_| {})
        .unwrap_err();
    assert!(
        matches!(
            error,
            CutterError::Stopped {
                position_lost: true,
                ..
            }
        ),
        "{error}"
    );
    assert!(
        error.to_string().contains("home it before the next job"),
        "{error}"
    );
}

#[test]
fn a_boot_log_longer_than_the_banner_wait_is_waited_out_without_a_reset() {
    // An ESP32 controller: 1.2 s of boot log, then the banner; the banner wait is 500 ms.
    let mut fake = Scripted::new(usize::MAX, false);
    fake.out.clear();
    let start = std::time::Instant::now();
    for i in 1..=4 {
        fake.timed.push_back((
            start + Duration::from_millis(300 * i),
            "[MSG:INFO: booting]\r\n",
        ));
    }
    fake.timed.push_back((
        start + Duration::from_millis(1300),
        "Grbl 3.7 [FluidNC v3.7.8]\r\n",
    ));
    let resets = fake.resets.clone();
    let cutter = Cutter::connect(Box::new(fake), "esp32".into(), quick()).unwrap();
    assert_eq!(cutter.version(), "3.7");
    assert_eq!(
        resets.load(Ordering::Relaxed),
        0,
        "never reset while it talked"
    );
}

#[test]
fn a_silent_controller_running_a_job_is_refused_without_a_reset() {
    // A networked controller that does not greet, busy with another client's job.
    let mut fake = Scripted::new(usize::MAX, false);
    fake.out.clear();
    fake.running = true;
    let resets = fake.resets.clone();
    let error = Cutter::connect(Box::new(fake), "tcp".into(), quick()).unwrap_err();
    assert!(
        matches!(error, CutterError::NotIdle { ref state } if state == "Run"),
        "{error}"
    );
    assert_eq!(resets.load(Ordering::Relaxed), 0, "its job was not aborted");
}

#[test]
fn a_restart_that_swallows_a_status_request_is_asked_again() {
    // GRBL forgets a pending `?` when it resets: the first request after the banner is answered
    // by another banner (a late one, or a restart), and the driver asks once more.
    let mut fake = Scripted::new(usize::MAX, false);
    fake.banners_for_status = 1;
    let cutter = Cutter::connect(Box::new(fake), "restart".into(), quick()).unwrap();
    assert_eq!(cutter.version(), "1.1h");
    let mut fake = Scripted::new(usize::MAX, false);
    fake.banners_for_status = 2;
    let error = Cutter::connect(Box::new(fake), "restarts".into(), quick()).unwrap_err();
    assert!(matches!(error, CutterError::Restarted), "{error}");
}

#[test]
fn noise_without_line_ends_is_a_wrong_baud_rate_not_a_growing_buffer() {
    let mut fake = Scripted::new(0, false);
    fake.out = std::iter::repeat_n(b'\xfe', 10_000).collect();
    let error = Cutter::connect(Box::new(fake), "noise".into(), quick()).unwrap_err();
    assert!(
        error.to_string().contains("is the baud rate right?"),
        "{error}"
    );
}

#[test]
fn a_machine_held_past_the_hold_timeout_is_given_up_and_stopped() {
    // Someone pressed feed hold at the machine and walked away: the status says Hold:0 forever.
    let mut fake = Scripted::new(usize::MAX, false);
    fake.held_at = Some(std::time::Instant::now());
    let mut cutter = Cutter::connect(
        Box::new(fake),
        "held".into(),
        ConnectOptions {
            hold_timeout: Some(Duration::from_millis(300)),
            ..quick()
        },
    );
    // Held from the start: the connect refuses it as not idle.
    assert!(matches!(cutter, Err(CutterError::NotIdle { .. })));
    let mut fake = Scripted::new(usize::MAX, false);
    fake.hold_after_lines = Some(1);
    cutter = Cutter::connect(
        Box::new(fake),
        "held".into(),
        ConnectOptions {
            hold_timeout: Some(Duration::from_millis(300)),
            ..quick()
        },
    );
    let error = stream(cutter.as_mut().unwrap(), "G1X1F100\nG1X2\n").unwrap_err();
    assert!(
        matches!(error.cause(), CutterError::HeldTooLong { state, .. } if state == "Hold:0"),
        "{error}"
    );
    assert!(error.to_string().contains("laser is off"), "{error}");
}

#[test]
fn another_firmwares_codes_are_marked_as_read_with_grbl_meanings() {
    let mut fake = Scripted::new(usize::MAX, false);
    fake.out = b"\r\nGrblHAL 1.1f ['$' or '$HELP' for help]\r\n"
        .iter()
        .copied()
        .collect();
    fake.refuse_line = Some(2);
    let mut cutter = Cutter::connect(Box::new(fake), "hal".into(), quick()).unwrap();
    assert_eq!(cutter.flavour(), "grblHAL");
    let error = stream(&mut cutter, "G0X1\nG1X2F100\n").unwrap_err();
    assert!(
        matches!(
            error.cause(),
            CutterError::Rejected {
                line: 2,
                code: 20,
                ..
            }
        ),
        "{error}"
    );
    assert!(
        error.to_string().contains("GRBL 1.1's; grblHAL may number"),
        "{error}"
    );
    assert!(error.to_string().ends_with("laser is off"), "{error}");
    assert_eq!(scripted(1, false).flavour(), "GRBL");
}

#[test]
fn reports_in_inches_are_read_in_mm() {
    let mut fake = Scripted::new(usize::MAX, false);
    fake.settings = "$32=1\r\n$13=1\r\n";
    fake.mpos = "1.000,2.000,0.500";
    let mut cutter = Cutter::connect(Box::new(fake), "inches".into(), quick()).unwrap();
    let report = stream(&mut cutter, "G1X1F100\n").unwrap();
    assert_eq!(report.position_mm, Some([25.4, 50.8, 12.7]));
}

#[test]
fn a_grbl_older_than_1_1_is_refused() {
    let mut fake = Scripted::new(0, false);
    fake.out = b"\r\nGrbl 0.9j ['$' for help]\r\n"
        .iter()
        .copied()
        .collect();
    let error = Cutter::connect(Box::new(fake), "scripted".into(), quick()).unwrap_err();
    assert!(matches!(error, CutterError::OldVersion { .. }), "{error}");
    assert!(error.to_string().contains("GRBL 0.9j"), "{error}");
}

#[test]
fn a_job_under_m3_without_m5_ends_with_the_laser_off() {
    // Under M3 GRBL keeps the beam on at rest after a cut: the driver closes every program
    // with M5 and confirms it.
    let mut cutter = sim(SimCutterOptions::default());
    let report = stream(&mut cutter, "G21 G90\nM3 S800\nG1 X10 F600\n").unwrap();
    assert_eq!(report.lines, 3);
    let record = log(&cutter).snapshot();
    assert_eq!((record.state.as_str(), record.laser_power_s), ("Idle", 0.0));
    assert_eq!(record.segments.len(), 1);
    assert!(record.segments[0].complete);
}

#[test]
fn a_link_that_dies_mid_job_is_the_laser_may_still_be_on_error() {
    let (server, mut port) =
        CutterServer::pty(SimCutterOptions::default(), Pace::LockStep).unwrap();
    serialport::SerialPort::set_timeout(&mut port, Duration::from_millis(10)).unwrap();
    let mut cutter = Cutter::connect(Box::new(port), "pty".into(), quick()).unwrap();
    let mut on_progress = |p: &StreamProgress| {
        if !p.checking && p.answered >= 10 {
            server.stop();
        }
    };
    let error = cutter
        .stream(&squares(10, 12), &AtomicBool::new(false), &mut on_progress)
        .unwrap_err();
    assert!(error.laser_may_be_on(), "{error}");
    assert!(
        error.to_string().starts_with("THE LASER MAY STILL BE ON"),
        "{error}"
    );
}

#[test]
fn ctrl_c_while_connecting_ends_the_connect() {
    // A controller that accepts the connection and never says a word.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address: CutterAddress = format!("grbl+tcp://{}", listener.local_addr().unwrap())
        .parse()
        .unwrap();
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    let pressed = std::thread::spawn(move || {
        let held = listener.accept().unwrap();
        std::thread::sleep(Duration::from_millis(100));
        flag.store(true, Ordering::Relaxed);
        held
    });
    let slow = ConnectOptions {
        banner_wait: Duration::from_secs(30),
        ..options()
    };
    let started = std::time::Instant::now();
    let error = Cutter::open_cancellable(&address, slow, cancel).unwrap_err();
    assert!(
        matches!(error, CutterError::ConnectCancelled { .. }),
        "{error}"
    );
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "it did not wait out the banner"
    );
    drop(pressed.join().unwrap());
}

/// A cutter twin with 200 × 200 × 50 mm of travel, soft limits off (GRBL's default).
fn small_machine() -> Cutter {
    sim(SimCutterOptions {
        travel_mm: [200.0, 200.0, 50.0],
        ..SimCutterOptions::default()
    })
}

#[test]
fn the_travel_is_read_at_connect_and_a_program_beyond_it_is_refused_before_anything_is_sent() {
    let mut cutter = small_machine();
    let travel = cutter.travel().unwrap();
    assert_eq!(
        (travel.travel_mm, travel.soft_limits, travel.homing),
        ([200.0, 200.0, 50.0], false, false)
    );
    assert_eq!(travel.bed_mm(), [200.0, 200.0]);
    // Square after square, 5 mm apart: the 38th starts at X185 and cuts to X195; the 40th
    // reaches X205.
    let error = stream(&mut cutter, &squares(10, 40)).unwrap_err();
    let CutterError::BeyondTravel { ref beyond } = error else {
        panic!("{error}");
    };
    assert_eq!((beyond.axis, beyond.work_mm()), (0, 205.0));
    assert!(!error.stop_was_tried());
    let message = error.to_string();
    for says in [
        "(`G1 X205 Y0 S800 F3000`) takes the head to X 205.000 mm",
        "$130=200",
        "end stop",
        "Nothing was sent",
        "--origin-mm",
    ] {
        assert!(message.contains(says), "{says}: {message}");
    }
    // Relative moves are followed from where the head stands.
    let error = stream(&mut cutter, "G91\nG0 X150\nG0 X60\n").unwrap_err();
    assert!(error.to_string().contains("line 3 (`G0 X60`)"), "{error}");
    // A probe cannot be bounded.
    let error = stream(&mut cutter, "G0 X10\nG38.2 Z-20 F100\n").unwrap_err();
    assert!(
        matches!(error, CutterError::Unbounded { line: 2, .. }),
        "{error}"
    );
    assert!(error.to_string().contains("cannot be checked"), "{error}");
    let record = log(&cutter).snapshot();
    assert!(
        record.gcode_received.is_empty(),
        "{:?}",
        record.gcode_received
    );
    // Inside the travel it runs.
    stream(&mut cutter, &squares(10, 30)).unwrap();
    assert!(log(&cutter).snapshot().end_stop_hits.is_empty());
}

#[test]
fn on_a_homed_machine_work_coordinates_map_through_the_work_offset() {
    // Homing: the travel is −200..0 in machine coordinates; G54 puts work X0 Y0 Z0 at the
    // front-left corner and the bottom of Z.
    let twin = SimCutterOptions {
        travel_mm: [200.0, 200.0, 50.0],
        homing: true,
        work_offset_mm: [-200.0, -200.0, -50.0],
        ..SimCutterOptions::default()
    };
    let unlocking = ConnectOptions {
        unlock: true,
        ..options()
    };
    let mut cutter = Cutter::sim(twin, unlocking).unwrap();
    let travel = cutter.travel().unwrap();
    assert_eq!(travel.work_offset_mm(), [-200.0, -200.0, -50.0]);
    stream(&mut cutter, &squares(10, 30)).unwrap();
    let error = stream(&mut cutter, "G0 Z55\n").unwrap_err();
    let message = error.to_string();
    assert!(
        message.contains("Z 55.000 mm in work coordinates (machine 5.000)"),
        "{message}"
    );
    assert!(message.contains("$132=50"), "{message}");
    assert!(log(&cutter).snapshot().end_stop_hits.is_empty());
}
