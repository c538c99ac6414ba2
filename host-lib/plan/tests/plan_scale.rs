//! Plans at scale: what must stay true when a plan is large and its contours are dilated on
//! several threads. A problem deep in a large file is still named by its line and column; the
//! output and the summary do not depend on the number of threads; removing many replaced DXF
//! entities keeps every other entity, in order, with its handle; progress is reported stage by
//! stage. (How fast it is: `cargo xtask bench-plan`, a benchmark, not a test.)

use std::sync::{Arc, Mutex};

use dxf::entities::{Circle, Entity, EntityType, Line, Text};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, Point};
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::dxf_plan::{DxfOptions, dilate_dxf};
use kerfmeter_plan::progress::{Progress, Stage};
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};

const HEAD: &str = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"600mm\" height=\"600mm\" viewBox=\"0 0 600 600\">\n";

/// `n` × `n` parts, one a line, each a square with a round hole and a rounded window, no ids.
fn svg_plan(n: usize) -> String {
    let mut s = HEAD.to_string();
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (5.0 + 20.0 * i as f64, 5.0 + 20.0 * j as f64);
            s.push_str(&format!(
                "  <g stroke=\"red\" stroke-width=\"0.1\" fill=\"none\"><path d=\"M{x} {y} h15 v15 h-15 Z\"/><circle cx=\"{}\" cy=\"{}\" r=\"2\"/><rect x=\"{}\" y=\"{}\" width=\"6\" height=\"4\" rx=\"1\"/></g>\n",
                x + 4.0,
                y + 4.0,
                x + 7.0,
                y + 9.0
            ));
        }
    }
    s
}

/// Why dilating `text` by `kerf_um` is refused (a panic with the summary when it is not).
fn refusal(text: &str, kerf_um: f64) -> String {
    match dilate_svg(text, &KerfSource::Uniform(kerf_um), &SvgOptions::default()) {
        Ok((_, summary)) => panic!("dilated: {summary:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_crossing_cut_deep_in_a_large_file_is_named_by_its_line_and_column() {
    let mut text = svg_plan(25);
    // Line 627 (the head, then 625 parts), column 7: a bow tie, which crosses itself.
    text.push_str("   \t  <path stroke=\"red\" stroke-width=\"0.1\" fill=\"none\" d=\"M 570 570 L 590 590 L 590 570 L 570 580 Z\"/>\n</svg>\n");
    let e = refusal(&text, 150.0);
    assert!(
        e.contains("<path> at line 627, column 7") && e.contains("crosses itself"),
        "{e}"
    );
}

#[test]
fn an_xml_error_deep_in_a_large_file_is_named_by_its_line_and_column() {
    let mut text = svg_plan(25);
    // Line 627: an attribute without a value, at column 12.
    text.push_str("  <path d/>\n</svg>\n");
    let e = dilate_svg(&text, &KerfSource::Uniform(150.0), &SvgOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("not a readable SVG") && e.contains("627:"),
        "{e}"
    );
}

/// `f` run on a rayon pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn the_svg_output_does_not_depend_on_the_number_of_threads() {
    let text = format!("{}</svg>\n", svg_plan(12));
    let run = || {
        let (out, summary) =
            dilate_svg(&text, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap();
        (out, serde_json::to_string(&summary).unwrap())
    };
    let one = on_threads(1, run);
    assert_eq!(one.1.matches("\"parts\":144").count(), 1, "{}", one.1);
    for threads in [2, 3, 8] {
        assert!(on_threads(threads, run) == one, "{threads} threads");
    }
}

#[test]
fn problems_are_listed_in_file_order_whatever_the_threads() {
    // Every other part's hole is too narrow for the kerf.
    let mut text = HEAD.to_string();
    for k in 0..40 {
        let x = 5.0 + 12.0 * k as f64;
        let w = if k % 2 == 0 { 0.1 } else { 2.0 };
        text.push_str(&format!(
            "<rect id=\"part{k}\" x=\"{x}\" y=\"5\" width=\"10\" height=\"10\" stroke=\"red\" stroke-width=\"0.1\" fill=\"none\"/><rect id=\"hole{k}\" x=\"{}\" y=\"7\" width=\"{w}\" height=\"5\" stroke=\"red\" stroke-width=\"0.1\" fill=\"none\"/>\n",
            x + 2.0
        ));
    }
    text.push_str("</svg>\n");
    let run = || refusal(&text, 200.0);
    let one = on_threads(1, run);
    let holes: Vec<usize> = (0..40)
        .filter_map(|k| one.find(&format!("\"hole{k}\"")))
        .collect();
    assert_eq!(holes.len(), 20, "{one}");
    assert!(holes.is_sorted(), "in file order: {one}");
    assert_eq!(on_threads(4, run), one);
}

/// A drawing (mm) of `n` parts: a label (TEXT, not a cut), a square of four LINEs and a CIRCLE.
fn dxf_plan(n: usize) -> Drawing {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2000;
    d.header.default_drawing_units = Units::Millimeters;
    let red = |specific| {
        let mut e = Entity::new(specific);
        e.common.color = dxf::Color::from_index(1);
        e
    };
    for k in 0..n {
        let x = 20.0 * k as f64;
        let mut label = Entity::new(EntityType::Text(Text {
            value: format!("part {k}"),
            ..Text::default()
        }));
        label.common.color = dxf::Color::from_index(3);
        d.add_entity(label);
        let corners = [(x, 0.0), (x + 10.0, 0.0), (x + 10.0, 10.0), (x, 10.0)];
        for i in 0..4 {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            d.add_entity(red(EntityType::Line(Line::new(
                Point::new(a.0, a.1, 0.0),
                Point::new(b.0, b.1, 0.0),
            ))));
        }
        d.add_entity(red(EntityType::Circle(Circle::new(
            Point::new(x + 5.0, 5.0, 0.0),
            2.0,
        ))));
    }
    d
}

#[test]
fn replaced_dxf_chains_go_and_every_other_entity_stays_in_order_with_its_handle() {
    let input = dxf_plan(300);
    let kept_before: Vec<(u64, String)> = input
        .entities()
        .filter(|e| !matches!(e.specific, EntityType::Line(_)))
        .map(|e| (e.common.handle.0, format!("{:?}", e.specific)))
        .collect();
    let mut bytes = Vec::new();
    input.save(&mut bytes).unwrap();
    let (out, summary) =
        dilate_dxf(&bytes, &KerfSource::Uniform(200.0), &DxfOptions::default()).unwrap();
    let out = Drawing::load(&mut std::io::Cursor::new(out)).unwrap();
    assert_eq!((summary.parts, summary.holes), (300, 300));
    let mut kept_after = Vec::new();
    let mut new_outlines = 0;
    for e in out.entities() {
        match &e.specific {
            EntityType::Line(_) => panic!("a replaced LINE is still there"),
            EntityType::LwPolyline(lw) => {
                assert_eq!(lw.vertices.len(), 8, "a square with round corners");
                new_outlines += 1;
            }
            EntityType::Text(t) => kept_after.push((e.common.handle.0, t.value.clone())),
            EntityType::Circle(c) => {
                assert!((c.radius - 1.9).abs() < 1e-9, "{}", c.radius);
                kept_after.push((e.common.handle.0, String::new()));
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(new_outlines, 300);
    assert_eq!(kept_after.len(), kept_before.len());
    for (before, after) in kept_before.iter().zip(&kept_after) {
        assert_eq!(before.0, after.0, "same handles in the same order");
    }
}

#[test]
fn the_dxf_output_does_not_depend_on_the_number_of_threads() {
    // 1,100 parts: more changed entities (5,500) and more new ones (1,100) than the splice
    // writes in one batch (1,024), so batches meet in the output.
    let mut bytes = Vec::new();
    dxf_plan(1100).save(&mut bytes).unwrap();
    let run = || {
        dilate_dxf(&bytes, &KerfSource::Uniform(150.0), &DxfOptions::default())
            .unwrap()
            .0
    };
    let one = on_threads(1, run);
    assert!(on_threads(4, run) == one);
    // And what the batches wrote is whole: every part's new outline and circle, each entity
    // with a handle of its own, the labels in order.
    let out = Drawing::load(&mut one.as_slice()).unwrap();
    let mut handles = std::collections::HashSet::new();
    let (mut outlines, mut circles, mut labels) = (0, 0, Vec::new());
    for e in out.entities() {
        assert!(
            handles.insert(e.common.handle.0),
            "handle {:X} twice",
            e.common.handle.0
        );
        match &e.specific {
            EntityType::LwPolyline(_) => outlines += 1,
            EntityType::Circle(_) => circles += 1,
            EntityType::Text(t) => labels.push(t.value.clone()),
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!((outlines, circles), (1100, 1100));
    let expected: Vec<String> = (0..1100).map(|k| format!("part {k}")).collect();
    assert_eq!(labels, expected);
}

#[test]
fn progress_is_told_stage_by_stage_with_every_contour_counted() {
    let text = format!("{}</svg>\n", svg_plan(10));
    let told: Arc<Mutex<Vec<(Stage, usize, usize)>>> = Arc::default();
    let sink = Arc::clone(&told);
    let options = SvgOptions {
        progress: Progress::new(move |stage, done, total| {
            sink.lock().unwrap().push((stage, done, total));
        }),
        ..SvgOptions::default()
    };
    dilate_svg(&text, &KerfSource::Uniform(150.0), &options).unwrap();
    let told = told.lock().unwrap();
    let stages: Vec<Stage> = told.iter().map(|t| t.0).collect();
    let first = |s: Stage| stages.iter().position(|&x| x == s).unwrap();
    let last = |s: Stage| stages.iter().rposition(|&x| x == s).unwrap();
    assert!(last(Stage::Reading) < first(Stage::Dilating), "{told:?}");
    assert!(last(Stage::Dilating) < first(Stage::Writing), "{told:?}");
    // 300 contours: told at every hundredth, the last one included.
    let counted: Vec<usize> = told
        .iter()
        .filter(|t| t.0 == Stage::Dilating && t.1 > 0)
        .map(|t| t.1)
        .collect();
    assert!(told.contains(&(Stage::Dilating, 0, 300)), "{told:?}");
    assert_eq!(counted.len(), 100, "{counted:?}");
    assert_eq!(counted.iter().max(), Some(&300));
}

/// A drawing far from the origin, where single precision (usvg's) cannot hold its coordinates,
/// is refused for that, not for what the rounding made of its shapes; nearer, but beyond the
/// 0.1 µm the output keeps, it dilates with a note saying how finely it was held.
#[test]
fn a_drawing_far_from_the_origin_is_refused_for_its_precision_and_noted_nearer() {
    let square = |x_mm: f64| {
        format!(
            "{HEAD}<path id=\"far\" stroke=\"red\" stroke-width=\"0.1\" fill=\"none\" d=\"M{x_mm} 10 h15 v15 h-15 Z\"/></svg>"
        )
    };
    let why = refusal(&square(5.0e6), 150.0);
    assert!(
        why.contains("reaches 5000015 mm from the origin") && why.contains("move the drawing"),
        "{why}"
    );
    let opts = SvgOptions::default();
    let (_, summary) = dilate_svg(&square(2000.0), &KerfSource::Uniform(150.0), &opts).unwrap();
    assert!(
        summary
            .notes
            .iter()
            .any(|n| n.contains("reaches 2015 mm") && n.contains("not 0.1 µm")),
        "{:?}",
        summary.notes
    );
    let (_, summary) = dilate_svg(&square(500.0), &KerfSource::Uniform(150.0), &opts).unwrap();
    assert!(summary.notes.is_empty(), "{:?}", summary.notes);
}

/// An `<svg>` root without the SVG namespace is told what it lacks, not that its root is
/// `<svg>`.
#[test]
fn an_svg_root_without_its_namespace_is_told_to_add_it() {
    let why = refusal("<svg width=\"10mm\" height=\"10mm\"/>", 150.0);
    assert!(
        why.contains("add xmlns=\"http://www.w3.org/2000/svg\""),
        "{why}"
    );
}
