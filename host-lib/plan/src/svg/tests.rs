//! SVG plans read, dilated and written back, end to end; and the pieces whose output is
//! hard to see from there (numbers written, the source made again from its tagged copy).

use super::edits::Edit;
use super::path_writer::num;
use super::reading::usvg_options;
use super::tagging::Tagged;
use super::*;

const HEAD: &str = r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="100mm" height="100mm" viewBox="0 0 100 100">"#;

fn run(body: &str, kerf_um: f64) -> Result<(String, PlanSummary)> {
    dilate_svg(
        &format!("{HEAD}{body}</svg>"),
        &KerfSource::Uniform(kerf_um),
        &SvgOptions::default(),
    )
}

#[test]
fn under_a_prefixed_root_unprefixed_cuts_are_read_as_usvg_draws_them() {
    // Unprefixed elements under `<s:svg xmlns:s=…>` have no namespace; usvg draws them as
    // SVG, so they are cuts like the prefixed ones (not left untagged, and so taken for
    // another element).
    let doc = format!(
        r#"<s:svg xmlns:s="{SVG_NS}" width="100mm" height="100mm" viewBox="0 0 100 100"><s:rect x="1" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><s:rect x="11" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><s:rect x="21" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><s:rect x="31" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/><rect id="plain" x="41" y="1" width="5" height="5" fill="none" stroke="red" stroke-width="0.1"/></s:svg>"#
    );
    let (out, summary) =
        dilate_svg(&doc, &KerfSource::Uniform(200.0), &SvgOptions::default()).expect("dilated");
    assert_eq!(summary.contours_dilated, 5, "{summary:?}");
    assert!(
        out.contains(r#"<path id="plain" fill="none" stroke="red" stroke-width="0.1" d="M41 0.9 "#),
        "{out}"
    );
    assert_eq!(out.matches("<s:path").count(), 4, "{out}");
}

#[test]
fn a_rect_becomes_a_dilated_path_with_its_attributes() {
    let (out, s) = run(
        r#"<rect id="r" class="c" x="10" y="10" width="20" height="10" fill="none" stroke="red" stroke-width="0.01"/>"#,
        200.0,
    )
    .unwrap();
    assert_eq!(s.contours_dilated, 1);
    assert!(
        out.contains(r#"<path id="r" class="c" fill="none" stroke="red" stroke-width="0.01" d="M"#),
        "{out}"
    );
    assert!(!out.contains("width=\"20\""));
    // Corners are quarter arcs of radius 0.1 mm.
    assert!(out.contains("A0.1 0.1 0 0 "), "{out}");
}

#[test]
fn non_cuts_and_the_rest_of_the_file_are_untouched() {
    let body = r##"<!-- comment --><text x="1" y="5" fill="black">Label</text><path id="g" d="M 0 0 L 5 5" stroke="#00ff00" fill="none"/>"##;
    let cut = r#"<rect id="c" x="10" y="10" width="5" height="5" stroke="red" stroke-width="0.1" fill="none"/>"#;
    let src = format!("{HEAD}{body}{cut}</svg>");
    let (out, s) = dilate_svg(&src, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap();
    // All but the record of what was applied, right after the root's start tag, and the cut.
    let record = s.compensation_applied.as_ref().unwrap().svg_record();
    assert!(out.starts_with(&format!("{HEAD}{record}{body}")), "{out}");
    assert!(out.ends_with("</svg>") && !out.contains(cut), "{out}");
    assert_eq!(s.contours_dilated, 1);
    assert_eq!(s.passed_through.get("text"), Some(&1));
}

#[test]
fn path_data_that_breaks_off_is_refused_in_a_cut_and_noted_elsewhere() {
    const CUT: &str = r#"<rect id="c" x="10" y="10" width="5" height="5" stroke="red" stroke-width="0.1" fill="none"/>"#;
    // A cut: usvg would read the first square only; its dilation would lose the second.
    let broken = r#"<path id="b" d="M40 40 H60 V60 H40 Z M70 70 L NaN 80 H90 Z" stroke="red" stroke-width="0.1" fill="none"/>"#;
    let e = run(&format!("{CUT}{broken}"), 150.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the cut path \"b\" has an error in its path data"),
        "{e}"
    );
    // An engraving (green): passed through as it is, with a note.
    let green = broken.replace("red", "#00ff00");
    let (out, s) = run(&format!("{CUT}{green}"), 150.0).unwrap();
    assert!(out.contains(&green), "{out}");
    assert!(
        s.notes
            .iter()
            .any(|n| n.contains("1 path(s) not read as cuts") && n.contains("path \"b\"")),
        "{:?}",
        s.notes
    );
}

#[test]
fn a_cut_polygon_whose_points_break_off_is_refused() {
    let polygon = r#"<polygon id="p" points="10,10 30,10 30,30 10" stroke="red" stroke-width="0.1" fill="none"/>"#;
    let e = run(polygon, 150.0).unwrap_err().to_string();
    assert!(
        e.contains("the cut polygon \"p\" has an error in its points"),
        "{e}"
    );
}

#[test]
fn a_coordinate_single_precision_cannot_hold_is_refused_by_name() {
    // usvg drops such a path whole: the plan would have said "nothing drawn".
    let far = r#"<path d="M10 10 H30 V30 H10 Z M70 70 L80 70 L1e39 80 Z" stroke="red" stroke-width="0.1" fill="none"/>"#;
    let e = run(far, 150.0).unwrap_err().to_string();
    assert!(e.contains("<path> at line 1, column"), "{e}");
    assert!(e.contains("the number 1e39 in its path data"), "{e}");
}

#[test]
fn a_plan_without_a_closed_cut_is_refused_and_says_what_was_found() {
    // Only non-cuts (a label, a green line, a red square drawn 1 mm wide: wider than the
    // rules' 0.3 mm) and an open red line: nothing to dilate, and no output that records
    // a compensation it did not apply.
    let body = r##"<text x="1" y="5" fill="black">Label</text><path d="M 0 0 L 5 5" stroke="#00ff00" fill="none"/><rect x="10" y="10" width="5" height="5" stroke="red" stroke-width="1" fill="none"/><path id="open" d="M 20 20 L 30 30" stroke="red" stroke-width="0.1" fill="none"/>"##;
    let src = format!("{HEAD}{body}</svg>");
    let e = dilate_svg(&src, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap_err();
    assert!(matches!(e, PlanError::NoCuts(_)), "{e:?}");
    let e = e.to_string();
    for said in [
        "no closed cut contour",
        "1 text",
        "1 open cut path",
        "up to 0.3 mm wide",
        "--cut-max-width-mm",
    ] {
        assert!(e.contains(said), "{said:?} in {e}");
    }
}

#[test]
fn the_report_gives_the_root_user_unit() {
    let rect = r##"<rect x="10" y="10" width="20" height="20" fill="none" stroke="#FF0000" stroke-width="0.1"/>"##;
    for (root, unit_mm) in [
        (r#"width="100mm" height="60mm" viewBox="0 0 100 60""#, 1.0),
        (r#"width="100mm" height="60mm" viewBox="0 0 1000 600""#, 0.1),
        (r#"width="10cm" height="6cm" viewBox="0 0 100 60""#, 1.0),
        (r#"width="100mm" height="60mm""#, 25.4 / 96.0),
    ] {
        let svg = format!(r#"<svg xmlns="http://www.w3.org/2000/svg" {root}>{rect}</svg>"#);
        let (_, s) = dilate_svg(&svg, &KerfSource::Uniform(150.0), &SvgOptions::default()).unwrap();
        assert!(
            (s.mm_per_unit - unit_mm).abs() < 1e-9,
            "{root}: {}",
            s.mm_per_unit
        );
    }
}

#[test]
fn unitless_documents_need_assumed_units() {
    let src = r#"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100"><rect x="1" y="1" width="5" height="5" stroke="red" stroke-width="0.1" fill="none"/></svg>"#;
    let e = dilate_svg(src, &KerfSource::Uniform(100.0), &SvgOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown units"), "{e}");
    let opts = SvgOptions {
        assume_units: Some(AssumedUnits::Mm),
        ..SvgOptions::default()
    };
    assert!(dilate_svg(src, &KerfSource::Uniform(100.0), &opts).is_ok());
}

#[test]
fn one_path_with_an_outline_and_a_hole_dilates_both_ways() {
    let (out, s) = run(
        r##"<path id="p" d="M 10 10 H 40 V 40 H 10 Z M 20 20 H 30 V 30 H 20 Z" fill="none" stroke="#000" stroke-width="0.1"/>"##,
        200.0,
    )
    .unwrap();
    assert_eq!((s.contours_dilated, s.parts, s.holes), (2, 1, 1));
    // The hole shrinks to 9.8 × 9.8 with sharp corners.
    assert!(
        out.contains("M20.1 20.1 L29.9 20.1 L29.9 29.9 L20.1 29.9 Z"),
        "{out}"
    );
}

#[test]
fn polygons_and_clones_of_groups_are_dilated() {
    let (out, s) = run(
        r##"<defs><g id="t"><polygon id="tri" points="0,0 10,0 5,8" fill="none" stroke="red" stroke-width="0.05"/></g></defs>
<use id="u" href="#t" x="20" y="20"/>"##,
        100.0,
    )
    .unwrap();
    assert_eq!(s.contours_dilated, 1);
    assert!(
        out.contains(r#"<g id="t-kerf1"><path id="tri-kerf1" fill="none""#),
        "{out}"
    );
    assert!(out.contains(r##"href="#t-kerf1""##), "{out}");
    // The original template is untouched.
    assert!(out.contains(r#"<polygon id="tri" points="0,0 10,0 5,8""#));
}

#[test]
fn a_cloned_id_with_reserved_characters_is_written_back_escaped() {
    let (out, s) = run(
        r##"<defs><g id="t&amp;&quot;1"><polygon id="a&lt;b" points="0,0 10,0 5,8" fill="none" stroke="red" stroke-width="0.05"/></g></defs>
<use id="u" href="#t&amp;&quot;1" x="20" y="20"/>"##,
        100.0,
    )
    .unwrap();
    assert_eq!(s.contours_dilated, 1);
    assert!(out.contains(r#"<g id="t&amp;&quot;1-kerf1">"#), "{out}");
    assert!(out.contains(r#"<path id="a&lt;b-kerf1""#), "{out}");
    assert!(out.contains(r##"href="#t&amp;&quot;1-kerf1""##), "{out}");
    // The output is XML that reads back with the clone's ids.
    let doc = roxmltree::Document::parse(&out).expect("well-formed");
    assert!(
        doc.descendants()
            .any(|n| n.attribute("id") == Some("a<b-kerf1"))
    );
}

#[test]
fn cuts_reached_through_nested_clones_are_refused() {
    let e = run(
        r##"<defs><rect id="r" width="5" height="5" fill="none" stroke="red" stroke-width="0.05"/><g id="g"><use href="#r"/></g></defs>
<use id="outer" href="#g" x="10" y="10"/>"##,
        100.0,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("nested <use>"), "{e}");
}

#[test]
fn numbers_are_written_as_exact_float_formatting_would() {
    // Float formatting with the trailing zeros dropped, `-0` as `0`.
    let exact = crate::decimal::trimmed;
    let values = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        20.1,
        29.9,
        0.1,
        -0.000_004,
        1_234.567_891_23,
        -987.654_321,
        1e-5,
        3.000_01,
        12.5,
        100.0,
        2_550.075_000_1,
        // Too large for the fast path.
        1e16,
        -2.5e17,
    ];
    for v in values {
        for digits in [0, 1, 3, 5, 6] {
            let mut out = String::new();
            num(v, digits, &mut out);
            assert_eq!(out, exact(v, digits), "{v} with {digits} digits");
        }
    }
}

#[test]
fn the_source_is_made_again_from_its_tagged_copy() {
    let src = "<svg>\n  <path d=\"M0 0\"/><use href=\"#a\"/>é<rect/></svg>";
    let at = |needle: &str| src.find(needle).unwrap();
    let insert = |at: usize, text: &str| Edit {
        range: at..at,
        text: text.into(),
    };
    // Given out of order, two at one place.
    let edits = vec![
        insert(at("<rect") + 5, " style=\"b\""),
        insert(at("<path") + 5, " style=\"a\""),
        insert(at("<use") + 4, " id=\"u\""),
        insert(at("<use") + 4, " x=\"1\""),
    ];
    let tagged = Tagged::new(src, edits).unwrap();
    assert_eq!(
        tagged.text,
        "<svg>\n  <path style=\"a\" d=\"M0 0\"/><use id=\"u\" x=\"1\" href=\"#a\"/>é<rect style=\"b\"/></svg>"
    );
    assert_eq!(tagged.untagged(), src);
}

/// No image is loaded: an `href` may name any file or device (`/dev/zero`, a FIFO).
#[test]
fn images_are_passed_through_and_never_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("a.png");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n not really a picture").unwrap();
    let href = png.to_str().unwrap();
    let options = usvg_options();
    assert!((options.image_href_resolver.resolve_string)(href, &options).is_none());
    let defaults = usvg::Options::default();
    assert!(
        (defaults.image_href_resolver.resolve_string)(href, &defaults).is_some(),
        "usvg's own resolver reads the file"
    );
    let body = format!(
        r#"<image href="{href}" width="10" height="10"/>
<rect x="0" y="0" width="10" height="10" fill="none" stroke="red" stroke-width="0.1"/>"#
    );
    let (_, summary) = run(&body, 150.0).unwrap();
    assert_eq!(summary.passed_through.get("image"), Some(&1));
    assert_eq!(summary.contours_dilated, 1);
}

/// 250 KB that roxmltree would have grown to 5 GB (one large entity used many times).
#[test]
fn entities_that_would_grow_the_file_many_times_over_are_refused_unparsed() {
    let svg = format!(
        "<!DOCTYPE svg [<!ENTITY big \"{}\">]><svg xmlns=\"{SVG_NS}\"><desc>{}</desc></svg>",
        "x".repeat(100_000),
        "&big;".repeat(50_000)
    );
    let error = dilate_svg(&svg, &KerfSource::Uniform(150.0), &SvgOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("entities of its document type declaration would add 5000 MB"),
        "{error}"
    );
}

#[test]
fn a_view_box_that_draws_nothing_or_maps_absurdly_is_refused() {
    for view_box in [
        "0 0 0 0",
        "0 0 1e-300 1e-300",
        "0 0 1e300 1e300",
        "0 0 -5 5",
        "a b c d",
    ] {
        let svg = format!(
            r#"<svg xmlns="{SVG_NS}" width="100mm" height="100mm" viewBox="{view_box}"><rect width="10" height="10" fill="none" stroke="red" stroke-width="0.1"/></svg>"#
        );
        let error = dilate_svg(&svg, &KerfSource::Uniform(150.0), &SvgOptions::default())
            .unwrap_err()
            .to_string();
        assert!(error.contains("not a usable box"), "{view_box}: {error}");
    }
}

#[test]
fn broken_xml_is_a_clear_error() {
    let e = dilate_svg(
        "<svg><path",
        &KerfSource::Uniform(100.0),
        &SvgOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("not a readable SVG"), "{e}");
}
