//! One link toward the MCU, another GCU or a client (ARCHITECTURE "Routing
//! semantics"): NAK of every damaged frame received, ACK when the router
//! says so (ARCHITECTURE "Delivery contract": at once for answers and on
//! links to other GCUs, on delivery for a client's command), and a bounded send queue whose
//! head is retransmitted by the protocol crate's [`Transmitter`] on NAK or
//! ACK time-out, up to the configured count. ACK/NAK bytes carry no address,
//! so a link has one unacknowledged frame at a time (stop and wait). On a
//! lossless link (TCP) frames go out back to back instead: nothing is ever
//! retransmitted or given up there.
//!
//! Forwarded stop commands overtake the frames waiting on the link (not the
//! one in flight), are bounded apart from them (so that a burst of traffic
//! never costs a stop its place, ARCHITECTURE "Safety"), and a stop identical to
//! one already waiting is merged into it.

use sagebrush_protocol::{FrameBuf, OwnedEvent, RetryPolicy, Transmitter, TxStep};

use crate::config::{LinkConfig, LinkSettings};
use crate::line::LineReceiver;
use crate::outbox::Wire;
use crate::queue::{Queued, StopFirstQueue};
use crate::stats::LinkStats;
use crate::types::DropReason;

/// A frame waiting on a link, with the reverse-path entry it belongs to.
#[derive(Clone, Debug)]
pub(crate) struct Outgoing {
    pub frame: FrameBuf,
    pub pending: Option<u64>,
    /// A forwarded stop command.
    pub stop: bool,
    /// A dead-man stop (ARCHITECTURE "Safety"): never refused for a full queue.
    /// Their number is bounded by the motions the router tracks.
    pub dead_man: bool,
}

impl Queued for Outgoing {
    fn is_stop(&self) -> bool {
        self.stop
    }
    fn always_fits(&self) -> bool {
        self.dead_man
    }
    fn same_frame(&self, other: &Self) -> bool {
        self.frame == other.frame
    }
}

/// What a link asks the router to do or know; a frame to write, or one
/// given up, is held inline, without an allocation of its own, on its
/// short way to the Outbox.
#[derive(Debug)]
pub(crate) enum LinkOut {
    Write(Wire),
    /// The frame of this reverse-path entry was transmitted for the first time.
    FirstSent(u64),
    /// ... and again: the next GCU may execute it twice.
    Resent(u64),
    /// The frame was given up (by value: a `Box` here was an allocation
    /// per frame a link gave up, ARCHITECTURE "Scale").
    Failed(Outgoing, DropReason),
}

/// What arrived on a link for the router to route.
#[derive(Debug)]
#[expect(
    clippy::large_enum_variant,
    reason = "a frame moves by value, without an allocation of its own, on its short way to routing"
)]
pub(crate) enum Received {
    Frame(FrameBuf),
    Nic,
}

#[derive(Debug)]
pub(crate) struct Link {
    pub config: LinkConfig,
    line: LineReceiver,
    /// A frame in flight is its pinned head: nothing overtakes it.
    queue: StopFirstQueue<Outgoing>,
    tx: Transmitter,
    pub stats: LinkStats,
    /// This connection asked for end-of-window reports (`~W`; router
    /// module `window`): it lives and dies with the connection.
    pub window_reports: bool,
    /// The user this connection's door acts for now (`~U`; module
    /// `principal`): its next commands are that user's.
    pub acting: Option<crate::principal::Actor>,
    /// The principal and priority this GCU last said its commands on this
    /// link are from (`~P`, [`crate::LinkConfig::sends_principals`]).
    pub principal_sent: Option<(std::sync::Arc<str>, u8)>,
}

impl Link {
    pub fn new(config: LinkConfig, settings: &LinkSettings, stats: LinkStats) -> Self {
        let policy = RetryPolicy {
            ack_timeout: settings.ack_timeout,
            retries: settings.retries,
        };
        Self {
            config,
            line: LineReceiver::new(settings.idle_timeout),
            queue: StopFirstQueue::new(settings.queue_bound, settings.stop_queue_bound),
            tx: Transmitter::new(policy),
            stats,
            window_reports: false,
            acting: None,
            principal_sent: None,
        }
    }

    fn write(&mut self, wire: Wire, out: &mut Vec<LinkOut>) {
        self.stats.line.bytes_out += wire.as_bytes().len() as u64;
        out.push(LinkOut::Write(wire));
    }

    /// Writes a bare ACK for a frame received intact (hop by hop), or for
    /// a client's command once it is delivered.
    pub fn ack(&mut self, out: &mut Vec<LinkOut>) {
        self.stats.acks_sent += 1;
        self.write(Wire::Ack, out);
    }

    /// Writes a bare `?` (a relayed NIC).
    pub fn write_nic(&mut self, out: &mut Vec<LinkOut>) {
        self.stats.line.nics_out += 1;
        self.write(Wire::Nic, out);
    }

    /// Queues a frame, or says (and counts) why not.
    pub fn enqueue(&mut self, now: u64, item: Outgoing, out: &mut Vec<LinkOut>) -> Result<(), DropReason> {
        let refused = if item.stop && self.queue.same_stop_mut(&item).is_some() {
            Some(DropReason::DuplicateStop)
        } else {
            (!self.queue.has_room(&item)).then_some(DropReason::QueueFull)
        };
        if let Some(reason) = refused {
            self.stats.line.drops.add(reason);
            return Err(reason);
        }
        self.queue.push(item);
        self.stats.queued += 1;
        self.note_queue();
        self.transmit_next(now, out);
        Ok(())
    }

    /// Frames waiting or in flight on this link (not yet acknowledged).
    pub fn unacknowledged(&self) -> impl Iterator<Item = &FrameBuf> {
        self.queue.iter().map(|item| &item.frame)
    }

    fn note_queue(&mut self) {
        self.stats.queue_len = self.queue.len();
        self.stats.queue_high_water = self.queue.high_water();
    }

    fn transmit_next(&mut self, now: u64, out: &mut Vec<LinkOut>) {
        if self.config.lossless {
            // TCP delivers every byte, in order: there is nothing to
            // retransmit and nothing to give up, so frames go out back to
            // back; a client slow to acknowledge loses no answer and gets
            // no duplicate. Its ACKs confirm nothing new.
            while !self.queue.is_empty() {
                self.send_head(out);
                self.step(TxStep::Delivered, out);
            }
            return;
        }
        if self.queue.head_pinned() || self.queue.is_empty() {
            return;
        }
        self.queue.pin_head();
        let step = self.tx.start(now);
        self.step(step, out);
    }

    fn send_head(&mut self, out: &mut Vec<LinkOut>) {
        let Some(head) = self.queue.front() else { return };
        let frame = Wire::Frame(head.frame.clone());
        let first = self.tx.transmissions() <= 1;
        let pending = head.pending;
        self.stats.line.frames_out += 1;
        if first {
            if let Some(key) = pending {
                out.push(LinkOut::FirstSent(key));
            }
        } else {
            self.stats.line.retransmits += 1;
            if let Some(key) = pending {
                out.push(LinkOut::Resent(key));
            }
        }
        self.write(frame, out);
    }

    fn step(&mut self, step: TxStep, out: &mut Vec<LinkOut>) {
        match step {
            TxStep::Send => self.send_head(out),
            TxStep::Wait => {}
            TxStep::Delivered => {
                self.queue.pop_front();
                self.stats.delivered += 1;
                self.note_queue();
            }
            TxStep::Failed(_) => {
                if let Some(item) = self.queue.pop_front() {
                    self.stats.failed += 1;
                    self.stats.line.drops.add(DropReason::LinkNoAck);
                    out.push(LinkOut::Failed(item, DropReason::LinkNoAck));
                }
                self.note_queue();
            }
        }
    }

    /// Bytes from the peer: ACK/NAK what they complete, hand frames and `?`
    /// over in `received` (the caller's, reused).
    pub fn receive(&mut self, now: u64, bytes: &[u8], out: &mut Vec<LinkOut>, received: &mut Vec<Received>) {
        LineReceiver::heard(now, bytes, &mut self.stats.line);
        self.on_events(now, bytes, out, received);
    }

    /// Takes the events `bytes` (or the silence, with none) complete.
    fn on_events(&mut self, now: u64, bytes: &[u8], out: &mut Vec<LinkOut>, received: &mut Vec<Received>) {
        let mut rest = bytes;
        while let Some(event) = self.line.next_event(now, &mut rest, &mut self.stats.line) {
            match event {
                OwnedEvent::Frame(frame) => {
                    // The router writes the ACK: at once, or once the
                    // command is delivered (ARCHITECTURE "Delivery contract").
                    received.push(Received::Frame(frame));
                }
                OwnedEvent::BadChecksum(_) => self.write(Wire::Nak, out),
                OwnedEvent::Ack if self.queue.head_pinned() => {
                    let step = self.tx.on_ack();
                    self.step(step, out);
                }
                OwnedEvent::Nak if self.queue.head_pinned() => {
                    self.stats.line.naks_received += 1;
                    let step = self.tx.on_nak(now);
                    self.step(step, out);
                }
                OwnedEvent::Ack if self.config.lossless => {}
                OwnedEvent::Ack | OwnedEvent::Nak => self.stats.line.stray_bytes += 1,
                OwnedEvent::Nic => {
                    self.stats.line.nics_in += 1;
                    received.push(Received::Nic);
                }
            }
            self.transmit_next(now, out);
        }
    }

    /// The next GCU reported the frame of reverse-path entry `key`: it has
    /// it. When that frame is still in flight here, its ACK was lost (on a
    /// line that keeps order the ACK comes before the report): taken as
    /// that ACK, so that the frame is not sent again, which the next GCU
    /// would run a second time (ARCHITECTURE "Links between GCUs").
    pub fn reported(&mut self, now: u64, key: u64, out: &mut Vec<LinkOut>) {
        let in_flight = self.queue.head_pinned() && self.queue.front().is_some_and(|h| h.pending == Some(key));
        if !in_flight {
            return;
        }
        let step = self.tx.on_ack();
        self.step(step, out);
        self.transmit_next(now, out);
    }

    /// Time passed: retransmit or give up the head, abandon a stale partial frame.
    pub fn poll(&mut self, now: u64, out: &mut Vec<LinkOut>, received: &mut Vec<Received>) {
        if self.queue.head_pinned() && self.tx.deadline().is_some_and(|t| now >= t) {
            self.stats.line.timeouts += 1;
            let step = self.tx.poll(now);
            self.step(step, out);
            self.transmit_next(now, out);
        }
        self.line.poll(now);
        self.on_events(now, &[], out, received);
    }

    pub fn next_deadline(&self) -> Option<u64> {
        let tx = if self.queue.head_pinned() {
            self.tx.deadline()
        } else {
            None
        };
        [tx, self.line.idle_deadline()].into_iter().flatten().min()
    }

    /// The link went down: everything queued is given back.
    pub fn shut_down(&mut self) -> Vec<Outgoing> {
        let dropped = self.queue.drain_all();
        for _ in &dropped {
            self.stats.failed += 1;
            self.stats.line.drops.add(DropReason::LinkDown);
        }
        self.stats.up = false;
        self.note_queue();
        dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{LinkKind, SourceFilter};
    use sagebrush_protocol::{ACK, Address, NAK};

    fn link(settings: &LinkSettings) -> Link {
        let config = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
        Link::new(config, settings, LinkStats::new(LinkKind::Client))
    }

    fn writes(out: &[LinkOut]) -> Vec<Vec<u8>> {
        out.iter()
            .filter_map(|o| match o {
                LinkOut::Write(w) => Some(w.as_bytes().to_vec()),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn naks_bad_and_acks_when_told() {
        let settings = LinkSettings::default();
        let mut l = link(&settings);
        let frame = FrameBuf::new(Address::new(1, 1, 1), 0, b"AW").unwrap();
        let mut bad = frame.as_bytes().to_vec();
        *bad.last_mut().unwrap() ^= 0x01;
        let mut out = Vec::new();
        let mut got = Vec::new();
        l.receive(0, &[frame.as_bytes(), &bad].concat(), &mut out, &mut got);
        assert!(matches!(got.as_slice(), [Received::Frame(f)] if *f == frame));
        assert_eq!(
            writes(&out),
            vec![vec![NAK]],
            "the router decides when a good frame is ACKed"
        );
        out.clear();
        l.ack(&mut out);
        assert_eq!(writes(&out), vec![vec![ACK]]);
        assert_eq!(l.stats.line.bad_checksums, 1);
    }

    #[test]
    fn retransmits_on_nak_and_timeout_then_gives_up() {
        let settings = LinkSettings {
            retries: 2,
            ack_timeout: 10,
            ..LinkSettings::default()
        };
        let mut l = link(&settings);
        let frame = FrameBuf::new(Address::new(0, 1, 1), 3, b"1").unwrap();
        let second = FrameBuf::new(Address::new(0, 1, 2), 3, b"2").unwrap();
        let mut out = Vec::new();
        let item = |frame: &FrameBuf, pending| Outgoing {
            frame: frame.clone(),
            pending,
            stop: false,
            dead_man: false,
        };
        assert!(l.enqueue(0, item(&frame, Some(7)), &mut out).is_ok());
        assert!(l.enqueue(0, item(&second, None), &mut out).is_ok());
        assert!(matches!(out[0], LinkOut::FirstSent(7)));
        assert_eq!(writes(&out), vec![frame.as_bytes().to_vec()]);
        out.clear();
        l.receive(1, &[NAK], &mut out, &mut Vec::new());
        assert_eq!(writes(&out), vec![frame.as_bytes().to_vec()]);
        out.clear();
        assert_eq!(l.next_deadline(), Some(11));
        l.poll(11, &mut out, &mut Vec::new());
        assert_eq!(writes(&out), vec![frame.as_bytes().to_vec()]);
        out.clear();
        l.poll(21, &mut out, &mut Vec::new());
        assert!(matches!(&out[0], LinkOut::Failed(item, DropReason::LinkNoAck) if item.frame == frame));
        assert_eq!(writes(&out), vec![second.as_bytes().to_vec()]);
        out.clear();
        l.receive(22, &[ACK], &mut out, &mut Vec::new());
        assert_eq!(l.stats.delivered, 1);
        assert_eq!(l.stats.failed, 1);
        assert_eq!(l.stats.line.retransmits, 2);
        assert_eq!(l.next_deadline(), None);
    }

    #[test]
    fn bounded_queue_refuses_when_full_stops_overtake_and_merge() {
        let settings = LinkSettings {
            queue_bound: 1,
            stop_queue_bound: 1,
            ..LinkSettings::default()
        };
        let mut l = link(&settings);
        let item = |payload: &[u8], stop| Outgoing {
            frame: FrameBuf::new(Address::new(7, 1, 1), 3, payload).unwrap(),
            pending: None,
            stop,
            dead_man: false,
        };
        let mut out = Vec::new();
        assert_eq!(l.enqueue(0, item(b"HO", false), &mut out), Ok(())); // in flight
        assert_eq!(l.enqueue(0, item(b"P?", false), &mut out), Err(DropReason::QueueFull));
        assert_eq!(l.enqueue(0, item(b"PS", true), &mut out), Ok(()));
        assert_eq!(
            l.enqueue(0, item(b"PS", true), &mut out),
            Err(DropReason::DuplicateStop)
        );
        assert_eq!(l.enqueue(0, item(b"TS", true), &mut out), Err(DropReason::QueueFull));
        assert_eq!(l.stats.line.drops.get(DropReason::QueueFull), 2);
        let dead_man = Outgoing {
            dead_man: true,
            ..item(b"ZS", true)
        };
        assert_eq!(l.enqueue(0, dead_man, &mut out), Ok(()), "a dead-man stop always fits");
        out.clear();
        l.receive(1, &[ACK], &mut out, &mut Vec::new());
        assert_eq!(writes(&out), vec![item(b"PS", true).frame.as_bytes().to_vec()]);
        assert_eq!(l.shut_down().len(), 2);
    }

    #[test]
    fn a_lossless_link_sends_back_to_back_and_never_retransmits() {
        let settings = LinkSettings {
            retries: 2,
            ack_timeout: 10,
            ..LinkSettings::default()
        };
        let mut config = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
        config.lossless = true;
        let mut l = Link::new(config, &settings, LinkStats::new(LinkKind::Client));
        let item = |payload: &[u8]| Outgoing {
            frame: FrameBuf::new(Address::new(0, 1, 1), 5, payload).unwrap(),
            pending: None,
            stop: false,
            dead_man: false,
        };
        let mut out = Vec::new();
        for payload in [b"1", b"2", b"3"] {
            assert_eq!(l.enqueue(0, item(payload), &mut out), Ok(()));
        }
        assert_eq!(writes(&out).len(), 3, "all three at once, no ACK awaited");
        out.clear();
        let mut got = Vec::new();
        l.poll(1000, &mut out, &mut got);
        assert!(got.is_empty());
        assert!(writes(&out).is_empty(), "nothing retransmitted");
        assert_eq!(l.next_deadline(), None);
        l.receive(1001, &[ACK, ACK, ACK], &mut out, &mut Vec::new());
        assert_eq!((l.stats.delivered, l.stats.failed, l.stats.line.stray_bytes), (3, 0, 0));
    }
}
