//! `kerfmeter map`: measure a grid of gauges across the bed and save a location-compensation map
//! (JSON). With `--sim`, every cell gets its own twin on a simulated bed whose kerf grows from one
//! corner to the opposite one.

use std::fmt;
use std::path::PathBuf;

use clap::Args;
use kerfmeter::JointSpec;
use kerfmeter::map::{Cell, Grid, KerfMap};
use kerfmeter::protocol::{GaugeGeometry, RunParams};
use serde::Serialize;

use crate::connection::{Global, Session};
use crate::error::CliError;
use crate::output::{JsonLayout, Report};
use crate::progress::{ask, one_run};

#[derive(Args)]
pub struct MapArgs {
    /// Where to save the map (JSON).
    #[arg(long, short = 'o', default_value = "kerf-map.json")]
    output: PathBuf,
    /// Bed width (x), mm.
    #[arg(long, default_value_t = 600.0)]
    bed_width_mm: f64,
    /// Bed depth (y), mm.
    #[arg(long, default_value_t = 400.0)]
    bed_depth_mm: f64,
    /// Grid columns along x.
    #[arg(long, default_value_t = 4)]
    cols: usize,
    /// Grid rows along y.
    #[arg(long, default_value_t = 3)]
    rows: usize,
    /// Measurements per cell.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=20))]
    per_cell: u32,
    /// Reference cell column.
    #[arg(long, default_value_t = 0)]
    reference_col: usize,
    /// Reference cell row.
    #[arg(long, default_value_t = 0)]
    reference_row: usize,
    /// Sheet thickness, mm.
    #[arg(long, default_value_t = kerfmeter::params::DEFAULT_THICKNESS_MM)]
    thickness_mm: f64,
    /// Simulated device only: how much the simulated bed's kerf grows from one corner to the
    /// opposite one, µm.
    #[arg(long, default_value_t = 20.0, value_name = "UM")]
    sim_bed_variation_um: f64,
    /// Do not ask before each cell (hardware only).
    #[arg(long, short = 'y')]
    yes: bool,
}

/// The saved map: each cell's compensation relative to the reference cell.
#[derive(Serialize)]
pub struct MapReport {
    /// The cells, row by row.
    pub cells: Vec<Cell>,
    /// The file the map was saved to.
    #[serde(serialize_with = "crate::output::lossy_path::one")]
    pub map: PathBuf,
    /// The kerf at the reference cell, µm.
    pub reference_kerf_um: f64,
    /// The reference cell (column, row).
    #[serde(skip)]
    pub reference: (usize, usize),
    /// Columns along x.
    #[serde(skip)]
    pub cols: usize,
}

/// Measure every cell, build the map and save it.
pub fn run(g: &Global, args: &MapArgs) -> Result<MapReport, CliError> {
    let grid = Grid::new(args.bed_width_mm, args.bed_depth_mm, args.cols, args.rows)?;
    if args.reference_col >= args.cols || args.reference_row >= args.rows {
        return Err(CliError::Usage(format!(
            "the reference cell ({}, {}) is outside the {} × {} grid",
            args.reference_col, args.reference_row, args.cols, args.rows
        )));
    }
    let joint = JointSpec {
        thickness_mm: args.thickness_mm,
        ..JointSpec::default()
    };
    let params = joint.run_params(GaugeGeometry::PAPER)?;
    // Before the first gauge: a survey of the whole bed is lost if the map cannot be saved.
    kerfmeter::files::ensure_writable(&args.output)?;
    let mut hardware = if g.sim { None } else { Some(g.connect()?) };
    let mut runs = Vec::new();
    for row in 0..args.rows {
        for col in 0..args.cols {
            let mut sim_session;
            let session = match &mut hardware {
                Some(s) => s,
                None => {
                    sim_session = sim_cell(g, args, &grid, (col, row))?;
                    &mut sim_session
                }
            };
            runs.push(measure_cell(g, args, &grid, session, &params, (col, row))?);
        }
    }
    let reference = (args.reference_col, args.reference_row);
    let map = KerfMap::from_runs(grid, reference, runs)?;
    save(&map, &args.output)?;
    Ok(MapReport {
        cells: map.cells,
        map: args.output.clone(),
        reference_kerf_um: map.reference_kerf_um,
        reference,
        cols: args.cols,
    })
}

/// Save the map where asked; failing that, keep it in the user's data folder or the temporary
/// folder and say where, or print it: the survey is not lost to a file that cannot be written.
fn save(map: &KerfMap, output: &std::path::Path) -> Result<(), CliError> {
    let not_saved = match map.save_or_keep(output, &kerfmeter::map::fallback_dirs()) {
        Ok(()) => return Ok(()),
        Err(not_saved) => not_saved,
    };
    let reason = match &not_saved.error {
        kerfmeter::Error::File { message, .. } => message.clone(),
        other => other.to_string(),
    };
    let kept = match &not_saved.kept {
        Some(kept) => format!(
            "the map measured is kept in {}: move it there",
            kept.display()
        ),
        None => {
            crate::output::print_line(&not_saved.json);
            "the map measured is printed above, as nowhere else would take it: save it".into()
        }
    };
    Err(kerfmeter::Error::File {
        path: output.to_owned(),
        message: format!("cannot be written ({reason}); {kept}"),
    }
    .into())
}

/// A twin for one cell of the simulated bed: its kerf grows linearly from one corner to the
/// opposite one, and each cell has its own seed.
fn sim_cell(
    g: &Global,
    args: &MapArgs,
    grid: &Grid,
    (col, row): (usize, usize),
) -> Result<Session, CliError> {
    let (x, y) = grid.centre_mm(col, row);
    let across = (x / args.bed_width_mm + y / args.bed_depth_mm) / 2.0;
    let kerf = g.sim_kerf_um + args.sim_bed_variation_um * (across - 0.5);
    let seed = g
        .sim_seed
        .wrapping_add((row * args.cols + col) as u64 * 7919);
    g.connect_sim(kerf, seed)
}

/// Measure `--per-cell` gauges at one cell, µm.
fn measure_cell(
    g: &Global,
    args: &MapArgs,
    grid: &Grid,
    session: &mut Session,
    params: &RunParams,
    (col, row): (usize, usize),
) -> Result<Vec<f64>, CliError> {
    let (x, y) = grid.centre_mm(col, row);
    let mut cell = Vec::new();
    for i in 0..args.per_cell {
        ask(
            g,
            args.yes,
            g.sim,
            &format!(
                "Cut and place gauge {} of {} at cell ({col}, {row}), x {x:.0} mm y {y:.0} mm",
                i + 1,
                args.per_cell
            ),
        )?;
        if i > 0 {
            session
                .meter
                .reset_kerfmeter_until(|_| crate::interrupt::check())?;
        }
        let label = format!("cell ({col},{row}) {}/{}", i + 1, args.per_cell);
        cell.push(f64::from(
            one_run(g, &mut session.meter, params, &label)?.kerf_um,
        ));
    }
    Ok(cell)
}

impl fmt::Display for MapReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "compensation (µm) relative to cell ({}, {}) = {:.1} µm:",
            self.reference.0, self.reference.1, self.reference_kerf_um
        )?;
        for (row, cells) in self.cells.chunks(self.cols).enumerate() {
            let line: Vec<String> = cells
                .iter()
                .map(|c| format!("{:+7.1}", c.compensation_um))
                .collect();
            writeln!(f, "  row {row}: {}", line.join(" "))?;
        }
        write!(f, "saved {}", self.map.display())
    }
}

impl Report for MapReport {
    const JSON: JsonLayout = JsonLayout::CompactSorted;
}
