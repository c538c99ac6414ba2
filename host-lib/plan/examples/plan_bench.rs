//! The plan benchmark's helper (`cargo xtask bench-plan` runs it; it is not a test):
//!
//! * `plan_bench generate --parts N --out-dir DIR` writes a plan of N box-joint parts as
//!   `plan-N.svg`, `plan-N.dxf` and `plan-N.wkt`: each part a 40 × 40 mm outline with seven
//!   fingers a side (116 vertices) and three holes, a slot, a round hole and a rounded window, on
//!   a square grid of 50 mm pitch filled row by row: 4·N closed contours.
//!   - SVG: one `<g transform="translate(…)">` per part holding a `<path>` (outline), a `<path>`
//!     (slot), a `<circle>` and a `<rect rx>`, the cut style inherited from the group; no ids.
//!   - DXF (R2000, mm): the outline a closed `LWPOLYLINE`, the slot four `LINE`s, the hole a
//!     `CIRCLE`, the window a chain of four `LINE`s and four `ARC`s (so chains are joined,
//!     replaced and removed).
//!   - WKT: one polygon with holes per part, arcs flattened to 8 segments per quarter circle,
//!     for GEOS to buffer.
//! * `plan_bench phases FILE --kerf-um K` dilates FILE in this process and prints, as one JSON
//!   object, the seconds spent reading (from the file to contours), in the kernel (nesting,
//!   offsets, checks) and writing (the dilated document's bytes), from the stages the library
//!   reports through [`kerfmeter_plan::progress`].

use std::f64::consts::FRAC_PI_2;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use dxf::entities::{Arc as DxfArc, Circle, Entity, EntityType, Line, LwPolyline};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, LwPolylineVertex, Point};
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::progress::{Progress, Stage};
use kerfmeter_plan::{DilateOptions, dilate_file};

#[path = "../benches/common/finger_part.rs"]
mod finger_part;
use finger_part::{HOLE, SLOT, WINDOW, outline};

/// Distance between parts, mm.
const PITCH_MM: f64 = 50.0;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("generate") => generate(&args[1..]),
        Some("phases") => phases(&args[1..]),
        _ => Err(
            "usage: plan_bench generate --parts N --out-dir DIR | phases FILE --kerf-um K".into(),
        ),
    };
    if let Err(e) = result {
        eprintln!("plan_bench: {e}");
        std::process::exit(2);
    }
}

/// The value after `--name` in `args`.
fn flag<'a>(args: &'a [String], name: &str) -> Result<&'a str, String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
        .ok_or_else(|| format!("{name} is missing"))
}

fn generate(args: &[String]) -> Result<(), String> {
    let parts: usize = flag(args, "--parts")?
        .parse()
        .map_err(|e| format!("--parts: {e}"))?;
    if parts == 0 {
        return Err("--parts must be at least 1".into());
    }
    let side = parts.isqrt() + usize::from(parts.isqrt().pow(2) < parts);
    let dir = PathBuf::from(flag(args, "--out-dir")?);
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let origins: Vec<(f64, f64)> = (0..parts)
        .map(|k| {
            let (i, j) = (k % side, k / side);
            (i as f64 * PITCH_MM + 5.0, j as f64 * PITCH_MM + 5.0)
        })
        .collect();
    let write = |ext: &str, bytes: &[u8]| {
        std::fs::write(dir.join(format!("plan-{parts}.{ext}")), bytes).map_err(|e| e.to_string())
    };
    write("svg", svg(side, &origins).as_bytes())?;
    write("dxf", &dxf(&origins)?)?;
    write("wkt", wkt(&origins).as_bytes())?;
    Ok(())
}

fn svg(side: usize, origins: &[(f64, f64)]) -> String {
    let page = side as f64 * PITCH_MM + 10.0;
    let mut s = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{page}mm\" height=\"{page}mm\" viewBox=\"0 0 {page} {page}\">\n"
    );
    let mut outline_d = String::new();
    for (k, (x, y)) in outline().into_iter().enumerate() {
        let _ = write!(outline_d, "{}{x} {y} ", if k == 0 { "M" } else { "L" });
    }
    outline_d.push('Z');
    let ((cx, cy), r) = HOLE;
    let ((wx, wy), (ww, wh), wr) = WINDOW;
    for (x, y) in origins {
        let _ = write!(
            s,
            "  <g transform=\"translate({x} {y})\" fill=\"none\" stroke=\"#ff0000\" stroke-width=\"0.1\">\n    <path d=\"{outline_d}\"/>\n    <path d=\"M{} {} H{} V{} H{} Z\"/>\n    <circle cx=\"{cx}\" cy=\"{cy}\" r=\"{r}\"/>\n    <rect x=\"{wx}\" y=\"{wy}\" width=\"{ww}\" height=\"{wh}\" rx=\"{wr}\"/>\n  </g>\n",
            SLOT[0].0, SLOT[0].1, SLOT[1].0, SLOT[2].1, SLOT[3].0
        );
    }
    s.push_str("</svg>\n");
    s
}

/// A red entity.
fn red(specific: EntityType) -> Entity {
    let mut e = Entity::new(specific);
    e.common.color = dxf::Color::from_index(1);
    e
}

fn line(a: (f64, f64), b: (f64, f64)) -> Entity {
    red(EntityType::Line(Line::new(
        Point::new(a.0, a.1, 0.0),
        Point::new(b.0, b.1, 0.0),
    )))
}

fn dxf(origins: &[(f64, f64)]) -> Result<Vec<u8>, String> {
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2000;
    d.header.default_drawing_units = Units::Millimeters;
    let shape = outline();
    let ((cx, cy), r) = HOLE;
    let ((wx, wy), (ww, wh), wr) = WINDOW;
    for &(x, y) in origins {
        let mut lw = LwPolyline {
            vertices: shape
                .iter()
                .map(|&(px, py)| LwPolylineVertex {
                    x: x + px,
                    y: y + py,
                    ..LwPolylineVertex::default()
                })
                .collect(),
            ..LwPolyline::default()
        };
        lw.set_is_closed(true);
        d.add_entity(red(EntityType::LwPolyline(lw)));
        for k in 0..4 {
            let (a, b) = (SLOT[k], SLOT[(k + 1) % 4]);
            d.add_entity(line((x + a.0, y + a.1), (x + b.0, y + b.1)));
        }
        d.add_entity(red(EntityType::Circle(Circle::new(
            Point::new(x + cx, y + cy, 0.0),
            r,
        ))));
        // The window: straight sides between the corner arcs, counter-clockwise.
        let (x0, y0, x1, y1) = (x + wx, y + wy, x + wx + ww, y + wy + wh);
        d.add_entity(line((x0 + wr, y0), (x1 - wr, y0)));
        d.add_entity(line((x1, y0 + wr), (x1, y1 - wr)));
        d.add_entity(line((x1 - wr, y1), (x0 + wr, y1)));
        d.add_entity(line((x0, y1 - wr), (x0, y0 + wr)));
        for (c, start) in [
            ((x1 - wr, y0 + wr), 270.0),
            ((x1 - wr, y1 - wr), 0.0),
            ((x0 + wr, y1 - wr), 90.0),
            ((x0 + wr, y0 + wr), 180.0),
        ] {
            d.add_entity(red(EntityType::Arc(DxfArc::new(
                Point::new(c.0, c.1, 0.0),
                wr,
                start,
                start + 90.0,
            ))));
        }
    }
    let mut out = Vec::new();
    d.save(&mut out).map_err(|e| e.to_string())?;
    Ok(out)
}

/// A closed ring as WKT coordinates.
fn ring(pts: &[(f64, f64)], s: &mut String) {
    s.push('(');
    for (x, y) in pts.iter().chain(pts.first()) {
        let _ = write!(s, "{x} {y},");
    }
    s.pop();
    s.push(')');
}

/// `n` points of the arc around `c` of radius `r` from angle `a0` over a quarter turn.
fn quarter(c: (f64, f64), r: f64, a0: f64, n: usize, pts: &mut Vec<(f64, f64)>) {
    for k in 0..n {
        let a = a0 + FRAC_PI_2 * k as f64 / n as f64;
        pts.push((c.0 + r * a.cos(), c.1 + r * a.sin()));
    }
}

fn wkt(origins: &[(f64, f64)]) -> String {
    let shape = outline();
    let ((cx, cy), r) = HOLE;
    let ((wx, wy), (ww, wh), wr) = WINDOW;
    let mut s = String::new();
    for &(x, y) in origins {
        let at = |p: &(f64, f64)| (x + p.0, y + p.1);
        s.push_str("POLYGON(");
        ring(&shape.iter().map(at).collect::<Vec<_>>(), &mut s);
        s.push(',');
        ring(&SLOT.iter().map(at).collect::<Vec<_>>(), &mut s);
        s.push(',');
        let mut hole = Vec::new();
        for q in 0..4 {
            quarter((x + cx, y + cy), r, FRAC_PI_2 * q as f64, 8, &mut hole);
        }
        ring(&hole, &mut s);
        s.push(',');
        let (x0, y0, x1, y1) = (x + wx + wr, y + wy + wr, x + wx + ww - wr, y + wy + wh - wr);
        let mut window = Vec::new();
        for (q, c) in [(x1, y0), (x1, y1), (x0, y1), (x0, y0)]
            .into_iter()
            .enumerate()
        {
            quarter(c, wr, FRAC_PI_2 * (q as f64 - 1.0), 8, &mut window);
            let end = FRAC_PI_2 * q as f64;
            window.push((c.0 + wr * end.cos(), c.1 + wr * end.sin()));
        }
        ring(&window, &mut s);
        s.push_str(")\n");
    }
    s
}

/// This process's peak resident set so far (VmHWM), MB; 0 where /proc does not say.
fn peak_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(0.0, |kb| kb * 1024.0 / 1e6)
}

fn phases(args: &[String]) -> Result<(), String> {
    let file = Path::new(args.first().ok_or("phases: FILE is missing")?);
    let kerf_um: f64 = flag(args, "--kerf-um")?
        .parse()
        .map_err(|e| format!("--kerf-um: {e}"))?;
    // When each stage first started.
    let starts: Arc<Mutex<Vec<(Stage, Instant)>>> = Arc::default();
    let seen = Arc::clone(&starts);
    let options = DilateOptions {
        progress: Progress::new(move |stage, done, _| {
            let mut s = seen.lock().expect("not poisoned");
            if done == 0 && !s.iter().any(|(st, _)| *st == stage) {
                s.push((stage, Instant::now()));
                eprintln!("{stage}: peak so far {:.1} MB", peak_mb());
            }
        }),
        ..DilateOptions::default()
    };
    let t0 = Instant::now();
    let (bytes, summary) =
        dilate_file(file, &KerfSource::Uniform(kerf_um), &options).map_err(|e| e.to_string())?;
    let t_end = Instant::now();
    eprintln!("done: peak {:.1} MB", peak_mb());
    let starts = starts.lock().expect("not poisoned");
    let at = |stage| {
        starts
            .iter()
            .find(|(s, _)| *s == stage)
            .map(|(_, t)| *t)
            .ok_or(format!("the {stage} stage was not reported"))
    };
    let (dilating, writing) = (at(Stage::Dilating)?, at(Stage::Writing)?);
    println!(
        "{{\"read_s\": {}, \"kernel_s\": {}, \"write_s\": {}, \"contours\": {}, \"output_bytes\": {}}}",
        (dilating - t0).as_secs_f64(),
        (writing - dilating).as_secs_f64(),
        (t_end - writing).as_secs_f64(),
        summary.contours_dilated,
        bytes.len()
    );
    Ok(())
}
