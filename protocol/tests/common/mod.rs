//! proptest strategies for every wire type, shared by the protocol's integration tests.
#![allow(dead_code)]

use kerfmeter_protocol::*;
use proptest::prelude::*;

/// Any f32, NaN and infinities included: the wire must carry them unchanged.
pub fn f() -> impl Strategy<Value = f32> {
    any::<f32>()
}

pub fn gauge() -> impl Strategy<Value = GaugeGeometry> {
    (f(), f(), f(), f(), f(), any::<bool>(), f()).prop_map(|(p, r, rp, rh, d, cw, dis)| {
        GaugeGeometry {
            pitch_um_per_deg: p,
            radius_mm: r,
            prong_radius_mm: rp,
            hole_radius_mm: rh,
            hole_distance_mm: d,
            jam_direction: if cw {
                JamDirection::Clockwise
            } else {
                JamDirection::CounterClockwise
            },
            disengage_deg: dis,
        }
    })
}

pub fn run_params() -> impl Strategy<Value = RunParams> {
    (gauge(), f(), f(), f(), f(), f(), any::<u32>(), any::<u32>()).prop_map(
        |(gauge, t, force, area, tmax, ramp, max_time_ms, host_timeout_ms)| RunParams {
            gauge,
            thickness_mm: t,
            target_force_n: force,
            contact_area_mm2: area,
            max_torque_nm: tmax,
            ramp_rate_nm_per_s: ramp,
            max_time_ms,
            host_timeout_ms,
        },
    )
}

pub fn config() -> impl Strategy<Value = DeviceConfig> {
    (
        f(),
        f(),
        any::<u16>(),
        any::<bool>(),
        f(),
        any::<bool>(),
        any::<bool>(),
        f(),
        f(),
    )
        .prop_map(
            |(tpd, brk, zero, motor_side, gear, mi, ei, imax, tpa)| DeviceConfig {
                torque_per_duty_nm: tpd,
                breakaway_duty: brk,
                encoder_zero_raw: zero,
                encoder_placement: if motor_side {
                    EncoderPlacement::MotorShaft
                } else {
                    EncoderPlacement::OutputShaft
                },
                gear_ratio: gear,
                motor_inverted: mi,
                encoder_inverted: ei,
                max_current_a: imax,
                torque_per_amp_nm: tpa,
            },
        )
}

pub fn request() -> impl Strategy<Value = Request> {
    prop_oneof![
        Just(Request::GetInfo),
        run_params().prop_map(Request::Run),
        Just(Request::GetStatus),
        any::<u16>().prop_map(|from| Request::GetSamples { from }),
        Just(Request::GetKerf),
        Just(Request::Reset),
        Just(Request::Abort),
        Just(Request::ClearFault),
        Just(Request::SelfTest),
        Just(Request::GetConfig),
        config().prop_map(Request::SetConfig),
        Just(Request::GetSelfTest),
        Just(Request::ConfirmHubAtZero),
    ]
}

pub fn fault() -> impl Strategy<Value = Fault> {
    proptest::sample::select(Fault::ALL)
}

pub fn param_field() -> impl Strategy<Value = ParamField> {
    proptest::sample::select(ParamField::ALL)
}

pub fn error_code() -> impl Strategy<Value = ErrorCode> {
    prop_oneof![
        Just(ErrorCode::UnknownRequest),
        Just(ErrorCode::Unsupported),
        Just(ErrorCode::Busy),
        fault().prop_map(ErrorCode::Faulted),
        param_field().prop_map(ErrorCode::InvalidParam),
        Just(ErrorCode::NoSamples),
        Just(ErrorCode::Storage),
        Just(ErrorCode::NotAtZero),
        any::<u16>().prop_map(|c| ErrorCode::Blocked(Conditions(c))),
        (any::<u16>(), any::<u16>()).prop_map(|(supply_mv, needed_mv)| ErrorCode::SupplyTooLow {
            supply_mv,
            needed_mv
        }),
    ]
}

pub fn run_state() -> impl Strategy<Value = RunState> {
    prop_oneof![
        Just(RunState::Idle),
        Just(RunState::Engaging),
        Just(RunState::Ramping),
        Just(RunState::Jammed),
        Just(RunState::Releasing),
        Just(RunState::Done),
        Just(RunState::Resetting),
        Just(RunState::SelfTest),
        fault().prop_map(RunState::Fault),
    ]
}

pub fn sample() -> impl Strategy<Value = Sample> {
    (any::<u32>(), f(), f()).prop_map(|(t_ms, torque_nm, angle_deg)| Sample {
        t_ms,
        torque_nm,
        angle_deg,
    })
}

pub fn kerf_result() -> impl Strategy<Value = KerfResult> {
    (any::<u32>(), f(), f(), f(), f(), f(), any::<u16>()).prop_map(
        |(run_id, k, a, p, t, force, fl)| KerfResult {
            run_id,
            kerf_um: k,
            angle_deg: a,
            play_deg: p,
            torque_at_jam_nm: t,
            force_at_jam_n: force,
            flags: QualityFlags(fl),
        },
    )
}

pub fn self_test_item() -> impl Strategy<Value = SelfTestItem> {
    (
        prop_oneof![
            Just(TestOutcome::Pass),
            Just(TestOutcome::Fail),
            Just(TestOutcome::Skipped)
        ],
        f(),
    )
        .prop_map(|(outcome, value)| SelfTestItem { outcome, value })
}

pub fn info() -> impl Strategy<Value = DeviceInfo> {
    (
        any::<[u16; 5]>(),
        any::<u32>(),
        "[a-z0-9-]{0,24}",
        any::<(u16, u8, u8, u16, u16)>(),
    )
        .prop_map(|(v, boot_id, board, (rate, eb, pb, ms, mf))| DeviceInfo {
            protocol: ProtocolVersion {
                major: v[0],
                minor: v[1],
            },
            firmware: FirmwareVersion {
                major: v[2],
                minor: v[3],
                patch: v[4],
            },
            boot_id,
            hardware: HardwareInfo {
                board: heapless::String::try_from(board.as_str()).unwrap(),
                control_rate_hz: rate,
                encoder_bits: eb,
                pwm_bits: pb,
                max_samples: ms,
                max_request_frame_len: mf,
            },
        })
}

pub fn response() -> impl Strategy<Value = Response> {
    prop_oneof![
        info().prop_map(Response::Info),
        Just(Response::Ok),
        error_code().prop_map(Response::Error),
        (
            run_state(),
            any::<(u32, u32, u16, u16)>(),
            (f(), f(), proptest::option::of(f())),
            any::<(u32, u32, u16)>()
        )
            .prop_map(
                |(
                    state,
                    (run_id, elapsed_ms, samples, encoder_errors),
                    (torque_nm, angle_deg, supply_v),
                    (longest_step_us, longest_gap_us, conditions),
                )| {
                    Response::Status(Status {
                        state,
                        run_id,
                        elapsed_ms,
                        torque_nm,
                        angle_deg,
                        samples,
                        encoder_errors,
                        supply_v,
                        longest_step_us,
                        longest_gap_us,
                        conditions: Conditions(conditions),
                    })
                }
            ),
        (
            any::<(u32, u16, u16, u16)>(),
            proptest::collection::vec(sample(), 0..=SAMPLES_PER_CHUNK)
        )
            .prop_map(
                |((run_id, from, total, ticks_per_sample), s)| Response::Samples(SampleChunk {
                    run_id,
                    from,
                    total,
                    ticks_per_sample,
                    samples: heapless::Vec::from_slice(&s).unwrap(),
                })
            ),
        proptest::option::of(kerf_result()).prop_map(Response::Kerf),
        (
            self_test_item(),
            self_test_item(),
            self_test_item(),
            self_test_item()
        )
            .prop_map(|(a, b, c, d)| {
                Response::SelfTest(Some(SelfTestReport {
                    encoder_ok_fraction: a,
                    magnet_magnitude: b,
                    direction_deg: c,
                    torque_per_duty_nm: d,
                }))
            }),
        Just(Response::SelfTest(None)),
        (config(), any::<(bool, bool)>()).prop_map(|(config, (defaults_in_use, saved))| {
            Response::Config(ConfigReport {
                config,
                defaults_in_use,
                saved,
            })
        }),
    ]
}

pub fn request_envelope() -> impl Strategy<Value = Envelope<Request>> {
    (any::<u16>(), request()).prop_map(|(seq, body)| Envelope { seq, body })
}

pub fn response_envelope() -> impl Strategy<Value = Envelope<Response>> {
    (any::<u16>(), response()).prop_map(|(seq, body)| Envelope { seq, body })
}

/// Encode into a fresh Vec (test helper).
pub fn frame<T: serde::Serialize>(msg: &T) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_RESPONSE_FRAME_LEN.max(MAX_REQUEST_FRAME_LEN)];
    encode_frame(msg, &mut buf).unwrap().to_vec()
}

/// Feed `input` in chunks of the given sizes (cycled) and collect every outcome.
pub fn deframe_all<T: serde::de::DeserializeOwned, const N: usize>(
    deframer: &mut Deframer<N>,
    input: &[u8],
    chunks: &[usize],
) -> Vec<Result<T, FrameError>> {
    let mut out = Vec::new();
    let mut pos = 0;
    let mut k = 0;
    while pos < input.len() {
        let size = chunks
            .get(k % chunks.len().max(1))
            .copied()
            .unwrap_or(input.len())
            .max(1);
        k += 1;
        let end = (pos + size).min(input.len());
        let mut window = &input[pos..end];
        while let Feed::Frame { result, rest } = deframer.feed::<T>(window) {
            out.push(result);
            window = rest;
        }
        pos = end;
    }
    out
}
