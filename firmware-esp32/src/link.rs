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
//!
//! # Bounded work per control tick
//!
//! The board's control loop steps the device, then serves the link in the same pass, every
//! [`PERIOD_US`](crate::controller::PERIOD_US). Unbounded link work (a burst of small frames)
//! would push the next step past the controller's overrun limit and fault a run with
//! `StepOverrun`. So a pass hands the link at most [`FRAMES_PER_TICK`] frames
//! ([`Link::receive_frames`] stops between two frames and says how many bytes it took); the
//! bytes after them stay queued for the next pass ([`Inbox`]). The budget counts every frame,
//! answered or dropped, since each one costs decoding; empty frames (resync delimiters) and
//! garbage between frames cost only a byte scan.
//!
//! Why a budget in frames, and not the control tick on a higher-priority interrupt executor:
//! the budget keeps one owner of the device (no critical-section mutex around it, no request
//! handled in the middle of a step), it is deterministic, so the digital twin runs exactly the
//! board's rule, and a frame's work is bounded — decoding a request no longer than
//! `MAX_REQUEST_FRAME_LEN`, the handler, encoding a response — except a configuration write to
//! flash, which the device refuses while the motor runs. Why frames and not a time budget on the
//! clock: the same bound then holds whatever a frame costs on the core, and a budget measured in
//! time could still be overrun by the one frame that started just before it ran out.
//!
//! A host that sends faster than [`FRAMES_PER_TICK`] frames a period is throttled by
//! back-pressure, never by dropped frames: the board's receive queue fills, its USB task stops
//! reading, and the USB-Serial-JTAG FIFO stops accepting the host's bytes. An answer that comes
//! late because of the queue is harmless: the host discards answers whose `seq` it is not
//! waiting for, a retry it sent meanwhile is answered from memory, and the queue (at most a few
//! hundred bytes, tens of frames) drains within tens of milliseconds, well inside the host's
//! timeout.

use kerfmeter_protocol::{
    Deframer, DeframerStats, Envelope, ErrorCode, Feed, FrameError, MAX_REQUEST_FRAME_LEN,
    MAX_RESPONSE_FRAME_LEN, Request, Response, encode_frame, heapless,
};

/// Frames the link takes per control pass. Two: the host's poll and one more (its retry, or a
/// second client's request). At two frames a pass of 300 µs each (a pessimistic frame cost), the
/// link work still fits in a period, so no step moves because of the host.
pub const FRAMES_PER_TICK: u32 = 2;

/// What one call of [`Link::receive_frames`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Received {
    /// Input bytes taken (the rest is for a later call).
    pub consumed: usize,
    /// Frames that ended in them, intact or not (each one counts against the budget).
    pub frames: u32,
    /// Requests answered (retries included).
    pub answered: usize,
}

/// What answers requests: the device behind the link.
pub trait Handler {
    /// Carry out `request` (or refuse it) and say what to answer.
    fn handle(&mut self, request: &Request) -> Response;

    /// The host was heard: a request came (one to carry out, a retry answered from memory, or
    /// one this firmware does not know). For the run's communication watchdog. No default: a
    /// wrapper that forgot to pass it on would fault every run `HostSilent`.
    fn host_activity(&mut self);
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
    /// Unbounded: for a bounded pass, see [`receive_frames`](Self::receive_frames).
    pub fn receive(
        &mut self,
        bytes: &[u8],
        handler: &mut impl Handler,
        transmit: impl FnMut(&[u8]),
    ) -> usize {
        self.receive_frames(bytes, u32::MAX, handler, transmit)
            .answered
    }

    /// Like [`receive`](Self::receive), but stop right after the `max_frames`-th frame that
    /// ends in `bytes`: the bytes after it are not taken ([`Received::consumed`] says how many
    /// were); give them again later. A frame cut by the stop cannot happen: the link stops only
    /// between frames, and a frame's beginning already taken is kept until its end comes.
    pub fn receive_frames(
        &mut self,
        bytes: &[u8],
        max_frames: u32,
        handler: &mut impl Handler,
        mut transmit: impl FnMut(&[u8]),
    ) -> Received {
        let mut done = Received::default();
        let mut input = bytes;
        while done.frames < max_frames {
            let Feed::Frame { result, rest } = self.deframer.feed::<Envelope<Request>>(input)
            else {
                input = &[];
                break;
            };
            input = rest;
            done.frames += 1;
            if result.is_ok() || matches!(&result, Err(FrameError::Decode(e)) if e.seq.is_some()) {
                handler.host_activity();
            }
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
                    done.answered += 1;
                }
            }
        }
        done.consumed = bytes.len() - input.len();
        done
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

/// The received bytes a pass has not handed to the link yet: the rest of the chunk the last
/// pass stopped in (see [the module docs](self)). Chunks come from the board's receive queue,
/// `N` bytes at most each.
pub struct Inbox<const N: usize> {
    chunk: heapless::Vec<u8, N>,
    taken: usize,
}

impl<const N: usize> Default for Inbox<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Inbox<N> {
    /// Nothing pending.
    pub const fn new() -> Self {
        Self {
            chunk: heapless::Vec::new(),
            taken: 0,
        }
    }

    /// Bytes pending from the last chunk.
    pub fn pending(&self) -> &[u8] {
        &self.chunk[self.taken..]
    }

    /// One pass's link work: the pending bytes, then chunks from `next_chunk` while it has
    /// some, handed to `link` until [`FRAMES_PER_TICK`] frames ended. Whatever follows the last
    /// of them stays pending, and unread chunks stay in their queue. Returns the frames taken.
    pub fn serve(
        &mut self,
        link: &mut Link,
        mut next_chunk: impl FnMut() -> Option<heapless::Vec<u8, N>>,
        handler: &mut impl Handler,
        mut transmit: impl FnMut(&[u8]),
    ) -> u32 {
        let mut frames = 0;
        while frames < FRAMES_PER_TICK {
            if self.pending().is_empty() {
                let Some(chunk) = next_chunk() else { break };
                self.chunk = chunk;
                self.taken = 0;
            }
            let done = link.receive_frames(
                &self.chunk[self.taken..],
                FRAMES_PER_TICK - frames,
                handler,
                &mut transmit,
            );
            self.taken += done.consumed;
            frames += done.frames;
        }
        frames
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerfmeter_protocol::{MAX_RESPONSE_FRAME_LEN, RunParams};
    use std::{vec, vec::Vec};

    /// Counts what it executes; answers `Ok` to everything but `GetKerf`.
    #[derive(Default)]
    struct Counter {
        runs: u32,
        handled: u32,
        heard: u32,
    }

    impl Handler for Counter {
        fn host_activity(&mut self) {
            self.heard += 1;
        }

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
        // The retry is the host heard all the same (a host whose answers get lost retries
        // until one comes through: it is not silent).
        assert_eq!(h.heard, 2);
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
        // Garbage is not the host.
        assert_eq!(h.heard, 1);
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
        assert_eq!(h.heard, 1);
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
    #[test]
    fn a_bounded_receive_stops_between_frames_and_keeps_the_rest() {
        let mut link = Link::new();
        let mut h = Counter::default();
        let mut stream = Vec::new();
        for seq in 0..3 {
            stream.extend(request_frame(seq, Request::GetStatus));
        }
        let mut wire = Vec::new();
        let first = link.receive_frames(&stream, 2, &mut h, |f| wire.push(f.to_vec()));
        assert_eq!((first.frames, first.answered), (2, 2));
        assert_eq!(h.handled, 2);
        assert!(first.consumed < stream.len());
        let rest = &stream[first.consumed..];
        let r = responses(&mut link, &mut h, rest);
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].seq, 2);
    }

    /// Chunks of `len` bytes of `stream`, as the board's receive queue holds them.
    fn chunks(stream: &[u8], len: usize) -> std::collections::VecDeque<heapless::Vec<u8, 64>> {
        stream
            .chunks(len)
            .map(|c| heapless::Vec::from_slice(c).unwrap())
            .collect()
    }

    #[test]
    fn an_inbox_serves_a_burst_a_few_frames_a_pass_in_order() {
        let mut link = Link::new();
        let mut h = Counter::default();
        let mut stream = b"\0\0noise\0".to_vec();
        for seq in 10..17 {
            stream.extend(request_frame(seq, Request::GetStatus));
        }
        // Chunks that cut frames anywhere.
        let mut queue = chunks(&stream, 5);
        let mut inbox = Inbox::<64>::new();
        let mut passes = Vec::new();
        while !(queue.is_empty() && inbox.pending().is_empty()) {
            let mut seqs = Vec::new();
            let frames = inbox.serve(
                &mut link,
                || queue.pop_front(),
                &mut h,
                |f| {
                    seqs.push(decode_response(f).seq);
                },
            );
            passes.push((frames, seqs));
        }
        // The garbage frame in front counts as one.
        let expected = [
            (2, vec![10]),
            (2, vec![11, 12]),
            (2, vec![13, 14]),
            (2, vec![15, 16]),
        ];
        assert_eq!(passes, expected);
        assert_eq!(h.handled, 7);
    }

    #[test]
    fn an_inbox_takes_no_chunk_it_has_no_budget_for() {
        let mut link = Link::new();
        let mut h = Counter::default();
        let mut queue = std::collections::VecDeque::new();
        for seq in 0..4 {
            queue.extend(chunks(&request_frame(seq, Request::GetKerf), 64));
        }
        let mut inbox = Inbox::<64>::new();
        let frames = inbox.serve(&mut link, || queue.pop_front(), &mut h, |_| {});
        assert_eq!(frames, FRAMES_PER_TICK);
        assert_eq!(queue.len(), 4 - FRAMES_PER_TICK as usize);
        assert!(inbox.pending().is_empty());
    }

    fn decode_response(frame: &[u8]) -> Envelope<Response> {
        let mut d = Deframer::<MAX_RESPONSE_FRAME_LEN>::new();
        match d.feed::<Envelope<Response>>(frame) {
            Feed::Frame { result, .. } => result.unwrap(),
            Feed::Consumed => panic!("no whole frame"),
        }
    }
}
