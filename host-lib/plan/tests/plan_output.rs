//! What is written is clean: numbers short enough not to bloat the file (no more decimals than a
//! 0.01 µm step needs, in the file's own units) yet keeping the geometry within 0.1 µm, and arcs
//! written as arcs (SVG `A`, DXF bulges and `CIRCLE`s). (That the output has no crossing,
//! overlapping or duplicated loops is checked on the whole corpus, in `plan_corpus`.)

use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::dxf_plan::{DxfOptions, dilate_dxf};
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};

/// 0.1 µm, in mm.
const TOL_MM: f64 = 1e-4;

/// A third of 10 mm: a side whose decimals never end.
const SIDE_MM: f64 = 10.0 / 3.0;

/// Half the kerf used, mm.
const HALF_KERF_MM: f64 = 0.075;

fn kerf() -> KerfSource {
    KerfSource::Uniform(2000.0 * HALF_KERF_MM)
}

/// The number of decimals of a number as written.
fn decimals(s: &str) -> usize {
    s.split_once('.').map_or(0, |(_, f)| f.len())
}

/// The numbers of an SVG path's `d`.
fn path_numbers(d: &str) -> Vec<&str> {
    d.split(|c: char| c.is_ascii_alphabetic() || c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .collect()
}

/// The dilated square's path data, from an SVG with `user_mm` mm per user unit.
fn dilated_square_svg(user_mm: f64) -> String {
    let side = SIDE_MM / user_mm;
    let size = 20.0 / user_mm;
    let svg = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="20mm" height="20mm" viewBox="0 0 {size} {size}"><rect id="sq" x="{side}" y="{side}" width="{side}" height="{side}" fill="none" stroke="red" stroke-width="{w}"/></svg>"#,
        w = 0.1 / user_mm
    );
    let (out, _) = dilate_svg(&svg, &kerf(), &SvgOptions::default()).unwrap();
    let start = out.find(" d=\"").unwrap() + 4;
    let end = start + out[start..].find('"').unwrap();
    out[start..end].to_string()
}

#[test]
fn svg_numbers_keep_0_1_um_with_no_more_decimals_than_needed() {
    // mm user units: 0.01 µm is the fifth decimal; px (96 per inch): 0.0378 px steps, also five.
    for (user_mm, most_decimals) in [(1.0, 5), (25.4 / 96.0, 5)] {
        let d = dilated_square_svg(user_mm);
        assert!(d.contains('A'), "round corners are arcs: {d}");
        let numbers = path_numbers(&d);
        let longest = numbers.iter().map(|s| decimals(s)).max().unwrap();
        assert!(longest <= most_decimals, "{longest} decimals in {d}");
        // Every corner point lies on a side of the square, or K/2 outside it.
        let (lo, hi) = (SIDE_MM - HALF_KERF_MM, 2.0 * SIDE_MM + HALF_KERF_MM);
        let expected = [lo, SIDE_MM, 2.0 * SIDE_MM, hi];
        for s in numbers {
            let v: f64 = s.parse::<f64>().unwrap() * user_mm;
            let on_grid = expected.iter().any(|e| (v - e).abs() < TOL_MM)
                || (v - HALF_KERF_MM).abs() < TOL_MM
                || v.abs() < TOL_MM
                || (v / user_mm - 1.0).abs() < 1e-12;
            assert!(
                on_grid,
                "{v} mm (from {s}) is not where the dilated square is"
            );
        }
    }
}

/// The numbers (group code, value) of a DXF's `LWPOLYLINE`s.
fn lwpolyline_numbers(dxf: &str) -> Vec<(String, String)> {
    let lines: Vec<&str> = dxf.lines().map(str::trim).collect();
    let mut out = Vec::new();
    let mut inside = false;
    for pair in lines.chunks(2) {
        let [code, value] = pair else { break };
        if *code == "0" {
            inside = *value == "LWPOLYLINE";
        } else if inside && ["10", "20", "42"].contains(code) {
            out.push((code.to_string(), value.to_string()));
        }
    }
    out
}

fn square_dxf(insunits: u8, unit_mm: f64) -> String {
    let side = SIDE_MM / unit_mm;
    let mut s = format!(
        "0\nSECTION\n2\nHEADER\n9\n$ACADVER\n1\nAC1015\n9\n$INSUNITS\n70\n{insunits}\n0\nENDSEC\n0\nSECTION\n2\nENTITIES\n0\nLWPOLYLINE\n8\nCUT\n62\n1\n90\n4\n70\n1\n"
    );
    for (x, y) in [(1.0, 1.0), (2.0, 1.0), (2.0, 2.0), (1.0, 2.0)] {
        s.push_str(&format!("10\n{}\n20\n{}\n", x * side, y * side));
    }
    s.push_str("0\nENDSEC\n0\nEOF\n");
    s
}

#[test]
fn dxf_numbers_keep_0_1_um_with_no_more_decimals_than_needed() {
    // mm: five decimals make 0.01 µm; inches: seven.
    for (insunits, unit_mm, most_decimals) in [(4u8, 1.0, 5), (1, 25.4, 7)] {
        let (out, _) = dilate_dxf(
            square_dxf(insunits, unit_mm).as_bytes(),
            &kerf(),
            &DxfOptions::default(),
        )
        .unwrap();
        let numbers = lwpolyline_numbers(&String::from_utf8(out).unwrap());
        assert!(numbers.iter().any(|(c, _)| c == "42"), "corners are arcs");
        let expected = [
            SIDE_MM - HALF_KERF_MM,
            SIDE_MM,
            2.0 * SIDE_MM,
            2.0 * SIDE_MM + HALF_KERF_MM,
        ];
        for (code, s) in numbers {
            let v: f64 = s.parse().unwrap();
            if code == "42" {
                // A quarter turn: tan(π/8).
                assert!(
                    (v.abs() - (std::f64::consts::PI / 8.0).tan()).abs() < 1e-9,
                    "{s}"
                );
                continue;
            }
            assert!(decimals(&s) <= most_decimals, "{s} has too many decimals");
            let mm = v * unit_mm;
            assert!(
                expected.iter().any(|e| (mm - e).abs() < TOL_MM),
                "{mm} mm (from {s}) is not where the dilated square is"
            );
        }
    }
}
