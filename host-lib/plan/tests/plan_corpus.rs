//! The corpus (`tests/corpus/`, and the plans in `tests/fixtures/`): plans as CAD and vector
//! programs write them. Every file dilates, or is refused with a clear message (what, where, what
//! to do), never a panic; what is written is clean (read again, it has no crossing, overlapping or
//! duplicated loops) and keeps arcs as arcs. Then every file, truncated and with bytes changed,
//! is fed to the readers: an error or a result, never a panic (the `plan_readers` fuzz target
//! does the same with coverage guidance, on nightly).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::dxf_plan::{DxfOptions, dilate_dxf};
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};
use kerfmeter_plan::{DilateOptions, PlanFormat, dilate_file, dilate_file_into};

/// What a corpus file must give with the default options.
enum Expect {
    /// Dilated: this many closed contours.
    Dilates(usize),
    /// Dilated when told what one unit is (refused without, for unknown units): contours.
    DilatesWithUnits(AssumedUnits, usize),
    /// Refused, the message containing all of these.
    Refused(&'static [&'static str]),
}

/// Every file of the corpus and the fixtures, with what it must give.
fn expectations() -> Vec<(&'static str, Expect)> {
    use Expect::*;
    vec![
        ("corpus/inkscape_1x_layers_use_mm.svg", Dilates(5)),
        ("corpus/illustrator_pt_units.svg", Dilates(4)),
        (
            "corpus/illustrator_px_style_classes.svg",
            DilatesWithUnits(AssumedUnits::Px72, 4),
        ),
        ("corpus/lightburn_export.svg", Dilates(3)),
        (
            "corpus/refused_nested_clones.svg",
            Refused(&["rect \"r\"", "nested <use>", "Unlink Clone"]),
        ),
        (
            "corpus/refused_crossing_path.svg",
            Refused(&["path \"bowtie\"", "(10.000, 10.000) mm", "crosses itself"]),
        ),
        (
            "corpus/refused_broken_path_data.svg",
            Refused(&[
                "the cut path \"tail\"",
                "error in its path data",
                "position 36",
            ]),
        ),
        (
            "corpus/r12_polyline_unitless.dxf",
            DilatesWithUnits(AssumedUnits::Mm, 3),
        ),
        ("corpus/librecad_r2000_lwpolyline.dxf", Dilates(4)),
        ("corpus/freecad_r2004_ellipse_spline_cm.dxf", Dilates(4)),
        ("corpus/fusion_r2018_blocks_inch.dxf", Dilates(13)),
        ("corpus/inkscape_r14_spline.dxf", Dilates(2)),
        ("corpus/cad_r2000_straight_spline.dxf", Dilates(2)),
        (
            "corpus/refused_fit_point_spline.dxf",
            Refused(&["SPLINE 33 on layer CUT", "fit points only", "polyline"]),
        ),
        (
            "corpus/refused_missing_block.dxf",
            Refused(&["INSERT 33", "\"MISSING\"", "not in the file"]),
        ),
        (
            "corpus/refused_damaged_value.dxf",
            Refused(&["line 201", "group code 90", "4294967295", "export it again"]),
        ),
        ("fixtures/box_generator.svg", Dilates(4)),
        ("fixtures/inkscape_layers.svg", Dilates(6)),
        ("fixtures/cad_plate.dxf", Dilates(6)),
    ]
}

fn tests_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests")
}

/// Every plan file in the corpus and fixture folders.
fn plan_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = ["corpus", "fixtures"]
        .iter()
        .flat_map(|d| std::fs::read_dir(tests_dir().join(d)).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| PlanFormat::of(p).is_ok())
        .collect();
    files.sort();
    files
}

fn kerf() -> KerfSource {
    KerfSource::Uniform(150.0)
}

fn options(units: Option<AssumedUnits>) -> DilateOptions {
    DilateOptions {
        assume_units: units,
        ..DilateOptions::default()
    }
}

/// Dilate a file, a panic turned into a test failure that names the file.
fn dilate(path: &Path, opts: &DilateOptions) -> Result<(Vec<u8>, PlanSummary), String> {
    catch_unwind(AssertUnwindSafe(|| dilate_file(path, &kerf(), opts)))
        .unwrap_or_else(|_| panic!("{}: the reader panicked", path.display()))
        .map_err(|e| e.to_string())
}

/// What was written, read again: it parses, and dilating it once more (by 1 µm, its own record of
/// compensation waved through) finds no crossing, overlapping or duplicated loops, and as many
/// contours.
fn check_clean(path: &Path, out: &[u8], contours: usize, units: Option<AssumedUnits>) {
    let dir = tempfile::tempdir().unwrap();
    let again = dir.path().join(path.file_name().unwrap());
    std::fs::write(&again, out).unwrap();
    let opts = DilateOptions {
        if_compensated: IfCompensated::DilateAnyway,
        ..options(units)
    };
    let (_, s) = dilate_file(&again, &KerfSource::Uniform(1.0), &opts)
        .unwrap_or_else(|e| panic!("{}: the output is not clean: {e}", path.display()));
    assert_eq!(s.contours_dilated, contours, "{}", path.display());
}

/// Whether the output keeps arcs as arcs: SVG `A` commands, DXF bulges or circles.
fn has_arcs(path: &Path, out: &[u8]) -> bool {
    let text = String::from_utf8_lossy(out);
    match PlanFormat::of(path).unwrap() {
        PlanFormat::Svg => text.contains(" A"),
        PlanFormat::Dxf => text.lines().any(|l| l.trim() == "42") || text.contains("CIRCLE"),
    }
}

#[test]
fn every_corpus_file_dilates_cleanly_or_is_refused_with_a_clear_message() {
    let expected = expectations();
    let files = plan_files();
    for path in &files {
        let name = path.strip_prefix(tests_dir()).unwrap().to_string_lossy();
        let Some((_, expect)) = expected.iter().find(|(n, _)| *n == name) else {
            panic!("{name}: a corpus file without an expectation; add it to the table");
        };
        let units = match expect {
            Expect::DilatesWithUnits(u, _) => {
                let e = dilate(path, &options(None)).unwrap_err();
                assert!(
                    e.contains("unknown units") && e.contains("--units"),
                    "{name}: {e}"
                );
                Some(*u)
            }
            _ => None,
        };
        match (expect, dilate(path, &options(units))) {
            (Expect::Dilates(n) | Expect::DilatesWithUnits(_, n), Ok((out, s))) => {
                assert_eq!(s.contours_dilated, *n, "{name}: {s:?}");
                assert!(has_arcs(path, &out), "{name}: the round joins are not arcs");
                check_clean(path, &out, *n, units);
            }
            (Expect::Refused(words), Err(e)) => {
                for w in *words {
                    assert!(e.contains(w), "{name}: {w:?} not in {e}");
                }
            }
            (_, Ok((_, s))) => panic!("{name}: dilated, expected a refusal: {s:?}"),
            (_, Err(e)) => panic!("{name}: refused: {e}"),
        }
    }
    assert_eq!(files.len(), expected.len(), "a listed file is missing");
}

/// A small deterministic generator (xorshift), so that every run feeds the same mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// `bytes` damaged in one of the ways files get damaged: cut short, a byte changed, a run of
/// bytes removed or repeated, a number replaced by an extreme one.
fn mutate(bytes: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = bytes.to_vec();
    if b.is_empty() {
        // A file already cut to nothing (damaged twice over).
        return b;
    }
    let at = rng.below(b.len());
    match rng.below(5) {
        0 => b.truncate(at),
        1 => b[at] = rng.next() as u8,
        2 => {
            let end = (at + 1 + rng.below(64)).min(b.len());
            b.drain(at..end);
        }
        3 => {
            let end = (at + 1 + rng.below(64)).min(b.len());
            let run = b[at..end].to_vec();
            b.splice(at..at, run);
        }
        _ => {
            let extreme: &[&[u8]] = &[
                b"1e308", b"-1e308", b"NaN", b"0", b"-1", b"1e-320", b"99999",
            ];
            let digit = b[at..].iter().position(u8::is_ascii_digit).map(|k| at + k);
            if let Some(s) = digit {
                let e = s + b[s..]
                    .iter()
                    .take_while(|c| c.is_ascii_digit() || **c == b'.')
                    .count();
                b.splice(s..e, extreme[rng.below(extreme.len())].iter().copied());
            }
        }
    }
    b
}

/// Feed bytes to the reader of `format`, as `kerfmeter dilate` would (units assumed, so that the
/// geometry is reached too): `Err` for a panic.
fn feed(format: PlanFormat, bytes: &[u8]) -> Result<(), ()> {
    catch_unwind(AssertUnwindSafe(|| match format {
        PlanFormat::Svg => {
            if let Ok(text) = std::str::from_utf8(bytes) {
                let opts = SvgOptions {
                    assume_units: Some(AssumedUnits::Mm),
                    ..SvgOptions::default()
                };
                let _ = dilate_svg(text, &kerf(), &opts);
            }
        }
        PlanFormat::Dxf => {
            let opts = DxfOptions {
                assume_units: Some(AssumedUnits::Mm),
                ..DxfOptions::default()
            };
            let _ = dilate_dxf(bytes, &kerf(), &opts);
        }
    }))
    .map_err(|_| ())
}

#[test]
fn damaged_corpus_files_never_panic_the_readers() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut panics = Vec::new();
    let mut fed = 0;
    // Inputs that once panicked a reader under the fuzzer, fed to both readers.
    let regressions = tests_dir().join("corpus/fuzz-regressions");
    for entry in std::fs::read_dir(regressions).unwrap() {
        let path = entry.unwrap().path();
        let bytes = std::fs::read(&path).unwrap();
        for format in [PlanFormat::Svg, PlanFormat::Dxf] {
            assert!(feed(format, &bytes).is_ok(), "{} panicked", path.display());
        }
    }
    for path in plan_files() {
        let format = PlanFormat::of(&path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        // Cut short at 16 places, then 150 random damages (some twice over).
        let cuts = (1..=16).map(|k| bytes[..bytes.len() * k / 17].to_vec());
        let damaged = (0..150).map(|k| {
            let once = mutate(&bytes, &mut rng);
            if k % 3 == 0 {
                mutate(&once, &mut rng)
            } else {
                once
            }
        });
        for input in cuts.chain(damaged.collect::<Vec<_>>()) {
            fed += 1;
            if feed(format, &input).is_err() {
                let keep = std::env::temp_dir().join(format!(
                    "kerfmeter-panic-{fed}.{}",
                    path.extension().unwrap().to_string_lossy()
                ));
                std::fs::write(&keep, &input).unwrap();
                panics.push(keep.display().to_string());
            }
        }
    }
    assert!(
        panics.is_empty(),
        "{} of {fed} damaged files panicked a reader; kept as {panics:?}",
        panics.len()
    );
}

/// `tests/expected/NAME.kerf150.svg`: what the dilation by 150 µm wrote for the plan `NAME`
/// before the SVG writer moved from the XML tree to byte ranges (2026-12-02, 237e183); with a
/// version other than the one it records, that version is put back first.
fn expected_svg(name: &str) -> String {
    let path = tests_dir()
        .join("expected")
        .join(format!("{name}.kerf150.svg"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `text` dilated by 150 µm as SVG, the tool's version written as the expected files have it.
fn dilated_svg(text: &str, units: Option<AssumedUnits>) -> String {
    let opts = SvgOptions {
        assume_units: units,
        ..SvgOptions::default()
    };
    let (out, _) = dilate_svg(text, &kerf(), &opts).unwrap();
    let version = env!("CARGO_PKG_VERSION");
    out.replace(&format!("version=\"{version}\""), "version=\"0.1.0\"")
        .replace(&format!("version={version} "), "version=0.1.0 ")
}

/// `text` written to a file and dilated by 150 µm from it, as the CLI and the Python binding do
/// (the file read again as the output is written), versions as in [`dilated_svg`].
fn dilated_svg_file(text: &str, units: Option<AssumedUnits>) -> String {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("plan.svg");
    std::fs::write(&input, text).unwrap();
    let options = DilateOptions {
        assume_units: units,
        ..DilateOptions::default()
    };
    let mut out = Vec::new();
    dilate_file_into(
        &input,
        &kerf(),
        &options,
        &dir.path().join("out.svg"),
        &mut out,
    )
    .unwrap();
    let version = env!("CARGO_PKG_VERSION");
    String::from_utf8(out)
        .unwrap()
        .replace(&format!("version=\"{version}\""), "version=\"0.1.0\"")
        .replace(&format!("version={version} "), "version=0.1.0 ")
}

#[test]
fn svg_outputs_are_byte_for_byte_what_they_were() {
    let plans = [
        ("corpus", "inkscape_1x_layers_use_mm", None),
        ("corpus", "illustrator_pt_units", None),
        (
            "corpus",
            "illustrator_px_style_classes",
            Some(AssumedUnits::Px72),
        ),
        ("corpus", "lightburn_export", None),
        ("fixtures", "box_generator", None),
        ("fixtures", "inkscape_layers", None),
    ];
    for (dir, name, units) in plans {
        let path = tests_dir().join(dir).join(format!("{name}.svg"));
        let text = std::fs::read_to_string(&path).unwrap();
        let expected = expected_svg(name);
        assert!(
            dilated_svg(&text, units) == expected,
            "{name}: the output changed"
        );
        assert!(
            dilated_svg_file(&text, units) == expected,
            "{name}: the output written from the file changed"
        );
    }
    // CRLF line ends, an attribute with an entity and characters beyond ASCII on a cut element
    // (a <circle>, rewritten as a <path> that keeps them).
    let path = tests_dir().join("corpus/inkscape_1x_layers_use_mm.svg");
    let text = std::fs::read_to_string(&path).unwrap();
    let variant = text
        .replacen("<circle", "<circle data-note=\"Café &amp; ☃\"", 1)
        .replace('\n', "\r\n");
    let name = "inkscape_1x_layers_use_mm.crlf_entities";
    assert!(
        dilated_svg(&variant, None) == expected_svg(name),
        "{name}: the output changed"
    );
    assert!(
        dilated_svg_file(&variant, None) == expected_svg(name),
        "{name}: the output written from the file changed"
    );
    // A byte-order mark, and a plan of many parts (its copies from the file span many reads,
    // and edits fall across their boundaries): from the file as from memory.
    let bom = format!("\u{feff}{text}");
    assert!(
        dilated_svg_file(&bom, None) == dilated_svg(&bom, None),
        "BOM"
    );
    let parts: String = (0..500)
        .map(|i| {
            let (x, y) = (f64::from(i % 20) * 12.0, f64::from(i / 20) * 12.0);
            format!(
                "<!-- part {i}: padding to spread the copies over reads -->\r\n\
                 <rect x=\"{x}\" y=\"{y}\" width=\"10\" height=\"10\" fill=\"none\" \
                 stroke=\"#ff0000\" stroke-width=\"0.01\"/>\r\n"
            )
        })
        .collect();
    let large = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"250mm\" height=\"250mm\" \
         viewBox=\"0 0 250 250\">\r\n{parts}</svg>\r\n"
    );
    assert!(large.len() > 64 * 1024, "{}", large.len());
    assert!(
        dilated_svg_file(&large, None) == dilated_svg(&large, None),
        "many parts"
    );
}

/// The fuzz find whose control point lies kilometres out (it tripped cavalier_contours' own
/// tolerance assert, which the build a user runs does not have): refused with a message, as
/// the CLI refuses it; for where it reaches, which single precision cannot hold (it was refused
/// as a hole narrower than the kerf, which the rounding had made of it).
#[test]
fn a_plan_with_a_control_point_kilometres_out_is_refused_not_dilated() {
    let text =
        std::fs::read_to_string(tests_dir().join("corpus/fuzz-regressions/far-control-point.svg"))
            .unwrap();
    let opts = SvgOptions {
        assume_units: Some(AssumedUnits::Mm),
        ..SvgOptions::default()
    };
    let e = dilate_svg(&text, &kerf(), &opts).unwrap_err();
    assert!(matches!(e, kerfmeter_plan::PlanError::Svg(_)), "{e}");
    assert!(
        e.to_string().contains("reaches 3464772 mm from the origin"),
        "{e}"
    );
}
