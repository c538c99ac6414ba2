use super::*;

const HEADER: &str = "(S_MAX=1000 must equal GRBL setting 30)\nG17 G21 G90 G94\nM5\n";

fn layers(steps: &Steps) -> Vec<&CutLayer> {
    steps
        .steps
        .iter()
        .flat_map(|s| match s {
            Step::Cut(layers) => layers.iter().collect(),
            _ => Vec::new(),
        })
        .collect()
}

#[test]
fn the_prong_moves_are_direct_moves_in_the_order_written() {
    let lower = "G21 G90\nM5 S0\nG0 Z10.0000\nG0 X70.0000 Y55.0000\nG1 Z-2.0000 F300.0\n";
    let steps = read(lower, [5.0, 5.0]).unwrap();
    assert_eq!(
        steps.steps,
        vec![
            Step::MoveZ(10.0),
            Step::MoveXy([70.0, 55.0]),
            Step::MoveZ(-2.0)
        ]
    );
    let back = read("G21 G90\nM5 S0\nG53 G0 Z0.0000\n", [1.0, 2.0]).unwrap();
    assert_eq!(back.steps, vec![Step::MoveZ(0.0)]);
}

#[test]
fn contours_become_layers_by_their_settings_and_travels_stay_dark() {
    let program = format!(
        "{HEADER}G0 X10 Y10\nF600\nM4 S500\nG1 X20 Y10\nG1 X20 Y20\nM5\nG0 X30 Y30\nM4 S500\nG1 X40 Y30\nM5\nG0 X50 Y50\nF1200\nM4 S1000\nG1 X60 Y50\nM5\nM2\n"
    );
    let steps = read(&program, [0.0, 0.0]).unwrap();
    assert_eq!(steps.steps.len(), 1, "{steps:?}");
    let l = layers(&steps);
    assert_eq!(l.len(), 2);
    assert_eq!((l[0].speed_mm_per_s, l[0].max_power_percent), (10.0, 50.0));
    assert_eq!(l[0].min_power_percent, l[0].max_power_percent);
    assert_eq!(
        l[0].paths_mm,
        vec![
            vec![[10.0, 10.0], [20.0, 10.0], [20.0, 20.0]],
            vec![[30.0, 30.0], [40.0, 30.0]]
        ]
    );
    assert_eq!((l[1].speed_mm_per_s, l[1].max_power_percent), (20.0, 100.0));
    assert_eq!(l[1].paths_mm, vec![vec![[50.0, 50.0], [60.0, 50.0]]]);
}

#[test]
fn arcs_are_flattened_within_the_tolerance_and_end_where_written() {
    // A counter-clockwise half turn of radius 5 about (15, 10), then a clockwise quarter.
    let program =
        format!("{HEADER}G0 X20 Y10\nF600\nM4 S300\nG3 X10 Y10 I-5 J0\nG2 X15 Y5 I5 J0\nM5\n");
    let steps = read(&program, [0.0, 0.0]).unwrap();
    let path = &layers(&steps)[0].paths_mm[0];
    assert_eq!(path.first(), Some(&[20.0, 10.0]));
    assert_eq!(path.last(), Some(&[15.0, 5.0]));
    assert!(path.contains(&[10.0, 10.0]));
    for pair in path.windows(2) {
        let mid = [
            (pair[0][0] + pair[1][0]) / 2.0,
            (pair[0][1] + pair[1][1]) / 2.0,
        ];
        let r_corner = (pair[1][0] - 15.0).hypot(pair[1][1] - 10.0);
        let r_mid = (mid[0] - 15.0).hypot(mid[1] - 10.0);
        assert!((r_corner - 5.0).abs() < 1e-9);
        assert!(5.0 - r_mid <= CHORD_TOLERANCE_MM + 1e-12, "{}", 5.0 - r_mid);
    }
    // The counter-clockwise half turn goes over the top: y above 10.
    let top = path.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
    assert!((top - 15.0).abs() < 1e-3, "{top}");
}

#[test]
fn what_kerfmeter_does_not_write_is_refused_with_its_line() {
    for (line, bad) in [
        ("G91", "G91"),
        ("G20", "G20"),
        ("G0 X1 Z2", "Z move with X/Y"),
        ("M4 S100\nF100\nG1 Z-3", "laser on"),
        ("G28", "G28"),
        ("M7", "M7"),
    ] {
        let program = format!("{HEADER}{line}\n");
        let e = read(&program, [0.0, 0.0]).unwrap_err();
        assert!(e.reason.contains(bad), "{line}: {e:?}");
        assert!(e.line >= 4, "{e:?}");
    }
    let e = read("G0 X1 Y1\nF100\nM4 S10\nG1 X2 Y2\n", [0.0, 0.0]).unwrap_err();
    assert!(e.reason.contains("S max"), "{e:?}");
}
