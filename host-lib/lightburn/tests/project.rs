//! LightBurn projects (`kerfmeter_lightburn::project`): the Kerf Offset of every Line pass is set to
//! half the kerf, everything else stays byte for byte; layers are chosen by index or name; a
//! project already compensated, a non-cut layer asked for, broken or hostile XML are refused.

use std::path::{Path, PathBuf};

use kerfmeter_lightburn::project::{
    LightBurnOptions, MAX_PROJECT_BYTES, set_kerf_offset, set_kerf_offset_file,
};
use kerfmeter_plan::PlanError;
use kerfmeter_plan::compensation::{CompensatedBy, IfCompensated};
use kerfmeter_protocol::advice::Advice;

fn corpus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(name)
}

fn read(name: &str) -> String {
    std::fs::read_to_string(corpus(name)).unwrap()
}

fn layers(list: &[&str]) -> LightBurnOptions {
    LightBurnOptions {
        layers: list.iter().map(|s| s.to_string()).collect(),
        ..LightBurnOptions::default()
    }
}

/// `out` without the record comment this tool puts before the root element.
fn without_record(out: &str) -> String {
    let start = out
        .find("<!-- kerfmeter-compensation")
        .expect("the output records what was applied");
    let end = start + out[start..].find("-->\n").unwrap() + 4;
    format!("{}{}", &out[..start], &out[end..])
}

#[test]
fn every_line_pass_gets_half_the_kerf_and_nothing_else_changes() {
    let input = read("lightburn_2x_layers.lbrn2");
    let (out, summary) = set_kerf_offset(&input, 150.0, &LightBurnOptions::default()).unwrap();
    // The only differences: a <kerf> after the speed of the Line layer 0 and of the Line
    // sub-layer of the Fill layer 3, indented like their neighbours, and layer 2's 0 replaced.
    let expected = input
        .replacen(
            "<speed Value=\"12\"/>\n",
            "<speed Value=\"12\"/>\n        <kerf Value=\"0.075\"/>\n",
            1,
        )
        .replacen("<kerf Value=\"0\"/>", "<kerf Value=\"0.075\"/>", 1)
        .replacen(
            "<speed Value=\"10\"/>\n",
            "<speed Value=\"10\"/>\n            <kerf Value=\"0.075\"/>\n",
            1,
        );
    assert_ne!(expected, input);
    assert_eq!(without_record(&out), expected);
    assert_eq!(summary.kerf_offset_mm, 0.075);
    let set: Vec<(i64, usize)> = summary
        .layers
        .iter()
        .map(|l| (l.index, l.set.len()))
        .collect();
    assert_eq!(set, [(0, 1), (1, 0), (2, 1), (3, 1)]);
    assert_eq!(summary.layers[3].set[0].sub_layer, Some(1));
    assert_eq!(summary.layers[2].set[0].before_mm, Some(0.0));
    assert!(
        summary.layers[1]
            .left_alone
            .as_deref()
            .unwrap()
            .contains("not a Line layer")
    );
    assert!(summary.compensation_found.is_none());
}

#[test]
fn the_record_comment_precedes_the_root_and_says_what_was_applied() {
    let input = read("lightburn_2x_layers.lbrn2");
    let (out, _) = set_kerf_offset(&input, 150.0, &LightBurnOptions::default()).unwrap();
    let record = out.find("<!-- kerfmeter-compensation").unwrap();
    assert!(record < out.find("<LightBurnProject").unwrap());
    assert!(out.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- kerfmeter"));
    let line = &out[record..out[record..].find("-->").unwrap() + record];
    assert!(line.contains("kerf_um=150"), "{line}");
    assert!(line.contains("offset_um=75"), "{line}");
    assert!(line.contains("Line layers 0, 2, 3"), "{line}");
}

#[test]
fn a_crlf_project_stays_crlf() {
    let input = read("lightburn_2x_layers.lbrn2").replace('\n', "\r\n");
    let (out, _) = set_kerf_offset(&input, 150.0, &LightBurnOptions::default()).unwrap();
    assert!(out.contains("-->\r\n<LightBurnProject"), "{out}");
    // Every line ends in CRLF: no bare LF anywhere, record and inserted <kerf> lines included.
    assert_eq!(out.matches('\n').count(), out.matches("\r\n").count());
    assert_eq!(out.matches("<kerf Value=\"0.075\"/>").count(), 3);
}

#[test]
fn layers_are_chosen_by_index_or_name() {
    let input = read("lightburn_2x_layers.lbrn2");
    let (out, summary) = set_kerf_offset(&input, 200.0, &layers(&["Parts & holes", "3"])).unwrap();
    let set: Vec<i64> = summary
        .layers
        .iter()
        .filter(|l| !l.set.is_empty())
        .map(|l| l.index)
        .collect();
    assert_eq!(set, [0, 3]);
    assert_eq!(out.matches("<kerf Value=\"0.1\"/>").count(), 2);
    // Layer 2 (not asked for) keeps its 0.
    assert!(out.contains("<kerf Value=\"0\"/>"));
    assert_eq!(
        summary.layers[2].left_alone.as_deref(),
        Some("not asked for (--layers)")
    );
}

#[test]
fn a_value_lists_layers_by_commas_unless_it_is_a_whole_name_with_one() {
    let set_of = |input: &str, wanted: &[&str]| -> Vec<i64> {
        let (_, summary) = set_kerf_offset(input, 200.0, &layers(wanted)).unwrap();
        summary
            .layers
            .iter()
            .filter(|l| !l.set.is_empty())
            .map(|l| l.index)
            .collect()
    };
    let input = read("lightburn_2x_layers.lbrn2");
    assert_eq!(set_of(&input, &["0,3"]), [0, 3]);
    // LightBurn lets a layer's name hold a comma: asked for whole, it is that layer.
    let named = input.replace("\"Score\"", "\"Score, 3 mm\"");
    assert_eq!(set_of(&named, &["Score, 3 mm"]), [2]);
    assert_eq!(set_of(&named, &["Score, 3 mm", "0"]), [0, 2]);
    // An empty value is refused rather than setting nothing and recording it.
    assert!(set_kerf_offset(&input, 200.0, &layers(&[""])).is_err());
}

#[test]
fn a_layer_that_is_not_a_cut_layer_or_not_there_is_refused() {
    let input = read("lightburn_2x_layers.lbrn2");
    let e = set_kerf_offset(&input, 150.0, &layers(&["Engrave"])).unwrap_err();
    assert!(matches!(e, PlanError::InvalidArgument(_)), "{e}");
    assert!(
        e.to_string()
            .contains("layer 1 \"Engrave\" (Scan) is not a Line"),
        "{e}"
    );
    let e = set_kerf_offset(&input, 150.0, &layers(&["Photo", "7"])).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("\"Photo\"") && msg.contains("\"7\""), "{msg}");
}

#[test]
fn a_project_already_compensated_is_refused_replaced_or_added_to() {
    let input = read("lightburn_compensated.lbrn2");
    let e = set_kerf_offset(&input, 150.0, &LightBurnOptions::default()).unwrap_err();
    let PlanError::AlreadyCompensated { found, .. } = &e else {
        panic!("{e}");
    };
    assert_eq!(found.by, CompensatedBy::LightBurn);
    assert!(found.offset_um.0[1] >= 80.0, "{:?}", found.offset_um);
    assert!(found.found_in.contains("0.08 mm"), "{}", found.found_in);
    let msg = e.to_string();
    assert!(msg.contains("layer 0 \"C00\" (Cut): 0.08 mm"), "{msg}");
    assert_eq!(
        e.advice(),
        [Advice::Recompensate, Advice::AlreadyCompensatedOk]
    );
    let replace = LightBurnOptions {
        if_compensated: IfCompensated::Recompensate,
        ..LightBurnOptions::default()
    };
    let (out, s) = set_kerf_offset(&input, 150.0, &replace).unwrap();
    assert_eq!(out.matches("<kerf Value=\"0.075\"/>").count(), 2);
    assert_eq!(s.compensation_applied.action, "recompensate");
    let add = LightBurnOptions {
        if_compensated: IfCompensated::DilateAnyway,
        ..LightBurnOptions::default()
    };
    let (out, _) = set_kerf_offset(&input, 150.0, &add).unwrap();
    assert!(out.contains("<kerf Value=\"0.155\"/>"), "{out}");
    assert!(out.contains("<kerf Value=\"0.075\"/>"), "{out}");
    // Layers not asked for do not count.
    assert!(set_kerf_offset(&input, 150.0, &layers(&["5"])).is_ok());
}

#[test]
fn an_output_is_refused_again_and_recompensating_it_keeps_one_record() {
    let input = read("lightburn_2x_layers.lbrn2");
    let (once, _) = set_kerf_offset(&input, 150.0, &LightBurnOptions::default()).unwrap();
    let e = set_kerf_offset(&once, 150.0, &LightBurnOptions::default()).unwrap_err();
    assert!(matches!(e, PlanError::AlreadyCompensated { .. }), "{e}");
    let replace = LightBurnOptions {
        if_compensated: IfCompensated::Recompensate,
        ..LightBurnOptions::default()
    };
    let (twice, _) = set_kerf_offset(&once, 180.0, &replace).unwrap();
    assert_eq!(twice.matches("kerfmeter-compensation").count(), 1);
    assert_eq!(twice.matches("<kerf Value=\"0.09\"/>").count(), 3);
    assert_eq!(
        without_record(&twice),
        without_record(&once).replace("0.075", "0.09")
    );
}

#[test]
fn hostile_and_broken_projects_are_refused_with_a_clear_error() {
    let e = set_kerf_offset_file(
        &corpus("refused_lightburn_entities.lbrn2"),
        150.0,
        &LightBurnOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("document type declaration"), "{e}");
    let cases = [
        (
            "<LightBurnProject><CutSetting type=\"Cut\">",
            "not well-formed XML",
        ),
        ("<svg/>", "the root element is <svg>"),
        ("<LightBurnProject/>", "no Line (cut) layer"),
        (
            "<LightBurnProject><CutSetting type=\"Cut\"><name Value=\"x\"/></CutSetting></LightBurnProject>",
            "has no <index",
        ),
        (
            "<LightBurnProject><CutSetting type=\"Cut\"><index Value=\"0\"/><kerf Value=\"wide\"/></CutSetting></LightBurnProject>",
            "\"wide\" is not a number",
        ),
        (
            "<LightBurnProject><CutSetting type=\"Cut\"><index Value=\"0\"/><kerf Value=\"0\"/><kerf Value=\"0\"/></CutSetting></LightBurnProject>",
            "two <kerf>",
        ),
    ];
    for (text, needle) in cases {
        let e = set_kerf_offset(text, 150.0, &LightBurnOptions::default()).unwrap_err();
        assert!(e.to_string().contains(needle), "{text}: {e}");
    }
    assert!(set_kerf_offset("<LightBurnProject/>", -1.0, &LightBurnOptions::default()).is_err());
}

#[test]
fn files_too_large_or_not_utf8_are_refused_before_parsing() {
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.lbrn2");
    // A sparse file: its length is checked before anything is read.
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(MAX_PROJECT_BYTES + 1)
        .unwrap();
    let e = set_kerf_offset_file(&huge, 150.0, &LightBurnOptions::default()).unwrap_err();
    assert!(e.to_string().contains("more than the"), "{e}");
    assert_eq!(e.path(), Some(huge.as_path()));
    let latin1 = dir.path().join("latin1.lbrn2");
    std::fs::write(&latin1, b"<LightBurnProject Name=\"\xe9\"/>").unwrap();
    let e = set_kerf_offset_file(&latin1, 150.0, &LightBurnOptions::default()).unwrap_err();
    assert!(e.to_string().contains("not UTF-8"), "{e}");
}

#[test]
fn every_truncation_of_a_project_is_set_or_refused_never_a_panic() {
    let input = read("lightburn_2x_layers.lbrn2");
    for end in (0..input.len()).filter(|&i| input.is_char_boundary(i)) {
        let _ = set_kerf_offset(&input[..end], 150.0, &LightBurnOptions::default());
    }
}
