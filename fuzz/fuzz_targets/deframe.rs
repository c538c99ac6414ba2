//! Fuzz the deframer and both decoders with arbitrary bytes in arbitrary chunks.
//!
//! Properties: no panic; the frame counters add up; every accepted message re-encodes to a
//! frame that decodes to the same message (nothing half-decoded is ever accepted).

#![no_main]

use kerfmeter_protocol::{
    Deframer, Envelope, Feed, MAX_REQUEST_FRAME_LEN, MAX_RESPONSE_FRAME_LEN, Request, Response,
    encode_frame,
};
use libfuzzer_sys::fuzz_target;

fn check<T, const N: usize>(data: &[u8], chunk: usize)
where
    T: serde::Serialize + serde::de::DeserializeOwned,
{
    let mut deframer = Deframer::<N>::new();
    let mut seen = 0u32;
    for piece in data.chunks(chunk) {
        let mut input = piece;
        while let Feed::Frame { result, rest } = deframer.feed::<T>(input) {
            seen += 1;
            input = rest;
            if let Ok(msg) = result {
                let mut buf = [0u8; MAX_RESPONSE_FRAME_LEN];
                let frame = encode_frame(&msg, &mut buf).expect("accepted messages re-encode");
                let mut again = Deframer::<MAX_RESPONSE_FRAME_LEN>::new();
                match again.feed::<T>(frame) {
                    Feed::Frame {
                        result: Ok(back), ..
                    } => {
                        let mut buf2 = [0u8; MAX_RESPONSE_FRAME_LEN];
                        let frame2 = encode_frame(&back, &mut buf2).unwrap();
                        assert_eq!(frame2, &buf[..frame2.len()]);
                    }
                    _ => panic!("a re-encoded accepted message did not decode"),
                }
            }
        }
    }
    let stats = deframer.stats();
    assert_eq!(seen, stats.frames_ok + stats.frames_dropped);
}

fuzz_target!(|data: &[u8]| {
    let Some((&first, rest)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(first % 64) + 1;
    check::<Envelope<Request>, MAX_REQUEST_FRAME_LEN>(rest, chunk);
    check::<Envelope<Response>, MAX_RESPONSE_FRAME_LEN>(rest, chunk);
});
