//! `kerfmeter bringup`: the guided first power-on ([`kerfmeter_app::bringup`]). This module only
//! turns the flags into a request, asks the person at a terminal what only they can see, and
//! saves and prints the report; the checks and their words are the library's.

use std::fmt;
use std::io::{BufRead, IsTerminal, Write};
use std::path::PathBuf;

use clap::Args;
use kerfmeter_app::bringup::{
    self, BringupReport, BringupRequest, HubTurn, ReportFiles, TwinTruth, Witness,
};
use serde::Serialize;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

#[derive(Args)]
pub struct BringupArgs {
    /// The motor supply your meter reads at the G2's VIN, V (else asked at a terminal; with
    /// --sim the twin's supply answers).
    #[arg(long, value_name = "V")]
    meter_v: Option<f32>,
    /// Which way the hub turned first in the self-test, seen from above: cw, ccw or still (else
    /// asked at a terminal; with --sim the twin answers).
    #[arg(long, value_name = "cw|ccw|still")]
    hub_turned: Option<HubTurn>,
    /// A cut gauge is under the prongs, lowered into it, for the last step's run (else asked at
    /// a terminal; with --sim the twin places its own).
    #[arg(long, conflicts_with = "no_gauge")]
    gauge_placed: bool,
    /// No run on a gauge: that step is left not checked.
    #[arg(long)]
    no_gauge: bool,
    /// Where to save the report: PATH.txt and PATH.json [default:
    /// kerfmeter-bringup-<date>.txt and .json in the current folder].
    #[arg(long, value_name = "PATH")]
    report: Option<PathBuf>,
}

/// The report and where it was saved.
#[derive(Serialize)]
pub struct BringupOutcome {
    /// The bring-up's report.
    #[serde(flatten)]
    pub report: BringupReport,
    /// The files it was saved to.
    pub saved: ReportFiles,
}

/// Walk the bench checks, save the report, and print it.
pub fn run(g: &Global, args: &BringupArgs) -> Result<BringupOutcome, CliError> {
    let files = ReportFiles::choose(args.report.as_deref(), &bringup::today());
    let inputs: Vec<&std::path::Path> = g.sim_plant_file.as_deref().into_iter().collect();
    let request = BringupRequest {
        meter_v: args.meter_v,
        hub_turned: args.hub_turned,
        gauge_placed: match (args.gauge_placed, args.no_gauge) {
            (true, _) => Some(true),
            (_, true) => Some(false),
            _ => None,
        },
    };
    files.check(&inputs)?;
    request.check()?;
    let mut session = g.connect()?;
    let twin = session.sim.as_ref().map(|sim| TwinTruth::of(sim.options()));
    let interactive = !g.json && std::io::stdin().is_terminal();
    let mut witness: Box<dyn Witness> = if interactive {
        Box::new(Terminal)
    } else {
        Box::new(bringup::NoWitness)
    };
    let report = bringup::bring_up(&mut session.meter, &request, twin, witness.as_mut(), |_| {
        crate::interrupt::check()
    })?;
    files.save(&report)?;
    Ok(BringupOutcome {
        report,
        saved: files,
    })
}

/// The person at the terminal, asked on stderr.
struct Terminal;

impl Terminal {
    /// Ask `question`; the answer's line, trimmed (`None`: nothing typed or nothing to read).
    fn ask(question: &str) -> Option<String> {
        eprint!("{question} ");
        std::io::stderr().flush().ok();
        let mut line = String::new();
        crate::interrupt::at_prompt(|| std::io::stdin().lock().read_line(&mut line)).ok()?;
        let answer = line.trim();
        (!answer.is_empty()).then(|| answer.to_owned())
    }

    /// Ask until the answer parses or is left empty.
    fn ask_parsed<T>(question: &str, parse: impl Fn(&str) -> Result<T, String>) -> Option<T> {
        loop {
            match parse(&Self::ask(question)?) {
                Ok(value) => return Some(value),
                Err(why) => eprintln!("{why}"),
            }
        }
    }
}

impl Witness for Terminal {
    fn meter_v(&mut self, device_v: f32) -> Option<f32> {
        Self::ask_parsed(
            &format!(
                "The device reads its motor supply as {device_v:.2} V. What does your meter read \
                 at the G2's VIN, in volts? (Enter to skip)"
            ),
            |s| {
                s.trim_end_matches(['V', 'v'])
                    .trim()
                    .parse::<f32>()
                    .map_err(|_| format!("`{s}` is not a number of volts"))
            },
        )
    }

    fn watch_hub(&mut self) {
        Self::ask(
            "Next, the self-test turns the hub a little each way (no gauge under the prongs). \
             Watch it from above, then press Enter",
        );
    }

    fn hub_turned(&mut self) -> Option<HubTurn> {
        Self::ask_parsed(
            "Which way did the hub turn first, seen from above: cw, ccw or still? (Enter to skip)",
            str::parse,
        )
    }

    fn gauge_placed(&mut self) -> Option<bool> {
        Self::ask_parsed(
            "Last, one run on a cut gauge (`kerfmeter gauge -o gauge.svg`). Lower the prongs \
             into one: is it in place? (y/n)",
            |s| match s.to_ascii_lowercase().as_str() {
                "y" | "yes" => Ok(true),
                "n" | "no" => Ok(false),
                _ => Err("say y or n".to_owned()),
            },
        )
    }
}

impl fmt::Display for BringupOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}\nreport saved to {} and {}",
            self.report,
            self.saved.text.display(),
            self.saved.json.display()
        )
    }
}

impl Report for BringupOutcome {
    const JSON: JsonLayout = JsonLayout::Pretty;

    fn verdict(&self) -> Result<(), CliError> {
        if self.report.passed {
            Ok(())
        } else {
            Err(CliError::BringupFailed)
        }
    }
}
