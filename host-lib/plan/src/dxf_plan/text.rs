//! The text of what a dilation writes into a DXF: cut entities edited in place, and new closed
//! polylines in the form the drawing's version has.
//!
//! * A closed `LWPOLYLINE` cut gets its new vertices in place (its other pairs kept in order; its
//!   width, vertex id and extrusion pairs dropped); a `CIRCLE` cut gets its new centre and radius
//!   (extrusion dropped: it is written in world coordinates).
//! * A new closed polyline (for a chain, a `POLYLINE`, `ELLIPSE` or `SPLINE`, a circle that did not
//!   stay one, or a cut inside a block) is an `LWPOLYLINE` from R14 on; before, a `POLYLINE` with
//!   its `VERTEX`es (bulges on them) and `SEQEND`, with the subclass markers and owners of R13,
//!   none in R12. Each part gets a new handle when the drawing has handles, and the style pairs
//!   (layer, colour, linetype, lineweight) and owner of what it replaces, copied as the file
//!   writes them.
//!
//! Numbers are printed from the integer count of their last decimal (see the `decimal` module),
//! not by the float formatter, with the same text.

use std::io::Write as _;

use cavalier_contours::polyline::PlineSource;

use super::layout::{Pair, Pairs, Span};
use super::write::rounded;
use crate::decimal::{pow10, write_scaled};
use crate::geom::Pline;

/// How the dilated contours' numbers are written: mm per drawing unit, and the decimals of a
/// coordinate (in drawing units) and of a bulge.
#[derive(Debug, Clone, Copy)]
pub(super) struct Precision {
    pub mm_per_unit: f64,
    pub unit_digits: i32,
    pub bulge_digits: i32,
}

/// The form of a new closed polyline: what the drawing's version has.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Form {
    /// `LWPOLYLINE` (R14 and later).
    LwPolyline,
    /// `POLYLINE`, `VERTEX`es and `SEQEND`, with subclass markers and owners (R13) or without
    /// (R12 and earlier).
    Polyline { subclasses: bool },
}

impl Form {
    /// How many handles a new polyline of `vertices` takes.
    pub fn handles(self, vertices: usize) -> u64 {
        match self {
            Form::LwPolyline => 1,
            Form::Polyline { .. } => vertices as u64 + 2,
        }
    }
}

/// A new closed polyline: its contour (mm), the style pairs it copies (spans of the file), and
/// where the file writes its owner's handle.
pub(super) struct NewPolyline<'p> {
    pub contour: &'p Pline,
    pub style: Vec<Span>,
    pub owner: Option<Span>,
}

/// Where text is written, and how: the file's line end, and the precision of the dilated
/// contours' numbers.
pub(super) struct Out {
    pub bytes: Vec<u8>,
    pub eol: &'static str,
    pub precision: Precision,
}

impl Out {
    /// An empty output written the same way (for pieces placed later).
    pub fn sibling(&self) -> Out {
        Out {
            bytes: Vec::new(),
            ..*self
        }
    }

    /// A group code line, right-aligned in three columns as AutoCAD writes it.
    pub fn code(&mut self, code: i32) {
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

    pub fn pair(&mut self, code: i32, value: &str) {
        self.code(code);
        self.bytes.extend_from_slice(value.as_bytes());
        self.bytes.extend_from_slice(self.eol.as_bytes());
    }

    fn pair_handle(&mut self, code: i32, handle: u64) {
        self.code(code);
        let _ = write!(self.bytes, "{handle:X}");
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

    /// A pair whose value is the span `value` of the input `bytes`.
    fn pair_from(&mut self, code: i32, bytes: &[u8], value: Span) {
        self.code(code);
        self.bytes.extend_from_slice(&bytes[value.0..value.1]);
        self.bytes.extend_from_slice(self.eol.as_bytes());
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
pub(super) fn number(v: f64, out: &mut Vec<u8>) {
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
pub(super) fn edit_lwpolyline(
    bytes: &[u8],
    span: Span,
    contour: &Pline,
    out: &mut Out,
) -> Option<()> {
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
pub(super) fn edit_circle(bytes: &[u8], span: Span, c: [f64; 4], out: &mut Out) -> Option<()> {
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

/// A new closed polyline in `form`, its handles from `first_handle` on when `handles`.
pub(super) fn new_polyline(
    bytes: &[u8],
    new: &NewPolyline,
    form: Form,
    first_handle: Option<u64>,
    out: &mut Out,
) {
    let handle = |k: u64| first_handle.map(|h| h + k);
    match form {
        Form::LwPolyline => {
            entity_head(
                bytes,
                "LWPOLYLINE",
                handle(0),
                Owner::File(new.owner),
                true,
                new,
                out,
            );
            out.pair(100, "AcDbPolyline");
            out.pair(90, &new.contour.vertex_count().to_string());
            out.pair(70, "1");
            out.vertices(new.contour);
        }
        Form::Polyline { subclasses } => {
            let parent = Owner::New(handle(0));
            entity_head(
                bytes,
                "POLYLINE",
                handle(0),
                Owner::File(new.owner),
                subclasses,
                new,
                out,
            );
            if subclasses {
                out.pair(100, "AcDb2dPolyline");
            }
            out.pair(66, "1");
            for code in [10, 20, 30] {
                out.pair(code, "0.0");
            }
            out.pair(70, "1");
            let p = out.precision;
            for (k, v) in new.contour.iter_vertexes().enumerate() {
                entity_head(
                    bytes,
                    "VERTEX",
                    handle(k as u64 + 1),
                    parent,
                    subclasses,
                    new,
                    out,
                );
                if subclasses {
                    out.pair(100, "AcDbVertex");
                    out.pair(100, "AcDb2dVertex");
                }
                out.pair_fixed(10, v.x / p.mm_per_unit, p.unit_digits);
                out.pair_fixed(20, v.y / p.mm_per_unit, p.unit_digits);
                out.pair(30, "0.0");
                if rounded(v.bulge, p.bulge_digits) != 0.0 {
                    out.pair_fixed(42, v.bulge, p.bulge_digits);
                }
            }
            let seqend = handle(new.contour.vertex_count() as u64 + 1);
            entity_head(bytes, "SEQEND", seqend, parent, subclasses, new, out);
        }
    }
}

/// Who owns a new entity: what the file says of the entity it replaces, or a new polyline.
#[derive(Clone, Copy)]
enum Owner {
    File(Option<Span>),
    New(Option<u64>),
}

/// The first pairs of a new entity: type, handle, owner and `AcDbEntity` (with `subclasses`),
/// and its style pairs (layer `0` when it copies none).
fn entity_head(
    bytes: &[u8],
    kind: &str,
    handle: Option<u64>,
    owner: Owner,
    subclasses: bool,
    new: &NewPolyline,
    out: &mut Out,
) {
    out.pair(0, kind);
    if let Some(h) = handle {
        out.pair_handle(5, h);
    }
    if subclasses {
        match owner {
            Owner::File(Some(span)) => out.pair_from(330, bytes, span),
            Owner::New(Some(h)) => out.pair_handle(330, h),
            _ => {}
        }
        out.pair(100, "AcDbEntity");
    }
    let mut has_layer = false;
    for &(start, end) in &new.style {
        has_layer |= Pairs::new(&bytes[..end], start)
            .next()
            .is_some_and(|p| p.code == 8);
        out.bytes.extend_from_slice(&bytes[start..end]);
    }
    if !has_layer {
        out.pair(8, "0");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cavalier_contours::polyline::{PlineSourceMut, PlineVertex};

    fn out() -> Out {
        Out {
            bytes: Vec::new(),
            eol: "\n",
            precision: Precision {
                mm_per_unit: 1.0,
                unit_digits: 5,
                bulge_digits: 10,
            },
        }
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
        let mut out = out();
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

    #[test]
    fn an_r12_polyline_has_vertices_with_bulges_handles_and_no_subclasses() {
        let mut square = Pline::new_closed();
        for (x, y, b) in [(0.0, 0.0, 0.5), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0)] {
            square.add_vertex(PlineVertex::new(x, y, b));
        }
        let style = b"  8\nCUT\n 62\n1\n";
        let new = NewPolyline {
            contour: &square,
            style: vec![(0, style.len())],
            owner: None,
        };
        let mut out = out();
        new_polyline(
            style,
            &new,
            Form::Polyline { subclasses: false },
            Some(0x2A),
            &mut out,
        );
        let text = String::from_utf8(out.bytes).unwrap();
        let kinds: Vec<&str> = text
            .lines()
            .collect::<Vec<_>>()
            .chunks(2)
            .filter(|p| p[0] == "  0")
            .map(|p| p[1])
            .collect();
        assert_eq!(kinds, ["POLYLINE", "VERTEX", "VERTEX", "VERTEX", "SEQEND"]);
        assert!(!text.contains("100\n") && !text.contains("330\n"), "{text}");
        assert_eq!(text.matches("  5\n").count(), 5);
        assert!(text.contains("  5\n2E\n  8\nCUT\n 62\n1\n"), "{text}");
        assert!(
            text.contains(" 42\n0.5\n") && text.contains(" 70\n1\n"),
            "{text}"
        );
        assert_eq!(Form::Polyline { subclasses: false }.handles(3), 5);
        // Without handles (an R12 file that has none), none.
        let mut out2 = super::tests::out();
        new_polyline(
            style,
            &new,
            Form::Polyline { subclasses: false },
            None,
            &mut out2,
        );
        assert!(!String::from_utf8(out2.bytes).unwrap().contains("  5\n"));
    }
}
