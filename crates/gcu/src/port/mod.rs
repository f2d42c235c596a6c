//! The per-port transaction scheduler (ARCHITECTURE "Routing semantics", "On a
//! port, one transaction at a time"):
//!
//! - One [`Transaction`](sagebrush_protocol::Transaction) of the protocol crate at a time on each bus: write,
//!   await ACK (NAK/time-out -> retransmit), then the result or NIC when the
//!   command has one (normal or long class, `IX` is long), else a short NIC
//!   window (on a full-duplex line the next command to the same device
//!   goes in it, `pipeline`). Device address 255 is written once, no ACK
//!   awaited, then a quiet guard time.
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
//!
//! This module holds the [`Job`], what a port asks of the router
//! ([`PortOut`]), the [`Port`] and its surface (opened, lost, idle, its next
//! deadline); each concern of running a bus has a module of its own:
//!
//! - `queueing`: jobs queued (stops first, identical stops merged, bounds
//!   and the fair drop), cancelled, the bus kept free for a planned stop,
//!   and which job goes next;
//! - `exchange`: a transaction started, stepped by what the bus sends
//!   (`Port::receive`: ACK, NAK, NIC, frames, and whose they are) and by
//!   time (`Port::poll`), and finished; a long result wait set aside for a
//!   stop, the quiet after a give-up and the device server's backlog;
//! - `pipeline`: on a full-duplex line, the next command to a device
//!   started in the NIC window of the one before, and whose a `?` is;
//! - `registry`: what an exchange teaches about its device (the device
//!   registry) and the rate changes it makes.

mod exchange;
mod pipeline;
mod queueing;
mod registry;

use std::collections::{BTreeMap, BTreeSet};

use sagebrush_protocol::link::TransactionPolicy;
use sagebrush_protocol::{DataRate, FrameBuf, RetryPolicy, Undelivered};

use crate::command::CommandFacts;
use crate::config::PortConfig;
use crate::line::LineReceiver;
use crate::outbox::Wire;
use crate::queue::StopFirstQueue;
use crate::stats::{DeviceStats, PortStats};
use crate::types::{CommandId, CommandOutcome, DropReason, Origin, RouterEvent};

use exchange::{Backlog, Running};
use pipeline::Windowing;

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
    /// An exchange in its NIC window while the next command to its device
    /// is on the bus (full-duplex lines, module `pipeline`).
    windowing: Option<Windowing>,
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
            windowing: None,
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
            .chain(self.windowing.take().map(|w| w.running))
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

    /// Nothing on the bus, set aside or queued.
    pub fn is_idle(&self) -> bool {
        self.active.is_none() && self.windowing.is_none() && self.detached.is_empty() && self.queue.is_empty()
    }

    pub fn next_deadline(&self) -> Option<u64> {
        let active = self.active.as_ref().and_then(|r| r.txn.deadline());
        let detached = self.detached.iter().filter_map(|r| r.txn.deadline()).min();
        let settle = self
            .settle_until
            .max(self.drained_at())
            .filter(|_| self.active.is_none() && !self.queue.is_empty());
        // Held back by a reservation: the governance's stop lifts it.
        [
            active,
            self.window_deadline(),
            detached,
            settle,
            self.line.idle_deadline(),
        ]
        .into_iter()
        .flatten()
        .min()
    }
}
