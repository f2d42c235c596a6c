//! One direction of one interface, split into records by the protocol
//! crate's [`Framer`]: frames, bare ACK/NAK/NIC bytes, bad-checksum
//! candidates and the noise between them, each with the time the chunk
//! holding its first byte was read or written.

use std::collections::VecDeque;
use std::time::{Duration, Instant, SystemTime};

use sagebrush_protocol::{Event, Framer};

use super::record::RecordKind;

/// One direction of one interface, split into records.
pub struct Stream {
    framer: Box<Framer>,
    /// Bytes from stream offset `base` on, kept until recorded.
    raw: Vec<u8>,
    base: u64,
    /// Bytes before this offset are in a record.
    covered: u64,
    /// Stream offset and time of each chunk still in `raw`.
    chunks: VecDeque<(u64, SystemTime)>,
    /// When the last chunk came.
    last: Instant,
}

impl Stream {
    pub fn new() -> Self {
        Self {
            framer: Box::new(Framer::new()),
            raw: Vec::new(),
            base: 0,
            covered: 0,
            chunks: VecDeque::new(),
            last: Instant::now(),
        }
    }

    /// Takes in a chunk read or written at `at`, and collects the records
    /// it completes as (kind, start, end) stream offsets.
    pub fn push(&mut self, at: SystemTime, bytes: &[u8], records: &mut Vec<(RecordKind, u64, u64)>) {
        let offset = self.base + self.raw.len() as u64;
        self.chunks.push_back((offset, at));
        self.raw.extend_from_slice(bytes);
        self.last = Instant::now();
        let mut input = bytes;
        // Each round pushes at least one byte (the framer drains to make room).
        for _ in 0..=bytes.len() {
            if input.is_empty() {
                break;
            }
            let n = self.framer.push(input);
            input = &input[n..];
            self.drain(records);
            if n == 0 && self.framer.buffered() > 0 {
                // Full of an undecidable candidate: give it up.
                self.framer.line_idle();
                self.drain(records);
            }
        }
    }

    /// Whether an incomplete candidate has waited `idle` for its next byte.
    pub fn silent_for(&self, idle: Duration) -> bool {
        self.framer.buffered() > 0 && self.last.elapsed() >= idle
    }

    /// Whether an incomplete candidate waits for more bytes.
    pub fn holds_bytes(&self) -> bool {
        self.framer.buffered() > 0
    }

    /// Gives up an incomplete candidate (line silent or closed): its bytes
    /// are collected as records.
    pub fn give_up(&mut self, records: &mut Vec<(RecordKind, u64, u64)>) {
        self.framer.line_idle();
        self.drain(records);
    }

    /// When the chunk holding stream offset `offset` came.
    pub fn time_of(&self, offset: u64) -> SystemTime {
        self.chunks
            .iter()
            .rev()
            .find(|(start, _)| *start <= offset)
            .or(self.chunks.front())
            .map_or_else(SystemTime::now, |(_, t)| *t)
    }

    /// The bytes from stream offset `from` to `to` (as far as kept).
    pub fn bytes(&self, from: u64, to: u64) -> &[u8] {
        let a = (from.saturating_sub(self.base) as usize).min(self.raw.len());
        let b = (to.saturating_sub(self.base) as usize).min(self.raw.len());
        &self.raw[a..b.max(a)]
    }

    /// Collects the framer's decisions as (kind, start, end) records.
    fn drain(&mut self, out: &mut Vec<(RecordKind, u64, u64)>) {
        // Each event consumes at least one byte of a bounded buffer.
        for _ in 0..=self.raw.len() + 1 {
            let (kind, bad_at, len) = match self.framer.next_event() {
                None => break,
                Some(Event::Frame(f)) => (RecordKind::Frame, None, f.wire_len() as u64),
                Some(Event::Ack) => (RecordKind::Ack, None, 1),
                Some(Event::Nak) => (RecordKind::Nak, None, 1),
                Some(Event::Nic) => (RecordKind::Nic, None, 1),
                Some(Event::BadChecksum(b)) => (RecordKind::BadChecksum, Some(b.offset), 7 + b.payload_len as u64),
            };
            let end_consumed = self.framer.stream_offset();
            let start = bad_at.unwrap_or_else(|| end_consumed.saturating_sub(len));
            if start > self.covered {
                out.push((RecordKind::Noise, self.covered, start));
            }
            out.push((kind, start, start + len));
            self.covered = self.covered.max(start + len);
        }
        let decided = self.framer.stream_offset();
        if decided > self.covered {
            out.push((RecordKind::Noise, self.covered, decided));
            self.covered = decided;
        }
    }

    /// Forgets bytes no record can need any more.
    pub fn trim(&mut self) {
        let keep = self.covered.min(self.framer.stream_offset());
        if keep > self.base {
            let n = ((keep - self.base) as usize).min(self.raw.len());
            self.raw.drain(..n);
            self.base += n as u64;
        }
        while self.chunks.len() > 1 && self.chunks[1].0 <= self.base {
            self.chunks.pop_front();
        }
    }
}
