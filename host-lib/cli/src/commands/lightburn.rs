//! LightBurn. Offline, `kerfmeter dilate project.lbrn2 --kerf-um K -o out.lbrn2` sets the Kerf
//! Offset of the project's Line layers (`kerfmeter_lightburn::project` does the work and
//! documents LightBurn's convention: half the kerf, positive outward); this module checks the
//! arguments that apply to a project, writes the output atomically (never over the input) and
//! reports. Online, `kerfmeter lightburn pair` and `kerfmeter lightburn apply` do the same to the
//! project open in a running LightBurn through its REST API (`kerfmeter_lightburn::rest`); with
//! `--sim`, to a LightBurn twin started for the call (`kerfmeter_lightburn::twin`).

use std::fmt;
use std::path::{Path, PathBuf};

use kerfmeter::files::{ensure_not_input, write_atomically};
use kerfmeter_lightburn::project::{
    LightBurnOptions, LightBurnSummary, format_mm, is_project_path, set_kerf_offset_file,
};
use kerfmeter_lightburn::rest::{
    Applied, Client, DEFAULT_HOST, ExistingOffset, Pairing, apply_kerf,
};
use kerfmeter_lightburn::twin::{LightBurnTwin, LightBurnTwinOptions};
use kerfmeter_plan::PlanError;
use kerfmeter_plan::dilate::KerfSource;
use serde::Serialize;

use super::dilate::DilateArgs;
use crate::error::CliError;
use crate::output::{JsonLayout, Report};

type Result<T, E = CliError> = std::result::Result<T, E>;

/// What `dilate` did to a LightBurn project (or, with `--dry-run`, would do).
#[derive(Debug, Clone, Serialize)]
pub struct LightBurnReport {
    /// The project read.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub input: PathBuf,
    /// The project written (`None` on a dry run).
    #[serde(serialize_with = "crate::output::lossy_path::option")]
    pub output: Option<PathBuf>,
    /// True when nothing was written.
    pub dry_run: bool,
    /// Always `lightburn`.
    pub format: &'static str,
    /// What was found and done.
    #[serde(flatten)]
    pub summary: LightBurnSummary,
}

/// The options of `dilate` that mean nothing for a LightBurn project, if any were given.
fn refuse_plan_only_options(args: &DilateArgs) -> Result<()> {
    let d = &args.dilation;
    let given: Vec<&str> = [
        (d.map.is_some(), "--map"),
        (!d.cut_colors.is_empty(), "--cut-color"),
        (!d.cut_layers.is_empty(), "--cut-layer (use --layers)"),
        (d.units.is_some(), "--units"),
        (args.strict, "--strict"),
    ]
    .into_iter()
    .filter_map(|(on, name)| on.then_some(name))
    .collect();
    if given.is_empty() {
        return Ok(());
    }
    Err(CliError::Usage(format!(
        "{} do{} not apply to a LightBurn project: LightBurn applies one Kerf Offset per layer to its shapes",
        given.join(", "),
        if given.len() == 1 { "es" } else { "" }
    )))
}

/// Refuse an output whose extension is not the input's: the output holds the input's bytes, so
/// an `.lbrn` (LightBurn 1.x) saved as `.lbrn2` (or the reverse) would not be what it says.
fn same_extension(input: &Path, output: &Path) -> Result<()> {
    let ext = |p: &Path| {
        p.extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default()
    };
    if ext(input) == ext(output) {
        return Ok(());
    }
    Err(PlanError::InvalidArgument(format!(
        "the output {} must have the input's extension .{} (the project keeps its format: .lbrn stays .lbrn, .lbrn2 stays .lbrn2)",
        output.display(),
        ext(input)
    ))
    .into())
}

/// Set the Kerf Offset of the LightBurn project `args.input` (see the module doc).
pub fn run_offline(args: &DilateArgs) -> Result<LightBurnReport> {
    refuse_plan_only_options(args)?;
    if let Some(out) = &args.output {
        if !is_project_path(out) {
            return Err(PlanError::InvalidArgument(format!(
                "the output {} must be a LightBurn project too (.lbrn2 or .lbrn)",
                out.display()
            ))
            .into());
        }
        same_extension(&args.input, out)?;
        ensure_not_input(&args.input, out)?;
        if !args.dry_run {
            kerfmeter_plan::ownership::ensure_replaceable(out, args.force)?;
        }
    }
    let options = LightBurnOptions {
        layers: args.layers.clone(),
        if_compensated: args.dilation.if_compensated(),
    };
    let (bytes, summary) = set_kerf_offset_file(&args.input, args.dilation.kerf_um, &options)?;
    let output = if args.dry_run {
        None
    } else {
        args.output.clone()
    };
    if let Some(out) = &output {
        write_atomically(out, &bytes)?;
    }
    Ok(LightBurnReport {
        input: args.input.clone(),
        output,
        dry_run: args.dry_run,
        format: "lightburn",
        summary,
    })
}

impl fmt::Display for LightBurnReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.summary;
        match &self.output {
            Some(out) => write!(f, "set {} → {}", self.input.display(), out.display())?,
            None => write!(f, "dry run, nothing written: {}", self.input.display())?,
        }
        writeln!(
            f,
            " (LightBurn project) for a kerf of {} µm: Kerf Offset {} mm (half the kerf, positive = outward, LightBurn's convention)",
            s.kerf_um,
            format_mm(s.kerf_offset_mm)
        )?;
        for l in &s.layers {
            write!(f, "  layer {} \"{}\" ({}): ", l.index, l.name, l.mode)?;
            match &l.left_alone {
                Some(why) => writeln!(f, "left alone, {why}")?,
                None => writeln!(f, "{}", passes(l))?,
            }
        }
        if let Some(found) = &s.compensation_found {
            writeln!(f, "  found: {}", found.describe())?;
            let what = match s.compensation_applied.action.as_str() {
                "recompensate" => "replaced by this kerf's (--recompensate)",
                _ => "kept, this kerf's added on top (--already-compensated-ok)",
            };
            writeln!(f, "  compensation: {what}")?;
        }
        Ok(())
    }
}

/// The passes of a layer that were set, in words.
fn passes(l: &kerfmeter_lightburn::project::LayerOutcome) -> String {
    let each: Vec<String> = l
        .set
        .iter()
        .map(|p| {
            let whose = match p.sub_layer {
                None => "line pass".to_string(),
                Some(i) => format!("line sub-layer {i}"),
            };
            match p.before_mm {
                Some(b) => format!("{whose} {} → {} mm", format_mm(b), format_mm(p.after_mm)),
                None => format!("{whose} (none) → {} mm", format_mm(p.after_mm)),
            }
        })
        .collect();
    format!(
        "{} pass{} set: {}",
        l.set.len(),
        if l.set.len() == 1 { "" } else { "es" },
        each.join(", ")
    )
}

/// `kerfmeter lightburn`: talk to a running LightBurn over its local REST API (one that has the
/// `project_write` capability; see the library's `lightburn` module for what that rests on).
#[derive(Debug, Clone, clap::Subcommand)]
pub enum LightBurnCommand {
    /// Pair with LightBurn: it shows a consent dialog naming this program; approve it within
    /// 30 s. The secret it gives is kept in your config directory (or --pairing-file).
    Pair(PairArgs),
    /// Write the kerf into the Kerf Offset of LightBurn's Line layers (half the kerf, positive =
    /// outward, in LightBurn's display units). Close LightBurn's cut settings editor first.
    Apply(ApplyArgs),
}

/// Where LightBurn listens and where the pairing is kept.
#[derive(Debug, Clone, clap::Args)]
pub struct Endpoint {
    /// LightBurn's API address, host:port [default: the paired one, else 127.0.0.1:19520].
    #[arg(long, value_name = "HOST:PORT")]
    pub host: Option<String>,
    /// The pairing file [default: <config dir>/kerfmeter/lightburn.json, or
    /// $KERFMETER_LIGHTBURN_PAIRING].
    #[arg(long, value_name = "FILE")]
    pub pairing_file: Option<PathBuf>,
}

impl Endpoint {
    fn pairing_path(&self) -> Result<PathBuf> {
        self.pairing_file
            .clone()
            .or_else(Pairing::default_path)
            .ok_or_else(|| {
                CliError::Usage(
                    "no config directory to keep the LightBurn pairing in: give --pairing-file"
                        .into(),
                )
            })
    }
}

/// `kerfmeter lightburn pair`.
#[derive(Debug, Clone, clap::Args)]
pub struct PairArgs {
    /// Where.
    #[command(flatten)]
    pub endpoint: Endpoint,
}

/// `kerfmeter lightburn apply`.
#[derive(Debug, Clone, clap::Args)]
pub struct ApplyArgs {
    /// Kerf (full cut width), µm; LightBurn's Kerf Offset is half of it.
    #[arg(long)]
    pub kerf_um: f64,
    /// Set only these layers, each by index (0, 1, …) or name (repeat or separate by commas; a
    /// value that is a whole layer's name is not split) [default: every Line layer in use].
    #[arg(long = "layers", value_name = "LAYER")]
    pub layers: Vec<String>,
    /// A layer that already has a Kerf Offset is refused; add this kerf's to it anyway.
    #[arg(long, conflicts_with = "recompensate")]
    pub already_compensated_ok: bool,
    /// Replace the Kerf Offsets already set by this kerf's.
    #[arg(long)]
    pub recompensate: bool,
    /// Where.
    #[command(flatten)]
    pub endpoint: Endpoint,
}

/// What `lightburn pair` did.
#[derive(Debug, Clone, Serialize)]
pub struct PairReport {
    /// LightBurn's address.
    pub host: String,
    /// Where the secret is kept (`None` with the LightBurn twin: nothing is kept).
    #[serde(serialize_with = "crate::output::lossy_path::option")]
    pub pairing_file: Option<PathBuf>,
    /// True when paired with the LightBurn twin (`--sim`).
    pub simulated: bool,
    /// What it grants.
    pub capabilities: Vec<String>,
    /// A pairing was kept in the file before this one: its secret is still authorised in
    /// LightBurn (pairing again revokes nothing) until the user revokes it there.
    pub earlier_pairing_still_authorised: bool,
}

/// Where an earlier pairing's secret is revoked (`authentication.md` § Clients that run on
/// another machine: LightBurn's "Manage authorizations" dialog lists each pairing).
const REVOKE_EARLIER: &str = "the secret of the pairing it replaces is still authorised in LightBurn: revoke the older \"Kerfmeter\" entry in LightBurn's Manage authorizations dialog";

impl fmt::Display for PairReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kept = match &self.pairing_file {
            Some(path) => format!("the secret is kept in {}", path.display()),
            None => "the simulated LightBurn's secret is not kept".into(),
        };
        let what = if self.simulated {
            "the LightBurn twin (--sim)"
        } else {
            "LightBurn"
        };
        write!(
            f,
            "paired with {what} at {} ({}); {kept}",
            self.host,
            self.capabilities.join(", ")
        )?;
        if self.earlier_pairing_still_authorised {
            write!(f, "\n  {REVOKE_EARLIER}")?;
        }
        Ok(())
    }
}

impl Report for PairReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

/// What `lightburn apply` did.
#[derive(Debug, Clone, Serialize)]
pub struct ApplyReport {
    /// LightBurn's address.
    pub host: String,
    /// True when applied to the LightBurn twin (`--sim`).
    pub simulated: bool,
    /// What was set.
    #[serde(flatten)]
    pub applied: Applied,
}

impl fmt::Display for ApplyReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = &self.applied;
        writeln!(
            f,
            "{} at {}: Kerf Offset {} {} for a kerf of {} µm (half the kerf, positive = outward)",
            if self.simulated {
                "The LightBurn twin (--sim)"
            } else {
                "LightBurn"
            },
            self.host,
            round6(a.kerf_offset),
            a.unit,
            a.kerf_um
        )?;
        for l in &a.layers {
            let show = |v: &[f64]| v.iter().map(|x| round6(*x).to_string()).collect::<Vec<_>>();
            writeln!(
                f,
                "  layer {} \"{}\": {} → {} {}",
                l.layer_index,
                l.name,
                show(&l.before).join(", "),
                show(&l.after).join(", "),
                a.unit
            )?;
        }
        if a.project_modified {
            writeln!(
                f,
                "  LightBurn's project is now modified and not saved (one undo step a layer): save it, and send the job again: a job sent to the laser before this change does not have the new Kerf Offset"
            )?;
        }
        write!(f, "  review the settings in LightBurn before you cut")
    }
}

impl Report for ApplyReport {
    const JSON: JsonLayout = JsonLayout::Pretty;
}

fn round6(v: f64) -> f64 {
    (v * 1e6).round() / 1e6
}

/// For `--sim`: a fresh LightBurn twin (as `--sim` gives a fresh device) and a pairing with
/// it, kept in memory only. The twin serves until it is dropped.
fn sim_pairing(endpoint: &Endpoint) -> Result<(LightBurnTwin, Pairing)> {
    if endpoint.host.is_some() || endpoint.pairing_file.is_some() {
        return Err(CliError::Usage(
            "--sim talks to a LightBurn twin of its own: --host and --pairing-file do not apply"
                .into(),
        ));
    }
    let twin = LightBurnTwin::start(LightBurnTwinOptions::default())?;
    let pairing = Client::pair(twin.host())?;
    Ok((twin, pairing))
}

/// Pair with LightBurn and keep the secret; with `sim`, pair with a LightBurn twin and keep
/// nothing (the user's pairing stays as it was).
pub fn pair(args: &PairArgs, sim: bool) -> Result<PairReport> {
    if sim {
        let (_twin, pairing) = sim_pairing(&args.endpoint)?;
        return Ok(PairReport {
            host: pairing.host,
            pairing_file: None,
            simulated: true,
            capabilities: pairing.capabilities,
            earlier_pairing_still_authorised: false,
        });
    }
    let path = args.endpoint.pairing_path()?;
    let host = args.endpoint.host.clone().unwrap_or(DEFAULT_HOST.into());
    // A file there, readable or not, held a secret LightBurn gave: nothing revokes it.
    let earlier = path.exists();
    let pairing = Client::pair(&host)?;
    pairing.save(&path)?;
    Ok(PairReport {
        host,
        pairing_file: Some(path),
        simulated: false,
        capabilities: pairing.capabilities,
        earlier_pairing_still_authorised: earlier,
    })
}

/// Write the kerf into LightBurn's Line layers; with `sim`, into a LightBurn twin's, paired
/// for this call only.
pub fn apply(args: &ApplyArgs, sim: bool) -> Result<ApplyReport> {
    let kerf_um = KerfSource::check_kerf_um(args.kerf_um)?;
    let (_twin, pairing) = if sim {
        let (twin, pairing) = sim_pairing(&args.endpoint)?;
        (Some(twin), pairing)
    } else {
        (None, Pairing::load(&args.endpoint.pairing_path()?)?)
    };
    let host = args.endpoint.host.clone().unwrap_or(pairing.host.clone());
    let existing = if args.recompensate {
        ExistingOffset::Replace
    } else if args.already_compensated_ok {
        ExistingOffset::Add
    } else {
        ExistingOffset::Refuse
    };
    let applied = apply_kerf(
        &Client::new(&host),
        &pairing,
        kerf_um,
        &args.layers,
        existing,
    )?;
    Ok(ApplyReport {
        host,
        simulated: sim,
        applied,
    })
}
