//! Dilation's own cases: nesting, parts, joins, the problems found, a kerf per part.

use super::*;
use cavalier_contours::polyline::{PlineSource, PlineSourceMut};

fn rect(x0: f64, y0: f64, x1: f64, y1: f64, ccw: bool) -> Pline {
    let mut p = Pline::new_closed();
    let pts = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
    if ccw {
        for (x, y) in pts {
            p.add(x, y, 0.0);
        }
    } else {
        for (x, y) in pts.iter().rev() {
            p.add(*x, *y, 0.0);
        }
    }
    p
}

fn c(p: Pline, label: &str) -> Contour {
    Contour {
        pline: p,
        label: label.into(),
    }
}

/// A circle as two half-circle arcs, counter-clockwise.
fn circle(cx: f64, cy: f64, r: f64) -> Pline {
    let mut p = Pline::new_closed();
    p.add(cx - r, cy, 1.0);
    p.add(cx + r, cy, 1.0);
    p
}

/// A 60 mm square part with the two circle holes (x, y, r) given, named "a" and "b".
fn square_with_holes(a: (f64, f64, f64), b: (f64, f64, f64)) -> Vec<Contour> {
    vec![
        c(rect(0.0, 0.0, 60.0, 60.0, true), "square"),
        c(circle(a.0, a.1, a.2), "a"),
        c(circle(b.0, b.1, b.2), "b"),
    ]
}

#[test]
fn a_hole_drawn_twice_is_an_error() {
    let contours = square_with_holes((30.0, 30.0, 5.0), (30.0, 30.0, 5.0));
    let e = dilate(&contours, &KerfSource::Uniform(150.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("a and b are the same loop drawn twice"), "{e}");
    assert!(e.contains("delete one"), "{e}");
    // Drawn the other way round, it is still the same loop.
    let mut contours = contours;
    contours[2].pline.invert_direction_mut();
    let e = dilate(&contours, &KerfSource::Uniform(150.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("a and b are the same loop drawn twice"), "{e}");
}

#[test]
fn holes_of_a_part_that_cross_are_an_error() {
    // Equal areas: nesting compares neither with the other.
    let nearly_twice = square_with_holes((30.0, 30.0, 5.0), (30.0, 30.05, 5.0));
    // A smaller hole sticking out of the larger one's box.
    let overlapping = square_with_holes((30.0, 30.0, 5.0), (33.0, 30.0, 4.0));
    for contours in [nearly_twice, overlapping] {
        let e = dilate(&contours, &KerfSource::Uniform(150.0))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the holes a and b of the part square cross or touch at"),
            "{e}"
        );
        assert!(e.contains("move them apart"), "{e}");
    }
}

#[test]
fn holes_closer_than_the_kerf_shrink_apart_and_dilate() {
    // 50 µm apart with a 150 µm kerf: each hole shrinks into itself, away from the other.
    let contours = square_with_holes((30.0, 30.0, 5.0), (40.05, 30.0, 5.0));
    let d = dilate(&contours, &KerfSource::Uniform(150.0)).unwrap();
    assert_eq!(d.parts[0].holes, vec![1, 2]);
    let r = 5.0 - 0.075;
    for h in [1, 2] {
        assert!((d.contours[h].area() - std::f64::consts::PI * r * r).abs() < 1e-9);
    }
}

#[test]
fn holes_that_grow_into_each_other_when_a_compensation_is_undone_are_an_error() {
    // Drawn 200 µm outside their parts (a burn of 0.2 mm), recompensated for a 100 µm kerf:
    // every hole grows by 150 µm, so two holes 200 µm apart would overlap.
    let contours = square_with_holes((30.0, 30.0, 5.0), (40.2, 30.0, 5.0));
    let how = Offsetting::Recompensate { burn_mm: 0.2 };
    let e = dilate_with(&contours, &KerfSource::Uniform(100.0), how)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the hole a and the hole b of the part square would overlap near"),
        "{e}"
    );
    // 400 µm apart they still fit.
    let contours = square_with_holes((30.0, 30.0, 5.0), (40.4, 30.0, 5.0));
    assert!(dilate_with(&contours, &KerfSource::Uniform(100.0), how).is_ok());
    // The outline shrinks as much: 200 µm from a hole, they would overlap too.
    let contours = square_with_holes((5.2, 30.0, 5.0), (30.0, 30.0, 5.0));
    let e = dilate_with(&contours, &KerfSource::Uniform(100.0), how)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("the outline square and the hole a of the part square would overlap"),
        "{e}"
    );
    // Dilating instead, the same part is fine: both move away from the web.
    assert!(dilate(&contours, &KerfSource::Uniform(100.0)).is_ok());
}

#[test]
fn outer_grows_hole_shrinks_island_grows_with_orientation_kept() {
    let contours = vec![
        c(rect(0.0, 0.0, 100.0, 100.0, false), "outer"),
        c(rect(10.0, 10.0, 90.0, 90.0, true), "hole"),
        c(rect(40.0, 40.0, 60.0, 60.0, false), "island"),
    ];
    let d = dilate(&contours, &KerfSource::Uniform(200.0)).unwrap();
    assert_eq!(d.roles, vec![Role::Outer, Role::Hole, Role::Outer]);
    assert_eq!(d.parts.len(), 2);
    assert_eq!(d.parts[0].holes, vec![1]);
    // Outer: 100.2 × 100.2 with four quarter-round corners of radius 0.1.
    let r: f64 = 0.1;
    let expected_outer = 100.0 * 100.0 + 4.0 * 100.0 * r + std::f64::consts::PI * r * r;
    assert!((d.contours[0].area().abs() - expected_outer).abs() < 1e-9);
    // Hole: 79.8 × 79.8, sharp corners.
    assert!((d.contours[1].area().abs() - 79.8 * 79.8).abs() < 1e-9);
    // Orientation kept.
    assert!(d.contours[0].area() < 0.0 && d.contours[1].area() > 0.0 && d.contours[2].area() < 0.0);
    // The part's centroid: the middle.
    assert!((d.parts[0].centroid_mm[0] - 50.0).abs() < 1e-9);
}

#[test]
fn parts_closer_than_the_kerf_merge_and_are_reported() {
    let contours = vec![
        c(rect(0.0, 0.0, 10.0, 10.0, true), "a"),
        c(rect(10.15, 0.0, 20.0, 10.0, true), "b"),
    ];
    let e = dilate(&contours, &KerfSource::Uniform(200.0))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("would merge") && e.contains("a") && e.contains("b"),
        "{e}"
    );
    assert!(dilate(&contours, &KerfSource::Uniform(100.0)).is_ok());
}

#[test]
fn a_hole_narrower_than_the_kerf_is_an_error() {
    let contours = vec![
        c(rect(0.0, 0.0, 10.0, 10.0, true), "part"),
        c(rect(2.0, 2.0, 2.15, 8.0, true), "slit"),
    ];
    let e = dilate(&contours, &KerfSource::Uniform(200.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("slit") && e.contains("vanish"), "{e}");
}

#[test]
fn crossing_contours_are_an_error() {
    let contours = vec![
        c(rect(0.0, 0.0, 10.0, 10.0, true), "big"),
        c(rect(5.0, 5.0, 10.0, 12.0, true), "sticks-out"),
    ];
    let e = dilate(&contours, &KerfSource::Uniform(100.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("would merge"), "{e}");
    // A square inside an L's bounding box, crossing the L.
    let mut l = Pline::new_closed();
    for (x, y) in [
        (0.0, 0.0),
        (10.0, 0.0),
        (10.0, 5.0),
        (5.0, 5.0),
        (5.0, 10.0),
        (0.0, 10.0),
    ] {
        l.add(x, y, 0.0);
    }
    let contours = vec![c(l, "L"), c(rect(3.0, 3.0, 7.0, 7.0, true), "square")];
    let e = dilate(&contours, &KerfSource::Uniform(100.0))
        .unwrap_err()
        .to_string();
    assert!(e.contains("square and L cross"), "{e}");
}

#[test]
fn releasing_the_drawn_contours_frees_them_and_dilates_the_same() {
    let drawn = vec![
        c(rect(0.0, 0.0, 100.0, 100.0, false), "outer"),
        c(rect(10.0, 10.0, 90.0, 90.0, true), "hole"),
    ];
    let lent = dilate(&drawn, &KerfSource::Uniform(200.0)).unwrap();
    let mut given = drawn.clone();
    let released = dilate_releasing_drawn(
        &mut given,
        &KerfSource::Uniform(200.0),
        Offsetting::Dilate,
        &Progress::default(),
    )
    .unwrap();
    assert_eq!(released.contours.len(), lent.contours.len());
    for (a, b) in released.contours.iter().zip(&lent.contours) {
        assert_eq!(a.vertex_data, b.vertex_data);
    }
    assert_eq!(released.parts, lent.parts);
    // The drawn geometry is gone; the labels stay for messages.
    assert!(given.iter().all(|c| c.pline.vertex_count() == 0));
    let labels: Vec<&str> = given.iter().map(|c| c.label.as_str()).collect();
    assert_eq!(labels, ["outer", "hole"]);
}

#[test]
fn a_map_gives_each_part_the_kerf_at_its_centroid() {
    // 120 µm left of x = 100 mm, 160 µm right of it.
    let field = |x_mm: f64, _y_mm: f64| if x_mm < 100.0 { 120.0 } else { 160.0 };
    let contours = vec![
        c(rect(40.0, 40.0, 60.0, 60.0, true), "left"),
        c(rect(140.0, 40.0, 160.0, 60.0, true), "right"),
    ];
    let d = dilate(&contours, &KerfSource::Map(Arc::new(field))).unwrap();
    assert!((d.parts[0].kerf_um - 120.0).abs() < 1e-9);
    assert!((d.parts[1].kerf_um - 160.0).abs() < 1e-9);
}
