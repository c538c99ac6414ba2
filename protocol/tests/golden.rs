//! Golden frames: the exact bytes of representative messages. Any change to the wire format fails
//! here first; when it is intended, bump `PROTOCOL_VERSION` (see the compatibility rules) and
//! update the bytes (the failure message prints the new ones: check that only the intended
//! messages changed). Protocol 2.0 changed `Status` (supply, longest step and gap, conditions)
//! and `ConfigReport` (`saved`), and added `ErrorCode::Blocked`; `DeviceInfo`'s bytes stand.
//! Protocol 2.1 only added: `ErrorCode::SupplyTooLow`, the `SUPPLY_OUT_OF_RANGE` condition and
//! the `SUPPLY_LIMITED` flag (new frames below; every older frame's bytes stand). Protocol 2.2
//! only added the `TORQUE_MISMATCH` flag, bit 8 (its frame below); protocol 2.3 only the
//! `FORCE_SENSITIVE` flag, bit 9 (its frame below); protocol 2.4 only a flag's meaning; protocol
//! 2.5 only the `HUB_TURN_UNKNOWN` condition and the `ConfirmHubAtZero` request (its frame
//! below); protocol 2.6 only the `GetDiagnostics` request, its `Diagnostics` answer and the
//! `ADC_UNCALIBRATED` condition (their frames below). Each golden frame is also
//! mutated byte by byte: no mutation may be accepted.

mod common;
use common::*;
use kerfmeter_protocol::*;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

fn sample_info() -> DeviceInfo {
    DeviceInfo {
        protocol: ProtocolVersion { major: 1, minor: 0 },
        firmware: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        boot_id: 0xDEAD_BEEF,
        hardware: HardwareInfo {
            board: heapless::String::try_from("esp32c3").unwrap(),
            control_rate_hz: 1000,
            encoder_bits: 14,
            pwm_bits: 11,
            max_samples: 2048,
            max_request_frame_len: 80,
        },
    }
}

fn golden_requests() -> Vec<(&'static str, Envelope<Request>)> {
    vec![
        (
            "000201039f1600",
            Envelope {
                seq: 1,
                body: Request::GetInfo,
            },
        ),
        (
            "00070201378931400103204101010a4048e11a409a99a9400101031b4301038040010b5c4233331743cdcc4c3f0109803f904ee807784000",
            Envelope {
                seq: 2,
                body: Request::Run(RunParams::DEFAULT),
            },
        ),
        (
            "0007ac020340031400",
            Envelope {
                seq: 300,
                body: Request::GetSamples { from: 64 },
            },
        ),
        (
            "000dffff030aae47613f0ad7233d01010103a84101010109d0409cc4203ee8b800",
            Envelope {
                seq: 65535,
                body: Request::SetConfig(DeviceConfig::DEFAULT),
            },
        ),
        // Protocol 2.5: appended.
        (
            "0005070c238800",
            Envelope {
                seq: 7,
                body: Request::ConfirmHubAtZero,
            },
        ),
        // Protocol 2.6: appended.
        (
            "0005080d621a00",
            Envelope {
                seq: 8,
                body: Request::GetDiagnostics,
            },
        ),
    ]
}

fn golden_responses() -> Vec<(&'static str, Envelope<Response>)> {
    vec![
        (
            "000201020101020117effdb6f50d0765737033326333e8070e0b801050b13300",
            Envelope {
                seq: 1,
                body: Response::Info(sample_info()),
            },
        ),
        (
            "000502017e2d00",
            Envelope {
                seq: 2,
                body: Response::Ok,
            },
        ),
        (
            "000703020406fd6e00",
            Envelope {
                seq: 3,
                body: Response::Error(ErrorCode::InvalidParam(ParamField::ThicknessMm)),
            },
        ),
        (
            "000704020309238c00",
            Envelope {
                seq: 4,
                body: Response::Error(ErrorCode::Faulted(Fault::HostSilent)),
            },
        ),
        (
            "000708020809bfff00",
            Envelope {
                seq: 8,
                body: Response::Error(ErrorCode::Blocked(
                    Conditions::NO_MAGNET.union(Conditions::DRIVER_FAULT),
                )),
            },
        ),
        (
            "000a0a02098c47fe58e93400",
            Envelope {
                seq: 10,
                body: Response::Error(ErrorCode::SupplyTooLow {
                    supply_mv: 9_100,
                    needed_mv: 11_390,
                }),
            },
        ),
        (
            "00070b0208187adb00",
            Envelope {
                seq: 11,
                body: Response::Error(ErrorCode::Blocked(
                    Conditions::SUPPLY_OUT_OF_RANGE.union(Conditions::DRIVER_FAULT),
                )),
            },
        ),
        (
            "00050c050108010370420103d041010390400103403f01074e428001244e00",
            Envelope {
                seq: 12,
                body: Response::Kerf(Some(KerfResult {
                    run_id: 8,
                    kerf_um: 60.0,
                    angle_deg: 26.0,
                    play_deg: 4.5,
                    torque_at_jam_nm: 0.75,
                    force_at_jam_n: 51.5,
                    flags: QualityFlags::SUPPLY_LIMITED,
                })),
            },
        ),
        (
            "00050d05010901031643010370420103b0400103203f01075c428202b8ab00",
            Envelope {
                seq: 13,
                body: Response::Kerf(Some(KerfResult {
                    run_id: 9,
                    kerf_um: 150.0,
                    angle_deg: 60.0,
                    play_deg: 5.5,
                    torque_at_jam_nm: 0.625,
                    force_at_jam_n: 55.0,
                    flags: QualityFlags(
                        QualityFlags::TORQUE_MISMATCH.0 | QualityFlags::NOISY_HOLD.0,
                    ),
                })),
            },
        ),
        (
            "00050e05010a01031643010370420103b0400103203f01075c428004953000",
            Envelope {
                seq: 14,
                body: Response::Kerf(Some(KerfResult {
                    run_id: 10,
                    kerf_um: 150.0,
                    angle_deg: 60.0,
                    play_deg: 5.5,
                    torque_at_jam_nm: 0.625,
                    force_at_jam_n: 55.0,
                    flags: QualityFlags::FORCE_SENSITIVE,
                })),
            },
        ),
        (
            "000b0907ae47613f0ad7233d01010103a84101010108d0409cc4203e010390b400",
            Envelope {
                seq: 9,
                body: Response::Config(ConfigReport {
                    config: DeviceConfig::DEFAULT,
                    defaults_in_use: true,
                    saved: false,
                }),
            },
        ),
        (
            "000705030207d2090103803e01072a42d2090201010a4041b401aa0b08172f00",
            Envelope {
                seq: 5,
                body: Response::Status(Status {
                    state: RunState::Ramping,
                    run_id: 7,
                    elapsed_ms: 1234,
                    torque_nm: 0.25,
                    angle_deg: 42.5,
                    samples: 1234,
                    encoder_errors: 2,
                    supply_v: Some(12.0),
                    longest_step_us: 180,
                    longest_gap_us: 1_450,
                    conditions: Conditions::DRIVER_FAULT,
                }),
            },
        ),
        (
            "00050605010704803443010390420103a0400101023f01065c4208696400",
            Envelope {
                seq: 6,
                body: Response::Kerf(Some(KerfResult {
                    run_id: 7,
                    kerf_um: 180.5,
                    angle_deg: 72.0,
                    play_deg: 5.0,
                    torque_at_jam_nm: 0.5,
                    force_at_jam_n: 55.0,
                    flags: QualityFlags::ENCODER_ERRORS,
                })),
            },
        ),
        (
            "000407040704020102010101010101010106016f12833a0101043f51cb00",
            Envelope {
                seq: 7,
                body: Response::Samples(SampleChunk {
                    run_id: 7,
                    from: 0,
                    total: 2,
                    ticks_per_sample: 1,
                    samples: heapless::Vec::from_slice(&[
                        Sample {
                            t_ms: 0,
                            torque_nm: 0.0,
                            angle_deg: 0.0,
                        },
                        Sample {
                            t_ms: 1,
                            torque_nm: 0.001,
                            angle_deg: 0.5,
                        },
                    ])
                    .unwrap(),
                }),
            },
        ),
        // Protocol 2.6: appended.
        (
            "0005090802010204020103013d01094a420101a01f5a01010105b80291080401f2ba00",
            Envelope {
                seq: 9,
                body: Response::Diagnostics(Diagnostics {
                    reset_reason: ResetReason::Watchdog,
                    chip_revision: Some(ChipRevision { major: 0, minor: 4 }),
                    adc_calibration: AdcCalibration::Efuse { version: 1 },
                    brown_out: BrownOutDetector::Resets,
                    cs_asleep_mv: Some(61),
                    cs_offset_mv: 50.5,
                    cs_offset_learnt: true,
                    encoder: Some(EncoderHealth {
                        magnitude: 4000,
                        agc: 90,
                        ocf: true,
                        cof: false,
                        comp_low: false,
                        comp_high: false,
                    }),
                    longest_step_us: 312,
                    longest_gap_us: 1041,
                    adc_restarts: 0,
                    driver: G2Variant::V24v13,
                }),
            },
        ),
    ]
}

fn check_golden<T: serde::Serialize + serde::de::DeserializeOwned>(
    golden: Vec<(&str, T)>,
) -> Vec<String> {
    let mut mismatches = Vec::new();
    for (expected, msg) in &golden {
        let got = hex(&frame(msg));
        if got != *expected {
            mismatches.push(format!("expected {expected}\n     got {got}"));
        }
    }
    mismatches
}

#[test]
fn golden_request_frames() {
    let m = check_golden(golden_requests());
    assert!(
        m.is_empty(),
        "request wire bytes changed:\n{}",
        m.join("\n")
    );
}

#[test]
fn golden_response_frames() {
    let m = check_golden(golden_responses());
    assert!(
        m.is_empty(),
        "response wire bytes changed:\n{}",
        m.join("\n")
    );
}

/// Every one-byte change of a golden frame (every position, every other value) is rejected:
/// the deframer yields no message at all.
fn no_mutation_accepted<T: serde::de::DeserializeOwned + std::fmt::Debug>(hex_frames: &[&str]) {
    let mut checked = 0u32;
    for h in hex_frames {
        let original = unhex(h);
        for pos in 0..original.len() {
            for value in 0..=255u8 {
                if value == original[pos] {
                    continue;
                }
                let mut mutated = original.clone();
                mutated[pos] = value;
                // A trailing 0x00 closes whatever the mutation left open.
                mutated.push(0);
                let mut d = Deframer::<{ MAX_RESPONSE_FRAME_LEN }>::new();
                let out: Vec<Result<T, FrameError>> =
                    deframe_all(&mut d, &mutated, &[mutated.len()]);
                let accepted: Vec<_> = out.iter().filter(|r| r.is_ok()).collect();
                assert!(
                    accepted.is_empty(),
                    "frame {h} with byte {pos} = {value:#04x} was accepted: {accepted:?}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 1000);
}

#[test]
fn any_one_byte_change_to_a_golden_request_is_rejected() {
    let frames: Vec<&str> = golden_requests().iter().map(|(h, _)| *h).collect();
    no_mutation_accepted::<Envelope<Request>>(&frames);
}

#[test]
fn any_one_byte_change_to_a_golden_response_is_rejected() {
    let frames: Vec<&str> = golden_responses().iter().map(|(h, _)| *h).collect();
    no_mutation_accepted::<Envelope<Response>>(&frames);
}
