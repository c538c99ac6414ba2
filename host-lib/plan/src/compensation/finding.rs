//! Finding a compensation a plan already carries: this tool's own record (in an SVG's
//! metadata and comments, in a DXF's `999` comments), or boxes.py's burn (its command line, its
//! web generator's URL, its reference label).

use super::*;

/// `key=value` fields of a record line (values may be "quoted"), after its [`MARKER`].
pub(super) fn record_fields(line: &str) -> Option<Vec<(String, String)>> {
    let rest = line.trim_start().strip_prefix(MARKER)?;
    let mut fields = Vec::new();
    let mut s = rest.trim_start();
    while let Some(eq) = s.find('=') {
        let key = s[..eq].trim().to_string();
        let after = &s[eq + 1..];
        let (value, next) = match after.strip_prefix('"') {
            Some(q) => {
                let end = q.find('"')?;
                (&q[..end], &q[end + 1..])
            }
            None => {
                let end = after.find(char::is_whitespace).unwrap_or(after.len());
                (&after[..end], &after[end..])
            }
        };
        fields.push((key, value.to_string()));
        s = next.trim_start();
        if s.starts_with(':') || key_is_done(s) {
            break;
        }
    }
    Some(fields)
}

/// Whether what follows the fields is no longer `key=value` (the human part of a comment).
pub(super) fn key_is_done(s: &str) -> bool {
    s.split_whitespace().next().is_none_or(|w| !w.contains('='))
}

/// A record of this tool's, from its fields.
pub(super) fn own_record(fields: &[(String, String)], found_in: &str) -> Option<FoundCompensation> {
    let get = |k: &str| {
        fields
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.as_str())
    };
    if get("tool").is_some_and(|t| t != TOOL) {
        return None;
    }
    let gauge = get("drawing") == Some("gauge");
    // A gauge records its test piece's kerf (the spiral carries none).
    let kerf_key = if gauge {
        "test_piece_kerf_um"
    } else {
        "kerf_um"
    };
    Some(FoundCompensation {
        by: if gauge {
            CompensatedBy::KerfmeterGauge
        } else {
            CompensatedBy::Kerfmeter
        },
        offset_um: RangeUm::parse(get("offset_um")?)?,
        kerf_um: get(kerf_key).and_then(RangeUm::parse),
        rules: get("rules").map(str::to_string),
        version: get("version").map(str::to_string),
        found_in: found_in.into(),
        default_burn: false,
    })
}

/// What an SVG document says about compensation already applied: this tool's record first,
/// then boxes.py's.
pub(crate) fn find_in_svg(doc: &Document) -> Option<FoundCompensation> {
    own_in_svg(doc).or_else(|| boxes_in_svg(doc))
}

pub(super) fn own_in_svg(doc: &Document) -> Option<FoundCompensation> {
    if let Some(e) = doc
        .descendants()
        .find(|n| n.has_tag_name((NAMESPACE, "compensation")))
    {
        let fields: Vec<(String, String)> = e
            .attributes()
            .map(|a| (a.name().to_string(), a.value().to_string()))
            .collect();
        return own_record(&fields, "the SVG's <metadata>");
    }
    doc.descendants()
        .filter(|n| n.is_comment())
        .filter_map(|n| record_fields(n.text()?))
        .find_map(|f| own_record(&f, "an SVG comment"))
}

/// This tool's records in an SVG (the comment and the `kerfmeter:compensation` element, or the
/// `<metadata>` holding only it): the byte ranges to remove when the plan is dilated again.
pub(crate) fn own_svg_records(doc: &Document) -> Vec<std::ops::Range<usize>> {
    let mut ranges = Vec::new();
    for n in doc.descendants() {
        if n.is_comment() && n.text().is_some_and(|t| record_fields(t).is_some()) {
            ranges.push(n.range());
        } else if n.has_tag_name((NAMESPACE, "compensation")) {
            let parent = n.parent_element().filter(|p| {
                p.tag_name().name() == "metadata"
                    && p.children().filter(Node::is_element).count() == 1
            });
            ranges.push(parent.unwrap_or(n).range());
        }
    }
    ranges
}

/// The texts boxes.py writes its command line into: comments, and the text of `<metadata>`,
/// `<desc>` and `<title>` (with where each is).
pub(super) fn svg_texts(doc: &Document) -> Vec<(String, &'static str)> {
    let mut texts = Vec::new();
    for n in doc.descendants() {
        if n.is_comment() {
            if let Some(t) = n.text() {
                texts.push((t.to_string(), "an SVG comment"));
            }
        } else if n.is_element() && matches!(n.tag_name().name(), "metadata" | "desc" | "title") {
            let t: String = n
                .descendants()
                .filter(|d| d.is_text())
                .filter_map(|d| d.text())
                .collect();
            let place = match n.tag_name().name() {
                "metadata" => "the SVG's <metadata>",
                "desc" => "the SVG's <desc>",
                _ => "the SVG's <title>",
            };
            texts.push((t, place));
        }
    }
    // The full command line (metadata) is more complete than the comment's short one.
    texts.sort_by_key(|(_, place)| *place == "an SVG comment");
    texts
}

pub(super) fn boxes_in_svg(doc: &Document) -> Option<FoundCompensation> {
    let texts = svg_texts(doc);
    let is_boxes = texts.iter().any(|(t, _)| is_boxes_text(t));
    let found = |burn_mm: f64, found_in: String, default_burn: bool| FoundCompensation {
        by: CompensatedBy::BoxesPy,
        offset_um: RangeUm::one(burn_mm * 1000.0),
        kerf_um: None,
        rules: None,
        version: None,
        found_in,
        default_burn,
    };
    for (t, place) in &texts {
        if let Some(b) = burn_in_command_line(t) {
            return Some(found(b, format!("the command line in {place}"), false));
        }
    }
    for (t, place) in &texts {
        if let Some(b) = burn_in_url(t) {
            return Some(found(b, format!("the URL in {place}"), false));
        }
    }
    if !is_boxes {
        return None;
    }
    let label = doc
        .descendants()
        .filter(|n| n.is_element() && n.tag_name().name() == "text")
        .filter_map(|n| {
            n.descendants()
                .find_map(|d| d.text().and_then(burn_in_label))
        })
        .next();
    Some(match label {
        Some(b) => found(b, "the reference rectangle's label".into(), false),
        None => found(
            BOXES_DEFAULT_BURN_MM,
            "a boxes.py command line that does not set it".into(),
            true,
        ),
    })
}

/// Whether an element is part of boxes.py's reference rectangle: its group holds the label
/// `100.0mm, burn:0.10mm`.
pub(crate) fn is_boxes_reference(n: Node) -> bool {
    n.parent_element().is_some_and(|g| {
        g.children()
            .filter(|c| c.is_element() && c.tag_name().name() == "text")
            .any(|t| {
                t.descendants()
                    .any(|d| d.text().is_some_and(|s| burn_in_label(s).is_some()))
            })
    })
}

/// Whether a text says it was written by boxes.py.
pub(super) fn is_boxes_text(t: &str) -> bool {
    t.to_ascii_lowercase().contains("boxes.py")
        || t.lines().any(|l| {
            l.split_once("Command line")
                .and_then(|(_, rest)| rest.split_once(':'))
                .is_some_and(|(_, cmd)| cmd.trim_start().starts_with("boxes "))
        })
}

/// A number at the start of `s` (up to whitespace, a quote, `&` or the end).
pub(super) fn leading_number(s: &str) -> Option<f64> {
    let end = s
        .find(|c: char| c.is_whitespace() || matches!(c, '\'' | '"' | '&' | '<'))
        .unwrap_or(s.len());
    s[..end]
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite() && *v >= 0.0)
}

/// The value of `--burn VALUE` or `--burn=VALUE` in a command line (a comment's `- -burn` too).
pub(super) fn burn_in_command_line(t: &str) -> Option<f64> {
    let mut s = t.replace("- -", "--");
    while s.contains("- -") {
        s = s.replace("- -", "--");
    }
    s.match_indices("--burn").find_map(|(i, m)| {
        let rest = &s[i + m.len()..];
        match rest.chars().next()? {
            '=' => leading_number(&rest[1..]),
            c if c.is_whitespace() => leading_number(rest.trim_start()),
            _ => None,
        }
    })
}

/// The value of `burn=VALUE` in a URL's query (boxes.py's web generator).
pub(super) fn burn_in_url(t: &str) -> Option<f64> {
    t.match_indices("burn=").find_map(|(i, m)| {
        let before = t[..i].chars().next_back()?;
        matches!(before, '?' | '&' | ';')
            .then(|| leading_number(&t[i + m.len()..]))
            .flatten()
    })
}

/// The burn in boxes.py's reference label, `100.0mm, burn:0.10mm`.
pub(super) fn burn_in_label(t: &str) -> Option<f64> {
    let rest = &t[t.find("burn:")? + 5..];
    let end = rest.find("mm")?;
    rest[..end].trim().parse().ok()
}

/// This tool's record among the first lines of a DXF file (ASCII DXF; `999` comments).
pub(crate) fn find_in_dxf(bytes: &[u8]) -> Option<FoundCompensation> {
    let head = &bytes[..bytes.len().min(16 * 1024)];
    let text = String::from_utf8_lossy(head);
    let lines: Vec<&str> = text.lines().take(DXF_HEAD_LINES).collect();
    lines.windows(2).find_map(|w| {
        (w[0].trim() == "999")
            .then(|| record_fields(w[1]))
            .flatten()
            .and_then(|f| own_record(&f, "a DXF 999 comment"))
    })
}
