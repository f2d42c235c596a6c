//! The router's side of the governance (module `govern`, ARCHITECTURE
//! "Governance"): every command from a link to a local gimbal is put to
//! the [`Governor`] before it is routed (a refusal is dropped and
//! reported, nothing reaches the bus); a take-over stops the holder's
//! motion first; the governor's own commands (polls, stops, tour and park
//! gotos) are dispatched as the GCU's; answers and ends of commands are
//! shown to it; and the GCU commands of port 0 (`~R`, `~C`, `~T`) are
//! answered here, and `~B` (the gimbal's limits and zones).

use std::sync::Arc;

use sagebrush_protocol::gcu::{ControllerReply, RuleItem, encode_rules, encode_tour_list, encode_tour_reply};
use sagebrush_protocol::{Address, Command, Describes, Frame, FrameBuf, GcuCommand, MAX_PAYLOAD, MountEffect, Reply};

use crate::boundary::Action;
use crate::command::ReadCommand;
use crate::govern::{Actor, Decision, Holder, Order};
use crate::outbox::Outbox;
use crate::types::{CommandId, CommandOutcome, DropReason, LinkId, Origin, Place, StopCause};

use super::Router;
use super::in_flight::IssuedStop;

/// What the governance made of a command from a link.
pub(super) enum Governed {
    /// Let through (or not its business).
    Pass,
    /// Refused before the bus.
    Refused(DropReason),
    /// Held until gcud knows enough (module `waiting`); refused with this
    /// reason if the gimbal does not say in time.
    Waits(DropReason),
}

impl Router {
    /// Who `link`'s next command is from (module `principal`):
    /// the user its door acts for, its principal, or the link itself.
    pub(super) fn identity(&self, link: LinkId) -> Option<Actor> {
        let l = self.links.get(&link)?;
        if let Some(acting) = &l.acting {
            return Some(acting.clone());
        }
        let config = &l.config;
        let name = config.name.clone().unwrap_or_else(|| Arc::from(""));
        Some(Actor::of_connection(&name, config.priority, config.principal.as_ref()))
    }

    /// `~U`: `link`'s next commands act for `user` (`None`: for the door
    /// itself). Only a principal that `acts_for_users` may say so.
    /// `~U` or `~P` from `link` (`who`: the user or principal named and
    /// `~P`'s priority): acknowledged, or refused `16` when the link may
    /// not say so.
    fn acting_said(
        &mut self,
        now: u64,
        id: CommandId,
        link: LinkId,
        frame: &Frame<'_>,
        who: (Option<&[u8]>, Option<u8>),
        out: &mut Outbox,
    ) -> CommandOutcome {
        let outcome = self.act_for(link, who.0, who.1);
        if let Err(reason) = outcome {
            self.drop_frame(reason, Place::Router, frame.dest, frame.source, out);
        }
        self.resolve(now, id, outcome.map_err(|r| r.undelivered()), self.group, out);
        match outcome {
            Ok(()) => CommandOutcome::Completed,
            Err(reason) => CommandOutcome::Dropped(reason),
        }
    }

    /// `claimed`: `~P`'s priority, as the GCU that sent it governs the
    /// principal (ARCHITECTURE "Principals", between GCUs), capped by the
    /// sending GCU's own.
    fn act_for(&mut self, link: LinkId, user: Option<&[u8]>, claimed: Option<u8>) -> Result<(), DropReason> {
        let Some(l) = self.links.get(&link) else {
            return Err(DropReason::OriginGone);
        };
        if !l.config.principal.as_ref().is_some_and(|p| p.acts_for_users) {
            return Err(DropReason::NotPermitted);
        }
        let acting = match user {
            None => None,
            Some(user) => {
                let door = Actor::of_connection(
                    &l.config.name.clone().unwrap_or_else(|| Arc::from("")),
                    l.config.priority,
                    l.config.principal.as_ref(),
                );
                let name: Arc<str> = Arc::from(String::from_utf8_lossy(user));
                Some(match claimed {
                    Some(priority) => Actor {
                        name,
                        priority: priority.min(door.priority),
                        via: Some(door.name.clone()),
                        for_user: None,
                    },
                    None => door.acting_for(&name, self.governor.principal(user)),
                })
            }
        };
        if let Some(mut l) = self.links.get_mut(&link) {
            l.acting = acting;
        }
        Ok(())
    }

    /// Puts command `id` from `link` for a local gimbal to the governor. A
    /// take-over stops the holder's motions first. A stop gives up the
    /// motions still waiting for knowledge that it would undo; a change
    /// waits behind those of its gimbal (module `waiting`).
    pub(super) fn govern_command(
        &mut self,
        now: u64,
        id: CommandId,
        link: LinkId,
        command: &ReadCommand,
        out: &mut Outbox,
    ) -> Governed {
        let facts = &command.facts;
        let dest = command.frame.frame().dest;
        let Some(who) = self.in_flight.get(&id).and_then(|c| c.who.clone()) else {
            return Governed::Pass;
        };
        if facts.stop {
            self.supersede_waiting(now, dest, facts, out);
        } else if facts.mount.changes() {
            self.outrank_waiting(now, dest, &who, out);
            if let Some(why) = self.waiting_for(dest) {
                return Governed::Waits(why);
            }
        }
        let known: Vec<(u8, u8)> =
            match dest.port == sagebrush_protocol::WILDCARD || dest.device == sagebrush_protocol::WILDCARD {
                true => self
                    .ports
                    .iter()
                    .flat_map(|(&p, port)| port.device_stats.keys().map(move |&d| (p, d)))
                    .collect(),
                false => Vec::new(),
            };
        let verdict = match self.governor.on_command(now, id, &who, dest, facts, &known) {
            Decision::Pass(verdict) => verdict,
            Decision::Refuse(reason) => return Governed::Refused(reason),
            Decision::Learn(why) => return Governed::Waits(why),
        };
        self.audit(id, None, out);
        if !verdict.relearn.is_empty() {
            if let Some(c) = self.in_flight.get_mut(&id) {
                c.note.relearn = verdict.relearn;
            }
        }
        for (port, device) in verdict.taken_over {
            // The holder's motions stop before the new command is queued,
            // and what it queued that moves (a tour's goto too) is given up.
            self.with_port(now, port, out, |p, _, po| {
                let moves = |j: &crate::port::Job| {
                    j.origin.link() != Some(link)
                        && !matches!(j.facts.reply.result_kind(), sagebrush_protocol::ResultKind::Required(_))
                };
                p.cancel_for_device(device, moves, DropReason::NotInControl, po)
            });
            // `PT` below ends pan and tilt; the lens motions get their own stops.
            let mut stops = self.deadman.take_device(port, device, link);
            stops.retain(|(_, _, stop)| !matches!(stop, Command::PanStop | Command::TiltStop));
            self.stop_motions(now, stops, StopCause::TakeOver, out);
            self.issue(
                now,
                Order {
                    port,
                    device,
                    command: Command::StopMotion,
                    stop: Some(StopCause::TakeOver),
                    cancel_slews: None,
                    purpose: crate::govern::Purpose::Motion,
                },
                out,
            );
        }
        Governed::Pass
    }

    /// The governor's own command, dispatched as the GCU's.
    pub(super) fn issue(&mut self, now: u64, order: Order, out: &mut Outbox) {
        let dest = Address::new(self.group, order.port, order.device);
        let Ok(frame) = FrameBuf::build(dest, self.group, |buf| order.command.encode(buf).map(<[u8]>::len)) else {
            return;
        };
        if let Some(reason) = order.cancel_slews {
            let (device, stop) = (order.device, order.command);
            // (A `PT` ends the slews of both axes.)
            let both = stop == Command::StopMotion;
            self.with_port(now, order.port, out, |p, _, po| {
                p.cancel_for_device(
                    device,
                    |j| {
                        j.facts.stopped_by == Some(stop)
                            || (both && matches!(j.facts.stopped_by, Some(Command::PanStop | Command::TiltStop)))
                    },
                    reason,
                    po,
                )
            });
        }
        let command = ReadCommand::built(&order.command, frame);
        // Known before dispatch: the command may end inside it.
        let id = CommandId(self.next_id);
        self.governor.sent(id, (order.port, order.device), order.purpose);
        match order.stop {
            Some(cause) => self.send_stop(
                now,
                command,
                IssuedStop {
                    link: None,
                    cause,
                    round: 1,
                },
                out,
            ),
            None => {
                let note = crate::govern::CommandNote {
                    own: Some(((order.port, order.device), order.purpose)),
                    relearn: Vec::new(),
                };
                self.dispatch(now, Origin::Internal, None, command, None, note, out);
            }
        }
    }

    /// Runs the governor: lapses, follows, tours, park; its commands dispatched, its events logged.
    pub(super) fn govern_poll(&mut self, now: u64, out: &mut Outbox) {
        // Orders may end at once and make more: a few rounds at most.
        for _ in 0..4 {
            let orders = self.governor.poll(now);
            for e in self.governor.events.drain(..) {
                out.push(Action::Event(e));
            }
            if orders.is_empty() {
                break;
            }
            for order in orders {
                self.issue(now, order, out);
            }
        }
        // The ports whose reservation may change: those with a stop planned
        // and those reserved until now, in order (every other port has
        // none and had none: reserving it would change nothing).
        let mut ports = std::mem::take(&mut self.reserve_scratch);
        ports.clear();
        self.governor.ports_with_planned_stops(&mut ports);
        ports.append(&mut self.reserved_ports);
        ports.sort_unstable();
        ports.dedup();
        for &port in &ports {
            if !self.ports.contains_key(&port) {
                continue;
            }
            let reserved = self.governor.reservation(port);
            if reserved.is_some() {
                self.reserved_ports.push(port);
            }
            self.with_port(now, port, out, |p, now, po| p.reserve(now, reserved, po));
        }
        self.reserve_scratch = ports;
    }

    /// A result of command `id` from `port`: what the governor learns from
    /// it, by what the command's row says its answer describes.
    pub(super) fn govern_result(&mut self, now: u64, id: CommandId, port: u8, reply: &FrameBuf) {
        let Some(c) = self.in_flight.get(&id) else { return };
        let MountEffect::Reads(describes) = c.command.facts.mount else {
            return;
        };
        if describes == Describes::Other {
            return;
        }
        let f = reply.frame();
        if let Ok(r) = Reply::parse_expected(&c.command.facts.reply, f.payload()) {
            self.governor.on_result(now, (port, f.dest.device), describes, &r);
        }
    }

    /// Command `id` ended with `outcome`: an own query's end may decide
    /// what waits for knowledge.
    pub(super) fn govern_finished(&mut self, id: CommandId, outcome: CommandOutcome, out: &mut Outbox) {
        let now = self.last_now;
        let note = self
            .in_flight
            .get_mut(&id)
            .map(|c| std::mem::take(&mut c.note))
            .unwrap_or_default();
        if self.governor.on_finished(now, id, outcome, note) {
            self.decide_waiting(now, out);
        }
    }

    /// A GCU command of port 0 (`~R`, `~C`, `~T`, `~B`; protocol crate, module
    /// `gcu`) from `origin`: its answer, or `None` for a NIC.
    pub(super) fn gcu_command(
        &mut self,
        now: u64,
        id: CommandId,
        origin: Origin,
        frame: &Frame<'_>,
        out: &mut Outbox,
    ) -> CommandOutcome {
        let Origin::Link { link, .. } = origin else {
            return CommandOutcome::Completed;
        };
        let Some(command) = GcuCommand::parse(frame.payload()) else {
            return self.gcu_nic(now, id, origin, out);
        };
        if !self.permits(link, &command) {
            let reason = DropReason::NotPermitted;
            self.drop_frame(reason, Place::Router, frame.dest, frame.source, out);
            self.resolve(now, id, Err(reason.undelivered()), self.group, out);
            return CommandOutcome::Dropped(reason);
        }
        let mut buf = [0u8; MAX_PAYLOAD];
        let len = match command {
            GcuCommand::Release(port, device) => {
                let Some(who) = self.identity(link) else {
                    return CommandOutcome::Dropped(DropReason::OriginGone);
                };
                return match self.governor.release(now, &who, (port, device)) {
                    Ok(()) => {
                        self.resolve(now, id, Ok(()), self.group, out);
                        CommandOutcome::Completed
                    }
                    Err(reason) => {
                        self.drop_frame(reason, Place::Router, frame.dest, frame.source, out);
                        self.resolve(now, id, Err(reason.undelivered()), self.group, out);
                        CommandOutcome::Dropped(reason)
                    }
                };
            }
            GcuCommand::ActFor(user) => return self.acting_said(now, id, link, frame, (user, None), out),
            GcuCommand::Principal(priority, name) => {
                return self.acting_said(now, id, link, frame, (Some(name), Some(priority)), out);
            }
            GcuCommand::Controller(port, device) => {
                let holder = self.governor.holder(now, (port, device));
                let reply = match &holder {
                    None => ControllerReply::Nobody,
                    Some(Holder::Link { name, priority, via }) => ControllerReply::Link {
                        priority: *priority,
                        name: clip(name.as_bytes()),
                        via: via.as_deref().map_or(&[][..], |v| clip(v.as_bytes())),
                        yours: self.identity(link).is_some_and(|me| *me.name == **name),
                    },
                    Some(Holder::Tour(n)) => ControllerReply::Tour(clip(n.as_bytes())),
                    Some(Holder::Park) => ControllerReply::Park,
                };
                reply.encode(port, device, &mut buf)
            }
            GcuCommand::TourStart(name) | GcuCommand::TourStop(name) => {
                let start = matches!(command, GcuCommand::TourStart(_));
                let Some((state, waiting_for)) = self.governor.tour_command(now, name, start) else {
                    return self.gcu_nic(now, id, origin, out);
                };
                let holder = match &waiting_for {
                    Some(Holder::Link { name, .. }) | Some(Holder::Tour(name)) => name.clone(),
                    Some(Holder::Park) => "park".into(),
                    None => String::new(),
                };
                encode_tour_reply(state, clip(holder.as_bytes()), &mut buf)
            }
            GcuCommand::Rules(port, device) => {
                let rules = self.governor.rules((port, device));
                let reserved = self.governor.named_presets((port, device));
                Some(encode_rules(port, device, rule_items(rules, &reserved), &mut buf))
            }
            GcuCommand::WindowReports => match self.window_reports_on(link) {
                Some(on) => {
                    buf[..on.len()].copy_from_slice(on);
                    Some(on.len())
                }
                None => return self.gcu_nic(now, id, origin, out),
            },
            GcuCommand::TourList => {
                let tours = self.governor.tour_status(now);
                Some(encode_tour_list(
                    tours.iter().map(|t| (t.name.as_bytes(), t.state)),
                    &mut buf,
                ))
            }
        };
        self.govern_poll(now, out);
        self.resolve(now, id, Ok(()), self.group, out);
        let Some(len) = len else {
            return CommandOutcome::Completed;
        };
        // Table 3 header: back to the asker, port 0, the device as addressed.
        let dest = Address::new(frame.source, frame.dest.port, frame.dest.device);
        let Ok(reply) = FrameBuf::build(dest, self.group, |b| {
            let n = len.min(b.len());
            b[..n].copy_from_slice(&buf[..n]);
            Ok::<usize, sagebrush_protocol::EncodeError>(n)
        }) else {
            return CommandOutcome::Completed;
        };
        match self.send_on_link(now, link, reply, out) {
            Ok(()) => CommandOutcome::Result,
            Err(reason) => CommandOutcome::Dropped(reason),
        }
    }

    /// Whether `link` may send GCU command `command` (ARCHITECTURE "GCU
    /// commands on port 0"): a tour is started or stopped only from the
    /// configured priority up; a gimbal's rules and its controller are
    /// told only to links that may read them.
    fn permits(&self, link: LinkId, command: &GcuCommand<'_>) -> bool {
        let Some(config) = self.links.get(&link).map(|l| &l.config) else {
            return false;
        };
        match command {
            GcuCommand::TourStart(_) | GcuCommand::TourStop(_) => self
                .governor
                .tours_min_priority()
                .is_none_or(|least| config.priority >= least),
            GcuCommand::Rules(..) | GcuCommand::Controller(..) => config.may_read_rules,
            GcuCommand::Release(..)
            | GcuCommand::WindowReports
            | GcuCommand::TourList
            | GcuCommand::ActFor(_)
            | GcuCommand::Principal(..) => true,
        }
    }

    fn gcu_nic(&mut self, now: u64, id: CommandId, origin: Origin, out: &mut Outbox) -> CommandOutcome {
        self.resolve(now, id, Ok(()), self.group, out);
        match self.nic_to(now, origin, out) {
            Ok(()) => CommandOutcome::Nic,
            Err(reason) => CommandOutcome::Dropped(reason),
        }
    }

    /// Control of every governed or held gimbal (gcud's `/status`).
    pub fn control(&self) -> Vec<crate::GimbalControl> {
        self.governor.control(self.last_now)
    }

    /// Every configured tour and its state.
    pub fn tours(&self) -> Vec<crate::TourStatus> {
        self.governor.tour_status(self.last_now)
    }

    /// Counters of the governance.
    pub fn governance_stats(&self) -> crate::GovernStats {
        self.governor.stats
    }

    /// A reload changed configured link `name`'s priority: its live
    /// connections take it at once.
    pub fn set_link_priority(&mut self, name: &str, priority: u8) {
        self.links.for_each_mut(|_, link| {
            if link.config.name.as_deref() == Some(name) {
                link.config.priority = priority;
            }
        });
        self.governor.set_priority(name, priority);
    }
}

/// A name as a GCU command carries it (at most 32 bytes).
fn clip(name: &[u8]) -> &[u8] {
    &name[..name.len().min(sagebrush_protocol::gcu::NAME_MAX)]
}

/// A gimbal's limits and zones as `~B` answers them: limits first, the
/// presets park and its tours recall (`reserved`), then the zones (as many
/// as the payload holds). Spans are within ±327.67° (the configuration's
/// bounds); one beyond is clamped.
fn rule_items<'a>(rules: Option<&'a crate::GimbalRules>, reserved: &'a [u8]) -> impl Iterator<Item = RuleItem> + 'a {
    fn span(s: &crate::Span) -> [i16; 2] {
        let clamp = |v: i32| v.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16;
        [clamp(s.lo), clamp(s.hi)]
    }
    let limits = [
        rules
            .and_then(|r| r.pan_limits.as_ref())
            .map(|s| RuleItem::PanLimits(span(s))),
        rules
            .and_then(|r| r.tilt_limits.as_ref())
            .map(|s| RuleItem::TiltLimits(span(s))),
    ];
    let zones = rules
        .into_iter()
        .flat_map(|r| r.keep_out.iter())
        .map(|z| RuleItem::KeepOut {
            pan: span(&z.pan),
            tilt: span(&z.tilt),
        });
    let reserved = reserved.iter().map(|&n| RuleItem::Reserved(n));
    limits.into_iter().flatten().chain(reserved).chain(zones)
}
