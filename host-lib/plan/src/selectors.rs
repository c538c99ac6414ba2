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
    items
        .into_iter()
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect()
}

/// The items of every value in `values`, split by [`split_list`].
pub fn split_lists(values: &[String]) -> Vec<&str> {
    values.iter().flat_map(|v| split_list(v)).collect()
}

/// The layer selectors in `values`: a value that `is_layer` recognises whole (a layer's name or
/// index) stays whole; any other is split by [`split_list`].
pub fn layer_selectors(values: &[String], is_layer: impl Fn(&str) -> bool) -> Vec<&str> {
    values
        .iter()
        .flat_map(|v| {
            if is_layer(v) {
                vec![v.as_str()]
            } else {
                split_list(v)
            }
        })
        .collect()
}

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
    }

    #[test]
    fn a_value_that_names_a_layer_is_not_split() {
        let names = ["Cut, 3 mm", "Score"];
        let is_layer = |s: &str| names.contains(&s);
        let values = ["Cut, 3 mm".to_string(), "Score,0".to_string()];
        assert_eq!(
            layer_selectors(&values, is_layer),
            ["Cut, 3 mm", "Score", "0"]
        );
    }
}
