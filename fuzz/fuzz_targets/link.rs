//! Fuzz the device's protocol server: arbitrary bytes into the link in front of the device.
//!
//! Properties: no panic; the device answers only with complete, decodable response frames.

#![no_main]

use kerfmeter_firmware::device::Device;
use kerfmeter_firmware::link::Link;
use kerfmeter_protocol::{Deframer, Envelope, Feed, MAX_RESPONSE_FRAME_LEN, Response};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut link = Link::new();
    let mut device = Device::new("fuzz", 1);
    let mut out = Vec::new();
    for piece in data.chunks(17) {
        link.receive(piece, &mut device, |frame| out.extend_from_slice(frame));
    }
    let mut deframer = Deframer::<MAX_RESPONSE_FRAME_LEN>::new();
    let mut input = &out[..];
    while let Feed::Frame { result, rest } = deframer.feed::<Envelope<Response>>(input) {
        result.expect("the device only sends intact responses");
        input = rest;
    }
});
