//! Where things are in an ASCII DXF file: a scan of its code/value lines ([`Pairs`]), not a
//! parse (the `dxf` crate parses the drawing). It finds the byte span of every entity of the
//! `ENTITIES` section and of each block of the `BLOCKS` section (with its `VERTEX`, `ATTRIB` and
//! `SEQEND` followers), the header values a dilation may change (`$HANDSEED`, `$INSUNITS`), the
//! largest handle in the file, and an earlier record of this tool at the top.
//!
//! The spans are matched with the entities the crate read by their order (see the `placing`
//! submodule), so an entity needs no handle, and a handle used twice does no harm.

use std::collections::HashMap;

/// A byte range of the file.
pub(super) type Span = (usize, usize);

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
/// a pair (`broken` then says where that line starts).
pub(super) struct Pairs<'a> {
    bytes: &'a [u8],
    at: usize,
    pub broken: Option<usize>,
}

impl<'a> Pairs<'a> {
    pub fn new(bytes: &'a [u8], from: usize) -> Self {
        Pairs {
            bytes,
            at: from,
            broken: None,
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
            self.broken = Some(start);
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

/// An entity as scanned: its span (with its followers), where its type name is, its handle (when
/// it has one), and where its owner handle's value is.
#[derive(Debug, Clone, Copy)]
pub(super) struct Scanned {
    pub span: Span,
    pub kind: Span,
    pub handle: Option<u64>,
    pub owner: Option<Span>,
}

impl Scanned {
    /// The entity's type name as the file writes it.
    pub fn kind<'b>(&self, bytes: &'b [u8]) -> &'b [u8] {
        &bytes[self.kind.0..self.kind.1]
    }

    /// The entity's own pairs (not its followers, nor the pairs inside `102 {…}` application
    /// groups, nor its extended data), after its type.
    pub fn own_pairs<'b>(&self, bytes: &'b [u8]) -> impl Iterator<Item = Pair<'b>> {
        let mut in_group = false;
        Pairs::new(&bytes[..self.span.1], self.span.0)
            .skip(1)
            .take_while(|p| p.code != 0 && p.code != 1001)
            .filter(move |p| {
                if p.code == 102 {
                    in_group = p.value.starts_with(b"{");
                    return false;
                }
                !in_group
            })
    }
}

/// A block of the `BLOCKS` section: its entities in file order.
#[derive(Debug, Default)]
pub(super) struct ScannedBlock {
    pub entities: Vec<Scanned>,
}

/// Where things are in an ASCII DXF file.
pub(super) struct Layout {
    /// The file's line end.
    pub eol: &'static str,
    /// The entities of the `ENTITIES` section, in file order.
    pub model: Vec<Scanned>,
    /// The blocks by upper-case name (`None`: two blocks have the name).
    pub blocks: HashMap<String, Option<ScannedBlock>>,
    /// Where the `ENTITIES` section's `ENDSEC` pair starts.
    pub entities_end: Option<usize>,
    /// Where the `HEADER` section's `ENDSEC` pair starts.
    pub header_end: Option<usize>,
    /// The `$HANDSEED` value's span in the header, and its value.
    pub handseed: Option<(Span, u64)>,
    /// The `$INSUNITS` value's span in the header.
    pub insunits: Option<Span>,
    /// The largest handle given to anything outside the header.
    pub max_handle: u64,
    /// Pairs at the top of the file that are an earlier record of this tool, to drop.
    pub old_records: Vec<Span>,
    /// Values of `5` pairs in `DIMSTYLE` records that are not handles (an R12 dimension style's
    /// arrow block name, which the `dxf` crate reads as a handle and stops on).
    pub dimstyle_names: Vec<Span>,
}

fn hex(value: &[u8]) -> Option<u64> {
    u64::from_str_radix(std::str::from_utf8(value).ok()?, 16).ok()
}

/// The value span of a pair (its value line, without the line end and surrounding blanks).
pub(super) fn value_span(bytes: &[u8], p: &Pair) -> Span {
    let start = p.value.as_ptr() as usize - bytes.as_ptr() as usize;
    (start, start + p.value.len())
}

/// Pairs of a record of this tool: its record line, and the words after it.
fn is_old_record(value: &[u8]) -> bool {
    crate::compensation::is_own_comment(&String::from_utf8_lossy(value))
}

/// Whether a `0` pair of type `follower` belongs to the entity of type `open` before it (as the
/// `dxf` crate gathers them: a `POLYLINE`'s vertices, an `INSERT`'s attributes, and the `SEQEND`
/// that ends them).
fn follows(open: &[u8], follower: &[u8]) -> bool {
    match follower {
        b"VERTEX" => open == b"POLYLINE",
        b"ATTRIB" => open == b"INSERT",
        b"SEQEND" => open == b"POLYLINE" || open == b"INSERT",
        _ => false,
    }
}

/// The state of a scan: which section and block it is in, and the entity being read.
struct Scan<'a> {
    bytes: &'a [u8],
    layout: Layout,
    section: &'a [u8],
    /// The block being read (upper-case name, its entities), from its `BLOCK` pair to `ENDBLK`.
    block: Option<(Option<String>, ScannedBlock)>,
    /// The entity being read (its type, and its scan so far) and whether its followers started.
    open: Option<(&'a [u8], Scanned)>,
    in_follower: bool,
    in_group: bool,
    /// The table record being read (its type).
    record: &'a [u8],
}

impl Layout {
    /// Scan ASCII DXF bytes; why not, when they are not a sequence of code/value pairs.
    pub fn scan(bytes: &[u8]) -> Result<Layout, String> {
        let first_end = bytes
            .iter()
            .position(|&b| b == b'\n')
            .unwrap_or(bytes.len());
        let eol = if first_end > 0 && bytes[first_end - 1] == b'\r' {
            "\r\n"
        } else {
            "\n"
        };
        let from = if bytes.starts_with("\u{feff}".as_bytes()) {
            3
        } else {
            0
        };
        let mut scan = Scan {
            bytes,
            layout: Layout {
                eol,
                model: Vec::new(),
                blocks: HashMap::new(),
                entities_end: None,
                header_end: None,
                handseed: None,
                insunits: None,
                max_handle: 0,
                old_records: Vec::new(),
                dimstyle_names: Vec::new(),
            },
            section: b"",
            block: None,
            open: None,
            in_follower: false,
            in_group: false,
            record: b"",
        };
        let mut pairs = Pairs::new(bytes, from);
        let mut prev: Option<Pair> = None;
        let mut seen_zero = false;
        let mut handseed_named = false;
        for p in pairs.by_ref() {
            if p.code == 0 && p.value == b"EOF" {
                // Readers stop here; whatever follows is copied as it is.
                break;
            }
            seen_zero |= p.code == 0;
            if p.code == 999 && !seen_zero && is_old_record(p.value) {
                scan.layout.old_records.push((p.start, p.end));
            }
            handseed_named |= scan.section == b"HEADER" && p.code == 9 && p.value == b"$HANDSEED";
            scan.pair(&p, prev.as_ref());
            // The `dxf` crate skips comments between a pair and the one it belongs to.
            if p.code != 999 {
                prev = Some(p);
            }
        }
        scan.close_entity(bytes.len());
        if let Some(at) = pairs.broken {
            let line = bytes[..at].iter().filter(|&&b| b == b'\n').count() + 1;
            return Err(format!(
                "line {line} is not a group code followed by its value"
            ));
        }
        // A `$HANDSEED` whose value was not found could not be moved past the new handles.
        if handseed_named && scan.layout.handseed.is_none() {
            return Err("its $HANDSEED has no handle value".into());
        }
        Ok(scan.layout)
    }
}

impl<'a> Scan<'a> {
    /// One pair (`prev`: the pair before it, comments skipped).
    fn pair(&mut self, p: &Pair<'a>, prev: Option<&Pair<'a>>) {
        let after =
            |code: i32, value: &[u8]| prev.is_some_and(|q| q.code == code && q.value == value);
        if p.code == 2 && after(0, b"SECTION") {
            self.section = p.value;
            return;
        }
        if p.code == 0 && p.value == b"ENDSEC" {
            self.end_section(p.start);
            return;
        }
        match self.section {
            b"HEADER" => self.header_pair(p, prev),
            b"TABLES" => self.table_pair(p),
            b"ENTITIES" | b"BLOCKS" => self.entity_pair(p),
            _ => self.handle_pair(p),
        }
    }

    fn end_section(&mut self, at: usize) {
        self.close_entity(at);
        match self.section {
            b"HEADER" => self.layout.header_end = Some(at),
            b"ENTITIES" => self.layout.entities_end = Some(at),
            _ => {}
        }
        self.section = b"";
    }

    fn header_pair(&mut self, p: &Pair<'a>, prev: Option<&Pair<'a>>) {
        let variable = prev.filter(|q| q.code == 9).map(|q| q.value);
        match (variable, p.code) {
            (Some(b"$HANDSEED"), 5) => {
                self.layout.handseed = hex(p.value).map(|h| (value_span(self.bytes, p), h));
            }
            (Some(b"$INSUNITS"), 70) => self.layout.insunits = Some(value_span(self.bytes, p)),
            _ => {}
        }
    }

    fn table_pair(&mut self, p: &Pair<'a>) {
        if p.code == 0 {
            self.record = p.value;
        } else if p.code == 5 && self.record == b"DIMSTYLE" && hex(p.value).is_none() {
            self.layout.dimstyle_names.push(value_span(self.bytes, p));
            return;
        }
        self.handle_pair(p);
    }

    /// A handle of anything (`5`, or a dimension style's `105`): the largest is kept.
    fn handle_pair(&mut self, p: &Pair<'a>) {
        if matches!(p.code, 5 | 105)
            && let Some(h) = hex(p.value)
        {
            self.layout.max_handle = self.layout.max_handle.max(h);
        }
    }

    /// A pair of the `ENTITIES` or `BLOCKS` section.
    fn entity_pair(&mut self, p: &Pair<'a>) {
        self.handle_pair(p);
        if p.code == 0 {
            self.entity_starts(p);
            return;
        }
        if self.in_follower {
            return;
        }
        if let Some((_, scanned)) = self.open.as_mut() {
            match p.code {
                5 if scanned.handle.is_none() => scanned.handle = hex(p.value).filter(|&h| h != 0),
                102 => self.in_group = p.value.starts_with(b"{"),
                330 if scanned.owner.is_none() && !self.in_group => {
                    scanned.owner = Some(value_span(self.bytes, p));
                }
                _ => {}
            }
        } else if let Some((name, _)) = self.block.as_mut()
            && p.code == 2
            && name.is_none()
        {
            *name = Some(String::from_utf8_lossy(p.value).to_uppercase());
        }
    }

    /// A `0` pair in `ENTITIES` or `BLOCKS`: a follower of the open entity, a block's start or
    /// end, or the start of the next entity.
    fn entity_starts(&mut self, p: &Pair<'a>) {
        if let Some((kind, _)) = self.open
            && follows(kind, p.value)
        {
            self.in_follower = true;
            return;
        }
        self.close_entity(p.start);
        let in_blocks = self.section == b"BLOCKS";
        match p.value {
            b"BLOCK" if in_blocks => self.block = Some((None, ScannedBlock::default())),
            b"ENDBLK" if in_blocks => self.end_block(),
            kind => {
                let scanned = Scanned {
                    span: (p.start, p.end),
                    kind: value_span(self.bytes, p),
                    handle: None,
                    owner: None,
                };
                self.open = Some((kind, scanned));
            }
        }
    }

    /// Record the open entity, which ends at `end`.
    fn close_entity(&mut self, end: usize) {
        self.in_follower = false;
        self.in_group = false;
        let Some((_, mut scanned)) = self.open.take() else {
            return;
        };
        scanned.span.1 = end;
        match (self.section, self.block.as_mut()) {
            (b"ENTITIES", _) => self.layout.model.push(scanned),
            (b"BLOCKS", Some((_, block))) => block.entities.push(scanned),
            _ => {}
        }
    }

    fn end_block(&mut self) {
        let Some((Some(name), block)) = self.block.take() else {
            return;
        };
        self.layout
            .blocks
            .entry(name)
            .and_modify(|b| *b = None)
            .or_insert(Some(block));
    }
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
        assert_eq!(broken.broken, Some(10));
        let blank = Layout::scan(b"  0\nSECTION\n\n  2\nENTITIES\n")
            .err()
            .unwrap();
        assert_eq!(blank, "line 3 is not a group code followed by its value");
    }

    #[test]
    fn entities_blocks_and_header_values_are_found() {
        let text = "999\nkerfmeter-compensation tool=kerfmeter offset_um=75\n0\nSECTION\n2\nHEADER\n9\n$HANDSEED\n5\n20\n9\n$INSUNITS\n70\n4\n0\nENDSEC\n\
            0\nSECTION\n2\nTABLES\n0\nTABLE\n2\nDIMSTYLE\n0\nDIMSTYLE\n105\n1A\n2\nSTANDARD\n5\nOPEN30\n0\nENDTAB\n0\nENDSEC\n\
            0\nSECTION\n2\nBLOCKS\n0\nBLOCK\n5\n21\n2\nPart\n0\nCIRCLE\n5\n22\n40\n1.0\n0\nPOLYLINE\n5\n23\n0\nVERTEX\n5\n24\n0\nSEQEND\n5\n25\n0\nENDBLK\n5\n26\n0\nENDSEC\n\
            0\nSECTION\n2\nENTITIES\n0\nINSERT\n5\n27\n102\n{ACAD_REACTORS\n330\n99\n102\n}\n330\n1F\n2\nPART\n0\nLINE\n8\n0\n0\nENDSEC\n0\nEOF\n";
        let bytes = text.as_bytes();
        let layout = Layout::scan(bytes).expect("a layout");
        assert_eq!(layout.old_records.len(), 1);
        assert_eq!(layout.handseed.map(|(_, h)| h), Some(0x20));
        let units = layout.insunits.expect("$INSUNITS");
        assert_eq!(&bytes[units.0..units.1], b"4");
        assert_eq!(layout.max_handle, 0x27);
        assert_eq!(layout.dimstyle_names.len(), 1);
        let model: Vec<&[u8]> = layout.model.iter().map(|e| e.kind(bytes)).collect();
        assert_eq!(model, [&b"INSERT"[..], b"LINE"]);
        let insert = layout.model[0];
        assert_eq!(insert.handle, Some(0x27));
        let owner = insert.owner.expect("its owner, not its reactor");
        assert_eq!(&bytes[owner.0..owner.1], b"1F");
        let name = insert.own_pairs(bytes).find(|p| p.code == 2);
        assert_eq!(name.map(|p| p.value), Some(&b"PART"[..]));
        assert_eq!(layout.model[1].handle, None);
        let part = layout.blocks["PART"].as_ref().expect("one block PART");
        let kinds: Vec<&[u8]> = part.entities.iter().map(|e| e.kind(bytes)).collect();
        assert_eq!(kinds, [&b"CIRCLE"[..], b"POLYLINE"]);
        // The POLYLINE's span holds its VERTEX and SEQEND.
        let polyline = &bytes[part.entities[1].span.0..part.entities[1].span.1];
        assert!(String::from_utf8_lossy(polyline).ends_with("SEQEND\n5\n25\n"));
        assert!(layout.entities_end.is_some() && layout.header_end.is_some());
    }
}
