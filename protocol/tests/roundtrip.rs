//! Every message survives encode → frame → deframe → decode, byte for byte, and stays within the
//! compile-time frame bounds.

mod common;
use common::*;
use kerfmeter_protocol::*;
use proptest::prelude::*;

fn roundtrip<T>(msg: &T, max_len: usize)
where
    T: serde::Serialize + serde::de::DeserializeOwned,
{
    let bytes = frame(msg);
    assert!(
        bytes.len() <= max_len,
        "frame of {} bytes exceeds the bound {max_len}",
        bytes.len()
    );
    assert_eq!(bytes.first(), Some(&0));
    assert_eq!(bytes.last(), Some(&0));
    assert!(
        !bytes[1..bytes.len() - 1].contains(&0),
        "COBS leaves no zero inside a frame"
    );

    let mut deframer = Deframer::<{ MAX_RESPONSE_FRAME_LEN }>::new();
    let got: Vec<Result<T, FrameError>> = deframe_all(&mut deframer, &bytes, &[bytes.len()]);
    assert_eq!(got.len(), 1);
    let back = got.into_iter().next().unwrap().expect("frame decodes");
    // Compare re-encoded bytes so that NaN payloads count as equal to themselves.
    assert_eq!(frame(&back), bytes);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn requests_roundtrip(msg in request_envelope()) {
        roundtrip(&msg, MAX_REQUEST_FRAME_LEN);
    }

    #[test]
    fn responses_roundtrip(msg in response_envelope()) {
        roundtrip(&msg, MAX_RESPONSE_FRAME_LEN);
    }

    #[test]
    fn requests_roundtrip_by_value(msg in request_envelope()) {
        // Without NaN, the decoded value also compares equal field by field.
        let bytes = frame(&msg);
        let mut d = Deframer::<MAX_REQUEST_FRAME_LEN>::new();
        let got: Vec<Result<Envelope<Request>, _>> = deframe_all(&mut d, &bytes, &[3]);
        let back = got.into_iter().next().unwrap().unwrap();
        if format!("{msg:?}").contains("NaN") {
            prop_assert_eq!(format!("{back:?}"), format!("{msg:?}"));
        } else {
            prop_assert_eq!(back, msg);
        }
    }
}

#[test]
fn get_info_is_variant_zero_forever() {
    // Envelope { seq: 0, body: GetInfo } is the two bytes [seq=0, variant=0].
    let bytes = postcard::to_slice(
        &Envelope {
            seq: 0,
            body: Request::GetInfo,
        },
        &mut [0u8; 8],
    )
    .unwrap()
    .to_vec();
    assert_eq!(bytes, [0, 0]);
    let info = Response::Info(DeviceInfo {
        protocol: PROTOCOL_VERSION,
        firmware: FirmwareVersion {
            major: 0,
            minor: 0,
            patch: 0,
        },
        boot_id: 0,
        hardware: HardwareInfo {
            board: heapless::String::new(),
            control_rate_hz: 0,
            encoder_bits: 0,
            pwm_bits: 0,
            max_samples: 0,
            max_request_frame_len: 0,
        },
    });
    let bytes = postcard::to_slice(&info, &mut [0u8; 64]).unwrap().to_vec();
    assert_eq!(bytes[0], 0, "Response::Info is variant 0");
}

#[test]
fn default_params_are_valid_and_ranges_reject_nonsense() {
    assert_eq!(RunParams::DEFAULT.validate(), Ok(()));
    assert_eq!(DeviceConfig::DEFAULT.validate(), Ok(()));

    let mut p = RunParams::DEFAULT;
    p.thickness_mm = f32::NAN;
    assert_eq!(p.validate(), Err(ParamField::ThicknessMm));

    let mut p = RunParams::DEFAULT;
    p.gauge.hole_radius_mm = 1.5; // smaller than the 2 mm prong
    assert_eq!(p.validate(), Err(ParamField::HoleRadiusMm));

    let mut p = RunParams::DEFAULT;
    p.gauge.hole_distance_mm = 9.0; // hole would cut through the spiral
    assert_eq!(p.validate(), Err(ParamField::HoleDistanceMm));

    let mut p = RunParams::DEFAULT;
    p.max_time_ms = 0;
    assert_eq!(p.validate(), Err(ParamField::MaxTimeMs));
}

#[test]
fn paper_gauge_covers_the_paper_kerf_range() {
    // c = maxKerf / maxRotation = 430 µm / 155°.
    let max = GaugeGeometry::PAPER.max_kerf_um();
    assert!((max - 430.0).abs() < 0.1, "{max}");
}
