//! The messages: [`Envelope`], [`Request`], [`Response`] and the typed [`ErrorCode`].
//!
//! Variant order is part of the wire format (postcard encodes the variant index): only append.

use postcard::experimental::max_size::MaxSize;
use serde::{Deserialize, Serialize};

use crate::diagnostics::Diagnostics;
use crate::params::{DeviceConfig, RunParams};
use crate::report::{Conditions, Fault, KerfResult, SampleChunk, SelfTestReport, Status};

/// One message with its sequence number. The device echoes the request's `seq` in its response.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Envelope<B> {
    /// Chosen by the host; a retry re-sends the same value (see the crate docs).
    pub seq: u16,
    /// The request or response.
    pub body: B,
}

/// What the host asks. Every request gets exactly one [`Response`].
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// Variant 0, frozen forever: answered with [`Response::Info`] whatever the device's state.
    GetInfo,
    /// Start a measurement. Answered with `Ok` once started; poll [`Request::GetStatus`].
    Run(RunParams),
    /// Current state, torque and angle. Any request feeds the run's communication watchdog.
    GetStatus,
    /// Recorded (time, torque, angle) samples of the last run, starting at index `from`.
    GetSamples {
        /// Index of the first sample wanted.
        from: u16,
    },
    /// The last result, or `None` after a reset or before the first run.
    GetKerf,
    /// Clear the last result and drive the hub back to its zero position.
    Reset,
    /// Stop the motor now (safe state within one control tick) and end the run.
    Abort,
    /// Leave a latched fault (the motor stays in its safe state).
    ClearFault,
    /// Start the self-test (encoder, magnet, drive direction, torque constant) with no gauge
    /// under the prongs: the hub turns a little each way. Answered with `Ok` once started.
    SelfTest,
    /// Read the stored device configuration.
    GetConfig,
    /// Validate, store and apply a new device configuration.
    SetConfig(DeviceConfig),
    /// The last self-test's report (`None` before the first, or while one runs).
    GetSelfTest,
    /// The user says the hub stands at its zero mark, within half a motor turn (protocol 2.5).
    /// With the encoder on the motor shaft the device cannot tell after power-up which motor turn
    /// the hub is on ([`Conditions::HUB_TURN_UNKNOWN`]); this restarts the encoder's turn count
    /// on the motor turn nearest the zero and clears that condition (a `Reset` then brings the
    /// hub to zero exactly). Answered `Ok`; refused while the motor may be driven (`Busy`). With
    /// the encoder on the output shaft there is nothing to confirm: `Ok`, nothing changes.
    ConfirmHubAtZero,
    /// What the device knows about its own health since boot (protocol 2.6): answered with
    /// [`Response::Diagnostics`] in any state. An older device answers `UnknownRequest`.
    GetDiagnostics,
}

/// What the device answers.
// `Samples` dominates the size; there is no heap on the device to box it in, and a response is
// built once per request, so the size costs nothing but stack.
#[allow(clippy::large_enum_variant)]
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Response {
    /// Variant 0, frozen forever: the answer to [`Request::GetInfo`].
    Info(DeviceInfo),
    /// The request was carried out (or started, for `Run`, `Reset` and `SelfTest`).
    Ok,
    /// The request was refused or failed; nothing was changed.
    Error(ErrorCode),
    /// Answer to [`Request::GetStatus`].
    Status(Status),
    /// Answer to [`Request::GetSamples`].
    Samples(SampleChunk),
    /// Answer to [`Request::GetKerf`].
    Kerf(Option<KerfResult>),
    /// Answer to [`Request::GetSelfTest`].
    SelfTest(Option<SelfTestReport>),
    /// Answer to [`Request::GetConfig`] and [`Request::SetConfig`].
    Config(ConfigReport),
    /// Answer to [`Request::GetDiagnostics`] (protocol 2.6).
    Diagnostics(Diagnostics),
}

/// The device's configuration and where it came from.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ConfigReport {
    /// The configuration in use.
    pub config: DeviceConfig,
    /// True when no valid record was found in flash (none, corrupt, or from an incompatible
    /// version) and the defaults are in use.
    pub defaults_in_use: bool,
    /// True when the configuration in use is the one in flash (loaded from it, or saved by this
    /// `SetConfig`); false when it was applied but not saved and lasts until the next boot (no
    /// configuration partition, or one holding a newer firmware's record).
    pub saved: bool,
}

/// A protocol version; see the compatibility rules in the crate docs.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProtocolVersion {
    /// Incompatible changes.
    pub major: u16,
    /// Backward-compatible additions.
    pub minor: u16,
}

impl ProtocolVersion {
    /// True when a peer speaking `other` can be talked to by one speaking `self`.
    pub fn compatible_with(&self, other: &ProtocolVersion) -> bool {
        self.major == other.major
    }
}

/// A firmware version (semver).
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FirmwareVersion {
    /// Major.
    pub major: u16,
    /// Minor.
    pub minor: u16,
    /// Patch.
    pub patch: u16,
}

/// Longest board name in [`HardwareInfo::board`].
pub const BOARD_NAME_LEN: usize = 24;

/// Fixed facts of the hardware and firmware build.
#[derive(Serialize, Deserialize, Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HardwareInfo {
    /// What is answering: `"esp32c3"`, `"esp32c6"`, `"twin"`.
    pub board: heapless::String<BOARD_NAME_LEN>,
    /// Control loop rate, Hz.
    pub control_rate_hz: u16,
    /// Encoder resolution, bits per turn.
    pub encoder_bits: u8,
    /// PWM duty resolution, bits.
    pub pwm_bits: u8,
    /// Capacity of the sample log (samples of one run).
    pub max_samples: u16,
    /// Longest frame the device accepts, bytes.
    pub max_request_frame_len: u16,
}

impl MaxSize for HardwareInfo {
    const POSTCARD_MAX_SIZE: usize = varint_len(BOARD_NAME_LEN)
        + BOARD_NAME_LEN
        + u16::POSTCARD_MAX_SIZE
        + u8::POSTCARD_MAX_SIZE
        + u8::POSTCARD_MAX_SIZE
        + u16::POSTCARD_MAX_SIZE
        + u16::POSTCARD_MAX_SIZE;
}

/// The answer to [`Request::GetInfo`]; frozen forever, so it reports only what never changes
/// while the device runs. The motor supply, a measurement, is in [`Status::supply_v`](crate::Status)
/// instead.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceInfo {
    /// The protocol the device speaks.
    pub protocol: ProtocolVersion,
    /// The firmware build.
    pub firmware: FirmwareVersion,
    /// Random per boot: a change between two calls means the device was reset.
    pub boot_id: u32,
    /// Fixed facts of the hardware.
    pub hardware: HardwareInfo,
}

/// Why a request was refused. The host turns each into a message that says what to do.
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ErrorCode {
    /// The frame was intact but its request is not one this firmware knows (a newer host).
    UnknownRequest,
    /// This firmware build does not implement the request.
    Unsupported,
    /// A run, reset or self-test is in progress; wait for it, or `Abort`.
    Busy,
    /// A fault is latched; the device does nothing else until `ClearFault` (or `Reset`).
    Faulted(Fault),
    /// A parameter is out of its range.
    InvalidParam(ParamField),
    /// `GetSamples` asked past the end of the log, or there is no run to read.
    NoSamples,
    /// The configuration could not be written to flash; the old one is still in use.
    Storage,
    /// A run must start with the hub at its zero position (prongs centred in the gauge's holes),
    /// within [`START_TOLERANCE_DEG`]: send `Reset` first.
    NotAtZero,
    /// `Run`, `Reset` or `SelfTest` refused: these blocking idle conditions stand (no magnet,
    /// driver FLT low with the motor supply off, ...; for `Run` also a motor-shaft hub turn not
    /// confirmed, [`Conditions::BLOCKING_RUN`]). Nothing is latched: fix the cause and retry;
    /// `GetStatus` shows when they are gone.
    Blocked(Conditions),
    /// `Run` refused (protocol 2.1): the torque the run may ask for (the most its target force
    /// needs, at most its `max_torque_nm`) needs more than full duty at the measured motor
    /// supply. Raise the supply to at least `needed_mv`, or ask for less torque (a lower force or
    /// torque cap). The motor did not move.
    SupplyTooLow {
        /// The motor supply as measured (filtered), mV.
        supply_mv: u16,
        /// The least supply at which the run's torque is reachable, mV (saturated at
        /// `u16::MAX`).
        needed_mv: u16,
    },
}

/// How far from its zero position, degrees either way, the hub may stand when a run starts.
/// Further out the device refuses the run with [`ErrorCode::NotAtZero`], and the host resets the
/// hub before a run by the same rule, so the two sides cannot disagree about "at zero".
///
/// Wider than the 0.3° band within which `Reset` settles, so that a hub nudged a little while a
/// gauge is placed needs no second reset; narrow against the hole play (about 4.5° for the
/// paper's gauge) that a run turns through before the prongs drag the inset.
pub const START_TOLERANCE_DEG: f32 = 1.0;

/// A value out of its field's range, as a message ([`ParamField::out_of_range`]): "the joint's
/// assembly force (target_force_n) = 0 N is out of range (allowed 1 to 500 N)".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutOfRange {
    /// The field.
    pub field: ParamField,
    /// The value given, where known.
    pub value: Option<f32>,
}

/// A number as a message shows what was given: as written, but in exponent form when huge or
/// tiny (`{}` writes an `f64` near its limit with 309 digits), and `0` for −0. NaN and
/// infinities as Rust writes them (`NaN`, `inf`, `-inf`).
///
/// ```
/// use kerfmeter_protocol::Shown;
/// assert_eq!(Shown(1e308).to_string(), "1e308");
/// assert_eq!(Shown(-0.0_f64).to_string(), "0");
/// assert_eq!(Shown(152.5_f32).to_string(), "152.5");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shown<T>(pub T);

macro_rules! shown {
    ($t:ty) => {
        impl core::fmt::Display for Shown<$t> {
            fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                let v = self.0;
                if v == 0.0 {
                    f.write_str("0")
                } else if v.is_finite() && (v.abs() >= 1e9 || v.abs() < 1e-6) {
                    write!(f, "{v:e}")
                } else {
                    write!(f, "{v}")
                }
            }
        }
    };
}
shown!(f32);
shown!(f64);

impl core::fmt::Display for OutOfRange {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let (what, unit) = self.field.words();
        let (lo, hi) = self.field.range();
        let space = if unit.is_empty() { "" } else { " " };
        write!(f, "{what} ({})", self.field.name())?;
        if let Some(value) = self.value {
            write!(f, " = {}{space}{unit}", Shown(value))?;
        }
        write!(f, " is out of range (allowed {lo} to {hi}{space}{unit})")
    }
}

/// A parameter of [`RunParams`] or [`DeviceConfig`], named in [`ErrorCode::InvalidParam`].
#[derive(Serialize, Deserialize, MaxSize, Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[allow(missing_docs)] // Each variant names the field of the same name.
pub enum ParamField {
    PitchUmPerDeg,
    RadiusMm,
    ProngRadiusMm,
    HoleRadiusMm,
    HoleDistanceMm,
    DisengageDeg,
    ThicknessMm,
    TargetForceN,
    ContactAreaMm2,
    MaxTorqueNm,
    RampRateNmPerS,
    MaxTimeMs,
    HostTimeoutMs,
    TorquePerDutyNm,
    BreakawayDuty,
    EncoderZeroRaw,
    GearRatio,
    MaxCurrentA,
    TorquePerAmpNm,
}

impl ParamField {
    /// Every field, in wire order (`ALL[i]` is variant index `i`).
    pub const ALL: &'static [Self] = &[
        Self::PitchUmPerDeg,
        Self::RadiusMm,
        Self::ProngRadiusMm,
        Self::HoleRadiusMm,
        Self::HoleDistanceMm,
        Self::DisengageDeg,
        Self::ThicknessMm,
        Self::TargetForceN,
        Self::ContactAreaMm2,
        Self::MaxTorqueNm,
        Self::RampRateNmPerS,
        Self::MaxTimeMs,
        Self::HostTimeoutMs,
        Self::TorquePerDutyNm,
        Self::BreakawayDuty,
        Self::EncoderZeroRaw,
        Self::GearRatio,
        Self::MaxCurrentA,
        Self::TorquePerAmpNm,
    ];

    /// The field's name as it appears in the Rust types and the JSON output.
    pub const fn name(self) -> &'static str {
        match self {
            Self::PitchUmPerDeg => "pitch_um_per_deg",
            Self::RadiusMm => "radius_mm",
            Self::ProngRadiusMm => "prong_radius_mm",
            Self::HoleRadiusMm => "hole_radius_mm",
            Self::HoleDistanceMm => "hole_distance_mm",
            Self::DisengageDeg => "disengage_deg",
            Self::ThicknessMm => "thickness_mm",
            Self::TargetForceN => "target_force_n",
            Self::ContactAreaMm2 => "contact_area_mm2",
            Self::MaxTorqueNm => "max_torque_nm",
            Self::RampRateNmPerS => "ramp_rate_nm_per_s",
            Self::MaxTimeMs => "max_time_ms",
            Self::HostTimeoutMs => "host_timeout_ms",
            Self::TorquePerDutyNm => "torque_per_duty_nm",
            Self::BreakawayDuty => "breakaway_duty",
            Self::EncoderZeroRaw => "encoder_zero_raw",
            Self::GearRatio => "gear_ratio",
            Self::MaxCurrentA => "max_current_a",
            Self::TorquePerAmpNm => "torque_per_amp_nm",
        }
    }

    /// What the field is, in words, and its unit (empty for a ratio), for messages to a user
    /// who set it through a command's option rather than by this name.
    pub const fn words(self) -> (&'static str, &'static str) {
        match self {
            Self::PitchUmPerDeg => ("the gauge's spiral pitch", "µm/°"),
            Self::RadiusMm => ("the gauge's spiral radius", "mm"),
            Self::ProngRadiusMm => ("the prong radius", "mm"),
            Self::HoleRadiusMm => ("the gauge's prong-hole radius", "mm"),
            Self::HoleDistanceMm => ("the prong holes' distance from the centre", "mm"),
            Self::DisengageDeg => ("the gauge's disengage angle", "°"),
            Self::ThicknessMm => ("the sheet thickness", "mm"),
            Self::TargetForceN => ("the joint's assembly force", "N"),
            Self::ContactAreaMm2 => ("the joint's contact area", "mm²"),
            Self::MaxTorqueNm => ("the torque cap", "N·m"),
            Self::RampRateNmPerS => ("the torque ramp rate", "N·m/s"),
            Self::MaxTimeMs => ("the run's time limit", "ms"),
            Self::HostTimeoutMs => ("the host-silence timeout", "ms"),
            Self::TorquePerDutyNm => ("the torque per unit duty at 12 V", "N·m"),
            Self::BreakawayDuty => ("the breakaway duty", ""),
            Self::EncoderZeroRaw => ("the encoder's zero", "counts"),
            Self::GearRatio => ("the gear ratio", ""),
            Self::MaxCurrentA => ("the over-current threshold", "A"),
            Self::TorquePerAmpNm => ("the torque per amp", "N·m/A"),
        }
    }

    /// The message for `value` (`None`: not known) out of this field's range, said in words
    /// with the field's name and unit; `to_string()` it, or write it into a message.
    pub const fn out_of_range(self, value: Option<f32>) -> OutOfRange {
        OutOfRange { field: self, value }
    }

    /// The accepted range (inclusive) of the field. Cross-field rules (the hole must fit inside
    /// the spiral, the hole must be larger than the prong) are reported on the dependent field.
    pub const fn range(self) -> (f32, f32) {
        match self {
            Self::PitchUmPerDeg => (0.5, 20.0),
            Self::RadiusMm => (3.0, 50.0),
            Self::ProngRadiusMm => (0.2, 10.0),
            Self::HoleRadiusMm => (0.2, 10.0),
            Self::HoleDistanceMm => (0.5, 40.0),
            Self::DisengageDeg => (30.0, 300.0),
            Self::ThicknessMm => (0.5, 25.0),
            Self::TargetForceN => (1.0, 500.0),
            Self::ContactAreaMm2 => (1.0, 10_000.0),
            Self::MaxTorqueNm => (0.01, 5.0),
            Self::RampRateNmPerS => (0.01, 20.0),
            Self::MaxTimeMs => (100.0, 120_000.0),
            Self::HostTimeoutMs => (50.0, 60_000.0),
            Self::TorquePerDutyNm => (0.01, 20.0),
            Self::BreakawayDuty => (0.0, 0.5),
            Self::EncoderZeroRaw => (0.0, 16_383.0),
            Self::GearRatio => (1.0, 1_000.0),
            Self::MaxCurrentA => (0.1, 30.0),
            Self::TorquePerAmpNm => (0.001, 10.0),
        }
    }
}

/// Bytes postcard needs for the varint of `n` (for hand-written `MaxSize` bounds).
pub(crate) const fn varint_len(mut n: usize) -> usize {
    let mut len = 1;
    while n >= 0x80 {
        n >>= 7;
        len += 1;
    }
    len
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(o: OutOfRange) -> heapless::String<160> {
        let mut s = heapless::String::new();
        core::fmt::write(&mut s, format_args!("{o}")).unwrap();
        s
    }

    #[test]
    fn a_value_out_of_range_is_said_in_words_with_its_name_and_unit() {
        assert_eq!(
            text(ParamField::TargetForceN.out_of_range(Some(0.0))),
            "the joint's assembly force (target_force_n) = 0 N is out of range (allowed 1 to 500 N)"
        );
        let (lo, hi) = ParamField::GearRatio.range();
        let unknown = text(ParamField::GearRatio.out_of_range(None));
        assert!(
            unknown.starts_with("the gear ratio (gear_ratio) is out of range (allowed"),
            "{unknown}"
        );
        assert!(unknown.ends_with(lo_to_hi(lo, hi).as_str()), "{unknown}");
        // Every field has words.
        for field in ParamField::ALL {
            assert!(field.words().0.starts_with("the "), "{field:?}");
        }
    }

    #[test]
    fn a_value_in_range_against_a_rule_is_said_as_that_rule() {
        let mut params = RunParams::DEFAULT;
        params.gauge.hole_radius_mm = params.gauge.prong_radius_mm - 0.1;
        let field = params.validate().unwrap_err();
        let mut s: heapless::String<300> = heapless::String::new();
        core::fmt::write(&mut s, format_args!("{}", params.why_invalid(field))).unwrap();
        assert!(s.contains("is smaller than the prong radius"), "{s}");
        assert!(!s.contains("out of range"), "{s}");
        params.gauge.hole_radius_mm = f32::NAN;
        s.clear();
        let field = params.validate().unwrap_err();
        core::fmt::write(&mut s, format_args!("{}", params.why_invalid(field))).unwrap();
        assert!(s.contains("= NaN mm is out of range"), "{s}");
    }

    /// "lo to hi)" for a unitless field.
    fn lo_to_hi(lo: f32, hi: f32) -> heapless::String<40> {
        let mut s = heapless::String::new();
        core::fmt::write(&mut s, format_args!("{lo} to {hi})")).unwrap();
        s
    }

    #[test]
    fn param_field_all_is_every_variant_in_wire_order() {
        // `ALL[i]` encodes as variant index `i`, and the index one past the list is not a
        // variant: the list is complete, in order and without repeats.
        let mut buf = [0u8; 4];
        for (i, field) in ParamField::ALL.iter().enumerate() {
            let bytes = postcard::to_slice(field, &mut buf).unwrap();
            assert_eq!(bytes, [i as u8], "{field:?}");
        }
        let past_the_end = [ParamField::ALL.len() as u8];
        assert!(postcard::from_bytes::<ParamField>(&past_the_end).is_err());
    }
}
