//! What the person at the terminal sees while a command works: a spinner with the device's
//! progress (hidden with `--json`), a bar while a plan is dilated (on a terminal only), and the
//! prompts before each gauge (hardware only).

use std::io::{BufRead, IsTerminal, Write};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use kerfmeter::protocol::{KerfResult, RunParams};
use kerfmeter::{Kerfmeter, Progress};
use kerfmeter_plan::progress::{Progress as PlanProgress, Stage};

use crate::connection::Global;
use crate::error::CliError;

/// A spinner labelled `label`, hidden with `--json`.
pub fn progress_bar(g: &Global, label: &str) -> ProgressBar {
    if g.json {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {prefix} {msg}").expect("valid template"),
    );
    bar.set_prefix(label.to_owned());
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

/// Show the device's progress on `bar`.
pub fn show(bar: &ProgressBar, p: &Progress) {
    bar.set_message(format!(
        "{:<10} torque {:6.3} N·m   angle {:7.2}°   {:5.2} s",
        format!("{:?}", p.state),
        p.torque_nm,
        p.angle_deg,
        f64::from(p.elapsed_ms) / 1000.0
    ));
}

/// Progress of a plan dilation, shown as a bar on stderr when it is a terminal and `json` is off
/// (otherwise nothing is shown, and the returned bar is hidden). Finish the bar when done.
pub fn plan_progress(json: bool) -> (PlanProgress, ProgressBar) {
    if json || !std::io::stderr().is_terminal() {
        return (PlanProgress::default(), ProgressBar::hidden());
    }
    let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
    let counted =
        ProgressStyle::with_template("{spinner} {prefix:8} [{bar:30}] {pos}/{len} contours")
            .expect("valid template")
            .progress_chars("=> ");
    let uncounted = ProgressStyle::with_template("{spinner} {prefix:8}").expect("valid template");
    bar.set_style(uncounted.clone());
    bar.enable_steady_tick(Duration::from_millis(100));
    let shown = bar.clone();
    let progress = PlanProgress::new(move |stage: Stage, done, total| {
        if done == 0 {
            shown.set_style(if total > 0 {
                counted.clone()
            } else {
                uncounted.clone()
            });
            shown.set_length(total as u64);
            shown.set_position(0);
            shown.set_prefix(stage.to_string());
        } else {
            shown.set_position(done as u64);
        }
    });
    (progress, bar)
}

/// Ask the person at the cutter to do something (hardware only, interactive only).
pub fn ask(g: &Global, yes: bool, sim: bool, what: &str) -> Result<(), CliError> {
    if sim || yes || g.json || !std::io::stdin().is_terminal() {
        return Ok(());
    }
    eprint!("{what}, then press Enter (Ctrl-C to stop) ");
    std::io::stderr().flush().ok();
    let mut line = String::new();
    crate::interrupt::at_prompt(|| std::io::stdin().lock().read_line(&mut line))
        .map_err(|e| CliError::Usage(format!("cannot read the answer: {e}")))?;
    Ok(())
}

/// Prepare for a run (reset to zero if needed), then one run with a progress bar; a signal
/// stops either ([`crate::interrupt`]).
pub fn one_run(
    g: &Global,
    meter: &mut Kerfmeter,
    params: &RunParams,
    label: &str,
) -> Result<KerfResult, CliError> {
    meter.prepare_for_run_until(|_| crate::interrupt::check())?;
    let bar = progress_bar(g, label);
    let result = meter.run_kerfmeter_until(params, |p| {
        show(&bar, p);
        crate::interrupt::check()
    });
    bar.finish_and_clear();
    Ok(result?)
}
