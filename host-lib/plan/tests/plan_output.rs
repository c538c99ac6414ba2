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

/// The pieces of a small R2000 DXF (LF line ends, numbers padded as some CAD programs write
/// them, a comment, handles up to 0x27 and `$HANDSEED` 0x30): everything but the `$HANDSEED`
/// value and the cut entities is to come out byte for byte.
mod spliced {
    pub const HEAD: &str = "999\nmade by a CAD program\n  0\nSECTION\n  2\nHEADER\n  9\n$ACADVER\n  1\nAC1015\n  9\n$INSUNITS\n 70\n4\n  9\n$HANDSEED\n  5\n";
    pub const SEED: &str = "30";
    pub const MIDDLE: &str = "\n  0\nENDSEC\n  0\nSECTION\n  2\nTABLES\n  0\nTABLE\n  2\nLAYER\n  5\n2\n 70\n1\n  0\nLAYER\n  5\n10\n330\n2\n100\nAcDbSymbolTableRecord\n100\nAcDbLayerTableRecord\n  2\nCUT\n 70\n0\n 62\n1\n  6\nCONTINUOUS\n  0\nENDTAB\n  0\nENDSEC\n  0\nSECTION\n  2\nENTITIES\n  0\nTEXT\n  5\n20\n330\n1F\n100\nAcDbEntity\n  8\nNOTES\n 62\n3\n100\nAcDbText\n 10\n1.50000000\n 20\n2.00000000\n 30\n0.0\n 40\n2.5\n  1\nlabel\n";
    /// A red square 0…10 (handle 21), with extended data.
    pub const SQUARE: &str = "  0\nLWPOLYLINE\n  5\n21\n330\n1F\n100\nAcDbEntity\n  8\nCUT\n 62\n1\n100\nAcDbPolyline\n 90\n4\n 70\n1\n 43\n0.0\n 10\n0.00000000\n 20\n0.00000000\n 10\n10.00000000\n 20\n0.00000000\n 10\n10.00000000\n 20\n10.00000000\n 10\n0.00000000\n 20\n10.00000000\n1001\nAPP\n1000\nkept\n";
    /// A red circle about (30, 5), radius 2 (handle 22).
    pub const CIRCLE: &str = "  0\nCIRCLE\n  5\n22\n330\n1F\n100\nAcDbEntity\n  8\nCUT\n 62\n1\n100\nAcDbCircle\n 10\n30.00000000\n 20\n5.00000000\n 30\n0.0\n 40\n2.00000000\n";
    /// A green line: not a cut (handle 23).
    pub const GREEN: &str = "  0\nLINE\n  5\n23\n330\n1F\n100\nAcDbEntity\n  8\nNOTES\n 62\n3\n100\nAcDbLine\n 10\n0.50000000\n 20\n20.0\n 30\n0.0\n 11\n9.5\n 21\n20.0\n 31\n0.0\n";
    pub const TAIL: &str = "  0\nENDSEC\n  0\nSECTION\n  2\nOBJECTS\n  0\nDICTIONARY\n  5\nC\n330\n0\n100\nAcDbDictionary\n  0\nENDSEC\n  0\nEOF\n";

    /// A red line (a side of the square 50…60 drawn as four lines, handles 24…27).
    pub fn red_line(handle: u32, a: (f64, f64), b: (f64, f64)) -> String {
        format!(
            "  0\nLINE\n  5\n{handle:X}\n330\n1F\n100\nAcDbEntity\n  8\nCUT\n 62\n1\n100\nAcDbLine\n 10\n{:.8}\n 20\n{:.8}\n 30\n0.0\n 11\n{:.8}\n 21\n{:.8}\n 31\n0.0\n",
            a.0, a.1, b.0, b.1
        )
    }

    pub fn file() -> String {
        let corners = [(50.0, 50.0), (60.0, 50.0), (60.0, 60.0), (50.0, 60.0)];
        let lines: String = (0..4)
            .map(|k| red_line(0x24 + k as u32, corners[k], corners[(k + 1) % 4]))
            .collect();
        format!("{HEAD}{SEED}{MIDDLE}{SQUARE}{CIRCLE}{GREEN}{lines}{TAIL}")
    }
}

#[test]
fn a_dxf_is_written_as_read_but_for_its_cuts() {
    use dxf::entities::EntityType;
    use spliced::*;
    let (out, summary) = dilate_dxf(file().as_bytes(), &kerf(), &DxfOptions::default()).unwrap();
    assert_eq!(summary.contours_dilated, 3);
    let out = String::from_utf8(out).unwrap();
    // The record first, in the file's own line ends, then every untouched byte, in order.
    assert!(out.starts_with("999\nkerfmeter-compensation"), "{out}");
    assert!(!out.contains('\r'));
    let mut at = 0;
    for piece in [HEAD, MIDDLE, GREEN, TAIL] {
        let found = out[at..]
            .find(piece)
            .unwrap_or_else(|| panic!("{piece} not in {out}"));
        at += found + piece.len();
    }
    assert!(out.ends_with(TAIL));
    // The cuts: the square's vertices in place (its extended data kept), the circle's radius,
    // and the four red lines replaced by one new LWPOLYLINE on their layer and colour, whose
    // handle follows the seed, which moves past it.
    assert!(!out.contains("\n  5\n24\n"), "the red lines are gone");
    assert!(out.contains("1001\nAPP\n1000\nkept\n"));
    let drawing = dxf::Drawing::load(&mut std::io::Cursor::new(out.as_bytes())).unwrap();
    let mut handles = Vec::new();
    for e in drawing.entities() {
        handles.push(e.common.handle.0);
        match &e.specific {
            EntityType::LwPolyline(p) => {
                assert_eq!(p.vertices.len(), 8, "{p:?}");
                assert!(p.is_closed());
                assert_eq!(
                    (e.common.layer.as_str(), e.common.color.index()),
                    ("CUT", Some(1))
                );
            }
            EntityType::Circle(c) => {
                assert!(
                    (c.radius - 2.0 - HALF_KERF_MM).abs() < TOL_MM,
                    "{}",
                    c.radius
                );
            }
            EntityType::Text(_) | EntityType::Line(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(handles, [0x20, 0x21, 0x22, 0x23, 0x30]);
    assert!(out.contains("$HANDSEED\n  5\n31\n"), "{out}");
    // Dilated again on purpose, the output carries the new record alone, and the other comment.
    let opts = DxfOptions {
        if_compensated: kerfmeter_plan::compensation::IfCompensated::DilateAnyway,
        ..DxfOptions::default()
    };
    let (again, _) = dilate_dxf(out.as_bytes(), &kerf(), &opts).unwrap();
    let again = String::from_utf8(again).unwrap();
    assert_eq!(
        again.matches("kerfmeter-compensation").count(),
        1,
        "{again}"
    );
    assert!(again.contains("999\nmade by a CAD program\n"));
}

#[test]
fn a_dxf_entity_without_a_handle_is_never_confused_with_another() {
    use dxf::entities::EntityType;
    use spliced::*;
    // No `$HANDSEED`, and a red square with no handle: the `dxf` crate gives it a handle of its
    // own, here the one a green open polyline already has. The square must be dilated, the
    // polyline not.
    let head = HEAD.replace("  9\n$HANDSEED\n  5\n", "");
    let square = SQUARE.replace("  5\n21\n", "");
    let green = |handle: u64| {
        format!(
            "  0\nLWPOLYLINE\n  5\n{handle:X}\n330\n1F\n100\nAcDbEntity\n  8\nNOTES\n 62\n3\n100\nAcDbPolyline\n 90\n2\n 70\n0\n 10\n0.0\n 20\n30.0\n 10\n10.0\n 20\n30.0\n"
        )
    };
    let middle = MIDDLE.trim_start_matches('\n');
    let with = |handle: u64| format!("{head}{middle}{square}{}{TAIL}", green(handle));
    // The handle the crate gives the square (the green polyline's own is far from it).
    let probe = dxf::Drawing::load(&mut std::io::Cursor::new(with(0xFFFF).as_bytes())).unwrap();
    let given = probe
        .entities()
        .find(|e| e.common.layer == "CUT")
        .map(|e| e.common.handle.0)
        .unwrap();
    assert_ne!(given, 0xFFFF);
    let (out, summary) =
        dilate_dxf(with(given).as_bytes(), &kerf(), &DxfOptions::default()).unwrap();
    assert_eq!(summary.contours_dilated, 1);
    let drawing = dxf::Drawing::load(&mut std::io::Cursor::new(&out)).unwrap();
    let mut seen = 0;
    for e in drawing.entities() {
        if let EntityType::LwPolyline(p) = &e.specific {
            seen += 1;
            match e.common.layer.as_str() {
                "NOTES" => assert!(p.vertices.len() == 2 && !p.is_closed(), "{p:?}"),
                _ => assert!(p.vertices.len() == 8 && p.is_closed(), "{p:?}"),
            }
        }
    }
    assert_eq!(seen, 2);
}

#[test]
fn a_new_dxf_polyline_is_owned_by_its_pieces_owner_not_their_reactors() {
    use dxf::entities::EntityType;
    use spliced::*;
    // Lines in a group: AutoCAD writes the group's reactor 330 before the owner's.
    let corners = [(50.0, 50.0), (60.0, 50.0), (60.0, 60.0), (50.0, 60.0)];
    let lines: String = (0..4)
        .map(|k| {
            red_line(0x24 + k as u32, corners[k], corners[(k + 1) % 4]).replace(
                "330\n1F\n",
                "102\n{ACAD_REACTORS\n330\n40\n102\n}\n330\n1F\n",
            )
        })
        .collect();
    let file = format!("{HEAD}{SEED}{MIDDLE}{lines}{TAIL}");
    let (out, summary) = dilate_dxf(file.as_bytes(), &kerf(), &DxfOptions::default()).unwrap();
    assert_eq!(summary.contours_dilated, 1);
    let out = String::from_utf8(out).unwrap();
    let new = &out[out.find("LWPOLYLINE").expect("the chain's new polyline")..];
    assert!(new.contains("330\n1F\n"), "{new}");
    assert!(
        !new[..new.find("AcDbPolyline").unwrap()].contains("330\n40\n"),
        "{new}"
    );
    let drawing = dxf::Drawing::load(&mut std::io::Cursor::new(out.as_bytes())).unwrap();
    let polylines = drawing
        .entities()
        .filter(|e| matches!(e.specific, EntityType::LwPolyline(_)))
        .count();
    assert_eq!(polylines, 1);
}

#[test]
fn a_dxf_handle_seed_behind_a_comment_still_moves_past_the_new_handles() {
    use spliced::*;
    let file = file().replace("$HANDSEED\n  5\n", "$HANDSEED\n999\nnote\n  5\n");
    let (out, _) = dilate_dxf(file.as_bytes(), &kerf(), &DxfOptions::default()).unwrap();
    let out = String::from_utf8(out).unwrap();
    assert!(out.contains("$HANDSEED\n999\nnote\n  5\n31\n"), "{out}");
}
