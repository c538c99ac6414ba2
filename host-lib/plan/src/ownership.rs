//! Which existing files an output may replace: one this tool wrote (a plan it dilated, a gauge,
//! a G-code program, a curve plot: each carries this tool's marker in its first lines), or any
//! file when the user says `--force`. A typo in an output's name must not replace someone's
//! cutting plan.

use std::io::Read;
use std::path::Path;

use crate::error::{PlanError, Result};

/// The marker of a plot this tool drew (an SVG comment, a PNG `tEXt` chunk).
pub const PLOT_MARKER: &str = "kerfmeter-plot";

/// How much of a file is searched for this tool's marker: every output puts it in its first
/// lines (a plan's record after the root tag or in its first `999` comments, a program's first
/// comment, a plot's comment or its `tEXt` chunk before the pixels).
const MARKER_SEARCH_BYTES: u64 = 1 << 20;

/// The text a plot carries: the marker and the tool's version.
pub fn plot_marker_text() -> String {
    format!(
        "{PLOT_MARKER} torque-angle curve, kerfmeter {}",
        env!("CARGO_PKG_VERSION")
    )
}

/// True when the file at `path` was written by this tool.
pub fn written_by_kerfmeter(path: &Path) -> std::io::Result<bool> {
    let mut head = Vec::new();
    std::fs::File::open(path)?
        .take(MARKER_SEARCH_BYTES)
        .read_to_end(&mut head)?;
    let has = |needle: &str| head.windows(needle.len()).any(|w| w == needle.as_bytes());
    // A program's first comment: `(kerfmeter 0.1.0 G-code for GRBL 1.1 laser mode)`.
    let program = has("(kerfmeter ") && has(crate::gcode::HEADER_MARKER);
    Ok(has(crate::compensation::MARKER) || has(PLOT_MARKER) || program)
}

/// Refuse to replace an existing file at `path` that this tool did not write, unless `force`.
/// No file (or a folder, which the write refuses with its own message): nothing to check.
pub fn ensure_replaceable(path: &Path, force: bool) -> Result<()> {
    if force || !path.is_file() {
        return Ok(());
    }
    let why = match written_by_kerfmeter(path) {
        Ok(true) => return Ok(()),
        Ok(false) => "it exists and was not written by kerfmeter, so it is not replaced (a typo \
                      could lose a cutting plan); give another name, or add --force to replace it"
            .to_owned(),
        Err(e) => format!(
            "it exists and cannot be read to see whether kerfmeter wrote it ({e}); give another \
             name, or add --force to replace it"
        ),
    };
    Err(PlanError::Write {
        path: path.to_owned(),
        source: std::io::Error::new(std::io::ErrorKind::AlreadyExists, why),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_this_tools_files_are_replaced_without_force() {
        let dir = tempfile::tempdir().unwrap();
        let theirs = dir.path().join("plan.svg");
        std::fs::write(&theirs, "<svg xmlns=\"http://www.w3.org/2000/svg\"/>").unwrap();
        let err = ensure_replaceable(&theirs, false).unwrap_err().to_string();
        assert!(err.contains("not written by kerfmeter"), "{err}");
        assert!(err.contains("--force"), "{err}");
        ensure_replaceable(&theirs, true).unwrap();
        let ours = [
            format!("<svg>\n<!-- {} -->", plot_marker_text()),
            format!(
                "<svg><!-- {} tool=kerfmeter --></svg>",
                crate::compensation::MARKER
            ),
            format!("(kerfmeter 9.9.9 {})\nG21\n", crate::gcode::HEADER_MARKER),
        ];
        for (i, text) in ours.iter().enumerate() {
            let path = dir.path().join(format!("ours-{i}"));
            std::fs::write(&path, text).unwrap();
            ensure_replaceable(&path, false).unwrap();
        }
        ensure_replaceable(&dir.path().join("absent.svg"), false).unwrap();
        ensure_replaceable(dir.path(), false).unwrap();
    }
}
