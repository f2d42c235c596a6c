//! The per-port transaction scheduler (ARCHITECTURE "Routing semantics", "On a
//! port, one transaction at a time"):
//!
//! - One [`Transaction`] of the protocol crate at a time on each bus: write,
//!   await ACK (NAK/time-out -> retransmit), then the result or NIC when the
//!   command has one (normal or long class, `IX` is long), else a short NIC
//!   window. Device address 255 is written once, no ACK awaited, then a
//!   quiet guard time.
//! - Hop by hop on the bus: every good frame a device sends is ACKed, a bad
//!   checksum is NAKed so that the device retransmits.
//! - Stop and halt commands overtake queued work (they queue behind earlier
//!   stops only). A long result wait (`IX` acknowledged, result pending) is
//!   set aside when a stop is queued: the stop goes out at once and the
//!   set-aside exchange still takes its result (matched by its Table 3
//!   header) or times out. Until it ends, only stops use the bus (another
//!   exchange could be answered with the same header). The bus is never
//!   written while an ACK is awaited.
//! - A result is taken only when its header is that of the exchange (Table
//!   3: port and device unchanged, destination group = the command's source
//!   group), during a device-255 guard time too. After an exchange that
//!   needed a retransmission, the device may have executed the command
//!   twice, or answered after the GCU gave up: the bus stays quiet for one
//!   ACK time-out so that such an answer is not taken for the next
//!   exchange's (it is ACKed and counted as unsolicited); so it does after
//!   any give-up, a NAK one included, so that a dead-man stop's next round
//!   is queued before other work starts. After an ACK wait of a device that
//!   answered its last exchange ran out (the exchange gave up, or a later
//!   try was answered), the bus stays quiet for
//!   `PortConfig::late_answer_guard`, at least one ACK time-out like any
//!   give-up (an address that never answered, or a device already offline,
//!   gets no guard: a scan of empty addresses stays fast and a dead device
//!   does not hold up its bus).
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
//!   address in the header (so that every answer names its port). During a
//!   device-255 guard time, result frames (from a device alone on its bus
//!   that answers broadcasts) are acknowledged and relayed.
//! - A `C0`..`C7` rate change acknowledged by every device of the port
//!   (configured list, or the devices that answered since the port opened),
//!   or broadcast to device 255, switches the port's own line rate.
//!   Reserved rates `C8`..`CF` never do (protocol-notes E15).
//! - A lost port fails its in-flight and queued jobs ([`DropReason::PortLost`]).
//! - Behind a device server (`PortConfig::buffered`) nothing is
//!   retransmitted and a missing ACK is `0B not confirmed`: the bytes may
//!   wait in the server while it stalls and run when it resumes. Their
//!   answers then come whenever it resumes, and an ACK names no command, so
//!   after such a give-up ([`Backlog`]) the first answer heard is nobody's:
//!   the exchange on the bus at that moment is `0B not confirmed` as well,
//!   and no exchange starts until the bus has been quiet for the late-answer
//!   guard (at least one ACK time-out) since the last byte heard. What
//!   arrives meanwhile is ACKed and counted as unsolicited, never relayed.

use std::collections::{BTreeMap, BTreeSet};

use sagebrush_protocol::link::TransactionPolicy;
use sagebrush_protocol::{
    DataRate, Event, FrameBuf, OwnedEvent, Reply, RetryPolicy, Transaction, TransactionStep, TxFailure, WILDCARD,
};
use sagebrush_protocol::{Outcome, ResultKind, ResultTimeout, Row, Undelivered};

use crate::command::CommandFacts;
use crate::config::PortConfig;
use crate::line::LineReceiver;
use crate::outbox::Wire;
use crate::queue::{Queued, StopFirstQueue};
use crate::stats::{DeviceError, DeviceStats, PortStats};
use crate::types::{CommandId, CommandOutcome, DropReason, Origin, RouterEvent};

/// One command exchange waiting for or holding a bus.
#[derive(Clone, Debug)]
pub(crate) struct Job {
    pub id: CommandId,
    pub origin: Origin,
    pub frame: FrameBuf,
    pub facts: CommandFacts,
    /// Identical stops of other commands merged into this one: they share its outcome.
    pub merged: Vec<CommandId>,
    /// A stop ahead of every other (a slew near a limit or zone).
    pub urgent: bool,
}

impl Job {
    pub fn new(id: CommandId, origin: Origin, frame: FrameBuf, facts: CommandFacts) -> Self {
        Self {
            id,
            origin,
            frame,
            facts,
            merged: Vec::new(),
            urgent: false,
        }
    }

    /// The command ids this job decides: its own and the merged ones.
    fn ids(&self) -> impl Iterator<Item = CommandId> + '_ {
        core::iter::once(self.id).chain(self.merged.iter().copied())
    }
}

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

/// What a port asks the router to do. Frames are held inline, without an
/// allocation of their own, on their short way to the Outbox or the origin.
#[derive(Debug)]
pub(crate) enum PortOut {
    Write(Wire),
    /// A result frame for the origin of job `id`, header as the device sent it.
    Relay {
        id: CommandId,
        origin: Origin,
        reply: FrameBuf,
    },
    /// The device acknowledged job `id` (or a device-255 command was written):
    /// the command is delivered (ARCHITECTURE "Delivery contract").
    Delivered {
        id: CommandId,
    },
    /// Job `id` ended without the device acknowledging it.
    Undelivered {
        id: CommandId,
        failure: Undelivered,
    },
    /// Job `id` is over.
    Finished {
        id: CommandId,
        outcome: CommandOutcome,
    },
    SetRate(u32),
    Event(RouterEvent),
}

#[derive(Debug)]
struct Running {
    job: Job,
    txn: Transaction,
    /// An ACK wait ran out: the device may still answer that try, late.
    ack_timed_out: bool,
}

impl Running {
    fn device(&self) -> u8 {
        self.job.frame.frame().dest.device
    }

    /// Whether `frame` can be this exchange's result: port and device
    /// unchanged (the protocol `Transaction` checks those) and, Table 3, the
    /// destination group is the command's source group. The protocol
    /// crate's check alone takes a late duplicate result meant for another
    /// source group's command to the same device.
    fn answered_by(&self, frame: &sagebrush_protocol::Frame<'_>) -> bool {
        frame.dest.group == self.job.frame.frame().source && self.txn.is_result_header(&frame.dest)
    }
}

/// Behind a device server: whether bytes of a given-up exchange may still
/// be waiting in it (module doc; ARCHITECTURE "Delivery contract").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Backlog {
    /// Every exchange was answered (or its address is known to be empty).
    Clear,
    /// An exchange went unanswered: its bytes may still run, and any answer
    /// heard may be theirs.
    Unsure,
    /// The bus answered since: nothing starts until it has been quiet for
    /// the guard since `last_heard`.
    Draining { last_heard: u64 },
}

#[derive(Debug)]
pub(crate) struct Port {
    pub id: u8,
    /// What it was made from (a reload compares it).
    pub config: PortConfig,
    policy: TransactionPolicy,
    /// Quiet after a late answer may still come: `late_answer_guard`, never
    /// shorter than the ACK time-out of quiet after any give-up (a guard
    /// of 0: seed 232276).
    late_answer_quiet: u64,
    devices: Option<Vec<u8>>,
    line: LineReceiver,
    open: bool,
    rate: DataRate,
    queue: StopFirstQueue<Job>,
    active: Option<Running>,
    /// Long result waits set aside for a stop, oldest first.
    detached: Vec<Running>,
    /// Devices that answered since the port was opened.
    seen: BTreeSet<u8>,
    /// Rate changes acknowledged per device, not yet applied to the port.
    acked_rates: BTreeMap<u8, DataRate>,
    /// After an exchange that was retransmitted the device may answer a
    /// second time: no new exchange starts before this tick.
    settle_until: Option<u64>,
    /// Behind a device server: given-up bytes perhaps still in it.
    backlog: Backlog,
    /// Being closed (removed or reconfigured): only the GCU's own stops are taken.
    pub closing: bool,
    /// A stop the governance will send at this tick, and how long a short
    /// exchange holds the bus: work that would overlap it waits.
    reserved: Option<(u64, u64)>,
    /// Round robin: when each origin (link) was last served, by `turn`.
    served: BTreeMap<Option<crate::LinkId>, u64>,
    turn: u64,
    pub stats: PortStats,
    pub device_stats: BTreeMap<u8, DeviceStats>,
}

impl Port {
    pub fn new(config: &PortConfig) -> Self {
        let policy = TransactionPolicy {
            retry: RetryPolicy {
                ack_timeout: config.ack_timeout,
                retries: config.retransmissions(),
            },
            result_timeout: config.result_timeout,
            long_result_timeout: config.long_result_timeout,
            nic_window: config.nic_window,
            broadcast_guard: config.broadcast_guard,
        };
        let rate = DataRate::from_bits_per_second(config.bps).unwrap_or(DataRate::Bps9600);
        Self {
            id: config.id,
            config: config.clone(),
            policy,
            late_answer_quiet: config.late_answer_guard.max(config.ack_timeout),
            devices: config.devices.clone(),
            line: LineReceiver::new(config.idle_timeout),
            open: false,
            rate,
            queue: StopFirstQueue::new(config.queue_bound, config.stop_queue_bound),
            active: None,
            detached: Vec::new(),
            seen: BTreeSet::new(),
            acked_rates: BTreeMap::new(),
            settle_until: None,
            backlog: Backlog::Clear,
            closing: false,
            reserved: None,
            served: BTreeMap::new(),
            turn: 0,
            stats: PortStats {
                bps: rate.bits_per_second().unwrap_or(9600),
                ..PortStats::default()
            },
            device_stats: BTreeMap::new(),
        }
    }

    fn write(&mut self, wire: Wire, out: &mut Vec<PortOut>) {
        self.stats.line.bytes_out += wire.as_bytes().len() as u64;
        out.push(PortOut::Write(wire));
    }

    /// The registry's entry of `device`, made on first use; none for the
    /// wildcard (a broadcast), which is no device (gcud's /status would
    /// list it as an offline gimbal).
    fn device(&mut self, device: u8) -> Option<&mut DeviceStats> {
        (device != WILDCARD).then(|| self.device_stats.entry(device).or_default())
    }

    fn note_queue(&mut self) {
        self.stats.queue_len = self.queue.len();
        self.stats.queue_high_water = self.queue.high_water();
    }

    fn drop_job(&mut self, job: Job, reason: DropReason, out: &mut Vec<PortOut>) {
        self.stats.line.drops.add(reason);
        for id in job.ids() {
            out.push(PortOut::Finished {
                id,
                outcome: CommandOutcome::Dropped(reason),
            });
        }
    }

    fn delivered(job: &Job, out: &mut Vec<PortOut>) {
        out.extend(job.ids().map(|id| PortOut::Delivered { id }));
    }

    /// The port was opened: tell the daemon the rate the bus runs at.
    pub fn open(&mut self, now: u64, out: &mut Vec<PortOut>) {
        self.open = true;
        self.stats.open = true;
        self.line.reset();
        out.push(PortOut::SetRate(self.stats.bps));
        self.start_next(now, out);
    }

    /// The port vanished: fail everything in flight or queued.
    pub fn lose(&mut self, out: &mut Vec<PortOut>) {
        self.open = false;
        self.stats.open = false;
        self.line.reset();
        self.seen.clear();
        self.acked_rates.clear();
        let running = self
            .active
            .take()
            .into_iter()
            .chain(self.detached.drain(..))
            .collect::<Vec<_>>();
        for r in running {
            self.drop_job(r.job, DropReason::PortLost, out);
        }
        while let Some(job) = self.queue.pop_front() {
            self.drop_job(job, DropReason::PortLost, out);
        }
        self.note_queue();
    }

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
            let same = device == WILDCARD || to == device;
            let slew_of = j.facts.stopped_by.map(|s| s.row());
            let mount_slew = matches!(slew_of, Some(Row::PanStop | Row::TiltStop));
            same && !j.facts.stop && (slew_of == Some(axis_stop) || (both && (mount_slew || j.facts.goes_to)))
        });
        for job in undone {
            self.drop_job(job, DropReason::Superseded, out);
        }
    }

    /// Queued jobs for `device` that `pick` names are given up unsent
    /// (`reason` tells their origins): a take-over, or a stop at a
    /// boundary, must not be undone by a motion still waiting behind it.
    pub fn cancel_for_device(
        &mut self,
        device: u8,
        pick: impl Fn(&Job) -> bool,
        reason: DropReason,
        out: &mut Vec<PortOut>,
    ) {
        let cancel = self
            .queue
            .remove_where(|j| !j.facts.stop && j.frame.frame().dest.device == device && pick(j));
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

    fn start_next(&mut self, now: u64, out: &mut Vec<PortOut>) {
        if self.settle_until.is_some_and(|t| now < t) {
            return;
        }
        self.settle_until = None;
        if let Some(until) = self.drained_at() {
            if now < until {
                return;
            }
            self.backlog = Backlog::Clear;
        }
        while self.active.is_none() && self.open {
            // While a long wait is set aside only stops use the bus: another
            // exchange could take its result (same Table 3 header) or give it theirs.
            if !self.detached.is_empty() && !self.queue.front().is_some_and(|j| j.facts.stop) {
                break;
            }
            // The bus is kept free for a stop the governance will send at
            // `reserved.0`: no work starts that would still hold it then.
            let front_is_stop = self.queue.front().is_some_and(|j| j.facts.stop);
            if self.reserved.is_some_and(|(at, busy)| now + busy > at) && !front_is_stop {
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

    /// The next job: a stop first; else round robin between origins (each
    /// link is one client, ARCHITECTURE "Safety": none starves another), the
    /// oldest job of the origin served least recently.
    fn next_job(&mut self) -> Option<Job> {
        if self.queue.front()?.facts.stop {
            return self.queue.pop_front();
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
        let job = self.queue.remove(pick)?;
        self.turn += 1;
        self.served.insert(job.origin.link(), self.turn);
        if self.served.len() > 2 * self.queue.len() + 16 {
            let queued: BTreeSet<_> = self.queue.iter().map(|j| j.origin.link()).collect();
            self.served.retain(|o, _| queued.contains(o));
        }
        Some(job)
    }

    /// A long result wait gives the bus to a queued stop.
    fn maybe_detach(&mut self, now: u64, out: &mut Vec<PortOut>) {
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
                if let Some(r) = self.active.take() {
                    self.finish(now, r, outcome, frame, out);
                }
                self.start_next(now, out);
            }
        }
    }

    fn finish(&mut self, now: u64, r: Running, outcome: Outcome, frame: Option<FrameBuf>, out: &mut Vec<PortOut>) {
        let device = r.device();
        let was_online = self.device_stats.get(&device).is_some_and(|d| d.online);
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
                if let Some(d) = self.device(device) {
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

    /// A change of `device`'s answering (the registry's `online`) since
    /// `before` (online, answered since the port opened), as one
    /// [`RouterEvent::DeviceState`].
    fn tell_device_state(&self, device: u8, before: (bool, bool), out: &mut Vec<PortOut>) {
        let online = self.device_stats.get(&device).is_some_and(|d| d.online);
        let (was_online, answered_before) = before;
        if online != was_online {
            out.push(PortOut::Event(RouterEvent::DeviceState {
                port: self.config.id,
                device,
                online,
                first: !answered_before,
            }));
        }
    }

    /// What an exchange tells about its device (the device registry):
    /// whether it answers, its last error, and the position or lens
    /// position it answered to `P?` (Table 15) or `V?` (Table 17).
    fn learn(&mut self, now: u64, device: u8, job: &Job, outcome: Outcome, result: Option<&FrameBuf>) {
        let Some(d) = self.device(device) else { return };
        let error = match outcome {
            Outcome::Broadcast => return,
            Outcome::Failed(TxFailure::NoAck) => Some(DeviceError::Silent),
            Outcome::Failed(TxFailure::Nak) => Some(DeviceError::Nak),
            Outcome::NoResult => Some(DeviceError::NoResult),
            Outcome::Nic => Some(DeviceError::Nic),
            Outcome::Result | Outcome::Acknowledged => None,
        };
        d.online = error != Some(DeviceError::Silent);
        if let Some(error) = error {
            d.last_error = Some((now, error));
        }

        let Some(result) = result.filter(|_| job.facts.registry) else {
            return;
        };
        match Reply::parse_expected(&job.facts.reply, result.frame().payload()) {
            Ok(Reply::Position(p)) => d.position = Some((now, p)),
            Ok(Reply::Lens(l)) => d.lens = Some((now, l)),
            _ => {}
        }
    }

    fn rate_acknowledged(&mut self, device: u8, rate: Option<DataRate>, out: &mut Vec<PortOut>) {
        let Some(rate) = rate.filter(|r| r.bits_per_second().is_some()) else {
            return;
        };
        self.acked_rates.insert(device, rate);
        let everyone = match &self.devices {
            Some(list) => list.to_vec(),
            None => self.seen.iter().copied().collect(),
        };
        if !everyone.is_empty() && everyone.iter().all(|d| self.acked_rates.get(d) == Some(&rate)) {
            self.switch_rate(rate, out);
        }
    }

    fn switch_rate(&mut self, rate: DataRate, out: &mut Vec<PortOut>) {
        let Some(bps) = rate.bits_per_second() else { return };
        self.acked_rates.clear();
        if self.rate == rate {
            return;
        }
        self.rate = rate;
        self.stats.bps = bps;
        self.stats.rate_switches += 1;
        self.line.reset();
        out.push(PortOut::SetRate(bps));
        out.push(PortOut::Event(RouterEvent::RateSwitched { port: self.id, bps }));
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
                    }
                    None => self.stats.line.stray_bytes += 1,
                }
            }
            OwnedEvent::Nic => {
                self.stats.line.nics_in += 1;
                if let Some(r) = self.active.as_mut().filter(|r| !r.txn.is_broadcast()) {
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

    /// When the bus will have been quiet long enough after answers heard
    /// with a backlog, if it is draining one.
    fn drained_at(&self) -> Option<u64> {
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
        self.line.poll(now);
        while let Some(event) = self.line.next_event(now, &mut &[][..], &mut self.stats.line) {
            self.on_event(now, event, out);
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

    /// Nothing on the bus, set aside or queued.
    pub fn is_idle(&self) -> bool {
        self.active.is_none() && self.detached.is_empty() && self.queue.is_empty()
    }

    pub fn next_deadline(&self) -> Option<u64> {
        let active = self.active.as_ref().and_then(|r| r.txn.deadline());
        let detached = self.detached.iter().filter_map(|r| r.txn.deadline()).min();
        let settle = self
            .settle_until
            .max(self.drained_at())
            .filter(|_| self.active.is_none() && !self.queue.is_empty());
        // Held back by a reservation: the governance's stop lifts it.
        [active, detached, settle, self.line.idle_deadline()]
            .into_iter()
            .flatten()
            .min()
    }
}
