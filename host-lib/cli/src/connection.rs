//! The global flags (port, simulated device and its plant, `--json`, timeout, the history's
//! database) and the connection they open: a real port, found by its USB ids or named, or the
//! in-process digital twin.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use kerfmeter::protocol::G2Variant;
use kerfmeter::sim::{PlantParamError, PlantParams, SimDevice, SimMaterial, SimOptions};
use kerfmeter::{Kerfmeter, Options};
use kerfmeter_app::measure::RunReport;

use crate::error::CliError;

/// The simulated device's kerf, µm, when none is given.
const SIM_KERF_UM: f64 = 150.0;
/// The simulated device's seed when none is given.
const SIM_SEED: u64 = 1;

/// Flags every command takes (cloned by `kerfmeter serve`, which re-opens the device with them).
/// Where every command's help lists the options that are not its own: how to reach the device
/// and how to print.
const GLOBAL_HEADING: &str = "Device and output (any command)";
/// ... and how the simulated device is set up (with `--sim`).
const SIM_HEADING: &str = "Simulated device (with --sim)";

#[derive(Args, Clone)]
pub struct Global {
    /// Serial port of the device (e.g. /dev/ttyACM0). Also from KERFMETER_PORT.
    #[arg(long, global = true, help_heading = GLOBAL_HEADING, env = "KERFMETER_PORT", conflicts_with = "sim")]
    pub port: Option<String>,
    /// Use the simulated device (the digital twin) instead of hardware; with `lightburn`, a
    /// LightBurn twin instead of LightBurn.
    #[arg(long, global = true, help_heading = GLOBAL_HEADING)]
    pub sim: bool,
    /// Simulated device: nominal kerf of the gauges its cutter cuts, µm (each gauge's true kerf
    /// adds the cut's own bias and spread, which `run --json` reports as sim_truth_um).
    #[arg(long, global = true, help_heading = SIM_HEADING, default_value_t = SIM_KERF_UM, value_name = "UM")]
    pub sim_kerf_um: f64,
    /// Simulated device: gauge-to-gauge spread (SD) of the simulated cutter's kerf, µm.
    #[arg(long, global = true, help_heading = SIM_HEADING, default_value_t = 0.0, value_name = "UM")]
    pub sim_kerf_sd_um: f64,
    /// Simulated device: seed of every random number (same seed, same gauges and plant; a
    /// reading can still move by tenths of a µm, as the host's requests reach the twin when the
    /// machine's scheduling lets them).
    #[arg(long, global = true, help_heading = SIM_HEADING, default_value_t = SIM_SEED)]
    pub sim_seed: u64,
    /// Simulated device: inject a fault (parity, magnet-lost, miso-stuck, no-inset,
    /// motor-disconnected, driver-fault, over-current, host-silent, prong-slip).
    #[arg(long, global = true, help_heading = SIM_HEADING, value_name = "NAME")]
    pub sim_fault: Option<kerfmeter::sim::SimFault>,
    /// Simulated device: the encoder on the motor shaft, so configured in its flash: from
    /// power-up it refuses runs until `confirm-zero` (its hub stands at its mark). Every --sim
    /// command starts a fresh twin: to confirm, then measure, use one that lives on (`serve`,
    /// or `kerfmeter-twin --encoder-on-motor-shaft` and --port).
    #[arg(long, global = true, help_heading = SIM_HEADING)]
    pub sim_encoder_on_motor_shaft: bool,
    /// Simulated device: a chip without ADC calibration eFuses; its current sense reads 35 %
    /// high, and it reports `adc-uncalibrated`.
    #[arg(long, global = true, help_heading = SIM_HEADING)]
    pub sim_adc_uncalibrated: bool,
    /// Simulated device: the Pololu G2 variant it is built with (18v17, 24v13, 24v21): its
    /// current-sense gain and the highest supply it accepts.
    #[arg(long, global = true, help_heading = SIM_HEADING, value_name = "VARIANT")]
    pub sim_driver: Option<G2Variant>,
    /// Simulated device: the motor's leads swapped at the G2 (a wiring mistake): the hub turns
    /// against the direction asked for, which `self-test` and `bringup` catch.
    #[arg(long, global = true, help_heading = SIM_HEADING)]
    pub sim_motor_leads_swapped: bool,
    /// Simulated device: run in real time instead of as fast as the host keeps up.
    #[arg(long, global = true, help_heading = SIM_HEADING)]
    pub sim_realtime: bool,
    /// Simulated device: the gauge's material (mdf, plywood, acrylic, cardboard), setting the
    /// contact's stiffness and friction and their spread.
    #[arg(long, global = true, help_heading = SIM_HEADING, value_name = "NAME")]
    pub sim_material: Option<SimMaterial>,
    /// Simulated device: plant parameters from a JSON object of numbers ({"supply_v": 24, ...}),
    /// applied over the material.
    #[arg(long, global = true, help_heading = SIM_HEADING, value_name = "FILE")]
    pub sim_plant_file: Option<PathBuf>,
    /// Simulated device: set one plant parameter, applied last (repeatable), e.g. supply_v=24.
    /// An unknown name lists every parameter with its range.
    #[arg(long, global = true, help_heading = SIM_HEADING, value_name = "NAME=VALUE")]
    pub sim_plant: Vec<String>,
    /// Print one JSON object instead of text.
    #[arg(long, global = true, help_heading = GLOBAL_HEADING)]
    pub json: bool,
    /// The measurement history's SQLite file, in a folder that exists [default:
    /// kerfmeter/history.sqlite3 in the user's data directory]. Also from KERFMETER_DB.
    #[arg(long, global = true, help_heading = GLOBAL_HEADING, env = "KERFMETER_DB", value_name = "FILE")]
    pub db: Option<PathBuf>,
    /// Per-attempt response timeout, ms.
    #[arg(long, global = true, help_heading = GLOBAL_HEADING, default_value_t = 300, value_parser = clap::value_parser!(u64).range(10..=60_000))]
    pub timeout_ms: u64,
}

/// The connection: a real port, or the twin (kept alive as long as the client).
pub struct Session {
    /// The client.
    pub meter: Kerfmeter,
    /// The twin behind it, when simulated.
    pub sim: Option<SimDevice>,
}

impl Session {
    /// `report`, with the twin's truth beside each reading when the device is the twin.
    pub fn with_twin_truth(&self, report: RunReport) -> RunReport {
        match &self.sim {
            Some(sim) => {
                report.with_twin_truth(sim.options().kerf_um, sim.options().kerf_sd_um, |run_id| {
                    sim.truth_um(run_id)
                })
            }
            None => report,
        }
    }
}

impl Global {
    /// Before a measurement: the folder of a history the user named (`--db`, `KERFMETER_DB`)
    /// exists. The history is written once the gauge is measured, when a mistyped folder could
    /// only be warned about.
    pub fn check_db_folder(&self) -> Result<(), kerfmeter_history::Error> {
        self.db
            .as_deref()
            .map_or(Ok(()), kerfmeter_history::History::check_folder)
    }

    /// The client's options.
    fn client_options(&self) -> Options {
        Options {
            timeout: Duration::from_millis(self.timeout_ms),
            ..Options::default()
        }
    }

    /// The twin's options, with its cutter's kerf and its seed.
    fn sim_options(&self, kerf_um: f64, seed: u64) -> Result<SimOptions, CliError> {
        let plant = PlantParams::build(
            self.sim_material,
            self.sim_plant_file.as_deref(),
            &self.sim_plant,
        )
        .map_err(|e| match e {
            // A file that cannot be read or parsed is a file error (exit 4), as for a plan.
            PlantParamError::File { path, reason } => CliError::Meter(kerfmeter::Error::File {
                path: path.into(),
                message: format!("plant parameter file: {reason}"),
            }),
            other => CliError::Usage(other.to_string()),
        })?;
        Ok(SimOptions {
            kerf_um,
            kerf_sd_um: self.sim_kerf_sd_um,
            seed,
            fault: self.sim_fault,
            realtime: self.sim_realtime,
            plant,
            encoder_on_motor_shaft: self.sim_encoder_on_motor_shaft,
            adc_uncalibrated: self.sim_adc_uncalibrated,
            motor_leads_swapped: self.sim_motor_leads_swapped,
            driver: self.sim_driver.unwrap_or_default(),
            ..SimOptions::default()
        })
    }

    /// True when a flag that only the simulated device understands was given (the kerf, its
    /// spread and the seed, which have defaults, when they differ from them).
    fn sim_flags_given(&self) -> bool {
        self.sim_fault.is_some()
            || self.sim_realtime
            || self.sim_encoder_on_motor_shaft
            || self.sim_adc_uncalibrated
            || self.sim_motor_leads_swapped
            || self.sim_driver.is_some()
            || self.sim_material.is_some()
            || self.sim_plant_file.is_some()
            || !self.sim_plant.is_empty()
            || self.sim_kerf_um != SIM_KERF_UM
            || self.sim_kerf_sd_um != 0.0
            || self.sim_seed != SIM_SEED
    }

    /// A fresh twin cutting `kerf_um` with `seed` (the other simulated flags as given).
    pub fn connect_sim(&self, kerf_um: f64, seed: u64) -> Result<Session, CliError> {
        let (sim, meter) =
            SimDevice::connect(self.sim_options(kerf_um, seed)?, self.client_options())?;
        Ok(Session {
            meter,
            sim: Some(sim),
        })
    }

    /// Connect as the flags say: the twin with `--sim`, else `--port` or the discovered device.
    pub fn connect(&self) -> Result<Session, CliError> {
        if self.sim {
            return self.connect_sim(self.sim_kerf_um, self.sim_seed);
        }
        if self.sim_flags_given() {
            return Err(CliError::Usage(
                "the --sim-… options (--sim-kerf-um, --sim-seed, --sim-fault, --sim-material, \
                 --sim-plant, …) set up the simulated device: add --sim, or leave them out to use \
                 the real one"
                    .into(),
            ));
        }
        let meter = match &self.port {
            Some(path) => Kerfmeter::open_with(path, self.client_options())?,
            None => Kerfmeter::discover(self.client_options())?,
        };
        Ok(Session { meter, sim: None })
    }
}
