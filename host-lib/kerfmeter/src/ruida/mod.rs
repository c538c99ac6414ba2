//! Drive a Ruida CO2-laser controller (the RDC644x family) over the network, as the job loop's
//! second cutter ([`crate::job::JobCutter`]): `ruida:HOST?z-mm=MIN,MAX` ([`RuidaAddress`]), and
//! with the `sim` feature the simulated controller of `kerfmeter-ruida`'s `twin` on loopback UDP
//! (`ruida-sim`).
//!
//! - [`steps`]: the G-code Kerfmeter writes, read as cut programs (layers of polylines with
//!   their speed and power, arcs flattened within 1 µm) and direct moves, anything else refused
//!   before a byte is sent. The loop speaks one program language; its travel checks read it for
//!   both controllers.
//! - [`RuidaCutter`]: the driver on the protocol crate's UDP link: connect (a status read that
//!   must be answered and idle, the bed from its registers, the head), the travel (the bed from
//!   the registers or the address, the prongs' axis from the address), each program checked
//!   against it before anything is sent, packets sent one at a time and a program packet never
//!   twice, the machine polled busy/idle, and every failure and `cancel` ended by a stop
//!   (`D8 01`) confirmed by an idle status read, or [`CutterError::NotStopped`]
//!   (exit 5).
//! - [`RuidaFailure`]: what a Ruida controller can fail with, inside
//!   [`CutterError::Ruida`].
//!
//! What only a real controller can tell (the status bits, whether a program needs `D8 00` to
//! start, a `D9` move's speed, the laser's own state) is listed in `docs/ruida.md`: the driver
//! takes "idle after `D8 01`" as the laser off, which no register is known to confirm.

mod address;
mod driver;
mod error;
mod job;
mod send;
#[cfg(feature = "sim")]
mod sim;
pub mod steps;

pub use address::{ProngAxis, RuidaAddress};
pub use driver::{RuidaCutter, Timing};
pub use error::RuidaFailure;
#[cfg(feature = "sim")]
pub use sim::SIM_Z_TRAVEL_MM;

use crate::grbl::{CutterAddress, CutterError};

/// Open the Ruida controller `address` names: `ruida:…` over the network (its bed from its
/// registers, else the address's `bed-mm`, else `bed_mm`: `job --bed-mm`), or with the `sim`
/// feature `ruida-sim`, the simulated controller on a bed of `bed_mm` (600 × 400 mm when
/// `None`). Any other address is not a Ruida one.
pub fn open(address: &CutterAddress, bed_mm: Option<[f64; 2]>) -> Result<RuidaCutter, CutterError> {
    match address {
        CutterAddress::Ruida { address } => {
            let address = RuidaAddress {
                fallback_bed_mm: bed_mm,
                ..address.parse()?
            };
            RuidaCutter::open(&address, Timing::default())
        }
        #[cfg(feature = "sim")]
        CutterAddress::RuidaSim => RuidaCutter::sim(sim::twin_config(bed_mm), Timing::sim()),
        #[cfg(not(feature = "sim"))]
        CutterAddress::RuidaSim => {
            let _ = bed_mm;
            Err(CutterError::Sim(
                "this program was built without the `sim` feature".into(),
            ))
        }
        other => Err(CutterError::BadAddress(other.to_string())),
    }
}
