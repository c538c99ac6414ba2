//! The source's elements as the other modules find and name them: its shapes and `<use>`
//! elements by index, elements by id, the element a `<use>` refers to, the Inkscape layer an
//! element is on, and an element's name in messages (by id, else by line and column).

use std::collections::HashMap;

use roxmltree::{Document, Node};

use super::{INKSCAPE_NS, SVG_NS, XLINK_NS};

const SHAPES: [&str; 7] = [
    "path", "rect", "circle", "ellipse", "line", "polyline", "polygon",
];

/// The shape elements and the `<use>` elements of a document, each in document order (an
/// instance's `element` and `via_use` index these).
pub(super) fn shapes_and_uses<'d, 'a>(
    doc: &'d Document<'a>,
) -> (Vec<Node<'d, 'a>>, Vec<Node<'d, 'a>>) {
    let shapes = doc
        .descendants()
        .filter(|n| SHAPES.iter().any(|shape| is_svg(*n, shape)))
        .collect();
    let uses = doc.descendants().filter(|n| is_svg(*n, "use")).collect();
    (shapes, uses)
}

/// Whether `n` is the SVG element `name` as usvg reads them: in SVG's namespace, or in none
/// (under a prefixed root, `<s:svg xmlns:s="…">`, an unprefixed element has no namespace).
pub(super) fn is_svg(n: Node, name: &str) -> bool {
    n.is_element()
        && matches!(n.tag_name().namespace(), None | Some(SVG_NS))
        && n.tag_name().name() == name
}

/// The elements of a parsed source that cuts are named and written by.
pub(super) struct Elements<'d, 'a> {
    /// The shape elements, in document order (an instance's `element` indexes this).
    pub(super) shapes: Vec<Node<'d, 'a>>,
    /// The `<use>` elements, in document order.
    pub(super) uses: Vec<Node<'d, 'a>>,
    /// Elements by id (the first one with each id).
    pub(super) ids: HashMap<&'d str, Node<'d, 'a>>,
}

impl<'d, 'a> Elements<'d, 'a> {
    pub(super) fn of(doc: &'d Document<'a>) -> Self {
        let (shapes, uses) = shapes_and_uses(doc);
        let mut ids: HashMap<&str, Node> = HashMap::new();
        for n in doc.descendants().filter(|n| n.is_element()) {
            if let Some(id) = n.attribute("id") {
                ids.entry(id).or_insert(n);
            }
        }
        Elements { shapes, uses, ids }
    }
}

/// The element a `<use>` refers to.
pub(super) fn use_target<'a, 'i>(
    u: Node<'a, 'i>,
    ids: &HashMap<&str, Node<'a, 'i>>,
) -> Option<Node<'a, 'i>> {
    let href = u
        .attribute("href")
        .or_else(|| u.attribute((XLINK_NS, "href")))?;
    ids.get(href.strip_prefix('#')?).copied()
}

/// The Inkscape layer (a `<g inkscape:groupmode="layer">`) nearest around `node`: its label, else
/// its id.
pub(super) fn inkscape_layer(node: Node) -> Option<String> {
    node.ancestors()
        .find(|a| a.attribute((INKSCAPE_NS, "groupmode")) == Some("layer"))
        .and_then(|g| {
            g.attribute((INKSCAPE_NS, "label"))
                .or_else(|| g.attribute("id"))
                .map(str::to_string)
        })
}

/// `path "id"` or `<rect> at line 12, column 5`.
pub(super) fn describe(lines: &LineIndex, n: Node) -> String {
    match n.attribute("id") {
        Some(id) => format!("{} \"{id}\"", n.tag_name().name()),
        None => {
            let text = n.document().input_text();
            let (line, column) = lines.line_column(text, n.range().start);
            format!("<{}> at line {line}, column {column}", n.tag_name().name())
        }
    }
}

/// Line and column numbers of byte offsets in a text, each found by a binary search over the
/// lines' starts. (roxmltree's `Document::text_pos_at` counts from the start of the document
/// every time, which made naming every element of a large file quadratic in its size.)
pub(super) struct LineIndex {
    /// Byte offset of the start of each line.
    starts: Vec<usize>,
}

impl LineIndex {
    pub(super) fn new(text: &str) -> Self {
        let breaks = text.bytes().enumerate().filter(|&(_, b)| b == b'\n');
        let starts = std::iter::once(0)
            .chain(breaks.map(|(i, _)| i + 1))
            .collect();
        LineIndex { starts }
    }

    /// The line and column (both from 1; the column counts characters, as XML tools do) of the
    /// byte at `offset` of `text` (the text indexed).
    fn line_column(&self, text: &str, offset: usize) -> (usize, usize) {
        let offset = offset.min(text.len());
        let line = self.starts.partition_point(|&s| s <= offset);
        let start = self.starts[line - 1];
        let column = text.get(start..offset).map_or(0, |s| s.chars().count()) + 1;
        (line, column)
    }
}
