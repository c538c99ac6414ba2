//! DXF curves against their true shapes: `ELLIPSE`s, and `CIRCLE`s, `ARC` chains and bulged
//! `LWPOLYLINE`s inside blocks inserted with unequal x and y scales (ellipses then), dilated and
//! measured against the exact parallel curve (see `analytic`) as outlines and holes, 1 mm to
//! 500 mm, aspect ratios up to 20:1, turned all round; and a closed `SPLINE`'s biarcs (read at
//! no kerf) against the spline evaluated independently. Every point within the curve tolerance
//! (0.05 µm), as docs/plans.md says.
//!
//! Rotations and scales are drawn from a seeded generator ([`SEED`], developed against;
//! `KERFMETER_CURVE_SEED=n` draws others); `--nocapture` prints the worst deviation by size.

mod analytic;

use std::f64::consts::TAU;

use analytic::{Ellipse, P, Report, Rng, Sampled, deviation};
use cavalier_contours::polyline::PlineSource;
use dxf::entities::{Arc, Circle, Entity, EntityType, Insert, LwPolyline, Spline};
use dxf::enums::{AcadVersion, Units};
use dxf::{Drawing, LwPolylineVertex, Point, Vector};
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::geom::{CURVE_TOLERANCE_MM, Pline};
use kerfmeter_plan::{DilateOptions, dilate_file_cuts};

/// How far a dilated contour may stray from the exact parallel curve, µm (see the module doc).
const TOLERANCE_UM: f64 = CURVE_TOLERANCE_MM * 1e3;

/// The generator's seed the cases were developed against.
const SEED: u64 = 40;

/// Major diameters, mm, and aspect ratios of the grid.
const SIZES_MM: [f64; 5] = [1.0, 5.0, 20.0, 100.0, 500.0];
const ASPECTS: [f64; 3] = [1.5, 4.0, 20.0];

/// What a case draws.
#[derive(Debug, Clone, Copy)]
enum Shape {
    /// An `ELLIPSE` in model space: its major axis (a vector from the centre) and ratio.
    Ellipse { major: P, ratio: f64 },
    /// A unit circle in a block (a `CIRCLE`, two `ARC`s end to end, or an `LWPOLYLINE` of two
    /// half-circle bulges) inserted with scales `sx`, `sy` and turned `degrees`.
    Inserted {
        drawn: Drawn,
        sx: f64,
        sy: f64,
        degrees: f64,
    },
}

/// How a block draws its unit circle.
#[derive(Debug, Clone, Copy)]
enum Drawn {
    Circle,
    Arcs,
    Bulges,
}

/// One case: a shape centred at `centre`, a hole (in a square outline) or not, the kerf.
#[derive(Debug, Clone, Copy)]
struct Case {
    shape: Shape,
    centre: P,
    hole: bool,
    kerf_um: f64,
}

/// A red entity (ACI 1: a cut).
fn red(e: EntityType) -> Entity {
    let mut e = Entity::new(e);
    e.common.color = dxf::Color::from_index(1);
    e
}

impl Case {
    /// The true curve.
    fn ellipse(&self) -> Ellipse {
        match self.shape {
            Shape::Ellipse { major, ratio } => {
                let minor = (-major.1 * ratio, major.0 * ratio);
                Ellipse::from_map(self.centre, [[major.0, minor.0], [major.1, minor.1]])
            }
            Shape::Inserted {
                sx, sy, degrees, ..
            } => {
                let (s, c) = degrees.to_radians().sin_cos();
                Ellipse::from_map(self.centre, [[c * sx, -s * sy], [s * sx, c * sy]])
            }
        }
    }

    /// The drawing: the shape, in a square outline when it is a hole.
    fn drawing(&self) -> Drawing {
        let mut d = Drawing::new();
        d.header.version = AcadVersion::R2000;
        d.header.default_drawing_units = Units::Millimeters;
        let at = Point::new(self.centre.0, self.centre.1, 0.0);
        match self.shape {
            Shape::Ellipse { major, ratio } => {
                let e = dxf::entities::Ellipse {
                    center: at,
                    major_axis: Vector::new(major.0, major.1, 0.0),
                    minor_axis_ratio: ratio,
                    ..Default::default()
                };
                d.add_entity(red(EntityType::Ellipse(e)));
            }
            Shape::Inserted {
                drawn,
                sx,
                sy,
                degrees,
            } => {
                d.add_block(dxf::Block {
                    name: "SHAPE".into(),
                    entities: unit_circle(drawn),
                    ..Default::default()
                });
                d.add_entity(red(EntityType::Insert(Insert {
                    name: "SHAPE".into(),
                    location: at,
                    x_scale_factor: sx,
                    y_scale_factor: sy,
                    rotation: degrees,
                    ..Default::default()
                })));
            }
        }
        if self.hole {
            let reach = 2.0 * self.ellipse().major + 2.0;
            let (x, y) = self.centre;
            let mut square = LwPolyline::default();
            for (dx, dy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                square.vertices.push(LwPolylineVertex {
                    x: x + dx * reach,
                    y: y + dy * reach,
                    ..Default::default()
                });
            }
            square.set_is_closed(true);
            d.add_entity(red(EntityType::LwPolyline(square)));
        }
        d
    }
}

/// A unit circle about the block's origin, drawn as `drawn` says, in the block's colour.
fn unit_circle(drawn: Drawn) -> Vec<Entity> {
    let by_block = |e: EntityType| {
        let mut e = Entity::new(e);
        e.common.color = dxf::Color::by_block();
        e
    };
    let origin = Point::origin();
    match drawn {
        Drawn::Circle => vec![by_block(EntityType::Circle(Circle::new(origin, 1.0)))],
        Drawn::Arcs => vec![
            by_block(EntityType::Arc(Arc::new(origin.clone(), 1.0, 30.0, 250.0))),
            by_block(EntityType::Arc(Arc::new(origin, 1.0, 250.0, 390.0))),
        ],
        Drawn::Bulges => {
            let mut p = LwPolyline::default();
            for x in [1.0, -1.0] {
                p.vertices.push(LwPolylineVertex {
                    x,
                    bulge: 1.0,
                    ..Default::default()
                });
            }
            p.set_is_closed(true);
            vec![by_block(EntityType::LwPolyline(p))]
        }
    }
}

/// Dilate `drawing` by `kerf_um` and give back its contours (DXF's coordinates, mm).
fn dilated(drawing: &Drawing, kerf_um: f64, dir: &std::path::Path) -> Vec<Pline> {
    let file = dir.join("plan.dxf");
    drawing
        .save_file(&file)
        .expect("the crate saves a new drawing");
    let kerf = KerfSource::Uniform(kerf_um);
    let (_, cuts, _) =
        dilate_file_cuts(&file, &kerf, &DilateOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    cuts.into_iter().map(|c| c.pline).collect()
}

/// The smallest contour (the shape, not the square around a hole).
fn smallest(contours: Vec<Pline>) -> Pline {
    (contours.into_iter())
        .min_by(|a, b| a.area().abs().total_cmp(&b.area().abs()))
        .expect("a contour")
}

/// Run `cases` and check them.
fn run(title: &str, cases: Vec<Case>) {
    let dir = tempfile::tempdir().unwrap();
    let mut report = Report::new(TOLERANCE_UM);
    for case in cases {
        let e = case.ellipse();
        if case.hole && 2.0 * e.minor <= 2.0 * case.kerf_um / 1e3 {
            // Narrower than the kerf: refused.
            continue;
        }
        let contour = smallest(dilated(&case.drawing(), case.kerf_um, dir.path()));
        let dev = deviation(&e, &contour, case.kerf_um / 2e3, case.hole);
        report.add(2.0 * e.major, format!("{case:?}"), dev);
    }
    report.check(title);
}

#[test]
fn ellipse_entities_are_dilated_from_the_true_curve() {
    let mut rng = Rng::new(SEED);
    let mut cases = Vec::new();
    for (size, aspect) in SIZES_MM.into_iter().flat_map(|s| ASPECTS.map(|a| (s, a))) {
        for hole in [false, true] {
            for _ in 0..3 {
                let (s, c) = rng.range(0.0, TAU).sin_cos();
                let a = size / 2.0;
                cases.push(Case {
                    shape: Shape::Ellipse {
                        major: (a * c, a * s),
                        ratio: 1.0 / aspect,
                    },
                    centre: (rng.range(-300.0, 300.0), rng.range(-300.0, 300.0)),
                    hole,
                    kerf_um: 150.0,
                });
            }
        }
    }
    run("ELLIPSE", cases);
}

#[test]
fn circles_arcs_and_bulges_under_unequal_insert_scales_are_dilated_from_the_true_curve() {
    let mut rng = Rng::new(SEED);
    let mut cases = Vec::new();
    for (size, aspect) in SIZES_MM.into_iter().flat_map(|s| ASPECTS.map(|a| (s, a))) {
        for (hole, drawn) in [
            (false, Drawn::Circle),
            (true, Drawn::Arcs),
            (false, Drawn::Bulges),
            (true, Drawn::Circle),
        ] {
            let (sx, sy) = (size / 2.0, size / 2.0 / aspect);
            // Either scale the larger, and a mirror now and then.
            let (sx, sy) = if rng.next() < 0.5 { (sx, sy) } else { (sy, sx) };
            let sx = if rng.next() < 0.25 { -sx } else { sx };
            cases.push(Case {
                shape: Shape::Inserted {
                    drawn,
                    sx,
                    sy,
                    degrees: rng.range(0.0, 360.0),
                },
                centre: (rng.range(-300.0, 300.0), rng.range(-300.0, 300.0)),
                hole,
                kerf_um: 150.0,
            });
        }
    }
    run(
        "CIRCLE, ARC and LWPOLYLINE in an unequally scaled INSERT",
        cases,
    );
}

/// A point of the cubic B-spline with `knots` and `control` points at `t` (de Boor).
fn de_boor(knots: &[f64], control: &[P], t: f64) -> P {
    let degree = 3;
    let k = (degree..control.len())
        .rfind(|&i| knots[i] <= t)
        .unwrap_or(degree);
    let mut d: Vec<P> = (0..=degree).map(|j| control[j + k - degree]).collect();
    for r in 1..=degree {
        for j in (r..=degree).rev() {
            let i = j + k - degree;
            let alpha = (t - knots[i]) / (knots[i + 1 + degree - r] - knots[i]);
            d[j] = (
                (1.0 - alpha) * d[j - 1].0 + alpha * d[j].0,
                (1.0 - alpha) * d[j - 1].1 + alpha * d[j].1,
            );
        }
    }
    d[degree]
}

/// A drawing of one closed cubic `SPLINE`.
fn spline_drawing(control: &[P], knots: &[f64]) -> Drawing {
    let mut spline = Spline {
        degree_of_curve: 3,
        knot_values: knots.to_vec(),
        control_points: control.iter().map(|p| Point::new(p.0, p.1, 0.0)).collect(),
        ..Default::default()
    };
    spline.set_is_closed(true);
    let mut d = Drawing::new();
    d.header.version = AcadVersion::R2000;
    d.header.default_drawing_units = Units::Millimeters;
    d.add_entity(red(EntityType::Spline(spline)));
    d
}

#[test]
fn spline_biarcs_are_within_the_curve_tolerance() {
    let mut rng = Rng::new(SEED);
    let mut report = Report::new(TOLERANCE_UM);
    let dir = tempfile::tempdir().unwrap();
    for size in SIZES_MM {
        for n in [6, 9] {
            // A clamped cubic B-spline whose ends meet: control points round a circle.
            let r = size / 2.0;
            let mut control: Vec<P> = (0..n)
                .map(|k| {
                    let angle = TAU * k as f64 / n as f64;
                    let radius = r * rng.range(0.6, 1.0);
                    (radius * angle.cos(), radius * angle.sin())
                })
                .collect();
            control.push(control[0]);
            let spans = control.len() - 3;
            let mut knots = vec![0.0; 4];
            knots.extend((1..spans).map(|k| k as f64 / spans as f64));
            knots.extend([1.0; 4]);
            let d = spline_drawing(&control, &knots);
            let contour = smallest(dilated(&d, 0.0, dir.path()));
            let samples = 200_000;
            let points = (0..samples)
                .map(|k| de_boor(&knots, &control, k as f64 / samples as f64))
                .collect();
            let what = format!("{n} control points round {size} mm");
            report.add(
                size,
                what,
                deviation(&Sampled::new(points), &contour, 0.0, false),
            );
        }
    }
    report.check("SPLINE");
}
