//! The protocol crate's streaming [`Framer`] as a `tokio_util` codec, so
//! that any byte stream (serial port, TCP) becomes a stream of framer
//! events (1.4.1 frames, 1.4.2 ACK, NAK and NIC bytes) with
//! `tokio_util::codec::Framed`, and a sink of what a station writes.
//!
//! Decoding never drops bytes: events a read completes beyond the one
//! asked for stay queued for the next call. At end of stream a partial
//! frame is abandoned as after silence ([`Framer::line_idle`]).

use std::io;

use bytes::{Buf, BytesMut};
use sagebrush_protocol::{ACK, FrameBuf, Framer, NAK, NIC, OwnedEvent};
use tokio_util::codec::{Decoder, Encoder};

/// What a station writes: a frame, or one of the bare bytes of 1.4.2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Write<'a> {
    Frame(&'a FrameBuf),
    Ack,
    Nak,
    Nic,
}

/// Framer events in, frames and bare bytes out.
#[derive(Debug, Default)]
pub struct FrameCodec {
    framer: Framer,
}

impl FrameCodec {
    pub fn new() -> Self {
        Self::default()
    }

    /// The framer, for its counters (noise bytes skipped).
    pub fn framer(&self) -> &Framer {
        &self.framer
    }
}

impl Decoder for FrameCodec {
    type Item = OwnedEvent;
    type Error = io::Error;

    fn decode(&mut self, src: &mut BytesMut) -> io::Result<Option<OwnedEvent>> {
        loop {
            if let Some(event) = self.framer.next_event() {
                return Ok(Some(event.to_owned()));
            }
            // With no event pending, less than a frame is buffered, so the
            // framer takes at least one byte: every turn makes progress.
            let taken = self.framer.push(src);
            if taken == 0 {
                return Ok(None);
            }
            src.advance(taken);
        }
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> io::Result<Option<OwnedEvent>> {
        if let Some(event) = self.decode(src)? {
            return Ok(Some(event));
        }
        self.framer.line_idle();
        Ok(self.framer.next_event().map(|e| e.to_owned()))
    }
}

impl Encoder<Write<'_>> for FrameCodec {
    type Error = io::Error;

    fn encode(&mut self, item: Write<'_>, dst: &mut BytesMut) -> io::Result<()> {
        match item {
            Write::Frame(frame) => dst.extend_from_slice(frame.as_bytes()),
            Write::Ack => dst.extend_from_slice(&[ACK]),
            Write::Nak => dst.extend_from_slice(&[NAK]),
            Write::Nic => dst.extend_from_slice(&[NIC]),
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::Address;

    fn decode_all(codec: &mut FrameCodec, chunks: &[&[u8]]) -> Vec<OwnedEvent> {
        let mut src = BytesMut::new();
        let mut events = Vec::new();
        for chunk in chunks {
            src.extend_from_slice(chunk);
            while let Some(e) = codec.decode(&mut src).expect("decode") {
                events.push(e);
            }
        }
        while let Some(e) = codec.decode_eof(&mut src).expect("decode at end") {
            events.push(e);
        }
        events
    }

    #[test]
    fn events_in_any_chunking_none_lost_and_a_cut_frame_abandoned_at_the_end() {
        let frame = FrameBuf::new(Address::new(5, 1, 3), 0, b"P?").unwrap();
        let mut bytes = vec![ACK];
        bytes.extend_from_slice(frame.as_bytes());
        bytes.extend_from_slice(&[NIC, NAK]);
        bytes.extend_from_slice(frame.as_bytes());
        let want = vec![
            OwnedEvent::Ack,
            OwnedEvent::Frame(frame.clone()),
            OwnedEvent::Nic,
            OwnedEvent::Nak,
            OwnedEvent::Frame(frame.clone()),
        ];
        assert_eq!(decode_all(&mut FrameCodec::new(), &[&bytes]), want, "one read");
        let singles: Vec<&[u8]> = bytes.chunks(1).collect();
        assert_eq!(decode_all(&mut FrameCodec::new(), &singles), want, "byte by byte");
        // A frame cut short, then the stream ends: abandoned as after
        // silence, never delivered as a frame; its bytes count as noise.
        let mut cut = frame.as_bytes()[..5].to_vec();
        cut.push(ACK);
        let mut codec = FrameCodec::new();
        let events = decode_all(&mut codec, &[&cut]);
        assert!(!events.iter().any(|e| matches!(e, OwnedEvent::Frame(_))), "{events:?}");
        assert!(codec.framer().skipped_bytes() > 0);
    }

    #[test]
    fn writes_frames_and_bare_bytes() {
        let frame = FrameBuf::new(Address::new(5, 1, 3), 0, b"P?").unwrap();
        let mut codec = FrameCodec::new();
        let mut dst = BytesMut::new();
        for w in [Write::Frame(&frame), Write::Ack, Write::Nak, Write::Nic] {
            codec.encode(w, &mut dst).expect("encode");
        }
        let mut want = frame.as_bytes().to_vec();
        want.extend_from_slice(&[ACK, NAK, NIC]);
        assert_eq!(&dst[..], &want[..]);
    }
}
