//! Tests of the `compensation` module.

use super::finding::*;
use super::*;

#[test]
fn burn_is_read_in_every_form_boxes_writes() {
    assert_eq!(
        burn_in_command_line("Command line: boxes ABox --burn 0.1 --x=3"),
        Some(0.1)
    );
    assert_eq!(
        burn_in_command_line("Command line: boxes ABox --x=3 --burn=0.05"),
        Some(0.05)
    );
    assert_eq!(
        burn_in_command_line("Command line (remove spaces between dashes): boxes ABox - -burn=0.2"),
        Some(0.2)
    );
    // cli_short loses a separate value: not a burn.
    assert_eq!(burn_in_command_line("boxes ABox --burn --x=3"), None);
    assert_eq!(burn_in_command_line("boxes ABox --burnish=3"), None);
    assert_eq!(
        burn_in_url("Url: https://boxes.hackerspace-bamberg.de/ABox?x=100&burn=0.15&render=1"),
        Some(0.15)
    );
    assert_eq!(burn_in_url("noburn=3"), None);
    assert_eq!(burn_in_label("100.0mm, burn:0.10mm"), Some(0.1));
}

#[test]
fn a_compensation_that_varies_over_the_bed_cannot_be_undone_but_can_be_dilated_on() {
    let found = FoundCompensation {
        by: CompensatedBy::Kerfmeter,
        offset_um: RangeUm([60.0, 80.0]),
        kerf_um: Some(RangeUm([120.0, 160.0])),
        rules: None,
        version: Some("0.1.0".into()),
        found_in: "here".into(),
        default_burn: false,
    };
    let kerf = KerfSource::Uniform(150.0);
    let e = treatment(Some(&found), IfCompensated::Recompensate, &kerf)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("kerf 120..160 µm") && e.contains("kerf map"),
        "{e}"
    );
    let t = treatment(Some(&found), IfCompensated::DilateAnyway, &kerf).unwrap();
    let a = applied(&t, Some([150.0, 150.0]), &kerf, String::new(), 0);
    assert_eq!(a.offset_um, RangeUm([135.0, 155.0]));
    // Nothing found: dilated as usual whatever the policy.
    let t = treatment(None, IfCompensated::Refuse, &kerf).unwrap();
    assert_eq!(
        (t.offsetting, t.corner_loop_max_mm),
        (Offsetting::Dilate, None)
    );
}

#[test]
fn records_round_trip_through_their_text() {
    let a = AppliedCompensation {
        action: "dilate".into(),
        kerf_um: RangeUm::one(150.0),
        net_offset_um: RangeUm::one(75.0),
        offset_um: RangeUm::one(75.0),
        rules: "unfilled lines in red \"x\" -- y".into(),
        corner_loops_removed: 0,
        tool: TOOL.into(),
        version: "1.2.3".into(),
    };
    let fields = record_fields(&a.record_line()).unwrap();
    let f = own_record(&fields, "here").unwrap();
    assert_eq!(f.offset_um, RangeUm::one(75.0));
    assert_eq!(f.kerf_um, Some(RangeUm::one(150.0)));
    assert_eq!(f.version.as_deref(), Some("1.2.3"));
    let svg = a.svg_record();
    let comment = &svg[svg.find("<!--").unwrap() + 4..svg.find("-->").unwrap()];
    assert!(
        !comment.contains("--") && comment.contains("kerf_um=150"),
        "{svg}"
    );
    assert_eq!(RangeUm::parse("120..160"), Some(RangeUm([120.0, 160.0])));
}

/// A job checks the plan before it cuts the gauge: refused for the reasons a dilation by the
/// kerf it measures would refuse it then, unless the user said what to do.
#[test]
fn a_job_refuses_a_compensated_plan_before_measuring_as_its_dilation_would() {
    let found = |by, offset_um: f64| FoundCompensation {
        by,
        offset_um: RangeUm([offset_um, offset_um]),
        kerf_um: None,
        rules: None,
        version: None,
        found_in: "here".into(),
        default_burn: false,
    };
    let (boxes, gauge) = (
        found(CompensatedBy::BoxesPy, 100.0),
        found(CompensatedBy::KerfmeterGauge, 0.0),
    );
    let message = |f: &FoundCompensation, policy| match check_before_measuring(Some(f), policy) {
        Err(PlanError::AlreadyCompensated { message, .. }) => Some(message),
        Err(other) => panic!("{other}"),
        Ok(()) => None,
    };
    let refused = message(&boxes, IfCompensated::Refuse).expect("refused");
    assert!(
        refused.says("The job would dilate it by the kerf it measures")
            && refused.says("nothing was cut")
            && !refused.says(" = "),
        "{refused}"
    );
    let ways_on: Vec<Advice> = refused.advice().collect();
    assert_eq!(
        ways_on,
        [Advice::Recompensate, Advice::AlreadyCompensatedOk]
    );
    assert_eq!(message(&boxes, IfCompensated::Recompensate), None);
    assert_eq!(message(&boxes, IfCompensated::DilateAnyway), None);
    for policy in [IfCompensated::Refuse, IfCompensated::Recompensate] {
        let refused = message(&gauge, policy).expect("a gauge is refused");
        assert!(refused.says("a gauge is cut as drawn"), "{refused}");
        assert_eq!(
            refused.says("does not apply: the spiral carries no compensation"),
            policy == IfCompensated::Recompensate
        );
        assert_eq!(
            refused.advice().any(|a| a == Advice::Recompensate),
            policy == IfCompensated::Recompensate
        );
    }
    assert_eq!(message(&gauge, IfCompensated::DilateAnyway), None);
    assert!(check_before_measuring(None, IfCompensated::Refuse).is_ok());
    // A plan recorded as dilated by nothing carries nothing to undo.
    assert_eq!(
        message(&found(CompensatedBy::Kerfmeter, 0.0), IfCompensated::Refuse),
        None
    );
}
