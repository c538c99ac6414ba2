//! The loop's stages ([`Stage`]): their names in reports and what each says to the user.

use std::fmt;

use serde::Serialize;

/// The loop's stages, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Stream the gauge's G-code.
    CutGauge,
    /// Wait until the controller reports the motion finished.
    WaitMotion,
    /// Move the prongs over the gauge and lower them into its holes.
    Lower,
    /// Run the device.
    Measure,
    /// Lift the prongs clear.
    Lift,
    /// Dilate the plan by the kerf measured and write its G-code.
    Dilate,
    /// Stream the job.
    StreamJob,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 7] = [
        Stage::CutGauge,
        Stage::WaitMotion,
        Stage::Lower,
        Stage::Measure,
        Stage::Lift,
        Stage::Dilate,
        Stage::StreamJob,
    ];

    /// Its name in JSON and messages.
    pub fn name(self) -> &'static str {
        match self {
            Stage::CutGauge => "cut-gauge",
            Stage::WaitMotion => "wait-motion",
            Stage::Lower => "lower",
            Stage::Measure => "measure",
            Stage::Lift => "lift",
            Stage::Dilate => "dilate",
            Stage::StreamJob => "stream-job",
        }
    }

    /// What it does, for a progress display.
    pub fn describe(self) -> &'static str {
        match self {
            Stage::CutGauge => "cutting the gauge",
            Stage::WaitMotion => "waiting for the motion to end",
            Stage::Lower => "lowering the prongs into the gauge",
            Stage::Measure => "measuring the kerf",
            Stage::Lift => "lifting the prongs",
            Stage::Dilate => "dilating the plan",
            Stage::StreamJob => "cutting the job",
        }
    }

    /// What to do before the head moves again when the loop stopped in this stage: in the
    /// stages that lower, hold and lift the prongs they may still be down in the gauge (a stop
    /// moves nothing, not even Z). Empty for the other stages.
    pub fn prongs_note(self) -> &'static str {
        match self {
            Stage::Lower | Stage::Measure | Stage::Lift => {
                ". The prongs may still be down in the gauge: lift them (jog Z up to the travel height) before anything moves the head"
            }
            _ => "",
        }
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}
