//! A gauge as a real cutter cuts it, drawn from the plant's parameters: everything that makes one
//! gauge differ from its drawing, held in a [`GaugeCut`] so that a run's gauge can be logged and
//! placed again ([`super::Plant::place_gauge`]).
//!
//! - **Kerf**: the twin's kerf, plus a bias of the place on the bed where this twin's gauges are
//!   cut (drawn once per twin, SD `kerf_location_sd_um`: a cutter's kerf varies across its bed),
//!   plus this gauge's own spread (`TwinOptions::kerf_sd_um`).
//! - **Taper**: the kerf at the top of the sheet minus at the bottom (`kerf_taper_um`); the kerf
//!   is the mid-sheet one, so the cut is `kerf − taper/2` wide at the bottom, never less than 0.
//! - **Hole centres** displaced by the cutter's repeatability: each hole, radially and
//!   tangentially, SD `hole_position_sd_um`.
//! - **Prongs off-centre at zero**: the head returns over the gauge with its repeatability, so the
//!   hub's axis stands off the gauge's centre by a vector drawn per gauge (each axis, SD
//!   `prong_offset_sd_um`).
//! - **Contact**: the spiral contact's stiffness (relative SD `contact_stiffness_sd_frac`) and
//!   friction coefficient (SD `contact_mu_sd`), each clamped to its parameter's documented range
//!   (and the stiffness to at least a fifth of its mean): a draw may not leave the physical.
//!
//! A cutter twin's settings of this model are a [`CutterKerf`] (kerf, spread, repeatability);
//! a gauge it traced keeps its traced holes and centre on top of these draws
//! ([`crate::gauge_trace`]).
//!
//! Every draw takes the same number of numbers from the stream whatever the spreads are, so
//! that setting one spread to zero does not reshuffle the others.

use kerfmeter_firmware::fakes::rng::Rng;

use super::{PlantParams, param};
use crate::options::{InvalidOptions, KERF_RANGE_UM, KERF_SD_RANGE_UM, REPEATABILITY_RANGE_UM};

/// Mixed into the seed of the stream that draws the location bias of a twin's gauges (once per
/// twin), so that it depends on the seed alone.
pub const LOCATION_STREAM: u64 = 0x6c6f_6361_7469_6f6e;

/// The smallest share of its mean that a drawn contact stiffness keeps.
const MIN_STIFFNESS_SHARE: f64 = 0.2;

/// One gauge as it was cut: what differs from the drawing. Lengths in µm; displacements in the
/// frame of the gauge at zero, per hole: radial (outward) and tangential (positive in the jam
/// direction). Hole 0 is the one prong 0 enters; hole 1 is diametrically opposite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaugeCut {
    /// The kerf at mid-sheet, µm (location bias and this gauge's spread included).
    pub kerf_um: f64,
    /// The kerf at the top of the sheet minus at the bottom, µm.
    pub taper_um: f64,
    /// Each hole centre's displacement from where it was drawn, µm: `[radial, tangential]`.
    pub hole_offset_um: [[f64; 2]; 2],
    /// Where the hub's axis stands off the gauge's centre, µm: `[x, y]` on the table, x towards
    /// hole 0 and y the jam direction at hole 0, with the gauge (and the hub) at zero.
    pub hub_offset_um: [f64; 2],
    /// Stiffness of the spiral contact over the full face, N/µm.
    pub stiffness_n_per_um: f64,
    /// Normal force at which the contact starts to crush, N.
    pub yield_n: f64,
    /// Friction coefficient of the spiral contact.
    pub mu: f64,
}

impl GaugeCut {
    /// The gauge as drawn, with kerf `kerf_um`, the plant's taper and the mean contact: what an
    /// average gauge of this material is.
    pub fn nominal(params: &PlantParams, kerf_um: f64) -> Self {
        Self {
            kerf_um,
            taper_um: params.kerf_taper_um,
            hole_offset_um: [[0.0; 2]; 2],
            hub_offset_um: [0.0; 2],
            stiffness_n_per_um: params.contact_stiffness_n_per_um,
            yield_n: params.contact_yield_n,
            mu: params.contact_mu,
        }
    }

    /// The cut as a JSON object, for logs and replays.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "kerf_um": self.kerf_um,
            "taper_um": self.taper_um,
            "hole_offset_um": self.hole_offset_um,
            "hub_offset_um": self.hub_offset_um,
            "stiffness_n_per_um": self.stiffness_n_per_um,
            "yield_n": self.yield_n,
            "mu": self.mu,
        })
    }
}

/// How a cutter cuts, as a cutter twin is set up (`kerfmeter::grbl::twin::CutterOptions::kerf`):
/// the settings of the one kerf model, [`Cutter`], that a cutter's own options carry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutterKerf {
    /// Nominal kerf at mid-sheet, µm (before the bias of the place on the bed).
    pub kerf_um: f64,
    /// SD of the kerf from gauge to gauge, µm.
    pub kerf_sd_um: f64,
    /// The machine's repeatability: SD of each traced position, each axis, µm. Each hole centre
    /// is displaced by it, and the head returning over the gauge (the prongs ride on it) too.
    pub repeatability_um: f64,
}

impl Default for CutterKerf {
    /// 150 µm, no spread, the default plant's repeatability (7.5 µm).
    fn default() -> Self {
        Self {
            kerf_um: 150.0,
            kerf_sd_um: 0.0,
            repeatability_um: 7.5,
        }
    }
}

impl CutterKerf {
    /// The cutter these settings make, on the plant `params` (its taper, contact and location
    /// spread), for the twin seeded with `seed`; or which setting is out of its range.
    pub fn cutter(&self, params: PlantParams, seed: u64) -> Result<Cutter, InvalidOptions> {
        if !KERF_RANGE_UM.contains(&self.kerf_um) {
            return Err(InvalidOptions::Kerf(self.kerf_um));
        }
        if !KERF_SD_RANGE_UM.contains(&self.kerf_sd_um) {
            return Err(InvalidOptions::KerfSpread(self.kerf_sd_um));
        }
        if !REPEATABILITY_RANGE_UM.contains(&self.repeatability_um) {
            return Err(InvalidOptions::Repeatability(self.repeatability_um));
        }
        let params = PlantParams {
            hole_position_sd_um: self.repeatability_um,
            prong_offset_sd_um: self.repeatability_um,
            ..params
        };
        params.validate()?;
        Ok(Cutter::for_twin(
            params,
            self.kerf_um,
            self.kerf_sd_um,
            seed,
        ))
    }
}

/// The cutter at the place where a twin's gauges are cut: draws each gauge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cutter {
    params: PlantParams,
    kerf_um: f64,
    kerf_sd_um: f64,
    location_bias_um: f64,
}

impl Cutter {
    /// A cutter whose nominal kerf is `kerf_um`, spread `kerf_sd_um` gauge to gauge, at a place
    /// whose bias is drawn from `rng`.
    pub fn new(params: PlantParams, kerf_um: f64, kerf_sd_um: f64, rng: &mut Rng) -> Self {
        let location_bias_um = f64::from(rng.normal()) * params.kerf_location_sd_um;
        Self {
            params,
            kerf_um,
            kerf_sd_um,
            location_bias_um,
        }
    }

    /// The cutter of the twin seeded with `seed`: its location bias depends on the seed alone
    /// (see [`LOCATION_STREAM`]).
    pub fn for_twin(params: PlantParams, kerf_um: f64, kerf_sd_um: f64, seed: u64) -> Self {
        Self::new(
            params,
            kerf_um,
            kerf_sd_um,
            &mut Rng::new(seed ^ LOCATION_STREAM),
        )
    }

    /// The bias of the kerf where this cutter cuts, µm.
    pub fn location_bias_um(&self) -> f64 {
        self.location_bias_um
    }

    /// Cut one gauge, drawing its imperfections from `rng`.
    pub fn cut(&self, rng: &mut Rng) -> GaugeCut {
        let p = &self.params;
        let mut normal = || f64::from(rng.normal());
        let kerf_um = (self.kerf_um + self.location_bias_um + normal() * self.kerf_sd_um).max(0.0);
        let hole_sd = p.hole_position_sd_um;
        let hole_offset_um = [
            [normal() * hole_sd, normal() * hole_sd],
            [normal() * hole_sd, normal() * hole_sd],
        ];
        let prong_sd = p.prong_offset_sd_um;
        let hub_offset_um = [normal() * prong_sd, normal() * prong_sd];
        let stiffness_share =
            (1.0 + normal() * p.contact_stiffness_sd_frac).max(MIN_STIFFNESS_SHARE);
        let mu = p.contact_mu + normal() * p.contact_mu_sd;
        GaugeCut {
            kerf_um,
            taper_um: p.kerf_taper_um,
            hole_offset_um,
            hub_offset_um,
            stiffness_n_per_um: within_range(
                "contact_stiffness_n_per_um",
                p.contact_stiffness_n_per_um * stiffness_share,
            ),
            yield_n: p.contact_yield_n,
            mu: within_range("contact_mu", mu),
        }
    }
}

/// `value` clamped to the documented range of the parameter `name`.
fn within_range(name: &str, value: f64) -> f64 {
    let spec = param(name).expect("a parameter of the list");
    value.clamp(spec.min, spec.max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cutter(seed: u64) -> Cutter {
        Cutter::for_twin(PlantParams::default(), 150.0, 8.0, seed)
    }

    #[test]
    fn per_gauge_draws_are_reproducible_for_a_seed_and_vary_between_gauges() {
        let cuts = |seed: u64| {
            let mut rng = Rng::new(seed);
            (0..3)
                .map(|_| cutter(seed).cut(&mut rng))
                .collect::<Vec<_>>()
        };
        let first = cuts(11);
        assert_eq!(first, cuts(11), "the same seed cuts the same gauges");
        assert_ne!(first[0], first[1]);
        for field in [
            |c: &GaugeCut| c.kerf_um,
            |c: &GaugeCut| c.hole_offset_um[0][1],
            |c: &GaugeCut| c.hole_offset_um[1][0],
            |c: &GaugeCut| c.hub_offset_um[1],
            |c: &GaugeCut| c.stiffness_n_per_um,
            |c: &GaugeCut| c.mu,
        ] {
            assert_ne!(field(&first[0]), field(&first[1]), "{first:?}");
        }
        assert_ne!(first, cuts(12), "another seed, other gauges");
    }

    #[test]
    fn the_spreads_have_their_configured_size() {
        let p = PlantParams::default();
        let c = Cutter::for_twin(p, 150.0, 8.0, 3);
        let mut rng = Rng::new(5);
        let cuts: Vec<GaugeCut> = (0..4000).map(|_| c.cut(&mut rng)).collect();
        let sd = |f: &dyn Fn(&GaugeCut) -> f64| {
            let n = cuts.len() as f64;
            let mean = cuts.iter().map(f).sum::<f64>() / n;
            let var = cuts.iter().map(|c| (f(c) - mean).powi(2)).sum::<f64>() / (n - 1.0);
            (mean, var.sqrt())
        };
        let (kerf_mean, kerf_sd) = sd(&|c| c.kerf_um);
        assert!((kerf_sd - 8.0).abs() < 0.4, "{kerf_sd}");
        assert!((kerf_mean - 150.0 - c.location_bias_um()).abs() < 0.5);
        let (_, hole_sd) = sd(&|c| c.hole_offset_um[1][1]);
        assert!((hole_sd - p.hole_position_sd_um).abs() < 0.4, "{hole_sd}");
        let (_, hub_sd) = sd(&|c| c.hub_offset_um[0]);
        assert!((hub_sd - p.prong_offset_sd_um).abs() < 0.4, "{hub_sd}");
        let (k_mean, k_sd) = sd(&|c| c.stiffness_n_per_um);
        assert!(
            (k_mean - p.contact_stiffness_n_per_um).abs() < 0.1,
            "{k_mean}"
        );
        let k_frac = k_sd / p.contact_stiffness_n_per_um;
        assert!((k_frac - p.contact_stiffness_sd_frac).abs() < 0.01);
        let (mu_mean, mu_sd) = sd(&|c| c.mu);
        assert!((mu_mean - p.contact_mu).abs() < 0.003 && (mu_sd - p.contact_mu_sd).abs() < 0.003);
    }

    #[test]
    fn the_location_bias_is_drawn_once_per_twin_from_its_seed() {
        let biases: Vec<f64> = (0..200).map(|s| cutter(s).location_bias_um()).collect();
        assert_eq!(cutter(7).location_bias_um(), biases[7]);
        let sd = (biases.iter().map(|b| b * b).sum::<f64>() / biases.len() as f64).sqrt();
        let expected = PlantParams::default().kerf_location_sd_um;
        assert!((sd - expected).abs() < 0.2 * expected, "{sd}");
    }

    #[test]
    fn draws_stay_physical_even_with_the_widest_spreads() {
        let p = PlantParams {
            contact_stiffness_sd_frac: 0.5,
            contact_mu_sd: 0.1,
            contact_mu: 0.6,
            contact_stiffness_n_per_um: 1.0,
            ..PlantParams::default()
        };
        let c = Cutter::for_twin(p, 20.0, 100.0, 1);
        let mut rng = Rng::new(2);
        for _ in 0..2000 {
            let cut = c.cut(&mut rng);
            assert!(cut.kerf_um >= 0.0);
            assert!((0.1..=0.6).contains(&cut.mu), "{cut:?}");
            assert!((1.0..=500.0).contains(&cut.stiffness_n_per_um), "{cut:?}");
        }
    }

    #[test]
    fn a_cut_is_logged_with_every_draw() {
        let cut = cutter(3).cut(&mut Rng::new(4));
        let json = cut.to_json();
        assert_eq!(json["kerf_um"], cut.kerf_um);
        assert_eq!(json["hole_offset_um"][1][0], cut.hole_offset_um[1][0]);
        assert_eq!(json["hub_offset_um"][1], cut.hub_offset_um[1]);
        assert_eq!(json["mu"], cut.mu);
        assert_eq!(json["yield_n"], cut.yield_n);
        assert_eq!(json.as_object().map(|o| o.len()), Some(7));
    }

    #[test]
    fn a_cutters_settings_make_the_one_kerf_model_and_out_of_range_ones_are_named() {
        let p = PlantParams::default();
        let kerf = CutterKerf {
            kerf_um: 180.0,
            kerf_sd_um: 4.0,
            repeatability_um: 12.0,
        };
        let made = kerf.cutter(p, 9).unwrap();
        let repeatable = PlantParams {
            hole_position_sd_um: 12.0,
            prong_offset_sd_um: 12.0,
            ..p
        };
        assert_eq!(made, Cutter::for_twin(repeatable, 180.0, 4.0, 9));
        let bad = CutterKerf {
            repeatability_um: 31.0,
            ..kerf
        };
        assert_eq!(bad.cutter(p, 9), Err(InvalidOptions::Repeatability(31.0)));
        let bad = CutterKerf {
            kerf_sd_um: f64::NAN,
            ..kerf
        };
        assert!(matches!(
            bad.cutter(p, 9),
            Err(InvalidOptions::KerfSpread(_))
        ));
    }

    #[test]
    fn no_spread_means_a_nominal_gauge() {
        let p = PlantParams {
            kerf_location_sd_um: 0.0,
            hole_position_sd_um: 0.0,
            prong_offset_sd_um: 0.0,
            contact_stiffness_sd_frac: 0.0,
            contact_mu_sd: 0.0,
            ..PlantParams::default()
        };
        let cut = Cutter::for_twin(p, 150.0, 0.0, 4).cut(&mut Rng::new(1));
        assert_eq!(cut, GaugeCut::nominal(&p, 150.0));
    }
}
