//! An SVG plan dilated from its file is not held in memory while its cuts are dilated: the file
//! is read again as the dilated plan is written. The output is the same as from the text in
//! memory, a file that changed in between is refused, a file saved over by rename is read as
//! first opened, and a pipe is read once.

use std::io::Write;
use std::path::Path;

use kerfmeter_plan::dilate::KerfSource;
use kerfmeter_plan::progress::{Progress, Stage};
use kerfmeter_plan::svg::{SvgOptions, dilate_svg};
use kerfmeter_plan::{DilateOptions, dilate_file_into};

const HEAD: &str = r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="100mm" height="100mm" viewBox="0 0 100 100">"#;

/// Two cuts (one through a `<use>` clone when `with_use`), a comment and non-ASCII text.
fn plan(with_use: bool) -> String {
    let clone = if with_use {
        r##"<defs><rect id="t" width="5" height="5" fill="none" stroke="red" stroke-width="0.05"/></defs><use id="u" href="#t" x="60" y="60"/>"##
    } else {
        ""
    };
    format!(
        r#"{HEAD}
<!-- Schnittplan für Kästen -->
<rect id="r" x="10" y="10" width="20" height="10" fill="none" stroke="red" stroke-width="0.01"/>
<circle cx="50" cy="20" r="4" fill="none" stroke="red" stroke-width="0.01"/>{clone}
<text x="1" y="90">Größe</text>
</svg>"#
    )
}

fn kerf() -> KerfSource {
    KerfSource::Uniform(150.0)
}

/// Dilate the file at `input` into bytes, with `progress`.
fn from_file(input: &Path, progress: Progress) -> kerfmeter_plan::Result<Vec<u8>> {
    let options = DilateOptions {
        progress,
        ..DilateOptions::default()
    };
    let mut out = Vec::new();
    dilate_file_into(input, &kerf(), &options, Path::new("out.svg"), &mut out)?;
    Ok(out)
}

#[test]
fn a_plan_read_again_from_its_file_is_written_as_from_memory() {
    let dir = tempfile::tempdir().unwrap();
    for with_use in [false, true] {
        let text = plan(with_use);
        let input = dir.path().join("plan.svg");
        std::fs::write(&input, &text).unwrap();
        let (expected, _) = dilate_svg(&text, &kerf(), &SvgOptions::default()).unwrap();
        let got = from_file(&input, Progress::default()).unwrap();
        assert_eq!(
            String::from_utf8(got).unwrap(),
            expected,
            "with <use>: {with_use}"
        );
    }
}

#[test]
fn a_plan_file_changed_while_it_is_dilated_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for with_use in [false, true] {
        for same_length in [true, false] {
            let text = plan(with_use);
            let input = dir.path().join("plan.svg");
            std::fs::write(&input, &text).unwrap();
            // Another program edits the plan while its cuts are dilated.
            let changed = if same_length {
                text.replace("x=\"10\"", "x=\"11\"")
            } else {
                text.replace("x=\"10\"", "x=\"10.5\"")
            };
            assert_ne!(changed, text);
            let path = input.clone();
            let progress = Progress::new(move |stage, done, _| {
                if stage == Stage::Dilating && done == 0 {
                    let mut f = std::fs::File::create(&path).unwrap();
                    f.write_all(changed.as_bytes()).unwrap();
                }
            });
            let e = from_file(&input, progress).unwrap_err().to_string();
            assert!(
                e.contains("changed while it was being dilated"),
                "with <use>: {with_use}, same length: {same_length}: {e}"
            );
        }
    }
}

#[test]
fn a_plan_saved_over_by_rename_is_read_from_the_file_first_opened() {
    // Editors save by writing a new file and renaming it over the old one: the plan is read
    // again through the handle first opened, so the output is the plan as first read.
    let dir = tempfile::tempdir().unwrap();
    let text = plan(false);
    let input = dir.path().join("plan.svg");
    std::fs::write(&input, &text).unwrap();
    let (expected, _) = dilate_svg(&text, &kerf(), &SvgOptions::default()).unwrap();
    let (path, saved) = (input.clone(), dir.path().join("saved.svg"));
    let progress = Progress::new(move |stage, done, _| {
        if stage == Stage::Dilating && done == 0 {
            std::fs::write(&saved, text.replace("x=\"10\"", "x=\"11\"")).unwrap();
            std::fs::rename(&saved, &path).unwrap();
        }
    });
    let got = from_file(&input, progress).unwrap();
    assert_eq!(String::from_utf8(got).unwrap(), expected);
}

#[cfg(unix)]
#[test]
fn a_plan_from_a_pipe_is_read_once_and_held() {
    // A named pipe cannot be read twice: it is read once, as before, not waited on again.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("plan.svg");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("no mkfifo here: skipped");
        return;
    }
    let text = plan(false);
    let (expected, _) = dilate_svg(&text, &kerf(), &SvgOptions::default()).unwrap();
    let writer = {
        let (fifo, text) = (fifo.clone(), text.clone());
        std::thread::spawn(move || std::fs::write(&fifo, text).unwrap())
    };
    let got = from_file(&fifo, Progress::default()).unwrap();
    writer.join().unwrap();
    assert_eq!(String::from_utf8(got).unwrap(), expected);
}
