//! The [`Router`]: one GCU of group G, as pure logic. It ties together the
//! links (module `link`), the port schedulers (module `port`), the
//! routing table (module `routing`), the reverse path of forwarded frames
//! (module `reverse`) and the dead-man (module `deadman`). See the crate
//! documentation for the rules.
//!
//! This module holds the struct and its surface (inputs, polling, what a
//! port or link asks of it, writes toward links); each concern of routing
//! a command has a module of its own:
//!
//! - `in_flight`: the one record of a command in flight;
//! - `dispatch`: a command accepted, routed, finished;
//! - `local`: executed on this GCU's ports, or by the GCU itself (`self_answer`);
//! - `forwarding`: routed or flooded to other GCUs, their answers back;
//! - `receive`: what links receive (answers, reports, commands);
//! - `delivery`: the delivery contract (ACK or report, time-out);
//! - `govern`, `waiting`: the governance's decisions, and the commands
//!   that wait for what it must learn first;
//! - `lifecycle`: links and ports coming and going, reload, shutdown, the
//!   stops the GCU issues itself.

mod delivery;
mod dispatch;
mod forwarding;
mod govern;
mod in_flight;
mod lifecycle;
mod local;
mod receive;
mod self_answer;
mod waiting;
mod window;

use std::collections::BTreeMap;
use std::ops::Bound;

use sagebrush_protocol::{Address, FrameBuf, Undelivered};

use crate::boundary::{Action, Input};
use crate::by_id::ById;
use crate::config::{ConfigError, LinkSettings, PortConfig, RouterConfig};
use crate::deadman::DeadMan;
use crate::govern::Governor;
use crate::link::{Link, LinkOut, Outgoing, Received};
use crate::outbox::Outbox;
use crate::port::{Port, PortOut};
use crate::reverse::ReversePath;
use crate::routing::RoutingTable;
use crate::stats::{RouterStats, Stats};
use crate::timed::{Deadline, Timed};
use crate::types::{CommandId, DropReason, LineId, LinkId, Origin, Place, RouterEvent};

use in_flight::{Delivery, InFlight};

/// The GCU router core. See the crate documentation for how a daemon drives it.
#[derive(Debug)]
pub struct Router {
    group: u8,
    name: String,
    serial: String,
    /// As configured (a reload must not change them).
    settings: LinkSettings,
    /// In force: the reverse path's answer time-outs raised to what the
    /// configured ports may take ([`LinkSettings::with_answer_time_for`]).
    in_force: LinkSettings,
    /// Their deadlines indexed: a turn walks the due ones only.
    ports: Timed<u8, Port>,
    links: Timed<LinkId, Link>,
    routes: RoutingTable,
    reverse: ReversePath,
    deadman: DeadMan,
    /// Control, limits, zones, tours and park (ARCHITECTURE "Governance").
    governor: Governor,
    /// Commands in flight, by id.
    in_flight: ById<InFlight>,
    /// Commands from links waiting for the governance to know enough (module `waiting`).
    waiting: std::collections::VecDeque<waiting::Waiting>,
    /// The waiting commands are being decided (no second pass inside it).
    deciding: bool,
    /// [`crate::Input::Shutdown`] came: new commands are refused.
    stopping: bool,
    /// New configurations of ports that are closing (reconfigured).
    replacements: BTreeMap<u8, PortConfig>,
    next_id: u64,
    /// Emptied scratch vectors of port and link outputs, reused so that
    /// routing a frame does not allocate them anew (a few: calls nest).
    port_scratch: Vec<Vec<PortOut>>,
    link_scratch: Vec<Vec<LinkOut>>,
    received_scratch: Vec<Vec<Received>>,
    /// Commands whose forward expired unreported, reused likewise.
    expired_scratch: Vec<CommandId>,
    /// Ports a governor's stop reserves the bus of ([`Port::reserve`]),
    /// and a scratch vector for the ports whose reservation may change.
    reserved_ports: Vec<u8>,
    reserve_scratch: Vec<u8>,
    last_now: u64,
    stats: RouterStats,
    unknown_inputs: u64,
}

/// Scratch vectors kept for reuse, per kind (calls nest a few deep).
const SCRATCH_KEPT: usize = 4;

impl Router {
    /// A router for `config`; ports start closed until [`crate::Input::PortOpened`].
    pub fn new(config: RouterConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            group: config.group,
            ports: config.ports.iter().map(|p| (p.id, Port::new(p))).collect(),
            links: Timed::new(),
            routes: RoutingTable::new(config.static_routes, config.default_upstream),
            reverse: ReversePath::new(
                config.links.max_pending,
                (u64::from(config.links.retries) + 1) * config.links.ack_timeout,
            ),
            deadman: DeadMan::default(),
            governor: Governor::new(config.governance.clone()),
            in_flight: ById::new(),
            waiting: std::collections::VecDeque::new(),
            deciding: false,
            stopping: false,
            replacements: BTreeMap::new(),
            next_id: 0,
            port_scratch: Vec::new(),
            link_scratch: Vec::new(),
            received_scratch: Vec::new(),
            expired_scratch: Vec::new(),
            reserved_ports: Vec::new(),
            reserve_scratch: Vec::new(),
            last_now: 0,
            stats: RouterStats::default(),
            unknown_inputs: 0,
            in_force: config.links.with_answer_time_for(&config.ports),
            settings: config.links,
            name: config.name,
            serial: config.serial,
        })
    }

    /// This GCU's group address.
    pub fn group(&self) -> u8 {
        self.group
    }

    /// Feeds one input at tick `now` and appends the actions to execute, in
    /// order, to `out`. Time-outs due by `now` are processed too, so any
    /// input doubles as a tick. `now` never goes backwards (an earlier
    /// value is taken as the latest one seen).
    pub fn handle(&mut self, now: u64, input: Input<'_>, out: &mut Outbox) {
        let now = now.max(self.last_now);
        self.last_now = now;
        match input {
            Input::Tick => {}
            Input::PortOpened { port } => {
                self.port_state(port, true, out);
                self.with_port(now, port, out, |p, now, po| p.open(now, po));
            }
            Input::PortLost { port } => {
                self.port_state(port, false, out);
                self.with_port(now, port, out, |p, _, po| p.lose(po));
            }
            Input::Bytes {
                line: LineId::Port(port),
                bytes,
            } => self.with_port(now, port, out, |p, now, po| p.receive(now, bytes, po)),
            Input::Bytes {
                line: LineId::Link(link),
                bytes,
            } => self.link_bytes(now, link, bytes, out),
            Input::LinkUp { link, config } => self.link_up(now, link, config, out),
            Input::LinkDown { link } => self.link_down(now, link, out),
            Input::Shutdown => self.shut_down(now, out),
        }
        self.poll(now, out);
    }

    /// [`Router::handle`] into a fresh [`Outbox`] (tests; a daemon keeps one).
    pub fn handle_once(&mut self, now: u64, input: Input<'_>) -> Outbox {
        let mut out = Outbox::new();
        self.handle(now, input, &mut out);
        out
    }

    /// When the router next needs [`Input::Tick`], if anything is pending.
    pub fn next_deadline(&self) -> Option<u64> {
        self.ports
            .earliest()
            .into_iter()
            .chain(self.links.earliest())
            .chain(self.reverse.next_deadline())
            .chain(self.deadman.next_deadline())
            .chain(self.governor.next_deadline())
            .chain(self.waiting_deadline())
            .chain(self.in_flight.values().filter_map(|c| c.delivery?.deadline()))
            .min()
    }

    /// A snapshot of every counter.
    pub fn stats(&self) -> Stats {
        let mut router = self.stats;
        router.in_progress = self.in_progress() as u64;
        let links = self.links.iter().map(|(&id, l)| (id, l.stats)).collect();
        Stats {
            router,
            ports: self.ports.iter().map(|(&id, p)| (id, p.stats)).collect(),
            links,
            devices: self
                .ports
                .iter()
                .flat_map(|(&port, p)| p.device_stats.iter().map(move |(&d, s)| ((port, d), *s)))
                .collect(),
        }
    }

    /// Inputs naming a port that is not configured or a link that is not up.
    pub fn unknown_inputs(&self) -> u64 {
        self.unknown_inputs
    }

    /// Whether `link` is up.
    pub fn link_is_up(&self, link: LinkId) -> bool {
        self.links.contains_key(&link)
    }

    /// Commands accepted and not yet finished.
    pub fn in_progress(&self) -> usize {
        self.in_flight.values().filter(|c| c.jobs.is_some()).count()
    }

    /// Forwarded commands still owed a delivery report or a result (what
    /// shutdown waits for); answered entries kept only to recognise a
    /// repeated answer are not counted.
    pub fn pending_answers(&self) -> usize {
        self.reverse.unsettled()
    }

    /// Continuous motions owned by links (dead-man records).
    pub fn owned_motions(&self) -> usize {
        self.deadman.len()
    }

    fn with_port(&mut self, now: u64, port: u8, out: &mut Outbox, f: impl FnOnce(&mut Port, u64, &mut Vec<PortOut>)) {
        let Some(mut p) = self.ports.get_mut(&port) else {
            self.unknown_inputs += 1;
            return;
        };
        let mut po = self.port_scratch.pop().unwrap_or_default();
        f(&mut p, now, &mut po);
        drop(p);
        self.port_outs(now, port, po, out);
    }

    /// Runs `f` on `link` with a scratch vector for what it writes and
    /// does, then carries that out (module `link`: [`LinkOut`]); `None`
    /// when the link is not up.
    fn with_link<T>(
        &mut self,
        now: u64,
        link: LinkId,
        out: &mut Outbox,
        f: impl FnOnce(&mut Link, &mut Vec<LinkOut>) -> T,
    ) -> Option<T> {
        let mut l = self.links.get_mut(&link)?;
        let mut lo = self.link_scratch.pop().unwrap_or_default();
        let done = f(&mut l, &mut lo);
        drop(l);
        self.link_outs(now, link, lo, out);
        Some(done)
    }

    /// [`Router::with_link`] for what may complete frames (bytes read, the
    /// silence hook): what the link received is routed after its outputs.
    /// Whether the link is up.
    fn with_link_receiving(
        &mut self,
        now: u64,
        link: LinkId,
        out: &mut Outbox,
        f: impl FnOnce(&mut Link, &mut Vec<LinkOut>, &mut Vec<Received>),
    ) -> bool {
        let mut received = self.received_scratch.pop().unwrap_or_default();
        let up = self
            .with_link(now, link, out, |l, lo| f(l, lo, &mut received))
            .is_some();
        self.route_received(now, link, received, out);
        up
    }

    fn poll(&mut self, now: u64, out: &mut Outbox) {
        let mut expired = std::mem::take(&mut self.expired_scratch);
        self.reverse.expire(now, &mut expired);
        for id in expired.drain(..) {
            self.resolve(now, id, Err(Undelivered::NotConfirmed), self.group, out);
        }
        let overdue = self
            .in_flight
            .iter()
            .filter(|(_, c)| c.delivery.and_then(Delivery::deadline).is_some_and(|t| now >= t))
            .map(|(&id, _)| id);
        expired.extend(overdue);
        for id in expired.drain(..) {
            self.deliver_overdue(now, id, out);
        }
        self.expired_scratch = expired;
        self.stop_expired_leases(now, out);
        // The next due port or link after the last one polled: found afresh
        // each time (polling one may change the others), from the index of
        // their deadlines.
        let mut after = None;
        while let Some(port) = self.ports.next_due(now, after) {
            self.with_port(now, port, out, |p, now, po| p.poll(now, po));
            after = Some(port);
        }
        let mut after = None;
        while let Some(link) = self.links.next_due(now, after) {
            after = Some(link);
            self.with_link_receiving(now, link, out, |l, lo, received| l.poll(now, lo, received));
        }
        // Last: what the ports and links just ended is known to it.
        self.govern_poll(now, out);
        if self.waiting_deadline().is_some_and(|t| t <= now) {
            self.decide_waiting(now, out);
        }
    }

    fn drop_frame(&mut self, reason: DropReason, at: Place, dest: Address, source: u8, out: &mut Outbox) {
        self.stats.frame_drops.add(reason);
        out.push(Action::Event(RouterEvent::Dropped {
            reason,
            at,
            dest,
            source,
        }));
    }

    fn port_outs(&mut self, now: u64, port: u8, mut outs: Vec<PortOut>, out: &mut Outbox) {
        for o in outs.drain(..) {
            match o {
                PortOut::Write(wire) => out.write(LineId::Port(port), &wire),
                PortOut::SetRate(bps) => {
                    self.governor.port_rate(port, bps);
                    out.push(Action::SetPortRate { port, bps });
                }
                PortOut::Event(e) => {
                    if let RouterEvent::Started { id, .. } = e {
                        self.governor.started(now, port, id);
                    }
                    out.push(Action::Event(e));
                }
                PortOut::Relay { id, origin, reply } => {
                    self.govern_result(now, id, port, &reply);
                    self.relay_result(now, port, id, origin, reply, out);
                }
                PortOut::Delivered { id } => self.job_delivered(now, port, id, out),
                PortOut::Undelivered { id, failure } => {
                    if let Some(p) = self.jobs_of(id) {
                        p.failure = Some(failure);
                    }
                }
                PortOut::Finished { id, outcome, .. } => self.job_finished(now, port, id, outcome, out),
            }
        }
        if self.port_scratch.len() < SCRATCH_KEPT {
            self.port_scratch.push(outs);
        }
    }

    fn link_outs(&mut self, now: u64, link: LinkId, mut outs: Vec<LinkOut>, out: &mut Outbox) {
        for o in outs.drain(..) {
            match o {
                LinkOut::Write(wire) => out.write(LineId::Link(link), &wire),
                LinkOut::FirstSent(key) => self.reverse.sent(key, now, &self.in_force),
                LinkOut::Resent(key) => self.reverse.resent(key),
                LinkOut::Failed(item, reason) => self.dropped_on_link(now, link, &item, reason, out),
            }
        }
        if self.link_scratch.len() < SCRATCH_KEPT {
            self.link_scratch.push(outs);
        }
    }

    /// Queues a frame that is no forwarded command (an answer, a report)
    /// on `link`.
    fn send_on_link(&mut self, now: u64, link: LinkId, frame: FrameBuf, out: &mut Outbox) -> Result<(), DropReason> {
        let item = Outgoing {
            frame,
            pending: None,
            stop: false,
            dead_man: false,
        };
        self.enqueue_on_link(now, link, item, out)
    }

    /// Queues `item` on `link`.
    fn enqueue_on_link(&mut self, now: u64, link: LinkId, item: Outgoing, out: &mut Outbox) -> Result<(), DropReason> {
        self.with_link(now, link, out, |l, lo| l.enqueue(now, item, lo))
            .unwrap_or(Err(DropReason::LinkDown))
    }

    /// Writes a bare `?` to the origin (ARCHITECTURE "Routing semantics": a NIC is relayed as a bare `?`).
    fn nic_to(&mut self, now: u64, origin: Origin, out: &mut Outbox) -> Result<(), DropReason> {
        let Origin::Link { link, .. } = origin else {
            return Ok(());
        };
        self.with_link(now, link, out, |l, lo| l.write_nic(lo))
            .ok_or(DropReason::OriginGone)
    }

    /// Writes a bare ACK on `link`.
    fn ack(&mut self, now: u64, link: LinkId, out: &mut Outbox) {
        self.with_link(now, link, out, |l, lo| l.ack(lo));
    }
}

/// The keys after `after` (all of them for `None`): a cursor over a map
/// that is walked while it may change, without collecting its keys.
fn after_key<K: Copy>(after: Option<K>) -> (Bound<K>, Bound<K>) {
    (after.map_or(Bound::Unbounded, Bound::Excluded), Bound::Unbounded)
}

impl Deadline for Port {
    fn next_deadline(&self) -> Option<u64> {
        Port::next_deadline(self)
    }
}

impl Deadline for Link {
    fn next_deadline(&self) -> Option<u64> {
        Link::next_deadline(self)
    }
}
