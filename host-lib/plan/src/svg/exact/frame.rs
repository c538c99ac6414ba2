//! An element's map to document mm in double precision, read from the source.
//!
//! usvg holds every transform in single precision: composed, the map of an element to the page
//! is off by up to about 10⁻⁷ of the distance from the origin (0.05 µm on a 500 mm page), which
//! would be most of an exact curve's error. Where the source says the map simply — the root's
//! `viewBox` (with its `preserveAspectRatio`) and size, and the `transform` attributes of the
//! element and of the groups (`<g>`, `<a>`) it lies in — it is composed here in double
//! precision, as usvg composes it. Anything else on the way (a `<use>`, a nested `<svg>`, a
//! `<symbol>`, a `<switch>`, a `transform-origin`, a transform set in CSS, a root `transform`)
//! leaves the element to usvg's map, and so does a map that does not agree with usvg's to its
//! single precision ([`agrees`]).

use std::str::FromStr;

use roxmltree::Node;
use svgtypes::{Align, AspectRatio, Length, Transform, ViewBox};

use crate::geom::Affine;

/// The map of `node` (not reached through a `<use>`) to document mm, `mm_per_px` being usvg's
/// pixel (see the parent module), when the source says it simply (see the module doc).
pub(super) fn to_doc(node: Node, mm_per_px: f64) -> Option<Affine> {
    let mut map = own_transform(node)?;
    let mut parent = node.parent_element()?;
    while parent.parent_element().is_some() {
        if !matches!(parent.tag_name().name(), "g" | "a") {
            return None;
        }
        map = own_transform(parent)?.then_after(&map);
        parent = parent.parent_element()?;
    }
    let root = root_map(parent)?;
    Some(Affine::scale(mm_per_px).then_after(&root.then_after(&map)))
}

/// Whether `exact` is `usvg`'s map to its single precision (each coefficient within 10⁻⁶ of the
/// map's size).
pub(super) fn agrees(exact: &Affine, usvg: &Affine) -> bool {
    let linear = [exact.a, exact.b, exact.c, exact.d];
    let size = linear.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let reach = size + exact.e.abs() + exact.f.abs();
    let pairs = [
        (exact.a, usvg.a, size),
        (exact.b, usvg.b, size),
        (exact.c, usvg.c, size),
        (exact.d, usvg.d, size),
        (exact.e, usvg.e, reach),
        (exact.f, usvg.f, reach),
    ];
    size > 0.0 && pairs.iter().all(|&(x, u, s)| (x - u).abs() <= 1e-6 * s)
}

/// An element's own `transform` (the identity when it has none), or `None` when it is not read
/// here: one that does not parse, a `transform-origin`, a `style` that may set a transform.
fn own_transform(node: Node) -> Option<Affine> {
    let css = node
        .attribute("style")
        .is_some_and(|s| s.contains("transform"));
    if css || node.has_attribute("transform-origin") {
        return None;
    }
    let Some(text) = node.attribute("transform") else {
        return Some(Affine::IDENTITY);
    };
    let t = Transform::from_str(text).ok()?;
    Some(Affine {
        a: t.a,
        b: t.b,
        c: t.c,
        d: t.d,
        e: t.e,
        f: t.f,
    })
}

/// The root `<svg>`'s map from user units to usvg's pixels: its `viewBox` fitted to its size as
/// `preserveAspectRatio` says (usvg's `ViewBox::to_transform`), the identity without a
/// `viewBox`. `None` for a root with a `transform`, or a size that is not an absolute length.
fn root_map(root: Node) -> Option<Affine> {
    if root.has_attribute("transform") || root.has_attribute("transform-origin") {
        return None;
    }
    let Some(view_box) = root.attribute("viewBox") else {
        return Some(Affine::IDENTITY);
    };
    let vb = ViewBox::from_str(view_box).ok()?;
    let size = |name| {
        let l = Length::from_str(root.attribute(name)?).ok()?;
        super::super::units::length_px(&l)
    };
    let (width, height) = (size("width")?, size("height")?);
    let aspect = match root.attribute("preserveAspectRatio") {
        Some(text) => AspectRatio::from_str(text).ok()?,
        None => AspectRatio::default(),
    };
    let (mut sx, mut sy) = (width / vb.w, height / vb.h);
    if aspect.align != Align::None {
        let s = if aspect.slice { sx.max(sy) } else { sx.min(sy) };
        (sx, sy) = (s, s);
    }
    let (x, y) = (-vb.x * sx, -vb.y * sy);
    let (w, h) = (width - vb.w * sx, height - vb.h * sy);
    let (e, f) = aligned(aspect.align, x, y, w, h);
    Some(Affine {
        a: sx,
        d: sy,
        e,
        f,
        ..Affine::IDENTITY
    })
}

/// Where the fitted box starts: `(x, y)` moved by the room left over (`w`, `h`) as `align`
/// says (usvg's `aligned_pos`).
fn aligned(align: Align, x: f64, y: f64, w: f64, h: f64) -> (f64, f64) {
    let (fx, fy) = match align {
        Align::None | Align::XMinYMin => (0.0, 0.0),
        Align::XMidYMin => (0.5, 0.0),
        Align::XMaxYMin => (1.0, 0.0),
        Align::XMinYMid => (0.0, 0.5),
        Align::XMidYMid => (0.5, 0.5),
        Align::XMaxYMid => (1.0, 0.5),
        Align::XMinYMax => (0.0, 1.0),
        Align::XMidYMax => (0.5, 1.0),
        Align::XMaxYMax => (1.0, 1.0),
    };
    (x + fx * w, y + fy * h)
}
