//! Statistics per port, link and device, and for the router as a whole:
//! plain structs of `u64` counters (last-seen as the tick), for the daemon
//! to export as it likes.

use std::collections::BTreeMap;
use std::marker::PhantomData;

use crate::config::LinkKind;
use sagebrush_protocol::{LensPosition, Position, Undelivered};

use crate::types::{CommandOutcome, DropReason, LinkId};

/// A kind of thing counted by [`Counts`]: a code table's rows, each
/// counted in its own slot.
pub trait Counted: Copy + PartialEq + 'static {
    /// Every kind, in table order.
    const ALL: &'static [Self];
    /// The kind's slot: its place in [`Counted::ALL`].
    fn slot(self) -> usize {
        Self::ALL.iter().position(|&k| k == self).expect("every kind is in ALL")
    }
}

impl Counted for DropReason {
    const ALL: &'static [Self] = &DropReason::ALL;
    fn slot(self) -> usize {
        self.index()
    }
}

impl Counted for Undelivered {
    const ALL: &'static [Self] = &Undelivered::ALL;
}

/// Counts by kind (every one of the `N` kinds of `K`, zeros included).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Counts<K, const N: usize>([u64; N], PhantomData<K>);

/// Drops counted by reason.
pub type DropCounts = Counts<DropReason, { DropReason::ALL.len() }>;
/// Undelivered commands counted by [`Undelivered`] kind.
pub type UndeliveredCounts = Counts<Undelivered, { Undelivered::ALL.len() }>;

impl<K: Counted, const N: usize> Default for Counts<K, N> {
    fn default() -> Self {
        const { assert!(N == K::ALL.len(), "one slot per kind") };
        Self([0; N], PhantomData)
    }
}

impl<K: Counted, const N: usize> Counts<K, N> {
    /// Counts given per kind.
    pub fn from_fn(mut count: impl FnMut(K) -> u64) -> Self {
        let mut counts = Self::default();
        for &k in K::ALL {
            counts.0[k.slot()] = count(k);
        }
        counts
    }
    pub fn get(&self, kind: K) -> u64 {
        self.0[kind.slot()]
    }
    pub fn total(&self) -> u64 {
        self.0.iter().sum()
    }
    /// Every kind with its count (zeros included).
    pub fn iter(&self) -> impl Iterator<Item = (K, u64)> + '_ {
        K::ALL.iter().map(|&k| (k, self.get(k)))
    }
    pub(crate) fn add(&mut self, kind: K) {
        self.0[kind.slot()] += 1;
    }
    /// Adds another set of counts to these.
    pub fn absorb(&mut self, other: &Self) {
        for (mine, theirs) in self.0.iter_mut().zip(other.0) {
            *mine += theirs;
        }
    }
}

/// Counters of one line (a serial port or a link).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineStats {
    /// Good frames received.
    pub frames_in: u64,
    /// Frames written (retransmissions included).
    pub frames_out: u64,
    pub bytes_in: u64,
    pub bytes_out: u64,
    /// Received frame candidates whose checksum failed (each NAKed).
    pub bad_checksums: u64,
    /// NAKs this GCU wrote.
    pub naks_sent: u64,
    /// NAKs the other side sent back.
    pub naks_received: u64,
    /// ACK/NAK/`?` bytes nobody was waiting for.
    pub stray_bytes: u64,
    /// Frames written again after a NAK or ACK time-out.
    pub retransmits: u64,
    /// ACK or result time-outs.
    pub timeouts: u64,
    /// `?` received.
    pub nics_in: u64,
    /// `?` written.
    pub nics_out: u64,
    /// Noise bytes the framer skipped.
    pub noise_bytes: u64,
    pub drops: DropCounts,
    /// Tick of the last byte received.
    pub last_seen: Option<u64>,
}

impl LineStats {
    /// Adds another line's counters to these (the later `last_seen` wins).
    pub fn absorb(&mut self, o: &LineStats) {
        self.frames_in += o.frames_in;
        self.frames_out += o.frames_out;
        self.bytes_in += o.bytes_in;
        self.bytes_out += o.bytes_out;
        self.bad_checksums += o.bad_checksums;
        self.naks_sent += o.naks_sent;
        self.naks_received += o.naks_received;
        self.stray_bytes += o.stray_bytes;
        self.retransmits += o.retransmits;
        self.timeouts += o.timeouts;
        self.nics_in += o.nics_in;
        self.nics_out += o.nics_out;
        self.noise_bytes += o.noise_bytes;
        self.drops.absorb(&o.drops);
        self.last_seen = self.last_seen.max(o.last_seen);
    }
}

/// One serial port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortStats {
    pub line: LineStats,
    pub open: bool,
    /// Current line rate.
    pub bps: u32,
    /// Jobs waiting now (the one in flight not included).
    pub queue_len: usize,
    /// Most jobs ever waiting at once.
    pub queue_high_water: usize,
    /// Transactions started.
    pub transactions: u64,
    /// Transactions started in the NIC window of the one before, to the
    /// same device (full-duplex lines, `port::pipeline`).
    pub pipelined: u64,
    pub rate_switches: u64,
}

/// One link while it is up (its final counters leave with
/// [`crate::Action::LinkGone`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkStats {
    pub line: LineStats,
    pub up: bool,
    pub kind: LinkKind,
    /// Frames waiting now, the one in flight included.
    pub queue_len: usize,
    pub queue_high_water: usize,
    /// Frames accepted into the send queue.
    pub queued: u64,
    /// Frames the peer acknowledged.
    pub delivered: u64,
    /// Frames given up (retries exhausted) or dropped with the link.
    pub failed: u64,
    /// ACKs written (hop by hop, or for a client's delivered command).
    pub acks_sent: u64,
    /// A client's frame identical to its command still awaiting delivery:
    /// a retransmission, not executed again.
    pub repeats: u64,
}

impl LinkStats {
    /// Adds another link's counters to these (several connections of one
    /// configured link, live and gone); queue lengths add up, `up` if either is.
    pub fn absorb(&mut self, o: &LinkStats) {
        self.line.absorb(&o.line);
        self.up |= o.up;
        self.queue_len += o.queue_len;
        self.queue_high_water = self.queue_high_water.max(o.queue_high_water);
        self.queued += o.queued;
        self.delivered += o.delivered;
        self.failed += o.failed;
        self.acks_sent += o.acks_sent;
        self.repeats += o.repeats;
    }

    pub fn new(kind: LinkKind) -> Self {
        Self {
            line: LineStats::default(),
            up: true,
            kind,
            queue_len: 0,
            queue_high_water: 0,
            queued: 0,
            delivered: 0,
            failed: 0,
            acks_sent: 0,
            repeats: 0,
        }
    }
}

/// Why the last exchange with a device did not end as asked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceError {
    /// Never acknowledged: no ACK to any transmission (1.4.2).
    Silent,
    /// Answered NAK to every transmission.
    Nak,
    /// Acknowledged, result never came.
    NoResult,
    /// Answered `?`: it does not implement or cannot apply the command.
    Nic,
}

impl DeviceError {
    /// A stable snake_case name (metric labels, JSON).
    pub fn name(self) -> &'static str {
        match self {
            DeviceError::Silent => "device_silent",
            DeviceError::Nak => "device_nak",
            DeviceError::NoResult => "no_result",
            DeviceError::Nic => "nic",
        }
    }
}

impl core::fmt::Display for DeviceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            DeviceError::Silent => "did not acknowledge",
            DeviceError::Nak => "answered NAK to every try",
            DeviceError::NoResult => "acknowledged, sent no result",
            DeviceError::Nic => "answered NIC",
        })
    }
}

/// One device, keyed by (port, device address): its counters and what the
/// GCU learned from its answers (the device registry of `gcud`'s status
/// and metrics). Bounded: at most 255 per port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceStats {
    /// Transactions addressed to it.
    pub commands: u64,
    /// Command frames written to it (retransmissions included).
    pub frames_out: u64,
    /// Result frames from it.
    pub frames_in: u64,
    pub retransmits: u64,
    /// Never acknowledged after all retries.
    pub unreachable: u64,
    /// Acknowledged, result never came.
    pub no_result: u64,
    pub nics: u64,
    /// Tick of the last answer (ACK, NAK, result or `?`).
    pub last_seen: Option<u64>,
    /// Whether it answered the last exchange addressed to it (an ACK or
    /// NAK; a broadcast to device 255 says nothing). `false` before any.
    pub online: bool,
    /// The last position it answered to `P?` (Table 15), with its tick.
    pub position: Option<(u64, Position)>,
    /// The tick of the last motion sent to it (or broadcast to its port)
    /// after that answer: `position` is where it was, not where it is.
    pub moved: Option<u64>,
    /// The last lens position it answered to `V?` (Table 17), with its tick.
    pub lens: Option<(u64, LensPosition)>,
    /// The last exchange that did not end as asked, with its tick.
    pub last_error: Option<(u64, DeviceError)>,
}

/// Router-wide counters of accepted commands and their outcomes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RouterStats {
    /// Commands accepted (dead-man stops included).
    pub accepted: u64,
    pub results: u64,
    pub nics: u64,
    pub completed: u64,
    pub no_result: u64,
    pub unreachable: u64,
    pub forwarded: u64,
    /// Outcomes [`CommandOutcome::Dropped`], by reason.
    pub dropped: DropCounts,
    /// Frames dropped at the router (routing, source filter, stray answers), by reason.
    pub frame_drops: DropCounts,
    /// Result frames relayed back to an origin.
    pub results_relayed: u64,
    /// Group-255 copies flooded to downstream links.
    pub flooded: u64,
    pub dead_man_stops: u64,
    /// Stops issued because a link's motion lease ran out.
    pub lease_stops: u64,
    /// Stops issued at shutdown for motions still running.
    pub shutdown_stops: u64,
    /// Stops the governance issued: take-overs, slews near a limit or zone, tours stopped.
    pub governance_stops: u64,
    /// Commands from links whose origin was told "delivered" (ACK or report 00).
    pub delivered: u64,
    /// Commands from links whose origin was told "not delivered", by why.
    pub undelivered: UndeliveredCounts,
    /// Commands in progress now.
    pub in_progress: u64,
}

impl RouterStats {
    pub(crate) fn count(&mut self, outcome: CommandOutcome) {
        match outcome {
            CommandOutcome::Result => self.results += 1,
            CommandOutcome::Nic => self.nics += 1,
            CommandOutcome::Completed => self.completed += 1,
            CommandOutcome::NoResult => self.no_result += 1,
            CommandOutcome::Unreachable => self.unreachable += 1,
            CommandOutcome::Forwarded(_) => self.forwarded += 1,
            CommandOutcome::Dropped(reason) => self.dropped.add(reason),
        }
    }

    /// Sum of all outcomes so far.
    pub fn finished(&self) -> u64 {
        self.results
            + self.nics
            + self.completed
            + self.no_result
            + self.unreachable
            + self.forwarded
            + self.dropped.total()
    }
}

/// A snapshot of everything, from [`crate::Router::stats`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    pub router: RouterStats,
    pub ports: BTreeMap<u8, PortStats>,
    pub links: BTreeMap<LinkId, LinkStats>,
    pub devices: BTreeMap<(u8, u8), DeviceStats>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_of_either_kind_count_each_in_its_own_slot() {
        let mut drops = DropCounts::default();
        drops.add(DropReason::KeepOut);
        drops.add(DropReason::KeepOut);
        drops.add(DropReason::NotPermitted);
        assert_eq!(drops.get(DropReason::KeepOut), 2);
        assert_eq!(drops.get(DropReason::NotPermitted), 1);
        assert_eq!(drops.total(), 3);
        let mut both = DropCounts::from_fn(|r| u64::from(r == DropReason::NoRoute));
        both.absorb(&drops);
        assert_eq!(both.iter().filter(|(_, n)| *n > 0).count(), 3);
        // Codes that are not slots (Undelivered's start past zero) still count apart.
        let mut undelivered = UndeliveredCounts::default();
        for (i, &kind) in Undelivered::ALL.iter().enumerate() {
            for _ in 0..=i {
                undelivered.add(kind);
            }
        }
        let seen: Vec<u64> = undelivered.iter().map(|(_, n)| n).collect();
        let expected: Vec<u64> = (1..=Undelivered::ALL.len() as u64).collect();
        assert_eq!(seen, expected);
        let by_code = UndeliveredCounts::from_fn(|k| u64::from(k.code()));
        assert!(Undelivered::ALL.iter().all(|&k| by_code.get(k) == u64::from(k.code())));
    }
}
