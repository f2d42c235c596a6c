//! Streaming framer: turns a byte stream in any chunking into frames and the
//! bare ACK/NAK/NIC bytes (Table 1, 1.4.2), with resynchronisation.
//!
//! Rules (protocol-notes "Framing"):
//! - A candidate starts at `0xF8` and claims `7 + len` bytes. A candidate
//!   whose checksum fails is reported once as [`Event::BadChecksum`] (so a
//!   receiver can NAK) and the scan resumes at the byte after its `0xF8`,
//!   because `0xF8` also occurs as an address, length or checksum byte.
//! - Inside the span of a rejected candidate only `0xF8` starts something:
//!   `0x06`, `0x15` and `?` there are bytes of a damaged frame (device 6, a
//!   `P?` payload ...), not acknowledgements. Candidates nested in a rejected
//!   span are dropped silently, so one damaged frame gives one NAK.
//! - Any other byte between frames is noise: skipped and counted.
//! - [`Framer::line_idle`] (the silence hook) abandons an incomplete candidate
//!   and rescans what it had buffered; [`Framer::reset`] drops everything.
//! - Payload bytes are not checked for ASCII: `*xpt` may carry raw bytes.

use crate::address::Address;
use crate::frame::{ACK, Frame, FrameBuf, HEADER_LEN, Header, MAX_FRAME_LEN, NAK, NIC, PayloadLen, START, layout};

/// Default buffer size: room for two maximum frames, so compaction is rare.
pub const DEFAULT_CAPACITY: usize = 2 * MAX_FRAME_LEN;

/// A candidate frame whose checksum did not hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BadChecksum {
    /// Destination bytes as received (they may be the damaged ones).
    pub dest: Address,
    /// Source group byte as received.
    pub source: u8,
    /// Payload length announced by the length byte.
    pub payload_len: usize,
    /// Checksum computed over the received bytes.
    pub expected: u8,
    /// Checksum byte received.
    pub found: u8,
    /// Stream offset of the candidate's `0xF8`.
    pub offset: u64,
}

/// What the framer recognised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event<'a> {
    /// A frame whose checksum holds.
    Frame(Frame<'a>),
    /// A bare ACK (0x06).
    Ack,
    /// A bare NAK (0x15).
    Nak,
    /// A bare NIC `?` (0x3F).
    Nic,
    /// A frame-sized candidate whose checksum failed: NAK it.
    BadChecksum(BadChecksum),
}

/// An owned [`Event`]: the same five cases, with the frame copied into a
/// [`FrameBuf`], for queues and channels that outlive the framer's buffer.
/// Build one with [`Event::to_owned`] or `From`; borrow it back with
/// [`OwnedEvent::as_event`].
///
/// The frame is held inline (this crate has no `alloc`), so the type is
/// about 270 bytes; a caller that queues many may box it.
#[allow(
    clippy::large_enum_variant,
    reason = "no alloc: the frame is held inline, as in FrameBuf"
)]
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OwnedEvent {
    /// A frame whose checksum holds.
    Frame(FrameBuf),
    /// A bare ACK (0x06).
    Ack,
    /// A bare NAK (0x15).
    Nak,
    /// A bare NIC `?` (0x3F).
    Nic,
    /// A frame-sized candidate whose checksum failed: NAK it.
    BadChecksum(BadChecksum),
}

impl Event<'_> {
    /// An owned copy (the frame's bytes copied into a [`FrameBuf`]). Takes
    /// precedence over `ToOwned::to_owned`, which would give an `Event`.
    pub fn to_owned(&self) -> OwnedEvent {
        match *self {
            Event::Frame(frame) => OwnedEvent::Frame(FrameBuf::from_frame(&frame)),
            Event::Ack => OwnedEvent::Ack,
            Event::Nak => OwnedEvent::Nak,
            Event::Nic => OwnedEvent::Nic,
            Event::BadChecksum(bad) => OwnedEvent::BadChecksum(bad),
        }
    }
}

impl OwnedEvent {
    /// The event as the framer gave it, borrowing the frame from `self`
    /// (for `Transaction::on_event` and other consumers of [`Event`]).
    pub fn as_event(&self) -> Event<'_> {
        match self {
            OwnedEvent::Frame(frame) => Event::Frame(frame.frame()),
            OwnedEvent::Ack => Event::Ack,
            OwnedEvent::Nak => Event::Nak,
            OwnedEvent::Nic => Event::Nic,
            OwnedEvent::BadChecksum(bad) => Event::BadChecksum(*bad),
        }
    }
}

impl From<Event<'_>> for OwnedEvent {
    fn from(event: Event<'_>) -> Self {
        event.to_owned()
    }
}

impl From<&Event<'_>> for OwnedEvent {
    fn from(event: &Event<'_>) -> Self {
        event.to_owned()
    }
}

impl PartialEq<Event<'_>> for OwnedEvent {
    fn eq(&self, other: &Event<'_>) -> bool {
        self.as_event() == *other
    }
}

/// Counters of what the framer passed over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FramerStats {
    /// Bytes that were part of no Frame/Ack/Nak/Nic event.
    pub skipped_bytes: u64,
    /// Candidates rejected for their checksum (reported or nested).
    pub bad_checksums: u64,
    /// Incomplete candidates abandoned on line silence or reset.
    pub abandoned: u64,
}

/// One decision of the scanner over `data`.
struct Step<'d> {
    /// Bytes consumed from the front of `data`.
    consumed: usize,
    /// How many of those were skipped (not part of the event).
    skipped: usize,
    event: Option<Event<'d>>,
}

/// Scans `data` until an event or the need for more bytes.
/// `mask` (in, out) is how many leading bytes lie inside a rejected span.
fn scan<'d>(data: &'d [u8], mask: &mut usize, idle: bool, offset: u64, stats: &mut FramerStats) -> Step<'d> {
    let mut m = *mask; // absolute index into data
    let mut i = 0;
    let done = |i: usize, m: usize, mask: &mut usize, skipped: usize, event| {
        *mask = m.saturating_sub(i);
        Step {
            consumed: i,
            skipped,
            event,
        }
    };
    // Indexing below goes through `get` and slice patterns: a firmware image
    // links no bounds-check panic for the framer (firmware/build.sh checks).
    while let Some(&byte) = data.get(i) {
        let masked = i < m;
        if byte == START {
            let rest = data.get(i..).unwrap_or_default();
            // The candidate's span comes from its length byte (layout, Table 1).
            let total = match rest.first_chunk::<HEADER_LEN>() {
                Some(head) => layout::wire_len(PayloadLen::from_byte(head[layout::LENGTH])),
                None => MAX_FRAME_LEN,
            };
            let Some((head, candidate)) = rest.get(..total).and_then(|c| Some((c.first_chunk()?, c))) else {
                if !idle {
                    return done(i, m, mask, i, None);
                }
                // Line silent: this candidate will never complete.
                stats.abandoned += 1;
                m = m.max(data.len());
                i += 1;
                continue;
            };
            // `candidate` is exactly one frame's span, as `Frame::parse` checks it.
            let header = Header::read(head);
            let (expected, found) = match Frame::check(header, candidate) {
                Ok(frame) => return done(i + total, m, mask, i, Some(Event::Frame(frame))),
                Err(sums) => sums,
            };
            stats.bad_checksums += 1;
            m = m.max(i + total);
            if !masked {
                let bad = BadChecksum {
                    dest: header.dest,
                    source: header.source,
                    payload_len: header.len.get(),
                    expected,
                    found,
                    offset: offset + i as u64,
                };
                return done(i + 1, m, mask, i + 1, Some(Event::BadChecksum(bad)));
            }
            i += 1;
            continue;
        }
        if !masked {
            let event = match byte {
                ACK => Some(Event::Ack),
                NAK => Some(Event::Nak),
                NIC => Some(Event::Nic),
                _ => None,
            };
            if event.is_some() {
                return done(i + 1, m, mask, i, event);
            }
        }
        i += 1;
    }
    done(i, m, mask, i, None)
}

/// The streaming framer, with a fixed buffer of `N` bytes (`N` >= 263).
///
/// Two ways to drive it:
/// - [`Framer::feed`] with a callback: complete frames in the input are
///   parsed in place (zero copy); only a trailing partial frame is buffered.
/// - [`Framer::push`] (or [`Framer::spare_capacity_mut`] + [`Framer::commit`]
///   for DMA) and then [`Framer::next_event`] until it returns `None`.
#[derive(Debug)]
pub struct Framer<const N: usize = DEFAULT_CAPACITY> {
    buf: [u8; N],
    start: usize,
    end: usize,
    /// Bytes from `start` that lie inside a rejected candidate's span.
    mask: usize,
    idle: bool,
    /// Stream offset of `buf[start]`.
    offset: u64,
    stats: FramerStats,
}

impl<const N: usize> Default for Framer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Framer<N> {
    /// An empty framer; `N` must be at least [`MAX_FRAME_LEN`] (checked at compile time).
    pub const fn new() -> Self {
        const { assert!(N >= MAX_FRAME_LEN, "a framer must hold one maximum frame (263 bytes)") };
        Self {
            buf: [0; N],
            start: 0,
            end: 0,
            mask: 0,
            idle: false,
            offset: 0,
            stats: FramerStats {
                skipped_bytes: 0,
                bad_checksums: 0,
                abandoned: 0,
            },
        }
    }

    /// Counters since creation.
    pub fn stats(&self) -> FramerStats {
        self.stats
    }

    /// Bytes skipped since creation (noise and rejected candidates).
    pub fn skipped_bytes(&self) -> u64 {
        self.stats.skipped_bytes
    }

    /// Bytes buffered and not yet decided.
    pub fn buffered(&self) -> usize {
        self.end.saturating_sub(self.start)
    }

    /// Stream offset of the next byte to be decided.
    pub fn stream_offset(&self) -> u64 {
        self.offset
    }

    /// Moves the undecided bytes to the front. Byte by byte through `get`,
    /// so that no bounds-check panic is linked (`copy_within` has one); it
    /// runs when the buffer is full or empty, and then moves a partial frame
    /// at most.
    fn compact(&mut self) {
        if self.start > 0 {
            let len = self.buffered();
            for to in 0..len {
                if let Some(&byte) = self.buf.get(self.start + to) {
                    if let Some(slot) = self.buf.get_mut(to) {
                        *slot = byte;
                    }
                }
            }
            self.end = len;
            self.start = 0;
        }
    }

    /// Copies as many of `bytes` as fit; returns how many. Call
    /// [`Framer::next_event`] until `None` before pushing the rest.
    pub fn push(&mut self, bytes: &[u8]) -> usize {
        let spare = self.spare_capacity_mut();
        let mut n = 0;
        for (slot, &byte) in spare.iter_mut().zip(bytes) {
            *slot = byte;
            n += 1;
        }
        self.commit(n);
        n
    }

    /// Free space at the end of the buffer, for a DMA or `read` to fill;
    /// then [`Framer::commit`] the count written.
    pub fn spare_capacity_mut(&mut self) -> &mut [u8] {
        if self.end == N || self.start == self.end {
            self.compact();
        }
        self.buf.get_mut(self.end..).unwrap_or_default()
    }

    /// Marks `n` bytes written into [`Framer::spare_capacity_mut`] as received.
    pub fn commit(&mut self, n: usize) {
        self.end = self.end.saturating_add(n).min(N);
        if n > 0 {
            self.idle = false;
        }
    }

    /// The next event decided from the buffered bytes, if any.
    pub fn next_event(&mut self) -> Option<Event<'_>> {
        let step = scan(
            self.buf.get(self.start..self.end).unwrap_or_default(),
            &mut self.mask,
            self.idle,
            self.offset,
            &mut self.stats,
        );
        self.stats.skipped_bytes += step.skipped as u64;
        self.start += step.consumed;
        self.offset += step.consumed as u64;
        step.event
    }

    /// Feeds `input` and calls `on_event` for every event it completes.
    pub fn feed(&mut self, input: &[u8], mut on_event: impl FnMut(Event<'_>)) {
        let mut input = input;
        if !input.is_empty() {
            // New bytes end the silence, as in `commit`: a later `next_event`
            // must not abandon a candidate these bytes may still complete.
            self.idle = false;
        }
        // Finish what is buffered first.
        while self.start < self.end && !input.is_empty() {
            let n = self.push(input);
            input = input.get(n..).unwrap_or_default();
            while let Some(event) = self.next_event() {
                on_event(event);
            }
        }
        if input.is_empty() {
            return;
        }
        // Zero copy over the rest; only a trailing partial candidate is buffered.
        loop {
            let step = scan(input, &mut self.mask, false, self.offset, &mut self.stats);
            self.stats.skipped_bytes += step.skipped as u64;
            self.offset += step.consumed as u64;
            input = input.get(step.consumed..).unwrap_or_default();
            match step.event {
                Some(event) => on_event(event),
                None => break,
            }
        }
        // A partial candidate is shorter than a maximum frame, so it fits.
        self.start = 0;
        self.end = 0;
        for (slot, &byte) in self.buf.iter_mut().zip(input) {
            *slot = byte;
            self.end += 1;
        }
    }

    /// The line has been silent longer than a frame takes: an incomplete
    /// candidate will never complete. Abandons it and rescans the buffered
    /// bytes; call [`Framer::next_event`] until `None` to collect what that
    /// finds. Pushing more bytes ends the idle state.
    pub fn line_idle(&mut self) {
        self.idle = true;
    }

    /// [`Framer::line_idle`] and collect its events through a callback.
    pub fn flush_idle(&mut self, mut on_event: impl FnMut(Event<'_>)) {
        self.line_idle();
        while let Some(event) = self.next_event() {
            on_event(event);
        }
    }

    /// Drops everything buffered (counted as skipped and abandoned).
    pub fn reset(&mut self) {
        let dropped = self.buffered();
        if dropped > 0 {
            self.stats.skipped_bytes += dropped as u64;
            self.stats.abandoned += 1;
        }
        self.offset += dropped as u64;
        self.start = 0;
        self.end = 0;
        self.mask = 0;
        self.idle = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every event of a stream, owned.
    fn owned_events(bytes: &[u8]) -> ([Option<OwnedEvent>; 8], usize) {
        let mut out: [Option<OwnedEvent>; 8] = Default::default();
        let mut n = 0;
        let mut framer: Framer = Framer::new();
        framer.feed(bytes, |event| {
            if let Some(slot) = out.get_mut(n) {
                *slot = Some(event.to_owned());
            }
            n += 1;
        });
        (out, n)
    }

    #[test]
    fn owned_events_round_trip() {
        // `P?` to 5.1.12 from 2, ACK, NAK, NIC, then the frame with its
        // checksum damaged (rescanned from the byte after its 0xF8).
        let good = [0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5];
        let mut bad = good;
        bad[8] = 0xA6;
        let mut stream = [0u8; 21];
        stream[..9].copy_from_slice(&good);
        stream[9..12].copy_from_slice(&[ACK, NAK, NIC]);
        stream[12..].copy_from_slice(&bad);
        let (events, n) = owned_events(&stream);
        assert_eq!(n, 5);
        let frame = FrameBuf::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
        assert_eq!(events[0], Some(OwnedEvent::Frame(frame.clone())));
        assert_eq!(events[1], Some(OwnedEvent::Ack));
        assert_eq!(events[2], Some(OwnedEvent::Nak));
        assert_eq!(events[3], Some(OwnedEvent::Nic));
        let Some(OwnedEvent::BadChecksum(damaged)) = events[4] else {
            panic!("{:?}", events[4]);
        };
        assert_eq!((damaged.expected, damaged.found, damaged.offset), (0xA5, 0xA6, 12));
        assert_eq!(damaged.dest, Address::new(5, 1, 12));

        // Back to borrowed events, equal to what the framer gave.
        let original = Frame::new(Address::new(5, 1, 12), 2, b"P?").unwrap();
        let owned = OwnedEvent::from(Event::Frame(original));
        assert_eq!(owned.as_event(), Event::Frame(original));
        assert_eq!(owned, Event::Frame(original));
        assert_ne!(owned, Event::Ack);
        for event in [Event::Ack, Event::Nak, Event::Nic, Event::BadChecksum(damaged)] {
            let owned = OwnedEvent::from(&event);
            assert_eq!(owned.as_event(), event);
            assert_eq!(event.to_owned(), owned);
        }
        // The owned frame outlives the bytes it came from.
        let kept = {
            let bytes = good;
            let (frame, _) = Frame::parse(&bytes).unwrap();
            Event::Frame(frame).to_owned()
        };
        assert_eq!(kept, OwnedEvent::Frame(frame));
    }
}
