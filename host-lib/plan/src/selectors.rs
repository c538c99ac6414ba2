//! What the values of a list option (`--cut-color`, `--cut-layer`, `--layers`) select.
//!
//! Such an option may be repeated, and one value may hold several items separated by commas
//! (`--cut-color red,blue`). A comma does not always separate, though:
//!
//! * inside parentheses it belongs to the item: `rgb(255,0,0)` is one colour;
//! * a layer may be *named* with a comma (LightBurn and DXF allow it: `Cut, 3 mm`): a value that
//!   is a whole layer's name (or index) selects that layer and is not split.
//!
//! Clap therefore hands the values over whole (no `value_delimiter`), and the code that knows
//! the layers splits them here. The server passes each item of a JSON array as its own flag, so
//! nothing it is given is split by a comma it carried.

/// The items of one option value: split at the commas outside parentheses, each trimmed, empty
/// ones left out.
pub fn split_list(value: &str) -> Vec<&str> {
    let mut items = Vec::new();
    let (mut depth, mut start) = (0usize, 0);
    for (i, ch) in value.char_indices() {
        match ch {
            '(' => depth += 1,
            ')' => depth = depth.saturating_sub(1),
            ',' if depth == 0 => {
                items.push(&value[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&value[start..]);
    if depth > 0 {
        // A parenthesis left open (`Cut :(,Score`) is not a group: every comma separates.
        items = value.split(',').collect();
    }
    items
        .into_iter()
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect()
}

/// The items of every value in `values`, split by [`split_list`]; a value with no item at all
/// (`""`, `","`: an empty shell variable) is an error, not a silent "nothing".
pub fn split_lists(values: &[String]) -> Result<Vec<&str>, String> {
    let mut items = Vec::new();
    for v in values {
        let some = split_list(v);
        if some.is_empty() {
            return Err(format!("{v:?} names nothing"));
        }
        items.extend(some);
    }
    Ok(items)
}

/// The layer selectors in `values`: a value that `is_layer` recognises whole (a layer's name or
/// index, as given or trimmed) stays whole; any other is split by [`split_list`]. A value with
/// no item at all is an error.
pub fn layer_selectors(
    values: &[String],
    is_layer: impl Fn(&str) -> bool,
) -> Result<Vec<&str>, String> {
    let mut selectors = Vec::new();
    for v in values {
        match [v.as_str(), v.trim()].into_iter().find(|w| is_layer(w)) {
            Some(whole) => selectors.push(whole),
            None => {
                let some = split_list(v);
                if some.is_empty() {
                    return Err(format!("{v:?} names nothing"));
                }
                selectors.extend(some);
            }
        }
    }
    Ok(selectors)
}

/// The hint added to "no layer is called …" where a value was split: how to name a layer whose
/// name holds a comma.
pub const SPLIT_HINT: &str = "a value is split at its commas unless it is a layer's whole name";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commas_separate_items_except_inside_parentheses() {
        assert_eq!(split_list("red, #00f,blue"), ["red", "#00f", "blue"]);
        assert_eq!(
            split_list("rgb(255,0,0),rgb(0, 0, 255)"),
            ["rgb(255,0,0)", "rgb(0, 0, 255)"]
        );
        assert_eq!(split_list(" , red,,"), ["red"]);
        // An unbalanced parenthesis never swallows the rest, nor panics.
        assert_eq!(split_list("a),b"), ["a)", "b"]);
        assert_eq!(split_list("Cut :(,Score"), ["Cut :(", "Score"]);
        assert!(split_lists(&["red".into(), " , ".into()]).is_err());
    }

    #[test]
    fn a_value_that_names_a_layer_is_not_split() {
        let names = ["Cut, 3 mm", "Score"];
        let is_layer = |s: &str| names.contains(&s);
        let values = [
            "Cut, 3 mm ".to_string(),
            "Score,0".to_string(),
            "Cut, 3 mm".to_string(),
        ];
        assert_eq!(
            layer_selectors(&values, is_layer).unwrap(),
            ["Cut, 3 mm", "Score", "0", "Cut, 3 mm"]
        );
        assert!(layer_selectors(&[String::new()], is_layer).is_err());
    }
}
