//! The G-code programs: laser safety, cut geometry against the dilated plan (typed and as
//! written), cut order, settings per colour, a golden text and the gauge.

use super::*;
use crate::dilate::KerfSource;
use crate::dxf_plan::{DxfOptions, dilate_dxf_cuts};
use crate::gauge::{self, GaugeOptions, TestPieceSpec};
use crate::geom::{segment_distance, segment_point};
use crate::svg::{SvgOptions, dilate_svg_cuts};
use kerfmeter_protocol::GaugeGeometry;

const SETTINGS: CutSettings = CutSettings {
    feed_mm_per_min: 600.0,
    power_percent: 80.0,
    passes: 1,
};

fn svg(body: &str) -> String {
    format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="80mm" viewBox="0 0 100 80">{body}</svg>"#
    )
}

/// A rectangle, a circle and a path with arc commands, all red hairlines.
const ARCS: &str = r#"
  <rect id="plate" x="5" y="5" width="60" height="40" fill="none" stroke="red" stroke-width="0.01"/>
  <circle id="hole" cx="20" cy="20" r="6" fill="none" stroke="red" stroke-width="0.01"/>
  <path id="slot" d="M 35 15 L 50 15 A 5 5 0 0 1 50 25 L 35 25 A 5 5 0 0 1 35 15 Z" fill="none" stroke="red" stroke-width="0.01"/>
  <path id="disc" d="M 80 20 A 8 8 0 1 0 80 36 A 8 8 0 1 0 80 20 Z" fill="none" stroke="red" stroke-width="0.01"/>"#;

fn svg_cuts(body: &str, kerf_um: f64) -> Vec<CutPath> {
    dilate_svg_cuts(
        svg(body),
        &KerfSource::Uniform(kerf_um),
        &SvgOptions::default(),
    )
    .unwrap()
    .0
}

fn provenance() -> Provenance {
    Provenance {
        source: "test".into(),
        kerf: "200 um".into(),
    }
}

fn program(cuts: &[CutPath], y_down: bool, profile: &Profile) -> Result<(Program, Mapping)> {
    plan_program(
        cuts,
        y_down,
        profile,
        &GcodeOptions::default(),
        &provenance(),
    )
}

/// The largest distance from samples of `runs` (machine frame) to the nearest of `plines`
/// (document frame), and from samples of `plines` to the nearest run segment (both ways: nothing
/// extra cut, nothing left out). Only points go through `mapping`, so an arc drawn the wrong way
/// round is caught.
fn hausdorff(runs: &[Vec<Traced>], plines: &[Pline], mapping: &Mapping) -> f64 {
    let segs_of = |p: &Pline| -> Vec<Traced> {
        let n = p.vertex_count();
        (0..n)
            .map(|i| {
                let (a, b) = (p.at(i), p.at((i + 1) % n));
                (v2(a.x, a.y), v2(b.x, b.y), a.bulge)
            })
            .collect()
    };
    let plan: Vec<Traced> = plines.iter().flat_map(segs_of).collect();
    let cut: Vec<Traced> = runs.iter().flatten().copied().collect();
    let one_way = |from: &[Traced], to: &[Traced], map: &dyn Fn(V2) -> V2| -> f64 {
        let mut worst: f64 = 0.0;
        for &(a, b, bulge) in from {
            for k in 0..=8 {
                let q = map(segment_point(a, b, bulge, k as f64 / 8.0));
                let d = to
                    .iter()
                    .map(|&(c, e, g)| segment_distance(c, e, g, q))
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(d);
            }
        }
        worst
    };
    let to_doc = |q: V2| mapping.invert(q);
    let to_machine = |q: V2| mapping.apply(q);
    one_way(&cut, &plan, &to_doc).max(one_way(&plan, &cut, &to_machine))
}

/// Read the written text back (G0/G1/G2/G3 with X Y I J, M4/M5) into cut runs, refusing a
/// travel with the laser on.
fn reread(text: &str) -> Vec<Vec<Traced>> {
    let (mut on, mut head, mut runs) = (false, v2(0.0, 0.0), Vec::<Vec<Traced>>::new());
    for line in text.lines().filter(|l| !l.starts_with('(')) {
        let word = |c: char| {
            line.split(' ')
                .find(|w| w.starts_with(c))
                .map(|w| w[1..].parse::<f64>().unwrap())
        };
        let to = || v2(word('X').unwrap(), word('Y').unwrap());
        match line.split(' ').next().unwrap() {
            "M4" => {
                on = true;
                runs.push(Vec::new());
            }
            "M5" | "M2" => on = false,
            "G0" => {
                assert!(!on, "travel with the laser on: {line}");
                head = to();
            }
            "G1" => {
                runs.last_mut().unwrap().push((head, to(), 0.0));
                head = to();
            }
            g @ ("G2" | "G3") => {
                let c = head + v2(word('I').unwrap(), word('J').unwrap());
                let t = to();
                runs.last_mut()
                    .unwrap()
                    .push((head, t, arc_bulge(head, t, c, g == "G2")));
                head = t;
            }
            _ => {}
        }
        assert!(
            line.len() <= kerfmeter_grbl::LINE_MAX_LEN,
            "line too long for GRBL: {line}"
        );
    }
    assert!(!on, "the text ends with the laser on");
    runs
}

fn check_geometry(cuts: &[CutPath], y_down: bool) -> Program {
    let (prog, mapping) = program(cuts, y_down, &Profile::uniform(SETTINGS).unwrap()).unwrap();
    let runs = prog.traced().unwrap();
    assert_eq!(runs.len(), cuts.len());
    let expected: Vec<Pline> = cuts.iter().map(|c| c.pline.clone()).collect();
    let typed = hausdorff(&runs, &expected, &mapping);
    assert!(typed < 1e-6, "typed program off by {typed} mm");
    let written = hausdorff(&reread(&prog.to_text()), &expected, &mapping);
    assert!(
        written < 2e-4,
        "written program off by {} µm",
        written * 1e3
    );
    prog
}

#[test]
fn an_svg_with_arcs_is_cut_on_its_dilated_contours_with_the_laser_off_on_every_travel() {
    let cuts = svg_cuts(ARCS, 200.0);
    assert_eq!(cuts.len(), 4);
    let prog = check_geometry(&cuts, true);
    let arcs = prog
        .ops
        .iter()
        .filter(|o| matches!(o, Op::Arc { .. }))
        .count();
    assert!(arcs >= 8, "arcs kept as arcs: {arcs}");
    // Every travel comes after an explicit M5.
    let mut laser_off = false;
    for op in &prog.ops {
        match op {
            Op::LaserOff => laser_off = true,
            Op::LaserOn { .. } => laser_off = false,
            Op::Travel { .. } => assert!(laser_off),
            _ => {}
        }
    }
    let text = prog.to_text();
    let first: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with('('))
        .take(2)
        .collect();
    assert_eq!(first, ["G17 G21 G90 G94", "M5"]);
    assert!(text.ends_with("M5\nM2\n"));
}

#[test]
fn the_svg_is_flipped_into_the_machine_frame_with_its_box_at_the_origin() {
    let cuts = svg_cuts(ARCS, 0.0);
    let (_, mapping) = program(&cuts, true, &Profile::uniform(SETTINGS).unwrap()).unwrap();
    // The plate's top-left corner (5, 5) in the SVG is the machine's (0, 40): y up, box at 0.
    let q = mapping.apply(v2(5.0, 5.0));
    assert!((q - v2(0.0, 40.0)).length() < 1e-5, "{q:?}");
    assert!((mapping.invert(q) - v2(5.0, 5.0)).length() < 1e-12);
}

#[test]
fn a_dxf_is_cut_on_its_dilated_contours() {
    // The gauge's own DXF as a plan: LWPOLYLINE bulges and CIRCLEs, y up (dilated only on the
    // user's word: a gauge is cut as drawn).
    let d = gauge::build(&GaugeGeometry::PAPER, &GaugeOptions::default()).unwrap();
    let bytes = gauge::to_dxf(&d).unwrap();
    let opts = DxfOptions {
        if_compensated: crate::compensation::IfCompensated::DilateAnyway,
        ..DxfOptions::default()
    };
    let (cuts, _) = dilate_dxf_cuts(&bytes, &KerfSource::Uniform(150.0), &opts).unwrap();
    assert_eq!(cuts.len(), 3);
    assert!(cuts.iter().all(|c| c.group.layer.is_some()));
    check_geometry(&cuts, false);
}

#[test]
fn holes_and_islands_are_cut_before_the_contour_that_holds_them() {
    // Drawn outside in: the plate, its hole, an island in the hole, the island's hole; and a
    // second plate with a hole.
    let body = r#"
      <rect x="5" y="5" width="50" height="50" fill="none" stroke="red" stroke-width="0.01"/>
      <rect x="10" y="10" width="40" height="40" fill="none" stroke="red" stroke-width="0.01"/>
      <rect x="15" y="15" width="30" height="30" fill="none" stroke="red" stroke-width="0.01"/>
      <circle cx="30" cy="30" r="5" fill="none" stroke="red" stroke-width="0.01"/>
      <rect x="60" y="5" width="30" height="30" fill="none" stroke="red" stroke-width="0.01"/>
      <circle cx="75" cy="20" r="5" fill="none" stroke="red" stroke-width="0.01"/>"#;
    let cuts = svg_cuts(body, 100.0);
    let (prog, _) = program(&cuts, true, &Profile::uniform(SETTINGS).unwrap()).unwrap();
    let runs = prog.traced().unwrap();
    let closed: Vec<Pline> = runs
        .iter()
        .map(|r| {
            let mut p = Pline::new_closed();
            for &(a, _, bulge) in r {
                p.add(a.x, a.y, bulge);
            }
            p
        })
        .collect();
    assert_eq!(closed.len(), 6);
    for (i, earlier) in closed.iter().enumerate() {
        for later in &closed[i + 1..] {
            let v = later.at(0);
            assert_eq!(
                earlier.winding_number(v2(v.x, v.y)),
                0,
                "a contour is cut after one that encloses it"
            );
        }
    }
}

#[test]
fn settings_follow_the_colour_and_unknown_colours_are_refused() {
    let body = r##"
      <rect x="5" y="5" width="20" height="20" fill="none" stroke="#ff0000" stroke-width="0.01"/>
      <rect x="40" y="5" width="20" height="20" fill="none" stroke="blue" stroke-width="0.01"/>"##;
    let cuts = svg_cuts(body, 0.0);
    let profile = Profile::from_toml(
        "[color.red]\nfeed_mm_per_min = 300\npower_percent = 100\npasses = 2\n\
         [color.\"#0000ff\"]\nfeed_mm_per_min = 900\npower_percent = 40\n",
    )
    .unwrap();
    let (prog, mapping) = program(&cuts, true, &profile).unwrap();
    // Each contour's feed, power and number of segments (4 per pass).
    let mut seen = Vec::new();
    let (mut feed, mut s, mut segs) = (0.0, 0.0, 0);
    for op in &prog.ops {
        match op {
            Op::Feed { feed_mm_per_min } => feed = *feed_mm_per_min,
            Op::LaserOn { power_s } => (s, segs) = (*power_s, 0),
            Op::Line { .. } | Op::Arc { .. } => segs += 1,
            Op::LaserOff if segs > 0 => seen.push((feed, s, segs)),
            _ => {}
        }
    }
    seen.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(seen, [(300.0, 1000.0, 8), (900.0, 400.0, 4)]);
    let _ = mapping;
    let black = svg_cuts(
        r#"<rect x="70" y="5" width="20" height="20" fill="none" stroke="black" stroke-width="0.01"/>"#,
        0.0,
    );
    let mut all = cuts.clone();
    all.extend(black);
    let e = program(&all, true, &profile).unwrap_err().to_string();
    assert!(e.contains("colour #000000 (1 contour)"), "{e}");
    let with_default = Profile {
        default: Some(SETTINGS),
        ..profile
    };
    assert!(program(&all, true, &with_default).is_ok());
}

#[test]
fn inkscape_layers_and_dxf_layers_choose_settings() {
    let body = r#"<g xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" inkscape:groupmode="layer" inkscape:label="Fine">
      <rect x="5" y="5" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/></g>"#;
    let cuts = svg_cuts(body, 0.0);
    assert_eq!(cuts[0].group.layer.as_deref(), Some("Fine"));
    let profile =
        Profile::from_toml("[layer.fine]\nfeed_mm_per_min = 111\npower_percent = 10\n").unwrap();
    let (prog, _) = program(&cuts, true, &profile).unwrap();
    assert!(prog.ops.contains(&Op::Feed {
        feed_mm_per_min: 111.0
    }));
}

#[test]
fn a_square_with_a_round_hole_gives_the_golden_text() {
    let body = r#"
      <rect id="square" x="0" y="0" width="20" height="20" fill="none" stroke="red" stroke-width="0.01"/>
      <circle id="hole" cx="10" cy="10" r="4" fill="none" stroke="red" stroke-width="0.01"/>"#;
    let cuts = svg_cuts(body, 200.0);
    let (prog, _) = program(&cuts, true, &Profile::uniform(SETTINGS).unwrap()).unwrap();
    let stats = prog.stats();
    assert_eq!(stats.contours, 2);
    let expected_mm =
        2.0 * std::f64::consts::PI * 3.9 + 4.0 * 20.0 + 2.0 * std::f64::consts::PI * 0.1;
    assert!((stats.cut_mm - expected_mm).abs() < 1e-4, "{stats:?}");
    let text = prog.to_text();
    let body: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(body.join("\n"), GOLDEN.trim(), "\n{text}");
}

const GOLDEN: &str = r#"
(source: test)
(kerf applied: 200 um)
(settings: default: 600 mm/min, 80 pct, 1 pass)
(S_MAX=1000 must equal GRBL setting 30)
(needs GRBL setting 32=1 laser mode)
(arc tolerance setting 12 at most 0.002 mm, 0.001 better)
(SVG y flipped, box lower-left at X0 Y0 mm)
G17 G21 G90 G94
M5
(600 mm/min, 80 pct, 1 pass: circle "hole" [colour #FF0000])
G0 X10.1 Y6.2
F600
M4 S800
G2 X6.2 Y10.1 I0 J3.9
G2 X10.1 Y14 I3.9 J0
G2 X14 Y10.1 I0 J-3.9
G2 X10.1 Y6.2 I-3.9 J0
M5
(600 mm/min, 80 pct, 1 pass: rect "square" [colour #FF0000])
G0 X0.1 Y0
F600
M4 S800
G2 X0 Y0.1 I0 J0.1
G1 X0 Y20.1
G2 X0.1 Y20.2 I0.1 J0
G1 X20.1 Y20.2
G2 X20.2 Y20.1 I0 J-0.1
G1 X20.2 Y0.1
G2 X20.1 Y0 I-0.1 J0
G1 X0.1 Y0
M5
M2
"#;

#[test]
fn the_gauge_program_cuts_the_gauge_drawing() {
    let spec = TestPieceSpec {
        thickness_mm: 4.0,
        finger_width_mm: 6.3,
        kerf_um: 150.0,
    };
    let d = gauge::build(
        &GaugeGeometry::PAPER,
        &GaugeOptions {
            test_piece: Some(spec),
            label: true,
        },
    )
    .unwrap();
    let options = GcodeOptions {
        origin_mm: [100.0, 50.0],
        ..GcodeOptions::default()
    };
    let (prog, mapping) = gauge_program(&d, &SETTINGS, &options, &provenance()).unwrap();
    // The spiral centre is where it was asked for.
    assert!((mapping.apply(d.center) - v2(100.0, 50.0)).length() < 1e-12);
    let drawn: Vec<Pline> = gauge_cuts(&d).into_iter().map(|(_, p)| p).collect();
    assert_eq!(drawn.len(), 5);
    let runs = prog.traced().unwrap();
    assert!(hausdorff(&runs, &drawn, &mapping) < 1e-6);
    assert!(hausdorff(&reread(&prog.to_text()), &drawn, &mapping) < 2e-4);
    // Both holes are cut before the spiral that frees the inset holding them.
    let spiral_at = |r: &Vec<Traced>| (r[0].0 - mapping.apply(d.center)).length() > 10.0;
    let first_spiral = runs.iter().position(|r| r.len() > 20).unwrap();
    let holes_before = runs[..first_spiral]
        .iter()
        .filter(|r| !spiral_at(r))
        .count();
    assert_eq!(holes_before, 2);
}

#[test]
fn long_arcs_are_split_and_invisible_segments_dropped() {
    let mut p = Pline::new_closed();
    // A 270° arc and a straight closing chord, plus a 0.01 µm step.
    p.add(10.0, 0.0, (3.0 * std::f64::consts::PI / 8.0).tan());
    p.add(0.0, -10.0, 0.0);
    p.add(0.0, -10.000_000_01, 0.0);
    let job = Job {
        pline: p.clone(),
        label: "arc".into(),
        settings: SETTINGS,
    };
    let prog = build(vec![job], Vec::new(), DEFAULT_S_MAX);
    let arcs: Vec<&Op> = prog
        .ops
        .iter()
        .filter(|o| matches!(o, Op::Arc { .. }))
        .collect();
    assert_eq!(arcs.len(), 2);
    let lines = prog
        .ops
        .iter()
        .filter(|o| matches!(o, Op::Line { .. }))
        .count();
    assert_eq!(lines, 1);
    // The same contour with the arc as two 135° arcs (the distance of samples to an arc of over
    // half a turn is not reliable in the kernel).
    let h = (3.0 * std::f64::consts::PI / 16.0).tan();
    let mut same = Pline::new_closed();
    same.add(10.0, 0.0, h);
    same.add(-50f64.sqrt(), 50f64.sqrt(), h);
    same.add(0.0, -10.0, 0.0);
    let runs = prog.traced().unwrap();
    let identity = Mapping {
        flip_y: false,
        offset_mm: [0.0, 0.0],
    };
    assert!(hausdorff(&runs, std::slice::from_ref(&same), &identity) < 1e-6);
    assert!(hausdorff(&reread(&prog.to_text()), &[same], &identity) < 2e-4);
}

#[test]
fn numbers_are_written_on_a_tenth_of_a_micron() {
    assert_eq!(fmt_units(to_units(12.5)), "12.5");
    assert_eq!(fmt_units(to_units(-0.00004)), "0");
    assert_eq!(fmt_units(to_units(-3.00015)), "-3.0002");
    assert_eq!(fmt_units(to_units(7.0)), "7");
    assert_eq!(comment_text("path (a) 5 µm 80 %"), "path [a] 5 um 80 pct");
}

#[test]
fn comments_carry_no_realtime_or_sender_characters() {
    // GRBL acts on ? ! ~ even inside a comment; ; and $ confuse senders.
    assert_eq!(comment_text("why? stop! ~x; $30 é"), "why_ stop_ _x_ _30 _");
    let cuts = svg_cuts(ARCS, 0.0);
    let (prog, _) = program(&cuts, true, &Profile::uniform(SETTINGS).unwrap()).unwrap();
    let text = prog.to_text();
    for c in ['?', '!', '~', ';', '$'] {
        assert!(!text.contains(c), "{c} in\n{text}");
    }
    assert!(text.is_ascii());
}

#[test]
fn the_header_declares_the_s_max_the_powers_assume() {
    let options = GcodeOptions {
        s_max: 255.0,
        ..GcodeOptions::default()
    };
    let cuts = svg_cuts(ARCS, 0.0);
    let profile = Profile::uniform(SETTINGS).unwrap();
    let (prog, _) = plan_program(&cuts, true, &profile, &options, &provenance()).unwrap();
    let text = prog.to_text();
    let declared = format!("({S_MAX_TAG}255 must equal GRBL setting 30)");
    assert!(text.lines().any(|l| l == declared), "{text}");
    assert!(text.contains("M4 S204\n"), "80 % of 255:\n{text}");
}

#[test]
fn a_plan_beyond_any_bed_is_refused() {
    let mut huge = svg_cuts(ARCS, 0.0);
    let mut far = Pline::new_closed();
    // 20 m: beyond any laser's bed (and GRBL's float32 precision there).
    for (x, y) in [(0.0, 0.0), (2e4, 0.0), (2e4, 1.0)] {
        far.add(x, y, 0.0);
    }
    huge[0].pline = far;
    let e = program(&huge, true, &Profile::uniform(SETTINGS).unwrap())
        .unwrap_err()
        .to_string();
    assert!(e.contains("beyond any cutter's bed"), "{e}");
    let far_origin = GcodeOptions {
        origin_mm: [2e4, 0.0],
        ..GcodeOptions::default()
    };
    assert!(far_origin.check().is_err());
}

#[test]
fn a_contour_the_order_cannot_place_is_an_error_not_dropped() {
    let job = |pline: Pline, label: &str| Job {
        pline,
        label: label.into(),
        settings: SETTINGS,
    };
    let mut square = Pline::new_closed();
    for (x, y) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
        square.add(x, y, 0.0);
    }
    let e = cut_order(vec![job(square, "ok"), job(Pline::new_closed(), "empty")])
        .unwrap_err()
        .to_string();
    assert!(e.contains("empty"), "{e}");
}

#[test]
fn long_header_text_is_wrapped_not_cut_off() {
    let source = format!(
        "/home/someone/{}/plan.svg",
        "very-long-folder-name".repeat(6)
    );
    let provenance = Provenance {
        source: source.clone(),
        kerf: "200 um".into(),
    };
    let profile = Profile::from_toml(
        "[default]\nfeed_mm_per_min = 600\npower_percent = 80\n\n[color.blue]\nfeed_mm_per_min = 900\npower_percent = 40\n\n[layer.\"A rather long layer name for inner cuts\"]\nfeed_mm_per_min = 400\npower_percent = 90\n",
    )
    .unwrap();
    let cuts = svg_cuts(ARCS, 0.0);
    let options = GcodeOptions::default();
    let (prog, _) = plan_program(&cuts, true, &profile, &options, &provenance).unwrap();
    let text = prog.to_text();
    let comments: Vec<&str> = text.lines().filter(|l| l.starts_with('(')).collect();
    assert!(
        comments.iter().all(|l| l.len() <= MAX_COMMENT_CHARS + 2),
        "{text}"
    );
    let joined: String = comments
        .iter()
        .map(|l| l.trim_matches(['(', ')']).trim_start())
        .collect();
    assert!(joined.contains(&source), "{text}");
    assert!(joined.contains("inner cuts: 400"), "{text}");
    assert!(joined.contains("mm/min, 90 pct"), "{text}");
    assert!(joined.contains("#0000FF: 900 mm/min"), "{text}");
    assert!(joined.contains("default: 600 mm/min"), "{text}");
}

#[test]
fn large_radius_arcs_are_written_as_fine_chords() {
    // A 100 mm chord with a 10 µm sagitta: radius 125 m, where GRBL's float32 arc maths is off
    // by micrometres.
    let (from, to) = (v2(0.0, 0.0), v2(100.0, 0.0));
    let sweep = 2.0 * (50.0f64 / 125_000.0).asin();
    let bulge = (sweep / 4.0).tan();
    let arc = arc_geom(from, to, bulge).unwrap();
    let mut ops = Vec::new();
    segment_ops(from, to, bulge, &mut ops);
    assert!(ops.len() > 2, "{ops:?}");
    let mut head = from;
    for op in &ops {
        let Op::Line { to: p } = op else {
            panic!("not a chord: {op:?}")
        };
        assert!(((*p - arc.center).length() - arc.radius).abs() < 1e-4);
        let mid = (head + *p).scale(0.5);
        let sagitta = arc.radius - (mid - arc.center).length();
        assert!(sagitta <= CHORD_SAGITTA_MM + 1e-7, "{sagitta}");
        head = *p;
    }
    assert_eq!(head, to);
    // A small arc stays an arc.
    let mut ops = Vec::new();
    segment_ops(from, v2(2.0, 0.0), 0.5, &mut ops);
    assert!(matches!(ops[..], [Op::Arc { .. }]), "{ops:?}");
}

#[test]
fn a_program_with_a_travel_while_cutting_is_caught() {
    let prog = Program {
        header: Vec::new(),
        ops: vec![
            Op::LaserOff,
            Op::LaserOn { power_s: 100.0 },
            Op::Travel { to: v2(1.0, 1.0) },
            Op::LaserOff,
            Op::End,
        ],
    };
    assert!(prog.traced().unwrap_err().contains("travel"));
}
