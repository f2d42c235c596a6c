//! The receive side of one line (serial port or link): the protocol
//! crate's streaming [`Framer`] plus the silence hook (protocol-notes "Framing": a
//! partial candidate is abandoned once the line has been idle), turning
//! bytes into the protocol crate's [`OwnedEvent`]s, which the router can
//! keep while it mutates itself.

use sagebrush_protocol::{Framer, OwnedEvent};

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

    /// Bytes received at `now`.
    pub fn feed(&mut self, now: u64, bytes: &[u8]) -> Vec<OwnedEvent> {
        let mut events = Vec::new();
        if bytes.is_empty() {
            return events;
        }
        self.last_rx = Some(now);
        self.flushed = false;
        self.framer.feed(bytes, |e| events.push(e.to_owned()));
        events
    }

    /// When a partial frame would be abandoned, if one is buffered.
    pub fn idle_deadline(&self) -> Option<u64> {
        match self.last_rx {
            Some(t) if !self.flushed && self.framer.buffered() > 0 => Some(t.saturating_add(self.idle_timeout)),
            _ => None,
        }
    }

    /// Abandons a partial frame once the line has been silent long enough.
    pub fn poll(&mut self, now: u64) -> Vec<OwnedEvent> {
        let mut events = Vec::new();
        if self.idle_deadline().is_some_and(|t| now >= t) {
            self.flushed = true;
            self.framer.flush_idle(|e| events.push(e.to_owned()));
        }
        events
    }

    /// Drops everything buffered (line lost, rate switched).
    pub fn reset(&mut self) {
        self.framer.reset();
        self.flushed = true;
    }

    /// Noise bytes skipped so far.
    pub fn noise_bytes(&self) -> u64 {
        self.framer.skipped_bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sagebrush_protocol::{ACK, Address, FrameBuf};

    #[test]
    fn partial_frame_abandoned_after_silence_then_rescanned() {
        let mut line = LineReceiver::new(10);
        let frame = FrameBuf::new(Address::new(1, 2, 3), 0, b"AW").unwrap();
        // A truncated frame: the ACK after it is taken for its length byte.
        let mut bytes = frame.as_bytes()[..5].to_vec();
        bytes.push(ACK);
        assert!(line.feed(0, &bytes).is_empty());
        assert_eq!(line.idle_deadline(), Some(10));
        assert!(line.poll(9).is_empty());
        // Abandoned: the bytes of a damaged candidate are not acknowledgements.
        assert!(line.poll(10).is_empty());
        assert!(line.noise_bytes() >= 6);
        assert_eq!(line.idle_deadline(), None);
        assert_eq!(line.feed(11, frame.as_bytes()), vec![OwnedEvent::Frame(frame)]);
    }
}
