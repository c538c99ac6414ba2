//! The job's setup on the example plan: placed, checked and dilated before and without any
//! machine.

use std::path::PathBuf;

use kerfmeter::job::Stage;

use super::*;

/// A fresh folder for a test's outputs, removed when dropped.
struct Folder(PathBuf);

impl Folder {
    fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("kerfmeter-app-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Folder(dir)
    }

    /// The example plan, writing `output` here.
    fn files(&self, output: &str) -> JobFiles {
        JobFiles {
            input: PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/box-parts.svg"),
            output: self.0.join(output),
            gcode_out: None,
            profile: None,
            force: false,
        }
    }
}

impl Drop for Folder {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn a_dry_run_gives_every_stages_program_with_the_gauge_beside_the_plan() {
    let folder = Folder::new("dry-run");
    let setup = JobSetup::new(JobRequest::default(), folder.files("out.svg"), true).unwrap();
    assert_eq!(setup.gcode_out(), &folder.0.join("out.gcode"));
    let report = setup.dry_run(150.0).unwrap();
    let stages: Vec<Stage> = report.stages.iter().map(|s| s.stage).collect();
    assert_eq!(
        stages,
        [Stage::CutGauge, Stage::Lower, Stage::Lift, Stage::StreamJob]
    );
    assert!(report.stages[3].gcode.contains("not measured: a dry run"));
    let [x, y] = report.gauge_at_mm;
    assert!(
        (0.0..600.0).contains(&x) && (0.0..400.0).contains(&y),
        "{x}, {y}"
    );
    assert!(report.to_string().contains("dilated by 150 um here"));
}

#[test]
fn the_dilate_stage_writes_the_plan_and_the_gcode_it_hands_back() {
    let folder = Folder::new("dilate");
    let setup = JobSetup::new(JobRequest::default(), folder.files("out.svg"), false).unwrap();
    let placed = setup.on_machine(None).unwrap();
    assert_eq!(setup.loop_request(&placed).gauge_gcode, placed.gauge_gcode);
    let mut written = Vec::new();
    let gcode = setup.dilate_and_write(180.0, &mut written).unwrap();
    assert!(gcode.contains("measured by kerfmeter job"));
    assert_eq!(
        written,
        [folder.0.join("out.svg"), folder.0.join("out.gcode")]
    );
    assert_eq!(std::fs::read_to_string(&written[1]).unwrap(), gcode);
}

#[test]
fn what_cannot_be_cut_is_refused_before_anything_moves() {
    let folder = Folder::new("refused");
    let refused =
        |request: JobRequest, files: JobFiles| JobSetup::new(request, files, false).unwrap_err();
    let e = refused(JobRequest::default(), folder.files("out.dxf"));
    assert!(
        matches!(e, JobSetupError::App(crate::Error::Plan(_))),
        "{e}"
    );
    let same = JobFiles {
        gcode_out: Some(folder.0.join("out.svg")),
        ..folder.files("out.svg")
    };
    let e = refused(JobRequest::default(), same);
    assert!(matches!(e, JobSetupError::Invalid(_)), "{e}");
    let upward = JobRequest {
        insert_z_mm: 20.0,
        ..JobRequest::default()
    };
    let e = refused(upward, folder.files("out.svg"));
    assert!(matches!(e, JobSetupError::Job(_)), "{e}");
    let half = JobRequest {
        feed_mm_per_min: Some(600.0),
        ..JobRequest::default()
    };
    let e = refused(half, folder.files("out.svg"));
    assert!(e.to_string().contains("give both"), "{e}");
    let tiny_bed = JobRequest {
        bed_mm: Some([10.0, 10.0]),
        ..JobRequest::default()
    };
    assert!(JobSetup::new(tiny_bed, folder.files("out.svg"), false).is_err());
}
