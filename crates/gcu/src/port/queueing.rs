//! Queueing on a port (ARCHITECTURE "Routing semantics", "Bounded and fair
//! under load", "Safety"): which jobs wait, which are given up, which goes
//! next.
//!
//! - Stop and halt commands overtake queued work (they queue behind earlier
//!   stops only); a stop gives up the queued motions of its device that
//!   would undo it.
//! - Fair: the next job after the stops is the oldest of the origin (link,
//!   i.e. client) served least recently, round robin; when the queue is
//!   full, the origin holding the most jobs gives up its newest one for a
//!   newcomer of another origin (so one client's flood never costs another
//!   its command); the newcomer of the hog itself is refused.
//! - The queue is bounded, stops and other work separately so that a burst
//!   of work never costs a stop its place (and a burst of dead-man stops
//!   never pushes work out): a job that does not fit is dropped and counted
//!   ([`DropReason::QueueFull`]), except a dead-man stop, which always fits. A stop identical to one already queued
//!   (same destination and payload) is merged into it
//!   ([`DropReason::DuplicateStop`]): the queued one does the job.
//! - Wildcards: a copy of a port-255 command is written with this port's
//!   address in the header (so that every answer names its port).

use std::collections::{BTreeMap, BTreeSet};

use sagebrush_protocol::{Row, WILDCARD};

use crate::queue::Queued;
use crate::types::{CommandId, DropReason, Origin, RouterEvent};

use super::{Job, Port, PortOut};

impl Queued for Job {
    fn is_stop(&self) -> bool {
        self.facts.stop
    }
    fn always_fits(&self) -> bool {
        self.origin == Origin::Internal
    }
    fn same_frame(&self, other: &Self) -> bool {
        let (a, b) = (self.frame.frame(), other.frame.frame());
        a.dest == b.dest && a.payload() == b.payload()
    }
    fn urgent(&self) -> bool {
        self.urgent
    }
}

impl Port {
    /// Queues a job: stops ahead of every non-stop job, the rest in order.
    pub fn enqueue(&mut self, now: u64, mut job: Job, out: &mut Vec<PortOut>) {
        if !self.open {
            return self.drop_job(job, DropReason::PortClosed, out);
        }
        if self.closing && job.origin != Origin::Internal {
            return self.drop_job(job, DropReason::ShuttingDown, out);
        }
        let dest = job.frame.frame().dest;
        if dest.port == WILDCARD {
            let mut port_copy = dest;
            port_copy.port = self.id;
            job.frame.set_header(port_copy, job.frame.frame().source);
        }
        if job.facts.stop {
            self.cancel_undone_by(&job, out);
            // An urgent stop identical to one waiting takes its place
            // ahead of the other stops (the governance simulation: a
            // boundary `PS` merged into a client's, queued behind a
            // broadcast's guard, came 330 ms late).
            if job.urgent {
                if let Some(queued) = self.queue.take_same_stop(&job) {
                    self.stats.line.drops.add(DropReason::DuplicateStop);
                    job.merged.push(queued.id);
                    job.merged.extend(queued.merged);
                }
            }
            if let Some(queued) = self.queue.same_stop_mut(&job) {
                self.stats.line.drops.add(DropReason::DuplicateStop);
                queued.merged.push(job.id);
                queued.merged.extend(job.merged);
                return;
            }
            if !self.queue.has_room(&job) {
                return self.drop_job(job, DropReason::QueueFull, out);
            }
        } else if !self.queue.has_room(&job) {
            // Full: the origin holding the most work gives up its newest
            // job, unless that is the newcomer's own origin (fair drop:
            // one client's flood never costs another client its command).
            let mut counts: BTreeMap<Option<crate::LinkId>, usize> = BTreeMap::new();
            for j in self.queue.iter().filter(|j| !j.facts.stop) {
                *counts.entry(j.origin.link()).or_default() += 1;
            }
            let mine = counts.get(&job.origin.link()).copied().unwrap_or(0);
            let hog = counts.iter().max_by_key(|&(_, n)| *n).map(|(&o, &n)| (o, n));
            match hog {
                Some((hog, n)) if hog != job.origin.link() && n > mine + 1 => {
                    let newest = self.queue.iter().rposition(|j| !j.facts.stop && j.origin.link() == hog);
                    if let Some(victim) = newest.and_then(|at| self.queue.remove(at)) {
                        self.drop_job(victim, DropReason::QueueFull, out);
                    }
                }
                _ => return self.drop_job(job, DropReason::QueueFull, out),
            }
        }
        out.push(PortOut::Event(RouterEvent::Queued {
            id: job.id,
            port: self.id,
            stop: job.facts.stop,
        }));
        self.queue.push(job);
        self.note_queue();
        self.start_next(now, out);
        self.maybe_detach(now, out);
    }

    /// Gives up command `id`'s job if it is still queued (not on the bus).
    pub fn cancel_queued(&mut self, id: CommandId, reason: DropReason, out: &mut Vec<PortOut>) -> bool {
        let Some(at) = self.queue.iter().position(|j| j.id == id) else {
            return false;
        };
        if let Some(job) = self.queue.remove(at) {
            self.drop_job(job, reason, out);
        }
        self.note_queue();
        true
    }

    /// A stop overtakes queued work (module documentation): a motion of the
    /// same device still queued would run after it and undo it, so it is
    /// given up ([`DropReason::Superseded`]): the stop of an axis ends the
    /// slews of that axis, a stop of both axes (`PT`, `HS`, `HA`) every
    /// slew and goto of the mount.
    fn cancel_undone_by(&mut self, stop: &Job, out: &mut Vec<PortOut>) {
        let device = stop.frame.frame().dest.device;
        let both = matches!(stop.facts.row, Row::StopMotion | Row::MotorsStop | Row::Halt);
        let axis_stop = stop.facts.row;
        let undone = self.queue.remove_where(|j| {
            let to = j.frame.frame().dest.device;
            // A command to device 255 moves this device too.
            let same = device == WILDCARD || to == device || to == WILDCARD;
            let slew_of = j.facts.stopped_by.map(|s| s.row());
            let mount_slew = matches!(slew_of, Some(Row::PanStop | Row::TiltStop));
            same && !j.facts.stop && (slew_of == Some(axis_stop) || (both && (mount_slew || j.facts.goes_to())))
        });
        for job in undone {
            self.drop_job(job, DropReason::Superseded, out);
        }
    }

    /// Queued jobs for `device` (or every device) that `pick` names are given up unsent
    /// (`reason` tells their origins): a take-over, or a stop at a
    /// boundary, must not be undone by a motion still waiting behind it.
    pub fn cancel_for_device(
        &mut self,
        device: u8,
        pick: impl Fn(&Job) -> bool,
        reason: DropReason,
        out: &mut Vec<PortOut>,
    ) {
        // A command to device 255 reaches this device too (the governance
        // simulation: a `TD` to 5.255.255 queued behind a boundary stop ran
        // after it, and the gimbal went on past its limit).
        let to_it = |j: &Job| matches!(j.frame.frame().dest.device, d if d == device || d == WILDCARD);
        let cancel = self.queue.remove_where(|j| !j.facts.stop && to_it(j) && pick(j));
        for job in cancel {
            self.drop_job(job, reason, out);
        }
        self.note_queue();
    }

    /// Keeps the bus free for a stop due at `at` (`None`: no longer); work
    /// held back by a reservation starts when it is lifted.
    pub fn reserve(&mut self, now: u64, reserved: Option<(u64, u64)>, out: &mut Vec<PortOut>) {
        if self.reserved != reserved {
            self.reserved = reserved;
            self.start_next(now, out);
        }
    }

    /// Whether the job that goes next must wait for the reservation: the
    /// bus is kept free for a stop the governance will send at `reserved.0`,
    /// so no work starts that would still hold it then (a stop may). A
    /// command to device 255 holds the bus for its broadcast guard, longer
    /// than the short exchange the reservation allows for (the governance
    /// simulation: a `PL` to `5.1.255` kept a boundary stop 120 ms late).
    pub(super) fn held_for_reserved_stop(&self, now: u64) -> bool {
        let Some((at, busy)) = self.reserved else { return false };
        let front = self.queue.front();
        let broadcast = |j: &Job| j.frame.frame().dest.device == WILDCARD;
        // A stop goes, but for one to device 255: it would hold the bus for
        // its guard past the reserved stop (a client's `TS` to 5.1.255 kept
        // a boundary `PS` 300 ms late in the governance simulation).
        if front.is_some_and(|j| j.facts.stop && !broadcast(j)) {
            return false;
        }
        let next = match front {
            Some(j) if j.facts.stop => Some(j),
            _ => self.next_pick().and_then(|i| self.queue.iter().nth(i)),
        };
        let holds = match next {
            Some(j) if broadcast(j) => {
                let frame = sagebrush_protocol::link::wire_ms(j.frame.as_bytes().len(), self.stats.bps);
                busy.max(frame + self.policy.broadcast_guard)
            }
            _ => busy,
        };
        now + holds > at
    }

    /// The origin link went down: queued motions it started must not run
    /// after the dead-man stop.
    pub fn cancel_motions(&mut self, link: crate::LinkId, out: &mut Vec<PortOut>) {
        let cancel = self
            .queue
            .remove_where(|j| j.facts.stopped_by.is_some() && j.origin.link() == Some(link));
        for job in cancel {
            self.drop_job(job, DropReason::OriginGone, out);
        }
        self.note_queue();
    }

    /// Where the next job waits in the queue: a stop first; else round
    /// robin between origins (each link is one client, ARCHITECTURE
    /// "Safety": none starves another), the oldest job of the origin served
    /// least recently.
    pub(super) fn next_pick(&self) -> Option<usize> {
        if self.queue.front()?.facts.stop {
            return Some(0);
        }
        // An origin's later jobs have the served turn of its first, so the
        // strict `<` keeps each origin's oldest job.
        let mut best: Option<(u64, usize)> = None;
        for (i, j) in self.queue.iter().enumerate() {
            let origin = j.origin.link();
            let served = self.served.get(&origin).copied().unwrap_or(0);
            if best.is_none_or(|(s, _)| served < s) {
                best = Some((served, i));
            }
        }
        // Motions of one device run in the order they were accepted, whoever
        // sent them: the governance follows them in that order (a goto's
        // path is checked from where the motions before it leave the gimbal).
        let mut pick = best?.1;
        let chosen = self.queue.iter().nth(pick)?;
        if chosen.facts.moves() {
            let device = chosen.frame.frame().dest.device;
            if let Some(first) = self
                .queue
                .iter()
                .position(|j| !j.facts.stop && j.facts.moves() && j.frame.frame().dest.device == device)
            {
                pick = pick.min(first);
            }
        }
        Some(pick)
    }

    /// The next job ([`Port::next_pick`]), taken from the queue.
    pub(super) fn next_job(&mut self) -> Option<Job> {
        let pick = self.next_pick()?;
        if self.queue.front()?.facts.stop {
            return self.queue.pop_front();
        }
        let job = self.queue.remove(pick)?;
        self.turn += 1;
        self.served.insert(job.origin.link(), self.turn);
        if self.served.len() > 2 * self.queue.len() + 16 {
            let queued: BTreeSet<_> = self.queue.iter().map(|j| j.origin.link()).collect();
            self.served.retain(|o, _| queued.contains(o));
        }
        Some(job)
    }
}
