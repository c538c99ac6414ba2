//! `ruida-sim`: the simulated Ruida controller (`kerfmeter_ruida::twin`) on loopback UDP, driven
//! through the same driver as a real one, and what its laser traced, for the device twin.

use std::net::SocketAddr;

use kerfmeter_ruida::twin::{RuidaTwin, Stroke, TwinConfig};
use kerfmeter_twin::traced::{Segment, SegmentKind};

use super::RuidaFailure;
use super::address::{ProngAxis, RuidaAddress};
use super::driver::{RuidaCutter, Timing};
use crate::grbl::CutterError;

/// The simulated controller's Z travel, mm.
pub const SIM_Z_TRAVEL_MM: [f64; 2] = [-50.0, 50.0];

/// The simulated controller `ruida-sim` is: a bed of `bed_mm` (600 × 400 mm when `None`), busy
/// for a few status reads after each program, as a machine that takes time to cut.
pub fn twin_config(bed_mm: Option<[f64; 2]>) -> TwinConfig {
    let [w, h] = bed_mm.unwrap_or([600.0, 400.0]);
    TwinConfig {
        bed_um: [(w * 1000.0).round() as i32, (h * 1000.0).round() as i32],
        busy_reads: 3,
        ..TwinConfig::default()
    }
}

impl Timing {
    /// The timing for the twin: loopback answers at once, so every wait is short.
    pub fn sim() -> Self {
        Self {
            reply_timeout: std::time::Duration::from_millis(200),
            tries: 3,
            poll: std::time::Duration::from_millis(5),
            stop_confirm: std::time::Duration::from_secs(1),
            start_grace: std::time::Duration::from_millis(300),
        }
    }
}

impl RuidaCutter {
    /// Start a simulated controller as `config` says and connect to it.
    pub fn sim(config: TwinConfig, timing: Timing) -> Result<Self, CutterError> {
        let twin = RuidaTwin::start(config).map_err(|e| RuidaFailure::Sim(e.to_string()))?;
        Self::on_twin(twin, timing)
    }

    /// Connect to the simulated controller `twin` (started, and perhaps made unkind, by the
    /// caller), which the cutter then keeps.
    pub fn on_twin(twin: RuidaTwin, timing: Timing) -> Result<Self, CutterError> {
        let addr: SocketAddr = twin.addr();
        let address = RuidaAddress {
            host: addr.ip().to_string(),
            port: addr.port(),
            z_travel_mm: SIM_Z_TRAVEL_MM,
            bed_mm: None,
            fallback_bed_mm: None,
            prong_axis: ProngAxis::Z,
            local_port: 0,
        };
        let mut cutter = Self::connect(addr, format!("ruida-sim ({addr})"), &address, timing)?;
        cutter.twin = Some(twin);
        Ok(cutter)
    }

    /// The simulated controller, when this is one.
    pub fn twin(&self) -> Option<&RuidaTwin> {
        self.twin.as_ref()
    }

    /// What the simulated controller's laser traced, as the device twin reads a trace.
    pub fn traced_segments(&self) -> Option<Vec<Segment>> {
        let log = self.twin.as_ref()?.log();
        Some(log.strokes.iter().enumerate().map(segment).collect())
    }
}

/// A stroke as a traced segment: a cut is a line at its power (as `S` of 1000), a move a travel.
fn segment((index, stroke): (usize, &Stroke)) -> Segment {
    let mm = |p: [i32; 2]| [f64::from(p[0]) / 1000.0, f64::from(p[1]) / 1000.0, 0.0];
    let power_percent = f64::from(stroke.power_steps[1]) / 16384.0 * 100.0;
    Segment {
        kind: if stroke.laser_on {
            SegmentKind::Line
        } else {
            SegmentKind::Travel
        },
        start: mm(stroke.from_um),
        end: mm(stroke.to_um),
        power_s: if stroke.laser_on {
            power_percent * 10.0
        } else {
            0.0
        },
        feed_mm_per_min: f64::from(stroke.speed_um_per_s) * 60.0 / 1000.0,
        complete: true,
        line: u32::try_from(index + 1).unwrap_or(u32::MAX),
    }
}
