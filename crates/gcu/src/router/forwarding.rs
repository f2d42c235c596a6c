//! Commands for other groups (ARCHITECTURE "Routing semantics"): routed
//! to the next GCU's link with a reverse-path entry, flooded to downstream
//! links (group 255), their answers relayed back to their origin, and
//! what a link dropped settled once.

use sagebrush_protocol::{FrameBuf, Undelivered};

use crate::boundary::Action;
use crate::command::ReadCommand;
use crate::config::LinkKind;
use crate::link::Outgoing;
use crate::outbox::Outbox;
use crate::types::{CommandId, CommandOutcome, DropReason, LinkId, Origin, Place, RouterEvent};

use super::Router;
use super::after_key;
use super::dispatch::Accepted;

impl Router {
    /// Command `id` for another group: forwarded on the route's link (its
    /// delivery is settled by the next GCU's report), or dropped and reported.
    pub(super) fn route_to_link(&mut self, now: u64, accepted: Accepted, out: &mut Outbox) {
        let Accepted { id, origin, command } = accepted;
        let f = command.frame.frame();
        let dest = f.dest;
        let up = |l: LinkId| self.links.contains_key(&l);
        let any_upstream = self
            .links
            .iter()
            .find(|(_, l)| l.config.kind == LinkKind::Upstream)
            .map(|(&id, _)| id);
        let route = self.routes.lookup(dest.group, up, any_upstream).and_then(|next| {
            if Some(next) == origin.link() {
                Err(DropReason::Loop)
            } else {
                Ok(next)
            }
        });
        let settles = origin.link().map(|_| id);
        if let Ok(next) = route {
            self.principal_ahead(now, next, id, dest.group, out);
        }
        let outcome =
            match route.and_then(|next| self.forward(now, next, &command, (origin, settles), out).map(|()| next)) {
                Ok(next) => CommandOutcome::Forwarded(next),
                Err(reason) => CommandOutcome::Dropped(reason),
            };
        if let CommandOutcome::Dropped(reason) = outcome {
            self.drop_frame(reason, Place::Router, dest, f.source, out);
            self.resolve(now, id, Err(reason.undelivered()), self.group, out);
        }
        // A forwarded command's delivery is settled by the next GCU's report.
        self.finish(id, outcome, out);
    }

    /// Before command `id` goes to GCU `group` on `link`: its principal,
    /// `~P PR name`, when `link` sends principals and it is not the one
    /// last said there (ARCHITECTURE "Principals"). The GCU's own command:
    /// the next GCU's report settles its reverse-path entry, and nobody
    /// waits for it.
    fn principal_ahead(&mut self, now: u64, link: LinkId, id: CommandId, group: u8, out: &mut Outbox) {
        let Some(actor) = self.in_flight.get(&id).and_then(|c| c.who.clone()) else {
            return;
        };
        let Some(l) = self.links.get(&link).filter(|l| l.config.sends_principals) else {
            return;
        };
        if l.principal_sent
            .as_ref()
            .is_some_and(|(n, p)| *n == actor.name && *p == actor.priority)
        {
            return;
        }
        let said = sagebrush_protocol::GcuCommand::Principal(actor.priority, actor.name.as_bytes());
        let dest = sagebrush_protocol::Address::new(group, 0, 0);
        let encode = |buf: &mut [u8]| {
            let capacity = buf.len();
            said.encode(buf)
                .ok_or(sagebrush_protocol::EncodeError::BufferTooSmall { needed: 40, capacity })
        };
        let Ok(frame) = FrameBuf::build(dest, self.group, encode) else {
            return;
        };
        let command = ReadCommand::read(frame);
        if self.forward(now, link, &command, (Origin::Internal, None), out).is_ok() {
            if let Some(mut l) = self.links.get_mut(&link) {
                l.principal_sent = Some((actor.name, actor.priority));
            }
        }
    }

    /// Forwards `command` on `link` with a reverse-path entry: `back` is where
    /// its answers go back to (its origin) and the command whose delivery
    /// the next GCU's report decides, if any. A full reverse path forgets an
    /// entry first; a command it still owed a report is not confirmed.
    fn forward(
        &mut self,
        now: u64,
        link: LinkId,
        command: &ReadCommand,
        back: (Origin, Option<CommandId>),
        out: &mut Outbox,
    ) -> Result<(), DropReason> {
        let (origin, settles) = back;
        let f = command.frame.frame();
        let (key, evicted) = self.reverse.insert(link, origin, &f, command.facts, settles);
        if let Some(unreported) = evicted {
            self.drop_frame(DropReason::PendingFull, Place::Router, f.dest, f.source, out);
            if let Some(old) = unreported {
                self.resolve(now, old, Err(Undelivered::NotConfirmed), self.group, out);
            }
        }
        // A forwarded stop overtakes the frames waiting on the link; the
        // GCU's own stops always fit.
        let item = Outgoing {
            frame: command.frame.clone(),
            pending: Some(key),
            stop: command.facts.stop,
            dead_man: origin == Origin::Internal,
        };
        let sent = self.enqueue_on_link(now, link, item, out);
        if sent.is_err() {
            self.reverse.cancel(key);
        }
        sent
    }

    /// Group 255 from upstream (or a client, or the router itself) is
    /// copied to every downstream link, never back where it came from.
    /// Each found afresh after the last (forwarding may change the links),
    /// with no list of targets. A link's command `id` is settled by each
    /// copy's report too (module `in_flight`: `Spread`): how many copies
    /// went, and the first one's link.
    pub(super) fn flood(
        &mut self,
        now: u64,
        (origin, id): (Origin, CommandId),
        command: &ReadCommand,
        out: &mut Outbox,
    ) -> (u16, Option<LinkId>) {
        let f = command.frame.frame();
        let settles = origin.link().map(|_| id);
        let mut after = None;
        let (mut copies, mut first) = (0u16, None);
        while let Some(link) = self
            .links
            .range(after_key(after))
            .find(|&(&id, l)| l.config.kind == LinkKind::Downstream && Some(id) != origin.link())
            .map(|(&id, _)| id)
        {
            after = Some(link);
            match self.forward(now, link, command, (origin, settles), out) {
                Ok(()) => {
                    self.stats.flooded += 1;
                    copies = copies.saturating_add(1);
                    first = first.or(Some(link));
                }
                Err(reason) => self.drop_frame(reason, Place::Link(link), f.dest, f.source, out),
            }
        }
        (copies, first)
    }

    /// A frame `link` dropped (it went down, or gave up on the frame): a
    /// forwarded command's origin is told, once. Transmitted, the next GCU
    /// may have it and execute it: not confirmed.
    pub(super) fn dropped_on_link(
        &mut self,
        now: u64,
        link: LinkId,
        item: &Outgoing,
        reason: DropReason,
        out: &mut Outbox,
    ) {
        if let Some(key) = item.pending {
            let settled = self.reverse.command_of(key);
            self.reverse.cancel(key);
            if let Some((id, transmitted)) = settled {
                let failure = match transmitted {
                    true => Undelivered::NotConfirmed,
                    false => reason.undelivered(),
                };
                self.resolve(now, id, Err(failure), self.group, out);
            }
        }
        let f = item.frame.frame();
        out.push(Action::Event(RouterEvent::Dropped {
            reason,
            at: Place::Link(link),
            dest: f.dest,
            source: f.source,
        }));
    }

    /// An answer from another GCU to a frame we forwarded: back to its origin, unchanged.
    pub(super) fn relay_forwarded(
        &mut self,
        now: u64,
        from: LinkId,
        origin: Origin,
        frame: FrameBuf,
        out: &mut Outbox,
    ) {
        let Origin::Link { link, .. } = origin else { return };
        let f = frame.frame();
        let (dest, source) = (f.dest, f.source);
        let sent = match self.links.contains_key(&link) {
            true => self.send_on_link(now, link, frame, out),
            false => Err(DropReason::OriginGone),
        };
        match sent {
            Ok(()) => self.stats.results_relayed += 1,
            Err(reason) => self.drop_frame(reason, Place::Link(from), dest, source, out),
        }
    }
}
