//! What the device reports: run state, latched faults, the kerf result with its quality flags,
//! the (time, torque, angle) sample log and the self-test report.

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::messages::varint_len;

/// Why the device stopped the motor on its own. Latched until `ClearFault` or `Reset`.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// The run took longer than `RunParams::max_time_ms`.
    MaxRunTime,
    /// The inset turned past the gauge's disengage angle without jamming.
    Overtravel,
    /// Torque above breakaway but no motion: no inset in the gauge, or the motor is disconnected.
    NoMotion,
    /// The hub turned against the commanded direction.
    ReverseMotion,
    /// Too many consecutive encoder read errors (parity, error flag, impossible jumps).
    EncoderErrors,
    /// Encoder diagnostics failed: offset compensation not finished, or a stuck bus.
    EncoderDiagnostics,
    /// Magnet field too weak or too strong (magnet lost, or too far from / too close to the chip).
    Magnet,
    /// Motor current above `DeviceConfig::max_current_a`.
    OverCurrent,
    /// The motor driver pulled its FLT line low (on the G2 18v17: a short or under-voltage; it
    /// reports no over-temperature on FLT).
    DriverFault,
    /// The host sent nothing for `RunParams::host_timeout_ms` during a run, or for a
    /// second during a reset or a self-test (the firmware's default host timeout).
    HostSilent,
    /// A control step ran late: the loop could not keep its rate.
    StepOverrun,
    /// `Reset` could not bring the hub back to zero in time.
    ResetFailed,
}

impl Fault {
    /// Every fault, in wire order (`ALL[i]` is variant index `i`).
    pub const ALL: &'static [Self] = &[
        Self::MaxRunTime,
        Self::Overtravel,
        Self::NoMotion,
        Self::ReverseMotion,
        Self::EncoderErrors,
        Self::EncoderDiagnostics,
        Self::Magnet,
        Self::OverCurrent,
        Self::DriverFault,
        Self::HostSilent,
        Self::StepOverrun,
        Self::ResetFailed,
    ];
}

/// What the device is doing.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RunState {
    /// Motor in its safe state, ready for a run.
    Idle,
    /// Turning slowly through the hole play until the prongs drag the inset.
    Engaging,
    /// Ramping torque along τ(θs) while the inset turns.
    Ramping,
    /// The inset has stopped: holding torque while the jam angle is measured.
    Jammed,
    /// Unloading the gauge.
    Releasing,
    /// A result is ready (`GetKerf`); motor in its safe state.
    Done,
    /// Driving the hub back to its zero position.
    Resetting,
    /// Running the self-test.
    SelfTest,
    /// A fault is latched; motor in its safe state.
    Fault(Fault),
}

/// Answer to `GetStatus`.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status {
    /// What the device is doing.
    pub state: RunState,
    /// Id of the current or last run (0: none since boot).
    pub run_id: u32,
    /// Time since the current run started, ms.
    pub elapsed_ms: u32,
    /// Output torque commanded now, N·m.
    pub torque_nm: f32,
    /// Hub angle from its zero position, degrees, positive in the jam direction.
    pub angle_deg: f32,
    /// Samples recorded in the log so far.
    pub samples: u16,
    /// Encoder read errors ridden through since the run started (reported, not hidden).
    pub encoder_errors: u16,
    /// Motor supply (the driver's `VIN`), volts, as the controller uses it: the measured supply,
    /// low-pass filtered (a 32 ms time constant), the bus voltage under whatever load the motor
    /// draws now; `None` where the board does not measure it (the device then assumes
    /// [`REFERENCE_SUPPLY_V`](crate::REFERENCE_SUPPLY_V)).
    pub supply_v: Option<f32>,
    /// The longest control step since boot, µs (a tick's whole work, drivers included).
    pub longest_step_us: u32,
    /// The longest time between the starts of two control steps since boot, µs (the control
    /// period is 1000 µs at 1 kHz).
    pub longest_gap_us: u32,
    /// The idle conditions that stand now (see [`Conditions`]).
    pub conditions: Conditions,
}

/// Idle conditions: what the inputs say is wrong while the motor is at rest, updated every tick
/// and cleared when it goes away (and, from protocol 2.5, [`Conditions::HUB_TURN_UNKNOWN`],
/// which the user clears). A condition latches no fault and blocks no configuration; a
/// [`Conditions::BLOCKING`] one refuses `Run`, `Reset` and `SelfTest` with
/// `ErrorCode::Blocked(conditions)`, `HUB_TURN_UNKNOWN` `Run` only
/// ([`Conditions::BLOCKING_RUN`]). During a run, reset or self-test the inputs latch the typed
/// [`Fault`] instead (the motor is made safe that tick).
#[derive(Serialize, Deserialize, MaxSize, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Conditions(pub u16);

/// `Conditions(no-magnet|driver-fault)`: the names, and any unknown bits in hex.
impl core::fmt::Debug for Conditions {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("Conditions(")?;
        let mut sep = "";
        for name in self.names() {
            write!(f, "{sep}{name}")?;
            sep = "|";
        }
        let unknown = self.0 & !Self::KNOWN.0;
        if unknown != 0 {
            write!(f, "{sep}{unknown:#x}")?;
        }
        f.write_str(")")
    }
}

impl Conditions {
    /// The encoder reports its magnet field out of band: no magnet, or one too far from or too
    /// close to the chip (as [`Fault::Magnet`] during a run).
    pub const NO_MAGNET: Self = Self(1 << 0);
    /// The encoder's own diagnostics fail: offset compensation not finished, or a stuck bus (as
    /// [`Fault::EncoderDiagnostics`]).
    pub const ENCODER_DIAGNOSTICS: Self = Self(1 << 1);
    /// The encoder cannot be read: every read of the last ticks failed (as
    /// [`Fault::EncoderErrors`]).
    pub const ENCODER_UNREADABLE: Self = Self(1 << 2);
    /// The motor driver holds its FLT line low: most often its motor supply is off or below the
    /// driver's under-voltage lockout; also a short (as [`Fault::DriverFault`]).
    pub const DRIVER_FAULT: Self = Self(1 << 3);
    /// The measured motor supply ([`Status::supply_v`], filtered) is outside the rated
    /// [`SUPPLY_MIN_V`](crate::SUPPLY_MIN_V)–[`SUPPLY_MAX_V`](crate::SUPPLY_MAX_V), or (from
    /// protocol 2.6) above the motor driver's safe maximum
    /// ([`G2Variant::supply_max_v`](crate::G2Variant::supply_max_v): 24 V on the G2 18v17), by
    /// more than the supply sense's own uncertainty (2 % of the reading and the ADC's ±0.46 V
    /// through the divider), at rest (protocol 2.1). Unlike the others it
    /// latches no fault during a run: a bus that sags under load is expected, and what matters
    /// then is whether the torque can still be delivered (see [`QualityFlags::SUPPLY_LIMITED`]).
    /// Never set where the supply is not measured.
    pub const SUPPLY_OUT_OF_RANGE: Self = Self(1 << 4);
    /// Every condition above blocks a run, a reset and a self-test.
    pub const BLOCKING: Self = Self(0b1_1111);
    /// The encoder is on the motor shaft and the device cannot tell which motor turn the hub is
    /// on (protocol 2.5): set at power-up, as the encoder fixes the hub only modulo one motor turn
    /// (360°/gear ratio of hub angle) and its count may then take the wrong one, which would
    /// align the prongs a motor turn away from the gauge's holes. Blocks a run only (a reset
    /// turns the hub to the nearest zero of the count, a self-test needs no zero) until the user
    /// has turned the hub to its zero mark and sent [`Request::ConfirmHubAtZero`](crate::Request).
    pub const HUB_TURN_UNKNOWN: Self = Self(1 << 5);
    /// What blocks a run: every [`Conditions::BLOCKING`] one and [`Conditions::HUB_TURN_UNKNOWN`].
    pub const BLOCKING_RUN: Self = Self::BLOCKING.union(Self::HUB_TURN_UNKNOWN);
    /// The chip has no ADC calibration eFuses (protocol 2.6): esp-hal calibrates its readings
    /// against an assumed reference, and the current sense reads some 30–40 % high (see
    /// `Diagnostics::adc_calibration`). Stands from boot; blocks nothing (a measurement's
    /// torque is set from the duty, not the current), but the torque-constant check of a
    /// self-test and the winding estimate see the error.
    pub const ADC_UNCALIBRATED: Self = Self(1 << 6);
    /// Every condition this protocol knows.
    pub const KNOWN: Self = Self::BLOCKING_RUN.union(Self::ADC_UNCALIBRATED);

    /// Names of the conditions, for messages and JSON.
    pub const NAMES: [(Self, &'static str); 7] = [
        (Self::NO_MAGNET, "no-magnet"),
        (Self::ENCODER_DIAGNOSTICS, "encoder-diagnostics"),
        (Self::ENCODER_UNREADABLE, "encoder-unreadable"),
        (Self::DRIVER_FAULT, "driver-fault"),
        (Self::SUPPLY_OUT_OF_RANGE, "supply-out-of-range"),
        (Self::HUB_TURN_UNKNOWN, "hub-turn-unknown"),
        (Self::ADC_UNCALIBRATED, "adc-uncalibrated"),
    ];

    /// No condition.
    pub const fn empty() -> Self {
        Self(0)
    }
    /// True when every condition of `other` stands.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    /// The conditions of both.
    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }
    /// The conditions of `self` that are also in `other`.
    pub const fn intersection(self, other: Self) -> Self {
        Self(self.0 & other.0)
    }
    /// Set (`on`) or clear the conditions of `other`.
    pub fn set(&mut self, other: Self, on: bool) {
        if on {
            self.0 |= other.0;
        } else {
            self.0 &= !other.0;
        }
    }
    /// True when no condition stands.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// The names of the conditions that stand.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::NAMES
            .into_iter()
            .filter(move |(c, _)| self.contains(*c))
            .map(|(_, name)| name)
    }
}

/// Quality flags of a [`KerfResult`]: a set bit is a reason to distrust the number.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QualityFlags(pub u16);

impl QualityFlags {
    /// The jam angle is within 10 % of the gauge's disengage angle.
    pub const NEAR_DISENGAGE: Self = Self(1 << 0);
    /// The held angle drifted during the hold window: the jam was still moving while it was
    /// read (protocol 2.3: before, any spread of a few LSB, which the encoder's noise alone
    /// gives).
    pub const NOISY_HOLD: Self = Self(1 << 1);
    /// The magnet field was at the edge of its band during the run.
    pub const WEAK_MAGNET: Self = Self(1 << 2);
    /// Encoder read errors were ridden through during the run.
    pub const ENCODER_ERRORS: Self = Self(1 << 3);
    /// The torque limit was reached before the target force: the jam is at a lower force.
    pub const TORQUE_LIMITED: Self = Self(1 << 4);
    /// The hole-play fixed point did not converge (never expected; the value is the last iterate).
    pub const PLAY_NOT_CONVERGED: Self = Self(1 << 5);
    /// The sample log was decimated (a long run); the curve has coarser time steps.
    pub const DECIMATED: Self = Self(1 << 6);
    /// The motor supply, sagging under load, could not deliver the torque the run asked for: the
    /// torque was held to what it delivered (at full duty), so the jam is at a lower force, which
    /// `torque_at_jam_nm` and `force_at_jam_n` report (protocol 2.1).
    pub const SUPPLY_LIMITED: Self = Self(1 << 7);
    /// The torque set from the duty and the motor current measured at the jam disagree beyond
    /// what the winding's temperature and the current and supply senses' gain errors explain (a
    /// wrong `torque_per_duty_nm` or `torque_per_amp_nm`, a driver limiting its current below
    /// the motor's stall current, a loose lead): the torque at the jam, and so the force, is not
    /// the one reported (protocol 2.2).
    pub const TORQUE_MISMATCH: Self = Self(1 << 8);
    /// The reading depends on the force more than the device's torque is known: the kerf it
    /// read moved so far over the last part of the torque ramp that the torque's uncertainty
    /// (the senses' gain errors, the winding's temperature) could move it by more than the
    /// device's accuracy. A soft gauge material or a contact still creeping (protocol 2.3).
    pub const FORCE_SENSITIVE: Self = Self(1 << 9);
    /// The hole play in the reading is the spiral model's, not measured: the back-off after the
    /// release found no stall on the holes' far faces, or one too far from the model's, or was
    /// not made (no run time left for it, an encoder on the motor shaft, a light hold, a fault
    /// or abort during it). Such a reading is as good as every reading before protocol 2.4: on a
    /// tapered cut or with the head back off the gauge's centre, a micrometre or a few low
    /// (protocol 2.4). Advisory: it does not distrust the number ([`QualityFlags::ADVISORY`]).
    pub const PLAY_MODELLED: Self = Self(1 << 10);

    /// The flags that do not distrust the number: `decimated` (the curve is only coarser) and
    /// `play-modelled` (the model's play, as every reading before protocol 2.4). A measurement
    /// with any other flag is not trusted (the job stops, the history leaves it out of a label's
    /// drift, the robustness sweep counts it as flagged).
    pub const ADVISORY: Self = Self(Self::DECIMATED.0 | Self::PLAY_MODELLED.0);

    /// Names of the flags, for messages.
    pub const NAMES: [(Self, &'static str); 11] = [
        (Self::NEAR_DISENGAGE, "near-disengage"),
        (Self::NOISY_HOLD, "noisy-hold"),
        (Self::WEAK_MAGNET, "weak-magnet"),
        (Self::ENCODER_ERRORS, "encoder-errors"),
        (Self::TORQUE_LIMITED, "torque-limited"),
        (Self::PLAY_NOT_CONVERGED, "play-not-converged"),
        (Self::DECIMATED, "decimated"),
        (Self::SUPPLY_LIMITED, "supply-limited"),
        (Self::TORQUE_MISMATCH, "torque-mismatch"),
        (Self::FORCE_SENSITIVE, "force-sensitive"),
        (Self::PLAY_MODELLED, "play-modelled"),
    ];

    /// No flag set.
    pub const fn empty() -> Self {
        Self(0)
    }
    /// True when every flag of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    /// Set the flags of `other`.
    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }
    /// Clear the flags of `other`.
    pub fn remove(&mut self, other: Self) {
        self.0 &= !other.0;
    }
    /// The flags that distrust the number: all but the [`QualityFlags::ADVISORY`] ones.
    pub const fn distrusting(self) -> Self {
        Self(self.0 & !Self::ADVISORY.0)
    }
    /// Whether the flag named `name` is advisory ([`QualityFlags::ADVISORY`]).
    pub fn is_advisory_name(name: &str) -> bool {
        Self::ADVISORY.names().any(|n| n == name)
    }
    /// True when no flag is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// The names of the set flags.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::NAMES
            .into_iter()
            .filter(move |(f, _)| self.contains(*f))
            .map(|(_, name)| name)
    }
}

/// The result of one measurement.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct KerfResult {
    /// Which run produced it.
    pub run_id: u32,
    /// Kerf (full cut width), µm, corrected for the hole play.
    pub kerf_um: f32,
    /// Measured hub angle at the jam θm (median over the hold window), degrees.
    pub angle_deg: f32,
    /// Hole play included in `angle_deg`, degrees: measured by backing the hub off against the
    /// jammed inset after the release (half the turn between the holes' two faces), or, where
    /// that found no stall or one too far from the model, the model's θplay(k). The same at
    /// every force: the host reads the sweep (`GetSamples`) with it.
    pub play_deg: f32,
    /// Output torque at the jam, N·m: the one held, or, where the winding check after the probe
    /// found the hold's torque off (a winding the jam's duty could not measure), the one it
    /// really drove. The curve (`GetSamples`) logs the commanded torque.
    pub torque_at_jam_nm: f32,
    /// Joint assembly force this torque represents, N.
    pub force_at_jam_n: f32,
    /// Reasons to distrust the number.
    pub flags: QualityFlags,
}

/// One point of the sample log.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// Time since the run started, ms.
    pub t_ms: u32,
    /// Commanded output torque, N·m.
    pub torque_nm: f32,
    /// Hub angle from zero, degrees, positive in the jam direction.
    pub angle_deg: f32,
}

/// Samples per `GetSamples` answer.
pub const SAMPLES_PER_CHUNK: usize = 32;

/// Answer to `GetSamples`: up to [`SAMPLES_PER_CHUNK`] samples from index `from`.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleChunk {
    /// The run they belong to.
    pub run_id: u32,
    /// Index of the first sample in `samples`.
    pub from: u16,
    /// Samples in the whole log.
    pub total: u16,
    /// The log keeps one sample per this many control ticks (grows when a long run is decimated).
    pub ticks_per_sample: u16,
    /// The samples.
    pub samples: heapless::Vec<Sample, SAMPLES_PER_CHUNK>,
}

impl MaxSize for SampleChunk {
    const POSTCARD_MAX_SIZE: usize = u32::POSTCARD_MAX_SIZE
        + 3 * u16::POSTCARD_MAX_SIZE
        + varint_len(SAMPLES_PER_CHUNK)
        + SAMPLES_PER_CHUNK * Sample::POSTCARD_MAX_SIZE;
}

/// Outcome of one self-test item.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TestOutcome {
    /// Within limits.
    Pass,
    /// Out of limits.
    Fail,
    /// Not run (an earlier item failed).
    Skipped,
}

/// One self-test item with its measured value.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfTestItem {
    /// Pass, fail or skipped.
    pub outcome: TestOutcome,
    /// The measured value (unit given by the field's name in [`SelfTestReport`]).
    pub value: f32,
}

/// Answer to `SelfTest`.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfTestReport {
    /// Encoder reads without error over the test, as a fraction (0..1).
    pub encoder_ok_fraction: SelfTestItem,
    /// Magnet field magnitude (CORDIC magnitude, 0..16383).
    pub magnet_magnitude: SelfTestItem,
    /// Hub motion in the commanded direction, degrees (negative: wired backwards).
    pub direction_deg: SelfTestItem,
    /// Estimated output torque at full duty, N·m.
    pub torque_per_duty_nm: SelfTestItem,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_all_is_every_variant_in_wire_order() {
        // `ALL[i]` encodes as variant index `i`, and the index one past the list is not a
        // variant: the list is complete, in order and without repeats.
        let mut buf = [0u8; 4];
        for (i, fault) in Fault::ALL.iter().enumerate() {
            let bytes = postcard::to_slice(fault, &mut buf).unwrap();
            assert_eq!(bytes, [i as u8], "{fault:?}");
        }
        let past_the_end = [Fault::ALL.len() as u8];
        assert!(postcard::from_bytes::<Fault>(&past_the_end).is_err());
    }

    #[test]
    fn conditions_debug_names_them() {
        extern crate std;
        use std::format;
        let c = Conditions::NO_MAGNET.union(Conditions::DRIVER_FAULT);
        assert_eq!(format!("{c:?}"), "Conditions(no-magnet|driver-fault)");
        assert_eq!(format!("{:?}", Conditions::empty()), "Conditions()");
        assert_eq!(
            format!("{:?}", Conditions(0xa0)),
            "Conditions(hub-turn-unknown|0x80)"
        );
        assert_eq!(
            format!("{:?}", Conditions(0x50)),
            "Conditions(supply-out-of-range|adc-uncalibrated)"
        );
    }
}
