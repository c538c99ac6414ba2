//! Cut settings for G-code: how fast, how hard and how many times each cut is cut, chosen by the
//! colour or layer it was drawn with ([`CutGroup`]).
//!
//! A [`Profile`] is one setting for everything (command-line flags) or a small TOML file:
//!
//! ```toml
//! # Contours no entry below names (leave it out to refuse them).
//! [default]
//! feed_mm_per_min = 600
//! power_percent = 80
//!
//! # By stroke colour (SVG) or colour (DXF): any CSS colour.
//! [color."#ff0000"]
//! feed_mm_per_min = 300
//! power_percent = 100
//! passes = 2
//!
//! # By layer (DXF layer, Inkscape layer label), case-insensitive. A layer entry wins over a
//! # colour entry.
//! [layer."Inner cuts"]
//! feed_mm_per_min = 400
//! power_percent = 90
//! ```
//!
//! `passes` is 1 when not given. Power is a percentage of the controller's maximum `S` (GRBL's
//! `$30`, see [`crate::gcode`]). A contour whose colour and layer no entry names, with no
//! `[default]`, is refused: the message lists every such colour and layer, so that nothing is
//! cut with settings the user did not choose. Two entries naming the same colour (`red` and
//! `"#ff0000"`) or layer (`Inner` and `inner`) are refused, and [`Profile::unused`] lists the
//! entries that set no contour.

use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{PlanError, Result};
use crate::outcome::{CutGroup, CutPath};
use crate::rules::Rgb;

/// Largest feed accepted, mm/min (a sanity bound well above any laser cutter's).
pub const MAX_FEED_MM_PER_MIN: f64 = 100_000.0;
/// Smallest feed accepted, mm/min (smaller feeds would be written as `F0`).
pub const MIN_FEED_MM_PER_MIN: f64 = 1.0;
/// Smallest power accepted, percent (with `S` max at least 1, `S` is never written as `S0`).
pub const MIN_POWER_PERCENT: f64 = 0.01;
/// Largest number of passes accepted.
pub const MAX_PASSES: u32 = 100;

/// How one group of cuts is cut.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutSettings {
    /// Feed while cutting, mm/min.
    pub feed_mm_per_min: f64,
    /// Laser power, percent of the maximum `S`.
    pub power_percent: f64,
    /// How many times each contour is cut (all passes of a contour in a row).
    #[serde(default = "one_pass")]
    pub passes: u32,
}

fn one_pass() -> u32 {
    1
}

impl CutSettings {
    /// Check the values (`what` names the settings in the message).
    pub fn check(&self, what: &str) -> Result<()> {
        let bad = |m: String| Err(PlanError::InvalidArgument(format!("{what}: {m}")));
        if !(self.feed_mm_per_min.is_finite()
            && self.feed_mm_per_min >= MIN_FEED_MM_PER_MIN
            && self.feed_mm_per_min <= MAX_FEED_MM_PER_MIN)
        {
            return bad(format!(
                "the feed must be {MIN_FEED_MM_PER_MIN} to {MAX_FEED_MM_PER_MIN} mm/min, got {}",
                kerfmeter_protocol::Shown(self.feed_mm_per_min)
            ));
        }
        if !(self.power_percent.is_finite()
            && self.power_percent >= MIN_POWER_PERCENT
            && self.power_percent <= 100.0)
        {
            return bad(format!(
                "the power must be {MIN_POWER_PERCENT} to 100 %, got {}",
                kerfmeter_protocol::Shown(self.power_percent)
            ));
        }
        if !(1..=MAX_PASSES).contains(&self.passes) {
            return bad(format!(
                "the passes must be 1 to {MAX_PASSES}, got {}",
                self.passes
            ));
        }
        Ok(())
    }
}

impl fmt::Display for CutSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} mm/min, {} %, {} pass{}",
            self.feed_mm_per_min,
            self.power_percent,
            self.passes,
            if self.passes == 1 { "" } else { "es" }
        )
    }
}

/// The profile file as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    default: Option<CutSettings>,
    #[serde(default)]
    color: BTreeMap<String, CutSettings>,
    #[serde(default)]
    layer: BTreeMap<String, CutSettings>,
}

/// Cut settings by colour and layer, with an optional default (see the module doc).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Profile {
    /// For contours no entry names.
    pub default: Option<CutSettings>,
    /// By colour.
    pub by_color: Vec<(Rgb, CutSettings)>,
    /// By layer name (matched case-insensitively).
    pub by_layer: Vec<(String, CutSettings)>,
}

impl Profile {
    /// The same settings for every contour.
    pub fn uniform(settings: CutSettings) -> Result<Profile> {
        settings.check("the cut settings")?;
        Ok(Profile {
            default: Some(settings),
            ..Profile::default()
        })
    }

    /// A profile from the text of a TOML profile file (see the module doc).
    pub fn from_toml(text: &str) -> Result<Profile> {
        let file: ProfileFile = toml::from_str(text)
            .map_err(|e| PlanError::InvalidArgument(format!("not a usable profile: {e}")))?;
        if let Some(d) = &file.default {
            d.check("[default]")?;
        }
        let mut by_color: Vec<(Rgb, CutSettings)> = Vec::new();
        let mut color_names: Vec<String> = Vec::new();
        for (name, s) in file.color {
            s.check(&format!("[color.\"{name}\"]"))?;
            let rgb = Rgb::parse(&name)?;
            if let Some(i) = by_color.iter().position(|(c, _)| *c == rgb) {
                return Err(same_entry("color", &color_names[i], &name));
            }
            by_color.push((rgb, s));
            color_names.push(name);
        }
        let names: Vec<&String> = file.layer.keys().collect();
        for (i, (name, s)) in file.layer.iter().enumerate() {
            s.check(&format!("[layer.\"{name}\"]"))?;
            if let Some(other) = names[..i].iter().find(|n| n.eq_ignore_ascii_case(name)) {
                return Err(same_entry("layer", other, name));
            }
        }
        Ok(Profile {
            default: file.default,
            by_color,
            by_layer: file.layer.into_iter().collect(),
        })
    }

    /// Read a TOML profile file; errors name the file.
    pub fn load(path: &Path) -> Result<Profile> {
        let text = std::fs::read_to_string(path).map_err(|source| PlanError::Io {
            path: path.to_owned(),
            source,
        })?;
        Profile::from_toml(&text).map_err(|e| e.in_file(path))
    }

    /// The settings for a contour drawn with `group`: its layer's entry, else its colour's, else
    /// the default.
    pub fn settings_for(&self, group: &CutGroup) -> Option<CutSettings> {
        let by_layer = group.layer.as_ref().and_then(|l| {
            self.by_layer
                .iter()
                .find(|(name, _)| name.eq_ignore_ascii_case(l))
                .map(|(_, s)| *s)
        });
        let by_color = || {
            group.color.and_then(|c| {
                self.by_color
                    .iter()
                    .find(|(rgb, _)| *rgb == c)
                    .map(|(_, s)| *s)
            })
        };
        by_layer.or_else(by_color).or(self.default)
    }

    /// The settings of every cut, in order; refused, naming every colour and layer without
    /// settings, when some have none.
    pub fn resolve(&self, cuts: &[CutPath]) -> Result<Vec<CutSettings>> {
        let mut missing: BTreeMap<String, usize> = BTreeMap::new();
        let settings: Vec<Option<CutSettings>> = cuts
            .iter()
            .map(|c| {
                let s = self.settings_for(&c.group);
                if s.is_none() {
                    *missing.entry(c.group.to_string()).or_default() += 1;
                }
                s
            })
            .collect();
        if !missing.is_empty() {
            let list: Vec<String> = missing
                .iter()
                .map(|(g, n)| format!("{g} ({n} contour{})", if *n == 1 { "" } else { "s" }))
                .collect();
            return Err(PlanError::InvalidArgument(format!(
                "the profile has no cut settings for {}; add entries for them or a [default]",
                list.join(", ")
            )));
        }
        Ok(settings.into_iter().flatten().collect())
    }

    /// The entries that choose the settings of none of `cuts`, as written in a profile file
    /// (`[layer."…"]`, `[color."#…"]`): a misspelt layer, a colour the cut rules leave out (a
    /// profile entry does not make its colour a cut), or a colour every contour of which a layer
    /// entry takes.
    pub fn unused(&self, cuts: &[CutPath]) -> Vec<String> {
        let layer_entry = |layer: Option<&str>| {
            layer.and_then(|l| {
                self.by_layer
                    .iter()
                    .position(|(n, _)| n.eq_ignore_ascii_case(l))
            })
        };
        let mut unused = Vec::new();
        for (i, (name, _)) in self.by_layer.iter().enumerate() {
            if !cuts
                .iter()
                .any(|c| layer_entry(c.group.layer.as_deref()) == Some(i))
            {
                unused.push(format!("[layer.\"{name}\"]"));
            }
        }
        for (i, (rgb, _)) in self.by_color.iter().enumerate() {
            let chosen = |c: &CutPath| {
                layer_entry(c.group.layer.as_deref()).is_none()
                    && c.group.color.is_some_and(|cc| {
                        self.by_color.iter().position(|(r, _)| *r == cc) == Some(i)
                    })
            };
            if !cuts.iter().any(chosen) {
                unused.push(format!("[color.\"{rgb}\"]"));
            }
        }
        unused
    }

    /// The profile in a few words.
    pub fn describe(&self) -> String {
        self.entries().join("; ")
    }

    /// Each entry in a few words (one G-code header line each).
    pub fn entries(&self) -> Vec<String> {
        let mut parts: Vec<String> = Vec::new();
        for (name, s) in &self.by_layer {
            parts.push(format!("layer {name}: {s}"));
        }
        for (c, s) in &self.by_color {
            parts.push(format!("{c}: {s}"));
        }
        if let Some(d) = &self.default {
            parts.push(format!("default: {d}"));
        }
        parts
    }
}

/// Two entries that name the same colour or layer (`red` and `#ff0000`, `Inner` and `inner`):
/// which one applies would be a guess.
fn same_entry(table: &str, a: &str, b: &str) -> PlanError {
    PlanError::InvalidArgument(format!(
        "[{table}.\"{a}\"] and [{table}.\"{b}\"] name the same {table}: keep one"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn group(color: Option<Rgb>, layer: Option<&str>) -> CutGroup {
        CutGroup {
            color,
            layer: layer.map(str::to_string),
        }
    }

    const PROFILE: &str = r##"
[color."#ff0000"]
feed_mm_per_min = 300
power_percent = 100
passes = 2

[color.blue]
feed_mm_per_min = 900
power_percent = 40

[layer."Inner"]
feed_mm_per_min = 400
power_percent = 90
"##;

    #[test]
    fn a_layer_entry_wins_over_a_colour_entry() {
        let p = Profile::from_toml(PROFILE).unwrap();
        let red = p.settings_for(&group(Some(Rgb::RED), None)).unwrap();
        assert_eq!((red.feed_mm_per_min, red.passes), (300.0, 2));
        let blue = p.settings_for(&group(Some(Rgb::BLUE), Some("x"))).unwrap();
        assert_eq!((blue.power_percent, blue.passes), (40.0, 1));
        let inner = p
            .settings_for(&group(Some(Rgb::RED), Some("inner")))
            .unwrap();
        assert_eq!(inner.feed_mm_per_min, 400.0);
        assert_eq!(p.settings_for(&group(Some(Rgb::BLACK), None)), None);
    }

    #[test]
    fn entries_that_choose_no_contour_are_reported() {
        let p = Profile::from_toml(PROFILE).unwrap();
        let cut = |color, layer| CutPath {
            pline: crate::geom::Pline::new_closed(),
            label: "c".into(),
            group: group(color, layer),
        };
        // Red on layer "inner" takes the layer entry; blue on a misspelt layer takes blue's.
        let cuts = [
            cut(Some(Rgb::RED), Some("inner")),
            cut(Some(Rgb::BLUE), Some("Iner")),
        ];
        assert_eq!(p.unused(&cuts), ["[color.\"#FF0000\"]"]);
        assert_eq!(
            p.unused(&cuts[1..]),
            ["[layer.\"Inner\"]", "[color.\"#FF0000\"]"]
        );
        let all = [
            cut(Some(Rgb::RED), None),
            cut(Some(Rgb::BLUE), None),
            cuts[0].clone(),
        ];
        assert!(p.unused(&all).is_empty(), "{:?}", p.unused(&all));
    }

    #[test]
    fn bad_profiles_are_refused_with_the_entry_named() {
        let e = Profile::from_toml("[color.red]\nfeed_mm_per_min = 0\npower_percent = 50\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("[color.\"red\"]") && e.contains("feed"), "{e}");
        for twice in [
            "[color.red]\nfeed_mm_per_min = 1\npower_percent = 5\n[color.\"#ff0000\"]\nfeed_mm_per_min = 2\npower_percent = 5\n",
            "[layer.Inner]\nfeed_mm_per_min = 1\npower_percent = 5\n[layer.inner]\nfeed_mm_per_min = 2\npower_percent = 5\n",
        ] {
            let e = Profile::from_toml(twice).unwrap_err().to_string();
            assert!(e.contains("name the same"), "{e}");
        }
        // A feed that would be written as F0 is refused.
        let tiny = CutSettings {
            feed_mm_per_min: 0.00004,
            power_percent: 50.0,
            passes: 1,
        };
        assert!(tiny.check("x").is_err());
        let e = Profile::from_toml("[color.red]\nfeed = 10\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a usable profile"), "{e}");
        let e = Profile::from_toml("[color.nocolour]\nfeed_mm_per_min = 1\npower_percent = 5\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a colour"), "{e}");
        assert!(
            Profile::uniform(CutSettings {
                feed_mm_per_min: 100.0,
                power_percent: 120.0,
                passes: 1
            })
            .is_err()
        );
    }
}
