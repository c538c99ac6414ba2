//! `kerfmeter self-test`: check the encoder, magnet, drive direction and torque constant (no
//! gauge under the prongs). A failed item makes the command fail after reporting every item,
//! each failed one explained in words (what its value means, what to check).

use std::fmt;
use std::ops::ControlFlow;

use kerfmeter::protocol::{Conditions, SelfTestItem, SelfTestReport, TestOutcome};
use kerfmeter_app::self_test::{explain, items};
use serde::Serialize;

use kerfmeter::Progress;

use crate::connection::{Global, Session};
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::progress::{progress_bar, show};

/// The self-test's items, whether all passed, and why those that failed did.
#[derive(Serialize)]
pub struct SelfTestOutcome {
    /// True when every item passed.
    pub passed: bool,
    /// The device's report.
    pub report: SelfTestReport,
    /// Each failed item, in the order printed, with what its value means.
    pub failures: Vec<Failure>,
    /// The device reports its ADC uncalibrated (`adc-uncalibrated`, protocol 2.6): its current
    /// sense, and so the torque constant, reads some 30–40 % high, still inside the item's
    /// window; the text says so beside the items.
    pub adc_uncalibrated: bool,
}

/// A failed item, explained.
#[derive(Serialize, Debug, Clone, PartialEq)]
pub struct Failure {
    /// The item's name, as printed.
    pub item: &'static str,
    /// What its value says went wrong, and what to check.
    pub reason: String,
}

impl SelfTestOutcome {
    /// The outcome of `report`, by a device configured with `torque_per_duty_nm` (`None`: not
    /// known).
    pub fn new(report: SelfTestReport, torque_per_duty_nm: Option<f32>) -> Self {
        let failures: Vec<Failure> = items(&report)
            .into_iter()
            .filter(|(_, i, _)| i.outcome != TestOutcome::Pass)
            .map(|(item, i, _)| Failure {
                item,
                reason: explain(item, i, torque_per_duty_nm),
            })
            .collect();
        SelfTestOutcome {
            passed: failures.is_empty(),
            report,
            failures,
            adc_uncalibrated: false,
        }
    }
}

/// Run the device's self-test.
pub fn run(g: &Global) -> Result<SelfTestOutcome, CliError> {
    let mut s = g.connect()?;
    let bar = progress_bar(g, "self-test");
    let outcome = test(&mut s, |p| {
        show(&bar, p);
        crate::interrupt::check()
    });
    bar.finish_and_clear();
    outcome
}

/// Run the self-test of the device behind an open session, reporting to `progress`, which can
/// stop it (`kerfmeter serve` shares it).
pub fn test(
    s: &mut Session,
    progress: impl FnMut(&Progress) -> ControlFlow<()>,
) -> Result<SelfTestOutcome, CliError> {
    let report = s.meter.self_test_until(progress)?;
    // Only to explain a failed torque constant: a device that cannot answer still has its report.
    let configured = s.meter.config().ok().map(|c| c.config.torque_per_duty_nm);
    let mut outcome = SelfTestOutcome::new(report, configured);
    outcome.adc_uncalibrated = s
        .meter
        .status()
        .is_ok_and(|st| st.conditions.contains(Conditions::ADC_UNCALIBRATED));
    Ok(outcome)
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
        })?;
        for Failure { item, reason } in &self.failures {
            write!(f, "\n  {item}: {reason}")?;
        }
        if self.adc_uncalibrated {
            write!(
                f,
                "\nnote: this chip's ADC is uncalibrated (no calibration eFuses): its current \
                 sense reads some 30–40 % high, and the torque constant above with it"
            )?;
        }
        Ok(())
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

#[cfg(test)]
mod tests {
    use super::*;

    fn passed(value: f32) -> SelfTestItem {
        SelfTestItem {
            outcome: TestOutcome::Pass,
            value,
        }
    }

    #[test]
    fn an_uncalibrated_adc_is_said_beside_the_items_of_a_passed_self_test() {
        let report = SelfTestReport {
            encoder_ok_fraction: passed(1.0),
            magnet_magnitude: passed(4000.0),
            direction_deg: passed(12.0),
            torque_per_duty_nm: passed(1.19),
        };
        let mut outcome = SelfTestOutcome::new(report, Some(0.88));
        assert!(outcome.passed);
        assert!(!outcome.to_string().contains("uncalibrated"));
        outcome.adc_uncalibrated = true;
        let text = outcome.to_string();
        assert!(text.contains("self-test passed"), "{text}");
        assert!(text.contains("ADC is uncalibrated"), "{text}");
        assert!(text.contains("30–40 % high"), "{text}");
    }
}
