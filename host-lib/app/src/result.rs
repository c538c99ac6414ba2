//! A kerf result as a report: its JSON (the device's fields, and its quality flags by name) and
//! the table the CLI prints.

use std::fmt;

use kerfmeter::protocol::{KerfResult, QualityFlags};
use serde::Serialize;

/// A kerf result as JSON: the device's own fields (`flags` as its bits), and `flag_names`, the
/// flags by name (`weak-magnet`, `force-sensitive`, ...) for readers that do not know the bits.
#[derive(Serialize)]
pub struct ResultJson<'a> {
    /// The device's result.
    #[serde(flatten)]
    result: &'a KerfResult,
    /// Its quality flags by name; empty when it has none.
    flag_names: Vec<&'static str>,
}

impl<'a> From<&'a KerfResult> for ResultJson<'a> {
    fn from(result: &'a KerfResult) -> Self {
        ResultJson {
            result,
            flag_names: result.flags.names().collect(),
        }
    }
}

/// `serialize_with` for a list of results: each as [`ResultJson`].
pub fn results_json<S: serde::Serializer>(runs: &[KerfResult], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(runs.iter().map(ResultJson::from))
}

/// `serialize_with` for a result that may be missing: as [`ResultJson`], or `null`.
pub fn result_json<S: serde::Serializer>(
    result: &Option<KerfResult>,
    s: S,
) -> Result<S::Ok, S::Error> {
    result.as_ref().map(ResultJson::from).serialize(s)
}

/// The table of kerf results that `run` and `kerf` print.
pub struct ResultsTable<'a>(pub &'a [KerfResult]);

impl fmt::Display for ResultsTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:>4} {:>10} {:>10} {:>9} {:>11} {:>9}  flags",
            "run", "kerf µm", "angle °", "play °", "torque N·m", "force N"
        )?;
        for r in self.0 {
            write!(
                f,
                "\n{:>4} {:>10.1} {:>10.2} {:>9.2} {:>11.3} {:>9.1}  {}",
                r.run_id,
                r.kerf_um,
                r.angle_deg,
                r.play_deg,
                r.torque_at_jam_nm,
                r.force_at_jam_n,
                flags_text(r.flags)
            )?;
        }
        Ok(())
    }
}

/// The quality flags in words, or "ok".
fn flags_text(flags: QualityFlags) -> String {
    let names: Vec<&str> = flags.names().collect();
    if names.is_empty() {
        "ok".into()
    } else {
        names.join(",")
    }
}
