//! The delivery contract (ARCHITECTURE "Delivery contract"): a link's
//! command is told once whether it was delivered, a client with the ACK
//! it waited for or a delivery report instead, a link to another GCU with
//! a report either way; and a client's delivery time-out.

use sagebrush_protocol::{Address, CONTROL_UNIT, DeliveryReport, Frame, FrameBuf, LINK_PORT, Undelivered};

use crate::boundary::Action;
use crate::outbox::Outbox;
use crate::types::{CommandId, DropReason, LinkId, Origin, Place, RouterEvent};

use super::Router;
use super::in_flight::Delivery;

impl Router {
    /// Tells the origin of command `id` whether it was delivered, once
    /// (ARCHITECTURE "Delivery contract"): a client gets the ACK it was
    /// waiting for, or a delivery report instead; a link to another GCU
    /// (whose frame was ACKed hop by hop) gets a report either way.
    /// `at_group`: the GCU where delivery failed.
    pub(super) fn resolve(
        &mut self,
        now: u64,
        id: CommandId,
        delivery: Result<(), Undelivered>,
        at_group: u8,
        out: &mut Outbox,
    ) {
        let Some(c) = self.in_flight.get_mut(&id) else { return };
        // A group-255 command fails only where no part may still deliver it.
        let untold = c.delivery.is_some();
        let (delivery, at_group) = match (delivery, c.spread.as_mut()) {
            (Err(failure), Some(spread)) if untold => match spread.failed(failure, at_group) {
                Some((failure, group)) => (Err(failure), group),
                None => return,
            },
            (delivery, _) => (delivery, at_group),
        };
        // Only a link's command awaits its delivery outcome.
        let (Some(awaited), Origin::Link { link, .. }) = (c.delivery.take(), c.origin) else {
            return;
        };
        let (frame, command) = (c.command.frame.clone(), c.command.facts.reply.mnemonic());
        if delivery.is_err() {
            // Told its outcome: an answer that comes now is nobody's (module
            // `in_flight`: `disowned`), here or from the next GCU.
            c.disowned = true;
            self.reverse.disown(id);
        }
        if c.done() {
            self.in_flight.remove(&id);
        }
        let f = frame.frame();
        match delivery {
            Ok(()) => {
                self.stats.delivered += 1;
                out.push(Action::Event(RouterEvent::Delivered { id }));
            }
            Err(failure) => {
                self.stats.undelivered.add(failure);
                out.push(Action::Event(RouterEvent::Undelivered {
                    id,
                    origin: Origin::Link { link, source: f.source },
                    dest: f.dest,
                    command,
                    failure,
                }));
            }
        }
        if matches!(awaited, Delivery::Client { .. }) && delivery.is_ok() {
            return self.ack(now, link, out);
        }
        self.report(now, link, &f, delivery.err(), at_group, out);
    }

    /// A client's delivery time-out passed: jobs still queued are given up
    /// unsent (expired); one on the bus, or a forward, may still be
    /// delivered, which the client is told (not confirmed). A late ACK
    /// is never written: the client may be waiting for its next command's.
    pub(super) fn deliver_overdue(&mut self, now: u64, id: CommandId, out: &mut Outbox) {
        let mut cancelled = false;
        // Each port found afresh after the last, with no list (no allocation).
        let mut after = None;
        while let Some(port) = self.ports.range(super::after_key(after)).next().map(|(&id, _)| id) {
            after = Some(port);
            let mut po = self.port_scratch.pop().unwrap_or_default();
            if let Some(mut p) = self.ports.get_mut(&port) {
                cancelled |= p.cancel_queued(id, DropReason::Expired, &mut po);
            }
            self.port_outs(now, port, po, out);
        }
        let still_running = self.jobs_of(id).is_some() || !cancelled;
        let failure = match still_running {
            true => Undelivered::NotConfirmed,
            false => Undelivered::Expired,
        };
        // The time-out is the client's: whatever part is still unsettled.
        if let Some(c) = self.in_flight.get_mut(&id) {
            c.spread = None;
        }
        self.resolve(now, id, Err(failure), self.group, out);
    }

    /// Queues a delivery report about `command` on `link`.
    pub(super) fn report(
        &mut self,
        now: u64,
        link: LinkId,
        command: &Frame<'_>,
        failure: Option<Undelivered>,
        at_group: u8,
        out: &mut Outbox,
    ) {
        let report = DeliveryReport {
            failure,
            dest: command.dest,
            command_checksum: command.checksum(),
            at_group,
        };
        let to = Address::new(command.source, LINK_PORT, CONTROL_UNIT);
        if let Ok(frame) = FrameBuf::new(to, self.group, &report.encode()) {
            if let Err(reason) = self.send_on_link(now, link, frame, out) {
                self.drop_frame(reason, Place::Link(link), to, self.group, out);
            }
        }
    }

    /// Whether the report about `command` is still unacknowledged on the
    /// client `link`: the client has no outcome yet, so an identical frame is
    /// its retransmission (ARCHITECTURE "Delivery contract": a repeat gets
    /// the original's outcome), not a new command. Its ACK followed by the
    /// report's next copy would be two outcomes to the client.
    pub(super) fn report_on_its_way(&self, link: LinkId, command: &Frame<'_>) -> bool {
        let Some(l) = self.links.get(&link) else { return false };
        l.unacknowledged().any(|queued| {
            let f = queued.frame();
            f.dest == Address::new(command.source, LINK_PORT, CONTROL_UNIT)
                && DeliveryReport::parse(f.payload())
                    .is_ok_and(|r| r.dest == command.dest && r.command_checksum == command.checksum())
        })
    }
}
