//! The location map: kerf varies across a laser bed (focus, mirror alignment, bed flatness), so
//! a grid of measurements (default 4 × 3 cells, 3 runs each) gives each cell a compensation
//! relative to a reference cell, and [`KerfMap::kerf_at_um`] interpolates the kerf anywhere on
//! the bed (bilinear between cell centres, clamped at the edges). The paper's 4 × 3 map halved the
//! spread of assembly forces across the bed.
//!
//! Saved as JSON (see [`KerfMap::save`]): the grid, the bed size, each cell's runs, its median
//! and its compensation (median − reference median), so a map can be inspected and edited.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::files::write_atomically;
use crate::stats::median;

/// The largest bed a map may span each way, mm (ten metres: no laser bed is larger).
pub const MAX_BED_MM: f64 = 10_000.0;

/// Format version written into every map file.
pub const MAP_FORMAT_VERSION: u32 = 1;

/// One grid cell's measurements.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// Column, 0 = smallest x.
    pub col: usize,
    /// Row, 0 = smallest y.
    pub row: usize,
    /// Centre of the cell on the bed, mm.
    pub x_mm: f64,
    /// Centre of the cell on the bed, mm.
    pub y_mm: f64,
    /// Every kerf measured in the cell, µm.
    pub kerf_um: Vec<f64>,
    /// Median of `kerf_um`.
    pub median_um: f64,
    /// `median_um` minus the reference cell's median.
    pub compensation_um: f64,
}

/// A kerf map of a bed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KerfMap {
    /// File format version ([`MAP_FORMAT_VERSION`]).
    pub version: u32,
    /// Bed width (x), mm.
    pub bed_width_mm: f64,
    /// Bed depth (y), mm.
    pub bed_depth_mm: f64,
    /// Columns along x.
    pub cols: usize,
    /// Rows along y.
    pub rows: usize,
    /// The reference cell (column, row).
    pub reference: (usize, usize),
    /// The reference cell's median kerf, µm.
    pub reference_kerf_um: f64,
    /// Cells, row-major (`row * cols + col`).
    pub cells: Vec<Cell>,
}

/// The grid to measure: where each cell's centre is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Bed width (x), mm.
    pub bed_width_mm: f64,
    /// Bed depth (y), mm.
    pub bed_depth_mm: f64,
    /// Columns along x.
    pub cols: usize,
    /// Rows along y.
    pub rows: usize,
}

impl Grid {
    /// Check the grid and return it.
    pub fn new(bed_width_mm: f64, bed_depth_mm: f64, cols: usize, rows: usize) -> Result<Self> {
        let size_ok = |mm: f64| mm > 0.0 && mm <= MAX_BED_MM;
        if !(size_ok(bed_width_mm) && size_ok(bed_depth_mm)) {
            return Err(Error::invalid(format!(
                "the bed must be more than 0 and at most {MAX_BED_MM} mm each way, got {} × {} mm",
                kerfmeter_protocol::Shown(bed_width_mm),
                kerfmeter_protocol::Shown(bed_depth_mm)
            )));
        }
        if !(1..=20).contains(&cols) || !(1..=20).contains(&rows) {
            return Err(Error::invalid(format!(
                "a map grid has 1 to 20 columns and rows, got {cols} × {rows}"
            )));
        }
        Ok(Self {
            bed_width_mm,
            bed_depth_mm,
            cols,
            rows,
        })
    }

    /// Centre of cell (`col`, `row`), mm.
    pub fn centre_mm(&self, col: usize, row: usize) -> (f64, f64) {
        (
            (col as f64 + 0.5) * self.bed_width_mm / self.cols as f64,
            (row as f64 + 0.5) * self.bed_depth_mm / self.rows as f64,
        )
    }
}

impl KerfMap {
    /// Build a map from each cell's runs (`runs[row * cols + col]`), relative to `reference`.
    pub fn from_runs(grid: Grid, reference: (usize, usize), runs: Vec<Vec<f64>>) -> Result<Self> {
        if runs.len() != grid.cols * grid.rows || runs.iter().any(Vec::is_empty) {
            return Err(Error::invalid(
                "every cell of the map needs at least one measurement",
            ));
        }
        if reference.0 >= grid.cols || reference.1 >= grid.rows {
            return Err(Error::invalid(format!(
                "reference cell {reference:?} is outside the {} × {} grid",
                grid.cols, grid.rows
            )));
        }
        let reference_kerf_um = median(&runs[reference.1 * grid.cols + reference.0]);
        let cells = runs
            .into_iter()
            .enumerate()
            .map(|(i, kerf_um)| {
                let (col, row) = (i % grid.cols, i / grid.cols);
                let (x_mm, y_mm) = grid.centre_mm(col, row);
                let median_um = median(&kerf_um);
                Cell {
                    col,
                    row,
                    x_mm,
                    y_mm,
                    kerf_um,
                    median_um,
                    compensation_um: median_um - reference_kerf_um,
                }
            })
            .collect();
        Ok(Self {
            version: MAP_FORMAT_VERSION,
            bed_width_mm: grid.bed_width_mm,
            bed_depth_mm: grid.bed_depth_mm,
            cols: grid.cols,
            rows: grid.rows,
            reference,
            reference_kerf_um,
            cells,
        })
    }

    fn cell(&self, col: usize, row: usize) -> &Cell {
        &self.cells[row * self.cols + col]
    }

    /// The compensation at (`x_mm`, `y_mm`): bilinear between cell centres, constant beyond the
    /// outermost centres.
    pub fn compensation_at_um(&self, x_mm: f64, y_mm: f64) -> f64 {
        // Position in "cell-centre index" coordinates, clamped to the grid of centres.
        let fx =
            (x_mm / self.bed_width_mm * self.cols as f64 - 0.5).clamp(0.0, (self.cols - 1) as f64);
        let fy =
            (y_mm / self.bed_depth_mm * self.rows as f64 - 0.5).clamp(0.0, (self.rows - 1) as f64);
        let (c0, r0) = (fx.floor() as usize, fy.floor() as usize);
        let (c1, r1) = ((c0 + 1).min(self.cols - 1), (r0 + 1).min(self.rows - 1));
        let (tx, ty) = (fx - c0 as f64, fy - r0 as f64);
        let at = |c, r| self.cell(c, r).compensation_um;
        let top = at(c0, r0) * (1.0 - tx) + at(c1, r0) * tx;
        let bottom = at(c0, r1) * (1.0 - tx) + at(c1, r1) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// The kerf to use at (`x_mm`, `y_mm`) when the reference cell measures `reference_kerf_um`
    /// (pass [`KerfMap::reference_kerf_um`] to use the map's own measurement).
    pub fn kerf_at_um(&self, reference_kerf_um: f64, x_mm: f64, y_mm: f64) -> f64 {
        reference_kerf_um + self.compensation_at_um(x_mm, y_mm)
    }

    /// Check that a loaded map is consistent.
    fn validate(&self) -> std::result::Result<(), String> {
        if self.version != MAP_FORMAT_VERSION {
            return Err(format!(
                "map format version {} (this program reads {MAP_FORMAT_VERSION})",
                self.version
            ));
        }
        if self.cols == 0 || self.rows == 0 || self.cells.len() != self.cols * self.rows {
            return Err(format!(
                "{} cells for a {} × {} grid",
                self.cells.len(),
                self.cols,
                self.rows
            ));
        }
        if !(self.bed_width_mm > 0.0 && self.bed_depth_mm > 0.0) {
            return Err("the bed size must be positive".into());
        }
        for (i, c) in self.cells.iter().enumerate() {
            if c.col != i % self.cols || c.row != i / self.cols || !c.compensation_um.is_finite() {
                return Err(format!(
                    "cell {i} is out of place or has no finite compensation"
                ));
            }
        }
        Ok(())
    }

    /// Read a map saved by [`KerfMap::save`].
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::File {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        let map: KerfMap = serde_json::from_str(&text).map_err(|e| Error::File {
            path: path.to_owned(),
            message: format!("not a kerf map: {e}"),
        })?;
        map.validate().map_err(|message| Error::File {
            path: path.to_owned(),
            message: format!("not a usable kerf map: {message}"),
        })?;
        Ok(map)
    }

    /// Write the map as JSON, atomically (a crash never leaves a half-written file).
    pub fn save(&self, path: &Path) -> Result<()> {
        write_atomically(path, self.to_json().as_bytes())
    }

    /// The map as the JSON [`KerfMap::save`] writes.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("maps serialize")
    }

    /// [`KerfMap::save`], and should that fail (the survey done, its folder gone, the disk
    /// full), keep the map under a new name in the first of `fallback_dirs` that takes it:
    /// a survey is every gauge of a bed placed by hand, and is not lost to a file.
    pub fn save_or_keep(
        &self,
        path: &Path,
        fallback_dirs: &[PathBuf],
    ) -> std::result::Result<(), NotSaved> {
        let error = match self.save(path) {
            Ok(()) => return Ok(()),
            Err(e) => e,
        };
        let json = self.to_json();
        let kept = fallback_dirs.iter().find_map(|dir| keep_in(dir, &json));
        Err(NotSaved { error, kept, json })
    }
}

/// A map that could not be saved where asked ([`KerfMap::save_or_keep`]).
#[derive(Debug)]
pub struct NotSaved {
    /// Why it could not be saved there.
    pub error: Error,
    /// Where it was kept instead, if anywhere would take it.
    pub kept: Option<PathBuf>,
    /// The map's JSON, for the caller to print when it was kept nowhere.
    pub json: String,
}

/// Where a map that could not be saved is kept: this tool's folder in the user's data
/// directory, then the temporary folder.
pub fn fallback_dirs() -> Vec<PathBuf> {
    dirs::data_dir()
        .map(|d| d.join("kerfmeter"))
        .into_iter()
        .chain([std::env::temp_dir()])
        .collect()
}

/// Write `json` into `dir` under a new name (`kerf-map-unsaved-XXXXXX.json`, never replacing a
/// file); where it went.
fn keep_in(dir: &Path, json: &str) -> Option<PathBuf> {
    use std::io::Write;
    std::fs::create_dir_all(dir).ok()?;
    let mut file = tempfile::Builder::new()
        .prefix("kerf-map-unsaved-")
        .suffix(".json")
        .tempfile_in(dir)
        .ok()?;
    file.write_all(json.as_bytes()).ok()?;
    file.as_file().sync_all().ok()?;
    let (_, path) = file.keep().ok()?;
    Some(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_that_cannot_be_saved_is_kept_elsewhere_whole() {
        let dir = tempfile::tempdir().unwrap();
        let gone = dir.path().join("no-such-folder").join("kerf-map.json");
        let fallback = dir.path().join("kept");
        // A fallback that cannot be a folder (a file is in its way) is passed over.
        std::fs::write(dir.path().join("file"), "").unwrap();
        let not_saved = map()
            .save_or_keep(
                &gone,
                &[dir.path().join("file").join("x"), fallback.clone()],
            )
            .unwrap_err();
        assert!(
            not_saved.error.to_string().contains("does not exist"),
            "{:?}",
            not_saved.error
        );
        let kept = not_saved.kept.unwrap();
        assert!(kept.starts_with(&fallback), "{}", kept.display());
        assert_eq!(KerfMap::load(&kept).unwrap(), map());
        assert!(!gone.exists());
        map()
            .save_or_keep(&dir.path().join("ok.json"), &[])
            .unwrap();
    }

    fn map() -> KerfMap {
        let grid = Grid::new(400.0, 300.0, 4, 3).unwrap();
        // Kerf grows by 10 µm per column and 5 µm per row; three runs per cell.
        let runs = (0..12)
            .map(|i| {
                let k = 150.0 + 10.0 * (i % 4) as f64 + 5.0 * (i / 4) as f64;
                vec![k - 1.0, k, k + 3.0]
            })
            .collect();
        KerfMap::from_runs(grid, (0, 0), runs).unwrap()
    }

    #[test]
    fn compensation_is_relative_to_the_reference_median() {
        let m = map();
        assert_eq!(m.reference_kerf_um, 150.0);
        assert_eq!(m.cell(3, 2).compensation_um, 40.0);
    }

    #[test]
    fn interpolation_is_exact_at_centres_linear_between_and_flat_beyond() {
        let m = map();
        assert!((m.compensation_at_um(50.0, 50.0) - 0.0).abs() < 1e-9);
        assert!((m.compensation_at_um(350.0, 250.0) - 40.0).abs() < 1e-9);
        // Halfway between columns 0 and 1 on row 0.
        assert!((m.compensation_at_um(100.0, 50.0) - 5.0).abs() < 1e-9);
        // A plane is reproduced exactly by bilinear interpolation.
        assert!((m.compensation_at_um(200.0, 150.0) - (10.0 * 1.5 + 5.0 * 1.0)).abs() < 1e-9);
        // Beyond the outer centres: clamped.
        assert_eq!(m.compensation_at_um(-100.0, -100.0), 0.0);
        assert!((m.compensation_at_um(1000.0, 1000.0) - 40.0).abs() < 1e-9);
        assert!((m.kerf_at_um(160.0, 50.0, 50.0) - 160.0).abs() < 1e-9);
    }

    #[test]
    fn a_saved_map_loads_back_and_garbage_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("map.json");
        map().save(&path).unwrap();
        assert_eq!(KerfMap::load(&path).unwrap(), map());
        std::fs::write(&path, "{\"version\": 1}").unwrap();
        let e = KerfMap::load(&path).unwrap_err().to_string();
        assert!(e.contains("not a kerf map"), "{e}");
    }

    #[test]
    fn bad_grids_are_refused() {
        assert!(Grid::new(0.0, 100.0, 4, 3).is_err());
        assert!(Grid::new(100.0, 100.0, 0, 3).is_err());
        let g = Grid::new(100.0, 100.0, 2, 2).unwrap();
        assert!(KerfMap::from_runs(g, (2, 0), vec![vec![1.0]; 4]).is_err());
        assert!(KerfMap::from_runs(g, (0, 0), vec![vec![]; 4]).is_err());
    }
}
