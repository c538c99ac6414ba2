//! Every SVG either dilates or is refused: no cut is lost to usvg's single precision. A number
//! near the 32-bit float limit (a shape's `x` or `cx`, a `transform`'s offset or scale) made usvg
//! drop the element whole, and the plan dilated without it (12 contours of 16, no note, the
//! element copied undilated and left out of the G-code). Such numbers are refused, naming the
//! element; so are elements whose numbers are each allowed but combine past the limit, found by
//! what usvg draws.

use std::path::Path;

use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::file::{DilateOptions, dilate_file_cuts};
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};

/// Four parts, each a square with a round hole (8 closed cuts), and `extra` after them.
fn plan(extra: &str) -> String {
    let mut s = String::from(
        r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="200mm" height="200mm" viewBox="0 0 200 200"><g stroke="red" stroke-width="0.1" fill="none">"#,
    );
    for k in 0..4 {
        let x = 10 + 40 * k;
        s.push_str(&format!(
            r#"<rect x="{x}" y="10" width="30" height="30"/><circle cx="{}" cy="25" r="5"/>"#,
            x + 15
        ));
    }
    s.push_str(extra);
    s.push_str("</g></svg>");
    s
}

fn kerf() -> KerfSource {
    KerfSource::Uniform(150.0)
}

/// Why dilating `text` is refused (a panic with what was dilated when it is not).
fn refusal(text: &str) -> String {
    match dilate_svg(text, &kerf(), &SvgOptions::default()) {
        Ok((_, summary)) => panic!(
            "dilated {} contours: {:?}",
            summary.contours_dilated, summary.notes
        ),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_plan_without_far_numbers_dilates_all_its_contours() {
    let (_, summary) = dilate_svg(&plan(""), &kerf(), &SvgOptions::default()).unwrap();
    assert_eq!(summary.contours_dilated, 8);
    let extra = r#"<rect id="near" x="10" y="50" width="30" height="30"/>"#;
    let (_, summary) = dilate_svg(&plan(extra), &kerf(), &SvgOptions::default()).unwrap();
    assert_eq!(summary.contours_dilated, 9);
}

#[test]
fn a_rect_at_1e38_is_refused_by_name() {
    let why = refusal(&plan(
        r#"<rect id="far" x="1e38" y="50" width="30" height="30"/>"#,
    ));
    assert!(
        why.contains(r#"rect "far" has the number 1e38 in its x attribute"#),
        "{why}"
    );
    assert!(why.contains("single-precision"), "{why}");
}

#[test]
fn a_circle_at_1e38_is_refused_by_name() {
    let why = refusal(&plan(r#"<circle id="far" cx="1e38" cy="50" r="5"/>"#));
    assert!(
        why.contains(r#"circle "far" has the number 1e38 in its cx attribute"#),
        "{why}"
    );
}

#[test]
fn a_cut_translated_by_1e38_is_refused_by_name() {
    let why = refusal(&plan(
        r#"<rect id="far" transform="translate(1e38 0)" x="10" y="50" width="30" height="30"/>"#,
    ));
    assert!(
        why.contains(r#"rect "far" has the number 1e38 in its transform"#),
        "{why}"
    );
}

#[test]
fn a_cut_scaled_by_1e36_is_refused_by_name() {
    let why = refusal(&plan(
        r#"<rect id="far" transform="scale(1e36)" x="10" y="50" width="30" height="30"/>"#,
    ));
    assert!(
        why.contains(r#"rect "far" has the number 1e36 in its transform"#),
        "{why}"
    );
    // On the group around it, the group is named: the number is there.
    let why = refusal(&plan(
        r#"<g id="huge" transform="scale(1e36)"><rect x="10" y="50" width="30" height="30"/></g>"#,
    ));
    assert!(
        why.contains(r#"g "huge" has the number 1e36 in its transform"#),
        "{why}"
    );
}

#[test]
fn an_element_without_an_id_is_named_by_its_line_and_column() {
    let why = refusal(&plan(r#"<rect x="1e38" y="50" width="30" height="30"/>"#));
    assert!(why.contains("<rect> at line 1, column "), "{why}");
}

#[test]
fn a_clone_offset_by_1e38_is_refused_by_name() {
    let extra = r##"<rect id="part" x="10" y="50" width="30" height="30"/><use id="copy" xlink:href="#part" x="1e38"/>"##;
    let why = refusal(&plan(extra));
    assert!(
        why.contains(r#"use "copy" has the number 1e38 in its x attribute"#),
        "{why}"
    );
}

/// Each number within the rule, the two together beyond single precision: usvg drops the
/// element; drawn again smaller, it is found, and refused by name.
#[test]
fn numbers_that_combine_past_the_limit_are_found_in_what_usvg_draws() {
    let far_in_scaled = r#"<g transform="scale(1e10)"><rect id="lost" x="1e29" y="0" width="1e28" height="1e28"/></g>"#;
    let why = refusal(&plan(far_in_scaled));
    assert!(why.contains(r#"rect "lost" cannot be drawn"#), "{why}");
    let two_scales = r#"<g transform="scale(1e20)"><g transform="scale(1e20)"><circle id="lost" cx="1" cy="1" r="0.5"/></g></g>"#;
    let why = refusal(&plan(two_scales));
    assert!(why.contains(r#"circle "lost" cannot be drawn"#), "{why}");
    // Through a clone: the <use> is named with it.
    let cloned = r##"<rect id="part" x="1e29" y="0" width="1e28" height="1e28"/><g transform="scale(1e10)"><use id="copy" xlink:href="#part"/></g>"##;
    let why = refusal(&plan(cloned));
    assert!(
        why.contains(r#"rect "part" via <use> use "copy" cannot be drawn"#),
        "{why}"
    );
}

/// Past even the smaller drawing, what cannot be drawn cannot be named: the drawing is refused
/// as a whole, naming the group where the transforms overflow.
#[test]
fn transforms_that_overflow_even_drawn_smaller_are_refused_as_a_whole() {
    let three = r#"<g id="a" transform="scale(1e20)"><g id="b" transform="scale(1e20)"><g id="c" transform="scale(1e20)"><rect x="1" y="1" width="1" height="1"/></g></g></g>"#;
    let why = refusal(&plan(three));
    assert!(
        why.contains("the transforms around the element \"c\""),
        "{why}"
    );
}

/// A large scale is not itself refused: what it holds is drawn, and dilates (its stroke scaled
/// as much: 1e-10 wide, 0.1 mm on the page).
#[test]
fn a_large_scale_that_usvg_draws_dilates() {
    let tiny = r#"<g transform="scale(1e9)" stroke-width="1e-10"><rect id="tiny" x="1e-8" y="5e-8" width="2e-8" height="2e-8"/></g>"#;
    let (_, summary) = dilate_svg(&plan(tiny), &kerf(), &SvgOptions::default()).unwrap();
    assert_eq!(summary.contours_dilated, 9);
}

/// The G-code path reads the same way: refused, not cut without the part.
#[test]
fn the_cuts_for_g_code_are_refused_too() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("far.svg");
    let extra = r#"<circle id="far" cx="1e38" cy="50" r="5"/>"#;
    std::fs::write(&path, plan(extra)).unwrap();
    let e = dilate_file_cuts(Path::new(&path), &kerf(), &DilateOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains(r#"circle "far" has the number 1e38"#), "{e}");
}
