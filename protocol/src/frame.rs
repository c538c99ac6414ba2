//! Framing: `0x00 ‖ COBS(postcard(msg) ‖ CRC-16) ‖ 0x00` (see the crate docs for the diagram).
//!
//! [`encode_frame`] writes one frame into a caller's buffer. [`Deframer`] takes bytes in chunks of
//! any size, finds frames, and hands back each decoded message or the typed reason it was
//! dropped. It never returns a message whose CRC failed, and after any garbage it is ready for the
//! next frame as soon as it sees a `0x00`.

use crc::{CRC_16_IBM_SDLC, Crc};
use postcard::experimental::max_size::MaxSize;
use postcard::ser_flavors::{Cobs, Slice, crc::CrcModifier};
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::messages::{Envelope, Request, Response};

/// The frame checksum: CRC-16/IBM-SDLC (the HDLC / X.25 CRC), sent little-endian.
pub static CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_SDLC);

const CRC_LEN: usize = 2;

/// Longest frame (both delimiters included) for a message of at most `payload_max` postcard bytes.
pub const fn max_frame_len(payload_max: usize) -> usize {
    1 + cobs::max_encoding_length(payload_max + CRC_LEN) + 1
}

/// Longest request frame; what the device must buffer.
pub const MAX_REQUEST_FRAME_LEN: usize = max_frame_len(Envelope::<Request>::POSTCARD_MAX_SIZE);
/// Longest response frame; what the host must buffer.
pub const MAX_RESPONSE_FRAME_LEN: usize = max_frame_len(Envelope::<Response>::POSTCARD_MAX_SIZE);

// The device keeps one request and one response buffer in static RAM: keep them small.
const _: () = assert!(
    MAX_REQUEST_FRAME_LEN <= 128,
    "request frames grew past 128 bytes"
);
const _: () = assert!(
    MAX_RESPONSE_FRAME_LEN <= 512,
    "response frames grew past 512 bytes"
);

/// Why a message could not be framed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The output buffer is smaller than the frame.
    BufferTooSmall,
    /// postcard refused the value (never expected for this crate's types).
    Serialize,
}

impl From<postcard::Error> for EncodeError {
    fn from(e: postcard::Error) -> Self {
        match e {
            postcard::Error::SerializeBufferFull => Self::BufferTooSmall,
            _ => Self::Serialize,
        }
    }
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::BufferTooSmall => "frame buffer too small",
            Self::Serialize => "message could not be serialized",
        })
    }
}

/// Write `msg` as one frame (leading and trailing `0x00` included) into `buf`; returns the frame.
pub fn encode_frame<'b, T: Serialize + ?Sized>(
    msg: &T,
    buf: &'b mut [u8],
) -> Result<&'b mut [u8], EncodeError> {
    let (first, rest) = buf.split_first_mut().ok_or(EncodeError::BufferTooSmall)?;
    *first = 0;
    let flavor = CrcModifier::new(Cobs::try_new(Slice::new(rest))?, CRC16.digest());
    let len = postcard::serialize_with_flavor(msg, flavor)?.len();
    Ok(&mut buf[..1 + len])
}

/// Why a received frame was dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// More bytes than the buffer holds before a delimiter: garbage, or a frame from a peer with
    /// larger messages. Dropped up to the next `0x00`.
    Overflow,
    /// Not valid COBS (a zero inside, or a code byte pointing past the end).
    Cobs,
    /// Too short to hold a checksum, or the checksum does not match.
    Crc,
    /// Intact (the checksum matches) but not a message of the expected type: a peer speaking a
    /// newer protocol. `seq` is the envelope's sequence number when it could be read.
    Decode(DecodeError),
}

/// An intact frame whose contents were not understood.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecodeError {
    /// The envelope's sequence number, when its first field could be read.
    pub seq: Option<u16>,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Overflow => f.write_str("frame too long (garbage or a newer protocol)"),
            Self::Cobs => f.write_str("frame is not valid COBS"),
            Self::Crc => f.write_str("frame checksum mismatch"),
            Self::Decode(_) => f.write_str("intact frame with a message this side does not know"),
        }
    }
}

/// Counters of what a [`Deframer`] has seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeframerStats {
    /// Frames decoded into a message.
    pub frames_ok: u32,
    /// Frames dropped (any [`FrameError`]).
    pub frames_dropped: u32,
    /// Bytes thrown away because a frame overflowed the buffer.
    pub bytes_discarded: u32,
}

/// The outcome of [`Deframer::feed`].
#[derive(Debug)]
pub enum Feed<'a, T> {
    /// Every input byte was taken; no frame ended in it.
    Consumed,
    /// A frame ended. `rest` is the input after its delimiter: feed it again.
    Frame {
        /// The message, or why the frame was dropped.
        result: Result<T, FrameError>,
        /// The unread input.
        rest: &'a [u8],
    },
}

/// Finds and decodes frames in a byte stream; `N` is the longest frame it accepts.
///
/// ```
/// use kerfmeter_protocol::{Deframer, Envelope, Feed, Request, encode_frame, MAX_REQUEST_FRAME_LEN};
///
/// let mut buf = [0u8; MAX_REQUEST_FRAME_LEN];
/// let frame = encode_frame(&Envelope { seq: 7, body: Request::GetInfo }, &mut buf).unwrap();
///
/// let mut deframer = Deframer::<MAX_REQUEST_FRAME_LEN>::new();
/// let mut input: &[u8] = frame;
/// while let Feed::Frame { result, rest } = deframer.feed::<Envelope<Request>>(input) {
///     assert_eq!(result.unwrap().seq, 7);
///     input = rest;
/// }
/// ```
pub struct Deframer<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflowed: bool,
    stats: DeframerStats,
}

impl<const N: usize> Default for Deframer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Deframer<N> {
    /// An empty deframer.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            overflowed: false,
            stats: DeframerStats {
                frames_ok: 0,
                frames_dropped: 0,
                bytes_discarded: 0,
            },
        }
    }

    /// What it has seen so far.
    pub fn stats(&self) -> DeframerStats {
        self.stats
    }

    /// Forget a partly received frame (e.g. after the port was reopened).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflowed = false;
    }

    /// Take bytes until a frame ends; see [`Feed`].
    pub fn feed<'a, T: DeserializeOwned>(&mut self, input: &'a [u8]) -> Feed<'a, T> {
        for (i, &byte) in input.iter().enumerate() {
            if byte != 0 {
                if self.len < N {
                    self.buf[self.len] = byte;
                    self.len += 1;
                } else {
                    self.overflowed = true;
                    self.stats.bytes_discarded = self.stats.bytes_discarded.saturating_add(1);
                }
                continue;
            }
            let rest = &input[i + 1..];
            let result = if self.overflowed {
                self.stats.bytes_discarded =
                    self.stats.bytes_discarded.saturating_add(self.len as u32);
                Err(FrameError::Overflow)
            } else if self.len == 0 {
                // Two delimiters in a row: an empty frame, which senders use to resync.
                continue;
            } else {
                decode_frame(&mut self.buf[..self.len])
            };
            self.clear();
            match result {
                Ok(_) => self.stats.frames_ok = self.stats.frames_ok.saturating_add(1),
                Err(_) => self.stats.frames_dropped = self.stats.frames_dropped.saturating_add(1),
            }
            return Feed::Frame { result, rest };
        }
        Feed::Consumed
    }
}

/// Decode one frame's COBS bytes (delimiters removed) in place.
fn decode_frame<T: DeserializeOwned>(cobs_bytes: &mut [u8]) -> Result<T, FrameError> {
    let len = cobs::decode_in_place(cobs_bytes).map_err(|_| FrameError::Cobs)?;
    let data = &cobs_bytes[..len];
    if data.len() < CRC_LEN {
        return Err(FrameError::Crc);
    }
    match postcard::de_flavors::crc::take_from_bytes_u16::<T>(data, CRC16.digest()) {
        Ok((msg, [])) => Ok(msg),
        // Decoding failed, or stopped short of the checksum (the CRC flavor then reads the wrong
        // two bytes): tell a corrupted frame from an intact one we do not understand.
        _ => {
            let (body, crc) = data.split_at(data.len() - CRC_LEN);
            if CRC16.checksum(body).to_le_bytes() == crc {
                let seq = postcard::take_from_bytes::<u16>(body).ok().map(|(s, _)| s);
                Err(FrameError::Decode(DecodeError { seq }))
            } else {
                Err(FrameError::Crc)
            }
        }
    }
}
