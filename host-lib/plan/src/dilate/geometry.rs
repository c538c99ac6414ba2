//! The small geometric questions the checks ask of contours: where two cross, whether a point
//! is inside one, their bounding boxes and a spatial index of them; and a point named in mm for
//! the messages.

use cavalier_contours::polyline::PlineSource;
use cavalier_contours::static_aabb2d_index::{StaticAABB2DIndex, StaticAABB2DIndexBuilder};

use crate::geom::{Pline, V2, v2};

pub(super) fn at(p: V2) -> String {
    format!("({:.3}, {:.3}) mm", p.x, p.y)
}

pub(super) fn first_point(p: &Pline) -> V2 {
    let v = p.at(0);
    v2(v.x, v.y)
}

/// A point where two polylines cross or touch, if they do.
pub(super) fn crossing(a: &Pline, b: &Pline) -> Option<V2> {
    let found = a.find_intersects(b);
    if let Some(i) = found.basic_intersects.first() {
        return Some(i.point);
    }
    found.overlapping_intersects.first().map(|o| o.point1)
}

pub(super) fn inside(p: &Pline, q: V2) -> bool {
    p.winding_number(q) != 0
}

#[derive(Clone, Copy)]
pub(super) struct Bbox {
    pub(super) min: V2,
    pub(super) max: V2,
}

impl Bbox {
    pub(super) fn of(p: &Pline) -> Bbox {
        let e = p.extents().expect("a contour has vertices");
        Bbox {
            min: v2(e.min_x, e.min_y),
            max: v2(e.max_x, e.max_y),
        }
    }

    pub(super) fn contains(&self, o: &Bbox, eps: f64) -> bool {
        self.min.x <= o.min.x + eps
            && self.min.y <= o.min.y + eps
            && self.max.x >= o.max.x - eps
            && self.max.y >= o.max.y - eps
    }
}

pub(super) fn index_of(boxes: &[Bbox]) -> Option<StaticAABB2DIndex<f64>> {
    if boxes.is_empty() {
        return None;
    }
    let mut b = StaticAABB2DIndexBuilder::new(boxes.len());
    for x in boxes {
        b.add(x.min.x, x.min.y, x.max.x, x.max.y);
    }
    b.build().ok()
}
