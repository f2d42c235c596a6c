//! A transaction on the bus (ARCHITECTURE "Routing semantics": "On a port,
//! one transaction at a time", "Late answers"; "Delivery contract"; spec
//! Table 3): started, stepped by what the bus sends and by time, finished.
//!
//! - One [`Transaction`] of the protocol crate at a time on each bus: write,
//!   await ACK (NAK/time-out -> retransmit), then the result or NIC when the
//!   command has one (normal or long class, `IX` is long), else a short NIC
//!   window. Device address 255 is written once, no ACK awaited, then a
//!   quiet guard time.
//! - A long result wait (`IX` acknowledged, result pending) is set aside
//!   when a stop is queued: the stop goes out at once and the set-aside
//!   exchange still takes its result (matched by its Table 3 header) or
//!   times out. Until it ends, only stops use the bus (another exchange
//!   could be answered with the same header). The bus is never written
//!   while an ACK is awaited.
//! - Hop by hop on the bus: every good frame a device sends is ACKed, a bad
//!   checksum is NAKed so that the device retransmits.
//! - A result is taken only when its header is that of the exchange (Table
//!   3: port and device unchanged, destination group = the command's source
//!   group), during a device-255 guard time too. During a device-255 guard
//!   time, result frames (from a device alone on its bus that answers
//!   broadcasts) are acknowledged and relayed.
//! - After an exchange that needed a retransmission, the device may have
//!   executed the command twice, or answered after the GCU gave up: the bus
//!   stays quiet for one ACK time-out so that such an answer is not taken
//!   for the next exchange's (it is ACKed and counted as unsolicited); so it
//!   does after any give-up, a NAK one included, so that a dead-man stop's
//!   next round is queued before other work starts. After an ACK wait of a
//!   device that answered its last exchange ran out (the exchange gave up,
//!   or a later try was answered), the bus stays quiet for
//!   `PortConfig::late_answer_guard`, at least one ACK time-out like any
//!   give-up (an address that never answered, or a device already offline,
//!   gets no guard: a scan of empty addresses stays fast and a dead device
//!   does not hold up its bus).
//! - A `?` before the ACK of the exchange on the bus ends nothing (1.4.2:
//!   the NIC follows the ACK): a device answers in order, so it is an
//!   earlier command's NIC that came after that command's window (from
//!   this device or another on the bus), or this command's after its ACK
//!   was lost, and then the ACK wait runs out and the frame goes again (its
//!   answer comes again). Taken for this exchange's, a stop would end
//!   "delivered" on another device's word (the simulation's late NICs).
//! - Behind a device server (`PortConfig::buffered`) nothing is
//!   retransmitted and a missing ACK is `0B not confirmed`: the bytes may
//!   wait in the server while it stalls and run when it resumes. Their
//!   answers then come whenever it resumes, and an ACK names no command, so
//!   after such a give-up ([`Backlog`]) the first answer heard is nobody's:
//!   the exchange on the bus at that moment is `0B not confirmed` as well,
//!   and no exchange starts until the bus has been quiet for the late-answer
//!   guard (at least one ACK time-out) since the last byte heard. What
//!   arrives meanwhile is ACKed and counted as unsolicited, never relayed.

use sagebrush_protocol::{Event, FrameBuf, Outcome, OwnedEvent, ResultKind, ResultTimeout, Transaction};
use sagebrush_protocol::{TransactionStep, TxFailure, Undelivered, WILDCARD};

use crate::line::LineReceiver;
use crate::outbox::Wire;
use crate::types::{CommandOutcome, DropReason, Origin, RouterEvent};

use super::{Job, Port, PortOut};

#[derive(Debug)]
pub(super) struct Running {
    pub(super) job: Job,
    pub(super) txn: Transaction,
    /// An ACK wait ran out: the device may still answer that try, late.
    pub(super) ack_timed_out: bool,
}

impl Running {
    pub(super) fn device(&self) -> u8 {
        self.job.frame.frame().dest.device
    }

    /// Whether `frame` can be this exchange's result: port and device
    /// unchanged (the protocol `Transaction` checks those) and, Table 3, the
    /// destination group is the command's source group. The protocol
    /// crate's check alone takes a late duplicate result meant for another
    /// source group's command to the same device.
    pub(super) fn answered_by(&self, frame: &sagebrush_protocol::Frame<'_>) -> bool {
        frame.dest.group == self.job.frame.frame().source && self.txn.is_result_header(&frame.dest)
    }
}

/// Behind a device server: whether bytes of a given-up exchange may still
/// be waiting in it (module doc; ARCHITECTURE "Delivery contract").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Backlog {
    /// Every exchange was answered (or its address is known to be empty).
    Clear,
    /// An exchange went unanswered: its bytes may still run, and any answer
    /// heard may be theirs.
    Unsure,
    /// The bus answered since: nothing starts until it has been quiet for
    /// the guard since `last_heard`.
    Draining { last_heard: u64 },
}

impl Port {
    pub(super) fn start_next(&mut self, now: u64, out: &mut Vec<PortOut>) {
        // The quiet after an unanswered or repeated exchange keeps other
        // work off the bus, but not a stop: a boundary stop held 500 ms
        // behind a lost frame let the gimbal run on past its limit (the
        // governance simulation); a stop executed twice, or acknowledged by
        // a late ACK, stops all the same.
        let stop_next = self.queue.front().is_some_and(|j| j.facts.stop);
        let settling = self.settle_until.is_some_and(|t| now < t);
        if settling && !stop_next {
            return;
        }
        if !settling {
            self.settle_until = None;
        }
        if let Some(until) = self.drained_at() {
            if now < until {
                return;
            }
            self.backlog = Backlog::Clear;
        }
        self.pipeline(now);
        while self.active.is_none() && self.open {
            // Beside an exchange in its window only the next command to
            // its device goes (module `pipeline`).
            if let Some(w) = &self.windowing {
                if !self.next_is_for(w.running.device()) {
                    break;
                }
            }
            // While a long wait is set aside only stops use the bus: another
            // exchange could take its result (same Table 3 header) or give it theirs.
            if !self.detached.is_empty() && !self.queue.front().is_some_and(|j| j.facts.stop) {
                break;
            }
            if self.held_for_reserved_stop(now) {
                break;
            }
            if self.settle_until.is_some_and(|t| now < t) && !self.queue.front().is_some_and(|j| j.facts.stop) {
                break;
            }
            let Some(job) = self.next_job() else { break };
            self.note_queue();
            let dest = job.frame.frame().dest;
            // The ACK clock starts now, at the write: the frame's own wire
            // time is added to the wait.
            let policy = self.policy.for_frame(job.frame.as_bytes().len(), self.stats.bps);
            let mut txn = Transaction::expecting(dest, job.facts.reply.result_kind(), policy);
            out.push(PortOut::Event(RouterEvent::Started {
                id: job.id,
                port: self.id,
                stop: job.facts.stop,
            }));
            self.stats.transactions += 1;
            if let Some(d) = self.device(dest.device) {
                d.commands += 1;
            }
            let step = txn.start(now);
            self.active = Some(Running {
                job,
                txn,
                ack_timed_out: false,
            });
            self.active_step(now, step, None, out);
        }
    }

    /// A long result wait gives the bus to a queued stop.
    pub(super) fn maybe_detach(&mut self, now: u64, out: &mut Vec<PortOut>) {
        let stop_waiting = self.queue.front().is_some_and(|j| j.facts.stop);
        let long_wait = self.active.as_ref().is_some_and(|r| {
            r.job.facts.reply.result_kind() == ResultKind::Required(ResultTimeout::Long)
                && !r.txn.is_broadcast()
                && r.txn.acknowledged()
                && r.txn.outcome().is_none()
        });
        if stop_waiting && long_wait {
            if let Some(r) = self.active.take() {
                self.detached.push(r);
            }
            self.start_next(now, out);
        }
    }

    fn active_step(&mut self, now: u64, step: TransactionStep, frame: Option<FrameBuf>, out: &mut Vec<PortOut>) {
        match step {
            TransactionStep::Send => {
                let Some(r) = &self.active else { return };
                let frame = Wire::Frame(r.job.frame.clone());
                let retransmit = r.txn.transmissions() > 1;
                let device = r.device();
                self.stats.line.frames_out += 1;
                if let Some(d) = self.device(device) {
                    d.frames_out += 1;
                    d.retransmits += u64::from(retransmit);
                }
                if retransmit {
                    self.stats.line.retransmits += 1;
                }
                self.write(frame, out);
                if let Some(r) = self.active.as_ref().filter(|r| r.txn.is_broadcast()) {
                    // Device 255: no ACK on a shared bus; written is all there is.
                    Self::delivered(&r.job, out);
                }
            }
            TransactionStep::Wait => {}
            TransactionStep::Done(outcome) => {
                // The device answered this exchange (or never did): the one
                // in its window before it ends first (module `pipeline`).
                self.close_window(now, outcome != Outcome::Failed(TxFailure::NoAck), out);
                if let Some(r) = self.active.take() {
                    self.finish(now, r, outcome, frame, out);
                }
                self.start_next(now, out);
            }
        }
    }

    /// The quiet the bus keeps after `r` ended with `outcome`, before the
    /// next exchange starts (module doc: late answers, give-ups).
    fn settle_after(&mut self, now: u64, r: &Running, outcome: Outcome, was_online: bool) {
        let quiet = if r.ack_timed_out && was_online {
            // A device that answered its last exchange let an ACK wait run
            // out (given up, or answered a later try): its answer to that
            // try may still come, late, and would be taken for the next
            // command's ACK. (Once offline, a dead device does not hold the
            // bus up again.)
            self.late_answer_quiet
        } else if r.txn.transmissions() > 1 || r.ack_timed_out || matches!(outcome, Outcome::Failed(_)) {
            // The device may have executed the command twice, or answer
            // after we gave up (with no retransmission too: retries = 0, a
            // device server): let that answer arrive while nothing can take
            // it for its own. And after any give-up, NAK included (no
            // retransmission into a device server), a dead-man stop's next
            // round is queued before other work starts (seeds 2089, 33315).
            self.policy.retry.ack_timeout
        } else {
            0
        };
        if quiet > 0 {
            let settle = now.saturating_add(quiet);
            self.settle_until = Some(self.settle_until.map_or(settle, |t| t.max(settle)));
        }
    }

    pub(super) fn finish(
        &mut self,
        now: u64,
        r: Running,
        outcome: Outcome,
        frame: Option<FrameBuf>,
        out: &mut Vec<PortOut>,
    ) {
        let device = r.device();
        let was_online = self.device_stats.get(&device).is_some_and(|d| d.online);
        self.settle_after(now, &r, outcome, was_online);
        let surely_absent = self.devices.as_ref().is_some_and(|list| !list.contains(&device));
        if self.config.buffered
            && matches!(outcome, Outcome::Failed(TxFailure::NoAck))
            && !surely_absent
            && self.backlog == Backlog::Clear
        {
            // Its bytes may wait in the device server and be answered
            // whenever it resumes.
            self.backlog = Backlog::Unsure;
        }
        let answered = !matches!(outcome, Outcome::Failed(_) | Outcome::Broadcast);
        let before = (was_online, self.seen.contains(&device));
        if answered && device != WILDCARD {
            self.seen.insert(device);
            if let Some(d) = self.device(device) {
                d.last_seen = Some(now);
            }
        }
        self.learn(now, device, &r.job, outcome, frame.as_ref());
        self.tell_device_state(device, before, out);
        let outcome = match outcome {
            Outcome::Result => {
                if let Some(reply) = frame {
                    if let Some(d) = self.device(device) {
                        d.frames_in += 1;
                    }
                    out.push(PortOut::Relay {
                        id: r.job.id,
                        origin: r.job.origin,
                        reply,
                    });
                }
                CommandOutcome::Result
            }
            Outcome::Nic => {
                // gcud's own queries (a preset it asks for a park or a
                // tour) may meet a device that lacks the row: no error of
                // the device's (module `registry`).
                if let Some(d) = self.device(device).filter(|_| r.job.origin != Origin::Internal) {
                    d.nics += 1;
                }
                CommandOutcome::Nic
            }
            Outcome::Acknowledged => {
                self.rate_acknowledged(device, r.job.facts.rate, out);
                CommandOutcome::Completed
            }
            Outcome::Broadcast => {
                if let Some(rate) = r.job.facts.rate {
                    self.switch_rate(rate, out);
                }
                CommandOutcome::Completed
            }
            Outcome::NoResult => {
                self.stats.line.timeouts += 1;
                if let Some(d) = self.device(device) {
                    d.no_result += 1;
                }
                CommandOutcome::NoResult
            }
            Outcome::Failed(failure) => {
                let failure = match failure {
                    // Behind a device server the bytes may still be on
                    // their way to the device.
                    TxFailure::NoAck if self.config.buffered => {
                        self.stats.line.timeouts += 1;
                        Undelivered::NotConfirmed
                    }
                    TxFailure::NoAck => {
                        self.stats.line.timeouts += 1;
                        Undelivered::DeviceSilent
                    }
                    TxFailure::Nak => Undelivered::DeviceNak,
                };
                if let Some(d) = self.device(device) {
                    d.unreachable += 1;
                }
                out.extend(r.job.ids().map(|id| PortOut::Undelivered { id, failure }));
                CommandOutcome::Unreachable
            }
        };
        // An address that never answered anything (a scan's probe of an
        // empty address) leaves no entry behind: the registry holds the
        // devices that exist.
        if self
            .device_stats
            .get(&device)
            .is_some_and(|d| !d.online && d.last_seen.is_none())
        {
            self.device_stats.remove(&device);
        }
        out.extend(r.job.ids().map(|id| PortOut::Finished { id, outcome }));
    }

    /// Bytes from the bus.
    pub fn receive(&mut self, now: u64, bytes: &[u8], out: &mut Vec<PortOut>) {
        if !self.open {
            // Bytes of a port the router believes closed: noise.
            self.stats.line.stray_bytes += bytes.len() as u64;
            return;
        }
        LineReceiver::heard(now, bytes, &mut self.stats.line);
        let mut rest = bytes;
        while let Some(event) = self.line.next_event(now, &mut rest, &mut self.stats.line) {
            self.on_event(now, event, out);
        }
        self.maybe_detach(now, out);
    }

    fn on_event(&mut self, now: u64, event: OwnedEvent, out: &mut Vec<PortOut>) {
        if self.backlog != Backlog::Clear {
            self.heard_with_backlog(now, out);
        }
        match event {
            OwnedEvent::Frame(frame) => {
                self.write(Wire::Ack, out);
                self.on_frame(now, frame, out);
            }
            OwnedEvent::BadChecksum(_) => self.write(Wire::Nak, out),
            OwnedEvent::Ack | OwnedEvent::Nak => {
                let (fe, nak) = match event {
                    OwnedEvent::Nak => (Event::Nak, true),
                    _ => (Event::Ack, false),
                };
                if nak {
                    self.stats.line.naks_received += 1;
                }
                let awaiting = |r: &Running| !r.txn.is_broadcast() && !r.txn.acknowledged();
                if self.active.as_ref().is_some_and(awaiting) {
                    // The device answered the exchange on the bus: nothing
                    // more can come about the one in its window.
                    self.close_window(now, true, out);
                }
                match self
                    .active
                    .as_mut()
                    .filter(|r| !r.txn.is_broadcast() && !r.txn.acknowledged())
                {
                    Some(r) => {
                        let device = r.device();
                        let step = r.txn.on_event(&fe, now);
                        if r.txn.acknowledged() {
                            Self::delivered(&r.job, out);
                        }
                        if let Some(d) = self.device(device) {
                            d.last_seen = Some(now);
                        }
                        self.active_step(now, step, None, out);
                        // In its NIC window now: the next command to its
                        // device may go (module `pipeline`).
                        self.start_next(now, out);
                    }
                    None => self.stats.line.stray_bytes += 1,
                }
            }
            OwnedEvent::Nic => {
                self.stats.line.nics_in += 1;
                if let Some(r) = self.active.as_mut().filter(|r| !r.txn.is_broadcast()) {
                    if !r.txn.acknowledged() {
                        // A NIC follows its command's ACK (1.4.2): one before
                        // this exchange's ACK ends nothing (module doc), but
                        // may be the NIC of the exchange in its window.
                        if !self.hold_nic() {
                            self.stats.line.stray_bytes += 1;
                        }
                        return;
                    }
                    let step = r.txn.on_event(&Event::Nic, now);
                    if step != TransactionStep::Wait {
                        return self.active_step(now, step, None, out);
                    }
                }
                if !self.detached.is_empty() {
                    let mut r = self.detached.remove(0);
                    if let TransactionStep::Done(outcome) = r.txn.on_event(&Event::Nic, now) {
                        self.finish(now, r, outcome, None, out);
                        return self.start_next(now, out);
                    }
                    self.detached.insert(0, r);
                }
                self.stats.line.stray_bytes += 1;
            }
        }
    }

    fn on_frame(&mut self, now: u64, frame: FrameBuf, out: &mut Vec<PortOut>) {
        let view = frame.frame();
        if let Some(r) = self.active.as_mut() {
            if r.txn.is_broadcast() {
                let command = r.job.frame.frame();
                let port_matches = view.dest.port == command.dest.port || view.dest.port == WILDCARD;
                if port_matches && view.dest.group == command.source && self.backlog == Backlog::Clear {
                    // A device alone on its bus answering a broadcast.
                    let (id, origin) = (r.job.id, r.job.origin);
                    if let Some(d) = self.device(view.dest.device) {
                        d.frames_in += 1;
                        d.last_seen = Some(now);
                    }
                    out.push(PortOut::Relay {
                        id,
                        origin,
                        reply: frame,
                    });
                    return;
                }
            } else if r.answered_by(&view) {
                let step = r.txn.on_event(&Event::Frame(view), now);
                if let TransactionStep::Done(_) = step {
                    return self.active_step(now, step, Some(frame), out);
                }
            }
        }
        if let Some(at) = self.detached.iter().position(|r| r.answered_by(&view)) {
            let mut r = self.detached.remove(at);
            if let TransactionStep::Done(outcome) = r.txn.on_event(&Event::Frame(view), now) {
                self.finish(now, r, outcome, Some(frame), out);
                return self.start_next(now, out);
            }
            self.detached.insert(at, r);
        }
        self.stats.line.drops.add(DropReason::Unsolicited);
        out.push(PortOut::Event(RouterEvent::Dropped {
            reason: DropReason::Unsolicited,
            at: crate::Place::Port(self.id),
            dest: view.dest,
            source: view.source,
        }));
    }

    /// A frame began and the line fell silent before its end (a device
    /// stalled mid-frame, a USB adapter's latency): while the exchange on
    /// the bus awaits its result, that was the result, damaged, and is
    /// NAKed as a bad checksum is (1.4.2), so that the device sends it
    /// again instead of the exchange running out with the device's answer
    /// lost. At any other time the bytes were noise and go unanswered.
    fn on_cut_short(&mut self, out: &mut Vec<PortOut>) {
        if self.active.as_ref().is_some_and(|r| r.txn.awaiting_result()) {
            self.stats.line.naks_sent += 1;
            self.write(Wire::Nak, out);
        }
    }

    /// When the bus will have been quiet long enough after answers heard
    /// with a backlog, if it is draining one.
    pub(super) fn drained_at(&self) -> Option<u64> {
        match self.backlog {
            Backlog::Draining { last_heard } => Some(last_heard.saturating_add(self.late_answer_quiet)),
            Backlog::Clear | Backlog::Unsure => None,
        }
    }

    /// The bus answered while given-up bytes may have been waiting in the
    /// device server: the answer may be theirs, so the exchange on the bus
    /// is not confirmed either, and the bus drains before the next one.
    fn heard_with_backlog(&mut self, now: u64, out: &mut Vec<PortOut>) {
        self.backlog = Backlog::Draining { last_heard: now };
        self.close_window(now, false, out);
        let Some(r) = self.active.take_if(|r| !r.txn.is_broadcast()) else {
            return;
        };
        self.stats.line.timeouts += 1;
        if let Some(d) = self.device(r.device()) {
            d.unreachable += 1;
        }
        let failure = Undelivered::NotConfirmed;
        out.extend(r.job.ids().map(|id| PortOut::Undelivered { id, failure }));
        let outcome = CommandOutcome::Unreachable;
        out.extend(r.job.ids().map(|id| PortOut::Finished { id, outcome }));
    }

    /// Time passed.
    pub fn poll(&mut self, now: u64, out: &mut Vec<PortOut>) {
        let abandoned = self.line.abandoned();
        self.line.poll(now);
        while let Some(event) = self.line.next_event(now, &mut &[][..], &mut self.stats.line) {
            self.on_event(now, event, out);
        }
        if self.line.abandoned() > abandoned {
            self.on_cut_short(out);
        }
        self.poll_window(now, out);
        if self
            .active
            .as_ref()
            .is_some_and(|r| !r.txn.acknowledged() && r.txn.deadline().is_some_and(|t| now >= t))
        {
            // The exchange on the bus went unanswered: whose a `?` held
            // was cannot be known (module `pipeline`).
            self.close_window(now, false, out);
        }
        if let Some(r) = self
            .active
            .as_mut()
            .filter(|r| r.txn.deadline().is_some_and(|t| now >= t))
        {
            r.ack_timed_out |= !r.txn.acknowledged();
            let step = r.txn.poll(now);
            self.active_step(now, step, None, out);
        }
        let mut i = 0;
        while i < self.detached.len() {
            if self.detached[i].txn.deadline().is_some_and(|t| now >= t) {
                let mut r = self.detached.remove(i);
                match r.txn.poll(now) {
                    TransactionStep::Done(outcome) => self.finish(now, r, outcome, None, out),
                    _ => {
                        self.detached.insert(i, r);
                        i += 1;
                    }
                }
            } else {
                i += 1;
            }
        }
        if self.active.is_none() {
            self.start_next(now, out);
        }
        self.maybe_detach(now, out);
    }
}
