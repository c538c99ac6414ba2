//! The walk over usvg's tree: which drawn paths are cuts (by the rules), each tied back to its
//! element and outermost `<use>` by its tag, with its map to the page and its path data; and
//! usvg's transforms and path data in this module's types.

use std::collections::{HashMap, HashSet};

use usvg::tiny_skia_path::{self, PathSegment};

use super::exact::Exactness;
use super::{Instance, P32, Seg, lost};
use crate::geom::Affine;
use crate::outcome::PlanSummary;
use crate::rules::{CutRules, Rgb, Verdict};

/// The walk over usvg's tree: the cut instances found, and each one's path data (a copy).
pub(super) struct Walk<'a> {
    rules: &'a CutRules,
    mm_per_px: f64,
    shapes_len: usize,
    use_by_id: &'a HashMap<String, usize>,
    /// Whether cut instances are kept: not when only which elements are drawn is asked (see
    /// [`lost`]).
    keep: bool,
    pub(super) instances: Vec<Instance>,
    pub(super) paths: Vec<tiny_skia_path::Path>,
    /// The visible stroked elements drawn, by (shape, outermost `<use>`): every cut instance,
    /// and the other elements drawn with a stroke (only those can be named: see
    /// [`tagged`](super::tagging::tagged)).
    pub(super) seen: HashSet<(usize, Option<usize>)>,
    summary: &'a mut PlanSummary,
    pub(super) unidentified: usize,
    /// A group whose combined transform may have made usvg drop what it holds (see
    /// [`lost::Overflow`]).
    pub(super) overflow: Option<lost::Overflow>,
}

impl<'a> Walk<'a> {
    /// A walk that keeps the cut instances when `keep`.
    pub(super) fn new(
        rules: &'a CutRules,
        mm_per_px: f64,
        shapes_len: usize,
        use_by_id: &'a HashMap<String, usize>,
        summary: &'a mut PlanSummary,
        keep: bool,
    ) -> Self {
        // Room for one instance per shape (most plans: the cuts, and a few more) from the start:
        // grown by doubling, these vectors held up to twice their room at the peak of reading.
        let room = if keep { shapes_len } else { 0 };
        Walk {
            rules,
            mm_per_px,
            shapes_len,
            use_by_id,
            keep,
            instances: Vec::with_capacity(room),
            paths: Vec::with_capacity(room),
            seen: HashSet::new(),
            summary,
            unidentified: 0,
            overflow: None,
        }
    }

    pub(super) fn group(&mut self, g: &usvg::Group, uses: &mut Vec<usize>) {
        for child in g.children() {
            match child {
                usvg::Node::Group(c) => {
                    lost::Overflow::note(&mut self.overflow, c);
                    let u = self.use_by_id.get(c.id()).copied();
                    if let Some(u) = u {
                        uses.push(u);
                    }
                    self.group(c, uses);
                    if u.is_some() {
                        uses.pop();
                    }
                }
                usvg::Node::Path(p) => self.path(p, uses),
                // Never loaded (see `usvg_options`): the source counted them.
                usvg::Node::Image(_) => {}
                #[allow(unreachable_patterns)]
                _ => self.summary.pass("other"),
            }
        }
    }

    /// The shape (its index) whose tag (see [`tagged`](super::tagging::tagged)) is the stroke
    /// miter limit `code`.
    fn shape_of(&self, code: f32) -> Option<usize> {
        let element = code as usize;
        (code.fract() == 0.0 && element > 0 && element <= self.shapes_len).then(|| element - 1)
    }

    fn path(&mut self, p: &usvg::Path, uses: &[usize]) {
        if !p.is_visible() {
            self.summary.pass("hidden");
            return;
        }
        // usvg drops ids inside clones, so only the outermost <use> is seen; a cut reached
        // through nested clones is caught by the caller (it does not lie in that <use>'s
        // target).
        let via_use = uses.first().copied();
        let shape = p.stroke().and_then(|s| self.shape_of(s.miterlimit().get()));
        if !self.keep {
            self.seen.extend(shape.map(|e| (e, via_use)));
            return;
        }
        let to_doc = Affine::scale(self.mm_per_px).then_after(&affine(p.abs_transform()));
        let stroke = p.stroke().and_then(|s| match s.paint() {
            usvg::Paint::Color(c) if s.opacity().get() > 0.0 => Some((
                Rgb(c.red, c.green, c.blue),
                f64::from(s.width().get()) * to_doc.mean_scale(),
            )),
            _ => None,
        });
        let filled = p.fill().is_some_and(|f| f.opacity().get() > 0.0);
        match self.rules.classify_svg(stroke, filled) {
            Verdict::Keep(reason) => {
                self.summary.pass(reason);
                self.seen.extend(shape.map(|e| (e, via_use)));
            }
            Verdict::Cut => {
                let Some(element) = shape else {
                    self.unidentified += 1;
                    return;
                };
                if !self.seen.insert((element, via_use)) {
                    // The same element drawn twice in one instance (paint-order with markers).
                    return;
                }
                let instance = Instance {
                    element,
                    via_use,
                    to_doc,
                    subpath_count: 0,
                    drawn: Vec::new(),
                    stroke: stroke.map(|s| s.0),
                    exact: Exactness::Usvg,
                    start: 0,
                    slots: Vec::new(),
                };
                self.instances.push(instance);
                self.paths.push(p.data().clone());
            }
        }
    }
}

pub(super) fn affine(t: usvg::Transform) -> Affine {
    Affine {
        a: f64::from(t.sx),
        b: f64::from(t.ky),
        c: f64::from(t.kx),
        d: f64::from(t.sy),
        e: f64::from(t.tx),
        f: f64::from(t.ty),
    }
}

/// A path's subpaths as usvg resolved them, each vector no larger than it needs.
pub(super) fn subpaths_of(p: &tiny_skia_path::Path) -> Vec<Vec<Seg>> {
    let mut subpaths: Vec<Vec<Seg>> = Vec::new();
    let pt = |q: tiny_skia_path::Point| P32(q.x, q.y);
    for seg in p.segments() {
        let s = match seg {
            PathSegment::MoveTo(a) => {
                subpaths.push(Vec::new());
                Seg::M(pt(a))
            }
            PathSegment::LineTo(a) => Seg::L(pt(a)),
            PathSegment::QuadTo(a, b) => Seg::Q(pt(a), pt(b)),
            PathSegment::CubicTo(a, b, c) => Seg::C(pt(a), pt(b), pt(c)),
            PathSegment::Close => Seg::Z,
        };
        if subpaths.is_empty() {
            subpaths.push(Vec::new());
        }
        subpaths.last_mut().expect("pushed").push(s);
    }
    for sub in &mut subpaths {
        sub.shrink_to_fit();
    }
    subpaths.shrink_to_fit();
    subpaths
}
