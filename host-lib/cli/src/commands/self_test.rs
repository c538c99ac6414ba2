//! `kerfmeter self-test`: check the encoder, magnet, drive direction and torque constant (no
//! gauge under the prongs). A failed item makes the command fail after reporting every item.

use std::fmt;

use kerfmeter::protocol::{SelfTestItem, SelfTestReport, TestOutcome};
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::progress::{progress_bar, show};

/// The self-test's items and whether all passed.
#[derive(Serialize)]
pub struct SelfTestOutcome {
    /// True when every item passed.
    pub passed: bool,
    /// The device's report.
    pub report: SelfTestReport,
}

impl SelfTestOutcome {
    /// The outcome of `report`.
    pub fn new(report: SelfTestReport) -> Self {
        let passed = items(&report)
            .iter()
            .all(|(_, i, _)| i.outcome == TestOutcome::Pass);
        SelfTestOutcome { passed, report }
    }
}

/// Each item with its name and unit, in the order printed.
fn items(r: &SelfTestReport) -> [(&'static str, SelfTestItem, &'static str); 4] {
    [
        ("encoder reads ok", r.encoder_ok_fraction, ""),
        ("magnet magnitude", r.magnet_magnitude, ""),
        ("direction", r.direction_deg, "°"),
        ("torque constant", r.torque_per_duty_nm, " N·m"),
    ]
}

/// Run the device's self-test.
pub fn run(g: &Global) -> Result<SelfTestOutcome, CliError> {
    let mut s = g.connect()?;
    let bar = progress_bar(g, "self-test");
    let report = s.meter.self_test(|p| show(&bar, p));
    bar.finish_and_clear();
    Ok(SelfTestOutcome::new(report?))
}

impl fmt::Display for SelfTestOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (name, SelfTestItem { outcome, value }, unit) in items(&self.report) {
            writeln!(
                f,
                "{name:<18} {:<8} {value:.3}{unit}",
                format!("{outcome:?}")
            )?;
        }
        f.write_str(if self.passed {
            "self-test passed"
        } else {
            "self-test FAILED"
        })
    }
}

impl Report for SelfTestOutcome {
    const JSON: JsonLayout = JsonLayout::CompactSorted;

    fn verdict(&self) -> Result<(), CliError> {
        if self.passed {
            Ok(())
        } else {
            Err(CliError::SelfTestFailed)
        }
    }
}
