//! The cutter twin's GRBL emulation, byte for byte: what a sender sees and what the twin records.

use kerfmeter::grbl::twin::{
    CutterLog, CutterOptions, Grbl, PLANNER_BLOCKS, ProtocolViolation, RX_BUFFER_LEN, SOFT_RESET,
    SegmentKind,
};

fn cutter(options: CutterOptions) -> Grbl {
    Grbl::new(options, CutterLog::default())
}

fn said(grbl: &mut Grbl) -> String {
    String::from_utf8(grbl.take_output()).unwrap()
}

/// Send `line` and return the reply.
fn line(grbl: &mut Grbl, text: &str) -> String {
    grbl.receive(format!("{text}\n").as_bytes());
    said(grbl)
}

#[test]
fn it_boots_with_the_banner_and_reports_idle() {
    let mut grbl = cutter(CutterOptions::default());
    assert_eq!(said(&mut grbl), "\r\nGrbl 1.1h ['$' for help]\r\n");
    grbl.receive(b"?");
    let status = said(&mut grbl);
    assert!(
        status.starts_with("<Idle|MPos:0.000,0.000,0.000|"),
        "{status}"
    );
    assert!(line(&mut grbl, "$$").contains("$32=1\r\n"));
}

#[test]
fn bytes_beyond_the_receive_buffer_are_lost_and_recorded() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    // Thirty moves at once: the planner fills, the buffer fills, the rest is lost.
    let greedy: String = (1..=30).map(|i| format!("G1X{i}F600\n")).collect();
    assert!(greedy.len() > RX_BUFFER_LEN + PLANNER_BLOCKS * 10);
    grbl.receive(greedy.as_bytes());
    let violations = grbl.log().snapshot().violations;
    assert!(
        matches!(violations.as_slice(), [ProtocolViolation::RxOverflow { lost_bytes, .. }] if *lost_bytes > 0),
        "{violations:?}"
    );
}

#[test]
fn a_full_planner_holds_back_ok_until_a_block_is_done() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    let mut oks = 0;
    for i in 1..=PLANNER_BLOCKS + 2 {
        oks += line(&mut grbl, &format!("G1X{i}F600"))
            .matches("ok")
            .count();
    }
    assert_eq!(
        oks, PLANNER_BLOCKS,
        "one block runs, the queue holds the rest"
    );
    // Each move is 1 mm at 10 mm/s: 100 ms.
    grbl.advance_us(100_000);
    assert_eq!(said(&mut grbl).matches("ok").count(), 1);
    assert!(grbl.log().snapshot().violations.is_empty());
}

#[test]
fn a_move_takes_its_length_over_its_feed_and_is_traced_with_its_power() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    for l in ["G21G90", "M4 S800", "G0X10", "G1X10Y10F600", "G2X0Y10I-5J0"] {
        assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
    }
    assert_eq!(line(&mut grbl, "M5"), "", "M5 waits for the moves to run");
    grbl.advance_us(999_000);
    grbl.receive(b"?");
    assert!(said(&mut grbl).starts_with("<Run|MPos:"));
    grbl.advance_us(20_000_000);
    grbl.receive(b"?");
    let said_then = said(&mut grbl);
    assert!(
        said_then.starts_with("ok\r\n<Idle|MPos:0.000,10.000,0.000|"),
        "{said_then}"
    );
    let record = grbl.log().snapshot();
    let kinds: Vec<_> = record
        .segments
        .iter()
        .map(|s| (s.kind, s.power_s))
        .collect();
    assert_eq!(
        kinds,
        [
            (SegmentKind::Travel, 0.0),
            (SegmentKind::Line, 800.0),
            (
                SegmentKind::Arc {
                    center: [5.0, 10.0],
                    clockwise: true
                },
                800.0
            ),
        ]
    );
    // Laser mode kept the G0 dark, but the beam was left on for it: that is recorded apart.
    assert!(record.travel_firings.is_empty());
    let blanked: Vec<_> = record.blanked_travels.iter().map(|t| t.power_s).collect();
    assert_eq!(blanked, [800.0]);
}

#[test]
fn under_m3_the_beam_stays_on_at_rest_after_a_cut_until_m5() {
    for (spindle, at_rest_s) in [("M3", 800.0), ("M4", 0.0)] {
        let mut grbl = cutter(CutterOptions::default());
        said(&mut grbl);
        for l in [&format!("{spindle} S800"), "G1 X10 F600"] {
            assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
        }
        grbl.advance_us(2_000_000);
        let record = grbl.log().snapshot();
        assert_eq!(record.state, "Idle");
        assert_eq!(record.laser_power_s, at_rest_s, "{spindle} at rest");
        grbl.receive(b"?");
        assert!(said(&mut grbl).ends_with(&format!(",{at_rest_s:.0}>\r\n")));
        // After a travel the beam is off even under M3.
        line(&mut grbl, "G0 X0");
        grbl.advance_us(1_000_000);
        assert_eq!(grbl.log().snapshot().laser_power_s, 0.0, "{spindle}");
    }
    let mut grbl = cutter(CutterOptions::default());
    for l in ["M3 S800", "G1 X10 F600"] {
        line(&mut grbl, l);
    }
    grbl.advance_us(2_000_000);
    assert_eq!(line(&mut grbl, "M5"), "ok\r\n");
    assert_eq!(grbl.log().snapshot().laser_power_s, 0.0);
    assert_eq!(line(&mut grbl, "M2"), "[MSG:Pgm End]\r\nok\r\n");
}

#[test]
fn a_spindle_change_waits_for_the_planner_to_empty_and_lines_behind_it_wait_too() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    for l in ["M4 S800", "G1 X10 F600"] {
        assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
    }
    grbl.receive(b"M5\nG0X0\n");
    assert_eq!(said(&mut grbl), "", "M5 waits, and the travel behind it");
    grbl.advance_us(500_000);
    assert_eq!(said(&mut grbl), "");
    grbl.advance_us(600_000);
    assert_eq!(said(&mut grbl), "ok\r\nok\r\n");
    grbl.advance_us(200_000);
    // A new power with the spindle on and no motion waits too; with motion it does not.
    for l in ["M4 S100", "G1 X5"] {
        assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
    }
    assert_eq!(line(&mut grbl, "G1 X6 S200"), "ok\r\n");
    assert_eq!(line(&mut grbl, "S300"), "");
}

#[test]
fn check_mode_answers_every_line_and_moves_nothing() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    assert_eq!(line(&mut grbl, "$C"), "[MSG:Enabled]\r\nok\r\n");
    for l in ["M4 S800", "G1 X10 F600", "M5"] {
        assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
    }
    assert_eq!(line(&mut grbl, "G2 X20"), "error:35\r\n");
    grbl.receive(b"?");
    assert!(said(&mut grbl).starts_with("<Check|MPos:0.000,0.000,0.000|"));
    grbl.advance_us(5_000_000);
    let exit = line(&mut grbl, "$C");
    assert_eq!(
        exit,
        "[MSG:Disabled]\r\nok\r\n\r\nGrbl 1.1h ['$' for help]\r\n"
    );
    let record = grbl.log().snapshot();
    assert!(record.segments.is_empty(), "{:?}", record.segments);
    assert_eq!((record.state.as_str(), record.alarms.len()), ("Idle", 0));
    // Only from rest.
    line(&mut grbl, "G1 X10 F600");
    assert_eq!(line(&mut grbl, "$C"), "error:8\r\n");
}

#[test]
fn without_laser_mode_the_spindle_fires_through_travels_and_that_is_recorded() {
    let mut grbl = cutter(CutterOptions {
        laser_mode: false,
        ..CutterOptions::default()
    });
    for l in ["M3S500", "G0X10"] {
        line(&mut grbl, l);
    }
    grbl.advance_us(1_000_000);
    let firings = grbl.log().snapshot().travel_firings;
    assert_eq!(firings.len(), 1, "{firings:?}");
    assert_eq!(firings[0].power_s, 500.0);
}

#[test]
fn a_reset_during_motion_is_alarm_3_with_the_laser_off_until_unlocked() {
    let mut grbl = cutter(CutterOptions::default());
    for l in ["M3S1000", "G1X100F600"] {
        line(&mut grbl, l);
    }
    grbl.advance_us(500_000);
    assert_eq!(grbl.log().snapshot().laser_power_s, 1000.0);
    said(&mut grbl);
    grbl.receive(&[SOFT_RESET]);
    let reply = said(&mut grbl);
    assert!(reply.starts_with("ALARM:3\r\n\r\nGrbl 1.1h"), "{reply}");
    assert!(reply.ends_with("[MSG:'$H'|'$X' to unlock]\r\n"), "{reply}");
    let record = grbl.log().snapshot();
    assert_eq!(
        (record.laser_power_s, record.state.as_str()),
        (0.0, "Alarm")
    );
    assert!(!record.segments[0].complete);
    assert_eq!(line(&mut grbl, "G1X1"), "error:9\r\n");
    assert_eq!(line(&mut grbl, "$X"), "[MSG:Caution: Unlocked]\r\nok\r\n");
    assert_eq!(line(&mut grbl, "G1X1F600"), "ok\r\n");
}

#[test]
fn a_feed_hold_stops_the_laser_and_a_reset_after_it_keeps_the_position() {
    let mut grbl = cutter(CutterOptions::default());
    for l in ["M4S1000", "G1X100F6000"] {
        line(&mut grbl, l);
    }
    grbl.advance_us(100_000);
    grbl.receive(b"!?");
    assert!(said(&mut grbl).starts_with("<Hold:1|"));
    // 100 mm/s at 1000 mm/s²: 100 ms to stop.
    grbl.advance_us(100_000);
    grbl.receive(b"?");
    assert!(said(&mut grbl).starts_with("<Hold:0|MPos:15.000,"));
    assert_eq!(grbl.log().snapshot().laser_power_s, 0.0);
    grbl.receive(&[SOFT_RESET]);
    grbl.receive(b"?");
    let reply = said(&mut grbl);
    assert!(!reply.contains("ALARM"), "{reply}");
    assert!(reply.contains("<Idle|MPos:15.000,"), "{reply}");
}

#[test]
fn bytes_that_come_with_a_reset_after_it_are_lost() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    grbl.receive(b"\x18G1X10F600\n?");
    let reply = said(&mut grbl);
    assert_eq!(
        reply, "\r\nGrbl 1.1h ['$' for help]\r\n",
        "no ok, no status"
    );
    assert_eq!(line(&mut grbl, "G1X10F600"), "ok\r\n");
}

#[test]
fn a_hard_limit_stops_everything_and_only_a_reset_is_heard() {
    let mut grbl = cutter(CutterOptions {
        hard_limit_after_ms: Some(300),
        ..CutterOptions::default()
    });
    said(&mut grbl);
    for l in ["M4S1000", "G1X100F600"] {
        line(&mut grbl, l);
    }
    grbl.advance_us(1_000_000);
    assert_eq!(said(&mut grbl), "ALARM:1\r\n[MSG:Reset to continue]\r\n");
    assert_eq!(line(&mut grbl, "$X"), "", "nothing but a reset is heard");
    grbl.receive(b"?");
    assert_eq!(said(&mut grbl), "", "not even a status request");
    grbl.receive(&[SOFT_RESET]);
    assert!(said(&mut grbl).contains("'$X' to unlock"));
    let record = grbl.log().snapshot();
    assert_eq!(record.alarms, [1]);
    assert_eq!(record.segments[0].end[0], 3.0);
    assert_eq!(record.laser_power_s, 0.0);
}

#[test]
fn injected_errors_and_alarms_come_as_asked() {
    let mut grbl = cutter(CutterOptions {
        boot_in_alarm: true,
        error_on_line: Some((2, 33)),
        ..CutterOptions::default()
    });
    assert!(said(&mut grbl).ends_with("[MSG:'$H'|'$X' to unlock]\r\n"));
    line(&mut grbl, "$X");
    assert_eq!(line(&mut grbl, "G0X1"), "ok\r\n");
    assert_eq!(line(&mut grbl, "G0X2"), "error:33\r\n");
    assert_eq!(line(&mut grbl, "G0X3"), "ok\r\n");
}

#[test]
fn what_it_does_not_understand_is_an_error_not_silence() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    assert_eq!(line(&mut grbl, "G1X10"), "error:22\r\n", "no feed yet");
    assert_eq!(
        line(&mut grbl, "G2X10F100"),
        "error:35\r\n",
        "arc without I/J"
    );
    assert_eq!(line(&mut grbl, "G28"), "error:20\r\n");
    assert_eq!(line(&mut grbl, "$Q"), "error:3\r\n");
    assert_eq!(line(&mut grbl, "(only a comment)"), "ok\r\n");
    assert_eq!(line(&mut grbl, "$32=0"), "ok\r\n");
    assert!(line(&mut grbl, "$$").contains("$32=0\r\n"));
}

proptest::proptest! {
    /// Whatever a sender writes, and whenever, the twin answers without panicking, and its
    /// receive buffer never holds more than GRBL's.
    #[test]
    fn any_bytes_at_any_time_are_survived(
        chunks in proptest::collection::vec(
            (
                proptest::collection::vec(
                    proptest::prop_oneof![
                        proptest::sample::select(b"G0123XYZIJFSMP$=.-?!~\n\r ;()".to_vec()),
                        proptest::num::u8::ANY,
                    ],
                    0..64,
                ),
                0u64..5_000_000,
            ),
            0..24,
        )
    ) {
        let mut grbl = cutter(CutterOptions::default());
        for (bytes, dt_us) in chunks {
            grbl.receive(&bytes);
            grbl.advance_us(dt_us);
            grbl.receive(b"?");
            let out = grbl.take_output();
            let text = String::from_utf8_lossy(&out);
            if let Some(start) = text.rfind("|Bf:") {
                let free: Vec<usize> = text[start + 4..]
                    .split(['|', '>'])
                    .next()
                    .unwrap()
                    .split(',')
                    .map(|n| n.parse().unwrap())
                    .collect();
                proptest::prop_assert!(free[1] <= RX_BUFFER_LEN);
            }
        }
    }

    /// Huge values (as many digits as a line holds) are errors or long moves, never an
    /// overflow, even held and reset.
    #[test]
    fn huge_numbers_are_survived(
        value in 1e3f64..1e70,
        letter in proptest::sample::select(vec!['X', 'P', 'I']),
    ) {
        let mut grbl = cutter(CutterOptions::default());
        said(&mut grbl);
        let text = format!("F100\nG1 {letter}{value:.0}\nG2 X1 I{value:.0}\nG4 P{value:.0}\n");
        grbl.receive(text.as_bytes());
        grbl.advance_us(1_000);
        grbl.receive(b"!");
        grbl.advance_us(u64::MAX / 4);
        // Each line taken is answered as GRBL answers, `ok` or `error:N` and nothing else: the
        // feed and the move at once; the arc once its segments fit in the planner (a huge one
        // waits behind the held move) and the dwell once the moves end, if they do.
        let replies = said(&mut grbl);
        let answers: Vec<&str> = replies.lines().filter(|l| !l.is_empty()).collect();
        let well_formed = answers
            .iter()
            .all(|l| *l == "ok" || l.strip_prefix("error:").is_some_and(|n| n.parse::<u8>().is_ok()));
        proptest::prop_assert!(well_formed, "{}", replies);
        proptest::prop_assert!((2..=4).contains(&answers.len()), "{}", replies);
        grbl.receive(&[SOFT_RESET]);
        // After the reset it boots again, and its position is a number, not an overflow.
        let rebooted = said(&mut grbl);
        proptest::prop_assert!(rebooted.contains("Grbl 1.1h"), "{}", rebooted);
        grbl.receive(b"?");
        let status = said(&mut grbl);
        proptest::prop_assert!(status.starts_with('<') && status.contains("MPos:"), "{}", status);
        proptest::prop_assert!(!status.contains("inf") && !status.contains("NaN"), "{}", status);
    }
}

/// G53 moves in machine coordinates for its block alone, under G91 too (the default twin's work
/// offset is zero, so they are the work ones), and only with G0 or G1.
#[test]
fn g53_moves_to_machine_coordinates_for_its_block() {
    let mut grbl = cutter(CutterOptions::default());
    said(&mut grbl);
    for l in ["G21G91", "G0Z5", "G0Z5", "G53G0Z-2", "G0Z1"] {
        assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
    }
    grbl.advance_us(10_000_000);
    grbl.receive(b"?");
    let status = said(&mut grbl);
    assert!(
        status.starts_with("<Idle|MPos:0.000,0.000,-1.000|"),
        "{status}"
    );
    assert_eq!(line(&mut grbl, "G2G53X1I1"), "error:30\r\n");
}

/// A homed machine with its G54 at the front-left corner: work X0 Y0 is machine −200, −200.
fn homed(soft_limits: bool) -> Grbl {
    let mut grbl = cutter(CutterOptions {
        travel_mm: [200.0, 200.0, 50.0],
        homing: true,
        soft_limits,
        work_offset_mm: [-200.0, -200.0, -50.0],
        ..CutterOptions::default()
    });
    assert!(
        said(&mut grbl).contains("'$X' to unlock"),
        "homing locks it at boot"
    );
    assert_eq!(line(&mut grbl, "$H"), "ok\r\n");
    grbl
}

fn position(grbl: &mut Grbl) -> String {
    grbl.receive(b"?");
    let status = said(grbl);
    status.split('|').nth(1).unwrap_or_default().to_owned()
}

#[test]
fn the_travel_homing_and_work_offsets_are_reported_as_grbl_does() {
    let mut grbl = homed(true);
    let settings = line(&mut grbl, "$$");
    for s in [
        "$130=200\r\n",
        "$131=200\r\n",
        "$132=50\r\n",
        "$20=1\r\n",
        "$22=1\r\n",
    ] {
        assert!(settings.contains(s), "{s} in {settings}");
    }
    assert_eq!(
        position(&mut grbl),
        "MPos:-1.000,-1.000,-1.000",
        "pulled off the switches"
    );
    let offsets = line(&mut grbl, "$#");
    assert!(offsets.starts_with("[G54:-200.000,-200.000,-50.000]\r\n[G55:0.000,0.000,0.000]"));
    assert!(offsets.contains("[G92:0.000,0.000,0.000]\r\n[TLO:0.000]\r\n"));
    assert!(offsets.ends_with("ok\r\n"));
    // Work X10 Y20 is machine −190, −180; G53 is machine coordinates.
    assert_eq!(line(&mut grbl, "G0X10Y20"), "ok\r\n");
    assert_eq!(line(&mut grbl, "G53G0Z-10"), "ok\r\n");
    grbl.advance_us(10_000_000);
    assert_eq!(position(&mut grbl), "MPos:-190.000,-180.000,-10.000");
    // As GRBL: no soft limits without homing, and homing off turns them off.
    let mut plain = cutter(CutterOptions::default());
    said(&mut plain);
    assert_eq!(line(&mut plain, "$20=1"), "error:10\r\n");
    assert_eq!(line(&mut grbl, "$22=0"), "ok\r\n");
    assert!(line(&mut grbl, "$$").contains("$20=0\r\n"));
    assert_eq!(line(&mut plain, "$H"), "error:5\r\n");
}

/// GRBL's soft limit: a target outside the machine space is ALARM:2 before the line moves
/// anything, in check mode too, and then only a reset is heard.
#[test]
fn with_soft_limits_a_target_beyond_the_travel_is_alarm_2_before_anything_moves() {
    let mut grbl = homed(true);
    assert_eq!(line(&mut grbl, "G0X50Y50"), "ok\r\n");
    grbl.advance_us(10_000_000);
    // Work X250 is machine +50, past the home switch.
    let said_now = line(&mut grbl, "G1X250F600");
    assert_eq!(said_now, "ALARM:2\r\n[MSG:Reset to continue]\r\n");
    grbl.advance_us(10_000_000);
    assert_eq!(line(&mut grbl, "$X"), "", "nothing but a reset is heard");
    let record = grbl.log().snapshot();
    assert_eq!(record.alarms, [2]);
    assert_eq!(record.segments.len(), 1, "the refused line moved nothing");
    assert!(record.end_stop_hits.is_empty());
    grbl.receive(&[SOFT_RESET]);
    said(&mut grbl);
    line(&mut grbl, "$X");
    assert_eq!(
        position(&mut grbl),
        "MPos:-150.000,-150.000,-1.000",
        "the position is kept"
    );
    // An arc whose ends are inside but whose bulge is not; and check mode is no escape.
    assert_eq!(line(&mut grbl, "$C"), "[MSG:Enabled]\r\nok\r\n");
    assert_eq!(line(&mut grbl, "G0X50Y150"), "ok\r\n");
    // About (110, 150), radius 60: over its top at work Y210, machine +10.
    let arc = line(&mut grbl, "G2X170Y150I60J0F600");
    assert_eq!(arc, "ALARM:2\r\n[MSG:Reset to continue]\r\n");
}

/// An arc on the edge of the travel whose centre, rounded to the G-code's 0.1 µm grid, bulges it
/// a few hundredths of a micrometre past the edge is on the edge (the host's check allows as
/// much: a job placed at Y 0 sometimes hit the end stop by 0.05 µm); half a micrometre is past.
#[test]
fn an_arc_rounded_onto_the_edge_of_the_travel_is_not_an_end_stop_hit() {
    let bulging = |j: &str| {
        let mut grbl = cutter(CutterOptions {
            travel_mm: [200.0, 200.0, 50.0],
            ..CutterOptions::default()
        });
        said(&mut grbl);
        // From (10, 1) to (12, 1) under a centre J below the start: its lowest point at about
        // Y = 1 + J − 1 = J.
        for l in ["G0X10Y1", &format!("G3X12Y1I1J{j}F600")] {
            assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
        }
        grbl.advance_us(30_000_000);
        grbl.log().snapshot().end_stop_hits
    };
    assert!(bulging("0").is_empty());
    assert!(bulging("-0.00005").is_empty());
    // Recorded where the head first passes the edge by more than the grid.
    let hits = bulging("-0.0005");
    assert_eq!(hits.len(), 1, "{hits:?}");
    assert!(
        hits[0].beyond_mm > 1e-4 && hits[0].beyond_mm <= 5.01e-4,
        "{hits:?}"
    );
}

/// Soft limits off (GRBL's default): the move runs, into the end stop, and the twin records it.
#[test]
fn without_soft_limits_a_move_beyond_the_travel_runs_into_the_end_stop_and_is_recorded() {
    let mut grbl = cutter(CutterOptions {
        travel_mm: [200.0, 200.0, 50.0],
        ..CutterOptions::default()
    });
    said(&mut grbl);
    assert!(line(&mut grbl, "$$").contains("$130=200\r\n$131=200\r\n$132=50\r\n"));
    for l in ["G0X150Y20", "G0Z20", "G0X350", "G91G0Z10"] {
        assert_eq!(line(&mut grbl, l), "ok\r\n", "{l}");
    }
    grbl.advance_us(30_000_000);
    let record = grbl.log().snapshot();
    assert!(record.alarms.is_empty());
    let hits: Vec<_> = record
        .end_stop_hits
        .iter()
        .map(|h| (h.line, h.axis, h.beyond_mm))
        .collect();
    assert_eq!(
        hits,
        [(3, 0, 150.0), (4, 2, 5.0)],
        "X past 200; Z past +25 (booted mid-Z)"
    );
    assert_eq!(
        record.gcode_received,
        ["G0X150Y20", "G0Z20", "G0X350", "G91G0Z10"]
    );
    // The same with homing on but soft limits off: a target above machine zero hits the switch.
    let mut homed = homed(false);
    assert_eq!(line(&mut homed, "G0X250"), "ok\r\n");
    homed.advance_us(10_000_000);
    let hits = homed.log().snapshot().end_stop_hits;
    assert_eq!(hits.len(), 1);
    assert!((hits[0].beyond_mm - 50.0).abs() < 1e-9, "{hits:?}");
}
