//! The job's moves against the machine's travel ([`crate::grbl::travel`]), checked before
//! anything moves ([`check_travel`]): where the head stands, the plan as placed (as it will be
//! cut: the dilated plan's lower-left corner goes where the drawn one's does, and it is up to the
//! largest kerf the gauge measures wider and taller), the gauge's program, the head's move that
//! puts the prongs over the gauge (the prong offset), and the travel and insert Z. Each refusal
//! names the number, the machine's limit and the flag that changes it.
//!
//! The driver checks every program again before it streams it (the dilated job's own G-code
//! too); this check is the one that can still name the job's flags, and that comes before the
//! gauge is cut.

use kerfmeter_protocol::RunParams;

use crate::grbl::protocol::prepare;
use crate::grbl::travel::{Beyond, Travel};

use super::{JobError, JobRequest};

/// A Z height equal to another within this, mm.
const SAME_Z_MM: f64 = 1e-9;

/// Refuse `request` when anything it moves over lies outside `travel`: the plan as placed (when
/// its box is given), where the head stands, the gauge's program, the head's move over the gauge
/// and the Z heights, each with the flag that changes it ([`JobError::Travel`]).
pub fn check_travel(travel: &Travel, request: &JobRequest<'_>) -> Result<(), JobError> {
    if let Some(plan_box_mm) = request.plan_box_mm {
        check_plan_travel(travel, plan_box_mm, &request.params)?;
    }
    check_head(travel)?;
    check_gauge(travel, request)?;
    check_prongs(travel, request)?;
    check_heights(travel, request)
}

/// Refuse a plan whose cuts, placed at `plan_box_mm` (as drawn) and dilated by up to the largest
/// kerf the gauge of `params` measures, leave `travel` (the head's position checked first). The
/// part of [`check_travel`] that needs no gauge placed yet.
pub fn check_plan_travel(
    travel: &Travel,
    plan_box_mm: [[f64; 2]; 2],
    params: &RunParams,
) -> Result<(), JobError> {
    check_head(travel)?;
    let kerf_mm = f64::from(params.gauge.max_kerf_um()) / 1000.0;
    check_plan(travel, plan_box_mm, kerf_mm)
}

/// The head stands in the travel as read (else the rule does not fit the machine).
fn check_head(travel: &Travel) -> Result<(), JobError> {
    travel.check_head().map_err(|b| {
        refused(format!(
            "the head stands at {b}: where the controller puts it does not fit its travel as \
             read. Home the machine, or switch the controller on with the head at its origin \
             corner"
        ))
    })
}

/// A travel refusal, saying that nothing was sent.
fn refused(message: String) -> JobError {
    JobError::Travel(format!("{message}. Nothing was sent"))
}

/// The plan as placed, dilated by up to `kerf_mm`: its lower-left corner stays (the dilated
/// plan is placed by its own), its far sides grow by the kerf.
fn check_plan(travel: &Travel, plan: [[f64; 2]; 2], kerf_mm: f64) -> Result<(), JobError> {
    let [[x0, y0], [x1, y1]] = plan;
    for (axis, ends) in [[x0, x1], [y0, y1]].into_iter().enumerate() {
        let ends = [ends[0], ends[1] + kerf_mm];
        travel.check_work(axis, &ends).map_err(|b| {
            refused(format!(
                "the plan as placed fills ({x0:.1}, {y0:.1})–({x1:.1}, {y1:.1}) mm and, dilated \
                 by up to the largest kerf the gauge measures ({kerf_mm:.2} mm), reaches {b}. \
                 Move it with --origin-mm X,Y{}",
                set_travel(&b)
            ))
        })?;
    }
    Ok(())
}

/// Every move of the gauge's program.
fn check_gauge(travel: &Travel, request: &JobRequest<'_>) -> Result<(), JobError> {
    let [gx, gy] = request.placement.gauge_at_mm;
    let lines = prepare(request.gauge_gcode).map_err(|bad| {
        JobError::Invalid(format!(
            "the gauge's G-code line {}: {}",
            bad.number, bad.reason
        ))
    })?;
    let extent = travel.extent(&lines).map_err(|u| {
        JobError::Invalid(format!(
            "the gauge's G-code line {} ({}) {}",
            u.line, u.written, u.reason
        ))
    })?;
    travel.check(&extent).map_err(|b| {
        refused(format!(
            "the gauge at ({gx:.1}, {gy:.1}) mm would be cut out to {b}. Give a --gauge-at-mm \
             X,Y that keeps it within the travel, or leave it out for a free spot on the bed \
             (--bed-mm, the travel when not given){}",
            set_travel(&b)
        ))
    })
}

/// The head's move that puts the prongs' axis over the gauge's centre.
fn check_prongs(travel: &Travel, request: &JobRequest<'_>) -> Result<(), JobError> {
    let p = &request.placement;
    let [gx, gy] = p.gauge_at_mm;
    let [dx, dy] = p.prong_offset_mm;
    let head = p.head_over_gauge_mm();
    (0..2).try_for_each(|axis| {
        travel.check_work(axis, &[head[axis]]).map_err(|b| {
            refused(format!(
                "to put the prongs over the gauge at ({gx:.1}, {gy:.1}) mm the head would move \
                 to {b}. Check --prong-offset-mm ({dx}, {dy} mm: the prongs' axis relative to \
                 the nozzle, a few tens of mm; see docs/cutters.md to calibrate it), or move the \
                 gauge with --gauge-at-mm{}",
                set_travel(&b)
            ))
        })
    })
}

/// The travel and insert Z (and, where only Z's span is known, the head's height with them).
fn check_heights(travel: &Travel, request: &JobRequest<'_>) -> Result<(), JobError> {
    let p = &request.placement;
    let (up, down) = (p.travel_z_mm, p.insert_z_mm);
    travel.check_work(2, &[up, down]).map_err(|b| {
        let what = match (&b.from, (b.work_mm() - up).abs() <= SAME_Z_MM) {
            (Some(_), _) => format!(
                "the job moves Z between the head's height now, --travel-z-mm {up} and \
                 --insert-z-mm {down}: {b}. Bring them closer to the height the head stands at"
            ),
            (None, true) => {
                format!("--travel-z-mm {up} lifts the head to {b}. Give a lower --travel-z-mm")
            }
            (None, false) => {
                format!("--insert-z-mm {down} lowers the head to {b}. Give a higher --insert-z-mm")
            }
        };
        refused(format!("{what}{}", set_travel(&b)))
    })
}

/// The other way out: the machine's own travel setting, when it is wrong.
fn set_travel(b: &Beyond) -> String {
    format!(
        "; or, if the machine's travel is larger, {}",
        b.change_setting()
    )
}
