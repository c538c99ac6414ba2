//! The protocol server, sans-IO: bytes in, responses out as bytes.
//!
//! [`Link::receive`] takes whatever bytes the serial port delivered (any chunking, garbage
//! included), decodes complete request frames, asks a [`Handler`] for each response and hands
//! the framed response to a `transmit` callback. It owns the rules of the protocol's crate docs:
//!
//! - **Idempotent retries.** The link remembers the last request and its response. A request that
//!   repeats the last `seq` *and* the same body is a retry of a lost response: it is answered from
//!   memory and not given to the handler again (a `Run` is never started twice). The same `seq`
//!   with a different body is a new request (a restarted host counting from zero again).
//! - **Only answers.** One response per accepted request; nothing unsolicited.
//! - **Bad frames are dropped, not answered**: a corrupted frame has no trustworthy `seq`. The host
//!   times out and retries. An *intact* frame with an unknown request (a newer host) is answered
//!   with [`ErrorCode::UnknownRequest`] so the host can tell "old firmware" from "no device".
//! - Every received request counts as host activity, for the run's communication watchdog.

use kerfmeter_protocol::{
    Deframer, DeframerStats, Envelope, ErrorCode, Feed, FrameError, MAX_REQUEST_FRAME_LEN,
    MAX_RESPONSE_FRAME_LEN, Request, Response, encode_frame,
};

/// What answers requests: the device behind the link.
pub trait Handler {
    /// Carry out `request` (or refuse it) and say what to answer.
    fn handle(&mut self, request: &Request) -> Response;
}

/// Counters for diagnostics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkStats {
    /// Frame-level counters.
    pub frames: DeframerStats,
    /// Requests given to the handler.
    pub handled: u32,
    /// Retries answered from memory.
    pub replayed: u32,
    /// Intact frames with an unknown request.
    pub unknown: u32,
}

/// The protocol server of one serial port.
pub struct Link {
    deframer: Deframer<MAX_REQUEST_FRAME_LEN>,
    last: Option<(Envelope<Request>, Response)>,
    out: [u8; MAX_RESPONSE_FRAME_LEN],
    stats: LinkStats,
}

impl Default for Link {
    fn default() -> Self {
        Self::new()
    }
}

impl Link {
    /// A link with nothing received yet.
    pub const fn new() -> Self {
        Self {
            deframer: Deframer::new(),
            last: None,
            out: [0; MAX_RESPONSE_FRAME_LEN],
            stats: LinkStats {
                frames: DeframerStats {
                    frames_ok: 0,
                    frames_dropped: 0,
                    bytes_discarded: 0,
                },
                handled: 0,
                replayed: 0,
                unknown: 0,
            },
        }
    }

    /// Counters since boot.
    pub fn stats(&self) -> LinkStats {
        LinkStats {
            frames: self.deframer.stats(),
            ..self.stats
        }
    }

    /// Take received `bytes`; for each complete request, call `handler` and pass the framed
    /// response to `transmit`. Returns the number of requests answered (retries included).
    pub fn receive(
        &mut self,
        bytes: &[u8],
        handler: &mut impl Handler,
        mut transmit: impl FnMut(&[u8]),
    ) -> usize {
        let mut answered = 0;
        let mut input = bytes;
        while let Feed::Frame { result, rest } = self.deframer.feed::<Envelope<Request>>(input) {
            input = rest;
            let reply = match result {
                Ok(request) => Some(self.answer(request, handler)),
                Err(FrameError::Decode(e)) => e.seq.map(|seq| {
                    self.stats.unknown += 1;
                    Envelope {
                        seq,
                        body: Response::Error(ErrorCode::UnknownRequest),
                    }
                }),
                Err(_) => None,
            };
            if let Some(reply) = reply {
                // Every response fits: the buffer is sized by the compile-time bound.
                if let Ok(frame) = encode_frame(&reply, &mut self.out) {
                    transmit(frame);
                    answered += 1;
                }
            }
        }
        answered
    }

    fn answer(
        &mut self,
        request: Envelope<Request>,
        handler: &mut impl Handler,
    ) -> Envelope<Response> {
        if let Some((last_request, last_response)) = &self.last
            && *last_request == request
        {
            self.stats.replayed += 1;
            return Envelope {
                seq: request.seq,
                body: last_response.clone(),
            };
        }
        self.stats.handled += 1;
        let body = handler.handle(&request.body);
        let seq = request.seq;
        self.last = Some((request, body.clone()));
        Envelope { seq, body }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerfmeter_protocol::{MAX_RESPONSE_FRAME_LEN, RunParams};
    use std::vec::Vec;

    /// Counts what it executes; answers `Ok` to everything but `GetKerf`.
    #[derive(Default)]
    struct Counter {
        runs: u32,
        handled: u32,
    }

    impl Handler for Counter {
        fn handle(&mut self, request: &Request) -> Response {
            self.handled += 1;
            match request {
                Request::Run(_) => {
                    self.runs += 1;
                    Response::Ok
                }
                Request::GetKerf => Response::Kerf(None),
                _ => Response::Ok,
            }
        }
    }

    fn request_frame(seq: u16, body: Request) -> Vec<u8> {
        let mut buf = [0u8; MAX_REQUEST_FRAME_LEN];
        encode_frame(&Envelope { seq, body }, &mut buf)
            .unwrap()
            .to_vec()
    }

    fn responses(link: &mut Link, handler: &mut Counter, bytes: &[u8]) -> Vec<Envelope<Response>> {
        let mut wire = Vec::new();
        link.receive(bytes, handler, |f| wire.extend_from_slice(f));
        let mut d = Deframer::<MAX_RESPONSE_FRAME_LEN>::new();
        let mut out = Vec::new();
        let mut input = &wire[..];
        while let Feed::Frame { result, rest } = d.feed::<Envelope<Response>>(input) {
            out.push(result.unwrap());
            input = rest;
        }
        out
    }

    #[test]
    fn a_retried_run_is_answered_but_not_executed_twice() {
        let mut link = Link::new();
        let mut h = Counter::default();
        let run = request_frame(5, Request::Run(RunParams::DEFAULT));
        let first = responses(&mut link, &mut h, &run);
        let again = responses(&mut link, &mut h, &run);
        assert_eq!(first, again);
        assert_eq!(first[0].seq, 5);
        assert_eq!(h.runs, 1);
        assert_eq!(link.stats().replayed, 1);
    }

    #[test]
    fn same_seq_with_another_body_is_a_new_request() {
        let mut link = Link::new();
        let mut h = Counter::default();
        responses(&mut link, &mut h, &request_frame(0, Request::GetStatus));
        let r = responses(&mut link, &mut h, &request_frame(0, Request::GetKerf));
        assert_eq!(r[0].body, Response::Kerf(None));
        assert_eq!(h.handled, 2);
    }

    #[test]
    fn corrupted_frames_are_dropped_silently_and_the_next_one_is_answered() {
        let mut link = Link::new();
        let mut h = Counter::default();
        let mut bad = request_frame(1, Request::GetStatus);
        bad[2] ^= 0x10;
        let mut stream = b"garbage\xff\x01".to_vec();
        stream.extend(&bad);
        stream.extend(request_frame(2, Request::GetStatus));
        let r = responses(&mut link, &mut h, &stream);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].seq, 2);
        assert_eq!(h.handled, 1);
    }

    #[test]
    fn an_unknown_request_gets_a_typed_error_with_its_seq() {
        let mut link = Link::new();
        let mut h = Counter::default();
        // Variant 200 is no request this firmware knows (a newer host).
        let mut buf = [0u8; 32];
        let frame = encode_frame(&(42u16, 200u8), &mut buf).unwrap().to_vec();
        let r = responses(&mut link, &mut h, &frame);
        assert_eq!(
            r,
            [Envelope {
                seq: 42,
                body: Response::Error(ErrorCode::UnknownRequest)
            }]
        );
        assert_eq!(h.handled, 0);
    }

    #[test]
    fn byte_at_a_time_delivery_works() {
        let mut link = Link::new();
        let mut h = Counter::default();
        let frame = request_frame(3, Request::GetKerf);
        let mut all = Vec::new();
        for b in &frame {
            all.extend(responses(&mut link, &mut h, core::slice::from_ref(b)));
        }
        assert_eq!(all.len(), 1);
    }
}
