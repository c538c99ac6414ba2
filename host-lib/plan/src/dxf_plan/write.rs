//! Putting the dilated contours back into the file: each cut's origin becomes a change to the
//! input's text (see the `splice` submodule), found through the `placing` submodule.
//!
//! * a closed `LWPOLYLINE` gets its new vertices; a `CIRCLE` its new radius (one that did not
//!   stay a circle is left out and replaced);
//! * the entities of a chain, a `POLYLINE`, `ELLIPSE` or `SPLINE` are left out, and one new closed
//!   polyline takes the first one's style and owner;
//! * a cut inside a block is left out of the block (once, however often it is inserted), and each
//!   of its insertions gets a new model-space polyline, styled as the cut inherits through the
//!   `INSERT`s (layer `0` and `BYBLOCK` taking theirs), owned by model space;
//! * units assumed for a drawing that did not say are written into `$INSUNITS` (R2000 on).

use dxf::Drawing;
use dxf::entities::{Entity, EntityType};
use dxf::enums::{AcadVersion, Units};

use super::Origin;
use super::blocks::{BlockCut, Container, EntityRef};
use super::geometry::as_circle;
use super::layout::{Layout, Scanned};
use super::mirrored;
use super::placing::{Places, style_pairs};
use super::splice::{Change, Splice, Style};
use super::text::{Form, NewPolyline, Precision};
use crate::decimal::{decimals_for_step, pow10};
use crate::geom::Pline;

/// Decimal places of the numbers written: a step of at most 0.01 µm (so a coordinate is within
/// 0.005 µm), and bulges to 10⁻¹⁰ (a 10 m chord's arc within 0.001 µm). Trailing zeros are
/// dropped, so rounded numbers print short.
const STEP_MM: f64 = 1e-5;
const BULGE_DIGITS: i32 = 10;

/// `v` rounded to `digits` decimals.
pub(super) fn rounded(v: f64, digits: i32) -> f64 {
    let m = pow10(digits);
    let r = (v * m).round() / m;
    if r.is_finite() { r } else { v }
}

/// The decimals of a coordinate in drawing units (`scale` mm each) that give the step written
/// (see [`STEP_MM`]).
fn unit_digits(scale: f64) -> i32 {
    decimals_for_step(STEP_MM / scale) as i32
}

/// `mm` in drawing units (`scale` mm each), rounded to the step written (see [`STEP_MM`]).
fn units(mm: f64, scale: f64) -> f64 {
    rounded(mm / scale, unit_digits(scale))
}

/// A dilated drawing not yet written: the drawing as read, and what changes in it.
pub(super) struct Changes {
    pub drawing: Drawing,
    /// mm per drawing unit.
    pub scale: f64,
    /// Each cut's origin and its dilated contour (mm).
    pub cuts: Vec<(Origin, Pline)>,
    /// The units assumed for a drawing that did not say, to write into it (R2000 and later).
    pub assumed: Option<Units>,
}

/// The form new polylines take in a drawing of `version`.
fn form(version: AcadVersion) -> Form {
    if version >= AcadVersion::R14 {
        Form::LwPolyline
    } else {
        Form::Polyline {
            subclasses: version >= AcadVersion::R13,
        }
    }
}

/// The `$INSUNITS` code of the units that can be assumed.
fn insunits_code(units: Units) -> Option<i32> {
    match units {
        Units::Millimeters => Some(4),
        Units::Centimeters => Some(5),
        Units::Inches => Some(1),
        _ => None,
    }
}

impl Changes {
    /// The input `text` (laid out as `layout` says) with the changes spliced in, `record` first;
    /// why not, when a change cannot be placed.
    pub fn write(
        &self,
        text: &[u8],
        layout: &Layout,
        record: Option<&str>,
    ) -> Result<Vec<u8>, String> {
        let mut places = Places::new(text, layout, &self.drawing)?;
        let entities: Vec<&Entity> = self.drawing.entities().collect();
        let mut splice = Splice::new();
        for (origin, d) in &self.cuts {
            self.place(&mut splice, &mut places, &entities, text, origin, d)?;
        }
        if let Some(code) = self.assumed.and_then(insunits_code) {
            splice.set_insunits(code);
        }
        let version = self.drawing.header.version;
        let style = Style {
            form: form(version),
            handles: version >= AcadVersion::R13
                || layout.max_handle > 0
                || layout.handseed.is_some(),
        };
        let precision = Precision {
            mm_per_unit: self.scale,
            unit_digits: unit_digits(self.scale),
            bulge_digits: BULGE_DIGITS,
        };
        splice
            .write(text, layout, record, precision, style)
            .ok_or_else(|| "a change could not be placed (an entity changed twice, or no ENTITIES section or header to write into)".into())
    }

    /// Place one dilated contour's change in `splice`.
    fn place<'p>(
        &self,
        splice: &mut Splice<'p>,
        places: &mut Places,
        entities: &[&Entity],
        text: &[u8],
        origin: &Origin,
        d: &'p Pline,
    ) -> Result<(), String> {
        match origin {
            Origin::LwPolyline(i) => {
                let e = places.get(&EntityRef::model(*i))?;
                splice.change(&e, Change::Vertices, Some(d));
            }
            Origin::Circle(i) => {
                let e = places.get(&EntityRef::model(*i))?;
                match (as_circle(d), &entities[*i].specific) {
                    (Some((c, r)), EntityType::Circle(circle)) => {
                        let m = mirrored(&circle.normal).unwrap_or(false);
                        let z = circle.center.z * if m { -1.0 } else { 1.0 };
                        let new = [
                            units(c.x, self.scale),
                            units(c.y, self.scale),
                            z,
                            units(r, self.scale),
                        ];
                        splice.change(&e, Change::Circle(new), None);
                    }
                    _ => self.replace(splice, places, text, &[*i], d)?,
                }
            }
            Origin::Replace(list) => self.replace(splice, places, text, list, d)?,
            Origin::Block(cut) => self.explode(splice, places, text, cut, d)?,
        }
        Ok(())
    }

    /// Leave out the model-space entities `list` and add a new polyline for `d` styled and owned
    /// like the first.
    fn replace<'p>(
        &self,
        splice: &mut Splice<'p>,
        places: &mut Places,
        text: &[u8],
        list: &[usize],
        d: &'p Pline,
    ) -> Result<(), String> {
        let mut first = None;
        for &i in list {
            let e = places.get(&EntityRef::model(i))?;
            splice.change(&e, Change::Drop, None);
            first.get_or_insert(e);
        }
        let first = first.ok_or("a cut of no entity")?;
        splice.add(NewPolyline {
            contour: d,
            style: style_pairs(text, &[first]),
            owner: first.owner,
        });
        Ok(())
    }

    /// Leave the block entities of `cut` out of their block, and add a new model-space polyline
    /// for `d`, styled as the cut inherits through its `INSERT`s and owned as the outermost.
    fn explode<'p>(
        &self,
        splice: &mut Splice<'p>,
        places: &mut Places,
        text: &[u8],
        cut: &BlockCut,
        d: &'p Pline,
    ) -> Result<(), String> {
        let mut chain: Vec<Scanned> = Vec::with_capacity(cut.via.len() + 1);
        for &k in &cut.entities {
            let at = EntityRef {
                container: Container::Block(cut.block.clone()),
                index: k,
            };
            let e = places.get(&at)?;
            splice.change(&e, Change::Drop, None);
            if chain.is_empty() {
                chain.push(e);
            }
        }
        for at in cut.via.iter().rev() {
            chain.push(places.get(at)?);
        }
        let owner = cut
            .via
            .first()
            .map(|at| places.get(at))
            .transpose()?
            .and_then(|e| e.owner);
        splice.add(NewPolyline {
            contour: d,
            style: style_pairs(text, &chain),
            owner,
        });
        Ok(())
    }
}
