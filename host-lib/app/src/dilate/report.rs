//! What a plan file's dilation did ([`DilateReport`]): its JSON is `kerfmeter dilate --json`'s
//! and Python's `dilate()`'s dict, its text the command's lines.

use std::fmt;
use std::path::PathBuf;

use kerfmeter::protocol::advice::Advice;
use kerfmeter_plan::PlanFormat;
use kerfmeter_plan::outcome::PlanSummary;
use serde::Serialize;

/// What `dilate` did (or, with `--dry-run`, would do).
#[derive(Debug, Clone, Serialize)]
pub struct DilateReport {
    /// The plan read.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub input: PathBuf,
    /// The file written (`None` on a dry run).
    #[serde(serialize_with = "crate::lossy_path::option")]
    pub output: Option<PathBuf>,
    /// True when nothing was written.
    pub dry_run: bool,
    /// The file format (for the text; the JSON has the summary's `format`, one key).
    #[serde(skip)]
    pub format: PlanFormat,
    /// The kerf given, µm (with a map: at the reference cell).
    pub kerf_um: f64,
    /// The kerf map used.
    #[serde(serialize_with = "crate::lossy_path::option")]
    pub map: Option<PathBuf>,
    /// The cut rules, in words.
    pub cut_rules: String,
    /// What was found and done.
    #[serde(flatten)]
    pub summary: PlanSummary,
}

impl fmt::Display for DilateReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.summary;
        // With a map each part has its own kerf: the headline names the map's reference.
        let by = match &self.map {
            Some(_) => format!(
                "by the kerf map ({} µm at its reference cell; each cut moved half its part's kerf)",
                self.kerf_um
            ),
            None => format!(
                "by {} µm (each cut moved {} µm)",
                self.kerf_um,
                moved_um(s, self.kerf_um)
            ),
        };
        match (&self.output, self.dry_run) {
            (Some(out), false) => writeln!(
                f,
                "dilated {} → {} ({}) {by}",
                self.input.display(),
                out.display(),
                self.format,
            )?,
            _ => writeln!(
                f,
                "dry run, nothing written: {} ({}) {by}",
                self.input.display(),
                self.format,
            )?,
        }
        writeln!(
            f,
            "  {} closed contour{} in {} part{} ({} hole{}, {} island{}) from {} cut element{}; {} element{} rewritten",
            s.contours_dilated,
            plural(s.contours_dilated),
            s.parts,
            plural(s.parts),
            s.holes,
            plural(s.holes),
            s.islands,
            plural(s.islands),
            s.cut_elements,
            plural(s.cut_elements),
            s.changed_elements,
            plural(s.changed_elements)
        )?;
        if let (Some(map), Some([lo, hi])) = (&self.map, s.kerf_range_um) {
            writeln!(
                f,
                "  kerf per part {lo:.1}–{hi:.1} µm from the map {}",
                map.display()
            )?;
        }
        writeln!(f, "  cut rules: {}", self.cut_rules)?;
        if s.passed_through.is_empty() {
            writeln!(f, "  passed through untouched: nothing")?;
        } else {
            let list: Vec<String> = s
                .passed_through
                .iter()
                .map(|(reason, n)| format!("{n} × {reason}"))
                .collect();
            writeln!(f, "  passed through untouched: {}", list.join(", "))?;
        }
        write_open_paths(f, s)?;
        write_compensation(f, s)?;
        for n in &s.notes {
            writeln!(f, "  note: {n}")?;
        }
        Ok(())
    }
}

/// The warning about open cut paths, which stay as drawn (nothing when there are none).
fn write_open_paths(f: &mut fmt::Formatter<'_>, s: &PlanSummary) -> fmt::Result {
    if s.open_paths.is_empty() {
        return Ok(());
    }
    writeln!(
        f,
        "  warning: {} open cut path{} cannot be dilated and {} left as drawn:",
        s.open_paths.len(),
        plural(s.open_paths.len()),
        if s.open_paths.len() == 1 {
            "was"
        } else {
            "were"
        }
    )?;
    for o in &s.open_paths {
        writeln!(f, "    - {o}")?;
    }
    Ok(())
}

/// How far the cuts moved, µm, as text: the net offset applied (with `--recompensate`, the
/// kerf's half less the burn undone), else the kerf's half.
fn moved_um(s: &PlanSummary, kerf_um: f64) -> String {
    s.compensation_applied.as_ref().map_or_else(
        || (kerf_um / 2.0).to_string(),
        |a| a.net_offset_um.to_string(),
    )
}

/// What compensation was found and what was applied (nothing when none was found).
pub fn write_compensation(f: &mut fmt::Formatter<'_>, s: &PlanSummary) -> fmt::Result {
    let (Some(found), Some(applied)) = (&s.compensation_found, &s.compensation_applied) else {
        return Ok(());
    };
    writeln!(f, "  found: {}", found.describe())?;
    let what = match applied.action.as_str() {
        "recompensate" => format!("undone and replaced by the kerf ({})", Advice::Recompensate),
        "dilate_anyway" => format!(
            "kept, the kerf added on top ({})",
            Advice::AlreadyCompensatedOk
        ),
        _ => "none (not a compensation)".to_owned(),
    };
    writeln!(
        f,
        "  compensation: {what}; cuts moved {} µm, now {} µm outside the parts{}",
        applied.net_offset_um,
        applied.offset_um,
        if applied.corner_loops_removed > 0 {
            format!(
                "; {} loop{} at inner corners removed",
                applied.corner_loops_removed,
                plural(applied.corner_loops_removed)
            )
        } else {
            String::new()
        }
    )
}

/// "s" unless `n` is 1.
pub fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}
