//! G-code for GRBL 1.1 in laser mode, from a dilated plan or from the gauge drawing.
//!
//! A [`Program`] is built first as typed operations ([`Op`]: travels, straight and arc cuts,
//! power and feed changes, laser on and off), so that its geometry and safety can be checked
//! without parsing text ([`Program::traced`]); [`Program::to_text`] then writes it out.
//!
//! **What the text looks like.** Header comments (tool and version, source, kerf applied,
//! profile, the `S` of full power as `(S_MAX=…)`, GRBL settings needed, placement), then
//! `G17 G21 G90 G94` (XY plane, mm, absolute, feed per minute: whatever a startup block or an
//! interrupted job left) and `M5` (laser off). Each contour is:
//! a comment with its settings and name, `G0` to its start, `F` (its feed), `M4 S…` (laser on,
//! dynamic power), its `G1` lines and `G2`/`G3` arcs (`I`/`J` centre offsets, relative to the
//! arc's start as GRBL's default `G91.1` says) — every pass in a row, the contour being closed —
//! and `M5`. The program ends with `M5` and `M2`.
//!
//! **Laser safety.** Every travel (`G0`) happens after an explicit `M5`: the program never
//! relies on laser mode's own rule (GRBL with `$32=1` switches the laser off during `G0` even in
//! `M3`/`M4`), which stays a second guard. `M4` (dynamic power: the power scales with the actual
//! speed, so corners and accelerations are not over-burnt) is given only right before a
//! contour's first cut move.
//!
//! **GRBL settings assumed.** `$32=1` (laser mode: `S` changes do not stop motion — `M3`/`M4`/
//! `M5` do wait for it —, `G0` is laser-off) and `$30` = the `S` of full power (1000 by default;
//! `--s-max` when the controller differs). Power is written as `S = power_percent / 100 · $30`;
//! the header declares that `S` max (`(S_MAX=1000 …)`, [`S_MAX_TAG`]) and the GRBL driver
//! refuses the program on a controller whose `$30` differs (on `$30=255`, "25 %" would be 98 %).
//!
//! **Accuracy.** The 5 µm criterion below is about the *commanded* path. GRBL cuts each arc as
//! chords that stay within `$12` (0.002 mm by default) inside the curve, and a real machine moves
//! in steps of `1/$100` mm: keep `$12` at most 0.002 mm (0.001 recommended).
//!
//! **Coordinates.** Plan units are mm. The machine's y axis points up (away from the operator on
//! most cutters, origin front-left). [`Mapping::for_plan`] puts the lower-left corner of the
//! bounding box of the cuts (as cut, i.e. dilated) at `origin_mm` (default 0, 0): an SVG (y down)
//! is flipped about that box, so the picture comes out as seen on screen, not mirrored; a DXF
//! (y up) is only moved. Flipping reverses the sense of every arc, so a positive bulge in the
//! machine frame is counter-clockwise (`G3`) there, whatever it was in the file. The gauge
//! ([`gauge_program`]) is drawn y-up already and is only moved: its spiral centre goes to
//! `--at-mm`.
//!
//! **Numbers.** Coordinates and centre offsets are written to 0.1 µm (4 decimals, trailing
//! zeros dropped), computed on that grid so that `I`/`J` lead exactly from the written start to
//! the written centre: the written geometry is within 0.2 µm of the typed one, and an arc's end
//! radius matches its start radius far inside GRBL's 5 µm check (error 33). A segment whose
//! written ends coincide is dropped (GRBL would read an arc with equal ends as a full circle),
//! an arc of more than half a turn is split in two, an arc whose sagitta is under 0.05 µm is
//! written as a line, and an arc of radius over 2 m (near-straight biarcs from splines, Béziers
//! or DXF bulges) as lines whose sagitta is at most 0.25 µm: GRBL's float32 arc maths loses
//! micrometres at such radii. Coordinates beyond 10 m are refused. Lines stay under 70 characters (GRBL's line buffer is 80, and a
//! character-counting streamer needs lines well under its 128-byte receive buffer); comments are
//! plain ASCII without parentheses, GRBL's realtime characters (`?`, `!`, `~`), `;` or `$`, and
//! long header text is wrapped onto more lines rather than cut off.
//!
//! **Cutting order** ([`cut_order`]): a contour is cut only after every contour inside it, so a
//! part's holes (and any island in a hole, and the island's own holes) are cut before the outline
//! that would free it, and nothing drops out before it is finished. Among the contours that may
//! be cut next, the next is the one with a vertex nearest the head (greedy nearest neighbour),
//! and it starts at that vertex. The candidates' bounding boxes are kept in an R-tree (`rstar`),
//! updated as contours are cut and become free, and searched in order of distance until a box is
//! farther than the best vertex found: about O(n log n + V) for n contours of V vertices in all
//! (`cargo bench -p kerfmeter-plan --bench gcode`). The worst case is a large contour whose box
//! holds the head at every step (a comb part with many holes): its V vertices are scanned each
//! time, O(n·V).
//!
//! The cutter twin (a GRBL-speaking simulated cutter, written separately) is to replay this text
//! end to end; the tests here check the typed program and the written numbers.

use std::fmt::Write as _;

use cavalier_contours::polyline::{PlineCreation, PlineSource, PlineSourceMut};
use serde::Serialize;

use crate::error::{PlanError, Result};
use crate::gauge::GaugeDrawing;
use crate::geom::{ArcGeom, Pline, V2, arc_geom, v2};
use crate::outcome::CutPath;
use crate::profile::{CutSettings, Profile};
use kerfmeter_grbl::{realtime, settings};

mod order;

pub use order::cut_order;

/// The `S` value of full power when not told otherwise (GRBL's default `$30`).
pub const DEFAULT_S_MAX: f64 = settings::DEFAULT_MAX_POWER_S;
/// The resolution of the written coordinates, per mm (0.1 µm).
const UNITS_PER_MM: f64 = 10_000.0;
/// Arcs whose sagitta is below this are written as lines, mm.
const MIN_SAGITTA_MM: f64 = 5e-5;
/// Arcs of a larger radius are written as chords (GRBL computes arcs in float32: at 125 m
/// radius its angle step alone moves the path by ~8 µm), mm.
const MAX_ARC_RADIUS_MM: f64 = 2_000.0;
/// The largest sagitta of those chords, mm (0.25 µm).
const CHORD_SAGITTA_MM: f64 = 2.5e-4;
/// Comments are cut to this many characters (the line stays within GRBL's buffer).
const MAX_COMMENT_CHARS: usize = 60;
/// The modal state every program sets before it moves: XY plane (`G17`: a `G18`/`G19` left by a
/// startup block or an interrupted job would cut arcs in another plane), mm, absolute, feed in
/// units per minute (`G94`: under `G93` every `G1` is refused).
const PREAMBLE: &str = "G17 G21 G90 G94\n";
/// The header comment that declares the `S` of full power a program assumes:
/// `(S_MAX=1000 must equal GRBL setting 30)`. The GRBL driver reads it and refuses a program
/// whose value differs from the controller's `$30` (one definition, in GRBL's table).
pub use kerfmeter_grbl::S_MAX_TAG;

/// One operation of a program. Coordinates are machine mm.
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    /// A comment: `(…)`.
    Comment(String),
    /// A rapid move, always with the laser off: `G0`.
    Travel {
        /// Where to.
        to: V2,
    },
    /// The feed for the cut moves that follow: `F`.
    Feed {
        /// mm/min.
        feed_mm_per_min: f64,
    },
    /// Laser on, dynamic power: `M4 S`.
    LaserOn {
        /// The `S` value.
        power_s: f64,
    },
    /// A straight cut: `G1`.
    Line {
        /// Where to.
        to: V2,
    },
    /// A circular arc cut: `G2` (clockwise) or `G3`, centre given by `I`/`J`.
    Arc {
        /// Where to.
        to: V2,
        /// The centre.
        center: V2,
        /// Clockwise seen from above (y up).
        clockwise: bool,
    },
    /// Laser off: `M5`.
    LaserOff,
    /// Program end: `M2`.
    End,
}

/// A G-code program: header comments and operations.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// Header comment lines.
    pub header: Vec<String>,
    /// The operations, after the preamble (`G17 G21 G90 G94`).
    pub ops: Vec<Op>,
}

/// A straight (`bulge == 0`) or arc segment as the laser traces it: start, end, bulge (machine
/// mm, positive = counter-clockwise).
pub type Traced = (V2, V2, f64);

/// Document mm → machine mm (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mapping {
    /// Whether the y axis is flipped (SVG).
    pub flip_y: bool,
    /// Added after the flip, mm.
    pub offset_mm: [f64; 2],
}

impl Mapping {
    /// The lower-left corner of the bounding box of `plines` at `origin_mm`, flipped about the
    /// box when the document's y axis points down.
    pub fn for_plan<'a>(
        plines: impl IntoIterator<Item = &'a Pline>,
        y_down: bool,
        origin_mm: [f64; 2],
    ) -> Mapping {
        let (mut lo, mut hi) = (v2(f64::MAX, f64::MAX), v2(f64::MIN, f64::MIN));
        for p in plines {
            if let Some(e) = p.extents() {
                lo = v2(lo.x.min(e.min_x), lo.y.min(e.min_y));
                hi = v2(hi.x.max(e.max_x), hi.y.max(e.max_y));
            }
        }
        if lo.x > hi.x {
            (lo, hi) = (v2(0.0, 0.0), v2(0.0, 0.0));
        }
        let y = if y_down { hi.y } else { -lo.y };
        Mapping {
            flip_y: y_down,
            offset_mm: [origin_mm[0] - lo.x, origin_mm[1] + y],
        }
    }

    /// Map a point.
    pub fn apply(&self, p: V2) -> V2 {
        let y = if self.flip_y { -p.y } else { p.y };
        v2(p.x + self.offset_mm[0], y + self.offset_mm[1])
    }

    /// Map a machine point back to the document.
    pub fn invert(&self, q: V2) -> V2 {
        let y = q.y - self.offset_mm[1];
        v2(q.x - self.offset_mm[0], if self.flip_y { -y } else { y })
    }

    /// Map a contour (a flip reverses the sense of its arcs).
    pub fn pline(&self, p: &Pline) -> Pline {
        let mut out = Pline::with_capacity(p.vertex_count(), p.is_closed());
        for v in p.iter_vertexes() {
            let q = self.apply(v2(v.x, v.y));
            let bulge = if self.flip_y { -v.bulge } else { v.bulge };
            out.add(q.x, q.y, bulge);
        }
        out
    }
}

/// The bounding box `[[min_x, min_y], [max_x, max_y]]` of `plines` (arcs included) once mapped
/// by `mapping`, mm; `None` when they have no extent.
pub fn placed_box<'a>(
    plines: impl IntoIterator<Item = &'a Pline>,
    mapping: &Mapping,
) -> Option<[[f64; 2]; 2]> {
    let mut out: Option<[[f64; 2]; 2]> = None;
    for p in plines {
        let Some(e) = p.extents() else { continue };
        for corner in [v2(e.min_x, e.min_y), v2(e.max_x, e.max_y)] {
            let q = mapping.apply(corner);
            let [lo, hi] = out.get_or_insert([[q.x, q.y], [q.x, q.y]]);
            *lo = [lo[0].min(q.x), lo[1].min(q.y)];
            *hi = [hi[0].max(q.x), hi[1].max(q.y)];
        }
    }
    out
}

/// A contour to cut: machine mm, closed.
#[derive(Debug, Clone)]
pub struct Job {
    /// The contour.
    pub pline: Pline,
    /// Its name, for the comment before it.
    pub label: String,
    /// How to cut it.
    pub settings: CutSettings,
}

/// Where a program came from, for its header.
#[derive(Debug, Clone, Default)]
pub struct Provenance {
    /// The input (a file name, or "gauge …").
    pub source: String,
    /// The kerf applied, in words ("200 um", "none: the gauge measures it").
    pub kerf: String,
}

/// How to write a program.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GcodeOptions {
    /// The `S` of full power (GRBL's `$30`).
    pub s_max: f64,
    /// Where the lower-left corner of the plan goes (plans) or the spiral centre (the gauge), mm.
    pub origin_mm: [f64; 2],
}

impl Default for GcodeOptions {
    fn default() -> Self {
        GcodeOptions {
            s_max: DEFAULT_S_MAX,
            origin_mm: [0.0, 0.0],
        }
    }
}

impl GcodeOptions {
    /// Check the values.
    pub fn check(&self) -> Result<()> {
        if !(self.s_max.is_finite() && self.s_max >= 1.0 && self.s_max <= 100_000.0) {
            return Err(PlanError::InvalidArgument(format!(
                "the maximum S ($30) must be 1 to 100000, got {}",
                kerfmeter_protocol::Shown(self.s_max)
            )));
        }
        if !self
            .origin_mm
            .iter()
            .all(|x| x.is_finite() && x.abs() <= MAX_COORDINATE_MM)
        {
            return Err(PlanError::InvalidArgument(format!(
                "the placement must be finite mm within ±{MAX_COORDINATE_MM}, got {:?}",
                self.origin_mm
            )));
        }
        Ok(())
    }
}

/// The program for dilated cuts (document mm, y down for SVG): settings from `profile`, placed
/// and ordered as the module doc says. Also the mapping used.
pub fn plan_program(
    cuts: &[CutPath],
    y_down: bool,
    profile: &Profile,
    options: &GcodeOptions,
    provenance: &Provenance,
) -> Result<(Program, Mapping)> {
    options.check()?;
    if cuts.is_empty() {
        return Err(PlanError::InvalidArgument(
            "the plan has no closed cut contours: nothing to cut".into(),
        ));
    }
    let settings = profile.resolve(cuts)?;
    let mapping = Mapping::for_plan(cuts.iter().map(|c| &c.pline), y_down, options.origin_mm);
    check_size(cuts, &mapping)?;
    let jobs = cuts
        .iter()
        .zip(settings)
        .map(|(c, settings)| Job {
            pline: mapping.pline(&c.pline),
            label: format!("{} ({})", c.label, c.group),
            settings,
        })
        .collect();
    let placed = if y_down {
        "SVG y flipped, box lower-left at"
    } else {
        "box lower-left at"
    };
    let header = header_lines(provenance, &profile.entries(), placed, options);
    Ok((build(cut_order(jobs)?, header, options.s_max), mapping))
}

/// Largest machine coordinate accepted, mm (a sanity bound: 10 m, beyond any laser's bed).
const MAX_COORDINATE_MM: f64 = 10_000.0;

/// Refuse a plan that does not fit any cutter once placed (it would also overflow the written
/// numbers).
fn check_size(cuts: &[CutPath], mapping: &Mapping) -> Result<()> {
    for c in cuts {
        let Some(e) = c.pline.extents() else { continue };
        for corner in [v2(e.min_x, e.min_y), v2(e.max_x, e.max_y)] {
            let q = mapping.apply(corner);
            if !(q.x.abs() <= MAX_COORDINATE_MM && q.y.abs() <= MAX_COORDINATE_MM) {
                return Err(PlanError::InvalidArgument(format!(
                    "{} reaches ({:.1}, {:.1}) mm on the machine, beyond any cutter's bed: check the plan's units",
                    c.label, q.x, q.y
                )));
            }
        }
    }
    Ok(())
}

/// The gauge drawing's cuts (y up, mm): the prong holes, the spiral, and the test-piece parts,
/// with their names. Its engraved label is not cut (engraving is not written as G-code).
pub fn gauge_cuts(d: &GaugeDrawing) -> Vec<(String, Pline)> {
    let mut out = Vec::new();
    for (k, (c, r)) in d.holes.iter().enumerate() {
        let mut hole = Pline::new_closed();
        hole.add(c.x + r, c.y, 1.0);
        hole.add(c.x - r, c.y, 1.0);
        out.push((format!("gauge hole {}", k + 1), hole));
    }
    out.push(("gauge spiral".to_string(), d.spiral.clone()));
    out.extend(d.test_piece.iter().cloned());
    out
}

/// The program for the gauge drawing, not dilated (the kerf is what it measures), with its spiral
/// centre at `options.origin_mm`. Also the mapping used.
pub fn gauge_program(
    d: &GaugeDrawing,
    settings: &CutSettings,
    options: &GcodeOptions,
    provenance: &Provenance,
) -> Result<(Program, Mapping)> {
    options.check()?;
    settings.check("the gauge's cut settings")?;
    let mapping = Mapping {
        flip_y: false,
        offset_mm: [
            options.origin_mm[0] - d.center.x,
            options.origin_mm[1] - d.center.y,
        ],
    };
    let jobs = gauge_cuts(d)
        .into_iter()
        .map(|(label, p)| Job {
            pline: mapping.pline(&p),
            label,
            settings: *settings,
        })
        .collect();
    let header = header_lines(
        provenance,
        &[settings.to_string()],
        "spiral centre at",
        options,
    );
    Ok((build(cut_order(jobs)?, header, options.s_max), mapping))
}

/// What the first comment of every G-code program this tool writes says after the tool's name
/// and version: how such a program is told from anyone else's before it is replaced.
pub const HEADER_MARKER: &str = "G-code for GRBL 1.1 laser mode";

/// The header comments; `placed` says what goes to `options.origin_mm`. A long source name and
/// each settings entry get lines of their own, so that nothing is cut off.
fn header_lines(
    provenance: &Provenance,
    settings: &[String],
    placed: &str,
    options: &GcodeOptions,
) -> Vec<String> {
    let mut lines = vec![format!(
        "kerfmeter {} {HEADER_MARKER}",
        env!("CARGO_PKG_VERSION")
    )];
    lines.extend(wrapped("source: ", &provenance.source));
    lines.extend(wrapped("kerf applied: ", &provenance.kerf));
    for entry in settings {
        lines.extend(wrapped("settings: ", entry));
    }
    lines.extend([
        format!(
            "{S_MAX_TAG}{} must equal GRBL setting {}",
            fmt_plain(options.s_max),
            settings::MAX_POWER_S
        ),
        format!("needs GRBL setting {}=1 laser mode", settings::LASER_MODE),
        format!(
            "arc tolerance setting {} at most 0.002 mm, 0.001 better",
            settings::ARC_TOLERANCE_MM
        ),
        format!(
            "{placed} X{} Y{} mm",
            fmt_plain(options.origin_mm[0]),
            fmt_plain(options.origin_mm[1])
        ),
    ]);
    lines
}

/// `prefix` and `text` as comment lines of at most [`MAX_COMMENT_CHARS`], continued lines
/// indented.
fn wrapped(prefix: &str, text: &str) -> Vec<String> {
    let chars: Vec<char> = format!("{prefix}{text}").chars().collect();
    let mut lines = vec![chars.iter().take(MAX_COMMENT_CHARS).collect::<String>()];
    for chunk in chars
        .get(MAX_COMMENT_CHARS..)
        .unwrap_or_default()
        .chunks(MAX_COMMENT_CHARS - 2)
    {
        lines.push(format!("  {}", chunk.iter().collect::<String>()));
    }
    lines
}

/// `x` with up to 4 decimals, trailing zeros dropped.
fn fmt_plain(x: f64) -> String {
    fmt_units(to_units(x))
}

/// The program cutting `jobs` in the order given.
pub fn build(jobs: Vec<Job>, header: Vec<String>, s_max: f64) -> Program {
    let mut ops = vec![Op::LaserOff];
    for job in jobs {
        let s = job.settings;
        let Some(start) = job.pline.iter_vertexes().next().map(|v| v2(v.x, v.y)) else {
            continue;
        };
        ops.push(Op::Comment(format!("{s}: {}", job.label)));
        ops.push(Op::Travel { to: start });
        ops.push(Op::Feed {
            feed_mm_per_min: s.feed_mm_per_min,
        });
        ops.push(Op::LaserOn {
            power_s: s.power_percent / 100.0 * s_max,
        });
        for _ in 0..s.passes {
            contour_ops(&job.pline, &mut ops);
        }
        ops.push(Op::LaserOff);
    }
    ops.push(Op::End);
    Program { header, ops }
}

/// The cut moves around a closed contour from its first vertex (see the module doc for what is
/// dropped, split or straightened).
fn contour_ops(p: &Pline, ops: &mut Vec<Op>) {
    let n = p.vertex_count();
    for i in 0..n {
        let (a, b) = (p.at(i), p.at((i + 1) % n));
        segment_ops(v2(a.x, a.y), v2(b.x, b.y), a.bulge, ops);
    }
}

fn segment_ops(from: V2, to: V2, bulge: f64, ops: &mut Vec<Op>) {
    let Some(arc) = arc_geom(from, to, bulge) else {
        if grid(from) != grid(to) {
            ops.push(Op::Line { to });
        }
        return;
    };
    if arc.sweep.abs() > std::f64::consts::PI {
        let mid_angle = arc.start_angle + arc.sweep / 2.0;
        let mid = arc.center + v2(mid_angle.cos(), mid_angle.sin()).scale(arc.radius);
        let half = (arc.sweep / 8.0).tan();
        segment_ops(from, mid, half, ops);
        segment_ops(mid, to, half, ops);
        return;
    }
    if grid(from) == grid(to) {
        return;
    }
    let sagitta = arc.radius * (1.0 - (arc.sweep / 2.0).cos());
    if sagitta < MIN_SAGITTA_MM {
        ops.push(Op::Line { to });
    } else if arc.radius > MAX_ARC_RADIUS_MM {
        chord_ops(from, to, &arc, ops);
    } else {
        ops.push(Op::Arc {
            to,
            center: arc.center,
            clockwise: bulge < 0.0,
        });
    }
}

/// A large-radius arc as chords whose sagitta is at most [`CHORD_SAGITTA_MM`].
fn chord_ops(from: V2, to: V2, arc: &ArcGeom, ops: &mut Vec<Op>) {
    let max_sweep = 2.0 * (1.0 - CHORD_SAGITTA_MM / arc.radius).acos();
    let n = (arc.sweep.abs() / max_sweep).ceil().clamp(1.0, 1e6) as usize;
    let mut last = grid(from);
    for k in 1..n {
        let angle = arc.start_angle + arc.sweep * k as f64 / n as f64;
        let p = arc.center + v2(angle.cos(), angle.sin()).scale(arc.radius);
        if grid(p) != last {
            ops.push(Op::Line { to: p });
            last = grid(p);
        }
    }
    if grid(to) != last {
        ops.push(Op::Line { to });
    }
}

/// A coordinate on the written grid.
fn to_units(x: f64) -> i64 {
    (x * UNITS_PER_MM).round() as i64
}

fn grid(p: V2) -> (i64, i64) {
    (to_units(p.x), to_units(p.y))
}

/// A grid value as text: up to 4 decimals, trailing zeros dropped, no `-0`.
fn fmt_units(u: i64) -> String {
    let mut s = String::from(if u < 0 { "-" } else { "" });
    crate::decimal::write_scaled(u.unsigned_abs(), 4, |part| s.push_str(part));
    s
}

/// A comment's text as GRBL takes it: printable ASCII, no parentheses, not too long. GRBL acts
/// on its realtime characters (`?`, `!`, `~`) even inside a comment, and a sender may stop at `;`
/// or take `$` for a system command: those, and anything not ASCII, become `_`.
fn comment_text(s: &str) -> String {
    s.replace('%', "pct")
        .chars()
        .map(|c| match c {
            '(' => '[',
            ')' => ']',
            'µ' => 'u',
            c if realtime::PRINTABLE.contains(&c) => '_',
            ';' | '$' => '_',
            c if c.is_ascii_graphic() || c == ' ' => c,
            _ => '_',
        })
        .take(MAX_COMMENT_CHARS)
        .collect()
}

/// How much a program cuts and travels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ProgramStats {
    /// Contours cut (each once, whatever its passes).
    pub contours: usize,
    /// Length cut, all passes, mm.
    pub cut_mm: f64,
    /// Length travelled with the laser off, from the origin, mm.
    pub travel_mm: f64,
}

impl Program {
    /// How much the program cuts and travels.
    pub fn stats(&self) -> ProgramStats {
        let mut stats = ProgramStats::default();
        let mut head = v2(0.0, 0.0);
        for op in &self.ops {
            match op {
                Op::Travel { to } => {
                    stats.contours += 1;
                    stats.travel_mm += (*to - head).length();
                    head = *to;
                }
                Op::Line { to } => {
                    stats.cut_mm += (*to - head).length();
                    head = *to;
                }
                Op::Arc {
                    to,
                    center,
                    clockwise,
                } => {
                    let bulge = arc_bulge(head, *to, *center, *clockwise);
                    let sweep = 4.0 * bulge.atan();
                    stats.cut_mm += (head - *center).length() * sweep.abs();
                    head = *to;
                }
                _ => {}
            }
        }
        stats
    }

    /// The program as G-code text (see the module doc).
    pub fn to_text(&self) -> String {
        let mut out = String::with_capacity(self.ops.len() * 24 + 512);
        for h in &self.header {
            let _ = writeln!(out, "({})", comment_text(h));
        }
        out.push_str(PREAMBLE);
        let mut head = (0i64, 0i64);
        for op in &self.ops {
            match op {
                Op::Comment(c) => {
                    let _ = writeln!(out, "({})", comment_text(c));
                }
                Op::Travel { to } => head = move_line(&mut out, "G0", *to),
                Op::Feed { feed_mm_per_min } => {
                    let _ = writeln!(out, "F{}", fmt_plain(*feed_mm_per_min));
                }
                Op::LaserOn { power_s } => {
                    let _ = writeln!(out, "M4 S{}", fmt_plain(*power_s));
                }
                Op::Line { to } => head = move_line(&mut out, "G1", *to),
                Op::Arc {
                    to,
                    center,
                    clockwise,
                } => {
                    let (c, t) = (grid(*center), grid(*to));
                    let _ = writeln!(
                        out,
                        "{} X{} Y{} I{} J{}",
                        if *clockwise { "G2" } else { "G3" },
                        fmt_units(t.0),
                        fmt_units(t.1),
                        fmt_units(c.0.saturating_sub(head.0)),
                        fmt_units(c.1.saturating_sub(head.1))
                    );
                    head = t;
                }
                Op::LaserOff => out.push_str("M5\n"),
                Op::End => out.push_str("M2\n"),
            }
        }
        out
    }

    /// Replay the operations: the cut runs (one per laser-on stretch, the segments the laser
    /// traces), or what is wrong — a travel with the laser on, a cut with it off, a program that
    /// does not start or end with it off.
    pub fn traced(&self) -> std::result::Result<Vec<Vec<Traced>>, String> {
        if self.ops.first() != Some(&Op::LaserOff) {
            return Err("the program does not start with the laser off".into());
        }
        let (mut on, mut head) = (false, v2(0.0, 0.0));
        let mut runs: Vec<Vec<Traced>> = Vec::new();
        for (k, op) in self.ops.iter().enumerate() {
            match op {
                Op::Travel { to } if on => {
                    return Err(format!("op {k}: a travel to {to:?} with the laser on"));
                }
                Op::Travel { to } => head = *to,
                Op::LaserOn { .. } => {
                    on = true;
                    runs.push(Vec::new());
                }
                Op::LaserOff | Op::End => on = false,
                Op::Line { .. } | Op::Arc { .. } if !on => {
                    return Err(format!("op {k}: a cut move with the laser off"));
                }
                Op::Line { to } => {
                    runs.last_mut().expect("on").push((head, *to, 0.0));
                    head = *to;
                }
                Op::Arc {
                    to,
                    center,
                    clockwise,
                } => {
                    let bulge = arc_bulge(head, *to, *center, *clockwise);
                    runs.last_mut().expect("on").push((head, *to, bulge));
                    head = *to;
                }
                Op::Comment(_) | Op::Feed { .. } => {}
            }
        }
        if on || self.ops.last() != Some(&Op::End) {
            return Err("the program does not end with the laser off".into());
        }
        Ok(runs)
    }
}

/// `G0`/`G1` to `to`; the written point.
fn move_line(out: &mut String, g: &str, to: V2) -> (i64, i64) {
    let t = grid(to);
    let _ = writeln!(out, "{g} X{} Y{}", fmt_units(t.0), fmt_units(t.1));
    t
}

/// The bulge of the arc from `from` to `to` about `center` in the given sense.
pub fn arc_bulge(from: V2, to: V2, center: V2, clockwise: bool) -> f64 {
    let a0 = (from.y - center.y).atan2(from.x - center.x);
    let a1 = (to.y - center.y).atan2(to.x - center.x);
    let tau = std::f64::consts::TAU;
    let mut sweep = (a1 - a0).rem_euclid(tau);
    if clockwise {
        sweep -= tau;
    }
    (sweep / 4.0).tan()
}

#[cfg(test)]
mod tests;
