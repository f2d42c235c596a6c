//! Streaming framer: turns a byte stream in any chunking into frames and the
//! bare ACK/NAK/NIC bytes (Table 1, 1.4.2), with resynchronisation.
//!
//! Rules (NOTES "Framing"):
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
use crate::frame::{ACK, Frame, HEADER_LEN, MAX_FRAME_LEN, NAK, NIC, START, checksum, payload_len};

/// Default buffer size: room for two maximum frames, so compaction is rare.
pub const DEFAULT_CAPACITY: usize = 2 * MAX_FRAME_LEN;

/// A candidate frame whose checksum did not hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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

/// Counters of what the framer passed over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
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
            let total = match rest {
                [_, _, _, _, _, len, ..] => HEADER_LEN + payload_len(*len) + 1,
                _ => MAX_FRAME_LEN,
            };
            let Some(candidate) = rest.get(..total) else {
                if !idle {
                    return done(i, m, mask, i, None);
                }
                // Line silent: this candidate will never complete.
                stats.abandoned += 1;
                m = m.max(data.len());
                i += 1;
                continue;
            };
            // `candidate` holds `total` >= 7 bytes: start, five header
            // bytes, the payload and the checksum, so both patterns match.
            let (Some((&found, body)), &[_, group, port, device, source, ..]) = (candidate.split_last(), candidate)
            else {
                i += 1;
                continue;
            };
            let dest = Address::new(group, port, device);
            let expected = checksum(body.get(1..).unwrap_or_default());
            if expected == found {
                let frame = Frame::new(dest, source, body.get(HEADER_LEN..).unwrap_or_default());
                if let Ok(frame) = frame {
                    return done(i + total, m, mask, i, Some(Event::Frame(frame)));
                }
            }
            stats.bad_checksums += 1;
            m = m.max(i + total);
            if !masked {
                let bad = BadChecksum {
                    dest,
                    source,
                    payload_len: total - HEADER_LEN - 1,
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
