//! Learn before deciding (ARCHITECTURE "Governance"): a command whose
//! decision needs what gcud does not know yet but can ask the gimbal (its
//! position after a start, its rate after a speed change, where a preset
//! lies) waits here, at the head of its gimbal's line, while the governor
//! asks; it is decided again each time one of the governor's queries ends,
//! and refused with the true reason when the gimbal does not say in time.
//! Later changes of the same gimbal wait behind it (their order is the
//! order the gimbal must see); a stop passes and gives up the waiting
//! motions it would undo, as a stop overtaking a port's queue does.

use sagebrush_protocol::{Address, MountEffect, WILDCARD};

use crate::command::CommandFacts;
use crate::config::LinkKind;
use crate::outbox::Outbox;
use crate::principal::Actor;
use crate::types::{CommandId, DropReason, Origin};

use super::Router;
use super::dispatch::Accepted;
use super::govern::Governed;

/// A command from a link held until the governance can decide it.
#[derive(Debug)]
pub(super) struct Waiting {
    pub id: CommandId,
    kind: Option<LinkKind>,
    dest: Address,
    /// Refused with `why` when still undecided then.
    until: u64,
    why: DropReason,
}

/// Whether two addresses may name the same gimbal (255 names every port or device).
fn overlap(a: Address, b: Address) -> bool {
    let same = |x: u8, y: u8| x == y || x == WILDCARD || y == WILDCARD;
    same(a.port, b.port) && same(a.device, b.device)
}

impl Router {
    /// Command `id` waits until the governance can decide it, at most three
    /// quarters of its client's delivery time-out: the outcome must reach
    /// the client within it, and once let through the command still has its
    /// own exchange on the bus (at 9600 bit/s a broadcast's guard before it
    /// took half the time-out in the governance simulation).
    pub(super) fn wait_for_knowledge(&mut self, now: u64, id: CommandId, kind: Option<LinkKind>, why: DropReason) {
        let Some(c) = self.in_flight.get(&id) else { return };
        self.waiting.push_back(Waiting {
            id,
            kind,
            dest: c.command.frame.frame().dest,
            until: now.saturating_add(self.settings.delivery_timeout * 3 / 4),
            why,
        });
    }

    /// Why a change for `dest` must wait: a command before it for the same
    /// gimbal still waits.
    pub(super) fn waiting_for(&self, dest: Address) -> Option<DropReason> {
        self.waiting.iter().find(|w| overlap(w.dest, dest)).map(|w| w.why)
    }

    /// A stop for `dest` overtakes what waits: the slews of the axes it
    /// stops, and for a stop of both axes every motion, are given up
    /// (`11` superseded).
    pub(super) fn supersede_waiting(&mut self, now: u64, dest: Address, stop: &CommandFacts, out: &mut Outbox) {
        let (pan, tilt) = match stop.mount {
            MountEffect::Stop { pan, tilt } => (pan, tilt),
            MountEffect::Halt => (true, true),
            _ => return,
        };
        let undone: Vec<CommandId> = self
            .waiting
            .iter()
            .filter(|w| overlap(w.dest, dest))
            .filter(|w| {
                let Some(c) = self.in_flight.get(&w.id) else {
                    return true;
                };
                match c.command.facts.mount {
                    MountEffect::Slew { axis, .. } => match axis {
                        sagebrush_protocol::Axis::Pan => pan,
                        sagebrush_protocol::Axis::Tilt => tilt,
                    },
                    _ => pan && tilt && c.command.facts.moves(),
                }
            })
            .map(|w| w.id)
            .collect();
        for id in undone {
            self.waiting.retain(|w| w.id != id);
            self.refuse(now, id, DropReason::Superseded, out);
        }
    }

    /// A change for `dest` from `who` gives up what waits for the same
    /// gimbal from links it outranks: it would take control from them
    /// once decided, so they never get it (refused `NotInControl`), and it
    /// does not wait behind them (the governance simulation: a jog of the
    /// highest link waited behind a lower link's goto and was refused for
    /// want of time to learn the rate).
    pub(super) fn outrank_waiting(&mut self, now: u64, dest: Address, who: &Actor, out: &mut Outbox) {
        if self.waiting.is_empty() {
            return;
        }
        let below: Vec<CommandId> = self
            .waiting
            .iter()
            .filter(|w| overlap(w.dest, dest))
            .filter(|w| {
                let sender = self.in_flight.get(&w.id).and_then(|c| c.who.as_ref());
                sender.is_some_and(|s| s.priority < who.priority)
            })
            .map(|w| w.id)
            .collect();
        let outranked = |w: &Waiting, _: Option<Origin>| below.contains(&w.id);
        self.give_up_waiting(now, outranked, DropReason::NotInControl, out);
    }

    /// Decides again what waits, in order: let through, refused, or still
    /// waiting (and so is what follows for the same gimbal).
    pub(super) fn decide_waiting(&mut self, now: u64, out: &mut Outbox) {
        if self.deciding || self.waiting.is_empty() {
            return;
        }
        self.deciding = true;
        let mut held: Vec<Address> = Vec::new();
        let mut kept = std::collections::VecDeque::new();
        // Taken out whole: each is decided against those before it (`held`),
        // not against those after it.
        let mut pending = std::mem::take(&mut self.waiting);
        while let Some(w) = pending.pop_front() {
            let Some((origin, command)) = self.in_flight.get(&w.id).map(|c| (c.origin, c.command.clone())) else {
                continue;
            };
            let Origin::Link { link, .. } = origin else { continue };
            if self.stopping {
                self.refuse(now, w.id, DropReason::ShuttingDown, out);
                continue;
            }
            if !self.links.contains_key(&link) {
                self.refuse(now, w.id, DropReason::OriginGone, out);
                continue;
            }
            if held.iter().any(|&d| overlap(d, w.dest)) {
                held.push(w.dest);
                kept.push_back(w);
                continue;
            }
            if now >= w.until {
                self.refuse(now, w.id, w.why, out);
                continue;
            }
            match self.govern_command(now, w.id, link, &command, out) {
                Governed::Pass => {
                    let accepted = Accepted {
                        id: w.id,
                        origin,
                        command,
                    };
                    self.route_decided(now, accepted, w.kind, out);
                }
                Governed::Refused(reason) => self.refuse(now, w.id, reason, out),
                Governed::Waits(why) => {
                    held.push(w.dest);
                    kept.push_back(Waiting { why, ..w });
                }
            }
        }
        // Nothing is accepted while deciding; whatever was is kept after.
        kept.append(&mut self.waiting);
        self.waiting = kept;
        self.deciding = false;
    }

    /// What waits and `gives_up` names is given up with `reason`: all of it
    /// at shutdown (a slew let through after the shutdown's stops would run
    /// on), a link's own when it goes down (its dead-man owns nothing yet).
    pub(super) fn give_up_waiting(
        &mut self,
        now: u64,
        gives_up: impl Fn(&Waiting, Option<Origin>) -> bool,
        reason: DropReason,
        out: &mut Outbox,
    ) {
        let mut undone = Vec::new();
        self.waiting.retain(|w| {
            let origin = self.in_flight.get(&w.id).map(|c| c.origin);
            let gone = gives_up(w, origin);
            if gone {
                undone.push(w.id);
            }
            !gone
        });
        for id in undone {
            self.refuse(now, id, reason, out);
        }
    }

    /// When a waiting command falls due to be refused.
    pub(super) fn waiting_deadline(&self) -> Option<u64> {
        self.waiting.iter().map(|w| w.until).min()
    }
}
