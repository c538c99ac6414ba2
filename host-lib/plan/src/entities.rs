//! A bound on what an XML document's internal entities expand to, checked before it is parsed.
//!
//! SVG plans are parsed with their document type declaration allowed (Illustrator declares its
//! namespaces as entities: `<!ENTITY ns_svg "http://www.w3.org/2000/svg">`). roxmltree refuses
//! entity loops ("billion laughs"), but not a large entity used many times: a 250 KB file whose
//! 100 KB entity is referenced 50,000 times asked for 5 GB and aborted the process. So before any
//! parse, [`check`] adds up what every reference would insert and refuses a document that would
//! grow past [`limit_bytes`].
//!
//! The count errs on the side of refusing: every `<!ENTITY name "value">` anywhere in the text
//! counts (a declaration written inside another's value too, so none can be hidden from it), a
//! reference counts wherever it is (inside a value too), and a nested reference counts with the
//! whole expansion of what it names; a cycle counts as without end.

use std::collections::HashMap;

/// How much a document's entities may add to it: four times its own size, and never less than
/// 4 MiB (a real plan's entities add a few hundred bytes).
pub(crate) fn limit_bytes(text_len: usize) -> u64 {
    (4 * text_len as u64).max(4 << 20)
}

/// `Err` with the size the entities would add, when it is over [`limit_bytes`].
pub(crate) fn check(text: &str) -> Result<(), u64> {
    if !text.contains("<!ENTITY") {
        return Ok(());
    }
    let declared = declarations(text);
    let mut lengths = HashMap::new();
    let added = references(text)
        .filter(|name| declared.contains_key(name))
        .fold(0u64, |sum, name| {
            sum.saturating_add(expanded_len(name, &declared, &mut lengths, 0))
        });
    if added > limit_bytes(text.len()) {
        Err(added)
    } else {
        Ok(())
    }
}

/// Every general entity declared in `text` (the first declaration of a name wins, as in XML):
/// its name and quoted value.
fn declarations(text: &str) -> HashMap<&str, &str> {
    let mut found = HashMap::new();
    for (at, _) in text.match_indices("<!ENTITY") {
        if let Some((name, value)) = declaration(&text[at + "<!ENTITY".len()..]) {
            found.entry(name).or_insert(value);
        }
    }
    found
}

/// The name and value of one declaration (the text after `<!ENTITY`); `None` for a parameter
/// entity (`%`), an external one (`SYSTEM`, `PUBLIC`: never fetched) or one that is not
/// well formed.
fn declaration(rest: &str) -> Option<(&str, &str)> {
    let rest = rest.trim_start();
    let end = rest.find(|c: char| c.is_whitespace())?;
    let (name, rest) = rest.split_at(end);
    if name.starts_with('%') {
        return None;
    }
    let rest = rest.trim_start();
    let quote = rest.chars().next().filter(|q| *q == '"' || *q == '\'')?;
    let value = &rest[1..];
    let close = value.find(quote)?;
    Some((name, &value[..close]))
}

/// The names of every `&name;` reference in `text` (not `&#...;` character references).
fn references(text: &str) -> impl Iterator<Item = &str> {
    text.match_indices('&').filter_map(move |(at, _)| {
        let rest = &text[at + 1..];
        let end = rest.find(';')?;
        let name = &rest[..end];
        let plain = !name.is_empty()
            && !name.starts_with('#')
            && name.len() <= 256
            && !name.contains(|c: char| c.is_whitespace() || c == '&' || c == '<');
        plain.then_some(name)
    })
}

/// How long entity `name` is once expanded, bytes (saturating; `u64::MAX` for a cycle or a
/// nesting deeper than any real document's).
fn expanded_len<'t>(
    name: &'t str,
    declared: &HashMap<&'t str, &'t str>,
    lengths: &mut HashMap<&'t str, u64>,
    depth: usize,
) -> u64 {
    if let Some(&len) = lengths.get(name) {
        return len;
    }
    let Some(value) = declared.get(name) else {
        return 0;
    };
    if depth > 16 {
        return u64::MAX;
    }
    // Taken as endless while it is being expanded: a reference back to it is a cycle.
    lengths.insert(name, u64::MAX);
    let nested = references(value)
        .filter(|inner| declared.contains_key(inner))
        .fold(0u64, |sum, inner| {
            sum.saturating_add(expanded_len(inner, declared, lengths, depth + 1))
        });
    let len = (value.len() as u64).saturating_add(nested);
    lengths.insert(name, len);
    len
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn illustrators_namespace_entities_pass() {
        let svg = r#"<?xml version="1.0"?>
<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN" "http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd" [
  <!ENTITY ns_svg "http://www.w3.org/2000/svg">
  <!ENTITY ns_xlink 'http://www.w3.org/1999/xlink'>
]>
<svg xmlns="&ns_svg;" xmlns:xlink="&ns_xlink;"><rect/></svg>"#;
        assert_eq!(check(svg), Ok(()));
        assert_eq!(check("<svg>&amp; &#38; &lt;</svg>"), Ok(()));
    }

    #[test]
    fn a_large_entity_used_many_times_is_refused_before_parsing() {
        let value = "x".repeat(100_000);
        let uses = "&big;".repeat(50_000);
        let svg = format!("<!DOCTYPE svg [<!ENTITY big \"{value}\">]><svg>{uses}</svg>");
        let added = check(&svg).unwrap_err();
        assert_eq!(added, 100_000 * 50_000);
        // A few uses of it are fine.
        let svg = format!("<!DOCTYPE svg [<!ENTITY big \"{value}\">]><svg>&big;&big;</svg>");
        assert_eq!(check(&svg), Ok(()));
    }

    #[test]
    fn nested_and_looping_entities_count_with_all_they_expand_to() {
        let mut dtd = String::from("<!ENTITY a0 \"0123456789\">");
        for k in 1..8 {
            let refs = format!("&a{};", k - 1).repeat(10);
            dtd.push_str(&format!("<!ENTITY a{k} \"{refs}\">"));
        }
        let svg = format!("<!DOCTYPE svg [{dtd}]><svg>&a7;</svg>");
        assert!(check(&svg).unwrap_err() >= 10u64.pow(8));
        let looped = "<!DOCTYPE svg [<!ENTITY a \"&b;\"><!ENTITY b \"&a;\">]><svg>&a;</svg>";
        assert_eq!(check(looped), Err(u64::MAX));
        // A declaration hidden inside another's value still counts.
        let hidden = format!(
            "<!DOCTYPE svg [<!ENTITY c \"<!ENTITY big '{}'>\">]><svg>{}</svg>",
            "y".repeat(1000),
            "&big;".repeat(10_000)
        );
        assert!(check(&hidden).is_err());
    }
}
