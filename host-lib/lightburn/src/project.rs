//! LightBurn projects (`.lbrn2`, and the older `.lbrn`): set the **Kerf Offset** of their Line
//! (cut) layers to the measured kerf, and change nothing else, byte for byte.
//!
//! **LightBurn's convention.** A layer's Kerf Offset moves the laser's path off the drawn line so
//! that *the edge of the cut* lies on the drawing: it is half the width of the cut (the beam's
//! radius), in mm in the project file (whatever units LightBurn displays). A positive value moves
//! closed shapes outward and the holes inside them inward (LightBurn inverts the direction for
//! shapes nested in others on the same layer); negative shrinks. LightBurn applies it to layers in
//! Line mode only, and to closed shapes only (this is LightBurn's user documentation of the Kerf
//! Offset; its REST spec, which `kerfmeter lightburn apply` follows ([`crate::rest`]), defines no meaning for a
//! cut's `kerf`). This module therefore writes
//! `kerf = kerf_um / 2 / 1000` (mm, positive): the same offset `kerfmeter dilate` applies to an
//! SVG or DXF, left for LightBurn to apply when it sends the job.
//!
//! **The file.** A project is XML: a `<LightBurnProject>` root whose `<CutSetting type="…">`
//! children are the layers, each with child elements holding a `Value` attribute (`<index
//! Value="0"/>`, `<name Value="C00"/>`, `<kerf Value="0.1"/>` …); LightBurn omits settings left at
//! their defaults, so a layer without a Kerf Offset has no `<kerf>`. A layer may carry sub-layers
//! (`<SubLayer type="Cut" index="1">` with their own settings, e.g. a Fill layer's outline pass).
//! Every pass of type `Cut` (the layer's own, when it is a Line layer, and each Line sub-layer) is
//! a *line pass*; a layer with at least one is a cut layer. Image layers (`<CutSetting_Img>`) and
//! Fill or Offset Fill layers without a Line sub-layer are not.
//!
//! **The edit.** The document is parsed (roxmltree, which the plan crate's SVG reader uses too, with byte
//! positions) only to find where things are; the output is the input with the `Value` text of
//! each line pass's `<kerf>` replaced, or a `<kerf Value="…"/>` inserted after its `<speed>` (as
//! LightBurn orders them) with the indentation of its neighbours. Nothing is re-serialised.
//! A record of what was applied (the same `kerfmeter-compensation` line the SVG and DXF outputs
//! carry) goes into an XML comment before the root element: LightBurn ignores comments and drops
//! them when it saves, so the durable record is the Kerf Offset itself.
//!
//! **Never twice.** A line pass that already has a non-zero Kerf Offset means the project is
//! already compensated: it is refused ([`IfCompensated::Refuse`]); `--recompensate` replaces the
//! offset by this kerf's, `--already-compensated-ok` adds this kerf's on top (as it dilates an SVG
//! on top of its compensation).
//!
//! **Hostile input.** A document type declaration (and so entity expansion) is refused, as are
//! files over [`MAX_PROJECT_BYTES`], text that is not UTF-8 and anything that is not XML.

use kerfmeter_protocol::advice::{Advice, Advised};
use std::ops::Range;
use std::path::Path;

use roxmltree::{Document, Node, ParsingOptions};
use serde::Serialize;

use kerfmeter_plan::compensation::{self, AppliedCompensation, FoundCompensation, IfCompensated};
use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::{PlanError, Problems, Result, selectors};

/// The largest project read, bytes (projects with embedded images run to tens of MB).
pub const MAX_PROJECT_BYTES: u64 = 256 * 1024 * 1024;
/// The most XML nodes a project may have.
const MAX_NODES: u32 = 20_000_000;

/// Whether `path` names a LightBurn project (`.lbrn2` or `.lbrn`).
pub fn is_project_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("lbrn2") || e.eq_ignore_ascii_case("lbrn"))
}

/// Which layers to set and what to do with a project already compensated.
#[derive(Debug, Clone, Default)]
pub struct LightBurnOptions {
    /// Layers to set, each by its index (`0`…) or its name; empty: every cut layer. A layer
    /// asked for that is not a cut layer is refused.
    pub layers: Vec<String>,
    /// A line pass with a Kerf Offset already: refuse, replace or add.
    pub if_compensated: IfCompensated,
}

/// One line pass whose Kerf Offset was set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PassChange {
    /// The sub-layer's index, or `None` for the layer's own pass.
    pub sub_layer: Option<i64>,
    /// The Kerf Offset before, mm (`None`: the pass had none, i.e. 0).
    pub before_mm: Option<f64>,
    /// The Kerf Offset written, mm.
    pub after_mm: f64,
}

/// A layer of the project and what was done to it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LayerOutcome {
    /// Its index (`<index Value>`; the `CutIndex` of its shapes).
    pub index: i64,
    /// Its name (may be empty).
    pub name: String,
    /// Its mode as the file names it (`Cut` is Line, `Scan` Fill, `Offset` Offset Fill …).
    pub mode: String,
    /// The line passes set (empty: left alone).
    pub set: Vec<PassChange>,
    /// Why it was left alone, if it was.
    pub left_alone: Option<String>,
}

/// What was found in a project and done to it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LightBurnSummary {
    /// The kerf, µm (full cut width).
    pub kerf_um: f64,
    /// LightBurn's Kerf Offset for it, mm: half the kerf, positive (outward).
    pub kerf_offset_mm: f64,
    /// Every layer, in file order.
    pub layers: Vec<LayerOutcome>,
    /// The Kerf Offsets found already set on the layers to set (`None`: none).
    pub compensation_found: Option<FoundCompensation>,
    /// What was applied, as recorded in the output.
    pub compensation_applied: AppliedCompensation,
}

/// Read the project at `input` and set the Kerf Offset of its cut layers for `kerf_um`; the
/// project's new bytes and what was done. Every error about the file's content names the file.
pub fn set_kerf_offset_file(
    input: &Path,
    kerf_um: f64,
    options: &LightBurnOptions,
) -> Result<(Vec<u8>, LightBurnSummary)> {
    let io = |source| PlanError::Io {
        path: input.to_owned(),
        source,
    };
    let len = std::fs::metadata(input).map_err(io)?.len();
    if len > MAX_PROJECT_BYTES {
        return Err(PlanError::LightBurn(format!(
            "the project is {len} bytes, more than the {MAX_PROJECT_BYTES} this tool reads"
        ))
        .in_file(input));
    }
    let bytes = std::fs::read(input).map_err(io)?;
    let text = String::from_utf8(bytes).map_err(|_| {
        PlanError::LightBurn("not a LightBurn project (not UTF-8 text)".into()).in_file(input)
    })?;
    // A bad argument (the kerf, --layers) is the command's, not the file's.
    let (out, summary) = set_kerf_offset(&text, kerf_um, options).map_err(|e| match e {
        PlanError::InvalidArgument(_) => e,
        e => e.in_file(input),
    })?;
    Ok((out.into_bytes(), summary))
}

/// Set the Kerf Offset of the cut layers of the project `text` for `kerf_um` (see the module
/// doc): the new text, equal to `text` but for the kerf values and the record comment.
pub fn set_kerf_offset(
    text: &str,
    kerf_um: f64,
    options: &LightBurnOptions,
) -> Result<(String, LightBurnSummary)> {
    let kerf_um = KerfSource::check_kerf_um(kerf_um)?;
    let doc = parse(text)?;
    let layers = read_layers(&doc)?;
    let chosen = choose(&layers, &options.layers)?;
    let found = found_offsets(&layers, &chosen);
    if let (Some(found), IfCompensated::Refuse) = (&found, options.if_compensated) {
        return Err(PlanError::AlreadyCompensated {
            message: refusal(found, kerf_um),
            found: Box::new(found.clone()),
        });
    }
    let half_mm = kerf_um / 2000.0;
    let mut edits = Vec::new();
    let mut outcomes = Vec::new();
    for (i, layer) in layers.iter().enumerate() {
        let set = if chosen.contains(&i) {
            set_layer(text, layer, half_mm, options.if_compensated, &mut edits)?
        } else {
            Vec::new()
        };
        outcomes.push(layer.outcome(set, chosen.contains(&i)));
    }
    let applied = applied(kerf_um, &outcomes, options.if_compensated, found.is_some());
    edits.push(record_edit(&doc, &applied));
    Ok((
        apply(text, edits),
        LightBurnSummary {
            kerf_um,
            kerf_offset_mm: half_mm,
            layers: outcomes,
            compensation_found: found,
            compensation_applied: applied,
        },
    ))
}

/// The document, parsed without a DTD (so without entities to expand) and with a node limit.
fn parse(text: &str) -> Result<Document<'_>> {
    let doc = Document::parse_with_options(
        text,
        ParsingOptions {
            allow_dtd: false,
            nodes_limit: MAX_NODES,
            ..ParsingOptions::default()
        },
    )
    .map_err(|e| {
        PlanError::LightBurn(format!(
            "not a readable LightBurn project (not well-formed XML, or a document type declaration, which LightBurn never writes): {e}"
        ))
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "LightBurnProject" {
        return Err(PlanError::LightBurn(format!(
            "not a LightBurn project: the root element is <{}>, not <LightBurnProject>",
            root.tag_name().name()
        )));
    }
    Ok(doc)
}

/// A `<kerf>` setting found: its `Value` text's byte range and value, mm.
#[derive(Debug, Clone)]
struct KerfValue {
    range: Range<usize>,
    mm: f64,
}

/// A line pass: the element holding its settings, and its `<kerf>` if it has one.
#[derive(Debug, Clone)]
struct LinePass<'a, 'i> {
    element: Node<'a, 'i>,
    sub_layer: Option<i64>,
    kerf: Option<KerfValue>,
}

/// A `<CutSetting>` and its line passes.
#[derive(Debug, Clone)]
struct Layer<'a, 'i> {
    index: i64,
    name: String,
    mode: String,
    passes: Vec<LinePass<'a, 'i>>,
}

impl Layer<'_, '_> {
    fn describe(&self) -> String {
        format!("layer {} \"{}\" ({})", self.index, self.name, self.mode)
    }

    fn outcome(&self, set: Vec<PassChange>, chosen: bool) -> LayerOutcome {
        let left_alone = match (chosen, self.passes.is_empty()) {
            (true, _) => None,
            (false, true) => {
                Some("not a Line layer: LightBurn applies a Kerf Offset to Line passes only".into())
            }
            (false, false) => Some("not asked for (--layers)".into()),
        };
        LayerOutcome {
            index: self.index,
            name: self.name.clone(),
            mode: self.mode.clone(),
            set,
            left_alone,
        }
    }
}

/// The root's `<CutSetting>` layers, in file order; every problem with them reported together.
fn read_layers<'a, 'i>(doc: &'a Document<'i>) -> Result<Vec<Layer<'a, 'i>>> {
    let mut problems = Problems::default();
    let mut layers = Vec::new();
    for (n, e) in doc
        .root_element()
        .children()
        .filter(|c| c.has_tag_name("CutSetting"))
        .enumerate()
    {
        match read_layer(e) {
            Ok(layer) => layers.push(layer),
            Err(why) => problems.push(format!(
                "cut setting {} (line {}): {why}",
                n + 1,
                line_of(doc, e)
            )),
        }
    }
    problems.into_error(PlanError::LightBurn)?;
    Ok(layers)
}

fn read_layer<'a, 'i>(e: Node<'a, 'i>) -> std::result::Result<Layer<'a, 'i>, String> {
    let index = setting(e, "index")
        .ok_or("it has no <index Value=…>")?
        .trim()
        .parse::<i64>()
        .map_err(|_| "its <index> is not a whole number")?;
    let mode = e.attribute("type").unwrap_or("").to_string();
    let mut passes = Vec::new();
    if mode == "Cut" {
        passes.push(line_pass(e, None)?);
    }
    for (n, sub) in e
        .children()
        .filter(|c| c.has_tag_name("SubLayer"))
        .enumerate()
    {
        if sub.attribute("type") == Some("Cut") {
            let idx = sub.attribute("index").and_then(|i| i.trim().parse().ok());
            passes.push(line_pass(sub, Some(idx.unwrap_or(n as i64 + 1)))?);
        }
    }
    Ok(Layer {
        index,
        name: setting(e, "name").unwrap_or("").to_string(),
        mode,
        passes,
    })
}

/// The `Value` of the child setting element `tag` of `e`.
fn setting<'a>(e: Node<'a, '_>, tag: &str) -> Option<&'a str> {
    e.children()
        .find(|c| c.has_tag_name(tag))
        .and_then(|c| c.attribute("Value"))
}

fn line_pass<'a, 'i>(
    e: Node<'a, 'i>,
    sub_layer: Option<i64>,
) -> std::result::Result<LinePass<'a, 'i>, String> {
    let whose = match sub_layer {
        None => String::new(),
        Some(i) => format!("its sub-layer {i}: "),
    };
    let mut kerfs = e.children().filter(|c| c.has_tag_name("kerf"));
    let kerf = match (kerfs.next(), kerfs.next()) {
        (None, _) => None,
        (Some(_), Some(_)) => return Err(format!("{whose}it has two <kerf> settings")),
        (Some(k), None) => {
            let a = k
                .attribute_node("Value")
                .ok_or(format!("{whose}its <kerf> has no Value"))?;
            let mm = a
                .value()
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or(format!(
                    "{whose}its Kerf Offset \"{}\" is not a number",
                    a.value()
                ))?;
            Some(KerfValue {
                range: a.range_value(),
                mm,
            })
        }
    };
    Ok(LinePass {
        element: e,
        sub_layer,
        kerf,
    })
}

/// 1-based line of a node, for messages.
fn line_of(doc: &Document, n: Node) -> u32 {
    doc.text_pos_at(n.range().start).row
}

/// The positions (in `layers`) of the layers to set: those `wanted` names (each a layer's
/// index or whole name, or a comma-separated list of them: [`selectors`]), or every cut layer.
fn choose(layers: &[Layer], wanted: &[String]) -> Result<Vec<usize>> {
    if wanted.is_empty() {
        let all: Vec<usize> = (0..layers.len())
            .filter(|&i| !layers[i].passes.is_empty())
            .collect();
        if all.is_empty() {
            return Err(PlanError::LightBurn(
                "the project has no Line (cut) layer to set a Kerf Offset on; nothing was written"
                    .into(),
            ));
        }
        return Ok(all);
    }
    let mut problems = Problems::default();
    let mut chosen = Vec::new();
    let is = |l: &Layer, s: &str| l.index.to_string() == s.trim() || l.name == s;
    let names = selectors::layer_selectors(wanted, |s| layers.iter().any(|l| is(l, s)))
        .map_err(|e| PlanError::InvalidArgument(format!("--layers: {e}")))?;
    for s in names {
        let hits: Vec<usize> = (0..layers.len()).filter(|&i| is(&layers[i], s)).collect();
        if hits.is_empty() {
            let hint = match wanted.iter().any(|v| v.contains(',')) {
                true => format!(" ({})", selectors::SPLIT_HINT),
                false => String::new(),
            };
            problems.push(format!("no layer has the index or name \"{s}\"{hint}"));
        }
        for i in hits {
            if layers[i].passes.is_empty() {
                problems.push(format!(
                    "{} is not a Line (cut) layer: LightBurn applies a Kerf Offset to Line passes only",
                    layers[i].describe()
                ));
            } else if !chosen.contains(&i) {
                chosen.push(i);
            }
        }
    }
    problems.into_error(|m| PlanError::InvalidArgument(format!("--layers: {m}")))?;
    chosen.sort_unstable();
    Ok(chosen)
}

/// The Kerf Offsets already set on the chosen layers' passes, if any.
fn found_offsets(layers: &[Layer], chosen: &[usize]) -> Option<FoundCompensation> {
    let found: Vec<(String, f64)> = chosen
        .iter()
        .flat_map(|&i| layers[i].passes.iter().map(move |p| (&layers[i], p)))
        .filter_map(|(l, p)| {
            let mm = p.kerf.as_ref()?.mm;
            (mm != 0.0).then(|| match p.sub_layer {
                None => (format!("{}: {mm} mm", l.describe()), mm),
                Some(s) => (format!("{} sub-layer {s}: {mm} mm", l.describe()), mm),
            })
        })
        .collect();
    let offsets_um: Vec<f64> = found.iter().map(|&(_, mm)| mm * 1000.0).collect();
    let places: Vec<String> = found.into_iter().map(|(place, _)| place).collect();
    FoundCompensation::lightburn(places.join("; "), &offsets_um)
}

fn refusal(found: &FoundCompensation, kerf_um: f64) -> Advised {
    Advised::text(format!(
        "{}. The project is already compensated for a kerf; setting it again could compensate twice and make every joint too loose; nothing was written. Either replace those offsets by this kerf's ({} mm) with ",
        found.describe(),
        format_mm(kerf_um / 2000.0)
    ))
    .advise(Advice::Recompensate)
    .then(", or add this kerf's on top with ")
    .advise(Advice::AlreadyCompensatedOk)
    .then(".")
}

/// Set every line pass of `layer`: the edits, and what was done.
fn set_layer(
    text: &str,
    layer: &Layer,
    half_mm: f64,
    policy: IfCompensated,
    edits: &mut Vec<Edit>,
) -> Result<Vec<PassChange>> {
    let mut changes = Vec::new();
    for pass in &layer.passes {
        let before_mm = pass.kerf.as_ref().map(|k| k.mm);
        let after_mm = match (policy, before_mm) {
            (IfCompensated::DilateAnyway, Some(b)) => b + half_mm,
            _ => half_mm,
        };
        let value = format_mm(after_mm);
        edits.push(match &pass.kerf {
            Some(k) => Edit {
                range: k.range.clone(),
                text: value,
            },
            None => insert_kerf(text, pass, &value)
                .map_err(|why| PlanError::LightBurn(format!("{}: {why}", layer.describe())))?,
        });
        changes.push(PassChange {
            sub_layer: pass.sub_layer,
            before_mm,
            after_mm,
        });
    }
    Ok(changes)
}

/// Insert `<kerf Value="…"/>` into a pass that has none: after its `<speed>` (else its `<name>`,
/// `<index>`, or its first setting), on a line of its own indented like that element.
fn insert_kerf(text: &str, pass: &LinePass, value: &str) -> std::result::Result<Edit, String> {
    let e = pass.element;
    let anchor = ["speed", "name", "index"]
        .iter()
        .find_map(|t| e.children().find(|c| c.has_tag_name(*t)))
        .or_else(|| e.children().find(|c| c.is_element()))
        .ok_or("it has no settings to place a <kerf> among")?;
    let indent = anchor
        .prev_sibling()
        .filter(|p| p.is_text())
        .map(|p| &text[p.range()])
        .filter(|t| t.trim().is_empty())
        .unwrap_or("");
    let at = anchor.range().end;
    Ok(Edit {
        range: at..at,
        text: format!("{indent}<kerf Value=\"{value}\"/>"),
    })
}

/// The record of what was applied.
fn applied(
    kerf_um: f64,
    outcomes: &[LayerOutcome],
    policy: IfCompensated,
    found: bool,
) -> AppliedCompensation {
    let passes = || outcomes.iter().flat_map(|o| o.set.iter());
    let span = |f: &dyn Fn(&PassChange) -> f64| {
        passes()
            .map(f)
            .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], v| {
                [lo.min(v), hi.max(v)]
            })
    };
    let net = span(&|p| (p.after_mm - p.before_mm.unwrap_or(0.0)) * 1000.0);
    let total = span(&|p| p.after_mm * 1000.0);
    let layers: Vec<String> = outcomes
        .iter()
        .filter(|o| !o.set.is_empty())
        .map(|o| o.index.to_string())
        .collect();
    let action = match (found, policy) {
        (false, _) | (true, IfCompensated::Refuse) => "set_kerf_offset",
        (true, IfCompensated::DilateAnyway) => "dilate_anyway",
        (true, IfCompensated::Recompensate) => "recompensate",
    };
    compensation::applied_setting(
        action,
        kerf_um,
        net,
        total,
        format!("LightBurn Kerf Offset of Line layers {}", layers.join(", ")),
    )
}

/// The record comment before the root element, replacing an earlier record of this tool's.
fn record_edit(doc: &Document, applied: &AppliedCompensation) -> Edit {
    let comment = applied.xml_comment(
        "LightBurn's Kerf Offset (half the kerf, mm, positive = outward) of the layers named; LightBurn ignores this comment and drops it when it saves",
    );
    let root = doc.root_element();
    let earlier = root
        .prev_siblings()
        .find(|n| n.is_comment() && n.text().is_some_and(compensation::is_record));
    match earlier {
        Some(c) => Edit {
            range: c.range(),
            text: comment,
        },
        None => {
            let at = root.range().start;
            Edit {
                range: at..at,
                text: format!("{comment}{}", line_ending(doc.input_text())),
            }
        }
    }
}

/// The line ending of `text` (that of its first line): a CRLF project stays CRLF throughout.
fn line_ending(text: &str) -> &'static str {
    match text.find('\n') {
        Some(i) if text[..i].ends_with('\r') => "\r\n",
        _ => "\n",
    }
}

/// A byte-range replacement in the source (an insertion when the range is empty).
#[derive(Debug, Clone)]
struct Edit {
    range: Range<usize>,
    text: String,
}

/// `text` with `edits` (disjoint ranges) applied.
fn apply(text: &str, mut edits: Vec<Edit>) -> String {
    edits.sort_by_key(|e| (e.range.start, e.range.end));
    let mut out = String::with_capacity(text.len() + 64 * edits.len());
    let mut at = 0;
    for e in &edits {
        out.push_str(&text[at..e.range.start]);
        out.push_str(&e.text);
        at = e.range.end;
    }
    out.push_str(&text[at..]);
    out
}

/// A length in mm as LightBurn writes it: up to 6 decimals (a nanometre), no trailing zeros.
pub fn format_mm(mm: f64) -> String {
    kerfmeter_plan::decimal::trimmed(mm, 6)
}
