//! The loop itself ([`run_job`]): the machines it drives ([`Devices`]), what it is asked to cut
//! and measure ([`JobRequest`]), each stage in order, and the stop that makes every failure safe
//! (the device's run aborted, the cutter stopped with its laser off).

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use kerfmeter_protocol::{KerfResult, RunParams};

use super::cutter::{HeadState, JobCutter};
use super::{
    CutHeight, JobError, JobEvent, JobReport, Placement, Stage, StageTime, check_travel,
    stopping_flags,
};
use crate::client::Kerfmeter;
use crate::error::Error;
use crate::grbl::CutterError;

/// The simulated device behind `--sim`, told where the prongs landed on the gauge the simulated
/// cutter traced.
#[cfg(feature = "sim")]
pub struct SimLink<'a> {
    /// The device twin.
    pub device: &'a crate::sim::SimDevice,
    /// The cutter twin's kerf model (`None`: the device twin's own).
    pub kerf: Option<kerfmeter_twin::plant::CutterKerf>,
}

/// The machines the loop drives.
pub struct Devices<'a> {
    /// The laser cutter (the GRBL driver's [`crate::grbl::Cutter`], or any [`JobCutter`]).
    pub cutter: &'a mut dyn JobCutter,
    /// The Kerfmeter.
    pub meter: &'a mut Kerfmeter,
    /// With `--sim`: the device twin, which must measure the gauge the cutter twin cut.
    #[cfg(feature = "sim")]
    pub sim: Option<SimLink<'a>>,
}

/// What to cut and measure.
#[derive(Debug, Clone, Copy)]
pub struct JobRequest<'a> {
    /// The gauge's G-code, with its spiral centre at `placement.gauge_at_mm`.
    pub gauge_gcode: &'a str,
    /// Where the gauge is and how the prongs reach it.
    pub placement: Placement,
    /// The device run's parameters.
    pub params: RunParams,
    /// The plan's cuts as placed on the machine (as drawn), `[[min_x, min_y], [max_x, max_y]]`,
    /// mm: checked against the machine's travel before anything moves (`None`: only the job's
    /// own G-code is, by the driver, once it is dilated).
    pub plan_box_mm: Option<[[f64; 2]; 2]>,
}

/// The job's G-code for the kerf measured (µm), or why it cannot be made.
pub type Dilate<'a> = dyn FnMut(f64) -> Result<String, String> + 'a;

/// Run the loop (see the [module docs](crate::job)). `progress` hears of every stage.
pub fn run_job(
    devices: Devices<'_>,
    request: &JobRequest<'_>,
    dilate: &mut Dilate<'_>,
    cancel: &AtomicBool,
    progress: &mut dyn FnMut(JobEvent<'_>),
) -> Result<JobReport, JobError> {
    request.placement.check()?;
    crate::params::check(&request.params).map_err(|e| JobError::Invalid(e.to_string()))?;
    if let Some(travel) = devices.cutter.travel() {
        check_travel(&travel, request)?;
    }
    let mut run = Loop {
        devices,
        request,
        cancel,
        progress,
        stages: Vec::new(),
        sent_to_cutter: false,
    };
    let result = run.all(dilate);
    result.map_err(|e| run.make_safe(e))
}

/// The loop's state while it runs.
struct Loop<'a, 'r> {
    devices: Devices<'a>,
    request: &'r JobRequest<'r>,
    cancel: &'r AtomicBool,
    progress: &'r mut dyn FnMut(JobEvent<'_>),
    stages: Vec<StageTime>,
    /// Whether a program was given to the cutter yet: before, the laser was not this job's to
    /// switch on (see [`unless_nothing_sent`]).
    sent_to_cutter: bool,
}

impl Loop<'_, '_> {
    fn all(&mut self, dilate: &mut Dilate<'_>) -> Result<JobReport, JobError> {
        // Ctrl-C while the cutter connected: nothing moves, not even the device's reset.
        self.check_cancel(Stage::CutGauge)?;
        let cut_height = self.cut_height()?;
        self.devices
            .meter
            .prepare_for_run()
            .map_err(|source| JobError::Device {
                stage: Stage::CutGauge,
                source,
            })?;
        let gauge = self.request.gauge_gcode;
        self.timed(Stage::CutGauge, |l| l.stream(Stage::CutGauge, gauge))?;
        self.timed(Stage::WaitMotion, Self::wait_idle)?;
        let lower = self.request.placement.lower_program();
        let at = self.timed(Stage::Lower, |l| l.stream(Stage::Lower, &lower))?;
        let landing_mm = self.landing_mm(at);
        let kerf = self.timed(Stage::Measure, |l| l.measure(landing_mm))?;
        let lift = self.request.placement.lift_program() + &cut_height.return_program();
        self.timed(Stage::Lift, |l| l.stream(Stage::Lift, &lift))?;
        let kerf_um = kerf.kerf_um;
        let job_gcode = self.timed(Stage::Dilate, |_| {
            dilate(f64::from(kerf_um)).map_err(|reason| JobError::Dilate { kerf_um, reason })
        })?;
        self.check_cancel(Stage::StreamJob)?;
        let report = self.timed(Stage::StreamJob, |l| {
            l.stream_report(Stage::StreamJob, &job_gcode)
        })?;
        Ok(JobReport {
            kerf,
            stages: std::mem::take(&mut self.stages),
            job_gcode,
            job_lines: report.lines,
            landing_mm,
        })
    }

    /// Run `stage`, timing it and telling the progress callback.
    fn timed<T>(
        &mut self,
        stage: Stage,
        body: impl FnOnce(&mut Self) -> Result<T, JobError>,
    ) -> Result<T, JobError> {
        self.check_cancel(stage)?;
        (self.progress)(JobEvent::Started(stage));
        let start = Instant::now();
        let out = body(self)?;
        let elapsed = start.elapsed();
        self.stages.push(StageTime {
            stage,
            elapsed_s: elapsed.as_secs_f64(),
        });
        (self.progress)(JobEvent::Finished(stage, elapsed));
        Ok(out)
    }

    fn check_cancel(&self, stage: Stage) -> Result<(), JobError> {
        if self.cancel.load(Ordering::Relaxed) {
            return Err(JobError::Cancelled { stage });
        }
        Ok(())
    }

    /// Stream `program`; the head's position at the end, when reported.
    fn stream(&mut self, stage: Stage, program: &str) -> Result<Option<[f64; 3]>, JobError> {
        Ok(self.stream_report(stage, program)?.position_mm)
    }

    /// Stream `program` in `stage`, noting whether the cutter was given it; the stream's report.
    fn stream_report(
        &mut self,
        stage: Stage,
        program: &str,
    ) -> Result<crate::grbl::StreamReport, JobError> {
        let progress = &mut *self.progress;
        let streamed = self.devices.cutter.stream(program, self.cancel, &mut |p| {
            progress(JobEvent::Cutter(stage, p))
        });
        self.note_sent(&streamed);
        streamed.map_err(|e| cutter_error(stage, e))
    }

    /// Whether a stream's outcome means the cutter was given the program: it was unless the
    /// stream refused it before sending a line (no stop tried then).
    fn note_sent<T>(&mut self, streamed: &Result<T, CutterError>) {
        self.sent_to_cutter |= streamed
            .as_ref()
            .map_or_else(CutterError::stop_was_tried, |_| true);
    }

    /// Where the head stands before anything moves: the height the gauge and the plan are cut at.
    fn cut_height(&mut self) -> Result<CutHeight, JobError> {
        let status = self.devices.cutter.status();
        let status = status.map_err(|e| cutter_error(Stage::CutGauge, e))?;
        CutHeight::of(&status).ok_or_else(|| {
            JobError::Motion(
                "the cutter reports no position (neither MPos nor WPos), so the plan could not be cut at the height the gauge is cut at; nothing was cut".into(),
            )
        })
    }

    /// Poll the controller until it reports Idle (a stream already waits for it; this checks it
    /// again, and is where a controller that reports motion late is waited for).
    fn wait_idle(&mut self) -> Result<(), JobError> {
        let deadline = Instant::now() + Duration::from_secs(600);
        loop {
            self.check_cancel(Stage::WaitMotion)?;
            let status = self
                .devices
                .cutter
                .status()
                .map_err(|e| cutter_error(Stage::WaitMotion, e))?;
            match status.state {
                HeadState::Idle => return Ok(()),
                HeadState::Alarm => {
                    return Err(JobError::Motion(
                        "the cutter went into alarm after the gauge was cut".into(),
                    ));
                }
                HeadState::Busy(state) if Instant::now() > deadline => {
                    return Err(JobError::Motion(format!(
                        "the cutter was still {state} 10 minutes after the gauge was streamed"
                    )));
                }
                HeadState::Busy(_) => std::thread::sleep(Duration::from_millis(50)),
            }
        }
    }

    /// Where the prongs came down: the head's reported position plus the offset, or the gauge's
    /// centre when the controller does not report its machine position.
    fn landing_mm(&self, head: Option<[f64; 3]>) -> [f64; 2] {
        let p = &self.request.placement;
        match head {
            Some([x, y, _]) => [x + p.prong_offset_mm[0], y + p.prong_offset_mm[1]],
            None => p.gauge_at_mm,
        }
    }

    /// Run the device on the gauge under the prongs; a failed, flagged or cancelled run lifts
    /// the prongs (unless cancelled) before the error goes up.
    fn measure(&mut self, landing_mm: [f64; 2]) -> Result<KerfResult, JobError> {
        let result = self
            .place_sim_gauge(landing_mm)
            .and_then(|()| self.device_run());
        if let Err(e) = &result {
            let _ = self.devices.meter.abort();
            if !matches!(e, JobError::Cancelled { .. }) {
                // A failed lift has stopped the cutter itself; the first error is the one to tell.
                let lift = self.request.placement.lift_program();
                let _ = self.stream(Stage::Lift, &lift);
            }
        }
        result
    }

    fn device_run(&mut self) -> Result<KerfResult, JobError> {
        let progress = &mut *self.progress;
        let cancel = self.cancel;
        let run = self
            .devices
            .meter
            .run_kerfmeter_until(&self.request.params, |p| {
                progress(JobEvent::Device(p));
                if cancel.load(Ordering::Relaxed) {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            });
        let stage = Stage::Measure;
        let kerf = match run {
            Ok(kerf) => kerf,
            Err(Error::Cancelled) => return Err(JobError::Cancelled { stage }),
            Err(source) => return Err(JobError::Device { stage, source }),
        };
        let flags = stopping_flags(kerf.flags);
        if !flags.is_empty() {
            return Err(JobError::Flagged {
                kerf_um: kerf.kerf_um,
                flags: flags.names().collect::<Vec<_>>().join(", "),
            });
        }
        Ok(kerf)
    }

    /// With `--sim`: the gauge the cutter twin traced goes under the device twin's prongs.
    #[cfg(feature = "sim")]
    fn place_sim_gauge(&mut self, landing_mm: [f64; 2]) -> Result<(), JobError> {
        let Some(link) = &self.devices.sim else {
            return Ok(());
        };
        let Some(segments) = self.devices.cutter.traced_segments() else {
            return Err(JobError::Invalid(
                "the simulated device measures only a gauge the simulated cutter cut".into(),
            ));
        };
        link.device
            .place_traced_gauge(&segments, landing_mm, link.kerf)
            .map(|_| ())
            .map_err(|source| JobError::Device {
                stage: Stage::Measure,
                source,
            })
    }

    #[cfg(not(feature = "sim"))]
    fn place_sim_gauge(&mut self, _landing_mm: [f64; 2]) -> Result<(), JobError> {
        Ok(())
    }

    /// Stop the cutter after `e` (the laser off), unless a stream already tried to. A cutter's
    /// own failure is stopped as a stream's is, and tells how that went (a reset that found the
    /// head moving, an alarm that hears only a reset).
    fn make_safe(&mut self, e: JobError) -> JobError {
        let _ = self.devices.meter.abort();
        if stream_stopped(&e) {
            return e;
        }
        let sent = self.sent_to_cutter;
        match e {
            JobError::Cutter { stage, source } => JobError::Cutter {
                stage,
                source: unless_nothing_sent(self.devices.cutter.stop_after(source), sent),
            },
            e => match self.devices.cutter.stop() {
                Err(stop) if sent => JobError::NotStopped {
                    cause: Box::new(e),
                    stop,
                },
                _ => e,
            },
        }
    }
}

/// Whether `e` is a stream's failure after which the stream tried to stop the cutter itself.
fn stream_stopped(e: &JobError) -> bool {
    matches!(e, JobError::Cutter { source, .. } if source.stop_was_tried())
}

/// A cutter's failure after the stop that followed it, as the user is told it: before the job
/// sent the cutter a program (`sent`) it had only asked its state, so a stop that failed (the
/// port gone) is no sign of a laser this job switched on, and the failure is told as it was.
fn unless_nothing_sent(after_stop: CutterError, sent: bool) -> CutterError {
    match after_stop {
        CutterError::NotStopped { cause, .. } if !sent => *cause,
        after_stop => after_stop,
    }
}

/// A stream's error in `stage`; a cancelled stream is the loop's cancel, unless its stop left
/// more to say (the laser may be on, or the reset found the head moving: home it).
fn cutter_error(stage: Stage, e: CutterError) -> JobError {
    let plain_stop = matches!(
        e,
        CutterError::Stopped {
            position_lost: false,
            ..
        }
    );
    match e.cause() {
        CutterError::Cancelled { .. } if plain_stop => JobError::Cancelled { stage },
        _ => JobError::Cutter { stage, source: e },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_status_read_is_stopped_and_a_stop_that_fails_before_any_program_alarms_no_one() {
        let lost = || CutterError::Io {
            address: "grbl:/dev/ttyUSB0".into(),
            source: std::io::Error::other("the port vanished"),
        };
        let read_failed = JobError::Cutter {
            stage: Stage::WaitMotion,
            source: lost(),
        };
        assert!(!stream_stopped(&read_failed));
        let stream_failed = JobError::Cutter {
            stage: Stage::StreamJob,
            source: CutterError::Stopped {
                cause: Box::new(lost()),
                position_lost: false,
            },
        };
        assert!(stream_stopped(&stream_failed));
        let not_stopped = || CutterError::NotStopped {
            cause: Box::new(lost()),
            stop: Box::new(lost()),
        };
        assert!(unless_nothing_sent(not_stopped(), true).laser_may_be_on());
        let before_any = unless_nothing_sent(not_stopped(), false);
        assert!(!before_any.laser_may_be_on());
        assert!(
            before_any.to_string().contains("the port vanished"),
            "{before_any}"
        );
    }
}
