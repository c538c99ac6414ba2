//! Never compensate twice: plans that say they are already compensated for the kerf, what to do
//! with them, and the record of what was applied that every output carries.
//!
//! **What is recognised.**
//!
//! * **boxes.py** SVG plans. boxes.py draws every cut `burn` mm outside its part (default 0.1 mm)
//!   and writes its command line into the file: in the `<metadata>` description (`Command line:
//!   boxes ABox --burn 0.1 …`, the full command line), in an XML comment (`Command line (remove
//!   spaces between dashes): boxes ABox - -burn=0.1`, only the arguments that differ from the
//!   defaults, with `--` written `- -`), and in the web generator's URL (`…&burn=0.1&…`). The
//!   reference rectangle's label says `burn:0.10mm`. The burn is taken from the first of these
//!   that gives it; a file that is plainly boxes.py's (`Created with Boxes.py`, or a `Command
//!   line: boxes …`) but names no burn was made with boxes.py's default, 0.1 mm. A burn of 0 is
//!   no compensation. boxes.py's DXF keeps no command line (whichever of its writers made it), so
//!   it cannot be recognised. boxes.py draws its reference rectangle (in the group with
//!   the `burn:` label) without burn: recompensating dilates it by the kerf's half alone. One burn
//!   is taken for the rest (boxes.py's `BurnTest` draws each piece with its own).
//! * **This tool's own outputs.** Every dilated SVG gets an XML comment and a `<metadata>` element
//!   holding a `kerfmeter:compensation` element (namespace [`NAMESPACE`]) with the kerf, the net
//!   offset of this run, the total offset the plan now carries, the cut rules, the tool and its
//!   version. Every dilated DXF gets the same record as `999` comments at the top of the file:
//!   the `dxf` crate neither writes nor keeps comments (it skips `999` on reading), and its only
//!   free-text header variables (`$HYPERLINKBASE`, `$PROJECTNAME`, `$MENU`) mean something to CAD
//!   programs, so the comments are added to the written bytes and looked for in the first lines
//!   of a file read.
//! * **This tool's gauge** (`kerfmeter gauge`, [`GaugeRecord`]): the same kind of comment with
//!   `drawing=gauge` (and the test piece's kerf, when there is one). A gauge is cut as drawn: its
//!   spiral's gap is what measures the kerf. It is refused at any other kerf than 0, with that
//!   reason and none of the two ways on (there is nothing to recompensate);
//!   `--already-compensated-ok` still dilates it.
//!
//! **What is done** ([`IfCompensated`]): a compensated plan is refused by default
//! ([`PlanError::AlreadyCompensated`], naming what was found and the two ways on);
//! `--already-compensated-ok` dilates by the full kerf on top; `--recompensate` undoes the recorded
//! offset and applies the kerf instead (net offset kerf/2 − burn, corners as drawn: see
//! [`crate::recompensate`]). Either way boxes.py's small loops at inner corners are removed first.

use kerfmeter_protocol::advice::{Advice, Advised};
use std::fmt;

use roxmltree::{Document, Node};
use serde::Serialize;

use crate::dilate::{KerfSource, Offsetting};
use crate::error::{PlanError, Result};

mod finding;

pub(crate) use finding::{find_in_dxf, find_in_svg, is_boxes_reference, own_svg_records};

/// XML namespace of the `compensation` element this tool writes into SVG `<metadata>`.
pub const NAMESPACE: &str = "urn:x-kerfmeter:compensation:1";
/// The first word of this tool's records (SVG comment, DXF `999` comment): also how an output
/// of this tool is told from anyone else's file before it is replaced
/// (`kerfmeter::files::ensure_replaceable`).
pub const MARKER: &str = "kerfmeter-compensation";
/// The tool's name in records.
const TOOL: &str = "kerfmeter";
/// boxes.py's default `--burn`, mm.
const BOXES_DEFAULT_BURN_MM: f64 = 0.1;
/// How many lines at the top of a DXF file are searched for a record.
const DXF_HEAD_LINES: usize = 64;

/// What to do with a plan that says it is already compensated.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IfCompensated {
    /// Refuse it (the default): dilating it again would double the compensation.
    #[default]
    Refuse,
    /// Dilate it by the full kerf anyway (`--already-compensated-ok`).
    DilateAnyway,
    /// Undo the recorded compensation and apply the kerf instead (`--recompensate`).
    Recompensate,
}

/// Who compensated a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CompensatedBy {
    /// boxes.py, with its `--burn`.
    BoxesPy,
    /// This tool (`kerfmeter dilate`).
    Kerfmeter,
    /// LightBurn: its layers' Kerf Offsets (a `.lbrn2` project).
    #[serde(rename = "lightburn")]
    LightBurn,
    /// This tool's gauge drawing (`kerfmeter gauge`): cut as drawn, never dilated (its test
    /// piece, if any, is already dilated).
    KerfmeterGauge,
}

/// A range of values, µm: one value when both ends agree (a uniform kerf), else a kerf map's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RangeUm(pub [f64; 2]);

impl RangeUm {
    pub(crate) fn one(v: f64) -> RangeUm {
        RangeUm([v, v])
    }

    fn is_uniform(&self) -> bool {
        (self.0[0] - self.0[1]).abs() < 1e-6
    }

    fn parse(s: &str) -> Option<RangeUm> {
        let (lo, hi) = s.split_once("..").unwrap_or((s, s));
        let (lo, hi) = (lo.trim().parse().ok()?, hi.trim().parse().ok()?);
        [lo, hi]
            .iter()
            .all(|v: &f64| v.is_finite())
            .then_some(RangeUm([lo, hi]))
    }
}

impl fmt::Display for RangeUm {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = |v: f64| (v * 1000.0).round() / 1000.0;
        if self.is_uniform() {
            write!(f, "{}", r(self.0[0]))
        } else {
            write!(f, "{}..{}", r(self.0[0]), r(self.0[1]))
        }
    }
}

/// A compensation a plan says it already carries.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FoundCompensation {
    /// Who made it.
    pub by: CompensatedBy,
    /// How far the drawn cuts already lie outside the parts, µm: boxes.py's burn, this tool's
    /// total offset, or the range of a LightBurn project's Kerf Offsets (negative inwards).
    pub offset_um: RangeUm,
    /// The kerf it was made for, µm (this tool's records; for its gauge, the test piece's).
    pub kerf_um: Option<RangeUm>,
    /// The cut rules it used (this tool's records).
    pub rules: Option<String>,
    /// The version of the tool that made it (this tool's records).
    pub version: Option<String>,
    /// Where in the file it was found.
    pub found_in: String,
    /// boxes.py: the burn is boxes.py's default, the command line does not set it.
    pub default_burn: bool,
}

impl FoundCompensation {
    /// LightBurn's Kerf Offsets `offsets_um` (µm, positive outwards; at least one) found in
    /// `found_in` (its layers, in words): from a `.lbrn2` project or from a running LightBurn.
    pub fn lightburn(found_in: String, offsets_um: &[f64]) -> Option<Self> {
        let lo_um = offsets_um.iter().copied().fold(f64::INFINITY, f64::min);
        let hi_um = offsets_um.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (!offsets_um.is_empty()).then_some(FoundCompensation {
            by: CompensatedBy::LightBurn,
            offset_um: RangeUm([lo_um, hi_um]),
            kerf_um: None,
            rules: None,
            version: None,
            found_in,
            default_burn: false,
        })
    }

    /// What was found, in words, e.g. "boxes.py compensated this plan with --burn 0.1 (mm)".
    pub fn describe(&self) -> String {
        match self.by {
            CompensatedBy::BoxesPy => format!(
                "boxes.py compensated this plan with --burn {}{} (mm; found in {}): its cuts lie {} µm outside the parts",
                self.offset_um.0[0] / 1000.0,
                if self.default_burn {
                    ", boxes.py's default,"
                } else {
                    ""
                },
                self.found_in,
                self.offset_um
            ),
            CompensatedBy::Kerfmeter => format!(
                "{TOOL} {} already dilated this plan (found in {}): kerf {} µm, its cuts lie {} µm outside the parts; cut rules: {}",
                self.version.as_deref().unwrap_or("(unknown version)"),
                self.found_in,
                self.kerf_um
                    .map_or("(not recorded)".into(), |k| k.to_string()),
                self.offset_um,
                self.rules.as_deref().unwrap_or("(not recorded)")
            ),
            CompensatedBy::LightBurn => format!("Kerf Offsets already set: {}", self.found_in),
            CompensatedBy::KerfmeterGauge => format!(
                "this is the Kerfmeter gauge ({TOOL} gauge {}, found in {}), cut as drawn: its spiral's gap is what measures the laser's own kerf{}",
                self.version.as_deref().unwrap_or("(unknown version)"),
                self.found_in,
                self.kerf_um.map_or(String::new(), |k| format!(
                    ", and its test piece is already dilated by {k} µm"
                ))
            ),
        }
    }
}

/// The record a gauge drawing carries (`kerfmeter gauge`), so that `dilate` refuses it: it is
/// cut as drawn, its test piece (if any) already dilated by `test_piece_kerf_um`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaugeRecord {
    /// The kerf the test piece is dilated by, µm; `None` without a test piece.
    pub test_piece_kerf_um: Option<f64>,
}

impl GaugeRecord {
    /// The record as `key=value` fields after [`MARKER`] (one line, no `--`).
    fn record_line(&self) -> String {
        let test_piece = self
            .test_piece_kerf_um
            .map_or(String::new(), |k| format!(" test_piece_kerf_um={k}"));
        // A quoted value last: the comment's words follow a `:` right after it.
        format!(
            "{MARKER} tool={TOOL} version={} drawing=gauge offset_um=0{test_piece} rules=\"cut as drawn\"",
            env!("CARGO_PKG_VERSION")
        )
    }

    /// The words after the record.
    fn words(&self) -> &'static str {
        GAUGE_WORDS
    }

    /// The XML comment recording it in an SVG.
    pub fn svg_comment(&self) -> String {
        format!(
            "<!-- {} -->",
            comment_safe(&format!("{}: {}", self.record_line(), self.words()))
        )
    }

    /// The `999` comments recording it in a DXF, with the file's line ending.
    pub fn dxf_comments(&self, eol: &str) -> String {
        format!(
            "999{eol}{}{eol}999{eol}{}{eol}",
            self.record_line(),
            self.words()
        )
    }
}

/// What this run did about compensation: recorded in the output, and reported.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AppliedCompensation {
    /// What was done: `dilate` (no compensation found), `dilate_anyway`
    /// (`--already-compensated-ok`) or `recompensate`.
    pub action: String,
    /// The kerf applied, µm.
    pub kerf_um: RangeUm,
    /// How far this run moved the cuts away from the parts, µm (negative: towards them).
    pub net_offset_um: RangeUm,
    /// How far the output's cuts lie outside the parts, µm (what a later run must undo).
    pub offset_um: RangeUm,
    /// The cut rules, in words.
    pub rules: String,
    /// Small loops at inner corners (boxes.py's) removed before offsetting.
    pub corner_loops_removed: usize,
    /// The tool.
    pub tool: String,
    /// Its version.
    pub version: String,
}

impl AppliedCompensation {
    /// The record as `key=value` fields after [`MARKER`] (one line, no `--`).
    fn record_line(&self) -> String {
        format!(
            "{MARKER} tool={} version={} kerf_um={} net_offset_um={} offset_um={} rules=\"{}\"",
            self.tool,
            self.version,
            self.kerf_um,
            self.net_offset_um,
            self.offset_um,
            self.rules.replace('"', "'")
        )
    }

    /// The XML comment and `<metadata>` element recording this compensation in an SVG.
    pub(crate) fn svg_record(&self) -> String {
        let comment = format!(
            "{}: the cuts of this plan lie {} µm outside its parts (kerf {} µm); do not dilate it again (kerfmeter dilate refuses it, and recompensates it for another kerf when asked)",
            self.record_line(),
            self.offset_um,
            self.kerf_um
        );
        format!(
            "\n<!-- {} -->\n<metadata><kerfmeter:compensation xmlns:kerfmeter=\"{NAMESPACE}\" tool=\"{}\" version=\"{}\" kerf_um=\"{}\" net_offset_um=\"{}\" offset_um=\"{}\" rules=\"{}\"/></metadata>",
            comment_safe(&comment),
            crate::xml::escape(&self.tool),
            crate::xml::escape(&self.version),
            self.kerf_um,
            self.net_offset_um,
            self.offset_um,
            crate::xml::escape(&self.rules)
        )
    }

    /// The `999` comments recording this compensation in a DXF, with the file's line ending.
    pub(crate) fn dxf_record(&self, eol: &str) -> String {
        let human = format!(
            "{DXF_WORDS}{} um outside its parts (kerf {} um); do not dilate it again",
            self.offset_um, self.kerf_um
        );
        format!("999{eol}{}{eol}999{eol}{human}{eol}", self.record_line())
    }
}

impl AppliedCompensation {
    /// The record as one XML comment (the record line, then `what` in words), for formats that
    /// keep it nowhere else (LightBurn projects).
    pub fn xml_comment(&self, what: &str) -> String {
        format!(
            "<!-- {} -->",
            comment_safe(&format!(
                "{}: {what}; kerf {} µm, offset now {} µm",
                self.record_line(),
                self.kerf_um,
                self.offset_um
            ))
        )
    }
}

/// Whether a comment's text is a record of this tool's.
pub fn is_record(comment: &str) -> bool {
    comment.trim_start().starts_with(MARKER)
}

/// How the words of a dilated DXF's record begin (the `999` comment after the record line).
const DXF_WORDS: &str = "the cuts of this drawing lie ";
/// The words of a gauge drawing's record.
const GAUGE_WORDS: &str =
    "the Kerfmeter gauge: cut it as drawn, never dilated (kerfmeter dilate refuses it)";

/// Whether a comment is one this tool writes with a record (the record line, or the words after
/// it, a dilated plan's or a gauge's): an earlier record's, dropped when a plan is written again.
pub(crate) fn is_own_comment(comment: &str) -> bool {
    let text = comment.trim_start();
    is_record(text) || text.starts_with(DXF_WORDS) || text.starts_with(GAUGE_WORDS)
}

/// The record of a compensation set as a setting rather than drawn (LightBurn's Kerf Offset):
/// `net_um` this run's change, `total_um` the offset now, both as ranges over the layers set.
pub fn applied_setting(
    action: &str,
    kerf_um: f64,
    net_um: [f64; 2],
    total_um: [f64; 2],
    rules: String,
) -> AppliedCompensation {
    AppliedCompensation {
        action: action.into(),
        kerf_um: RangeUm::one(kerf_um),
        net_offset_um: RangeUm(net_um),
        offset_um: RangeUm(total_um),
        rules,
        corner_loops_removed: 0,
        tool: TOOL.into(),
        version: env!("CARGO_PKG_VERSION").into(),
    }
}

/// A comment's text made safe for XML (`--` is not allowed in a comment).
fn comment_safe(s: &str) -> String {
    let mut out = s.replace("--", "- -");
    while out.contains("--") {
        out = out.replace("--", "- -");
    }
    if out.ends_with('-') {
        out.push(' ');
    }
    out
}

/// What to do with a plan, decided from what it says and what the user asked.
#[derive(Debug, Clone)]
pub(crate) struct Treatment {
    /// How the contours are offset.
    pub offsetting: Offsetting,
    /// Remove loops at inner corners no larger than this (mm) before offsetting.
    pub corner_loop_max_mm: Option<f64>,
    /// The offset already in the plan, µm (0 when none).
    pub carried_um: RangeUm,
    /// The action, as recorded.
    pub action: &'static str,
}

/// Decide what to do with a plan that carries `found` (if anything), or refuse it.
pub(crate) fn treatment(
    found: Option<&FoundCompensation>,
    policy: IfCompensated,
    kerf: &KerfSource,
) -> Result<Treatment> {
    if let Some(gauge) = found.filter(|f| f.by == CompensatedBy::KerfmeterGauge) {
        return gauge_treatment(gauge, policy, kerf);
    }
    let Some(found) = found.filter(|f| f.offset_um.0[1] > 0.0) else {
        return Ok(Treatment {
            offsetting: Offsetting::Dilate,
            corner_loop_max_mm: None,
            carried_um: RangeUm::one(0.0),
            action: "dilate",
        });
    };
    // boxes.py's loops span about one burn; leave room for its 1 µm rounding.
    let corner_loop_max_mm = Some(4.0 * found.offset_um.0[1] / 1000.0 + 0.005);
    match policy {
        IfCompensated::Refuse => Err(refused(found, refusal(found, Some(kerf)))),
        IfCompensated::DilateAnyway => Ok(Treatment {
            offsetting: Offsetting::Dilate,
            corner_loop_max_mm,
            carried_um: found.offset_um,
            action: "dilate_anyway",
        }),
        IfCompensated::Recompensate if !found.offset_um.is_uniform() => Err(refused(
            found,
            format!(
                "{}; it varies over the bed (a kerf map), so it cannot be undone here: recompensate the original plan instead (nothing was written)",
                found.describe()
            ),
        )),
        IfCompensated::Recompensate => Ok(Treatment {
            offsetting: Offsetting::Recompensate {
                burn_mm: found.offset_um.0[0] / 1000.0,
            },
            corner_loop_max_mm,
            carried_um: found.offset_um,
            action: "recompensate",
        }),
    }
}

/// The check of a plan a job will dilate by the kerf it has yet to measure, made before anything
/// moves: refused, with the same reasons and ways on as its dilation would give once the kerf is
/// known (after the gauge was cut and measured), unless `policy` says what to do. A gauge drawing
/// is refused whatever `policy` but [`IfCompensated::DilateAnyway`].
pub fn check_before_measuring(
    found: Option<&FoundCompensation>,
    policy: IfCompensated,
) -> Result<()> {
    let Some(found) = found else {
        return Ok(());
    };
    let gauge = found.by == CompensatedBy::KerfmeterGauge;
    let refuse = match policy {
        IfCompensated::DilateAnyway => false,
        IfCompensated::Recompensate => gauge,
        IfCompensated::Refuse => gauge || found.offset_um.0[1] > 0.0,
    };
    if !refuse {
        return Ok(());
    }
    let message = if gauge {
        gauge_refusal(found, policy, None)
    } else {
        refusal(found, None)
    };
    Err(refused(found, message))
}

/// A compensated plan refused with `message`.
fn refused(found: &FoundCompensation, message: impl Into<Advised>) -> PlanError {
    PlanError::AlreadyCompensated {
        message: message.into(),
        found: Box::new(found.clone()),
    }
}

/// A gauge drawing is cut as drawn: at a kerf of 0 (its cuts as drawn, as `gcode` makes them)
/// it passes; otherwise it is refused, unless dilated anyway on the user's word (never
/// "recompensated": its spiral carries no compensation to undo).
fn gauge_treatment(
    gauge: &FoundCompensation,
    policy: IfCompensated,
    kerf: &KerfSource,
) -> Result<Treatment> {
    let as_drawn = matches!(kerf, KerfSource::Uniform(k) if *k == 0.0);
    if as_drawn || policy == IfCompensated::DilateAnyway {
        return Ok(Treatment {
            offsetting: Offsetting::Dilate,
            corner_loop_max_mm: None,
            carried_um: RangeUm::one(0.0),
            action: if as_drawn { "dilate" } else { "dilate_anyway" },
        });
    }
    Err(refused(gauge, gauge_refusal(gauge, policy, Some(kerf))))
}

/// Why a gauge drawing is not dilated, and the ways on: by the `kerf` given (`dilate`, `gcode`),
/// or, with none, by a job's (which would dilate it as the plan of its parts).
fn gauge_refusal(
    gauge: &FoundCompensation,
    policy: IfCompensated,
    kerf: Option<&KerfSource>,
) -> Advised {
    let recompensate = if policy == IfCompensated::Recompensate {
        Advised::text(" ")
            .advise(Advice::Recompensate)
            .then(" does not apply: the spiral carries no compensation to undo.")
    } else {
        Advised::default()
    };
    let twice = if gauge.kerf_um.is_some() {
        ", and compensate the test piece twice"
    } else {
        ""
    };
    let what = gauge.describe();
    let refusal = match kerf {
        Some(_) => Advised::text(format!(
            "{what}. Dilating it would widen the spiral's gap, so the device would read a kerf too small{twice}; cut it as it is, nothing was written (for its G-code: `kerfmeter gauge -o gauge.gcode --at-mm X,Y`; "
        )),
        None => Advised::text(format!(
            "{what}: a gauge is cut as drawn, not dilated as a job's plan (dilated, its spiral's gap would widen, so the device would read a kerf too small{twice}); nothing was cut. Give the plan of the parts to cut ("
        )),
    };
    let anyway = if kerf.is_some() {
        " dilates it anyway)."
    } else {
        " dilates this one anyway)."
    };
    refusal
        .advise(Advice::AlreadyCompensatedOk)
        .then(anyway)
        .append(recompensate)
}

/// The refusal of a plan compensated elsewhere or before: what was found, why it is refused, and
/// the two ways on. By the `kerf` given (`dilate`, `gcode`: with the net move when it is one
/// figure), or, with none, by the kerf a job would measure.
fn refusal(found: &FoundCompensation, kerf: Option<&KerfSource>) -> Advised {
    let burn_um = found.offset_um.0[0];
    let net = match kerf {
        Some(KerfSource::Uniform(k)) => format!(
            " = {} − {burn_um} = {} µm",
            k / 2.0,
            ((k / 2.0 - burn_um) * 1000.0).round() / 1000.0
        ),
        _ => String::new(),
    };
    let (twice, undone) = match kerf {
        Some(_) => (
            "Dilating it by the kerf again would compensate twice",
            "nothing was written",
        ),
        None => (
            "The job would dilate it by the kerf it measures and compensate it twice",
            "nothing was cut",
        ),
    };
    Advised::text(format!(
        "{}. {twice} and make every joint too loose; {undone}. Either undo that compensation and apply the measured kerf instead with ",
        found.describe()
    ))
    .advise(Advice::Recompensate)
    .then(format!(
        " (each cut moves by kerf/2 − burn{net}, inner corners kept sharp), or dilate it by the full kerf anyway with "
    ))
    .advise(Advice::AlreadyCompensatedOk)
    .then(".")
}

/// The applied record, once the parts' kerfs are known (`kerf_range_um` from the summary).
pub(crate) fn applied(
    t: &Treatment,
    kerf_range_um: Option<[f64; 2]>,
    kerf: &KerfSource,
    rules: String,
    corner_loops_removed: usize,
) -> AppliedCompensation {
    let [lo, hi] = kerf_range_um.unwrap_or_else(|| {
        let k = kerf.kerf_at_um(0.0, 0.0);
        [k, k]
    });
    let carried = t.carried_um.0;
    let (net, total) = match t.offsetting {
        Offsetting::Dilate => (
            [lo / 2.0, hi / 2.0],
            [carried[0] + lo / 2.0, carried[1] + hi / 2.0],
        ),
        Offsetting::Recompensate { burn_mm } => (
            [lo / 2.0 - burn_mm * 1000.0, hi / 2.0 - burn_mm * 1000.0],
            [lo / 2.0, hi / 2.0],
        ),
    };
    AppliedCompensation {
        action: t.action.into(),
        kerf_um: RangeUm([lo, hi]),
        net_offset_um: RangeUm(net),
        offset_um: RangeUm(total),
        rules,
        corner_loops_removed,
        tool: TOOL.into(),
        version: env!("CARGO_PKG_VERSION").into(),
    }
}

#[cfg(test)]
mod tests;
