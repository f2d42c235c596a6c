//! The receive side of one line (serial port or link): the protocol
//! crate's streaming [`Framer`] plus the silence hook (protocol-notes "Framing": a
//! partial candidate is abandoned once the line has been idle), turning
//! bytes into the protocol crate's [`OwnedEvent`]s, which the router can
//! keep while it mutates itself. It is the receive prologue both kinds of
//! line share: what it counts (bytes, frames, damaged frames, noise, when
//! the line was last heard) is counted here once; what a frame or an ACK
//! means differs between a port and a link (modules `port`, `link`).

use sagebrush_protocol::{Event, Framer, OwnedEvent};

use crate::stats::LineStats;

/// The receive side of one line: bytes in, framer events out, a partial
/// frame abandoned after silence.
#[derive(Debug)]
pub(crate) struct LineReceiver {
    framer: Framer,
    idle_timeout: u64,
    last_rx: Option<u64>,
    /// The framer was told the line is idle since the last byte.
    flushed: bool,
}

impl LineReceiver {
    pub fn new(idle_timeout: u64) -> Self {
        Self {
            framer: Framer::new(),
            idle_timeout,
            last_rx: None,
            flushed: true,
        }
    }

    /// Bytes read from the line at `now`: counted, and when the line was
    /// last heard. Take the events they complete with [`LineReceiver::next_event`].
    pub fn heard(now: u64, bytes: &[u8], stats: &mut LineStats) {
        stats.bytes_in += bytes.len() as u64;
        if !bytes.is_empty() {
            stats.last_seen = Some(now);
        }
    }

    /// The next event, taking bytes received at `now` from the front of
    /// `rest` as the framer has room for them; `None` once `rest` is used up
    /// and nothing more is decided. Events come out one at a time, so that
    /// receiving needs no list of them. After [`LineReceiver::poll`], pass an
    /// empty `rest` to collect what the silence decided. Frames and damaged
    /// frames are counted in `stats` (the caller answers a damaged one
    /// with a NAK: `naks_sent`), and the noise skipped once nothing is left.
    pub fn next_event(&mut self, now: u64, rest: &mut &[u8], stats: &mut LineStats) -> Option<OwnedEvent> {
        loop {
            if let Some(event) = self.framer.next_event() {
                match event {
                    Event::Frame(_) => stats.frames_in += 1,
                    Event::BadChecksum(_) => {
                        stats.bad_checksums += 1;
                        stats.naks_sent += 1;
                    }
                    _ => {}
                }
                return Some(event.to_owned());
            }
            if rest.is_empty() {
                stats.noise_bytes = self.framer.skipped_bytes();
                return None;
            }
            self.last_rx = Some(now);
            self.flushed = false;
            let taken = self.framer.push(rest);
            *rest = rest.get(taken..).unwrap_or_default();
            // The framer always has room once its events are taken; this
            // only bounds the loop.
            if taken == 0 {
                stats.noise_bytes = self.framer.skipped_bytes();
                return None;
            }
        }
    }

    /// When a partial frame would be abandoned, if one is buffered.
    pub fn idle_deadline(&self) -> Option<u64> {
        match self.last_rx {
            Some(t) if !self.flushed && self.framer.buffered() > 0 => Some(t.saturating_add(self.idle_timeout)),
            _ => None,
        }
    }

    /// Abandons a partial frame once the line has been silent long enough;
    /// take what the framer then finds with [`LineReceiver::next_event`]
    /// (no bytes).
    pub fn poll(&mut self, now: u64) {
        if self.idle_deadline().is_some_and(|t| now >= t) {
            self.flushed = true;
            self.framer.line_idle();
        }
    }

    /// Partial frames abandoned on silence so far (the framer's count).
    pub fn abandoned(&self) -> u64 {
        self.framer.stats().abandoned
    }

    /// Drops everything buffered (line lost, rate switched).
    pub fn reset(&mut self) {
        self.framer.reset();
        self.flushed = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::{ACK, Address, FrameBuf};

    #[test]
    fn partial_frame_abandoned_after_silence_then_rescanned() {
        let mut line = LineReceiver::new(10);
        let mut stats = LineStats::default();
        let frame = FrameBuf::new(Address::new(1, 2, 3), 0, b"AW").unwrap();
        // A truncated frame: the ACK after it is taken for its length byte.
        let mut bytes = frame.as_bytes()[..5].to_vec();
        bytes.push(ACK);
        LineReceiver::heard(0, &bytes, &mut stats);
        assert_eq!((stats.bytes_in, stats.last_seen), (6, Some(0)));
        let mut rest = &bytes[..];
        assert_eq!(line.next_event(0, &mut rest, &mut stats), None);
        assert!(rest.is_empty(), "every byte taken");
        assert_eq!(stats.noise_bytes, 0, "a candidate, not yet noise");
        assert_eq!(line.idle_deadline(), Some(10));
        line.poll(9);
        assert_eq!(line.next_event(9, &mut &[][..], &mut stats), None);
        // Abandoned: the bytes of a damaged candidate are not acknowledgements.
        line.poll(10);
        assert_eq!(line.next_event(10, &mut &[][..], &mut stats), None);
        assert!(stats.noise_bytes >= 6, "{stats:?}");
        assert_eq!(stats.frames_in, 0);
        assert_eq!(line.idle_deadline(), None);
        let wire = frame.as_bytes().to_vec();
        LineReceiver::heard(11, &wire, &mut stats);
        let mut rest = &wire[..];
        assert_eq!(
            line.next_event(11, &mut rest, &mut stats),
            Some(OwnedEvent::Frame(frame))
        );
        assert_eq!(line.next_event(11, &mut rest, &mut stats), None);
        assert_eq!(stats.frames_in, 1);
        assert_eq!((stats.bytes_in, stats.last_seen), (6 + wire.len() as u64, Some(11)));
        assert_eq!(stats.bad_checksums, 0);
    }
}
