//! Where the job's moves go: the gauge's place and the prongs' reach ([`Placement`]) with the
//! programs that lower and lift them, the height the job cuts at ([`CutHeight`]), the bed's room
//! for the gauge beside the plan ([`free_spot_mm`]) and the checks of every planned move against
//! the bed ([`Layout`], [`Placement::check_layout`]).

use serde::Serialize;

use super::JobError;
use super::cutter::HeadStatus;

/// Where the gauge is cut and how the prongs reach it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Placement {
    /// The gauge's spiral centre on the bed, mm.
    pub gauge_at_mm: [f64; 2],
    /// The prongs' axis relative to the laser nozzle, mm.
    pub prong_offset_mm: [f64; 2],
    /// Z that puts the prongs into the gauge's holes, mm (machine coordinates).
    pub insert_z_mm: f64,
    /// Z that keeps the prongs clear of the work, mm.
    pub travel_z_mm: f64,
    /// Feed of the plunge to `insert_z_mm`, mm/min.
    pub plunge_feed_mm_per_min: f64,
}

/// Largest coordinate accepted, mm (as the plan crate's G-code writer).
const MAX_COORDINATE_MM: f64 = 100_000.0;

impl Placement {
    /// Where the head goes so that the prongs stand over the gauge's centre, mm.
    pub fn head_over_gauge_mm(&self) -> [f64; 2] {
        [
            self.gauge_at_mm[0] - self.prong_offset_mm[0],
            self.gauge_at_mm[1] - self.prong_offset_mm[1],
        ]
    }

    /// Check the numbers: finite, on a plausible machine, a positive plunge feed.
    pub fn check(&self) -> Result<(), JobError> {
        let coordinates = [
            self.gauge_at_mm[0],
            self.gauge_at_mm[1],
            self.prong_offset_mm[0],
            self.prong_offset_mm[1],
            self.insert_z_mm,
            self.travel_z_mm,
        ];
        if !coordinates
            .iter()
            .all(|x| x.is_finite() && x.abs() < MAX_COORDINATE_MM)
        {
            return Err(JobError::Invalid(format!(
                "the gauge position, prong offset and Z heights must be finite mm within ±100000, got {self:?}"
            )));
        }
        let feed = self.plunge_feed_mm_per_min;
        if !(feed.is_finite() && feed > 0.0 && feed <= 100_000.0) {
            return Err(JobError::Invalid(format!(
                "the plunge feed must be above 0 and at most 100000 mm/min, got {feed}"
            )));
        }
        if self.insert_z_mm >= self.travel_z_mm {
            return Err(JobError::Invalid(format!(
                "the insert Z (--insert-z-mm {}) must be below the travel Z (--travel-z-mm {}): Z \
                 grows upward, and the prongs plunge from the travel height down into the gauge; \
                 give a lower --insert-z-mm (e.g. -6) or a higher --travel-z-mm",
                self.insert_z_mm, self.travel_z_mm
            )));
        }
        Ok(())
    }

    /// [`check`](Self::check) the numbers, then every move the job plans against `layout`: the
    /// plan and the gauge on the bed, the gauge (with the margin) clear of the plan, and the
    /// head's move that puts the prongs over the gauge on the bed. The one check of where the
    /// job's moves go, made before anything moves.
    pub fn check_layout(&self, layout: &Layout) -> Result<(), JobError> {
        self.check()?;
        layout.check_plan_on_bed()?;
        let bed = layout.bed_box_mm();
        let [bw, bh] = layout.bed_mm;
        let plan = layout.plan_box_mm;
        let gauge = placed(layout.gauge_extent_mm, self.gauge_at_mm);
        let [gx, gy] = self.gauge_at_mm;
        if !contains(bed, gauge) {
            return Err(JobError::Invalid(format!(
                "the gauge at ({gx:.1}, {gy:.1}) mm would be cut over {}, off the {bw} × {bh} mm \
                 bed {}: give a --gauge-at-mm X,Y that keeps it on the bed (or leave it out for a \
                 free spot beside the plan), or --bed-mm W,H if the bed is larger",
                show_box(gauge),
                show_box(bed)
            )));
        }
        let margin = layout.margin_mm;
        if overlap(grown(gauge, margin), plan) {
            return Err(JobError::Invalid(format!(
                "the gauge at ({gx:.1}, {gy:.1}) mm would be cut over {}, within {margin} mm of \
                 the plan, which fills {}: the gauge would cut into the job. Give a --gauge-at-mm \
                 X,Y clear of the plan, or leave it out for a free spot beside the plan",
                show_box(gauge),
                show_box(plan)
            )));
        }
        let [hx, hy] = self.head_over_gauge_mm();
        if !contains(bed, [[hx, hy], [hx, hy]]) {
            let [dx, dy] = self.prong_offset_mm;
            return Err(JobError::Invalid(format!(
                "to put the prongs over the gauge at ({gx:.1}, {gy:.1}) mm the head would move to \
                 X{hx:.1} Y{hy:.1}, off the {bw} × {bh} mm bed {}: check --prong-offset-mm \
                 ({dx}, {dy} mm: the prongs' axis relative to the nozzle, a few tens of mm; see \
                 docs/cutters.md to calibrate it), or move the gauge with --gauge-at-mm",
                show_box(bed)
            )));
        }
        Ok(())
    }

    /// The program that lifts to the travel height, moves the prongs over the gauge and lowers
    /// them (laser off throughout).
    pub fn lower_program(&self) -> String {
        let [x, y] = self.head_over_gauge_mm();
        format!(
            "G21 G90\nM5 S0\nG0 Z{:.4}\nG0 X{x:.4} Y{y:.4}\nG1 Z{:.4} F{:.1}\n",
            self.travel_z_mm, self.insert_z_mm, self.plunge_feed_mm_per_min
        )
    }

    /// The program that lifts the prongs clear (laser off).
    pub fn lift_program(&self) -> String {
        format!("G21 G90\nM5 S0\nG0 Z{:.4}\n", self.travel_z_mm)
    }
}

/// The height the job cuts at: where the head stood when the job began (the user's focus), in
/// the coordinates the controller reports it in. The gauge is cut there, and the head comes back
/// to it once the prongs are lifted, so that the plan is cut as the gauge was.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CutHeight {
    /// Machine Z, mm (`MPos`): gone back to with `G53`, whatever the work offset.
    Machine(f64),
    /// Work Z, mm (`WPos`, a controller set to report it): gone back to in work coordinates.
    Work(f64),
}

impl CutHeight {
    /// The height in `status`, when it reports a position.
    pub fn of(status: &HeadStatus) -> Option<Self> {
        let machine = status.machine_mm.map(|p| Self::Machine(p[2]));
        machine.or(status.work_mm.map(|p| Self::Work(p[2])))
    }

    /// The program that takes the head back to it, straight down or up (laser off).
    pub fn return_program(self) -> String {
        match self {
            Self::Machine(z) => format!("G21 G90\nM5 S0\nG53 G0 Z{z:.4}\n"),
            Self::Work(z) => format!("G21 G90\nM5 S0\nG0 Z{z:.4}\n"),
        }
    }
}

/// Where the job's moves must stay, for [`Placement::check_layout`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    /// The bed's size, mm, from the machine origin (0, 0).
    pub bed_mm: [f64; 2],
    /// The plan's cuts as placed on the machine, `[[min_x, min_y], [max_x, max_y]]`, mm (as
    /// drawn: the dilation grows them by half the kerf, well within `margin_mm`).
    pub plan_box_mm: [[f64; 2]; 2],
    /// The gauge's cuts relative to its spiral centre, `[[min_x, min_y], [max_x, max_y]]`, mm.
    pub gauge_extent_mm: [[f64; 2]; 2],
    /// Space kept between the gauge's cuts and the plan's, mm.
    pub margin_mm: f64,
}

impl Layout {
    /// The bed as a box, mm.
    fn bed_box_mm(&self) -> [[f64; 2]; 2] {
        [[0.0, 0.0], self.bed_mm]
    }

    /// The plan as placed lies on the bed (checked first: a plan off the bed leaves no room
    /// for the gauge either, and that is not what to fix).
    pub fn check_plan_on_bed(&self) -> Result<(), JobError> {
        let (bed, plan) = (self.bed_box_mm(), self.plan_box_mm);
        let [bw, bh] = self.bed_mm;
        if contains(bed, plan) {
            return Ok(());
        }
        Err(JobError::Invalid(format!(
            "the plan as placed fills {}, beyond the {bw} × {bh} mm bed {}: move it with \
             --origin-mm X,Y, or give the bed's size with --bed-mm W,H if it is larger",
            show_box(plan),
            show_box(bed)
        )))
    }
}

/// Rounding allowed when a box is compared with another, mm.
const TOLERANCE_MM: f64 = 1e-6;

/// `extent` (relative to a centre) with its centre at `at`.
fn placed(extent: [[f64; 2]; 2], at: [f64; 2]) -> [[f64; 2]; 2] {
    let [[x0, y0], [x1, y1]] = extent;
    [[at[0] + x0, at[1] + y0], [at[0] + x1, at[1] + y1]]
}

/// `b` grown by `by` on every side.
fn grown(b: [[f64; 2]; 2], by: f64) -> [[f64; 2]; 2] {
    [[b[0][0] - by, b[0][1] - by], [b[1][0] + by, b[1][1] + by]]
}

/// True when `inner` lies within `outer`.
fn contains(outer: [[f64; 2]; 2], inner: [[f64; 2]; 2]) -> bool {
    let outer = grown(outer, TOLERANCE_MM);
    (0..2).all(|i| inner[0][i] >= outer[0][i] && inner[1][i] <= outer[1][i])
}

/// True when `a` and `b` share more than their edges.
fn overlap(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> bool {
    let a = grown(a, -TOLERANCE_MM);
    (0..2).all(|i| a[0][i] < b[1][i] && b[0][i] < a[1][i])
}

/// A box as `(x0, y0)–(x1, y1) mm`.
fn show_box(b: [[f64; 2]; 2]) -> String {
    format!(
        "({:.1}, {:.1})–({:.1}, {:.1}) mm",
        b[0][0], b[0][1], b[1][0], b[1][1]
    )
}

/// A free spot on a bed of `bed_mm` (from 0,0) for a gauge whose cuts reach `gauge_extent_mm`
/// (`[[min_x, min_y], [max_x, max_y]]`, relative to its centre) beside a plan whose cuts fill
/// `plan_box_mm` on the machine, `margin_mm` apart: to the right of the plan, above, left or
/// below, in that order, aligned with the plan's lower-left corner. `None` when none fits.
pub fn free_spot_mm(
    plan_box_mm: [[f64; 2]; 2],
    gauge_extent_mm: [[f64; 2]; 2],
    bed_mm: [f64; 2],
    margin_mm: f64,
) -> Option<[f64; 2]> {
    let [[px0, py0], [px1, py1]] = plan_box_mm;
    let [[gx0, gy0], [gx1, gy1]] = gauge_extent_mm;
    let candidates = [
        [px1 + margin_mm - gx0, py0 - gy0],
        [px0 - gx0, py1 + margin_mm - gy0],
        [px0 - margin_mm - gx1, py0 - gy0],
        [px0 - gx0, py0 - margin_mm - gy1],
    ];
    let bed = [[0.0, 0.0], bed_mm];
    candidates
        .into_iter()
        .find(|c| contains(bed, placed(gauge_extent_mm, *c)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAUGE: [[f64; 2]; 2] = [[-30.0, -30.0], [30.0, 30.0]];

    #[test]
    fn the_gauge_goes_beside_the_plan_where_the_bed_has_room() {
        let bed = [400.0, 300.0];
        // Room on the right.
        let at = free_spot_mm([[0.0, 0.0], [100.0, 80.0]], GAUGE, bed, 5.0).unwrap();
        assert_eq!(at, [135.0, 30.0]);
        // A plan as wide as the bed: above it.
        let at = free_spot_mm([[0.0, 0.0], [400.0, 80.0]], GAUGE, bed, 5.0).unwrap();
        assert_eq!(at, [30.0, 115.0]);
        // No room anywhere.
        assert!(free_spot_mm([[0.0, 0.0], [390.0, 290.0]], GAUGE, bed, 5.0).is_none());
    }

    #[test]
    fn the_prong_moves_never_fire_the_laser_and_put_the_prongs_over_the_gauge() {
        let p = Placement {
            gauge_at_mm: [100.0, 50.0],
            prong_offset_mm: [30.0, -5.0],
            insert_z_mm: -2.0,
            travel_z_mm: 10.0,
            plunge_feed_mm_per_min: 300.0,
        };
        assert_eq!(p.head_over_gauge_mm(), [70.0, 55.0]);
        let lower = p.lower_program();
        assert!(lower.contains("M5 S0\nG0 Z10.0000\nG0 X70.0000 Y55.0000\nG1 Z-2.0000"));
        assert!(!lower.contains("M3") && !lower.contains("M4"));
        assert!(p.lift_program().ends_with("M5 S0\nG0 Z10.0000\n"));
        let bad = Placement {
            insert_z_mm: f64::NAN,
            ..p
        };
        assert!(bad.check().is_err());
    }

    fn layout() -> Layout {
        Layout {
            bed_mm: [600.0, 400.0],
            plan_box_mm: [[0.0, 0.0], [96.0, 96.0]],
            gauge_extent_mm: GAUGE,
            margin_mm: 5.0,
        }
    }

    fn at(gauge_at_mm: [f64; 2], prong_offset_mm: [f64; 2]) -> Placement {
        Placement {
            gauge_at_mm,
            prong_offset_mm,
            insert_z_mm: -2.0,
            travel_z_mm: 10.0,
            plunge_feed_mm_per_min: 300.0,
        }
    }

    fn refusal(p: Placement, layout: &Layout) -> String {
        p.check_layout(layout).unwrap_err().to_string()
    }

    #[test]
    fn the_gauge_beside_the_plan_on_the_bed_is_accepted() {
        let l = layout();
        let spot = free_spot_mm(l.plan_box_mm, GAUGE, l.bed_mm, l.margin_mm).unwrap();
        assert_eq!(spot, [131.0, 30.0]);
        at(spot, [20.0, -5.0]).check_layout(&l).unwrap();
        at([300.0, 200.0], [0.0, 0.0]).check_layout(&l).unwrap();
    }

    #[test]
    fn a_gauge_over_or_beside_the_plan_within_the_margin_is_refused() {
        let l = layout();
        let over = refusal(at([30.0, 30.0], [0.0, 0.0]), &l);
        assert!(over.contains("within 5 mm of the plan"), "{over}");
        assert!(over.contains("--gauge-at-mm"), "{over}");
        // 4 mm right of the plan: inside the margin.
        assert!(at([130.0, 30.0], [0.0, 0.0]).check_layout(&l).is_err());
    }

    #[test]
    fn a_gauge_the_plan_or_the_head_off_the_bed_is_refused() {
        let l = layout();
        for gauge_at in [[-500.0, 30.0], [5000.0, 30.0], [300.0, 390.0]] {
            let off = refusal(at(gauge_at, [0.0, 0.0]), &l);
            assert!(off.contains("off the 600 × 400 mm bed"), "{off}");
        }
        let head = refusal(at([131.0, 30.0], [1000.0, 1000.0]), &l);
        assert!(head.contains("X-869.0 Y-970.0"), "{head}");
        assert!(head.contains("--prong-offset-mm"), "{head}");
        let plan = Layout {
            plan_box_mm: [[500.0, 0.0], [700.0, 96.0]],
            ..l
        };
        let off = refusal(at([300.0, 200.0], [0.0, 0.0]), &plan);
        assert!(off.contains("--origin-mm"), "{off}");
    }

    #[test]
    fn an_insert_z_not_below_the_travel_z_is_refused() {
        let p = at([300.0, 200.0], [0.0, 0.0]);
        for insert_z_mm in [50.0, 10.0] {
            let up = Placement { insert_z_mm, ..p };
            let e = up.check().unwrap_err().to_string();
            assert!(e.contains("must be below the travel Z"), "{e}");
            assert!(up.check_layout(&layout()).is_err());
        }
    }
}
