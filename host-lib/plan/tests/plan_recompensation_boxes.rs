//! boxes.py's own plans, recompensated by the `kerfmeter` binary, against the same generator's
//! uncompensated plan dilated by the same kerf (issue 32 §4).
//!
//! Each generator's plan comes three times, made by boxes.py (`boxes_plans.py`: its `--burn`,
//! with `--spacing 0.5:-2·burn`, since boxes.py spaces parts by 2·burn more than asked):
//! `NAME.burn0.1.svg`, `NAME.burn0.svg` and `NAME.burn0.05.svg`. The first is recompensated to
//! a 100 µm kerf (`kerfmeter dilate --recompensate --kerf-um 100`), the second dilated by 100 µm;
//! their closed cut lines (red, blue and black: what is dilated) are compared (symmetric Hausdorff
//! distance, see `cut_lines`) part by part, each part (an SVG group boxes.py draws) moved by the
//! shift of its largest contour's centroid: boxes.py fits its page to the drawing and places
//! parts by amounts that depend on the burn. Two more figures tell the plans apart from the
//! recompensation: boxes.py's plan at burn 0.1 as read (loops cut off, not moved: kerf 200 µm)
//! against its uncompensated plan dilated by exactly that ("burnt": where boxes.py's own burn is
//! not an offset of its uncompensated plan, the recompensation cannot be either), and the
//! recompensation against boxes.py's own `--burn 0.05` plan.
//!
//! boxes.py writes coordinates to 1 µm (three decimals in mm), so each plan is off its exact
//! geometry by up to 0.5 µm in x and in y: two plans compared can differ by up to 1.4 µm where
//! nothing else is wrong, hence [`LIMIT_UM`]. The property test (`plan_recompensation`) shows the
//! construction within 1 µm on exact input.
//!
//! The plans are `tests/boxes_plans/` (a fixed sample of boxes.py's generators, made from
//! boxes.py at commit 7d1a89d9; all of them pass), or the folder in `KERFMETER_BOXES_PLANS` (any
//! set `boxes_plans.py` made: every generator, see `xtask/src/recompensation.rs`). The binary is
//! `KERFMETER` (default: the workspace's `target/debug/kerfmeter`). Run by `cargo xtask test`
//! (its step "recompensation against boxes.py's own plans"), which builds it.

mod cut_lines;

use std::path::{Path, PathBuf};
use std::process::Command;

use cut_lines::{Deviation, Drawn, Line, P, centroid, hausdorff, is_closed, read, shifted};

/// The largest deviation allowed, µm (1 µm, and boxes.py's rounding of both plans: up to 1.4).
const LIMIT_UM: f64 = 2.0;
/// The burn the plans were made with, and the kerf they are recompensated to.
const BURN: &str = "0.1";
const BURN_UM: u32 = 100;
const KERF_UM: u32 = 100;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn kerfmeter() -> PathBuf {
    let bin = std::env::var_os("KERFMETER")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("target/debug/kerfmeter"));
    assert!(
        bin.exists(),
        "no kerfmeter binary at {} (cargo build -p kerfmeter-cli, or set KERFMETER)",
        bin.display()
    );
    bin
}

fn plans_dir() -> PathBuf {
    std::env::var_os("KERFMETER_BOXES_PLANS")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/boxes_plans"))
}

/// The generators whose three plans are in `dir`, by name.
fn generators(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| {
            let name = e.ok()?.file_name().into_string().ok()?;
            name.strip_suffix(&format!(".burn{BURN}.svg"))
                .map(str::to_string)
        })
        .collect();
    names.sort();
    names
}

/// `kerfmeter dilate PLAN --kerf-um K [--recompensate] -o OUT`: the output's text, or why not.
fn dilate(plan: &Path, recompensate: bool, kerf_um: u32, out: &Path) -> Result<String, String> {
    let mut cmd = Command::new(kerfmeter());
    cmd.arg("dilate")
        .arg(plan)
        .args(["--kerf-um", &kerf_um.to_string(), "--force", "-o"])
        .arg(out);
    if recompensate {
        cmd.arg("--recompensate");
    }
    let run = cmd.output().expect("kerfmeter runs");
    if !run.status.success() {
        return Err(String::from_utf8_lossy(&run.stderr).trim().to_string());
    }
    Ok(std::fs::read_to_string(out).expect("the output"))
}

/// `a`'s lines moved onto `b`'s, part by part: each group's by the shift of its largest
/// contour's centroid onto the same group's in `b` (contours paired in drawing order; a part's
/// outline is drawn from the part's origin, its holes placed from there, so a hole boxes.py
/// places differently at another burn shows as a deviation of the hole). `None` when the two do
/// not pair.
fn aligned(a: &[Drawn], b: &[Drawn]) -> Option<Vec<Line>> {
    let mut groups: Vec<&str> = a.iter().map(|d| d.group.as_str()).collect();
    groups.dedup();
    let mut out = Vec::with_capacity(a.len());
    for g in groups {
        let of = |x: &[Drawn]| -> Vec<Line> {
            x.iter()
                .filter(|d| d.group == g)
                .map(|d| d.line.clone())
                .collect()
        };
        let (la, lb) = (of(a), of(b));
        out.extend(shifted(&la, translation(&la, &lb)?));
    }
    Some(out)
}

/// The shift of the largest of the lines `a` onto its partner in `b` (paired in order).
fn translation(a: &[Line], b: &[Line]) -> Option<P> {
    if a.len() != b.len() || a.is_empty() {
        return None;
    }
    let largest = (0..a.len()).max_by(|&i, &j| area(&a[i]).total_cmp(&area(&a[j])))?;
    let (p, q) = (centroid(&a[largest]), centroid(&b[largest]));
    Some((q.0 - p.0, q.1 - p.1))
}

fn area(l: &[P]) -> f64 {
    l.windows(2)
        .map(|w| w[0].0 * w[1].1 - w[1].0 * w[0].1)
        .sum::<f64>()
        .abs()
}

/// The id of the group of boxes.py's reference rectangle (the one labelled `burn:…`).
fn reference_group(svg: &str) -> Option<String> {
    let doc = roxmltree::Document::parse(svg).ok()?;
    let label = doc
        .descendants()
        .find(|n| n.has_tag_name("text") && n.text().is_some_and(|t| t.contains("burn:")))?;
    Some(label.parent_element()?.attribute("id")?.to_string())
}

/// The closed cut lines, in kerfmeter's default cut colours (red, blue, black): what is dilated.
/// Open ones pass through as drawn, and so do lines of other colours (boxes.py's engravings and
/// marks); boxes.py draws some of those differently at each burn.
fn closed(mut d: Vec<Drawn>) -> Vec<Drawn> {
    const CUTS: [[u8; 3]; 3] = [[255, 0, 0], [0, 0, 255], [0, 0, 0]];
    d.retain(|x| is_closed(&x.line) && CUTS.contains(&x.rgb));
    d
}

fn lines(d: &[Drawn]) -> Vec<Line> {
    d.iter().map(|x| x.line.clone()).collect()
}

/// How one generator's recompensation compares.
struct Outcome {
    name: String,
    contours: usize,
    /// The recompensated plan against the uncompensated plan dilated.
    recompensated: Deviation,
    /// boxes.py's own plan at burn 0.1 (its loops removed) against its uncompensated plan offset
    /// by 0.1 mm exactly: what boxes.py's burn itself differs from an offset.
    burnt: Deviation,
    /// The recompensated plan against boxes.py's own plan at burn 0.05 mm, µm.
    vs_boxes_um: Option<f64>,
}

/// `kerfmeter dilate` of generator `name`'s plan at `burn`, by `kerf_um`, recompensated when the
/// plan has a burn; its closed cut lines.
fn cut(dir: &Path, out: &Path, name: &str, burn: &str, kerf_um: u32) -> Result<Vec<Drawn>, String> {
    let plan = dir.join(format!("{name}.burn{burn}.svg"));
    let written = out.join(format!("{name}.burn{burn}.kerf{kerf_um}.svg"));
    dilate(&plan, burn != "0", kerf_um, &written).map(|text| closed(read(&text)))
}

/// The deviation of `a` from `b` (lines aligned part by part), or why they do not compare.
fn deviation(a: &[Drawn], b: &[Drawn]) -> Result<Deviation, String> {
    let moved = aligned(a, b).ok_or("the plans' parts do not pair")?;
    Ok(hausdorff(&moved, &lines(b)))
}

/// Compare generator `name`'s plans in `dir`, writing the outputs into `out`: the outcome, or why
/// it was not compared (the uncompensated plan is refused too), or the failure.
fn compare(dir: &Path, out: &Path, name: &str) -> Result<Result<Outcome, String>, String> {
    let fail = |e: String| format!("{name}: {e}");
    let (reference, exact) = match (
        cut(dir, out, name, "0", KERF_UM),
        cut(dir, out, name, "0", 2 * BURN_UM),
    ) {
        (Ok(r), Ok(e)) => (r, e),
        (Err(e), _) | (_, Err(e)) => {
            return Ok(Err(format!("its uncompensated plan is refused too: {e}")));
        }
    };
    let got = cut(dir, out, name, BURN, KERF_UM).map_err(fail)?;
    let as_drawn = cut(dir, out, name, BURN, 2 * BURN_UM).map_err(fail)?;
    let boxes = std::fs::read_to_string(dir.join(format!("{name}.burn0.05.svg")))
        .ok()
        .and_then(|text| {
            // boxes.py draws its reference rectangle without burn.
            let reference = reference_group(&text);
            let burnt = |d: &[Drawn]| -> Vec<Drawn> {
                d.iter()
                    .filter(|x| Some(&x.group) != reference.as_ref())
                    .cloned()
                    .collect()
            };
            deviation(&burnt(&got), &burnt(&closed(read(&text)))).ok()
        });
    Ok(Ok(Outcome {
        name: name.to_string(),
        contours: got.len(),
        recompensated: deviation(&got, &reference).map_err(fail)?,
        burnt: deviation(&as_drawn, &exact).map_err(fail)?,
        vs_boxes_um: boxes.map(|d| d.mm * 1000.0),
    }))
}

#[test]
#[ignore = "needs the kerfmeter binary: run by `cargo xtask test` (or build it and pass --ignored)"]
fn boxes_py_plans_recompensated_match_their_uncompensated_plans_dilated() {
    let dir = plans_dir();
    let out = tempfile::tempdir().unwrap();
    let names = generators(&dir);
    assert!(!names.is_empty(), "no plans in {}", dir.display());
    let (mut failures, mut worst) = (Vec::new(), 0.0f64);
    println!(
        "{:<22} {:>8} {:>13} {:>22} {:>11} {:>10}",
        "generator", "contours", "recomp. (µm)", "at (mm)", "burnt (µm)", "0.05 (µm)"
    );
    for name in &names {
        match compare(&dir, out.path(), name) {
            Ok(Ok(o)) => {
                let um = o.recompensated.mm * 1000.0;
                println!(
                    "{:<22} {:>8} {:>13.3} ({:>9.3}, {:>9.3}) {:>11.3} {:>10}",
                    o.name,
                    o.contours,
                    um,
                    o.recompensated.at.0,
                    o.recompensated.at.1,
                    o.burnt.mm * 1000.0,
                    o.vs_boxes_um.map_or("-".into(), |v| format!("{v:.3}"))
                );
                worst = worst.max(um);
                if um > LIMIT_UM {
                    failures.push(format!(
                        "{}: {um:.3} µm at {:?}",
                        o.name, o.recompensated.at
                    ));
                }
            }
            Ok(Err(why)) => println!(
                "{name:<22} not compared: {}",
                why.lines().next().unwrap_or("")
            ),
            Err(e) => failures.push(e),
        }
    }
    println!("worst: {worst:.3} µm over {} generators", names.len());
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
