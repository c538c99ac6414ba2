//! Drawing the spiral gauge: the CLI's `gauge`, the server's `gauge` and Python's `gauge()` are
//! one [`GaugeRequest`] (the server's params deserialized straight into it) drawn by [`draw`],
//! with one [`GaugeReport`]. As G-code (the CLI only) the gauge is not dilated (the kerf is what
//! it measures) and must be cut with the job's own settings, which the request must carry.

use std::fmt;
use std::path::PathBuf;

use kerfmeter::protocol::advice::Advice;
use kerfmeter::protocol::{GaugeGeometry, JamDirection};
use kerfmeter_plan::gauge::{self, GaugeDrawing, GaugeOptions, TestPieceSpec};
use kerfmeter_plan::gcode::{DEFAULT_S_MAX, GcodeOptions, ProgramStats, Provenance, gauge_program};
use kerfmeter_plan::profile::CutSettings;
use kerfmeter_plan::{PlanError, PlanFormat};
use serde::{Deserialize, Serialize};

use crate::Error;

/// A first try for cutting the gauge when no job settings exist yet (suggested, never used
/// silently): slow and at full power, one pass.
pub const GAUGE_SETTINGS: CutSettings = CutSettings {
    feed_mm_per_min: 300.0,
    power_percent: 100.0,
    passes: 1,
};

/// What the gauge is drawn as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GaugeFormat {
    /// SVG.
    #[default]
    Svg,
    /// DXF.
    Dxf,
    /// G-code for GRBL 1.1 laser mode.
    Gcode,
}

impl From<PlanFormat> for GaugeFormat {
    fn from(f: PlanFormat) -> Self {
        match f {
            PlanFormat::Svg => GaugeFormat::Svg,
            PlanFormat::Dxf => GaugeFormat::Dxf,
        }
    }
}

impl fmt::Display for GaugeFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            GaugeFormat::Svg => "SVG",
            GaugeFormat::Dxf => "DXF",
            GaugeFormat::Gcode => "G-code",
        })
    }
}

/// Sense in which the hub turns to close the gauge's gap, seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JamSense {
    /// Clockwise.
    #[default]
    Cw,
    /// Counter-clockwise.
    Ccw,
}

impl From<JamSense> for JamDirection {
    fn from(d: JamSense) -> Self {
        match d {
            JamSense::Cw => JamDirection::Clockwise,
            JamSense::Ccw => JamDirection::CounterClockwise,
        }
    }
}

/// Where and how the gauge's G-code is cut (not a parameter of the server's `gauge`: the
/// gauge's G-code is cut by a job).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GaugeCut {
    /// Where the spiral centre goes on the machine, mm (`None`: the drawing's lower-left corner
    /// at 0,0).
    pub at_mm: Option<[f64; 2]>,
    /// How to cut it (required for G-code: the job's own settings).
    pub settings: Option<CutSettings>,
    /// The S of full power ($30).
    pub s_max: f64,
}

/// The gauge to draw: its geometry (the paper's by default), a test piece, a label.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GaugeRequest {
    /// SVG, DXF or G-code.
    pub format: GaugeFormat,
    /// Spiral pitch c, µm of radius per degree of turn.
    pub pitch_um_per_deg: f32,
    /// Mean radius of the spiral, mm.
    pub radius_mm: f32,
    /// Radius of the device's prongs, mm (checked against the holes).
    pub prong_radius_mm: f32,
    /// Radius of the two prong holes as drawn, mm.
    pub hole_radius_mm: f32,
    /// Distance of each hole's centre from the gauge centre, mm.
    pub hole_distance_mm: f32,
    /// Sense in which the device turns the hub to close the gap, seen from above.
    pub jam_direction: JamSense,
    /// Rotation past which the inset disengages, degrees.
    pub disengage_deg: f32,
    /// Add the paper's one-finger box-joint test piece, dilated by `test_piece_kerf_um`.
    pub test_piece: bool,
    /// Sheet thickness for the test piece, mm.
    pub thickness_mm: f64,
    /// Finger (and slot) width of the test piece, mm.
    pub finger_width_mm: f64,
    /// Kerf to dilate the test piece by, µm.
    pub test_piece_kerf_um: Option<f64>,
    /// Add an engraved label naming the geometry and the jam direction (not in G-code).
    pub label: bool,
    /// G-code only: where and how it is cut.
    #[serde(skip)]
    pub cut: GaugeCut,
}

impl Default for GaugeRequest {
    fn default() -> Self {
        let g = GaugeGeometry::PAPER;
        Self {
            format: GaugeFormat::Svg,
            pitch_um_per_deg: g.pitch_um_per_deg,
            radius_mm: g.radius_mm,
            prong_radius_mm: g.prong_radius_mm,
            hole_radius_mm: g.hole_radius_mm,
            hole_distance_mm: g.hole_distance_mm,
            jam_direction: JamSense::Cw,
            disengage_deg: g.disengage_deg,
            test_piece: false,
            thickness_mm: 4.0,
            finger_width_mm: 6.3,
            test_piece_kerf_um: None,
            label: false,
            cut: GaugeCut {
                s_max: DEFAULT_S_MAX,
                ..GaugeCut::default()
            },
        }
    }
}

impl GaugeRequest {
    /// The gauge geometry asked for.
    pub fn geometry(&self) -> GaugeGeometry {
        GaugeGeometry {
            pitch_um_per_deg: self.pitch_um_per_deg,
            radius_mm: self.radius_mm,
            prong_radius_mm: self.prong_radius_mm,
            hole_radius_mm: self.hole_radius_mm,
            hole_distance_mm: self.hole_distance_mm,
            jam_direction: self.jam_direction.into(),
            disengage_deg: self.disengage_deg,
        }
    }

    fn options(&self) -> Result<GaugeOptions, Error> {
        let test_piece = match (self.test_piece, self.test_piece_kerf_um) {
            (false, None) => None,
            (false, Some(_)) => {
                return Err(invalid(format!(
                    "{} is the kerf of the test piece, which is drawn only with {}: add it, or leave the kerf out",
                    Advice::Param("test_piece_kerf_um"),
                    Advice::Param("test_piece")
                )));
            }
            (true, None) => {
                return Err(invalid(format!(
                    "{} needs {} (the kerf to dilate it by)",
                    Advice::Param("test_piece"),
                    Advice::Param("test_piece_kerf_um")
                )));
            }
            (true, Some(kerf_um)) => Some(TestPieceSpec {
                thickness_mm: self.thickness_mm,
                finger_width_mm: self.finger_width_mm,
                kerf_um,
            }),
        };
        Ok(GaugeOptions {
            test_piece,
            label: self.label,
        })
    }
}

/// A bad argument of the plan crate's kind.
fn invalid(message: String) -> Error {
    PlanError::InvalidArgument(message).into()
}

/// What the gauge is: its file (when written), format, geometry and how it is cut.
#[derive(Debug, Clone, Serialize)]
pub struct GaugeReport {
    /// The file written (none when the drawing is sent back instead).
    #[serde(
        serialize_with = "crate::lossy_path::option",
        skip_serializing_if = "Option::is_none"
    )]
    pub output: Option<PathBuf>,
    /// Its format.
    pub format: GaugeFormat,
    /// Page size (width, height), mm.
    pub page_mm: [f64; 2],
    /// Spiral pitch, µm per degree.
    pub pitch_um_per_deg: f64,
    /// Spiral pitch c, mm per radian.
    pub pitch_mm_per_rad: f64,
    /// Spiral radius at φ = 0 (a), mm.
    pub start_radius_mm: f64,
    /// Spiral radius at φ = 2π (a + 2πc), mm; the radial step is the difference.
    pub end_radius_mm: f64,
    /// Arcs approximating the spiral.
    pub spiral_arcs: usize,
    /// Largest distance between the drawn spiral and the true one, µm.
    pub max_deviation_um: f64,
    /// Hole radius as drawn, mm.
    pub hole_radius_mm: f64,
    /// Hole centres' distance from the gauge centre, mm.
    pub hole_distance_mm: f64,
    /// Jam direction, seen from above.
    pub jam_direction: JamSense,
    /// The test piece, if added.
    pub test_piece: Option<TestPieceSpec>,
    /// Whether a label was engraved.
    pub label: bool,
    /// The G-code, when that was written.
    pub gcode: Option<GaugeGcode>,
}

/// The gauge's G-code: where and how it is cut.
#[derive(Debug, Clone, Serialize)]
pub struct GaugeGcode {
    /// The spiral centre on the machine, mm.
    pub at_mm: [f64; 2],
    /// How it is cut.
    pub settings: CutSettings,
    /// The S of full power ($30).
    pub s_max: f64,
    /// What the program cuts and travels.
    pub program: ProgramStats,
}

/// An `f32` as the decimal it was written as (2.774, not 2.7739999294).
fn clean(x: f32) -> f64 {
    x.to_string().parse().unwrap_or(f64::from(x))
}

/// Draw the gauge `req` asks for, without writing it: the file's content and the report (its
/// `output` none; the caller that writes it sets it).
pub fn draw(req: &GaugeRequest) -> Result<(Vec<u8>, GaugeReport), Error> {
    let geometry = req.geometry();
    let options = req.options()?;
    let drawing = gauge::build(&geometry, &options)?;
    let (bytes, gcode) = match req.format {
        GaugeFormat::Gcode => {
            let (text, gcode) = gauge_gcode(&req.cut, &drawing)?;
            (text.into_bytes(), Some(gcode))
        }
        _ if req.cut.at_mm.is_some()
            || req.cut.settings.is_some()
            || req.cut.s_max != DEFAULT_S_MAX =>
        {
            return Err(invalid(format!(
                "{}, {} and the cut settings are for G-code output (a .gcode file)",
                Advice::Param("at_mm"),
                Advice::Param("s_max")
            )));
        }
        GaugeFormat::Svg => (gauge::to_svg(&drawing).into_bytes(), None),
        GaugeFormat::Dxf => (gauge::to_dxf(&drawing)?, None),
    };
    let report = report(req, &geometry, &drawing, options.test_piece, gcode);
    Ok((bytes, report))
}

/// The report of `drawing`.
fn report(
    req: &GaugeRequest,
    geometry: &GaugeGeometry,
    drawing: &GaugeDrawing,
    test_piece: Option<TestPieceSpec>,
    gcode: Option<GaugeGcode>,
) -> GaugeReport {
    let arcs = drawing
        .spiral
        .vertex_data
        .iter()
        .filter(|v| v.bulge != 0.0)
        .count();
    GaugeReport {
        output: None,
        format: req.format,
        page_mm: drawing.page_mm,
        pitch_um_per_deg: clean(geometry.pitch_um_per_deg),
        pitch_mm_per_rad: drawing.pitch_mm_per_rad,
        start_radius_mm: drawing.start_radius_mm,
        end_radius_mm: drawing.start_radius_mm + std::f64::consts::TAU * drawing.pitch_mm_per_rad,
        spiral_arcs: arcs,
        max_deviation_um: drawing.max_deviation_mm * 1e3,
        hole_radius_mm: clean(geometry.hole_radius_mm),
        hole_distance_mm: clean(geometry.hole_distance_mm),
        jam_direction: req.jam_direction,
        test_piece,
        label: req.label,
        gcode,
    }
}

/// The gauge's G-code text, and what it cuts where.
fn gauge_gcode(cut: &GaugeCut, drawing: &GaugeDrawing) -> Result<(String, GaugeGcode), Error> {
    let Some(settings) = cut.settings else {
        let (feed, power) = (
            Advice::Param("feed_mm_per_min"),
            Advice::Param("power_percent"),
        );
        return Err(invalid(format!(
            "say how to cut the gauge: {feed} and {power} (and {}) as the job will be cut, since the kerf it measures depends on them (a first try: {feed} {} {power} {})",
            Advice::Param("passes"),
            GAUGE_SETTINGS.feed_mm_per_min,
            GAUGE_SETTINGS.power_percent
        )));
    };
    let at_mm = cut.at_mm.unwrap_or([drawing.center.x, drawing.center.y]);
    let options = GcodeOptions {
        s_max: cut.s_max,
        origin_mm: at_mm,
    };
    let g = &drawing.geometry;
    let provenance = Provenance {
        source: format!(
            "gauge, pitch {} um/deg, radius {} mm",
            clean(g.pitch_um_per_deg),
            clean(g.radius_mm)
        ),
        kerf: "none: the gauge measures it".into(),
    };
    let (program, _) = gauge_program(drawing, &settings, &options, &provenance)?;
    let gcode = GaugeGcode {
        at_mm,
        settings,
        s_max: options.s_max,
        program: program.stats(),
    };
    Ok((program.to_text(), gcode))
}

impl fmt::Display for GaugeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let output = self.output.as_deref().unwrap_or("(not written)".as_ref());
        writeln!(
            f,
            "wrote {} ({}, {:.1} × {:.1} mm)",
            output.display(),
            self.format,
            self.page_mm[0],
            self.page_mm[1]
        )?;
        writeln!(
            f,
            "spiral r(φ) = {:.4} + {:.6}·φ mm (c = {} µm/°), one turn closed by a radial step of {:.4} mm, as {} arcs within {:.3} µm",
            self.start_radius_mm,
            self.pitch_mm_per_rad,
            self.pitch_um_per_deg,
            self.end_radius_mm - self.start_radius_mm,
            self.spiral_arcs,
            self.max_deviation_um
        )?;
        let (sense, turn) = match self.jam_direction {
            JamSense::Cw => ("counter-clockwise", "clockwise"),
            JamSense::Ccw => ("clockwise", "counter-clockwise"),
        };
        writeln!(
            f,
            "holes r = {} mm at ±{} mm (φ = 0 and π); seen from above φ grows {sense}, the hub turns the inset {turn}",
            self.hole_radius_mm, self.hole_distance_mm
        )?;
        if let Some(t) = &self.test_piece {
            writeln!(
                f,
                "test piece: one-finger box joint, finger {} mm × {} mm, dilated by {} µm",
                t.finger_width_mm, t.thickness_mm, t.kerf_um
            )?;
        }
        if let Some(gc) = &self.gcode {
            writeln!(
                f,
                "G-code: spiral centre at ({:.3}, {:.3}) mm, {}, {} contours, {:.1} mm cut; needs GRBL $32=1, $30={}",
                gc.at_mm[0],
                gc.at_mm[1],
                gc.settings,
                gc.program.contours,
                gc.program.cut_mm,
                gc.s_max
            )?;
        }
        write!(
            f,
            "cut the red hairlines with the sheet's top face up; there is no outer cut"
        )
    }
}
