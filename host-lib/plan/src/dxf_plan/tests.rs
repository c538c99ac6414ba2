//! The DXF reader and writer on drawings made with the `dxf` crate: units, splines, blocks
//! (rotated, scaled, nested, mirrored), and what is refused. Each drawing is saved by the crate,
//! dilated as a file, and the output read back.

use std::io::Cursor;

use dxf::entities::{Circle, Insert, Line, LwPolyline};
use dxf::{LwPolylineVertex, Point};

use super::geometry::ellipse_span;
use super::*;

/// Dilate a drawing saved as a file, and read the output back.
fn dilate_drawing(
    d: Drawing,
    kerf: &KerfSource,
    opts: &DxfOptions,
) -> Result<(Drawing, PlanSummary)> {
    let mut bytes = Vec::new();
    d.save(&mut bytes).expect("the crate saves a new drawing");
    let (out, summary) = dilate_dxf(&bytes, kerf, opts)?;
    let drawing = Drawing::load(&mut Cursor::new(out)).expect("the output reads back");
    Ok((drawing, summary))
}

#[test]
fn an_ellipse_span_is_one_turn_at_most_and_huge_parameters_end() {
    let tau = std::f64::consts::TAU;
    let close =
        |(a, b): (f64, f64), (c, d): (f64, f64)| (a - c).abs() < 1e-12 && (b - d).abs() < 1e-12;
    assert!(close(ellipse_span(0.0, tau), (0.0, tau)));
    assert!(close(ellipse_span(1.0, 3.0), (1.0, 3.0)));
    assert!(close(ellipse_span(5.0, 7.0), (5.0, 7.0)));
    assert!(close(ellipse_span(3.0, 1.0), (3.0, 1.0 + tau)));
    assert!(close(ellipse_span(0.0, 3.0 * tau), (0.0, tau)));
    assert!(close(ellipse_span(2.0, 2.0), (2.0, 2.0 + tau)));
    // Stepping a turn at a time never ended here.
    let (start, end) = ellipse_span(1e17, 1e17);
    assert!((0.0..tau).contains(&start) && (end - start - tau).abs() < 1e-9);
    let (start, end) = ellipse_span(1e12, 0.0);
    assert!((0.0..tau).contains(&start) && end > start && end - start <= tau);
}

fn drawing(units: Units) -> Drawing {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2000;
    d.header.default_drawing_units = units;
    let mut c = Entity::new(EntityType::Circle(Circle::new(
        Point::new(5.0, 5.0, 0.0),
        1.0,
    )));
    c.common.color = dxf::Color::from_index(1);
    d.add_entity(c);
    d
}

#[test]
fn inches_are_converted_both_ways() {
    // 254 µm of kerf = 0.01 in: the hole-less disc grows by 0.005 in of radius.
    let (out, s) = dilate_drawing(
        drawing(Units::Inches),
        &KerfSource::Uniform(254.0),
        &DxfOptions::default(),
    )
    .unwrap();
    assert_eq!(s.mm_per_unit, 25.4);
    let r = out
        .entities()
        .find_map(|e| match &e.specific {
            EntityType::Circle(c) => Some(c.radius),
            _ => None,
        })
        .unwrap();
    assert!((r - 1.005).abs() < 1e-12, "{r}");
}

#[test]
fn unitless_drawings_need_assumed_units_and_other_colours_pass() {
    let e = dilate_drawing(
        drawing(Units::Unitless),
        &KerfSource::Uniform(100.0),
        &DxfOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("unknown units"), "{e}");
    let mut d = drawing(Units::Unitless);
    let mut l = Entity::new(EntityType::Line(Line::new(
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
    )));
    l.common.color = dxf::Color::from_index(3);
    d.add_entity(l);
    let opts = DxfOptions {
        assume_units: Some(AssumedUnits::Mm),
        ..DxfOptions::default()
    };
    let (_, s) = dilate_drawing(d, &KerfSource::Uniform(100.0), &opts).unwrap();
    assert_eq!(s.contours_dilated, 1);
    assert_eq!(s.passed_through.len(), 1, "{:?}", s.passed_through);
    assert!(s.open_paths.is_empty());
}

#[test]
fn a_spline_that_cannot_be_a_curve_is_refused_with_the_reason() {
    let mut d = drawing(Units::Millimeters);
    let mut sp = Entity::new(EntityType::Spline(dxf::entities::Spline::default()));
    sp.common.color = dxf::Color::from_index(1);
    d.add_entity(sp);
    let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("SPLINE") && e.contains("control points"), "{e}");
}

/// A closed rational quadratic spline: the circle of radius 10 about (50, 50), four arcs.
fn circle_spline() -> dxf::entities::Spline {
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let pts = [
        (60.0, 50.0),
        (60.0, 60.0),
        (50.0, 60.0),
        (40.0, 60.0),
        (40.0, 50.0),
        (40.0, 40.0),
        (50.0, 40.0),
        (60.0, 40.0),
        (60.0, 50.0),
    ];
    let mut sp = dxf::entities::Spline {
        degree_of_curve: 2,
        control_points: pts.iter().map(|&(x, y)| Point::new(x, y, 0.0)).collect(),
        weight_values: (0..9).map(|k| if k % 2 == 1 { w } else { 1.0 }).collect(),
        knot_values: vec![0., 0., 0., 1., 1., 2., 2., 3., 3., 4., 4., 4.],
        ..Default::default()
    };
    sp.set_is_closed(true);
    sp.set_is_rational(true);
    sp
}

/// Every vertex's distance from (50, 50), and every arc's radius about it.
fn radii(p: &LwPolyline) -> Vec<f64> {
    let n = p.vertices.len();
    (0..n)
        .map(|k| {
            let (a, b) = (&p.vertices[k], &p.vertices[(k + 1) % n]);
            let mid = crate::geom::segment_point(v2(a.x, a.y), v2(b.x, b.y), a.bulge, 0.5);
            (mid - v2(50.0, 50.0)).length()
        })
        .collect()
}

fn lwpolylines(d: &Drawing) -> Vec<&LwPolyline> {
    d.entities()
        .filter_map(|e| match &e.specific {
            EntityType::LwPolyline(p) => Some(p),
            _ => None,
        })
        .collect()
}

#[test]
fn a_spline_is_read_as_arcs_and_dilated() {
    let mut d = drawing(Units::Millimeters);
    let mut sp = Entity::new(EntityType::Spline(circle_spline()));
    sp.common.color = dxf::Color::from_index(1);
    d.add_entity(sp);
    let (out, s) = dilate_drawing(d, &KerfSource::Uniform(200.0), &DxfOptions::default()).unwrap();
    assert_eq!(s.contours_dilated, 2);
    let pl = lwpolylines(&out);
    assert_eq!(pl.len(), 1);
    // Within 0.01 µm: the numbers are written to 0.01 µm.
    for r in radii(pl[0]) {
        assert!((r - 10.1).abs() < 1e-5, "{r} {:?}", pl[0].vertices);
    }
    assert!(
        s.notes.iter().any(|n| n.contains("SPLINE")),
        "{:?}",
        s.notes
    );
}

/// A block `PART` (base point (1, 1)): a red square 0..10 drawn on layer 0 in BYBLOCK colour,
/// a text, and an open red line; inserted by `insert`.
fn with_block(insert: Insert) -> Drawing {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2000;
    d.header.default_drawing_units = Units::Millimeters;
    let mut square = LwPolyline::default();
    for (x, y) in [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)] {
        square.vertices.push(LwPolylineVertex {
            x,
            y,
            ..Default::default()
        });
    }
    square.set_is_closed(true);
    let mut sq = Entity::new(EntityType::LwPolyline(square));
    sq.common.color = dxf::Color::by_block();
    let text = Entity::new(EntityType::Text(dxf::entities::Text {
        value: "label".into(),
        ..Default::default()
    }));
    let mut slit = Entity::new(EntityType::Line(Line::new(
        Point::new(2.0, 5.0, 0.0),
        Point::new(8.0, 5.0, 0.0),
    )));
    slit.common.color = dxf::Color::from_index(1);
    let block = dxf::Block {
        name: "PART".into(),
        base_point: Point::new(1.0, 1.0, 0.0),
        entities: vec![sq, text, slit],
        ..Default::default()
    };
    d.add_block(block);
    let mut ins = Entity::new(EntityType::Insert(insert));
    ins.common.color = dxf::Color::from_index(1);
    d.add_entity(ins);
    d
}

fn bounds(p: &LwPolyline) -> (f64, f64, f64, f64) {
    let xs = p.vertices.iter().map(|v| v.x);
    let ys = p.vertices.iter().map(|v| v.y);
    (
        xs.clone().fold(f64::INFINITY, f64::min),
        ys.clone().fold(f64::INFINITY, f64::min),
        xs.fold(f64::NEG_INFINITY, f64::max),
        ys.fold(f64::NEG_INFINITY, f64::max),
    )
}

#[test]
fn cuts_inside_a_rotated_scaled_block_are_dilated_and_the_rest_is_kept() {
    let insert = Insert {
        name: "PART".into(),
        location: Point::new(100.0, 0.0, 0.0),
        x_scale_factor: 2.0,
        y_scale_factor: 2.0,
        rotation: 90.0,
        ..Default::default()
    };
    let (out, s) = dilate_drawing(
        with_block(insert),
        &KerfSource::Uniform(200.0),
        &DxfOptions::default(),
    )
    .unwrap();
    assert_eq!(s.contours_dilated, 1);
    assert_eq!(s.open_paths.len(), 1, "{:?}", s.open_paths);
    // The square (0..10 about base (1, 1)), doubled and turned a quarter: x 100−18 … 100+2,
    // y −2 … 18; then dilated by 0.1 mm.
    let pl = lwpolylines(&out);
    assert_eq!(pl.len(), 1);
    let (x0, y0, x1, y1) = bounds(pl[0]);
    for (got, want) in [(x0, 81.9), (y0, -2.1), (x1, 102.1), (y1, 18.1)] {
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
    // The INSERT is as it was, and its block keeps the text and the open line alone.
    let name = out
        .entities()
        .find_map(|e| match &e.specific {
            EntityType::Insert(i) => Some(i.name.clone()),
            _ => None,
        })
        .unwrap();
    assert_eq!(name, "PART");
    let part = out.blocks().find(|b| b.name == "PART").unwrap();
    let kinds: Vec<String> = part
        .entities
        .iter()
        .map(|e| type_name(&e.specific))
        .collect();
    assert_eq!(kinds, ["TEXT", "LINE"]);
    assert!(
        s.notes
            .iter()
            .any(|n| n.contains("taken out of their blocks (PART)")),
        "{:?}",
        s.notes
    );
}

#[test]
fn unequal_block_scales_make_circles_ellipses_and_nested_blocks_compose() {
    let mut d = with_block(Insert {
        name: "PART".into(),
        ..Default::default()
    });
    // A block OUTER inserting PART stretched 3 × 1, itself inserted mirrored in x.
    let inner = Entity::new(EntityType::Insert(Insert {
        name: "PART".into(),
        location: Point::new(1.0, 1.0, 0.0),
        x_scale_factor: 3.0,
        ..Default::default()
    }));
    let mut circle = Entity::new(EntityType::Circle(Circle::new(
        Point::new(0.0, 20.0, 0.0),
        2.0,
    )));
    circle.common.color = dxf::Color::from_index(5);
    d.add_block(dxf::Block {
        name: "OUTER".into(),
        entities: vec![inner, circle],
        ..Default::default()
    });
    let mut outer = Entity::new(EntityType::Insert(Insert {
        name: "OUTER".into(),
        location: Point::new(50.0, 0.0, 0.0),
        x_scale_factor: -1.0,
        y_scale_factor: 2.0,
        ..Default::default()
    }));
    outer.common.color = dxf::Color::from_index(1);
    d.add_entity(outer);
    let (out, s) = dilate_drawing(d, &KerfSource::Uniform(200.0), &DxfOptions::default()).unwrap();
    // The first INSERT's square, the nested one, and the circle (now an ellipse 2 × 4).
    assert_eq!(s.contours_dilated, 3);
    let boxes: Vec<_> = lwpolylines(&out).into_iter().map(bounds).collect();
    let near = |a: (f64, f64, f64, f64), b: (f64, f64, f64, f64)| {
        [(a.0, b.0), (a.1, b.1), (a.2, b.2), (a.3, b.3)]
            .iter()
            .all(|(p, q)| (p - q).abs() < 1e-4)
    };
    // Nested: PART's x, y ∈ 0…10 about its base (1, 1), placed at (1, 1) in OUTER:
    // x ↦ 1 + 3·(x − 1) ∈ −2…28, y ∈ 0…10; OUTER at (50, 0) scaled (−1, 2): x 22…52, y 0…20.
    assert!(
        boxes.iter().any(|b| near(*b, (21.9, -0.1, 52.1, 20.1))),
        "{boxes:?}"
    );
    // The ellipse about (50, 40): semi-axes 2 (x) and 4 (y), dilated by 0.1.
    assert!(
        boxes.iter().any(|b| near(*b, (47.9, 35.9, 52.1, 44.1))),
        "{boxes:?}"
    );
    // OUTER keeps its INSERT of PART, whose cut (inserted twice) went once.
    let outer_block = out.blocks().find(|b| b.name == "OUTER").unwrap();
    assert_eq!(outer_block.entities.len(), 1);
    let part = out.blocks().find(|b| b.name == "PART").unwrap();
    assert_eq!(part.entities.len(), 2);
}

#[test]
fn a_block_with_cuts_also_inserted_in_paper_space_is_refused_naming_it() {
    let mut d = with_block(Insert {
        name: "PART".into(),
        ..Default::default()
    });
    let mut paper = Entity::new(EntityType::Insert(Insert {
        name: "PART".into(),
        ..Default::default()
    }));
    paper.common.is_in_paper_space = true;
    d.add_entity(paper);
    let e = dilate_drawing(d, &KerfSource::Uniform(200.0), &DxfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("block \"PART\" holds cuts"), "{e}");
    assert!(e.contains("inserted in paper space by INSERT"), "{e}");
}

#[test]
fn a_block_that_inserts_itself_or_is_missing_is_refused() {
    let mut d = drawing(Units::Millimeters);
    let me = Entity::new(EntityType::Insert(Insert {
        name: "LOOP".into(),
        ..Default::default()
    }));
    d.add_block(dxf::Block {
        name: "LOOP".into(),
        entities: vec![me],
        ..Default::default()
    });
    d.add_entity(Entity::new(EntityType::Insert(Insert {
        name: "LOOP".into(),
        ..Default::default()
    })));
    d.add_entity(Entity::new(EntityType::Insert(Insert {
        name: "GONE".into(),
        ..Default::default()
    })));
    let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("\"LOOP\" inside itself"), "{e}");
    assert!(e.contains("\"GONE\", which is not in the file"), "{e}");
}

/// A few hundred bytes: an array of 316 × 316 copies of a block of 50 circles (5 million
/// contours, which ran out of memory) is refused for its size before it is read.
#[test]
fn an_array_of_a_large_block_is_refused_for_the_entities_it_comes_to() {
    let mut d = drawing(Units::Millimeters);
    let circles = (0..50)
        .map(|k| {
            let mut c = Entity::new(EntityType::Circle(dxf::entities::Circle::new(
                Point::new(f64::from(k), 0.0, 0.0),
                0.4,
            )));
            c.common.color = dxf::Color::from_index(1);
            c
        })
        .collect();
    d.add_block(dxf::Block {
        name: "S".into(),
        entities: circles,
        ..Default::default()
    });
    d.add_entity(Entity::new(EntityType::Insert(Insert {
        name: "S".into(),
        column_count: 316,
        row_count: 316,
        column_spacing: 60.0,
        row_spacing: 2.0,
        ..Default::default()
    })));
    let e = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("come to more than 1000000 entities"), "{e}");
}

#[test]
fn a_cut_in_a_block_is_named_by_the_handle_its_file_gives_it() {
    // The crate renumbers a block's entities as it reads them; the message names the file's.
    let text = "  0\nSECTION\n  2\nHEADER\n  9\n$ACADVER\n  1\nAC1015\n  9\n$INSUNITS\n 70\n4\n  0\nENDSEC\n\
        0\nSECTION\n  2\nBLOCKS\n  0\nBLOCK\n  5\n20\n  2\nP\n 70\n0\n 10\n0.0\n 20\n0.0\n 30\n0.0\n\
        0\nPOLYLINE\n  5\nABC\n  8\nCUT\n 62\n1\n 66\n1\n 70\n9\n\
        0\nVERTEX\n  5\nABD\n  8\nCUT\n 10\n0.0\n 20\n0.0\n 30\n1.0\n 70\n32\n\
        0\nVERTEX\n  5\nABE\n  8\nCUT\n 10\n1.0\n 20\n0.0\n 30\n0.0\n 70\n32\n\
        0\nSEQEND\n  5\nABF\n  8\nCUT\n  0\nENDBLK\n  5\n21\n  8\n0\n  0\nENDSEC\n\
        0\nSECTION\n  2\nENTITIES\n  0\nINSERT\n  5\n30\n  8\nCUT\n  2\nP\n 10\n0.0\n 20\n0.0\n 30\n0.0\n  0\nENDSEC\n  0\nEOF\n";
    let e = dilate_dxf(
        text.as_bytes(),
        &KerfSource::Uniform(100.0),
        &DxfOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("POLYLINE ABC on layer CUT"), "{e}");
    assert!(e.contains("a 3-D polyline"), "{e}");
}

#[test]
fn a_binary_dxf_comes_back_as_ascii_with_its_cut_dilated() {
    let mut bytes = Vec::new();
    drawing(Units::Millimeters).save_binary(&mut bytes).unwrap();
    assert!(bytes.starts_with(b"AutoCAD Binary DXF"));
    let (out, s) = dilate_dxf(&bytes, &KerfSource::Uniform(200.0), &DxfOptions::default()).unwrap();
    assert!(out.starts_with(b"999"), "ASCII, the record first");
    assert!(
        s.notes.iter().any(|n| n.contains("written as ASCII")),
        "{:?}",
        s.notes
    );
    let back = Drawing::load(&mut Cursor::new(out)).unwrap();
    let r = back
        .entities()
        .find_map(|e| match &e.specific {
            EntityType::Circle(c) => Some(c.radius),
            _ => None,
        })
        .unwrap();
    assert!((r - 1.1).abs() < 1e-12, "{r}");
}

#[test]
fn an_r12_drawing_stays_r12_with_its_new_outlines_as_polylines() {
    let text = include_str!("../../tests/corpus/r12_polyline_unitless.dxf");
    let opts = DxfOptions {
        assume_units: Some(AssumedUnits::Mm),
        ..DxfOptions::default()
    };
    let (out, s) = dilate_dxf(text.as_bytes(), &KerfSource::Uniform(150.0), &opts).unwrap();
    let out = String::from_utf8(out).unwrap();
    assert!(
        out.contains("$ACADVER\r\n  1\r\nAC1009"),
        "kept its version"
    );
    assert!(!out.contains("LWPOLYLINE") && !out.contains("$INSUNITS") && !out.contains("100\r\n"));
    // The slot chain (LINEs and ARCs) became one more POLYLINE with its VERTEXes and SEQEND.
    let count = |t: &str, kind: &str| t.matches(&format!("\r\n{kind}\r\n")).count();
    assert_eq!(count(&out, "POLYLINE"), count(text, "POLYLINE") + 1);
    assert!(count(&out, "VERTEX") > count(text, "VERTEX"));
    assert_eq!(count(&out, "SEQEND"), count(text, "SEQEND") + 1);
    assert!(
        s.notes
            .iter()
            .any(|n| n.contains("$INSUNITS came with R2000")),
        "{:?}",
        s.notes
    );
}

#[test]
fn a_zero_radius_arc_is_noted_and_what_is_passed_through_says_which_flag_cuts_it() {
    let mut d = drawing(Units::Millimeters);
    let mut zero = Entity::new(EntityType::Arc(dxf::entities::Arc::new(
        Point::new(1.0, 1.0, 0.0),
        0.0,
        0.0,
        90.0,
    )));
    zero.common.color = dxf::Color::from_index(1);
    d.add_entity(zero);
    // Grey (ACI 8) and a thick red line: neither is cut, and each says what would cut it.
    let mut grey = Entity::new(EntityType::Line(Line::new(
        Point::new(0.0, 0.0, 0.0),
        Point::new(1.0, 0.0, 0.0),
    )));
    grey.common.color = dxf::Color::from_index(8);
    d.add_entity(grey);
    let mut thick = Entity::new(EntityType::Line(Line::new(
        Point::new(0.0, 2.0, 0.0),
        Point::new(1.0, 2.0, 0.0),
    )));
    thick.common.color = dxf::Color::from_index(1);
    thick.common.lineweight_enum_value = 70;
    d.add_entity(thick);
    let (_, s) = dilate_drawing(d, &KerfSource::Uniform(100.0), &DxfOptions::default()).unwrap();
    assert_eq!(s.contours_dilated, 1);
    assert!(
        s.notes
            .iter()
            .any(|n| n.contains("has radius 0: nothing to cut")),
        "{:?}",
        s.notes
    );
    let reasons: Vec<&String> = s.passed_through.keys().collect();
    assert!(
        reasons
            .iter()
            .any(|r| r.contains("colour #808080") && r.contains("--cut-color '#808080'")),
        "{reasons:?}"
    );
    assert!(
        reasons
            .iter()
            .any(|r| r.contains("lineweight 0.7 mm") && r.contains("--cut-max-width-mm")),
        "{reasons:?}"
    );
}

/// A drawing (R2018, mm) of two circles of radius 5 mm and nothing else: one in ACI `aci`, one
/// in the true colour `rgb` (group 420, written from R2004).
fn two_circles(aci: u8, rgb: u32) -> Drawing {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2018;
    d.header.default_drawing_units = Units::Millimeters;
    let mut by_index = Entity::new(EntityType::Circle(Circle::new(
        Point::new(0.0, 0.0, 0.0),
        5.0,
    )));
    by_index.common.color = dxf::Color::from_index(aci);
    d.add_entity(by_index);
    let mut by_rgb = Entity::new(EntityType::Circle(Circle::new(
        Point::new(20.0, 0.0, 0.0),
        5.0,
    )));
    by_rgb.common.color_24_bit = i32::try_from(rgb).unwrap();
    d.add_entity(by_rgb);
    d
}

/// How many contours `--cut-color colors` cuts in `d` (0 when the plan is refused for having
/// none), and the refusal's message.
fn cut_by(d: Drawing, colors: &[&str]) -> (usize, String) {
    let colors: Vec<String> = colors.iter().map(|c| c.to_string()).collect();
    let options = DxfOptions {
        rules: CutRules::new(&colors, 0.3, &[]).unwrap(),
        ..DxfOptions::default()
    };
    match dilate_drawing(d, &KerfSource::Uniform(100.0), &options) {
        Ok((_, s)) => (s.contours_dilated, String::new()),
        Err(e) => (0, e.to_string()),
    }
}

#[test]
fn a_cut_colour_is_an_aci_number_or_a_true_colour_and_matches_both_ways() {
    // ACI 8 is #808080 in the palette: an ACI-8 circle and a #808080 true-colour one.
    let grey = || two_circles(8, 0x80_80_80);
    for named in ["8", "#808080", "rgb(128,128,128)", "grey"] {
        assert_eq!(cut_by(grey(), &[named]).0, 2, "--cut-color {named}");
    }
    // Another grey (ACI 9, #C0C0C0) cuts neither, and the defaults (red, blue, black) neither:
    // the refusal says what to pass.
    for colors in [&["9"][..], &[][..]] {
        let (n, why) = cut_by(grey(), colors);
        assert_eq!(n, 0, "{colors:?}");
        assert!(
            why.contains("colour #808080") && why.contains("ACI number from 1 to 255"),
            "{why}"
        );
    }
    // A true colour past the first seven, named by its index (ACI 30 is #FF7F00), and an
    // index that shares red's colour (ACI 10), cut by the default red.
    assert_eq!(cut_by(two_circles(30, 0xFF_7F_00), &["30"]).0, 2);
    assert_eq!(cut_by(two_circles(10, 0xFF_00_00), &[]).0, 2);
    // A colour off the palette matches its true-colour entity only.
    assert_eq!(cut_by(two_circles(8, 0x80_80_81), &["#808081"]).0, 1);
    // ACI 7 is black on the laser's sheet, as before: `7` cuts it, not the red beside it.
    assert_eq!(cut_by(two_circles(7, 0xFF_00_00), &["7"]).0, 1);
}

#[test]
fn an_aci_number_outside_1_to_255_is_refused_saying_the_range() {
    for bad in ["0", "256", "1000"] {
        let e = CutRules::new(&[bad.to_string()], 0.3, &[]).unwrap_err();
        assert!(e.to_string().contains("from 1 to 255"), "{bad}: {e}");
    }
}
