//! The server's `job` method: the whole loop on the cutter given to `kerfmeter serve --cutter`.
//! Its params, besides the plan sent as text (or base64), are deserialized straight into a
//! [`JobRequest`] (unknown ones refused, a bad one named); the plan goes into a folder of the
//! server's own, which also receives the outputs, and the job is set up (the plan read, the
//! gauge placed) before the device is asked for.

use kerfmeter::grbl::CutterAddress;
use kerfmeter_app::job::{JobCliReport, JobFiles, JobRequest, JobSetup};
use kerfmeter_plan::PlanFormat;
use serde_json::{Value, json};

use super::Cutter;
use super::plans::{format, hide_history_db, plan_bytes, plan_work};
use super::rpc::{INVALID_PARAMS, PLAN_ERROR, Params, RpcError};
use crate::error::CliError;

/// A checked `job` request, set up in a folder of the server's own that holds the plan and
/// receives the outputs.
pub struct JobCall {
    /// The cutter it runs on.
    pub cutter: CutterAddress,
    /// What the loop needs, made before anything moves (the request and its files in it).
    pub setup: JobSetup,
    /// The folder (removed when the call is dropped).
    pub dir: tempfile::TempDir,
}

impl JobCall {
    /// The caller's label.
    pub fn label(&self) -> Option<&str> {
        self.setup.request().label.as_deref()
    }
}

impl std::fmt::Debug for JobCall {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobCall")
            .field("input", &self.setup.files().input)
            .field("dir", &self.dir.path())
            .finish_non_exhaustive()
    }
}

/// `job` {plan | plan_base64, format, ... a [`JobRequest`]}: checked (the plan is read, the
/// gauge placed) before the device is asked for. `unlock` is refused unless the server allows
/// it.
pub async fn job_call(mut p: Params, cutter: &Cutter) -> Result<JobCall, RpcError> {
    if !cutter.allow_unlock && p.0.get("unlock").is_some_and(|u| u != &Value::Bool(false)) {
        let why = "parameter `unlock`: refused, as the server was started without \
                   --allow-unlock: a controller in alarm was stopped by its own safety (a limit, \
                   a door, a reset mid-job); clear it at the machine";
        return Err(RpcError::new(INVALID_PARAMS, why));
    }
    let plan = plan_bytes(&mut p)?;
    let format = format(&mut p)?;
    // A null is a parameter not given, as it always was for `job`.
    p.0.retain(|_, v| !v.is_null());
    let request: JobRequest = p.into_request()?;
    let address: CutterAddress = cutter
        .address
        .parse()
        .map_err(|e| RpcError::from(&CliError::Cutter(e)))?;
    let ext = if format == PlanFormat::Dxf {
        "dxf"
    } else {
        "svg"
    };
    let no_room =
        |e: std::io::Error| RpcError::new(PLAN_ERROR, format!("no room for the plan: {e}"));
    let dir = tempfile::tempdir().map_err(no_room)?;
    let input = dir.path().join(format!("plan.{ext}"));
    std::fs::write(&input, &plan).map_err(no_room)?;
    let files = JobFiles {
        input,
        output: dir.path().join(format!("dilated.{ext}")),
        gcode_out: Some(dir.path().join("job.gcode")),
        profile: None,
        force: false,
    };
    let read = move || JobSetup::new(request, files, false).map_err(CliError::from);
    let setup = plan_work("reading the plan", read).await?;
    Ok(JobCall {
        cutter: address,
        setup,
        dir,
    })
}

/// What `job` answers: the loop's report (without the server's file names), the dilated plan
/// and the job's G-code as text.
pub fn job_answer(call: &JobCall, report: &JobCliReport) -> Result<Value, CliError> {
    let mut report = serde_json::to_value(report).expect("reports serialize");
    if let Some(fields) = report.as_object_mut() {
        for name in ["input", "output", "gcode_out"] {
            fields.remove(name);
        }
    }
    hide_history_db(&mut report);
    let read = |path: &std::path::Path| {
        std::fs::read(path).map_err(|e| kerfmeter::Error::File {
            path: path.to_owned(),
            message: e.to_string(),
        })
    };
    let files = call.setup.files();
    let content = String::from_utf8_lossy(&read(&files.output)?).into_owned();
    let gcode = String::from_utf8_lossy(&read(call.setup.gcode_out())?)
        // Its header names the plan's source: the server's own copy, which is not the caller's.
        .replace(
            &files.input.display().to_string(),
            "the plan sent to kerfmeter serve",
        );
    let kerf_um = report["kerf_um"].clone();
    Ok(json!({
        "kerf_um": kerf_um, "label": call.label(), "report": report, "content": content,
        "gcode": gcode,
    }))
}
