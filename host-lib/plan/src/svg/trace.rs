//! Tracing: each cut instance's subpaths drawn into document mm (from usvg's segments, or from
//! its exact geometry where that agrees), closed ones as contours and open ones as paths; and
//! how far from the origin single precision still holds a drawing.

use std::sync::atomic::{AtomicUsize, Ordering};

use cavalier_contours::polyline::PlineSource;
use rayon::prelude::*;

use super::edits::geometry_slots;
use super::elements::Elements;
use super::exact::{self, ExactPath, Exactness};
use super::{Instance, P32, Seg, bad};
use crate::error::Result;
use crate::geom::{Affine, PathSink, Pline, V2, v2};
use crate::outcome::PlanSummary;
use crate::pipeline::MAX_CUT_VERTICES;

/// A subpath of an instance traced into document mm.
pub(super) enum Traced {
    /// A closed contour: its subpath's index, the contour, its name.
    Closed(usize, Pline, String),
    /// An open path: its name, first and last points.
    Open(String, V2, V2),
}

/// Where each instance's element starts in the source `text`, where its new path data goes, and
/// whether its curves are traced from its exact geometry (read from the source here, with its
/// map to the page in double precision where the source gives it; `mm_per_px`: document mm per
/// usvg pixel).
pub(super) fn place(instances: &mut [Instance], text: &str, el: &Elements, mm_per_px: f64) {
    instances.par_iter_mut().for_each(|inst| {
        let node = el.shapes[inst.element];
        inst.start = node.range().start;
        inst.slots = geometry_slots(text, node);
        let cloned = inst.via_use.is_some();
        (inst.exact, inst.to_doc) = exact::exactness(node, inst.to_doc, mm_per_px, cloned);
    });
}

/// The exact geometry of `inst` (drawn by usvg as `segs`, held to `eps` mm), when it has one that
/// agrees with what usvg drew (see [`exact`]); an instance whose exact geometry does not agree is
/// marked [`Exactness::Approximated`].
pub(super) fn exact_geometry(
    inst: &mut Instance,
    segs: &[Vec<Seg>],
    eps: f64,
) -> Option<Box<ExactPath>> {
    match std::mem::take(&mut inst.exact) {
        Exactness::Exact(path) if path.agrees(segs, &inst.to_doc, join_mm(eps)) => Some(path),
        Exactness::Exact(_) | Exactness::Approximated => {
            inst.exact = Exactness::Approximated;
            None
        }
        Exactness::Usvg => None,
    }
}

/// Points of an instance closer than this (mm) are one point, its coordinates held to `eps` mm
/// (see [`Reach::eps_mm`]): 0.1 µm, more on huge pages (a few single-precision steps).
fn join_mm(eps: f64) -> f64 {
    (8.0 * eps).max(1e-4)
}

/// One instance's subpaths (`subpaths`, in its element's coordinates, or `exact`, its exact
/// geometry, when given) in document mm, ends within [`join_mm`] meeting; `name` names the
/// instance.
pub(super) fn trace(
    inst: &Instance,
    subpaths: &[Vec<Seg>],
    exact: Option<&ExactPath>,
    eps: f64,
    name: &str,
    vertices: &AtomicUsize,
) -> Vec<Traced> {
    let n_sub = subpaths.len();
    let mut traced = Vec::with_capacity(n_sub);
    // A curve may flatten to thousands of vertices (a line or move adds one): the budget is
    // watched after each.
    let over_budget =
        |sink: &PathSink| vertices.load(Ordering::Relaxed) + sink.vertex_count() > MAX_CUT_VERTICES;
    for (si, segs) in subpaths.iter().enumerate() {
        let mut sink = PathSink::new(join_mm(eps), eps);
        let over = match exact {
            Some(exact) => exact.draw(si, &inst.to_doc, &mut sink, &over_budget),
            None => draw_segs(segs, &inst.to_doc, &mut sink, &over_budget),
        };
        if over {
            // Refused by the caller: nothing more is traced.
            vertices.store(usize::MAX, Ordering::Relaxed);
            return traced;
        }
        vertices.fetch_add(sink.vertex_count(), Ordering::Relaxed);
        let Some(sub) = sink.finish().into_iter().next() else {
            continue;
        };
        let mut name = name.to_string();
        if n_sub > 1 {
            name.push_str(&format!(" (subpath {} of {n_sub})", si + 1));
        }
        if sub.pline.is_closed() {
            traced.push(Traced::Closed(si, sub.pline, name));
        } else {
            let first = sub.pline.at(0);
            let last = sub.pline.at(sub.pline.vertex_count() - 1);
            traced.push(Traced::Open(name, v2(first.x, first.y), v2(last.x, last.y)));
        }
    }
    traced
}

/// Draw usvg's subpath `segs` into `sink` in document mm (through `to_doc`). After each curve,
/// `over_budget` is asked whether the vertices drawn are too many: then drawing stops and `true`
/// is returned.
fn draw_segs(
    segs: &[Seg],
    to_doc: &Affine,
    sink: &mut PathSink,
    over_budget: &dyn Fn(&PathSink) -> bool,
) -> bool {
    let doc = |p: P32| to_doc.apply(p.v2());
    for s in segs {
        match *s {
            Seg::M(p) => sink.move_to(doc(p)),
            Seg::L(p) => sink.line_to(doc(p)),
            Seg::Q(a, b) => sink.quad_to(doc(a), doc(b)),
            Seg::C(a, b, c) => sink.cubic_to(doc(a), doc(b), doc(c)),
            Seg::Z => sink.close(),
        }
        if matches!(s, Seg::Q(..) | Seg::C(..)) && over_budget(sink) {
            return true;
        }
    }
    false
}

/// How far an instance's coordinates reach from the origin, in document mm: through its own
/// coordinates (scaled to mm) and in the document. usvg keeps them in `f32`, whose step grows
/// with the distance.
#[derive(Clone, Copy, Default)]
pub(super) struct Reach {
    local_mm: f64,
    doc_mm: f64,
}

impl Reach {
    /// The reach of `inst`'s `subpaths`.
    pub(super) fn of(inst: &Instance, subpaths: &[Vec<Seg>]) -> Self {
        let mut local = 0.0f64;
        let mut doc = 0.0f64;
        for s in subpaths.iter().flatten() {
            let pts: &[P32] = match s {
                Seg::M(a) | Seg::L(a) => std::slice::from_ref(a),
                Seg::Q(a, _) => std::slice::from_ref(a),
                Seg::C(a, _, _) => std::slice::from_ref(a),
                Seg::Z => &[],
            };
            for p in pts.iter().map(|p| p.v2()) {
                local = local.max(p.x.abs()).max(p.y.abs());
                let q = inst.to_doc.apply(p);
                doc = doc.max(q.x.abs()).max(q.y.abs());
            }
        }
        Reach {
            local_mm: local * inst.to_doc.mean_scale(),
            doc_mm: doc,
        }
    }

    /// Rounding uncertainty of the coordinates in document mm, with a margin: within it, ends
    /// meet.
    pub(super) fn eps_mm(self) -> f64 {
        4.0 * f64::from(f32::EPSILON) * (self.local_mm + self.doc_mm + 1e-3)
    }

    /// How finely single precision holds the farthest coordinate, ± mm (half its step).
    pub(super) fn held_to_mm(self) -> f64 {
        0.5 * f64::from(f32::EPSILON) * self.local_mm.max(self.doc_mm)
    }
}

/// Beyond this (± mm) a drawing is too far from the origin to be dilated: at 10 µm, 170 m out.
const FARTHEST_HELD_TO_MM: f64 = 0.01;

/// A drawing reaching `reach` (its farthest instance's, named `name`) is refused when single
/// precision holds it to worse than [`FARTHEST_HELD_TO_MM`]; noted in `summary` when worse than
/// the 0.1 µm the output keeps (1.7 m out).
pub(super) fn check_reach(reach: Reach, name: &str, summary: &mut PlanSummary) -> Result<()> {
    let (far_mm, held_um) = (reach.local_mm.max(reach.doc_mm), reach.held_to_mm() * 1e3);
    if reach.held_to_mm() > FARTHEST_HELD_TO_MM {
        return Err(bad(format!(
            "{name} reaches {far_mm:.0} mm from the origin, where an SVG's coordinates are held only to ±{held_um:.0} µm (single precision); move the drawing near the origin"
        )));
    }
    if held_um > 0.1 {
        summary.notes.push(format!(
            "{name} reaches {far_mm:.0} mm from the origin, where an SVG's coordinates are held to ±{held_um:.2} µm (single precision), not 0.1 µm"
        ));
    }
    Ok(())
}
