//! How a twin is set up: the gauge's kerf and its spread, the seed, the physics, the gauge, a
//! fault to inject, and how simulated time runs when the twin is served. One type for every
//! user: in-process tests, the host's `--sim` and the `kerfmeter-twin` binary.

use core::fmt;
use core::ops::RangeInclusive;
use core::str::FromStr;

use kerfmeter_protocol::{G2Variant, GaugeGeometry};

use crate::plant::{PlantParamError, PlantParams};
use crate::serve::Pace;

/// A fault the twin can inject, by the name used everywhere (twin binary, CLI, tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InjectedFault {
    /// Parity and error-flag errors on the encoder bus, all run long: ridden through, counted.
    Parity,
    /// The encoder magnet falls off mid-run.
    MagnetLost,
    /// The encoder's MISO line sticks low mid-run (valid-looking zeros).
    MisoStuck,
    /// No inset under the prongs: they turn freely, nothing jams.
    NoInset,
    /// The motor leads are disconnected (an open winding) from boot: no current, no torque. A
    /// run ends in `NoMotion`; a self-test fails its direction and torque-constant items.
    MotorDisconnected,
    /// The driver pulls FLT low mid-run.
    DriverFault,
    /// A short: the current sense reads far above the limit mid-run (in the drive phase of each
    /// PWM period, where the G2's current sense is valid).
    OverCurrent,
    /// The host stops talking mid-run (the twin ignores it until the device has reacted).
    HostSilent,
    /// A prong slips out of its hole mid-run: the hub turns on without the inset.
    ProngSlip,
}

impl InjectedFault {
    /// Every fault, in a fixed order.
    pub const ALL: [InjectedFault; 9] = [
        InjectedFault::Parity,
        InjectedFault::MagnetLost,
        InjectedFault::MisoStuck,
        InjectedFault::NoInset,
        InjectedFault::MotorDisconnected,
        InjectedFault::DriverFault,
        InjectedFault::OverCurrent,
        InjectedFault::HostSilent,
        InjectedFault::ProngSlip,
    ];

    /// The fault's name.
    pub const fn name(self) -> &'static str {
        match self {
            InjectedFault::Parity => "parity",
            InjectedFault::MagnetLost => "magnet-lost",
            InjectedFault::MisoStuck => "miso-stuck",
            InjectedFault::NoInset => "no-inset",
            InjectedFault::MotorDisconnected => "motor-disconnected",
            InjectedFault::DriverFault => "driver-fault",
            InjectedFault::OverCurrent => "over-current",
            InjectedFault::HostSilent => "host-silent",
            InjectedFault::ProngSlip => "prong-slip",
        }
    }

    /// The typed device fault a run ends in, or `None` for a fault the device rides through.
    pub const fn expected(self) -> Option<kerfmeter_protocol::Fault> {
        use kerfmeter_protocol::Fault;
        match self {
            InjectedFault::Parity => None,
            InjectedFault::MagnetLost => Some(Fault::Magnet),
            InjectedFault::MisoStuck => Some(Fault::EncoderDiagnostics),
            InjectedFault::NoInset => Some(Fault::Overtravel),
            InjectedFault::MotorDisconnected => Some(Fault::NoMotion),
            InjectedFault::DriverFault => Some(Fault::DriverFault),
            InjectedFault::OverCurrent => Some(Fault::OverCurrent),
            InjectedFault::HostSilent => Some(Fault::HostSilent),
            InjectedFault::ProngSlip => Some(Fault::Overtravel),
        }
    }
}

impl fmt::Display for InjectedFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown fault name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownFault(pub String);

impl fmt::Display for UnknownFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown fault `{}`; known faults:", self.0)?;
        for fault in InjectedFault::ALL {
            write!(f, " {fault}")?;
        }
        Ok(())
    }
}

impl std::error::Error for UnknownFault {}

impl FromStr for InjectedFault {
    type Err = UnknownFault;
    fn from_str(s: &str) -> Result<Self, UnknownFault> {
        InjectedFault::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| UnknownFault(s.to_owned()))
    }
}

/// The kerfs a twin accepts, µm.
pub const KERF_RANGE_UM: RangeInclusive<f64> = 0.0..=2000.0;
/// The gauge-to-gauge kerf spreads a twin accepts, µm.
pub const KERF_SD_RANGE_UM: RangeInclusive<f64> = 0.0..=200.0;

/// The cutter repeatabilities a twin accepts (SD of a traced position, each axis), µm: the
/// range of [`PlantParams::hole_position_sd_um`], which it sets.
pub const REPEATABILITY_RANGE_UM: RangeInclusive<f64> = 0.0..=30.0;

/// How a twin is set up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TwinOptions {
    /// Nominal kerf of the gauges placed under the prongs, at mid-sheet, µm. Each gauge's true
    /// kerf is this plus the bias of the place where this twin's gauges are cut (drawn once,
    /// `kerf_location_sd_um`) and its own spread ([`TwinOptions::kerf_sd_um`]).
    pub kerf_um: f64,
    /// Standard deviation of the cutter's kerf from gauge to gauge, µm (0: every gauge the same).
    pub kerf_sd_um: f64,
    /// Seed of every random number (noise, boot id, kerf variation): the same seed gives the same
    /// run.
    pub seed: u64,
    /// The fault to inject, if any.
    pub fault: Option<InjectedFault>,
    /// Served on a port, follow the wall clock instead of running ahead in lock-step (see
    /// [`Pace`]). An in-process twin runs only when told to and ignores this.
    pub realtime: bool,
    /// The physics.
    pub plant: PlantParams,
    /// The gauge that is cut (its sense and pitch must match what the host sends for a reading).
    pub gauge: GaugeGeometry,
    /// The encoder's magnet on the motor shaft, and a configuration saying so in the twin's flash
    /// before it boots: it comes up as such a device does after power-up, its hub's turn unknown
    /// until confirmed (`Conditions::HUB_TURN_UNKNOWN`). The hub stands at its mark.
    pub encoder_on_motor_shaft: bool,
    /// The board's motor driver: its current-sense gain (the twin's `CS`, and the firmware's
    /// division) and its safe maximum supply (the firmware's supply check).
    pub driver: G2Variant,
    /// The chip has no ADC calibration eFuses: its `CS` reads 35 % high
    /// ([`UNCALIBRATED_ADC_GAIN`](crate::sense::UNCALIBRATED_ADC_GAIN)) and the firmware reports
    /// `Conditions::ADC_UNCALIBRATED` (as the board does from its eFuses).
    pub adc_uncalibrated: bool,
    /// The motor's two leads swapped at the G2's `OUTA`/`OUTB` (a build mistake, not a plant
    /// parameter a study draws): the hub turns against the direction `DIR` asks for, as a real
    /// miswired motor does. The self-test's direction item fails, and a person watching the hub
    /// sees it turn the wrong way (`kerfmeter bringup`); `motor_inverted` corrects it.
    pub motor_leads_swapped: bool,
}

impl Default for TwinOptions {
    fn default() -> Self {
        Self {
            kerf_um: 150.0,
            kerf_sd_um: 0.0,
            seed: 1,
            fault: None,
            realtime: false,
            plant: PlantParams::default(),
            gauge: GaugeGeometry::PAPER,
            encoder_on_motor_shaft: false,
            driver: G2Variant::V18v17,
            adc_uncalibrated: false,
            motor_leads_swapped: false,
        }
    }
}

impl TwinOptions {
    /// Check the options a user can set: the kerf within [`KERF_RANGE_UM`], its spread within
    /// [`KERF_SD_RANGE_UM`], every plant parameter within its range.
    pub fn validate(&self) -> Result<(), InvalidOptions> {
        if !KERF_RANGE_UM.contains(&self.kerf_um) {
            return Err(InvalidOptions::Kerf(self.kerf_um));
        }
        if !KERF_SD_RANGE_UM.contains(&self.kerf_sd_um) {
            return Err(InvalidOptions::KerfSpread(self.kerf_sd_um));
        }
        self.plant.validate()?;
        Ok(())
    }

    /// How simulated time runs when the twin is served.
    pub fn pace(&self) -> Pace {
        if self.realtime {
            Pace::RealTime
        } else {
            Pace::LockStep
        }
    }
}

/// Options a twin cannot be built with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvalidOptions {
    /// The kerf, µm, is outside [`KERF_RANGE_UM`].
    #[error("simulated kerf must be between 0 and 2000 µm, got {0}")]
    Kerf(f64),
    /// The kerf spread, µm, is outside [`KERF_SD_RANGE_UM`].
    #[error("simulated kerf spread must be between 0 and 200 µm, got {0}")]
    KerfSpread(f64),
    /// The cutter's repeatability, µm, is outside [`REPEATABILITY_RANGE_UM`].
    #[error("simulated cutter repeatability must be between 0 and 30 µm (SD), got {0}")]
    Repeatability(f64),
    /// A plant parameter is out of its range or contradicts another.
    #[error(transparent)]
    Plant(#[from] PlantParamError),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_out_of_range_values_are_named() {
        assert_eq!(TwinOptions::default().validate(), Ok(()));
        let kerf = TwinOptions {
            kerf_um: -1.0,
            ..TwinOptions::default()
        };
        assert_eq!(kerf.validate(), Err(InvalidOptions::Kerf(-1.0)));
        let spread = TwinOptions {
            kerf_sd_um: 250.0,
            ..TwinOptions::default()
        };
        assert_eq!(spread.validate(), Err(InvalidOptions::KerfSpread(250.0)));
        let nan = TwinOptions {
            kerf_um: f64::NAN,
            ..TwinOptions::default()
        };
        assert!(nan.validate().is_err());
        assert_eq!(
            spread.validate().unwrap_err().to_string(),
            "simulated kerf spread must be between 0 and 200 µm, got 250"
        );
    }

    #[test]
    fn fault_names_round_trip() {
        for fault in InjectedFault::ALL {
            assert_eq!(fault.name().parse::<InjectedFault>(), Ok(fault));
        }
        let err = "magnet".parse::<InjectedFault>().unwrap_err();
        assert!(
            err.to_string()
                .starts_with("unknown fault `magnet`; known faults: parity")
        );
    }
}
