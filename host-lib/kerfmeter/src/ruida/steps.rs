//! The G-code Kerfmeter writes, read as what a Ruida controller is sent ([`Steps`]): cut
//! programs of layers (polylines with each layer's speed and power) and direct moves of the head
//! (X/Y) and of the prongs' axis (Z or U), in order.
//!
//! The job loop speaks one program language, the G-code of `kerfmeter gcode` and of the loop's
//! own prong moves, so that one loop drives GRBL and Ruida alike and its travel checks read one
//! text. This module reads the subset that G-code uses and refuses anything else before a byte
//! is sent ([`StepsError`]): `G17 G21 G90 G94`, `G53`, `G0`/`G1`/`G2`/`G3` with `X Y Z I J F`,
//! `M2 M3 M4 M5` and `S`. Powers are `S` over the `S_MAX=` the program declares.
//!
//! - A cut is a `G1`/`G2`/`G3` with the laser on (`M3`/`M4` and `S` > 0); everything else that
//!   moves X/Y is a travel, sent as a move (`88` inside a program, `D9 10` outside one): the
//!   laser is off on every travel by construction.
//! - A Z move must have the laser off and no X/Y on its line: it ends the program being built
//!   and becomes a direct move of the prongs' axis.
//! - Arcs are flattened into chords whose sagitta is at most [`CHORD_TOLERANCE_MM`] (1 µm, the
//!   controller's coordinate step), their radius interpolated from start to end as GRBL does;
//!   equal ends are a whole turn, as GRBL reads them.
//! - Each run of paths with one speed and power is a layer (`M4` dynamic power becomes a layer
//!   whose minimum and maximum power are the same `S`); a program holds at most
//!   [`kerfmeter_ruida::program::MAX_LAYERS`] layers, and more start another program.

use kerfmeter_ruida::CutLayer;
use kerfmeter_ruida::program::MAX_LAYERS;

use crate::grbl::protocol::{ProgramLine, declared_s_max, prepare};

/// The largest distance of a chord from the arc it stands for, mm.
pub const CHORD_TOLERANCE_MM: f64 = 0.001;

/// One thing the controller is sent.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Move the head to X/Y now, laser off (`D9 10`), mm.
    MoveXy([f64; 2]),
    /// Move the prongs' axis (Z or U) now, mm.
    MoveZ(f64),
    /// Run a cut program.
    Cut(Vec<CutLayer>),
}

/// A program's steps, and its G-code line count.
#[derive(Debug, Clone, PartialEq)]
pub struct Steps {
    /// In order.
    pub steps: Vec<Step>,
    /// G-code lines read.
    pub lines: usize,
}

/// A line the Ruida reading refuses (nothing sent).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StepsError {
    /// Its number in the file (0: the program as a whole).
    pub line: usize,
    /// Why.
    pub reason: String,
}

/// The settings a path is cut with.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Settings {
    speed_mm_per_s: f64,
    power_percent: f64,
}

/// The reader's state.
struct Reader {
    s_max: Option<f64>,
    at: [f64; 2],
    /// Where the last step left the head.
    sent_at: Option<[f64; 2]>,
    feed_mm_per_min: f64,
    s: f64,
    laser: bool,
    motion: u8,
    layers: Vec<CutLayer>,
    path: Option<(Settings, Vec<[f64; 2]>)>,
    steps: Vec<Step>,
}

/// Read `program` (see the [module docs](self)), the head standing at `head_mm` (X/Y).
pub fn read(program: &str, head_mm: [f64; 2]) -> Result<Steps, StepsError> {
    let bad = |e: crate::grbl::protocol::BadLine| StepsError {
        line: e.number,
        reason: e.reason,
    };
    let lines = prepare(program).map_err(bad)?;
    let mut r = Reader {
        s_max: declared_s_max(program).map_err(bad)?,
        at: head_mm,
        sent_at: Some(head_mm),
        feed_mm_per_min: 0.0,
        s: 0.0,
        laser: false,
        motion: 0,
        layers: Vec::new(),
        path: None,
        steps: Vec::new(),
    };
    for line in &lines {
        r.line(line).map_err(|reason| StepsError {
            line: line.number,
            reason,
        })?;
    }
    r.end_program();
    r.flush_travel();
    Ok(Steps {
        steps: r.steps,
        lines: lines.len(),
    })
}

/// The words of a cleaned line: letter and number.
fn words(text: &str) -> Result<Vec<(char, f64)>, String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(letter) = rest.chars().next() {
        let tail = &rest[letter.len_utf8()..];
        let end = tail
            .find(|c: char| c.is_ascii_alphabetic())
            .unwrap_or(tail.len());
        let number = tail[..end]
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{letter}` without a number"))?;
        out.push((letter.to_ascii_uppercase(), number));
        rest = &tail[end..];
    }
    Ok(out)
}

/// A line's axis words.
#[derive(Default)]
struct Target {
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    i: f64,
    j: f64,
}

impl Reader {
    fn line(&mut self, line: &ProgramLine) -> Result<(), String> {
        let mut target = Target::default();
        let mut machine = false;
        for (letter, value) in words(&line.text)? {
            match letter {
                'G' => self.g_word(value, &mut machine)?,
                'M' => self.m_word(value)?,
                'S' => self.s = value,
                'F' if value > 0.0 => self.feed_mm_per_min = value,
                'F' => return Err(format!("a feed rate of F{value}: above 0 needed")),
                'X' => target.x = Some(value),
                'Y' => target.y = Some(value),
                'Z' => target.z = Some(value),
                'I' => target.i = value,
                'J' => target.j = value,
                'N' => {}
                other => return Err(unsupported(&format!("{other}{value}"))),
            }
        }
        if target.z.is_some() {
            return self.move_z(&target);
        }
        if target.x.is_none() && target.y.is_none() {
            return Ok(());
        }
        let to = [
            target.x.unwrap_or(self.at[0]),
            target.y.unwrap_or(self.at[1]),
        ];
        if machine && self.motion != 0 {
            return Err("G53 only with G0 (a travel)".into());
        }
        self.move_xy(to, [target.i, target.j])
    }

    fn g_word(&mut self, value: f64, machine: &mut bool) -> Result<(), String> {
        match whole(value) {
            Some(n @ 0..=3) => self.motion = n as u8,
            Some(53) => *machine = true,
            Some(17 | 21 | 54 | 90 | 94) => {}
            _ => return Err(unsupported(&format!("G{value}"))),
        }
        Ok(())
    }

    fn m_word(&mut self, value: f64) -> Result<(), String> {
        match whole(value) {
            Some(3 | 4) => self.laser = true,
            Some(2 | 5 | 30) => self.laser = false,
            _ => return Err(unsupported(&format!("M{value}"))),
        }
        Ok(())
    }

    fn move_z(&mut self, target: &Target) -> Result<(), String> {
        if target.x.is_some() || target.y.is_some() || self.motion > 1 {
            return Err("a Z move with X/Y or an arc on its line: a Ruida controller moves Z on its own (give Z on a line of its own)".into());
        }
        if self.fires() && self.motion == 1 {
            return Err("a Z move with the laser on".into());
        }
        self.end_program();
        self.flush_travel();
        self.steps.push(Step::MoveZ(target.z.unwrap_or_default()));
        Ok(())
    }

    /// Whether a feed move now would fire the laser.
    fn fires(&self) -> bool {
        self.laser && self.s > 0.0
    }

    fn move_xy(&mut self, to: [f64; 2], ij: [f64; 2]) -> Result<(), String> {
        // A move with the laser off (an arc too) is a travel: straight, and dark.
        if self.motion == 0 || !self.fires() {
            self.end_path();
            self.at = to;
            return Ok(());
        }
        let settings = self.settings()?;
        let points = match self.motion {
            1 => vec![to],
            m => flatten(self.at, to, ij, m == 2),
        };
        self.cut(settings, &points);
        self.at = to;
        Ok(())
    }

    fn settings(&self) -> Result<Settings, String> {
        let s_max = self.s_max.ok_or(
            "the program declares no S max (`(S_MAX=1000 …)`, as `kerfmeter gcode` writes): its S values cannot be read as a share of full power",
        )?;
        if self.feed_mm_per_min <= 0.0 {
            return Err("a cut before any feed rate (F)".into());
        }
        Ok(Settings {
            speed_mm_per_s: self.feed_mm_per_min / 60.0,
            power_percent: (self.s / s_max * 100.0).min(100.0),
        })
    }

    /// Cut through `points` from where the head stands.
    fn cut(&mut self, settings: Settings, points: &[[f64; 2]]) {
        if self.path.as_ref().is_some_and(|(s, _)| *s != settings) {
            self.end_path();
        }
        let at = self.at;
        let (_, path) = self.path.get_or_insert_with(|| (settings, vec![at]));
        path.extend_from_slice(points);
    }

    /// The path being cut goes into its layer (a new one when the settings changed).
    fn end_path(&mut self) {
        let Some((s, path)) = self.path.take() else {
            return;
        };
        let same = self.layers.last().is_some_and(|l| {
            l.speed_mm_per_s == s.speed_mm_per_s && l.max_power_percent == s.power_percent
        });
        if !same && self.layers.len() == MAX_LAYERS {
            self.end_program();
        }
        match self.layers.last_mut() {
            Some(layer) if same => layer.paths_mm.push(path),
            _ => self.layers.push(CutLayer {
                speed_mm_per_s: s.speed_mm_per_s,
                min_power_percent: s.power_percent,
                max_power_percent: s.power_percent,
                paths_mm: vec![path],
            }),
        }
    }

    /// The program being built becomes a step.
    fn end_program(&mut self) {
        self.end_path();
        if self.layers.is_empty() {
            return;
        }
        let layers = std::mem::take(&mut self.layers);
        self.sent_at = layers
            .last()
            .and_then(|l| l.paths_mm.last())
            .and_then(|p| p.last())
            .copied();
        self.steps.push(Step::Cut(layers));
    }

    /// A travel not yet sent becomes a direct move.
    fn flush_travel(&mut self) {
        if self.sent_at != Some(self.at) {
            self.steps.push(Step::MoveXy(self.at));
            self.sent_at = Some(self.at);
        }
    }
}

/// `value` as a whole number, if it is one (`G38.2` is not `G38`).
fn whole(value: f64) -> Option<i64> {
    (value.fract() == 0.0 && value.abs() < 1e6).then_some(value as i64)
}

fn unsupported(word: &str) -> String {
    format!(
        "`{word}` is not in the G-code Kerfmeter writes (G0–G3, G17, G21, G53, G54, G90, G94, M2–M5, S, F), which is what a Ruida controller is sent from"
    )
}

/// The points along an arc from `from` to `to` about `from + ij`, within [`CHORD_TOLERANCE_MM`].
fn flatten(from: [f64; 2], to: [f64; 2], ij: [f64; 2], clockwise: bool) -> Vec<[f64; 2]> {
    let c = [from[0] + ij[0], from[1] + ij[1]];
    let r0 = ij[0].hypot(ij[1]);
    let r1 = (to[0] - c[0]).hypot(to[1] - c[1]);
    let a0 = (from[1] - c[1]).atan2(from[0] - c[0]);
    let a1 = (to[1] - c[1]).atan2(to[0] - c[0]);
    let ccw = if clockwise { a0 - a1 } else { a1 - a0 };
    let mut sweep = ccw.rem_euclid(std::f64::consts::TAU);
    if sweep < 1e-9 {
        sweep = std::f64::consts::TAU;
    }
    let r = r0.max(r1);
    let step = if r > CHORD_TOLERANCE_MM {
        2.0 * (1.0 - CHORD_TOLERANCE_MM / r).acos()
    } else {
        sweep
    };
    let n = (sweep / step).ceil().max(1.0) as usize;
    let turn = if clockwise { -sweep } else { sweep };
    let mut points: Vec<[f64; 2]> = (1..n)
        .map(|k| {
            let f = k as f64 / n as f64;
            let radius = r0 + (r1 - r0) * f;
            let (sin, cos) = (a0 + turn * f).sin_cos();
            [c[0] + radius * cos, c[1] + radius * sin]
        })
        .collect();
    points.push(to);
    points
}

#[cfg(test)]
mod tests;
