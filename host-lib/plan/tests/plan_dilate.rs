//! Dilating real plan files (fixtures in `tests/fixtures/`), as `kerfmeter dilate` does: a
//! box-generator SVG, an Inkscape SVG with layers, transforms and clones, a DXF as CAD programs
//! write it — fingers get wider and slots narrower by exactly the kerf, labels and everything else
//! stay as they were — and the ways it must refuse: broken files, unknown units, merging parts,
//! holes of a part that meet or are drawn twice, open paths when strict. (What only the command does — never writing over the input, the
//! dry-run report — is tested with the `kerfmeter-cli` package.)
//!
//! Geometry is measured on the *output file*, parsed again (SVG with `usvg`, DXF with `dxf`), and
//! compared with the input parsed the same way.

mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use common::{MM_PER_CSS_PX, Poly, Sampling, all_paths, path_by_id, seg_dist, subpaths};
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::outcome::{AssumedUnits, PlanSummary};
use kerfmeter_plan::rules::CutRules;
use kerfmeter_plan::{DilateOptions, PlanError, dilate_file};

/// 0.1 µm: coordinates pass through usvg in single precision.
const TOL_MM: f64 = 1e-4;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

/// A copy of a fixture in a fresh folder.
fn copy(name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let to = dir.path().join(name);
    std::fs::copy(fixture(name), &to).unwrap();
    (dir, to)
}

/// Dilate `input` by `kerf_um` with `options` and write the result to `output`.
fn dilate_with(
    input: &Path,
    kerf_um: f64,
    output: &Path,
    options: &DilateOptions,
) -> Result<PlanSummary, PlanError> {
    let kerf = KerfSource::Uniform(KerfSource::check_kerf_um(kerf_um)?);
    let (bytes, summary) = dilate_file(input, &kerf, options)?;
    std::fs::write(output, bytes).unwrap();
    Ok(summary)
}

/// Dilate `input` by `kerf_um` with the default rules and write the result to `output`.
fn dilate(input: &Path, kerf_um: f64, output: &Path) -> Result<PlanSummary, PlanError> {
    dilate_with(input, kerf_um, output, &DilateOptions::default())
}

fn tree(path: &Path) -> usvg::Tree {
    let text = std::fs::read_to_string(path).unwrap();
    usvg::Tree::from_str(&text, &usvg::Options::default()).unwrap()
}

/// The subpaths of a usvg path in document mm, curves sampled finely.
fn polys(path: &usvg::Path) -> Vec<Poly> {
    let sampling = Sampling {
        mm_per_px: MM_PER_CSS_PX,
        points_per_curve: 256,
        close_rings: true,
    };
    subpaths(path, &sampling)
}

fn group<'a>(g: &'a usvg::Group, id: &str) -> Option<&'a usvg::Group> {
    for n in g.children() {
        if let usvg::Node::Group(c) = n {
            if c.id() == id {
                return Some(c);
            }
            if let Some(x) = group(c, id) {
                return Some(x);
            }
        }
    }
    None
}

/// Sorted x where a closed polyline crosses the horizontal line at `y`.
fn crossings_at_y(poly: &Poly, y: f64) -> Vec<f64> {
    let mut xs = Vec::new();
    for w in poly.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if (y0 <= y && y1 > y) || (y1 <= y && y0 > y) {
            xs.push(x0 + (y - y0) / (y1 - y0) * (x1 - x0));
        }
    }
    xs.sort_by(f64::total_cmp);
    xs
}

fn area(poly: &Poly) -> f64 {
    poly.windows(2)
        .map(|w| w[0].0 * w[1].1 - w[1].0 * w[0].1)
        .sum::<f64>()
        / 2.0
}

fn dist_to(p: (f64, f64), poly: &Poly) -> f64 {
    poly.windows(2)
        .map(|w| seg_dist(p, w[0], w[1]))
        .fold(f64::INFINITY, f64::min)
}

/// Every point of `dilated` lies exactly `d` from `original`, and the area moved the right way.
fn check_offset(original: &Poly, dilated: &Poly, d: f64, grows: bool, what: &str) {
    let worst = dilated
        .iter()
        .map(|&p| (dist_to(p, original) - d).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 2.0 * TOL_MM,
        "{what}: a point is {worst} mm off the offset"
    );
    let (a0, a1) = (area(original).abs(), area(dilated).abs());
    assert_eq!(a1 > a0, grows, "{what}: area {a0} → {a1}");
}

fn widths(xs: &[f64]) -> (Vec<f64>, Vec<f64>) {
    // Material intervals are (x0, x1), (x2, x3), …; gaps lie between them.
    let material = xs.chunks(2).map(|c| c[1] - c[0]).collect();
    let gaps = xs[1..]
        .chunks(2)
        .filter(|c| c.len() == 2)
        .map(|c| c[1] - c[0])
        .collect();
    (material, gaps)
}

#[test]
fn box_generator_plan_fingers_wider_slots_narrower_by_exactly_the_kerf() {
    let (dir, input) = copy("box_generator.svg");
    let output = dir.path().join("box-k200.svg");
    let s = &dilate(&input, 200.0, &output).unwrap();
    assert_eq!(
        (s.contours_dilated, s.parts, s.holes, s.islands),
        (4, 2, 2, 0)
    );
    assert_eq!(s.open_paths.len(), 1, "the slit in side B");
    assert!((s.open_paths[0].start_mm[0] - 100.0).abs() < TOL_MM);
    assert_eq!(s.passed_through.get("text"), Some(&2));
    let k = 0.2;

    // Labels, the etching, the slit and the comment are byte-for-byte the same.
    let src = std::fs::read_to_string(&input).unwrap();
    let out = std::fs::read_to_string(&output).unwrap();
    for line in src.lines().filter(|l| {
        l.contains("<text")
            || l.contains("rgb(0,255,0)")
            || l.contains("V 50.000")
            || l.starts_with("thickness")
            || l.starts_with("<g ")
    }) {
        assert!(out.contains(line), "changed: {line}");
    }
    assert_eq!(out.matches("<path").count(), src.matches("<path").count());

    let (t_in, t_out) = (tree(&input), tree(&output));
    let side = |t: &usvg::Tree, g: &str, i: usize| {
        let paths = all_paths(group(t.root(), g).unwrap());
        polys(paths[i]).remove(0)
    };
    // Side A's fingers (at mid-height, y = 18.5): each wider by k.
    let (fa_in, _) = widths(&crossings_at_y(&side(&t_in, "p-0", 0), 18.5));
    let (fa_out, gaps_a) = widths(&crossings_at_y(&side(&t_out, "p-0", 0), 18.5));
    assert_eq!(fa_in.len(), 4);
    for (a, b) in fa_in.iter().zip(&fa_out) {
        assert!((b - a - k).abs() < TOL_MM, "finger {a} → {b}");
        assert!((a - 6.0).abs() < TOL_MM);
    }
    assert!(gaps_a.iter().all(|g| (g - (6.0 - k)).abs() < TOL_MM));
    // Side B's slots (y = 58.5): each narrower by k.
    let (_, sb_in) = widths(&crossings_at_y(&side(&t_in, "p-1", 0), 58.5));
    let (_, sb_out) = widths(&crossings_at_y(&side(&t_out, "p-1", 0), 58.5));
    assert_eq!(sb_in.len(), 4);
    for (a, b) in sb_in.iter().zip(&sb_out) {
        assert!((a - b - k).abs() < TOL_MM, "slot {a} → {b}");
    }
    // The inner slot for a divider, and the round hole, shrink by k.
    let slot_out = crossings_at_y(&side(&t_out, "p-1", 1), 37.5);
    assert!((slot_out[1] - slot_out[0] - (6.0 - k)).abs() < TOL_MM);
    // The hole is written as exact arcs of radius 3.9; usvg reads them back as cubics, whose
    // ends lie on the circle (and whose middles stray by ≈ 0.03 % of the radius).
    assert!(out.contains("A3.9 3.9 0 0 1 "), "the hole stays arcs");
    let hole = side(&t_out, "p-0", 1);
    for (i, p) in hole.iter().enumerate() {
        let err = ((p.0 - 40.0).hypot(p.1 - 40.0) - (4.0 - k / 2.0)).abs();
        assert!(
            err < if i % 256 == 0 { TOL_MM } else { 3e-4 * 4.0 },
            "hole point {i}: {err}"
        );
    }
    // The outline grew by k/2 all round.
    let outline = side(&t_out, "p-0", 0);
    let ymin = outline.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    let ymax = outline.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    assert!((ymin - (17.0 - k / 2.0)).abs() < TOL_MM && (ymax - (60.0 + k / 2.0)).abs() < TOL_MM);
}

#[test]
fn inkscape_plan_with_layers_transforms_and_clones() {
    let (dir, input) = copy("inkscape_layers.svg");
    let output = dir.path().join("out.svg");
    let s = &dilate(&input, 200.0, &output).unwrap();
    // plate (+ hole, slot), the skewed part, two clones; the hidden layer is not cut.
    assert_eq!((s.contours_dilated, s.parts, s.holes), (6, 4, 2));
    assert!(s.open_paths.is_empty());
    let d = 0.1;
    let src = std::fs::read_to_string(&input).unwrap();
    let out = std::fs::read_to_string(&output).unwrap();
    // What was applied is recorded right after the root's start tag; nothing else is added.
    let start = out.find("\n<!-- kerfmeter-compensation").unwrap();
    let end = start + out[start..].find("</metadata>").unwrap() + "</metadata>".len();
    let out = format!("{}{}", &out[..start], &out[end..]);

    // Layers, text, the score line, the hidden layer and the clone template stay as they were.
    for block in [
        &src[src.find("<text").unwrap()..src.find("</text>").unwrap()],
        &src[src
            .find("<path\n       style=\"fill:none;stroke:#00ff00")
            .unwrap()..src.find("id=\"score-line\" />").unwrap()],
        &src[src.find("<g\n     inkscape:label=\"Hidden\"").unwrap()..src.rfind("</g>").unwrap()],
        {
            let at = src.find("<rect\n       style=\"fill:none;stroke:#ff0000;stroke-width:0.1\"\n       id=\"tab-template\"").unwrap();
            &src[at..at + src[at..].find("/>").unwrap() + 2]
        },
        &src[..src.find("<defs").unwrap()],
    ] {
        assert!(out.contains(block), "changed:\n{block}");
    }
    assert_eq!(out.matches("inkscape:groupmode=\"layer\"").count(), 5);
    // The rect in the scaled group became a path with its id and style; Inkscape's arc
    // parameters are gone from the dilated circle.
    let slot_at = out.find("id=\"slot\"").unwrap();
    let slot_tag = &out[out[..slot_at].rfind('<').unwrap()..]
        [..out[slot_at..].find("/>").unwrap() + slot_at - out[..slot_at].rfind('<').unwrap()];
    assert!(
        slot_tag.starts_with("<path")
            && slot_tag.contains("stroke-width:0.2")
            && !slot_tag.contains("width=\"12\""),
        "{slot_tag}"
    );
    let hole_at = out.find("id=\"hole\"").unwrap();
    let hole_tag =
        &out[out[..hole_at].rfind('<').unwrap()..hole_at + out[hole_at..].find("/>").unwrap()];
    assert!(
        !hole_tag.contains("sodipodi:type") && hole_tag.contains(" A"),
        "{hole_tag}"
    );
    // The clones point at dilated copies.
    assert!(out.contains("xlink:href=\"#tab-template-kerf"));
    assert!(out.matches("-kerf").count() >= 4);

    let (t_in, t_out) = (tree(&input), tree(&output));
    for (id, grows) in [
        ("plate", true),
        ("hole", false),
        ("slot", false),
        ("skewed-part", true),
    ] {
        let a = polys(path_by_id(t_in.root(), id)).remove(0);
        let b = polys(path_by_id(t_out.root(), id)).remove(0);
        check_offset(&a, &b, d, grows, id);
    }
    // The skewed part (a non-uniform, rotated frame): area of a convex polygon offset by d.
    let skew_in = polys(path_by_id(t_in.root(), "skewed-part")).remove(0);
    let skew_out = polys(path_by_id(t_out.root(), "skewed-part")).remove(0);
    let perimeter: f64 = skew_in
        .windows(2)
        .map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1))
        .sum();
    let expected = area(&skew_in).abs() + perimeter * d + std::f64::consts::PI * d * d;
    assert!(
        (area(&skew_out).abs() - expected).abs() < 1e-3,
        "{} vs {expected}",
        area(&skew_out)
    );
    for clone in ["clone-1", "clone-2"] {
        let a = polys(all_paths(group(t_in.root(), clone).unwrap())[0]).remove(0);
        let b = polys(all_paths(group(t_out.root(), clone).unwrap())[0]).remove(0);
        check_offset(&a, &b, d, true, clone);
    }
    // The hidden layer's rect is still there, unrendered and untouched.
    assert!(out.contains("id=\"hidden-cut\""));
}

fn dxf_entities(path: &Path) -> Vec<dxf::entities::Entity> {
    dxf::Drawing::load_file(path)
        .unwrap()
        .entities()
        .cloned()
        .collect()
}

#[test]
fn cad_dxf_polylines_chains_circles_and_islands() {
    use dxf::entities::EntityType;
    let (dir, input) = copy("cad_plate.dxf");
    let output = dir.path().join("plate-k200.dxf");
    let s = &dilate(&input, 200.0, &output).unwrap();
    assert_eq!(
        (s.contours_dilated, s.parts, s.holes, s.islands),
        (6, 3, 3, 1)
    );
    assert_eq!(s.open_paths.len(), 1);
    assert!(
        s.open_paths[0].id.starts_with("LINE"),
        "{}",
        s.open_paths[0].id
    );
    let k = 0.2;
    let before = dxf_entities(&input);
    let after = dxf_entities(&output);
    let drawing = dxf::Drawing::load_file(&output).unwrap();
    assert_eq!(
        drawing.header.default_drawing_units,
        dxf::enums::Units::Millimeters
    );

    let handle_of = |pred: &dyn Fn(&EntityType) -> bool| {
        before
            .iter()
            .find(|e| pred(&e.specific))
            .unwrap()
            .common
            .handle
    };
    let by_handle = |h: dxf::Handle| after.iter().find(|e| e.common.handle == h);
    // The plate keeps its entity (same handle); fingers 12–18, 24–30, 36–42 widen by k.
    let plate_h = handle_of(&|e| matches!(e, EntityType::LwPolyline(_)));
    let Some(EntityType::LwPolyline(plate)) = by_handle(plate_h).map(|e| &e.specific) else {
        panic!("the plate LWPOLYLINE is gone");
    };
    assert!(plate.is_closed());
    let has = |x: f64, y: f64| {
        plate
            .vertices
            .iter()
            .any(|v| (v.x - x).abs() < 1e-9 && (v.y - y).abs() < 1e-9)
    };
    for (x0, x1) in [(12.0, 18.0), (24.0, 30.0), (36.0, 42.0)] {
        assert!(
            has(x0 - k / 2.0, 40.0 + k / 2.0)
                || has(x0 - k / 2.0, 40.0 - k / 2.0)
                || plate
                    .vertices
                    .iter()
                    .any(|v| (v.x - (x0 - k / 2.0)).abs() < 1e-9),
            "finger {x0}"
        );
        assert!(
            plate
                .vertices
                .iter()
                .any(|v| (v.x - (x1 + k / 2.0)).abs() < 1e-9),
            "finger {x1}"
        );
    }
    let ys: Vec<f64> = plate.vertices.iter().map(|v| v.y).collect();
    assert!((ys.iter().cloned().fold(f64::MIN, f64::max) - (43.0 + k / 2.0)).abs() < 1e-9);
    // Rounded corners keep their arcs (radius 3 + k/2): a quarter-turn bulge.
    assert!(
        plate
            .vertices
            .iter()
            .filter(|v| (v.bulge - (std::f64::consts::PI / 8.0).tan()).abs() < 1e-9)
            .count()
            >= 2
    );

    // Circles stay circles: the hole and the ring's hole shrink, the island grows.
    let radius_at = |cx: f64, cy: f64| -> Vec<f64> {
        after
            .iter()
            .filter_map(|e| match &e.specific {
                EntityType::Circle(c)
                    if (c.center.x - cx).abs() < 1e-9 && (c.center.y - cy).abs() < 1e-9 =>
                {
                    Some(c.radius)
                }
                _ => None,
            })
            .collect()
    };
    assert_eq!(radius_at(50.0, 20.0), vec![4.0 - k / 2.0]);
    let mut ring = radius_at(10.0, 20.0);
    ring.sort_by(f64::total_cmp);
    assert!((ring[0] - (3.0 + k / 2.0)).abs() < 1e-12 && (ring[1] - (6.0 - k / 2.0)).abs() < 1e-12);

    // The stadium slot (LINE/ARC chain, one arc mirrored) became one LWPOLYLINE, narrower by k.
    let lw: Vec<Vec<(f64, f64, f64)>> = after
        .iter()
        .filter_map(|e| match &e.specific {
            EntityType::LwPolyline(p) if e.common.handle != plate_h => {
                assert_eq!(e.common.layer, "CUT");
                Some(p.vertices.iter().map(|v| (v.x, v.y, v.bulge)).collect())
            }
            _ => None,
        })
        .collect();
    assert_eq!(lw.len(), 2, "the slot and the four-line part");
    let bbox = |v: &[(f64, f64, f64)]| {
        v.iter()
            .fold((f64::MAX, f64::MAX, f64::MIN, f64::MIN), |b, p| {
                (b.0.min(p.0), b.1.min(p.1), b.2.max(p.0), b.3.max(p.1))
            })
    };
    let slot = lw.iter().find(|v| bbox(v).0 < 30.0).unwrap();
    let (x0, y0, x1, y1) = bbox(slot);
    assert!((y1 - y0 - (6.0 - k)).abs() < 1e-9 && (y0 - (17.0 + k / 2.0)).abs() < 1e-9);
    // The straight sides keep their length; the ends stay half circles, now of radius 3 − k/2.
    assert!(
        (x0 - 22.0).abs() < 1e-9 && (x1 - 38.0).abs() < 1e-9,
        "{slot:?}"
    );
    assert_eq!(
        slot.iter()
            .filter(|v| (v.2.abs() - 1.0).abs() < 1e-9)
            .count(),
        2,
        "{slot:?}"
    );
    // The part drawn as four loose LINEs grew by k/2 all round.
    let part = lw.iter().find(|v| bbox(v).0 > 60.0).unwrap();
    let (x0, y0, x1, y1) = bbox(part);
    assert!((x0 - (70.0 - k / 2.0)).abs() < 1e-9 && (x1 - (90.0 + k / 2.0)).abs() < 1e-9);
    assert!((y0 + k / 2.0).abs() < 1e-9 && (y1 - (20.0 + k / 2.0)).abs() < 1e-9);

    // The label, and the open slit, are unchanged; the pieces of the chains are gone.
    let texts: Vec<_> = after
        .iter()
        .filter_map(|e| match &e.specific {
            EntityType::Text(t) => Some((
                t.value.clone(),
                t.location.x,
                t.location.y,
                e.common.layer.clone(),
            )),
            _ => None,
        })
        .collect();
    assert_eq!(
        texts,
        vec![("PLATE 1".to_string(), 5.0, 46.0, "ENGRAVE".to_string())]
    );
    let lines: Vec<_> = after
        .iter()
        .filter_map(|e| match &e.specific {
            EntityType::Line(l) => Some((l.p1.x, l.p1.y, l.p2.x, l.p2.y)),
            _ => None,
        })
        .collect();
    assert_eq!(lines, vec![(45.0, 30.0, 55.0, 30.0)]);
    assert!(
        !after
            .iter()
            .any(|e| matches!(e.specific, EntityType::Arc(_)))
    );
}

#[test]
fn a_kerf_map_gives_each_part_its_own_kerf() {
    let (dir, input) = copy("box_generator.svg");
    // As a two-cell bed map (centres x = 50 and x = 150 mm) gives it: 150 µm up to the first
    // centre, +100 µm at the second, linear between.
    let field = |x_mm: f64, _y_mm: f64| 150.0 + 100.0 * ((x_mm - 50.0) / 100.0).clamp(0.0, 1.0);
    let output = dir.path().join("out.svg");
    let (bytes, summary) = dilate_file(
        &input,
        &KerfSource::Map(Arc::new(field)),
        &DilateOptions::default(),
    )
    .unwrap();
    std::fs::write(&output, bytes).unwrap();
    let [lo, hi] = summary.kerf_range_um.unwrap();
    assert!(
        (lo - 150.0).abs() < 1e-9,
        "side A lies left of the first centre: {lo}"
    );
    assert!(
        hi > 200.0 && hi < 230.0,
        "side B's centroid is near x = 120: {hi}"
    );
    let t = tree(&output);
    let outline = |g: &str| polys(all_paths(group(t.root(), g).unwrap())[0]).remove(0);
    let (fingers, _) = widths(&crossings_at_y(&outline("p-0"), 18.5));
    assert!(
        fingers
            .iter()
            .all(|w| (w - (6.0 + lo / 1000.0)).abs() < TOL_MM),
        "{fingers:?}"
    );
    let (_, slots) = widths(&crossings_at_y(&outline("p-1"), 58.5));
    assert!(
        slots
            .iter()
            .all(|w| (w - (6.0 - hi / 1000.0)).abs() < TOL_MM),
        "{slots:?}"
    );
}

fn plan(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

#[test]
fn parts_that_would_merge_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let input = plan(
        dir.path(),
        "close.svg",
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="50mm" height="50mm" viewBox="0 0 50 50">
  <rect id="left" x="5" y="5" width="10" height="10" fill="none" stroke="red" stroke-width="0.01"/>
  <rect id="right" x="15.15" y="5" width="10" height="10" fill="none" stroke="red" stroke-width="0.01"/>
</svg>"#,
    );
    let output = dir.path().join("out.svg");
    let e = dilate(&input, 200.0, &output).unwrap_err().to_string();
    assert!(
        e.contains("would merge") && e.contains("\"left\"") && e.contains("\"right\""),
        "{e}"
    );
    assert!(e.contains("close.svg"), "names the file: {e}");
    assert!(!output.exists());
    // 150 µm fits (the gap is exactly 150 µm: still touching, so refused), 100 µm does.
    assert!(dilate(&input, 150.0, &output).is_err());
    assert!(dilate(&input, 100.0, &output).is_ok());
}

#[test]
fn holes_of_a_part_that_meet_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let part = |holes: &str| {
        format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="60mm" height="60mm" viewBox="0 0 60 60">
  <rect id="panel" x="0" y="0" width="60" height="60" fill="none" stroke="red" stroke-width="0.01"/>
  {holes}
</svg>"#
        )
    };
    let hole = |id: &str, cx: f64, cy: f64, r: f64| {
        format!(
            r#"<circle id="{id}" cx="{cx}" cy="{cy}" r="{r}" fill="none" stroke="red" stroke-width="0.01"/>"#
        )
    };
    let cases = [
        // Copied in place: the same loop twice.
        (
            hole("first", 30.0, 30.0, 5.0) + &hole("copy", 30.0, 30.0, 5.0),
            "are the same loop drawn twice",
        ),
        // Moved by 50 µm: they cross.
        (
            hole("first", 30.0, 30.0, 5.0) + &hole("copy", 30.0, 30.05, 5.0),
            "cross or touch",
        ),
        // A smaller one overlapping a larger one.
        (
            hole("first", 30.0, 30.0, 5.0) + &hole("copy", 33.0, 30.0, 4.0),
            "cross or touch",
        ),
    ];
    let output = dir.path().join("out.svg");
    for (holes, what) in cases {
        let input = plan(dir.path(), "holes.svg", &part(&holes));
        let e = dilate(&input, 150.0, &output).unwrap_err().to_string();
        assert!(
            e.contains(what) && e.contains("\"first\"") && e.contains("\"copy\""),
            "{e}"
        );
        assert!(!output.exists());
    }
    // 50 µm apart, closer than the kerf: each shrinks into itself, and the web stays.
    let input = plan(
        dir.path(),
        "holes.svg",
        &part(&(hole("first", 30.0, 30.0, 5.0) + &hole("copy", 40.05, 30.0, 5.0))),
    );
    dilate(&input, 150.0, &output).unwrap();
    // Measured against the input read the same way (usvg draws circles as Béziers).
    let (t_in, t_out) = (tree(&input), tree(&output));
    for id in ["first", "copy"] {
        let a_in = area(&polys(path_by_id(t_in.root(), id))[0]).abs();
        let a_out = area(&polys(path_by_id(t_out.root(), id))[0]).abs();
        let shrunk = (4.925f64 / 5.0).powi(2);
        assert!((a_out / a_in - shrunk).abs() < 1e-5, "{id}: {a_in} {a_out}");
    }
}

#[test]
fn broken_and_unitless_files_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out_svg = dir.path().join("out.svg");
    let out_dxf = dir.path().join("out.dxf");
    let cases: Vec<(PathBuf, PathBuf, &str)> = vec![
        (
            plan(
                dir.path(),
                "broken.svg",
                "<svg xmlns=\"http://www.w3.org/2000/svg\"><path d=",
            ),
            out_svg.clone(),
            "not a readable SVG",
        ),
        (
            plan(dir.path(), "text.svg", "hello"),
            out_svg.clone(),
            "not a readable SVG",
        ),
        (
            plan(dir.path(), "html.svg", "<html><body/></html>"),
            out_svg.clone(),
            "not an SVG document",
        ),
        (
            plan(
                dir.path(),
                "px.svg",
                r#"<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100"><rect x="1" y="1" width="5" height="5" fill="none" stroke="red"/></svg>"#,
            ),
            out_svg.clone(),
            "unknown units",
        ),
        (
            plan(dir.path(), "garbage.dxf", "this is not a drawing\n"),
            out_dxf.clone(),
            "not a readable DXF",
        ),
        (
            dir.path().join("missing.svg"),
            out_svg.clone(),
            "cannot read",
        ),
    ];
    for (input, output, expected) in cases {
        let e = dilate(&input, 150.0, &output).unwrap_err().to_string();
        assert!(e.contains(expected), "{}: {e}", input.display());
        assert!(!output.exists());
    }
    // A DXF without $INSUNITS: unknown units, unless told.
    let text = std::fs::read_to_string(fixture("cad_plate.dxf")).unwrap();
    let unitless = text.replacen("$INSUNITS\r\n 70\r\n4", "$INSUNITS\r\n 70\r\n0", 1);
    assert_ne!(unitless, text);
    let input = plan(dir.path(), "unitless.dxf", &unitless);
    let e = dilate(&input, 150.0, &out_dxf).unwrap_err().to_string();
    assert!(e.contains("unknown units"), "{e}");
    let in_mm = DilateOptions {
        assume_units: Some(AssumedUnits::Mm),
        ..DilateOptions::default()
    };
    assert!(dilate_with(&input, 150.0, &out_dxf, &in_mm).is_ok());
}

#[test]
fn strict_refuses_open_paths() {
    let (dir, input) = copy("box_generator.svg");
    let output = dir.path().join("out.svg");
    let strict = DilateOptions {
        strict: true,
        ..DilateOptions::default()
    };
    let e = dilate_with(&input, 150.0, &output, &strict)
        .unwrap_err()
        .to_string();
    assert!(e.contains("--strict") && e.contains("100.000"), "{e}");
    assert!(e.contains("box_generator.svg"), "names the file: {e}");
    assert!(!output.exists());
}

#[test]
fn cut_rules_decide_what_is_dilated() {
    let (dir, input) = copy("box_generator.svg");
    let output = dir.path().join("out.svg");
    let max_width_mm = CutRules::default().max_width_mm;
    let rules = |colours: &[String], max_width_mm| DilateOptions {
        rules: CutRules::new(colours, max_width_mm, &[]).unwrap(),
        ..DilateOptions::default()
    };
    // Only blue lines are cuts: the two inner cuts; the black outlines pass through.
    let blue = rules(&["blue".into()], max_width_mm);
    let summary = dilate_with(&input, 150.0, &output, &blue).unwrap();
    assert_eq!(summary.contours_dilated, 2);
    assert!(summary.open_paths.is_empty());
    assert!(summary.passed_through.keys().any(|k| k.contains("#000000")));
    // Hairlines only: nothing here is thinner than 0.05 mm, so nothing is a cut: refused, and
    // the earlier output is left as it was (not replaced by one recording a compensation).
    let before = std::fs::read(&output).unwrap();
    let hairlines = rules(&[], 0.05);
    let e = dilate_with(&input, 150.0, &output, &hairlines).unwrap_err();
    assert!(e.to_string().contains("no closed cut contour"), "{e}");
    assert_eq!(std::fs::read(&output).unwrap(), before);
}
