//! Where a bring-up's report is saved, text and JSON side by side: a name the user gave, or
//! `kerfmeter-bringup-<date>.txt`/`.json` in the current folder (`-2`, `-3`, … when that
//! exists). Written atomically; never over an input, and never over a file that is not a
//! bring-up report kerfmeter wrote. Checked before the bring-up moves anything, so that the
//! report cannot be lost at the end for a typo in its name.

use std::path::{Path, PathBuf};

use kerfmeter::Error;
use kerfmeter::files::{ensure_not_input, ensure_writable, write_atomically};
use serde::Serialize;

use super::report::{BringupReport, TEXT_MARKER};

/// The two files of a report.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ReportFiles {
    /// The text.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub text: PathBuf,
    /// The JSON.
    #[serde(serialize_with = "crate::lossy_path::one")]
    pub json: PathBuf,
}

impl ReportFiles {
    /// The files for `path` (its extension replaced by `.txt` and `.json`), or without one the
    /// first free `kerfmeter-bringup-<today>[-n]` pair in the current folder.
    pub fn choose(path: Option<&Path>, today: &str) -> Self {
        if let Some(path) = path {
            return Self::beside(path);
        }
        let name = format!("kerfmeter-bringup-{today}");
        (1u32..)
            .map(|n| match n {
                1 => Self::beside(Path::new(&name)),
                n => Self::beside(Path::new(&format!("{name}-{n}"))),
            })
            .find(|f| !f.text.exists() && !f.json.exists())
            .expect("some numbered name is free")
    }

    fn beside(path: &Path) -> Self {
        Self {
            text: path.with_extension("txt"),
            json: path.with_extension("json"),
        }
    }

    /// Refuse files that are one of `inputs`, exist and were not written by a bring-up, or
    /// cannot be written.
    pub fn check(&self, inputs: &[&Path]) -> Result<(), Error> {
        for (path, marker) in [
            (&self.text, TEXT_MARKER),
            (&self.json, "\"kerfmeter_bringup\""),
        ] {
            for input in inputs {
                ensure_not_input(input, path)?;
            }
            if path.exists() && !written_by_bringup(path, marker) {
                return Err(Error::File {
                    path: path.clone(),
                    message: "exists and is not a bring-up report kerfmeter wrote: give another \
                              --report (it is left as it is)"
                        .into(),
                });
            }
            ensure_writable(path)?;
        }
        Ok(())
    }

    /// Write `report` to both files (each atomically).
    pub fn save(&self, report: &BringupReport) -> Result<(), Error> {
        let json = serde_json::to_string_pretty(report).map_err(|e| Error::File {
            path: self.json.clone(),
            message: format!("the report cannot be written as JSON: {e}"),
        })?;
        write_atomically(&self.text, format!("{report}\n").as_bytes())?;
        write_atomically(&self.json, format!("{json}\n").as_bytes())
    }
}

/// True when `path`'s first bytes hold `marker`: a report of a bring-up, which may be replaced.
fn written_by_bringup(path: &Path, marker: &str) -> bool {
    std::fs::read(path).is_ok_and(|bytes| {
        let head = &bytes[..bytes.len().min(200)];
        String::from_utf8_lossy(head).contains(marker)
    })
}

/// Today's date (UTC), `YYYY-MM-DD`, for the report's default name.
pub fn today() -> String {
    jiff::Timestamp::now().strftime("%Y-%m-%d").to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_kerfmeter_did_not_write_or_an_input_is_refused_and_a_free_name_is_found() {
        let dir = tempfile::tempdir().unwrap();
        let plan = dir.path().join("plan.txt");
        std::fs::write(&plan, "someone's notes").unwrap();
        let files = ReportFiles::choose(Some(&dir.path().join("plan")), "2026-12-07");
        assert!(files.check(&[]).is_err());
        let input = dir.path().join("plant.json");
        let other = ReportFiles::choose(Some(&dir.path().join("plant.txt")), "x");
        assert!(other.check(&[&input]).is_err());
        let ours = ReportFiles::choose(Some(&dir.path().join("ours")), "x");
        std::fs::write(&ours.text, format!("{TEXT_MARKER} 1, …")).unwrap();
        std::fs::write(&ours.json, "{\n  \"kerfmeter_bringup\": 1}").unwrap();
        ours.check(&[]).unwrap();
    }
}
