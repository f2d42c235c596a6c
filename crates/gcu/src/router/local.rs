//! Commands for this GCU's group (ARCHITECTURE "Routing semantics"): port
//! 0 is the GCU itself (module `self_answer`), 1..=254 one port's job, 255
//! a job on every port; their results relayed with the Table 3 header and
//! the jobs' outcomes folded into the command's one outcome.

use sagebrush_protocol::{Address, FrameBuf, LINK_PORT, Undelivered, WILDCARD};

use crate::command::ReadCommand;
use crate::outbox::Outbox;
use crate::port::Job;
use crate::types::{CommandId, CommandOutcome, DropReason, Origin, Place};

use super::Router;
use super::after_key;
use super::dispatch::Accepted;
use super::in_flight::{PortSet, Progress};
use super::self_answer::answer;

impl Router {
    /// Destination group G or 255: port 0 is the GCU itself, 1..=254 one
    /// port, 255 every port.
    pub(super) fn execute_local(&mut self, now: u64, accepted: Accepted, out: &mut Outbox) {
        let Accepted {
            id,
            origin,
            command: ReadCommand { frame, facts },
        } = accepted;
        let f = frame.frame();
        let dest = f.dest;
        // One port, or every port (a broadcast to port 255): counted first,
        // then each found afresh, with no list of targets.
        let one = match dest.port {
            LINK_PORT if sagebrush_protocol::GcuCommand::is_gcu(f.payload()) => {
                let outcome = self.gcu_command(now, id, origin, &f, out);
                return self.finish(id, outcome, out);
            }
            LINK_PORT => {
                self.resolve(now, id, Ok(()), self.group, out);
                let outcome = match answer(self.group, &self.name, &self.serial, &f, facts.row) {
                    Some(reply) => match origin {
                        Origin::Link { link, .. } => match self.send_on_link(now, link, reply, out) {
                            Ok(()) => CommandOutcome::Result,
                            Err(_) => CommandOutcome::Dropped(DropReason::OriginGone),
                        },
                        Origin::Internal => CommandOutcome::Completed,
                    },
                    None => match self.nic_to(now, origin, out) {
                        Ok(()) => CommandOutcome::Nic,
                        Err(reason) => CommandOutcome::Dropped(reason),
                    },
                };
                return self.finish(id, outcome, out);
            }
            WILDCARD => None,
            port => Some(port),
        };
        // A stop the governance sends short of a boundary waits behind no other.
        let urgent = self
            .in_flight
            .get(&id)
            .and_then(|c| c.issued_stop)
            .is_some_and(|s| s.cause == crate::types::StopCause::Boundary);
        let targets = match one {
            Some(port) => usize::from(self.ports.contains_key(&port)),
            None => self.ports.len(),
        };
        if targets == 0 {
            // Group 255 flooded to other GCUs: the port is another GCU's,
            // not missing (its copies may deliver it); else dropped.
            let flooded_via = self.in_flight.get(&id).and_then(|c| c.spread).map(|s| s.via);
            if flooded_via.is_none() {
                self.drop_frame(DropReason::UnknownPort, Place::Router, dest, f.source, out);
            }
            self.resolve(now, id, Err(Undelivered::NoSuchPort), self.group, out);
            let outcome = flooded_via.map_or(
                CommandOutcome::Dropped(DropReason::UnknownPort),
                CommandOutcome::Forwarded,
            );
            return self.finish(id, outcome, out);
        }
        // Every target is undecided before the first is queued: a job may
        // be delivered (device 255: written) as it is queued.
        let mut ports = PortSet::default();
        match one {
            Some(port) => ports.insert(port),
            None => self.ports.keys().for_each(|&port| ports.insert(port)),
        }
        if let Some(c) = self.in_flight.get_mut(&id) {
            c.jobs = Some(Progress::new(targets, ports));
        }
        let mut after = None;
        while let Some(port) = match one {
            Some(port) => (after.is_none()).then_some(port),
            None => self.ports.range(after_key(after)).next().map(|(&id, _)| id),
        } {
            let mut job = Job::new(id, origin, frame.clone(), facts);
            job.urgent = urgent;
            self.with_port(now, port, out, |p, now, po| p.enqueue(now, job, po));
            after = Some(port);
        }
    }

    /// A result of job `id` from `port`: back to the origin with the Table 3
    /// header (destination group = the command's source group, port and
    /// device as answered, source group = G, checksum recomputed).
    pub(super) fn relay_result(
        &mut self,
        now: u64,
        port: u8,
        id: CommandId,
        origin: Origin,
        mut reply: FrameBuf,
        out: &mut Outbox,
    ) {
        let Origin::Link { link, source } = origin else {
            // The router's own command: the answer is taken, not relayed.
            if let Some(p) = self.jobs_of(id) {
                p.results += 1;
            }
            return;
        };
        // A result means the device had the command: the ACK goes first.
        self.resolve(now, id, Ok(()), self.group, out);
        let answered = reply.frame().dest;
        let answered_port = if answered.port == WILDCARD { port } else { answered.port };
        reply.set_header(Address::new(source, answered_port, answered.device), self.group);
        let dest = reply.frame().dest;
        // Its origin was told it was not delivered, or its link went down
        // (module `in_flight`: `disowned`): the result names no command but
        // by its header (1.4.3), which the origin's next command to the
        // device shares, and would be taken for that one's.
        let disowned = self.in_flight.get(&id).is_some_and(|c| c.disowned);
        let sent = match self.links.contains_key(&link) {
            false => Err(DropReason::OriginGone),
            true if disowned => Err(DropReason::Unsolicited),
            true => self.send_on_link(now, link, reply, out),
        };
        let progress = self.in_flight.get_mut(&id).and_then(|c| c.jobs.as_mut());
        match sent {
            Ok(()) => {
                self.stats.results_relayed += 1;
                if let Some(p) = progress {
                    p.results += 1;
                }
            }
            Err(reason) => {
                if let Some(p) = progress {
                    p.dropped = Some(reason);
                }
                self.drop_frame(reason, Place::Link(link), dest, self.group, out);
            }
        }
    }

    /// The device on `port` acknowledged job `id` (or a device-255 command
    /// was written there). The origin is told delivered once every job of
    /// the command was acknowledged or ended (ARCHITECTURE "Delivery
    /// contract"): a port-255 fan-out's one `?`, relayed when its last job
    /// ended, then follows its ACK within the port's window (1.4.2), never
    /// after a later command's ACK.
    pub(super) fn job_delivered(&mut self, now: u64, port: u8, id: CommandId, out: &mut Outbox) {
        let delivered = match self.jobs_of(id) {
            Some(p) => p.decide(port, true),
            None => true,
        };
        if delivered {
            self.resolve(now, id, Ok(()), self.group, out);
        }
    }

    /// Job `id` on `port` ended with `outcome`; the command's one outcome
    /// once its last job ended.
    pub(super) fn job_finished(
        &mut self,
        now: u64,
        port: u8,
        id: CommandId,
        outcome: CommandOutcome,
        out: &mut Outbox,
    ) {
        let Some(p) = self.jobs_of(id) else { return };
        // Ended unacknowledged, or acknowledged already (then a no-op).
        if p.decide(port, false) {
            self.resolve(now, id, Ok(()), self.group, out);
        }
        let Some(p) = self.jobs_of(id) else { return };
        match outcome {
            CommandOutcome::Result | CommandOutcome::Forwarded(_) => {}
            CommandOutcome::Nic => p.nics += 1,
            CommandOutcome::Completed => p.completed += 1,
            CommandOutcome::NoResult => p.no_result += 1,
            CommandOutcome::Unreachable => p.unreachable += 1,
            CommandOutcome::Dropped(reason) => p.dropped = Some(reason),
        }
        p.remaining = p.remaining.saturating_sub(1);
        if p.remaining > 0 {
            return;
        }
        let Some(c) = self.in_flight.get_mut(&id) else { return };
        let Some(p) = c.jobs.take() else { return };
        let (origin, disowned) = (c.origin, c.disowned);
        let (dest, source) = (c.command.frame.frame().dest, c.command.frame.frame().source);
        let mut outcome = p.outcome();
        self.resolve(now, id, p.delivery(outcome), self.group, out);
        self.window_passed(now, id, outcome, out);
        if outcome == CommandOutcome::Nic && disowned {
            // Its origin was told it was not delivered (module `in_flight`):
            // the `?` names no command, and would be taken for the next.
            self.drop_frame(DropReason::Unsolicited, Place::Port(port), dest, source, out);
        } else if outcome == CommandOutcome::Nic {
            if let Err(reason) = self.nic_to(now, origin, out) {
                outcome = CommandOutcome::Dropped(reason);
            }
        }
        // A safety stop that no device acknowledged is sent again (module `lifecycle`).
        let again = self.in_flight.get_mut(&id).and_then(|c| c.stop_again(outcome));
        self.finish(id, outcome, out);
        if let Some(round) = again {
            self.send_stop_round(now, round, out);
        }
    }
}
