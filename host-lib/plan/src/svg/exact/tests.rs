//! The rebuilt geometry against what usvg draws from the same source (the mirror of its path
//! building must give the same subpaths, point for point), what is left to usvg, and the notes.
//! How close the traced curves come to the true ones is measured in
//! `tests/plan_svg_curves.rs`.

use super::*;
use crate::dilate::KerfSource;
use crate::svg::walk::subpaths_of;
use crate::svg::{SvgOptions, dilate_svg};

/// usvg's subpaths of the only path in `svg`, and its map to px.
fn usvg_subpaths(svg: &str) -> (Vec<Vec<Seg>>, Affine) {
    let tree = usvg::Tree::from_str(svg, &usvg::Options::default()).expect("usvg reads it");
    let mut group = tree.root();
    loop {
        match group.children().first() {
            Some(usvg::Node::Group(g)) => group = g,
            Some(usvg::Node::Path(p)) => {
                return (
                    subpaths_of(p.data()),
                    super::super::walk::affine(p.abs_transform()),
                );
            }
            _ => panic!("no path in {svg}"),
        }
    }
}

/// An SVG of the one element `element` (user units are px).
fn svg_of(element: &str) -> String {
    format!(r#"<svg xmlns="http://www.w3.org/2000/svg" width="400" height="400">{element}</svg>"#)
}

/// The rebuilt geometry of `element`, and whether it agrees with usvg's.
fn agrees(element: &str) -> bool {
    let svg = svg_of(element);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let node = doc.root_element().first_element_child().unwrap();
    let path = read::geometry(node).unwrap_or_else(|| panic!("{element} is read"));
    let (drawn, to_px) = usvg_subpaths(&svg);
    path.agrees(&drawn, &to_px, 1e-4)
}

#[test]
fn rebuilt_paths_are_usvgs_subpath_for_subpath() {
    let data = [
        "M10 10 A 20 10 30 0 1 40 30 L 10 40 Z",
        // Relative, large arc, sweep 0.
        "m10 10 a20 10 30 1 0 30 20 l-30 10 z",
        // Smooth cubics and quadratics around an arc.
        "M0 0 C 10 0 20 10 20 20 S 30 40 40 40 Q 50 40 50 30 T 60 10 T 70 0 A 5 8 0 0 1 80 0 Z",
        "M0 0 Q 10 10 20 0 A 4 9 20 0 0 30 0 T 40 0 s 5 5 10 0 Z",
        // A segment after a close starts a subpath at the closed one's start.
        "M0 0 A 10 5 0 0 1 20 0 Z L 30 30 A 10 5 45 1 1 40 40 Z",
        "M0 0 a 5 10 0 0 1 10 0 z m 20 0 a 5 10 0 1 1 10 0 z",
        // A move after a move replaces it; a trailing move is a subpath of its own.
        "M0 0 M5 5 A 10 5 0 0 1 25 5 L 5 15 Z M 50 50",
        // Two closes are one.
        "M0 0 A 10 5 0 0 1 20 0 Z Z M 30 0 h 10 v 10 z",
        // Radii too small to reach are scaled up; a zero radius draws a line.
        "M0 0 A 1 0.5 0 0 1 30 0 Z",
        "M0 0 A 0 5 0 0 1 30 0 L 30 10 A 5 7 0 0 0 0 10 Z",
        "M 5 5 h 10 a 3 6 10 0 1 5 5 v 10 H 5 Z",
        // Inkscape's repeated arcs, one of them elliptical.
        "M 20,20 A 5,5 0 0 1 15,25 5,5 0 0 1 10,20 8,5 0 0 1 15,15 5,5 0 0 1 20,20 Z",
        // Open, and breaking off part way (usvg stops at the error).
        "M 0 0 A 30 20 -40 0 1 50 50 L 60 0 A 3 4 0 0 1",
    ];
    for d in data {
        assert!(agrees(&format!(r#"<path d="{d}"/>"#)), "{d}");
    }
}

#[test]
fn rebuilt_shapes_are_usvgs_subpath_for_subpath() {
    let shapes = [
        r#"<ellipse cx="50" cy="40" rx="20" ry="10"/>"#,
        // One radius stands for both; a negative one is not given.
        r#"<ellipse cx="50" cy="40" rx="5mm"/>"#,
        r#"<ellipse cx="50" cy="40" rx="-3" ry="7"/>"#,
        r#"<circle cx="1in" cy="2cm" r="1in"/>"#,
        r#"<circle cx="10" cy="20" r="3pt"/>"#,
        // Radii clamped to half the sides; only ry given.
        r#"<rect x="10" y="10" width="40" height="20" rx="30" ry="5"/>"#,
        r#"<rect x="10" y="10" width="40" height="20" ry="4"/>"#,
        r#"<rect x="1mm" y="2mm" width="3pc" height="20" rx="4" ry="-1"/>"#,
    ];
    for shape in shapes {
        assert!(agrees(shape), "{shape}");
    }
}

#[test]
fn other_geometry_than_usvgs_does_not_agree() {
    let svg = svg_of(r#"<ellipse cx="50" cy="40" rx="20" ry="10.01"/>"#);
    let (drawn, to_px) = usvg_subpaths(&svg);
    let other = svg_of(r#"<ellipse cx="50" cy="40" rx="20" ry="10"/>"#);
    let doc = roxmltree::Document::parse(&other).unwrap();
    let node = doc.root_element().first_element_child().unwrap();
    let path = read::geometry(node).unwrap();
    // 0.01 apart: within a join tolerance of 0.02, not of 0.001.
    assert!(path.agrees(&drawn, &to_px, 2e-2));
    assert!(!path.agrees(&drawn, &to_px, 1e-3));
    // A flag the other way.
    let svg = svg_of(r#"<path d="M0 0 A 20 10 0 0 1 30 5 Z"/>"#);
    let (drawn, to_px) = usvg_subpaths(&svg);
    let doc = roxmltree::Document::parse(r#"<path d="M0 0 A 20 10 0 1 1 30 5 Z"/>"#).unwrap();
    let path = read::geometry(doc.root_element()).unwrap();
    assert!(!path.agrees(&drawn, &to_px, 1e-4));
}

/// The exactness of `element`, alone in a document whose user unit is a millimetre.
fn exactness_of(element: &str) -> Exactness {
    let svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" viewBox="0 0 100 100">{element}</svg>"#
    );
    let (_, to_px) = usvg_subpaths(&svg);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let node = doc.root_element().first_element_child().unwrap();
    exactness(
        node,
        Affine::scale(25.4 / 96.0).then_after(&to_px),
        25.4 / 96.0,
        false,
    )
    .0
}

#[test]
fn only_elements_with_elliptical_arcs_are_rebuilt() {
    let exact = |e: &str| matches!(exactness_of(e), Exactness::Exact(_));
    let usvg = |e: &str| matches!(exactness_of(e), Exactness::Usvg);
    assert!(exact(r#"<ellipse cx="50" cy="40" rx="20" ry="10"/>"#));
    assert!(exact(
        r#"<circle cx="50" cy="40" r="20" transform="skewX(20)"/>"#
    ));
    assert!(exact(
        r#"<circle cx="50" cy="40" r="20" transform="scale(1 2)"/>"#
    ));
    assert!(exact(r#"<rect width="40" height="20" rx="4" ry="2"/>"#));
    assert!(exact(r#"<path d="M0 0 L 10 0 A 5 4 0 0 1 0 0 Z"/>"#));
    // Circles in the page stay with usvg, whose cubics are made exact arcs again.
    assert!(usvg(
        r#"<circle cx="50" cy="40" r="20" transform="rotate(30) scale(2)"/>"#
    ));
    assert!(usvg(
        r#"<ellipse cx="50" cy="40" rx="20" ry="10" transform="scale(1 2)"/>"#
    ));
    assert!(usvg(r#"<rect width="40" height="20" rx="4"/>"#));
    assert!(usvg(r#"<path d="M0 0 L 10 0 A 5 5 0 0 1 0 0 Z"/>"#));
    assert!(usvg(r#"<path d="M0 0 L 10 0 C 10 10 0 10 0 0 Z"/>"#));
    // A length relative to the viewport or the font is not read.
    assert!(matches!(
        exactness_of(r#"<ellipse cx="50" cy="40" rx="20%" ry="10"/>"#),
        Exactness::Approximated
    ));
    assert!(matches!(
        exactness_of(r#"<rect width="40" height="20" rx="1em" ry="2"/>"#),
        Exactness::Approximated
    ));
}

#[test]
fn the_map_to_the_page_is_composed_in_double_precision_where_the_source_gives_it() {
    let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" viewBox="10 -5 600 300" preserveAspectRatio="xMaxYMid meet"><g transform="translate(3.3 4.4) rotate(33)"><a><ellipse id="e" rx="20" ry="10" transform="matrix(1 0.2 0.3 1 7 8)"/></a></g></svg>"#;
    let (_, to_px) = usvg_subpaths(svg);
    let mm_per_px = 25.4 / 96.0;
    let usvg_map = Affine::scale(mm_per_px).then_after(&to_px);
    let doc = roxmltree::Document::parse(svg).unwrap();
    let node = doc
        .descendants()
        .find(|n| n.attribute("id") == Some("e"))
        .unwrap();
    let exact = frame::to_doc(node, mm_per_px).expect("a simple map");
    assert!(
        frame::agrees(&exact, &usvg_map),
        "{exact:?} vs {usvg_map:?}"
    );
    // The viewBox's 600 × 300 fitted into 300 × 200 mm: 0.5 mm a unit, the room left over
    // (50 mm) is below: y is centred.
    let origin = exact.apply(v2(0.0, 0.0));
    let expected_origin = {
        let (s, c) = 33f64.to_radians().sin_cos();
        let (x, y) = (3.3 + c * 7.0 - s * 8.0, 4.4 + s * 7.0 + c * 8.0);
        v2(0.5 * (x - 10.0), 0.5 * (y + 5.0) + 25.0)
    };
    assert!((origin - expected_origin).length() < 1e-12, "{origin:?}");
    // Through a <use>, a nested <svg> or a CSS transform it is usvg's.
    for inner in [
        r#"<svg x="5"><ellipse id="e" rx="2" ry="1"/></svg>"#,
        r#"<g style="transform: rotate(3deg)"><ellipse id="e" rx="2" ry="1"/></g>"#,
        r#"<g transform-origin="5 5" transform="rotate(3)"><ellipse id="e" rx="2" ry="1"/></g>"#,
    ] {
        let svg = format!(r#"<svg xmlns="http://www.w3.org/2000/svg">{inner}</svg>"#);
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let node = doc
            .descendants()
            .find(|n| n.attribute("id") == Some("e"))
            .unwrap();
        assert!(frame::to_doc(node, 1.0).is_none(), "{inner}");
    }
}

#[test]
fn an_element_left_to_usvgs_cubics_is_named_in_a_note() {
    let plan = |ellipse: &str| {
        format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" viewBox="0 0 100 100">{ellipse}</svg>"#
        )
    };
    let style = r#"fill="none" stroke="red" stroke-width="0.1""#;
    let kerf = KerfSource::Uniform(150.0);
    let opts = SvgOptions::default();
    let relative = plan(&format!(
        r#"<ellipse id="e" cx="50" cy="50" rx="20%" ry="10" {style}/>"#
    ));
    let (_, summary) = dilate_svg(&relative, &kerf, &opts).unwrap();
    let note = summary
        .notes
        .iter()
        .find(|n| n.contains("Bézier approximation"));
    assert!(
        note.is_some_and(|n| n.contains("ellipse \"e\"")),
        "{:?}",
        summary.notes
    );
    let absolute = plan(&format!(
        r#"<ellipse id="e" cx="50" cy="50" rx="20mm" ry="10" {style}/>"#
    ));
    let (_, summary) = dilate_svg(&absolute, &kerf, &opts).unwrap();
    assert!(summary.notes.is_empty(), "{:?}", summary.notes);
}
