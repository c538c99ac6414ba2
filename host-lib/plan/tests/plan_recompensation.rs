//! Recompensation as exact as compensation (issue 32 §4), as a property over random polygons with
//! acute and reflex corners, in three steps:
//!
//! 1. the polygon is compensated by `b1`: drawn by boxes.py's construction (`boxes_burn`: arcs
//!    around convex corners, loops and backarcs at inner ones, a corner drawn as two turns
//!    retracing its arc), or buffered by GEOS (shapely, `geos_buffer.py`; its round joins are
//!    chords, GEOS's default 8 a quarter circle) and recorded as an earlier dilation;
//! 2. that plan is recompensated to `b2` (`--recompensate` with a kerf of 2·`b2`);
//! 3. the result is compared with the polygon compensated directly by `b2` (`dilate`, the
//!    Minkowski sum with the beam's disk), and with GEOS's buffer by `b2`: symmetric Hausdorff
//!    distance of the cut lines as usvg reads them back (`cut_lines`), at most 1 µm (from GEOS's
//!    buffer, 1 µm more than its chords lie inside their arcs). GEOS splits a join of angle θ
//!    into round(θ / (π/16)) chords (`OffsetSegmentGenerator::addDirectedFillet`: the count is
//!    rounded, not raised), so one chord spans up to 1.5 · π/16 = 3π/32, and
//!    lies up to r·(1 − cos(3π/64)) inside its arc: 2.7 µm at 0.25 mm (a 16° join at 0.29 mm
//!    drawn as one chord, 2.84 µm in).
//!
//! The polygons are stars (5 to 12 corners at radii 2–10 mm, at least 0.25 rad apart: notches
//! of 18° and more, spikes as sharp), `b1` 0.05–0.25 mm and `b2` 0.02–0.3 mm (shrinking and
//! growing). A polygon one of whose edges a burn would swallow whole is left out: its cut
//! carries nothing of that edge to recompensate from (see the `recompensate` module doc).
//! Seeds are fixed (printed below each test), so every run draws the same polygons.

mod boxes_burn;
mod cut_lines;

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::{Mutex, OnceLock};

use boxes_burn::{P, Turn};
use kerfmeter_plan::compensation::IfCompensated;
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

/// The largest deviation allowed, mm.
const LIMIT_MM: f64 = 1e-3;
/// The seeds of the two properties.
const BOXES_SEED: u64 = 0x3204_0001;
const GEOS_SEED: u64 = 0x3204_0002;

/// One drawn case: the polygon (counter-clockwise), how each corner is drawn, both burns, mm.
#[derive(Debug, Clone)]
struct Case {
    poly: Vec<P>,
    turns: Vec<Turn>,
    b1: f64,
    b2: f64,
}

/// A star: corners at the given angle steps (scaled to a full turn) and radii.
fn star(steps: &[f64], radii: &[f64]) -> Vec<P> {
    let total: f64 = steps.iter().sum();
    let mut angle = 0.0;
    steps
        .iter()
        .zip(radii)
        .map(|(s, r)| {
            angle += s / total * std::f64::consts::TAU;
            (r * angle.cos(), r * angle.sin())
        })
        .collect()
}

fn cases() -> impl Strategy<Value = Case> {
    (5usize..=12)
        .prop_flat_map(|n| {
            (
                prop::collection::vec(1.0f64..3.0, n),
                prop::collection::vec(2.0f64..10.0, n),
                prop::collection::vec(prop::bool::ANY, n),
                0.05f64..0.25,
                0.02f64..0.3,
            )
        })
        .prop_map(|(steps, radii, twice, b1, b2)| Case {
            poly: star(&steps, &radii),
            turns: twice
                .into_iter()
                .map(|t| if t { Turn::Twice } else { Turn::Once })
                .collect(),
            b1,
            b2,
        })
        .prop_filter("corners at least 0.25 rad apart", |c| {
            min_step(&c.poly) >= 0.25
        })
        .prop_filter("no edge swallowed by a burn", |c| {
            edges_survive(&c.poly, c.b1.max(c.b2))
        })
}

/// The smallest angle between consecutive corners seen from the centre, rad.
fn min_step(poly: &[P]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|k| {
            let (a, b) = (poly[k], poly[(k + 1) % n]);
            (a.0 * b.1 - a.1 * b.0).atan2(a.0 * b.0 + a.1 * b.1)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Whether every edge keeps a piece (50 µm or more) once offset by `burn`: each inner corner
/// takes `burn`·tan(turn/2) off both its edges.
fn edges_survive(poly: &[P], burn: f64) -> bool {
    let n = poly.len();
    let turn = |k: usize| {
        let (a, b, c) = (poly[(k + n - 1) % n], poly[k], poly[(k + 1) % n]);
        let (u, w) = ((b.0 - a.0, b.1 - a.1), (c.0 - b.0, c.1 - b.1));
        (u.0 * w.1 - u.1 * w.0).atan2(u.0 * w.0 + u.1 * w.1)
    };
    let taken = |k: usize| burn * (turn(k).min(0.0).abs() / 2.0).tan();
    (0..n).all(|k| {
        let (a, b) = (poly[k], poly[(k + 1) % n]);
        (a.0 - b.0).hypot(a.1 - b.1) - taken(k) - taken((k + 1) % n) > 0.05
    })
}

/// An SVG plan of one red cut `d`, with `record` (metadata) saying how it is compensated.
fn plan(d: &str, record: &str) -> String {
    format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="40mm" height="40mm" viewBox="-20 -20 40 40">{record}<path id="part" d="{d}" fill="none" stroke="#ff0000" stroke-width="0.1"/></svg>"##
    )
}

/// boxes.py's record of a burn.
fn boxes_record(burn: f64) -> String {
    format!("<desc>Created with Boxes.py\nCommand line: boxes Polygon --burn={burn}</desc>")
}

/// This tool's record of an earlier dilation by `offset` mm.
fn own_record(offset: f64) -> String {
    format!(
        r#"<metadata><kerfmeter:compensation xmlns:kerfmeter="urn:x-kerfmeter:compensation:1" tool="kerfmeter" kerf_um="{}" offset_um="{}"/></metadata>"#,
        2000.0 * offset,
        1000.0 * offset
    )
}

/// Path data of closed rings.
fn rings_path(rings: &[Vec<P>]) -> String {
    rings
        .iter()
        .map(|r| {
            let pts: Vec<String> = r.iter().map(|p| format!("{:.9} {:.9}", p.0, p.1)).collect();
            format!("M {} Z", pts.join(" L "))
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The plan dilated by `half_kerf` mm (recompensated when `policy` says so): its cut lines.
fn cut(svg: &str, half_kerf: f64, policy: IfCompensated) -> Vec<cut_lines::Line> {
    let opts = SvgOptions {
        if_compensated: policy,
        ..SvgOptions::default()
    };
    let (out, _) = dilate_svg(svg, &KerfSource::Uniform(2000.0 * half_kerf), &opts)
        .unwrap_or_else(|e| panic!("{e}"));
    cut_lines::read(&out).into_iter().map(|d| d.line).collect()
}

/// The polygon compensated directly by `b2`: this tool's dilation of the plain polygon; `None`
/// when that is refused (a notch of the polygon narrower than the kerf would close around a
/// void: no compensation can cut it).
fn direct(case: &Case) -> Option<Vec<cut_lines::Line>> {
    let d = rings_path(std::slice::from_ref(&case.poly));
    let opts = SvgOptions::default();
    let (out, _) = dilate_svg(&plan(&d, ""), &KerfSource::Uniform(2000.0 * case.b2), &opts).ok()?;
    Some(cut_lines::read(&out).into_iter().map(|d| d.line).collect())
}

/// How far inside its arc of radius `r` a chord of GEOS's buffer lies at most, mm: a chord
/// spans up to 3π/32 (see the module doc).
fn chord_mm(r: f64) -> f64 {
    r * (1.0 - (3.0 * std::f64::consts::PI / 64.0).cos())
}

/// Whether `got` deviates from `want` by at most `limit` mm (else where, and by how much).
fn check(
    got: &[cut_lines::Line],
    want: &[cut_lines::Line],
    limit: f64,
    what: &str,
) -> Result<(), TestCaseError> {
    let d = cut_lines::hausdorff(got, want);
    prop_assert!(
        d.mm <= limit,
        "{what}: {:.3} µm at {:?}",
        d.mm * 1000.0,
        d.at
    );
    Ok(())
}

fn config(seed: u64, cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..Config::default()
    }
}

proptest! {
    #![proptest_config(config(BOXES_SEED, 96))]

    #[test]
    fn recompensating_boxes_py_s_construction_equals_compensating_directly(case in cases()) {
        let want = direct(&case);
        prop_assume!(want.is_some(), "the polygon cannot be compensated by b2");
        let d = boxes_burn::path(&case.poly, case.b1, &case.turns, 9);
        let got = cut(&plan(&d, &boxes_record(case.b1)), case.b2, IfCompensated::Recompensate);
        check(&got, &want.unwrap_or_default(), LIMIT_MM, "recompensated against dilated")?;
    }
}

/// GEOS through the project's Python: one process for the whole test, a request a line.
struct Geos {
    _child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
}

impl Geos {
    fn start() -> Geos {
        let python = std::env::var_os("KERFMETER_PYTHON").map_or_else(
            || {
                PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                    .join("../../target/python-venv/bin/python")
            },
            PathBuf::from,
        );
        let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/geos_buffer.py");
        let mut child = Command::new(&python)
            .arg(script)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| {
                panic!(
                    "{} (shapely in the project's venv: `cargo xtask test-python` makes it): {e}",
                    python.display()
                )
            });
        let stdin = child.stdin.take().expect("piped");
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        Geos {
            _child: child,
            stdin,
            stdout,
        }
    }

    /// The polygon buffered by `d` mm: its rings.
    fn buffer(&mut self, poly: &[P], d: f64) -> Vec<Vec<P>> {
        let request = serde_json::json!({ "rings": [poly], "d": d });
        writeln!(self.stdin, "{request}").expect("GEOS's helper reads");
        let mut line = String::new();
        self.stdout
            .read_line(&mut line)
            .expect("GEOS's helper answers");
        let answer: serde_json::Value = serde_json::from_str(&line).expect("JSON");
        let rings: Vec<Vec<P>> = serde_json::from_value(answer["rings"].clone())
            .unwrap_or_else(|_| panic!("GEOS: {line}"));
        // Each ring repeats its first point: the path's Z closes it.
        rings
            .into_iter()
            .map(|mut r| {
                r.pop();
                r
            })
            .collect()
    }
}

fn geos() -> &'static Mutex<Geos> {
    static GEOS: OnceLock<Mutex<Geos>> = OnceLock::new();
    GEOS.get_or_init(|| Mutex::new(Geos::start()))
}

proptest! {
    #![proptest_config(config(GEOS_SEED, 48))]

    // Needs shapely in the project's venv (`cargo xtask test` makes it before the host tests).
    // With GEOS_SEED the fourth case (a hexagon with a 5.7° reflex corner and a 60° spike, b1
    // 0.05 mm, b2 0.02 mm) was refused until the offsets of a recompensation were worked out in
    // µm: in mm, `cavalier_contours` took GEOS's chords (7.8 µm at 8.9°) for parallel, and its
    // offset 30 µm into the part came back as a sliver around the spike (see
    // `recompensate::offset_in_um`).
    #[test]
    fn recompensating_a_geos_buffer_equals_compensating_directly(case in cases()) {
        let want = direct(&case);
        prop_assume!(want.is_some(), "the polygon cannot be compensated by b2");
        let want = want.unwrap_or_default();
        let mut geos = geos().lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let buffered = rings_path(&geos.buffer(&case.poly, case.b1));
        let got = cut(&plan(&buffered, &own_record(case.b1)), case.b2, IfCompensated::Recompensate);
        check(&got, &want, LIMIT_MM + chord_mm(case.b1), "recompensated against dilated")?;
        // In document mm: the page's view box starts at (-20, -20).
        let theirs: Vec<cut_lines::Line> = geos
            .buffer(&case.poly, case.b2)
            .into_iter()
            .map(|mut r| {
                r.push(r[0]);
                r.into_iter().map(|p| (p.0 + 20.0, p.1 + 20.0)).collect()
            })
            .collect();
        check(&want, &theirs, LIMIT_MM + chord_mm(case.b2), "dilated against GEOS's buffer")?;
    }
}
