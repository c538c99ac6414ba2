//! Rendering a large SVG with usvg in slices, on every core.
//!
//! usvg reads a document on one thread, and on a large plan it was a third of the command's
//! wall time, the other core idle. A plan is mostly a long list of the root's children (one group
//! a part, or a few layers), each rendered alone: a slice is the document with the root's start
//! tag, every child that draws nothing by itself (`<defs>`, `<symbol>`, gradients, metadata…),
//! a run of the drawing children, and the end. The slices are rendered on any core, and their
//! cut instances put together in document order: the same instances, in the same order, as the
//! whole document gives. The slice texts are cut from the tagged copy, so every cut keeps its tag.
//!
//! A document is sliced only where that cannot change what is drawn:
//! * its root has a `viewBox` (without one usvg may size the document by what it contains);
//! * it has no `<style>` element, in any namespace as usvg reads them (a stylesheet's selectors
//!   may depend on the siblings a slice leaves out, `:first-child`, `+`, `~`);
//! * it cannot come near usvg's limit of a million nodes, its `<use>` copies counted (each slice
//!   is checked alone: a document usvg refuses whole must still be refused), nor has clones of
//!   clones (whose copies this count does not see);
//! * every reference (`href="#id"`, `url(#id)`) from a drawing child stays within that child or
//!   goes into a child that draws nothing (which every slice has), and no child that draws nothing
//!   refers into a drawing child.
//!
//! And only where it pays: every slice parses the shared part again, so that part times the
//! slices must be under a quarter of the drawing children.
//!
//! Otherwise, or when a slice cannot be rendered, the whole document is rendered at once.

use std::collections::HashMap;
use std::ops::Range;

use roxmltree::{Document, Node};

#[cfg(test)]
use super::SVG_NS;
use super::in_svg_namespace;

/// The root's children that draw nothing where they stand: a slice keeps all of them.
const DRAW_NOTHING: [&str; 14] = [
    "defs",
    "symbol",
    "linearGradient",
    "radialGradient",
    "pattern",
    "clipPath",
    "mask",
    "marker",
    "filter",
    "title",
    "desc",
    "metadata",
    "script",
    "font",
];

/// A document's slices, as byte ranges of its text: each slice is `head`, every range of
/// `shared`, its own ranges, then `tail`.
#[derive(Debug, PartialEq)]
pub(super) struct Slicing {
    /// From the start of the document to the root's first child element.
    head: Range<usize>,
    /// The root's children that draw nothing by themselves.
    shared: Vec<Range<usize>>,
    /// The drawing children, in runs of about equal size, in document order.
    slices: Vec<Vec<Range<usize>>>,
    /// From the end of the root's last child element to the end of the document.
    tail: Range<usize>,
}

impl Slicing {
    /// How `doc` is best cut into at most `count` slices, or `None` where it cannot be, would make
    /// one slice, or would not pay (see the module's documentation).
    pub fn plan(doc: &Document, count: usize) -> Option<Slicing> {
        Self::possible(doc, count).filter(|s| s.pays())
    }

    /// How `doc` can be cut into at most `count` slices, whether or not that pays.
    pub fn possible(doc: &Document, count: usize) -> Option<Slicing> {
        let root = doc.root_element();
        if !root.has_attribute("viewBox") || has_style_sheet(doc) || near_node_limit(doc) {
            return None;
        }
        let children: Vec<Node> = root.children().filter(Node::is_element).collect();
        let (first, last) = (children.first()?, children.last()?);
        let draws: Vec<bool> = children.iter().map(|c| !draws_nothing(*c)).collect();
        if !references_stay_in_place(root, &children, &draws) {
            return None;
        }
        let shared = (children.iter().zip(&draws))
            .filter(|(_, d)| !**d)
            .map(|(c, _)| c.range())
            .collect();
        let drawing: Vec<Range<usize>> = (children.iter().zip(&draws))
            .filter(|(_, d)| **d)
            .map(|(c, _)| c.range())
            .collect();
        let slices = runs(drawing, count);
        (slices.len() > 1).then(|| Slicing {
            head: 0..first.range().start,
            shared,
            slices,
            tail: last.range().end..doc.input_text().len(),
        })
    }

    /// The same slicing in a text made from the document's by inserting text: `position` maps a
    /// position in the document's text to the new text's (no insertion is at a child's bounds).
    pub fn moved(self, position: impl Fn(usize) -> usize) -> Slicing {
        let map = |r: Range<usize>| position(r.start)..position(r.end);
        Slicing {
            head: map(self.head),
            shared: self.shared.into_iter().map(map).collect(),
            slices: (self.slices.into_iter())
                .map(|s| s.into_iter().map(map).collect())
                .collect(),
            tail: map(self.tail),
        }
    }

    /// Whether slicing pays: every slice parses the head, the shared children and the tail
    /// again, which must be under a quarter of the drawing children.
    fn pays(&self) -> bool {
        let once = |r: &Range<usize>| r.len();
        let repeated =
            once(&self.head) + once(&self.tail) + self.shared.iter().map(once).sum::<usize>();
        let drawn: usize = self.slices.iter().flatten().map(once).sum();
        repeated.saturating_mul(self.len()).saturating_mul(4) < drawn
    }

    /// How many slices.
    pub fn len(&self) -> usize {
        self.slices.len()
    }

    /// The text of slice `k`, cut from `text` (the text the ranges are in).
    pub fn text(&self, text: &str, k: usize) -> String {
        let parts = std::iter::once(&self.head)
            .chain(&self.shared)
            .chain(&self.slices[k])
            .chain(std::iter::once(&self.tail));
        let mut out = String::with_capacity(parts.clone().map(Range::len).sum());
        for r in parts {
            out.push_str(&text[r.clone()]);
        }
        out
    }
}

/// Whether `n` (a child of the root) draws nothing where it stands: an element that is only drawn
/// where it is referred to, or describes, or an element of a namespace other than SVG's (usvg
/// draws elements of no namespace as SVG's).
fn draws_nothing(n: Node) -> bool {
    !in_svg_namespace(n) || DRAW_NOTHING.contains(&n.tag_name().name())
}

/// Whether the document has a `<style>` element (usvg reads one in any namespace).
fn has_style_sheet(doc: &Document) -> bool {
    doc.descendants()
        .any(|n| n.is_element() && n.tag_name().name() == "style")
}

/// usvg refuses a document of more than a million nodes, the copies its `<use>` elements make
/// counted; a document of half as many is not sliced.
const SLICED_NODES_MAX: usize = 500_000;

/// Whether the document's elements, each `<use>` counted with its target's, could come near
/// usvg's limit, or a `<use>` copies another one (whose copies are not counted here).
fn near_node_limit(doc: &Document) -> bool {
    let elements = || doc.descendants().filter(Node::is_element);
    let mut by_id: HashMap<&str, Node> = HashMap::new();
    for n in elements() {
        if let Some(id) = n.attribute("id") {
            by_id.entry(id).or_insert(n);
        }
    }
    let is_use = |n: &Node| n.tag_name().name() == "use";
    let mut nodes = 0usize;
    for n in elements() {
        nodes += 1;
        let target = is_use(&n)
            .then(|| n.attributes().find(|a| a.name() == "href"))
            .flatten()
            .and_then(|a| a.value().trim().strip_prefix('#'))
            .and_then(|id| by_id.get(id));
        if let Some(target) = target {
            let mut copied = 0;
            for d in target.descendants().filter(Node::is_element) {
                if is_use(&d) {
                    return true;
                }
                copied += 1;
            }
            nodes += copied;
        }
        if nodes > SLICED_NODES_MAX {
            return true;
        }
    }
    false
}

/// Whether every reference stays in place (see the module's documentation): `children` are the
/// root's child elements, `draws[i]` whether child `i` draws. An id given in two children is not
/// (which of them a reference finds could depend on the slice).
fn references_stay_in_place(root: Node, children: &[Node], draws: &[bool]) -> bool {
    let mut child_of_id: HashMap<&str, usize> = HashMap::new();
    for (i, c) in children.iter().enumerate() {
        for n in c.descendants().filter(Node::is_element) {
            if let Some(id) = n.attribute("id")
                && *child_of_id.entry(id).or_insert(i) != i
            {
                return false;
            }
        }
    }
    // From `from` (a child, or the root: `None`, which every slice has) to `id`: ids given
    // nowhere, or on the root, are the same in every slice.
    let allowed = |from: Option<usize>, id: &str| match child_of_id.get(id) {
        Some(&to) => Some(to) == from || !draws[to],
        None => true,
    };
    referenced_ids(root).all(|id| allowed(None, id))
        && children.iter().enumerate().all(|(i, c)| {
            c.descendants()
                .filter(Node::is_element)
                .all(|n| referenced_ids(n).all(|id| allowed(Some(i), id)))
        })
}

/// The ids an element's attributes refer to: `href` (any namespace) of `#id`, and every
/// `url(#id)` in any attribute (a `style` too).
fn referenced_ids<'a>(n: Node<'a, '_>) -> impl Iterator<Item = &'a str> {
    n.attributes().flat_map(|a| {
        let value = a.value();
        let href = (a.name() == "href")
            .then(|| value.trim().strip_prefix('#'))
            .flatten();
        href.into_iter().chain(url_ids(value))
    })
}

/// The ids in the `url(#id)` of a value (quoted or not, with spaces).
fn url_ids(value: &str) -> impl Iterator<Item = &str> {
    value.split("url(").skip(1).filter_map(|rest| {
        let inside = rest.split(')').next()?;
        let inside = inside.trim().trim_matches(|c| c == '"' || c == '\'').trim();
        inside.strip_prefix('#')
    })
}

/// `ranges` in at most `count` runs of about equal length, in order: a run ends where the length
/// before the next range reaches its share of the whole.
fn runs(ranges: Vec<Range<usize>>, count: usize) -> Vec<Vec<Range<usize>>> {
    let total: usize = ranges.iter().map(Range::len).sum();
    let mut runs: Vec<Vec<Range<usize>>> = Vec::new();
    let mut done = 0;
    for r in ranges {
        let k = runs.len();
        if k == 0 || (k < count && done * count >= k * total) {
            runs.push(Vec::new());
        }
        done += r.len();
        runs.last_mut().expect("pushed").push(r);
    }
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc_text(body: &str) -> String {
        format!(
            "<?xml version=\"1.0\"?>\n<svg xmlns=\"{SVG_NS}\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" viewBox=\"0 0 100 100\">\n{body}\n</svg>\n"
        )
    }

    fn slicing(body: &str, count: usize) -> Option<Vec<String>> {
        let text = doc_text(body);
        let doc = Document::parse(&text).expect("XML");
        let s = Slicing::possible(&doc, count)?;
        Some((0..s.len()).map(|k| s.text(&text, k)).collect())
    }

    #[test]
    fn each_slice_has_the_head_the_shared_children_a_run_and_the_end() {
        let body = "<g id=\"a\"><path d=\"M0 0H1\"/></g><defs><path id=\"p\" d=\"M0 0\"/></defs><g id=\"b\"><use href=\"#p\"/></g>";
        let slices = slicing(body, 2).expect("sliced");
        assert_eq!(slices.len(), 2);
        let head = doc_text("");
        let head = &head[..head.find("\n\n").expect("head") + 1];
        for s in &slices {
            assert!(s.starts_with(head), "{s}");
            assert!(
                s.contains("<defs><path id=\"p\" d=\"M0 0\"/></defs>"),
                "{s}"
            );
            assert!(s.ends_with("\n</svg>\n"), "{s}");
            Document::parse(s).expect("each slice is XML");
        }
        assert!(slices[0].contains("id=\"a\"") && !slices[0].contains("id=\"b\""));
        assert!(slices[1].contains("id=\"b\"") && !slices[1].contains("id=\"a\""));
    }

    #[test]
    fn a_document_that_a_slice_could_draw_differently_is_not_sliced() {
        let g = |id: &str, inner: &str| format!("<g id=\"{id}\">{inner}</g>");
        // A clone of another drawing child.
        let across = g("a", "<path id=\"p\" d=\"M0 0H1\"/>") + &g("b", "<use xlink:href=\"#p\"/>");
        assert_eq!(slicing(&across, 2), None);
        // A paint server inside another drawing child, in a style.
        let paint = g("a", "<linearGradient id=\"lg\"/>")
            + &g("b", "<path style=\"stroke: url( '#lg' )\" d=\"M0 0H1\"/>");
        assert_eq!(slicing(&paint, 2), None);
        // A definition that clones a drawing child.
        let defs = g("a", "<path id=\"p\" d=\"M0 0H1\"/>")
            + "<defs><use id=\"u\" href=\"#p\"/></defs>"
            + &g("b", "<use href=\"#u\"/>");
        assert_eq!(slicing(&defs, 2), None);
        // The root painting with a drawing child's gradient.
        let text = format!(
            "<svg xmlns=\"{SVG_NS}\" viewBox=\"0 0 9 9\" fill=\"url(#lg)\"><g><linearGradient id=\"lg\"/></g><g/></svg>"
        );
        let doc = Document::parse(&text).expect("XML");
        assert_eq!(Slicing::possible(&doc, 2), None);
        // An id given twice.
        let twice =
            g("a", "<path id=\"p\" d=\"M0 0H1\"/>") + &g("b", "<path id=\"p\" d=\"M0 0H1\"/>");
        assert_eq!(slicing(&twice, 2), None);
        // A style sheet, in any namespace.
        let css = "<style xmlns=\"\">g:first-child path { stroke: red }</style>".to_string()
            + &g("a", "<path d=\"M0 0H1\"/>")
            + &g("b", "<path d=\"M0 0H1\"/>");
        assert_eq!(slicing(&css, 2), None);
        // Clones of clones.
        let nested = g(
            "a",
            "<path id=\"p\" d=\"M0 0H1\"/><use id=\"u\" href=\"#p\"/>",
        ) + &g("b", "<path d=\"M0 0H1\"/>")
            + "<defs><use id=\"v\" href=\"#a\"/></defs>";
        assert_eq!(slicing(&nested, 2), None);
        // A style sheet.
        let css = "<style>g:first-child path { stroke: red }</style>".to_string()
            + &g("a", "<path d=\"M0 0H1\"/>")
            + &g("b", "<path d=\"M0 0H1\"/>");
        assert_eq!(slicing(&css, 2), None);
        // Within one child, or into the definitions: sliced.
        let within = g("a", "<path id=\"p\" d=\"M0 0H1\"/><use href=\"#p\"/>")
            + "<defs><linearGradient id=\"lg\"/></defs>"
            + &g("b", "<path stroke=\"url(#lg)\" d=\"M0 0H1\"/>");
        assert_eq!(slicing(&within, 2).map(|s| s.len()), Some(2));
    }

    #[test]
    fn without_a_view_box_or_with_one_drawing_child_there_is_one_piece() {
        let text = format!("<svg xmlns=\"{SVG_NS}\" width=\"10mm\" height=\"10mm\"><g/><g/></svg>");
        let doc = Document::parse(&text).expect("XML");
        assert_eq!(Slicing::possible(&doc, 4), None);
        assert_eq!(slicing("<defs/><g/>", 4), None);
    }

    #[test]
    fn elements_of_no_namespace_draw_as_usvg_draws_them() {
        // Under a prefixed root, unprefixed elements have no namespace: usvg draws them.
        let text = format!(
            "<s:svg xmlns:s=\"{SVG_NS}\" viewBox=\"0 0 9 9\"><s:g id=\"a\"><s:path d=\"M0 0H1\"/></s:g><g id=\"b\"><path d=\"M0 0H1\"/></g><x:meta xmlns:x=\"urn:x\"/><m xmlns=\"urn:m\"/></s:svg>"
        );
        let doc = Document::parse(&text).expect("XML");
        let s = Slicing::possible(&doc, 2).expect("sliced");
        let slices: Vec<String> = (0..s.len()).map(|k| s.text(&text, k)).collect();
        assert_eq!(slices.len(), 2, "{slices:?}");
        assert!(slices[1].contains("id=\"b\"") && !slices[0].contains("id=\"b\""));
        assert!(
            slices
                .iter()
                .all(|s| s.contains("<x:meta") && s.contains("<m "))
        );
    }

    #[test]
    fn a_document_near_usvg_s_node_limit_is_not_sliced() {
        let clones = "<use href=\"#many\"/>".repeat(60);
        let many = format!("<g id=\"many\">{}</g>", "<path d=\"M0 0\"/>".repeat(10_000));
        assert_eq!(
            slicing(&format!("<defs>{many}</defs><g>{clones}</g><g/>"), 2),
            None
        );
        let few = "<use href=\"#many\"/>".repeat(2);
        assert!(slicing(&format!("<defs>{many}</defs><g>{few}</g><g/>"), 2).is_some());
    }

    #[test]
    fn a_document_mostly_shared_is_not_sliced() {
        let part = "<g><use href=\"#p\"/></g>";
        let defs = format!(
            "<defs><path id=\"p\" d=\"M0 0{}\"/></defs>",
            "h1v1".repeat(100)
        );
        let planned = |body: String| {
            let text = doc_text(&body);
            let doc = Document::parse(&text).expect("XML");
            Slicing::plan(&doc, 2).map(|s| s.len())
        };
        assert_eq!(planned(defs.clone() + part + part), None);
        assert_eq!(planned(defs + &part.repeat(400)), Some(2));
    }

    #[test]
    fn runs_are_about_equal_and_in_order() {
        let ranges: Vec<Range<usize>> = (0..10).map(|i| i * 10..i * 10 + 10).collect();
        let r = runs(ranges.clone(), 3);
        assert_eq!(r.len(), 3);
        assert_eq!(r.concat(), ranges);
        assert!(r.iter().all(|run| (3..=4).contains(&run.len())), "{r:?}");
        assert_eq!(runs(ranges.clone(), 1), vec![ranges]);
    }

    #[test]
    fn url_references_are_read_in_every_spelling() {
        let ids: Vec<&str> = url_ids("url(#a) url( \"#b\" ) url('#c') url(x.svg#d)").collect();
        assert_eq!(ids, ["a", "b", "c"]);
    }
}
