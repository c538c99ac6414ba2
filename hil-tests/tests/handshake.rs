//! Acceptance: the handshake and the info fields are sane.

use kerfmeter::protocol::PROTOCOL_VERSION;
use kerfmeter_hil::{Target, connect};

#[test]
fn handshake_and_info_fields_are_sane() {
    let (target, mut meter) = connect(11).expect("connect");
    eprintln!("running against the {}", target.describe());
    let info = meter.info().expect("GetInfo");
    assert!(PROTOCOL_VERSION.compatible_with(&info.protocol));
    assert_eq!(
        info.hardware.encoder_bits, 14,
        "AS5048A is a 14-bit encoder"
    );
    assert!(
        info.hardware.control_rate_hz >= 1000,
        "control loop must run at 1 kHz or more"
    );
    assert!((8..=16).contains(&info.hardware.pwm_bits));
    assert!(info.hardware.max_samples >= 256);
    assert!(
        usize::from(info.hardware.max_request_frame_len)
            >= kerfmeter::protocol::MAX_REQUEST_FRAME_LEN,
        "device must accept every request this host can send"
    );
    match &target {
        Target::Twin(_) => assert_eq!(info.hardware.board.as_str(), "twin"),
        Target::Board(_) => assert!(info.hardware.board.starts_with("esp32")),
    }
    // The boot id is stable while the device runs.
    assert_eq!(meter.info().expect("GetInfo").boot_id, info.boot_id);
}
