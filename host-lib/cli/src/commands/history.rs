//! `kerfmeter history`: the measurements recorded by `run` and `job`, newest first, with the
//! drift warning of each label whose newest kerf left its usual spread. The real measurements,
//! or with `--sim` the simulated ones (they are never mixed). The device is not opened. The
//! listing is the application layer's ([`kerfmeter_app::history::listing`]): a history the user
//! named (`--db`, `KERFMETER_DB`) must exist (exit 4 if not).

use clap::Args;
pub use kerfmeter_app::history::listing::HistoryReport;
use kerfmeter_app::history::listing::{ListRequest, MAX_LIMIT, list};
use kerfmeter_app::history::parse_label;

use crate::connection::Global;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

#[derive(Args)]
pub struct HistoryArgs {
    /// Only this label's measurements.
    #[arg(long, value_parser = parse_label)]
    label: Option<String>,
    /// The newest this many.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_LIMIT)))]
    limit: u32,
}

/// List the history as `args` say: one the user named must exist.
pub fn run(g: &Global, args: &HistoryArgs) -> Result<HistoryReport, CliError> {
    let asked = ListRequest {
        label: args.label.clone(),
        limit: args.limit,
    };
    Ok(list(g.db.as_deref(), &asked, g.sim, g.db.is_some())?)
}

impl Report for HistoryReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}
