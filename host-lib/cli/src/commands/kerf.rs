//! `kerfmeter kerf`: the last result the device kept.

use std::fmt;

use kerfmeter::protocol::KerfResult;
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report, ResultsTable};

/// The device's last result, if it has one.
#[derive(Serialize)]
pub struct KerfReport {
    /// The kerf of that result, µm.
    pub kerf_um: Option<f32>,
    /// The whole result, its flags also by name.
    #[serde(serialize_with = "crate::output::result_json")]
    pub result: Option<KerfResult>,
}

impl KerfReport {
    /// The report of `result`.
    pub fn new(result: Option<KerfResult>) -> Self {
        KerfReport {
            kerf_um: result.map(|r| r.kerf_um),
            result,
        }
    }
}

/// Read the device's last result.
pub fn run(g: &Global) -> Result<KerfReport, CliError> {
    let result = g.connect()?.meter.get_kerf_value()?;
    Ok(KerfReport::new(result))
}

impl fmt::Display for KerfReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.result {
            Some(r) => ResultsTable(std::slice::from_ref(r)).fmt(f),
            None => f.write_str("no result: the device has not measured since its last reset"),
        }
    }
}

impl Report for KerfReport {
    const JSON: JsonLayout = JsonLayout::CompactSorted;
}

#[cfg(test)]
mod tests {
    use kerfmeter::protocol::QualityFlags;

    use super::*;
    use crate::output::to_json;

    #[test]
    fn the_printed_kerf_is_the_json_kerf_rounded() {
        let result = KerfResult {
            run_id: 7,
            kerf_um: 151.86,
            angle_deg: 60.2,
            play_deg: 5.3,
            torque_at_jam_nm: 0.64,
            force_at_jam_n: 55.0,
            flags: QualityFlags::default(),
        };
        let report = KerfReport::new(Some(result));
        let json: serde_json::Value =
            serde_json::from_str(&to_json(&report, KerfReport::JSON)).unwrap();
        let text = report.to_string();
        let row: Vec<&str> = text.lines().nth(1).unwrap().split_whitespace().collect();
        assert_eq!(row[0], "7");
        let kerf_um = json["kerf_um"].as_f64().unwrap();
        assert_eq!(row[1], format!("{kerf_um:.1}"));
        assert_eq!(row[1], "151.9");
        assert_eq!(json["result"]["run_id"], 7);
    }

    #[test]
    fn no_result_is_null_in_json_and_said_in_text() {
        let report = KerfReport::new(None);
        assert_eq!(
            to_json(&report, KerfReport::JSON),
            r#"{"kerf_um":null,"result":null}"#
        );
        assert!(report.to_string().starts_with("no result"));
    }
}
