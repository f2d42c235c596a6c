//! What links receive (ARCHITECTURE "Delivery contract"): answers to
//! forwarded commands, delivery reports of other GCUs, and commands
//! (a client's retransmission recognised as a repeat).

use sagebrush_protocol::{Address, CONTROL_UNIT, DeliveryReport, FrameBuf, LINK_PORT, Undelivered, WILDCARD};

use crate::command::ReadCommand;
use crate::config::LinkKind;
use crate::link::Received;
use crate::outbox::Outbox;
use crate::reverse::AnswerMatch;
use crate::types::{DropReason, LinkId, Origin, Place};

use super::{Router, SCRATCH_KEPT};

impl Router {
    /// Bytes read from `link`.
    pub(super) fn link_bytes(&mut self, now: u64, link: LinkId, bytes: &[u8], out: &mut Outbox) {
        if !self.with_link_receiving(now, link, out, |l, lo, received| l.receive(now, bytes, lo, received)) {
            self.unknown_inputs += 1;
        }
    }

    /// Routes what a link received; the vector goes back to the scratch pool.
    pub(super) fn route_received(&mut self, now: u64, link: LinkId, mut received: Vec<Received>, out: &mut Outbox) {
        for r in received.drain(..) {
            self.on_received(now, link, r, out);
        }
        if self.received_scratch.len() < SCRATCH_KEPT {
            self.received_scratch.push(received);
        }
    }

    fn on_received(&mut self, now: u64, link: LinkId, received: Received, out: &mut Outbox) {
        match received {
            Received::Frame(frame) => self.on_link_frame(now, link, frame, out),
            // A client answers no command: its `?` is a byte in the wrong
            // direction, counted as stray, not a dropped frame.
            Received::Nic if self.links.get(&link).is_some_and(|l| l.config.kind == LinkKind::Client) => {
                if let Some(mut l) = self.links.get_mut(&link) {
                    l.stats.line.stray_bytes += 1;
                }
            }
            Received::Nic => {
                let dropped = match self.reverse.match_nic(link) {
                    AnswerMatch::One(origin) => self.nic_to(now, origin, out).err(),
                    AnswerMatch::Ambiguous => Some(DropReason::AmbiguousAnswer),
                    // Nothing awaits it: no entry; a second `?` of an
                    // answered command (`Spent`: a bare `?` gets no ACK, so
                    // it is the next GCU's second run of a command it took
                    // twice, ARCHITECTURE "Links between GCUs"); or one of a
                    // command its origin was told was not delivered, or
                    // that left (`Disowned`, "Delivery contract"). (`Repeat`
                    // is a result's only: a `?` is never sent again.)
                    AnswerMatch::None | AnswerMatch::Repeat | AnswerMatch::Spent | AnswerMatch::Disowned => {
                        Some(DropReason::Unsolicited)
                    }
                };
                if let Some(reason) = dropped {
                    self.drop_frame(reason, Place::Link(link), Address::new(0, 0, 0), 0, out);
                }
            }
        }
    }

    /// A frame from a link. ARCHITECTURE "Delivery contract": answers
    /// (results, delivery reports) and every frame of a link to another GCU
    /// are ACKed at once, hop by hop; a client's command is ACKed only once
    /// it is delivered (a repeat of it meanwhile is its retransmission, not
    /// a new command), or answered with a report instead.
    fn on_link_frame(&mut self, now: u64, link: LinkId, frame: FrameBuf, out: &mut Outbox) {
        let Some(l) = self.links.get(&link) else { return };
        let kind = l.config.kind;
        let client = kind == LinkKind::Client;
        let f = frame.frame();
        let (dest, source) = (f.dest, f.source);
        // A client acts for this GCU and may speak as its group (Figure 7: a
        // command issued from GCU-2, answered with destination group 2); a
        // link to another GCU never may (a loop or a spoof).
        let own_group = source == self.group && !client;
        if source == WILDCARD || own_group || !l.config.allowed_sources.allows(source) {
            if let Some(mut l) = self.links.get_mut(&link) {
                l.stats.line.drops.add(DropReason::SourceNotAllowed);
            }
            if !client {
                self.ack(now, link, out);
            }
            self.drop_frame(DropReason::SourceNotAllowed, Place::Link(link), dest, source, out);
            if source != WILDCARD {
                self.stats.undelivered.add(Undelivered::SourceNotAllowed);
                self.report(now, link, &f, Some(Undelivered::SourceNotAllowed), self.group, out);
            }
            return;
        }
        // A report from another GCU is never a command (a report about a
        // report would bounce between two GCUs forever) nor a result (an
        // extended command's result may look like anything): it settles
        // what it fits, or is dropped.
        let report = (!client && dest.port == LINK_PORT && dest.device == CONTROL_UNIT)
            .then(|| DeliveryReport::parse(f.payload()).ok())
            .flatten();
        if let Some(report) = report {
            self.ack(now, link, out);
            let settled = self.reverse.match_report(link, dest.group, &report);
            if let Some((key, _)) = settled {
                self.with_link(now, link, out, |l, lo| l.reported(now, key, lo));
            }
            match settled.map(|(_, command)| command) {
                Some(Some(id)) => self.resolve(now, id, report.failure.map_or(Ok(()), Err), report.at_group, out),
                Some(None) => {}
                None => self.drop_frame(DropReason::Unsolicited, Place::Link(link), dest, source, out),
            }
            return;
        }
        let repeats = self.links.get(&link).is_some_and(|l| !l.config.lossless);
        match self.reverse.match_result(now, link, &f, repeats) {
            AnswerMatch::One(origin) => {
                self.ack(now, link, out);
                return self.relay_forwarded(now, link, origin, frame, out);
            }
            AnswerMatch::Ambiguous => {
                self.ack(now, link, out);
                return self.drop_frame(DropReason::AmbiguousAnswer, Place::Link(link), dest, source, out);
            }
            // The next GCU sent an answer again because our ACK was lost
            // (ARCHITECTURE "Links between GCUs": a repeat is recognised and
            // not relayed): ACKed again, and that is all; the first copy
            // went back already, hop by hop.
            AnswerMatch::Repeat => return self.ack(now, link, out),
            // Of a command its origin was told was not delivered (or that
            // left), or a second result of one the next GCU ran twice
            // (`Spent`): nobody awaits it (ARCHITECTURE "Delivery contract").
            AnswerMatch::Disowned | AnswerMatch::Spent => {
                self.ack(now, link, out);
                return self.drop_frame(DropReason::Unsolicited, Place::Link(link), dest, source, out);
            }
            AnswerMatch::None => {}
        }
        if client {
            let repeat = self
                .in_flight
                .values()
                .any(|c| c.delivery.is_some() && c.origin.link() == Some(link) && c.command.frame == frame)
                || self.report_on_its_way(link, &f);
            if repeat {
                if let Some(mut l) = self.links.get_mut(&link) {
                    l.stats.repeats += 1;
                }
                return;
            }
        } else {
            self.ack(now, link, out);
        }
        self.routes.learn(source, link, kind);
        let command = ReadCommand::read(frame);
        self.dispatch(
            now,
            Origin::Link { link, source },
            Some(kind),
            command,
            None,
            Default::default(),
            out,
        );
    }
}
