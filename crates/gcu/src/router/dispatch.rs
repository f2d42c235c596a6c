//! A command accepted (from a link, or the GCU's own stop): its id, its
//! in-flight record, where it goes (the GCU's ports, another GCU, or
//! nowhere: dropped and reported), and its one end.

use sagebrush_protocol::{Undelivered, WILDCARD};

use crate::boundary::Action;
use crate::command::ReadCommand;
use crate::config::LinkKind;
use crate::outbox::Outbox;
use crate::types::{CommandId, CommandOutcome, DropReason, Origin, Place, RouterEvent};

use super::Router;
use super::govern::Governed;
use super::in_flight::{Delivery, InFlight, IssuedStop, Progress, Spread};

/// A command the router accepted: its id, where it came from and what it
/// says, as it goes to the GCU's ports or to another GCU.
pub(super) struct Accepted {
    pub id: CommandId,
    pub origin: Origin,
    pub command: ReadCommand,
}

impl Router {
    /// A command accepted from `origin` (a link of `kind`, or the router
    /// itself), read once: gives it the next command id and its in-flight
    /// record, and returns the id. A stop the GCU issued itself carries
    /// its round, and a command of the governance's own its note, in the
    /// record before routing, since the command may end inside this call.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn dispatch(
        &mut self,
        now: u64,
        origin: Origin,
        kind: Option<LinkKind>,
        command: ReadCommand,
        issued_stop: Option<IssuedStop>,
        note: crate::govern::CommandNote,
        out: &mut Outbox,
    ) -> CommandId {
        let id = self.next_command_id();
        self.in_flight.insert(
            id,
            InFlight {
                origin,
                who: origin.link().and_then(|link| self.identity(link)),
                command: command.clone(),
                delivery: origin.link().map(|_| match kind {
                    Some(LinkKind::Client) => Delivery::Client {
                        deadline: now.saturating_add(self.settings.delivery_timeout),
                    },
                    _ => Delivery::Gcu,
                }),
                jobs: None,
                disowned: false,
                spread: None,
                issued_stop,
                finished: false,
                note,
            },
        );
        self.route_command(now, Accepted { id, origin, command }, kind, out);
        id
    }

    /// Routes command `id`: locally, to a link, or dropped and reported;
    /// a command the governance cannot decide yet waits (module `waiting`).
    fn route_command(&mut self, now: u64, accepted: Accepted, kind: Option<LinkKind>, out: &mut Outbox) {
        let (id, origin, command) = (accepted.id, accepted.origin, &accepted.command);
        let f = command.frame.frame();
        let (dest, source) = (f.dest, f.source);
        self.stats.accepted += 1;
        out.push(Action::Event(RouterEvent::Accepted {
            id,
            origin,
            dest,
            command: command.facts.reply.mnemonic(),
        }));
        if let Origin::Link { link, .. } = origin {
            if self.stopping {
                self.drop_frame(DropReason::ShuttingDown, Place::Router, dest, source, out);
                self.finish(id, CommandOutcome::Dropped(DropReason::ShuttingDown), out);
                return self.resolve(now, id, Err(Undelivered::ShuttingDown), self.group, out);
            }
            let local = dest.group == self.group || dest.group == WILDCARD;
            if local && dest.port != sagebrush_protocol::LINK_PORT {
                match self.govern_command(now, id, link, command, out) {
                    Governed::Pass => {}
                    Governed::Refused(reason) => return self.refuse(now, id, reason, out),
                    Governed::Waits(why) => return self.wait_for_knowledge(now, id, kind, why),
                }
            }
        }
        self.route_decided(now, accepted, kind, out);
    }

    /// Command `id` refused by the governance: dropped and reported, nothing sent.
    pub(super) fn refuse(&mut self, now: u64, id: CommandId, reason: DropReason, out: &mut Outbox) {
        let Some(c) = self.in_flight.get(&id) else { return };
        let f = c.command.frame.frame();
        let (dest, source) = (f.dest, f.source);
        self.audit(id, Some(reason), out);
        self.drop_frame(reason, Place::Router, dest, source, out);
        self.finish(id, CommandOutcome::Dropped(reason), out);
        self.resolve(now, id, Err(reason.undelivered()), self.group, out);
    }

    /// The audit line of command `id` from a link, when it moves or
    /// changes a gimbal (not a query): who sent it, and whether the
    /// governance let it through or refused it (`refused`).
    pub(super) fn audit(&self, id: CommandId, refused: Option<DropReason>, out: &mut Outbox) {
        let Some(c) = self.in_flight.get(&id) else { return };
        let Some(actor) = c.who.clone() else { return };
        if matches!(c.command.facts.mount, sagebrush_protocol::MountEffect::Reads(_)) {
            return;
        }
        out.push(Action::Event(RouterEvent::Motion {
            actor,
            frame: Box::new(c.command.frame.clone()),
            refused,
        }));
    }

    /// Routes command `id` that the governance let through (or that it
    /// does not concern): its motions owned by the dead-man, then executed
    /// here, flooded or forwarded.
    pub(super) fn route_decided(&mut self, now: u64, accepted: Accepted, kind: Option<LinkKind>, out: &mut Outbox) {
        let (id, origin, command) = (accepted.id, accepted.origin, &accepted.command);
        let dest = command.frame.frame().dest;
        if let Origin::Link { link, .. } = origin {
            let lease = self.links.get(&link).and_then(|l| l.config.motion_lease);
            self.deadman.on_command(now, link, lease, dest, &command.facts);
        }
        if dest.group == self.group || dest.group == WILDCARD {
            if dest.group == WILDCARD && kind != Some(LinkKind::Downstream) {
                let (copies, first) = self.flood(now, (origin, id), command, out);
                let via = first.filter(|_| origin.link().is_some());
                if let (Some(c), Some(via)) = (self.in_flight.get_mut(&id), via) {
                    // Its execution here, and each copy.
                    c.spread = Some(Spread {
                        unsettled: copies.saturating_add(1),
                        via,
                        failure: None,
                    });
                }
            }
            return self.execute_local(now, accepted, out);
        }
        self.route_to_link(now, accepted, out);
    }

    fn next_command_id(&mut self) -> CommandId {
        let id = CommandId(self.next_id);
        self.next_id += 1;
        id
    }

    /// Command `id` ended (its one [`RouterEvent::Finished`]); its record
    /// stays while its origin still awaits the delivery outcome.
    pub(super) fn finish(&mut self, id: CommandId, outcome: CommandOutcome, out: &mut Outbox) {
        self.govern_finished(id, outcome, out);
        if let Some(c) = self.in_flight.get_mut(&id) {
            c.finished = true;
            c.issued_stop = None;
            if c.done() {
                self.in_flight.remove(&id);
            }
        }
        self.stats.count(outcome);
        out.push(Action::Event(RouterEvent::Finished { id, outcome }));
    }

    /// The jobs of command `id` on local ports, while they run.
    pub(super) fn jobs_of(&mut self, id: CommandId) -> Option<&mut Progress> {
        self.in_flight.get_mut(&id)?.jobs.as_mut()
    }
}
