//! The Kerfmeter wire protocol, shared by the device firmware and the host library.
//!
//! `no_std`, no allocation: the same types and the same framing code run on the ESP32 and on a PC.
//! So does the gauge's model, [`spiral`]: hole play, the kerf from a jam angle, the torque for a
//! joint force and the spiral's pitch, shared by the device, its digital twin, the host and the
//! gauge drawer.
//!
//! # Wire format
//!
//! Every message travels as one frame:
//!
//! ```text
//!   0x00 │ COBS( postcard(Envelope<Request|Response>) ‖ CRC-16/IBM-SDLC little-endian ) │ 0x00
//!   ^^^^                                                                                 ^^^^
//!   optional leading delimiter (flushes                                    frame delimiter
//!   any garbage before the frame)
//!
//!   Envelope = seq: varint u16 │ body: varint variant index │ variant fields (postcard)
//! ```
//!
//! - **COBS** removes every `0x00` from the payload, so `0x00` only ever means "end of frame". A
//!   receiver that sees garbage (the ESP32-C3 ROM prints a boot banner on the same USB port) drops
//!   bytes until the next `0x00` and starts afresh: it *resynchronises*. Senders put an extra `0x00`
//!   before every frame so that a frame following garbage is not glued to it. Empty frames (two
//!   `0x00` in a row) are ignored.
//! - **CRC-16** (`CRC_16_IBM_SDLC`, the HDLC/X.25 checksum) over the postcard bytes catches what COBS
//!   does not: flipped bits and dropped bytes inside a frame. A frame that fails it is dropped and
//!   never answered; the host times out and retries.
//! - **`seq`** is chosen by the host and echoed by the device. The device remembers the last `seq`
//!   and its response: a request repeated with the same `seq` (a retry after a lost response) is
//!   answered again from memory, never executed twice. A new request uses a new `seq`.
//! - The device only answers: exactly one response per accepted request, never an unsolicited
//!   frame. Logs go elsewhere (UART0), never into this stream.
//! - Every size is bounded at compile time ([`postcard::experimental::max_size::MaxSize`]):
//!   [`MAX_REQUEST_FRAME_LEN`] and [`MAX_RESPONSE_FRAME_LEN`] are what a receiver must buffer.
//!
//! # Compatibility rules
//!
//! - [`Request::GetInfo`] is variant 0 and [`Response::Info`] is variant 0, and both are frozen
//!   forever, [`DeviceInfo`] included: whatever the versions, a host can always ask a device what it
//!   is and which protocol it speaks.
//! - Adding a request, a response, or an enum variant **at the end** is a *minor* change
//!   ([`PROTOCOL_VERSION`]`.minor += 1`). An older device answers an unknown request with
//!   [`ErrorCode::UnknownRequest`].
//! - Changing or reordering anything that exists (a field, its type, a variant's position) is a
//!   *major* change. Host and device refuse to talk across majors (the host checks
//!   [`DeviceInfo::protocol`] first).
//! - The golden-frame tests in `tests/golden.rs` pin the bytes of existing messages: a wire change
//!   fails them, and the version must move with it.

#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

/// Re-exported: [`HardwareInfo::board`] and [`SampleChunk::samples`] are `heapless` types.
pub use heapless;

#[cfg(feature = "std")]
pub mod advice;
mod diagnostics;
mod frame;
mod messages;
mod params;
mod report;
pub mod spiral;

pub use diagnostics::{
    AdcCalibration, BrownOutDetector, ChipRevision, Diagnostics, EncoderHealth, ResetReason,
};
pub use frame::{
    CRC16, DecodeError, Deframer, DeframerStats, EncodeError, Feed, FrameError,
    MAX_REQUEST_FRAME_LEN, MAX_RESPONSE_FRAME_LEN, encode_frame, max_frame_len,
};
pub use messages::{
    BOARD_NAME_LEN, ConfigReport, DeviceInfo, Envelope, ErrorCode, FirmwareVersion, HardwareInfo,
    OutOfRange, ParamField, ProtocolVersion, Request, Response, START_TOLERANCE_DEG, Shown,
};
pub use params::{
    DeviceConfig, EncoderPlacement, G2Variant, GaugeGeometry, JamDirection, REFERENCE_SUPPLY_V,
    RunParams, SUPPLY_MAX_V, SUPPLY_MIN_V, UnknownG2Variant, WhyInvalid,
};
pub use report::{
    Conditions, Fault, KerfResult, QualityFlags, RunState, SAMPLES_PER_CHUNK, Sample, SampleChunk,
    SelfTestItem, SelfTestReport, Status, TestOutcome,
};

/// The protocol this crate speaks. See the compatibility rules in the crate docs.
///
/// History:
/// - 1.0: the first.
/// - 2.0 (major: fields added to existing structs change their postcard encoding):
///   [`Status`] reports the motor supply, the longest step and gap since boot and the idle
///   [`Conditions`]; [`ConfigReport`] says whether the configuration was `saved`;
///   [`ErrorCode::Blocked`] refuses a run, reset or self-test while a blocking condition stands.
/// - 2.1 (minor, additive): supply-aware torque. [`ErrorCode::SupplyTooLow`] (appended) refuses
///   a run whose torque the measured supply cannot deliver, with the supply and the supply
///   needed; [`Conditions::SUPPLY_OUT_OF_RANGE`] (a new, blocking bit) stands while the supply
///   is outside [`SUPPLY_MIN_V`]–[`SUPPLY_MAX_V`]; [`QualityFlags::SUPPLY_LIMITED`] (a new bit)
///   marks a result whose torque a sagging supply held below the target. An older host shows
///   the new bits as unknown and the new error as a postcard decode failure.
/// - 2.2 (minor, additive): [`QualityFlags::TORQUE_MISMATCH`] (a new bit, 8) marks a result whose
///   torque from the duty and motor current measured at the jam disagree beyond what the
///   winding's temperature and the senses' gain errors explain. An older host shows it as an
///   unknown bit; every 2.1 frame keeps its bytes.
/// - 2.3 (minor, additive): [`QualityFlags::FORCE_SENSITIVE`] (a new bit, 9) marks a result
///   that the torque's uncertainty could move by more than the device's accuracy (a soft gauge
///   material); [`QualityFlags::NOISY_HOLD`] now means a hold that drifted, not one the
///   encoder's noise spread. Every 2.2 frame keeps its bytes.
/// - 2.4 (minor, additive): the hole play is measured by backing the hub off after the
///   release; [`QualityFlags::PLAY_MODELLED`] (a new bit, 10, advisory: see
///   [`QualityFlags::ADVISORY`]) marks a result read with the model's play instead, and
///   `GetKerf` answers only once a run has ended (the back-off completes the result). Every
///   2.3 frame keeps its bytes.
/// - 2.5 (minor, additive): [`Conditions::HUB_TURN_UNKNOWN`] (a new bit, 5, blocking a run
///   only: [`Conditions::BLOCKING_RUN`]) stands after power-up with the encoder on the motor
///   shaft until [`Request::ConfirmHubAtZero`] (appended) says the hub is at its zero mark. An
///   older device answers that request `UnknownRequest`; every 2.4 frame keeps its bytes.
/// - 2.6 (minor, additive): [`Request::GetDiagnostics`] (appended), answered by
///   [`Response::Diagnostics`] (appended): the last reset's reason, the chip revision, the ADC's
///   calibration, the brown-out detector, the current sense asleep and its learnt offset, the
///   encoder's diagnostics, the worst timing since boot and the motor driver ([`G2Variant`],
///   whose safe maximum now bounds the supply check); [`Conditions::ADC_UNCALIBRATED`] (a new
///   bit, 6, blocking nothing). An older device answers the request `UnknownRequest`; every 2.5
///   frame keeps its bytes.
pub const PROTOCOL_VERSION: ProtocolVersion = ProtocolVersion { major: 2, minor: 6 };

/// USB vendor id of the ESP32-C3/C6 USB-Serial-JTAG port (Espressif).
pub const USB_VID_ESPRESSIF: u16 = 0x303A;
/// USB product id of the ESP32-C3/C6 USB-Serial-JTAG port.
pub const USB_PID_SERIAL_JTAG: u16 = 0x1001;
