//! Writing a dilated ASCII DXF by splicing: the input's bytes are copied as read, and only the
//! entities that changed are rewritten in their place (found by their handle, code `5`).
//!
//! The `dxf` crate's own save builds every code pair of the drawing in memory and formats every
//! number again: most of the time and memory of dilating a large DXF went there, and it drops what
//! it does not model (comments, unknown entities and objects, the file's number formatting). Here
//! a small scanner of the code/value lines ([`Pairs`]) finds each model-space entity's byte span
//! (with its `VERTEX`, `ATTRIB` and `SEQEND` followers), and the output is:
//!
//! * the record of what was applied (`999` comments; an earlier record of this tool at the top of
//!   the input is dropped, the file's other comments kept);
//! * every byte of the input as read, except that
//!   - a closed `LWPOLYLINE` cut gets its new vertices in place (its other pairs kept in order;
//!     its width, vertex id and extrusion pairs dropped, as the drawing's rewrite does),
//!   - a `CIRCLE` cut gets its new centre and radius in place (extrusion dropped: it is
//!     written in world coordinates),
//!   - the entities a chain (or a `POLYLINE`, `ELLIPSE`, `SPLINE`, or a circle that did not stay a
//!     circle) replaces are left out, and the new closed `LWPOLYLINE`s are added at the end of
//!     the `ENTITIES` section, with new handles (and `$HANDSEED` moved past them), the owner of
//!     the entity they replace and its layer, linetype, colour and lineweight pairs copied as
//!     they are written in the file.
//!
//! Formatting the new vertices is most of the work: the changed entities' text is made on every
//! core, a batch at a time, and put in file order (the output does not depend on the number of
//! cores), and a rounded number is printed from the integer count of its last decimal
//! (`decimal`), not by the float formatter, with the same text.
//!
//! Anything this does not cover is written by the `dxf` crate instead ([`super`]'s `save`): a
//! binary DXF, a drawing to be written as another version (older than R2000), assumed units to
//! record in the header, cuts inside blocks (their `INSERT`s point at new blocks), a drawing with
//! an entity that has no usable handle (the crate gives it one of its own, which may be another
//! entity's here) or a `$HANDSEED` whose value cannot be read, and any entity to change that
//! shares its handle or is not where and what the scan expects. The scan stops at `0 EOF`, as
//! readers do.

use std::collections::HashMap;
use std::io::Write as _;

use cavalier_contours::polyline::PlineSource;
use rayon::prelude::*;

use super::rounded;
use crate::decimal::{pow10, write_scaled};
use crate::geom::Pline;

/// Changed entities whose text is made at once, on any core, before it is put in its place (the
/// text of all of them would be more than the file).
const WRITE_BATCH: usize = 1024;

/// One code/value pair of an ASCII DXF: where it starts and ends in the file, its code, and its
/// value (the line without its end, and without surrounding white space).
#[derive(Debug, Clone, Copy)]
pub(super) struct Pair<'a> {
    pub start: usize,
    pub end: usize,
    pub code: i32,
    pub value: &'a [u8],
}

/// The code/value pairs of ASCII DXF bytes, in order; stops at the end, or at a line that is not
/// a pair (`broken` then says so).
pub(super) struct Pairs<'a> {
    bytes: &'a [u8],
    at: usize,
    pub broken: bool,
}

impl<'a> Pairs<'a> {
    pub fn new(bytes: &'a [u8], from: usize) -> Self {
        Pairs {
            bytes,
            at: from,
            broken: false,
        }
    }

    /// The next line (without its end) and where the line after it starts.
    fn line(&self, from: usize) -> Option<(&'a [u8], usize)> {
        let rest = self.bytes.get(from..)?;
        if rest.is_empty() {
            return None;
        }
        Some(match rest.iter().position(|&b| b == b'\n') {
            Some(n) => (&rest[..n], from + n + 1),
            None => (rest, self.bytes.len()),
        })
    }
}

impl<'a> Iterator for Pairs<'a> {
    type Item = Pair<'a>;

    fn next(&mut self) -> Option<Pair<'a>> {
        let start = self.at;
        let (code_line, next) = self.line(start)?;
        if code_line.trim_ascii().is_empty() && next >= self.bytes.len() {
            // A blank last line.
            return None;
        }
        let code = std::str::from_utf8(code_line.trim_ascii())
            .ok()
            .and_then(|s| s.parse::<i32>().ok());
        let (Some(code), Some((value, end))) = (code, self.line(next)) else {
            self.broken = true;
            self.at = self.bytes.len();
            return None;
        };
        self.at = end;
        Some(Pair {
            start,
            end,
            code,
            value: value.trim_ascii(),
        })
    }
}

/// A byte range of the file.
type Span = (usize, usize);

/// A model-space entity as scanned: its span (with its followers), and where its owner handle's
/// value is.
#[derive(Debug, Clone, Copy)]
struct Scanned {
    span: Span,
    owner: Option<Span>,
    /// Inside a `102 {…` application group (reactors, dictionaries), whose `330`s are not the
    /// owner.
    in_group: bool,
}

/// Where things are in an ASCII DXF file.
pub(super) struct Layout {
    /// The file's line end.
    eol: &'static str,
    /// The entities of the `ENTITIES` section by handle (`None`: the handle is used twice).
    entities: HashMap<u64, Option<Scanned>>,
    /// Where the `ENTITIES` section's `ENDSEC` pair starts.
    entities_end: Option<usize>,
    /// The `$HANDSEED` value's span in the header, and its value.
    handseed: Option<(Span, u64)>,
    /// The largest handle given to anything outside the header.
    max_handle: u64,
    /// Pairs at the top of the file that are an earlier record of this tool, to drop.
    old_records: Vec<Span>,
    /// An entity of `ENTITIES` has no usable handle (none, 0, or not a 64-bit hex number): the
    /// `dxf` crate gives it one of its own when it reads the file, which may be another entity's
    /// handle here, so nothing can be found by handle.
    unhandled: bool,
}

fn hex(value: &[u8]) -> Option<u64> {
    u64::from_str_radix(std::str::from_utf8(value).ok()?, 16).ok()
}

/// The value span of a pair (its value line, without the line end and surrounding blanks).
fn value_span(bytes: &[u8], p: &Pair) -> Span {
    let start = p.value.as_ptr() as usize - bytes.as_ptr() as usize;
    (start, start + p.value.len())
}

/// Pairs of a record of this tool: its record line, and the words after it.
fn is_old_record(value: &[u8]) -> bool {
    crate::compensation::is_own_comment(&String::from_utf8_lossy(value))
}

impl Layout {
    /// Scan ASCII DXF bytes; `None` when they are binary or not a sequence of code/value pairs.
    pub fn scan(bytes: &[u8]) -> Option<Layout> {
        if bytes.starts_with(b"AutoCAD Binary DXF") {
            return None;
        }
        let first_end = bytes.iter().position(|&b| b == b'\n')?;
        let eol = if first_end > 0 && bytes[first_end - 1] == b'\r' {
            "\r\n"
        } else {
            "\n"
        };
        let mut layout = Layout {
            eol,
            entities: HashMap::new(),
            entities_end: None,
            handseed: None,
            max_handle: 0,
            old_records: Vec::new(),
            unhandled: false,
        };
        let mut pairs = Pairs::new(bytes, 0);
        let mut section: &[u8] = b"";
        let mut prev: Option<Pair> = None;
        let mut open: Option<(Option<u64>, Scanned)> = None;
        let mut in_follower = false;
        let mut seen_zero = false;
        let mut handseed_named = false;
        for p in pairs.by_ref() {
            if p.code == 0 && p.value == b"EOF" {
                // Readers stop here; whatever follows is copied as it is.
                break;
            }
            if p.code == 0 {
                seen_zero = true;
                if section == b"ENTITIES" {
                    layout.entity_starts(&p, &mut open, &mut in_follower);
                }
                if p.value == b"ENDSEC" {
                    section = b"";
                }
            } else if p.code == 2 && prev.is_some_and(|q| q.code == 0 && q.value == b"SECTION") {
                section = p.value;
            } else if p.code == 999 && !seen_zero && is_old_record(p.value) {
                layout.old_records.push((p.start, p.end));
            }
            if section == b"HEADER" {
                handseed_named |= p.code == 9 && p.value == b"$HANDSEED";
                if p.code == 5 && prev.is_some_and(|q| q.code == 9 && q.value == b"$HANDSEED") {
                    layout.handseed = hex(p.value).map(|h| (value_span(bytes, &p), h));
                }
            } else if matches!(p.code, 5 | 105)
                && let Some(h) = hex(p.value)
            {
                layout.max_handle = layout.max_handle.max(h);
            }
            if let Some((handle, scanned)) = open.as_mut().filter(|_| !in_follower) {
                match p.code {
                    5 if handle.is_none() => *handle = hex(p.value),
                    102 => scanned.in_group = p.value.starts_with(b"{"),
                    330 if scanned.owner.is_none() && !scanned.in_group => {
                        scanned.owner = Some(value_span(bytes, &p));
                    }
                    _ => {}
                }
            }
            // The `dxf` crate skips comments between a pair and the one it belongs to.
            if p.code != 999 {
                prev = Some(p);
            }
        }
        // An ENTITIES section that never ended has no place for new entities.
        layout.close(open.take(), bytes.len());
        // A `$HANDSEED` whose value was not found could not be moved past the new handles.
        if pairs.broken || layout.unhandled || (handseed_named && layout.handseed.is_none()) {
            return None;
        }
        Some(layout)
    }

    /// A `0` pair `p` in the `ENTITIES` section: a follower of the `open` entity (`VERTEX`,
    /// `ATTRIB`, `SEQEND`), the start of the next one, or the section's end.
    fn entity_starts(
        &mut self,
        p: &Pair,
        open: &mut Option<(Option<u64>, Scanned)>,
        in_follower: &mut bool,
    ) {
        if matches!(p.value, b"VERTEX" | b"SEQEND" | b"ATTRIB") && open.is_some() {
            *in_follower = true;
            return;
        }
        self.close(open.take(), p.start);
        *in_follower = false;
        if p.value == b"ENDSEC" {
            self.entities_end = Some(p.start);
        } else {
            let span = (p.start, p.end);
            let scanned = Scanned {
                span,
                owner: None,
                in_group: false,
            };
            *open = Some((None, scanned));
        }
    }

    /// Record the entity `open` that ends at `end`.
    fn close(&mut self, open: Option<(Option<u64>, Scanned)>, end: usize) {
        let Some((handle, mut scanned)) = open else {
            return;
        };
        let Some(handle) = handle.filter(|&h| h != 0) else {
            self.unhandled = true;
            return;
        };
        scanned.span.1 = end;
        self.entities
            .entry(handle)
            .and_modify(|e| *e = None)
            .or_insert(Some(scanned));
    }

    /// The entity with `handle`, when it is there once.
    fn entity(&self, handle: u64) -> Option<Scanned> {
        self.entities.get(&handle).copied().flatten()
    }
}

/// What is done to one entity of the input.
#[derive(Debug, Clone, Copy)]
pub(super) enum Change {
    /// A closed `LWPOLYLINE` whose vertices become the contour.
    Vertices,
    /// A `CIRCLE` whose centre becomes (x, y, z) and radius r (drawing units).
    Circle([f64; 4]),
    /// Left out (replaced by a new `LWPOLYLINE`).
    Drop,
}

/// The changes to make, found in the input: each entity to change, by its span.
pub(super) struct Splice<'p> {
    layout: Layout,
    /// (span, change, contour) in file order.
    edits: Vec<(Span, Change, Option<&'p Pline>)>,
    /// New `LWPOLYLINE`s: the entity whose properties they take, and the contour.
    added: Vec<(Scanned, &'p Pline)>,
}

impl<'p> Splice<'p> {
    pub fn new(layout: Layout) -> Self {
        Splice {
            layout,
            edits: Vec::new(),
            added: Vec::new(),
        }
    }

    /// Change the entity `handle` (its type, as the file writes it, must be `kind`); `false`
    /// when it cannot be found once.
    pub fn change(
        &mut self,
        bytes: &[u8],
        handle: u64,
        kind: &[u8],
        change: Change,
        contour: Option<&'p Pline>,
    ) -> bool {
        let Some(e) = self.layout.entity(handle) else {
            return false;
        };
        let first = Pairs::new(bytes, e.span.0).next();
        if !first.is_some_and(|p| p.code == 0 && p.value.eq_ignore_ascii_case(kind)) {
            return false;
        }
        self.edits.push((e.span, change, contour));
        true
    }

    /// Add a new closed `LWPOLYLINE` for `contour` with the properties of entity `like`.
    pub fn add(&mut self, like: u64, contour: &'p Pline) -> bool {
        let Some(e) = self.layout.entity(like) else {
            return false;
        };
        self.added.push((e, contour));
        true
    }

    /// The spliced file: `record` first, then the input with the changes (numbers written as
    /// `precision` says); `None` when the changes cannot be placed (an entity changed twice, or
    /// nowhere to add new ones). The changed entities' text is made on every core, a batch at a
    /// time, and put in file order.
    pub fn write(
        mut self,
        bytes: &[u8],
        record: Option<&str>,
        precision: Precision,
    ) -> Option<Vec<u8>> {
        let eol = self.layout.eol;
        let mut out = Out {
            bytes: Vec::with_capacity(bytes.len() + bytes.len() / 4),
            eol,
            precision,
        };
        if let Some(record) = record {
            let record = record.replace("\r\n", "\n").replace('\n', eol);
            out.bytes.extend_from_slice(record.as_bytes());
        }
        let mut next_handle = self
            .layout
            .handseed
            .map_or(0, |(_, h)| h)
            .max(self.layout.max_handle.checked_add(1)?);
        let first_new = next_handle;
        next_handle = next_handle.checked_add(self.added.len() as u64)?;
        let mut cuts: Vec<(Span, Cut)> = self
            .edits
            .drain(..)
            .map(|(span, change, contour)| (span, Cut::Entity(change, contour)))
            .collect();
        cuts.extend(self.layout.old_records.iter().map(|&s| (s, Cut::Remove)));
        if !self.added.is_empty() {
            let at = self.layout.entities_end?;
            cuts.push(((at, at), Cut::Insert));
            if let Some((span, _)) = self.layout.handseed {
                cuts.push((span, Cut::Handseed(next_handle)));
            }
        }
        cuts.sort_by_key(|(span, _)| *span);
        let mut at = 0;
        for batch in cuts.chunks(WRITE_BATCH) {
            let made: Vec<Option<Vec<u8>>> = batch
                .par_iter()
                .map(|(span, cut)| {
                    let mut piece = out.sibling();
                    cut.write(bytes, *span, &mut piece)?;
                    Some(piece.bytes)
                })
                .collect();
            for ((span, cut), piece) in batch.iter().zip(made) {
                if span.0 < at {
                    // Two changes to one place.
                    return None;
                }
                out.bytes.extend_from_slice(&bytes[at..span.0]);
                if matches!(cut, Cut::Insert) {
                    self.write_added(bytes, first_new, &mut out);
                }
                out.bytes.extend_from_slice(&piece?);
                at = span.1;
            }
        }
        out.bytes.extend_from_slice(&bytes[at..]);
        Some(out.bytes)
    }

    /// The new entities, handles from `first_handle` on, straight into `out`: formatted on every
    /// core a batch at a time, so that no more than a batch's text is held beside the output.
    fn write_added(&self, bytes: &[u8], first_handle: u64, out: &mut Out) {
        for (b, batch) in self.added.chunks(WRITE_BATCH).enumerate() {
            let first = first_handle + (b * WRITE_BATCH) as u64;
            let made: Vec<Vec<u8>> = batch
                .par_iter()
                .enumerate()
                .map(|(k, (like, contour))| {
                    let mut new = out.sibling();
                    new_lwpolyline(bytes, like, first + k as u64, contour, &mut new);
                    new.bytes
                })
                .collect();
            for text in made {
                out.bytes.extend_from_slice(&text);
            }
        }
    }
}

/// One change to the input, at a span.
enum Cut<'p> {
    Entity(Change, Option<&'p Pline>),
    Remove,
    /// The new entities (written by [`Splice::write_added`], not here).
    Insert,
    Handseed(u64),
}

impl Cut<'_> {
    fn write(&self, bytes: &[u8], span: Span, out: &mut Out) -> Option<()> {
        match *self {
            Cut::Entity(Change::Drop, _) | Cut::Remove => {}
            Cut::Entity(Change::Vertices, contour) => edit_lwpolyline(bytes, span, contour?, out)?,
            Cut::Entity(Change::Circle(c), _) => edit_circle(bytes, span, c, out)?,
            Cut::Insert => {}
            Cut::Handseed(h) => {
                let _ = write!(out.bytes, "{h:X}");
            }
        }
        Some(())
    }
}

/// How the dilated contours' numbers are written: mm per drawing unit, and the decimals of a
/// coordinate (in drawing units) and of a bulge.
#[derive(Debug, Clone, Copy)]
pub(super) struct Precision {
    pub mm_per_unit: f64,
    pub unit_digits: i32,
    pub bulge_digits: i32,
}

/// Where the spliced file is written, and how: the file's line end, and the precision of the
/// dilated contours' numbers.
struct Out {
    bytes: Vec<u8>,
    eol: &'static str,
    precision: Precision,
}

impl Out {
    /// An empty output written the same way (for pieces placed later).
    fn sibling(&self) -> Out {
        Out {
            bytes: Vec::new(),
            ..*self
        }
    }

    /// A group code line, right-aligned in three columns as the `dxf` crate writes it.
    fn code(&mut self, code: i32) {
        if (0..1000).contains(&code) {
            let width = if code >= 100 {
                0
            } else if code >= 10 {
                1
            } else {
                2
            };
            self.bytes.extend_from_slice(&b"  "[..width]);
            self.bytes
                .extend_from_slice(itoa::Buffer::new().format(code).as_bytes());
        } else {
            let _ = write!(self.bytes, "{code:>3}");
        }
        self.bytes.extend_from_slice(self.eol.as_bytes());
    }

    fn pair(&mut self, code: i32, value: &str) {
        self.code(code);
        self.bytes.extend_from_slice(value.as_bytes());
        self.bytes.extend_from_slice(self.eol.as_bytes());
    }

    fn pair_number(&mut self, code: i32, v: f64) {
        self.code(code);
        number(v, &mut self.bytes);
        self.bytes.extend_from_slice(self.eol.as_bytes());
    }

    /// A pair whose number is `v` rounded to `digits` decimals.
    fn pair_fixed(&mut self, code: i32, v: f64, digits: i32) {
        self.code(code);
        fixed(v, digits, &mut self.bytes);
        self.bytes.extend_from_slice(self.eol.as_bytes());
    }

    /// A pair of the input `bytes` as it is written there.
    fn copy(&mut self, bytes: &[u8], p: &Pair) {
        self.bytes.extend_from_slice(&bytes[p.start..p.end]);
    }

    /// The vertices of a closed contour (mm) as `LWPOLYLINE` pairs.
    fn vertices(&mut self, contour: &Pline) {
        let p = self.precision;
        for v in contour.iter_vertexes() {
            self.pair_fixed(10, v.x / p.mm_per_unit, p.unit_digits);
            self.pair_fixed(20, v.y / p.mm_per_unit, p.unit_digits);
            if rounded(v.bulge, p.bulge_digits) != 0.0 {
                self.pair_fixed(42, v.bulge, p.bulge_digits);
            }
        }
    }
}

/// A number as DXF text: the shortest form that reads back as `v`, with a decimal point.
fn number(v: f64, out: &mut Vec<u8>) {
    let start = out.len();
    let _ = write!(out, "{v}");
    if !out[start..]
        .iter()
        .any(|b| matches!(b, b'.' | b'e' | b'E' | b'N' | b'i'))
    {
        out.extend_from_slice(b".0");
    }
}

/// `v` rounded to `digits` decimals as DXF text: what [`number`] writes of the rounded value (the
/// shortest text that reads back as it, with a point), printed from the integer count of its
/// last decimal. Below 10¹⁵ of those the rounded decimal is that shortest text: any shorter one
/// is at least a last decimal away, more than the value's float step. Beyond, or not finite, the
/// float is formatted.
fn fixed(v: f64, digits: i32, out: &mut Vec<u8>) {
    let m = pow10(digits);
    let n = (v * m).round();
    if !(n.abs() < 1e15 && (0..=19).contains(&digits)) {
        number(rounded(v, digits), out);
        return;
    }
    if (n / m).is_sign_negative() {
        out.push(b'-');
    }
    if !write_scaled(n.abs() as u64, digits as usize, |s| {
        out.extend_from_slice(s.as_bytes())
    }) {
        out.extend_from_slice(b".0");
    }
}

/// An `LWPOLYLINE` (at `span`) with the vertices of `contour`, closed, its other pairs as read.
fn edit_lwpolyline(bytes: &[u8], span: Span, contour: &Pline, out: &mut Out) -> Option<()> {
    let (mut counts, mut placed) = (0, false);
    for p in Pairs::new(&bytes[..span.1], span.0) {
        match p.code {
            90 => {
                counts += 1;
                out.pair(90, &contour.vertex_count().to_string());
            }
            70 => {
                let flags: i32 = std::str::from_utf8(p.value).ok()?.parse().ok()?;
                out.pair(70, &(flags | 1).to_string());
            }
            10 if !placed => {
                placed = true;
                out.vertices(contour);
            }
            10 | 20 | 30 | 40 | 41 | 42 | 91 | 210 | 220 | 230 => {}
            _ => out.copy(bytes, &p),
        }
    }
    (counts == 1 && placed).then_some(())
}

/// A `CIRCLE` (at `span`) with centre and radius `c` (x, y, z, r), its other pairs as read.
fn edit_circle(bytes: &[u8], span: Span, c: [f64; 4], out: &mut Out) -> Option<()> {
    let (mut centre, mut radius) = (false, false);
    for p in Pairs::new(&bytes[..span.1], span.0) {
        match p.code {
            10 if !centre => {
                centre = true;
                out.pair_number(10, c[0]);
                out.pair_number(20, c[1]);
                out.pair_number(30, c[2]);
            }
            40 if !radius => {
                radius = true;
                out.pair_number(40, c[3]);
            }
            10 | 20 | 30 | 40 | 210 | 220 | 230 => {}
            _ => out.copy(bytes, &p),
        }
    }
    (centre && radius).then_some(())
}

/// A new closed `LWPOLYLINE` for `contour`, handle `handle`, with the owner and the layer,
/// linetype, colour and lineweight pairs of the entity `like` as the file writes them.
fn new_lwpolyline(bytes: &[u8], like: &Scanned, handle: u64, contour: &Pline, out: &mut Out) {
    out.pair(0, "LWPOLYLINE");
    out.pair(5, &format!("{handle:X}"));
    if let Some((s, e)) = like.owner {
        let eol = out.eol.as_bytes();
        out.bytes.extend_from_slice(b"330");
        out.bytes.extend_from_slice(eol);
        out.bytes.extend_from_slice(&bytes[s..e]);
        out.bytes.extend_from_slice(eol);
    }
    out.pair(100, "AcDbEntity");
    let mut seen: Vec<i32> = Vec::new();
    // The entity's own pairs, up to its first follower (a POLYLINE's VERTEX).
    for p in Pairs::new(&bytes[..like.span.1], like.span.0)
        .skip(1)
        .take_while(|p| p.code != 0)
    {
        if matches!(p.code, 6 | 8 | 62 | 370 | 420) && !seen.contains(&p.code) {
            seen.push(p.code);
            out.copy(bytes, &p);
        }
    }
    if !seen.contains(&8) {
        out.pair(8, "0");
    }
    out.pair(100, "AcDbPolyline");
    out.pair(90, &contour.vertex_count().to_string());
    out.pair(70, "1");
    out.vertices(contour);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_are_read_with_their_spans_and_a_broken_file_says_so() {
        let text = b"  0\r\nSECTION\r\n  2\r\nHEADER\r\n";
        let pairs: Vec<Pair> = Pairs::new(text, 0).collect();
        assert_eq!(pairs.len(), 2);
        assert_eq!((pairs[0].code, pairs[0].value), (0, &b"SECTION"[..]));
        assert_eq!((pairs[1].start, pairs[1].end), (14, text.len()));
        let mut broken = Pairs::new(b"0\nSECTION\nx\ny\n", 0);
        assert_eq!(broken.by_ref().count(), 1);
        assert!(broken.broken);
    }

    #[test]
    fn rounded_numbers_are_written_as_the_float_formatter_writes_them() {
        // A small deterministic generator: values of every magnitude the writer meets, signs,
        // exact ties, zeros and the decimals of mm, inches, µm and bulges.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut values = vec![0.0, -0.0, 1e-9, -1e-9, 0.5, -0.5, 2.5e-5, 123.456_785, 1e7];
        for _ in 0..20_000 {
            let mantissa = (next() % 2_000_000) as f64 / 1_000_000.0 - 1.0;
            let exponent = (next() % 16) as i32 - 8;
            values.push(mantissa * 10f64.powi(exponent));
        }
        for v in values {
            for digits in [0, 1, 4, 5, 7, 10, 12] {
                let (mut fast, mut formatted) = (Vec::new(), Vec::new());
                fixed(v, digits, &mut fast);
                number(rounded(v, digits), &mut formatted);
                assert_eq!(
                    String::from_utf8(fast).unwrap(),
                    String::from_utf8(formatted).unwrap(),
                    "{v:e} to {digits} decimals"
                );
            }
        }
    }

    #[test]
    fn codes_are_right_aligned_in_three_columns() {
        let mut out = Out {
            bytes: Vec::new(),
            eol: "\n",
            precision: Precision {
                mm_per_unit: 1.0,
                unit_digits: 5,
                bulge_digits: 10,
            },
        };
        for code in [0, 5, 10, 42, 100, 330, 999, 1000, 1071, -1] {
            out.code(code);
        }
        let expected: String = [0, 5, 10, 42, 100, 330, 999, 1000, 1071, -1]
            .iter()
            .map(|c| format!("{c:>3}\n"))
            .collect();
        assert_eq!(String::from_utf8(out.bytes).unwrap(), expected);
    }

    #[test]
    fn numbers_read_back_exactly_and_keep_a_decimal_point() {
        for v in [0.0, 100.0, -3.5, 12.34567, 1e-7, 254.00001] {
            let mut s = Vec::new();
            number(v, &mut s);
            let s = String::from_utf8(s).unwrap();
            assert!(s.contains('.'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap(), v);
        }
    }
}
