//! A drawing made new with the `dxf` crate and saved by it (the gauge): the crate writes no
//! handle on a table's head (`0 TABLE`), which drawings from R13 on give every object, so ezdxf's
//! audit had to fix seven of them in every gauge. Here each table head without one is given a new
//! handle (past every handle of the file, `$HANDSEED` moved past them). Nothing else is changed:
//! a drawing the crate builds afresh is otherwise as other programs read it (the faults of its
//! writer come with drawings it loaded, which are never written by it).

use super::layout::{Layout, Pairs, Span};

/// `text` (an ASCII DXF) with a handle on every table head; why not, when it is not a DXF.
pub(crate) fn with_table_handles(text: &[u8]) -> Result<Vec<u8>, String> {
    let layout = Layout::scan(text)?;
    let eol = layout.eol;
    let mut next = layout
        .handseed
        .map_or(0, |(_, h)| h)
        .max(layout.max_handle + 1);
    let mut edits: Vec<(Span, String)> = Vec::new();
    let pairs: Vec<_> = Pairs::new(text, 0).collect();
    for w in pairs.windows(3) {
        if w[0].code == 0 && w[0].value == b"TABLE" && w[1].code == 2 && w[2].code != 5 {
            edits.push(((w[1].end, w[1].end), format!("  5{eol}{next:X}{eol}")));
            next = next.saturating_add(1);
        }
    }
    if let Some((span, _)) = layout.handseed {
        edits.push((span, format!("{next:X}")));
    }
    edits.sort_by_key(|(span, _)| *span);
    let mut out = Vec::with_capacity(text.len() + edits.len() * 16);
    let mut at = 0;
    for ((start, end), new) in edits {
        out.extend_from_slice(&text[at..start]);
        out.extend_from_slice(new.as_bytes());
        at = end;
    }
    out.extend_from_slice(&text[at..]);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_heads_get_new_handles_and_the_seed_moves_past_them() {
        let text = "  0\nSECTION\n  2\nHEADER\n  9\n$HANDSEED\n  5\n20\n  0\nENDSEC\n  0\nSECTION\n  2\nTABLES\n  0\nTABLE\n  2\nLAYER\n 70\n1\n  0\nLAYER\n  5\n2A\n  2\n0\n  0\nENDTAB\n  0\nTABLE\n  2\nLTYPE\n  5\n3\n  0\nENDTAB\n  0\nENDSEC\n  0\nEOF\n";
        let out = String::from_utf8(with_table_handles(text.as_bytes()).unwrap()).unwrap();
        assert!(
            out.contains("TABLE\n  2\nLAYER\n  5\n2B\n 70\n1\n"),
            "{out}"
        );
        assert!(
            out.contains("TABLE\n  2\nLTYPE\n  5\n3\n  0\nENDTAB"),
            "{out}"
        );
        assert!(out.contains("$HANDSEED\n  5\n2C\n"), "{out}");
    }
}
