//! The [`Router`]: one GCU of group G, as pure logic. It ties together the
//! links (module `link`), the port schedulers (module `port`), the
//! routing table (module `routing`), the reverse path of forwarded frames
//! (module `reverse`), the dead-man (module `deadman`) and the GCU's own
//! answers (module `local`). See the crate documentation for the rules.

use std::collections::BTreeMap;
use std::ops::Bound;

use sagebrush_protocol::{
    Address, CONTROL_UNIT, Command, DeliveryReport, Frame, FrameBuf, LINK_PORT, Undelivered, WILDCARD,
};

use crate::by_id::ById;
use crate::config::{ConfigError, LinkKind, LinkSettings, PortConfig, RouterConfig};
use crate::deadman::{DeadMan, OwnedStop};
use crate::link::{Link, LinkOut, Outgoing, Received};
use crate::local::{SelfAnswer, answer};
use crate::outbox::Outbox;
use crate::port::{CommandFacts, Job, Port, PortOut};
use crate::reverse::{AnswerMatch, Forwarded, ReversePath};
use crate::routing::RoutingTable;
use crate::stats::{LinkStats, RouterStats, Stats};
use crate::types::{Action, CommandId, CommandOutcome, DropReason, Input, LinkId, Origin, Place, RouterEvent};

/// Progress of one accepted command executed on local ports (one job per
/// port; a port-255 command has one per configured port).
#[derive(Debug)]
struct Progress {
    remaining: usize,
    results: usize,
    nics: usize,
    completed: usize,
    no_result: usize,
    unreachable: usize,
    /// Why a result or `?` could not be handed to the origin, or a job was dropped.
    dropped: Option<DropReason>,
    /// Why a job's device did not acknowledge it.
    failure: Option<Undelivered>,
}

impl Progress {
    fn new(jobs: usize) -> Self {
        Self {
            remaining: jobs,
            results: 0,
            nics: 0,
            completed: 0,
            no_result: 0,
            unreachable: 0,
            dropped: None,
            failure: None,
        }
    }

    /// The one outcome of all jobs: any result relayed wins; then a NIC when
    /// nothing completed (one `?` is relayed); then completed, no result,
    /// unreachable, dropped.
    fn outcome(&self) -> CommandOutcome {
        if self.results > 0 {
            CommandOutcome::Result
        } else if self.nics > 0 && self.completed == 0 {
            CommandOutcome::Nic
        } else if self.completed > 0 {
            CommandOutcome::Completed
        } else if self.no_result > 0 {
            CommandOutcome::NoResult
        } else if self.unreachable > 0 {
            CommandOutcome::Unreachable
        } else {
            CommandOutcome::Dropped(self.dropped.unwrap_or(DropReason::UnknownPort))
        }
    }

    /// Whether the jobs' outcome means the command reached a device.
    fn delivery(&self, outcome: CommandOutcome) -> Result<(), Undelivered> {
        match outcome {
            CommandOutcome::Result
            | CommandOutcome::Nic
            | CommandOutcome::Completed
            | CommandOutcome::NoResult
            | CommandOutcome::Forwarded(_) => Ok(()),
            CommandOutcome::Unreachable => Err(self.failure.unwrap_or(Undelivered::DeviceSilent)),
            CommandOutcome::Dropped(reason) => Err(reason.undelivered()),
        }
    }
}

/// One command in flight, from its acceptance until it finished and its
/// origin was told whether it was delivered: everything the router keeps
/// about it, under its id.
#[derive(Debug)]
struct InFlight {
    origin: Origin,
    /// The command frame as accepted (a report names its checksum; a
    /// client's retransmission is byte-identical).
    frame: FrameBuf,
    command: &'static str,
    /// Its origin link has not yet been told whether it was delivered
    /// (ARCHITECTURE "Delivery contract").
    delivery: Option<Delivery>,
    /// Executed on local ports: its jobs, until they all ended.
    jobs: Option<Progress>,
    /// A stop the GCU issued itself: the link whose motion it ends, and
    /// which round of sending it this is (module-level `DEAD_MAN_ROUNDS`).
    dead_man: Option<(LinkId, u8)>,
    /// Its [`RouterEvent::Finished`] was sent.
    finished: bool,
}

impl InFlight {
    /// Nothing is left to do or tell about it.
    fn done(&self) -> bool {
        self.finished && self.delivery.is_none()
    }
}

/// What the origin link of a command in flight awaits.
#[derive(Clone, Copy, Debug)]
struct Delivery {
    /// A client link: the answer is the withheld ACK, or a report when
    /// undelivered; a link to another GCU gets a report either way.
    client: bool,
    /// When a client must be told at the latest (`delivery_timeout`).
    deadline: Option<u64>,
}

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
    ports: BTreeMap<u8, Port>,
    links: BTreeMap<LinkId, Link>,
    routes: RoutingTable,
    reverse: ReversePath,
    deadman: DeadMan,
    /// Commands in flight, by id.
    in_flight: ById<InFlight>,
    /// [`Input::Shutdown`] came: new commands are refused.
    stopping: bool,
    /// New configurations of ports that are closing (reconfigured).
    replacements: BTreeMap<u8, PortConfig>,
    next_id: u64,
    /// Emptied scratch vectors of port and link outputs, reused so that
    /// routing a frame does not allocate them anew (a few: calls nest).
    port_scratch: Vec<Vec<PortOut>>,
    link_scratch: Vec<Vec<LinkOut>>,
    received_scratch: Vec<Vec<Received>>,
    last_now: u64,
    stats: RouterStats,
    unknown_inputs: u64,
}

/// Why the GCU stops a motion it did not get a stop for.
#[derive(Clone, Copy, Debug)]
enum StopCause {
    /// Its link went down, or its port is closing.
    DeadMan,
    /// The daemon shuts down.
    Shutdown,
    /// Its link's motion lease ran out.
    Lease,
}

/// Rounds of a dead-man stop (each with the port's retries) before the
/// router gives up on a device that never acknowledges it.
const DEAD_MAN_ROUNDS: u8 = 5;

/// Scratch vectors kept for reuse, per kind (calls nest a few deep).
const SCRATCH_KEPT: usize = 4;

impl Router {
    /// A router for `config`; ports start closed until [`Input::PortOpened`].
    pub fn new(config: RouterConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            group: config.group,
            ports: config.ports.iter().map(|p| (p.id, Port::new(p))).collect(),
            links: BTreeMap::new(),
            routes: RoutingTable::new(config.static_routes, config.default_upstream),
            reverse: ReversePath::new(
                config.links.max_pending,
                (u64::from(config.links.retries) + 1) * config.links.ack_timeout,
            ),
            deadman: DeadMan::default(),
            in_flight: ById::new(),
            stopping: false,
            replacements: BTreeMap::new(),
            next_id: 0,
            port_scratch: Vec::new(),
            link_scratch: Vec::new(),
            received_scratch: Vec::new(),
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
            Input::PortBytes { port, bytes } => self.with_port(now, port, out, |p, now, po| p.receive(now, bytes, po)),
            Input::LinkUp { link, config } => {
                if self.links.contains_key(&link) {
                    self.link_down(now, link, out);
                }
                let stats = LinkStats::new(config.kind);
                if let Some(listener) = config.listener {
                    self.routes.accepted(listener, link);
                }
                self.links.insert(link, Link::new(config, &self.settings, stats));
                out.push(Action::Event(RouterEvent::LinkState { link, up: true }));
            }
            Input::LinkDown { link } => self.link_down(now, link, out),
            Input::Shutdown => self.shut_down(now, out),
            Input::LinkBytes { link, bytes } => match self.links.get_mut(&link) {
                Some(l) => {
                    let mut lo = self.link_scratch.pop().unwrap_or_default();
                    let mut received = self.received_scratch.pop().unwrap_or_default();
                    l.receive(now, bytes, &mut lo, &mut received);
                    self.link_outs(now, link, lo, out);
                    self.route_received(now, link, received, out);
                }
                None => self.unknown_inputs += 1,
            },
        }
        self.poll(now, out);
    }

    fn port_state(&self, port: u8, open: bool, out: &mut Outbox) {
        if self.ports.contains_key(&port) {
            out.push(Action::Event(RouterEvent::PortState { port, open }));
        }
    }

    /// [`Router::handle`] into a fresh [`Outbox`] (tests; a daemon keeps one).
    pub fn handle_once(&mut self, now: u64, input: Input<'_>) -> Outbox {
        let mut out = Outbox::new();
        self.handle(now, input, &mut out);
        out
    }

    /// When the router next needs [`Input::Tick`], if anything is pending.
    pub fn next_deadline(&self) -> Option<u64> {
        let ports = self.ports.values().filter_map(Port::next_deadline);
        let links = self.links.values().filter_map(Link::next_deadline);
        ports
            .chain(links)
            .chain(self.reverse.next_deadline())
            .chain(self.deadman.next_deadline())
            .chain(self.in_flight.values().filter_map(|c| c.delivery?.deadline))
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

    /// Applies a changed configuration (ARCHITECTURE "Safety": a port is closed
    /// or reconfigured only after its motions were stopped). Routes are
    /// replaced at once; a new port is added (closed until
    /// [`Input::PortOpened`]); a removed or changed port starts closing:
    /// it takes no new commands (refused as shutting down), every motion
    /// owned on it gets its stop, and once it is idle
    /// ([`Router::closed_ports`]) the daemon closes it and calls
    /// [`Router::port_closed`], which installs the changed port's new
    /// configuration. `reopen`: ports whose I/O the daemon changes (a
    /// new device path, say) although their router configuration is the
    /// same; they close and come back too. Other ports whose configuration
    /// did not change are not touched. The group, name, serial and link
    /// settings cannot change.
    pub fn reconfigure(
        &mut self,
        now: u64,
        config: RouterConfig,
        reopen: &[u8],
        out: &mut Outbox,
    ) -> Result<(), ConfigError> {
        config.validate()?;
        if config.group != self.group {
            return Err(ConfigError::NotReloadable("the group"));
        }
        if config.name != self.name || config.serial != self.serial {
            return Err(ConfigError::NotReloadable("the name or serial"));
        }
        if config.links != self.settings {
            return Err(ConfigError::NotReloadable("the link settings"));
        }
        self.in_force = self.settings.with_answer_time_for(&config.ports);
        self.routes
            .set_configured(config.static_routes, config.default_upstream);
        for (&id, port) in &mut self.ports {
            let same = config.ports.iter().any(|p| p.id == id && *p == port.config);
            port.closing = !same || reopen.contains(&id);
        }
        self.replacements = config
            .ports
            .into_iter()
            .filter(|p| self.ports.get(&p.id).is_none_or(|old| old.closing))
            .map(|p| (p.id, p))
            .collect();
        let added: Vec<u8> = self
            .replacements
            .keys()
            .copied()
            .filter(|id| !self.ports.contains_key(id))
            .collect();
        for id in added {
            if let Some(p) = self.replacements.remove(&id) {
                self.ports.insert(id, Port::new(&p));
            }
        }
        let closing: Vec<u8> = self
            .ports
            .iter()
            .filter(|(_, p)| p.closing)
            .map(|(&id, _)| id)
            .collect();
        for port in closing {
            let stops = self.deadman.take_port(port);
            self.stop_motions(now, stops, StopCause::DeadMan, out);
        }
        self.poll(now, out);
        Ok(())
    }

    /// Ports that are closing and idle: the daemon may close them now.
    pub fn closed_ports(&self) -> Vec<u8> {
        self.ports
            .iter()
            .filter(|(_, p)| p.closing && p.is_idle())
            .map(|(&id, _)| id)
            .collect()
    }

    /// Whether `port` is configured (and not closing).
    pub fn has_port(&self, port: u8) -> bool {
        self.ports.get(&port).is_some_and(|p| !p.closing)
    }

    /// The daemon closed a closing port (idle, or its grace ran out: what
    /// is left on it fails as [`DropReason::PortLost`]). A changed port
    /// comes back with its new configuration, closed until opened.
    pub fn port_closed(&mut self, now: u64, port: u8, out: &mut Outbox) {
        if !self.ports.get(&port).is_some_and(|p| p.closing) {
            return;
        }
        self.with_port(now, port, out, |p, _, po| p.lose(po));
        self.ports.remove(&port);
        if let Some(config) = self.replacements.remove(&port) {
            self.ports.insert(port, Port::new(&config));
        }
    }

    fn with_port(&mut self, now: u64, port: u8, out: &mut Outbox, f: impl FnOnce(&mut Port, u64, &mut Vec<PortOut>)) {
        let Some(p) = self.ports.get_mut(&port) else {
            self.unknown_inputs += 1;
            return;
        };
        let mut po = self.port_scratch.pop().unwrap_or_default();
        f(p, now, &mut po);
        self.port_outs(now, port, po, out);
    }

    fn poll(&mut self, now: u64, out: &mut Outbox) {
        for (id, failure) in self.reverse.expire(now) {
            self.resolve(now, id, Err(failure), self.group, out);
        }
        let overdue: Vec<CommandId> = self
            .in_flight
            .iter()
            .filter(|(_, c)| c.delivery.and_then(|d| d.deadline).is_some_and(|t| now >= t))
            .map(|(&id, _)| id)
            .collect();
        for id in overdue {
            self.deliver_overdue(now, id, out);
        }
        let expired = self.deadman.expired(now);
        self.stop_motions(now, expired, StopCause::Lease, out);
        let due = |d: Option<u64>| d.is_some_and(|t| t <= now);
        // The next due port or link after the last one polled: found afresh
        // each time (polling one may change the others), with no list.
        let mut after = None;
        while let Some(port) = self
            .ports
            .range(after_key(after))
            .find(|(_, p)| due(p.next_deadline()))
            .map(|(&id, _)| id)
        {
            self.with_port(now, port, out, |p, now, po| p.poll(now, po));
            after = Some(port);
        }
        let mut after = None;
        while let Some(link) = self
            .links
            .range(after_key(after))
            .find(|(_, l)| due(l.next_deadline()))
            .map(|(&id, _)| id)
        {
            after = Some(link);
            let Some(l) = self.links.get_mut(&link) else { continue };
            let mut lo = self.link_scratch.pop().unwrap_or_default();
            let mut received = self.received_scratch.pop().unwrap_or_default();
            l.poll(now, &mut lo, &mut received);
            self.link_outs(now, link, lo, out);
            self.route_received(now, link, received, out);
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
                PortOut::Write(wire) => out.write_port(port, &wire),
                PortOut::SetRate(bps) => out.push(Action::SetPortRate { port, bps }),
                PortOut::Event(e) => out.push(Action::Event(e)),
                PortOut::Relay { id, origin, reply } => self.relay_result(now, port, id, origin, reply, out),
                PortOut::Delivered { id } => self.resolve(now, id, Ok(()), self.group, out),
                PortOut::Undelivered { id, failure } => {
                    if let Some(p) = self.jobs_of(id) {
                        p.failure = Some(failure);
                    }
                }
                PortOut::Finished { id, outcome, .. } => self.job_finished(now, id, outcome, out),
            }
        }
        if self.port_scratch.len() < SCRATCH_KEPT {
            self.port_scratch.push(outs);
        }
    }

    fn link_outs(&mut self, now: u64, link: LinkId, mut outs: Vec<LinkOut>, out: &mut Outbox) {
        for o in outs.drain(..) {
            match o {
                LinkOut::Write(wire) => out.write_link(link, &wire),
                LinkOut::FirstSent(key) => self.reverse.sent(key, now, &self.in_force),
                LinkOut::Resent(key) => self.reverse.resent(key),
                LinkOut::Failed(item, reason) => self.dropped_on_link(now, link, &item, reason, out),
            }
        }
        if self.link_scratch.len() < SCRATCH_KEPT {
            self.link_scratch.push(outs);
        }
    }

    /// A frame `link` dropped (it went down, or gave up on the frame): a
    /// forwarded command's origin is told, once. Transmitted, the next GCU
    /// may have it and execute it: not confirmed.
    fn dropped_on_link(&mut self, now: u64, link: LinkId, item: &Outgoing, reason: DropReason, out: &mut Outbox) {
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

    /// Forwards `frame` on `link` with a reverse-path entry: `back` is where
    /// its answers go back to (its origin) and the command whose delivery
    /// the next GCU's report decides, if any. A full reverse path forgets an
    /// entry first; a command it still owed a report is not confirmed.
    fn forward(
        &mut self,
        now: u64,
        link: LinkId,
        frame: &FrameBuf,
        forwarded: Forwarded,
        back: (Origin, Option<CommandId>),
        out: &mut Outbox,
    ) -> Result<(), DropReason> {
        let (origin, settles) = back;
        let f = frame.frame();
        let (key, evicted) = self.reverse.insert(link, origin, &f, forwarded, settles);
        if let Some(unreported) = evicted {
            self.drop_frame(DropReason::PendingFull, Place::Router, f.dest, f.source, out);
            if let Some(old) = unreported {
                self.resolve(now, old, Err(Undelivered::NotConfirmed), self.group, out);
            }
        }
        let sent = self.send_on_link(now, link, frame.clone(), Some(key), origin == Origin::Internal, out);
        if sent.is_err() {
            self.reverse.cancel(key);
        }
        sent
    }

    /// Queues `frame` on `link`.
    fn send_on_link(
        &mut self,
        now: u64,
        link: LinkId,
        frame: FrameBuf,
        pending: Option<u64>,
        dead_man: bool,
        out: &mut Outbox,
    ) -> Result<(), DropReason> {
        let Some(l) = self.links.get_mut(&link) else {
            return Err(DropReason::LinkDown);
        };
        // Only forwarded commands carry a reverse-path entry; their stops go first.
        let stop = pending.is_some() && Command::parse(frame.frame().payload()).is_stop();
        let mut lo = self.link_scratch.pop().unwrap_or_default();
        let queued = l.enqueue(
            now,
            Outgoing {
                frame,
                pending,
                stop,
                dead_man,
            },
            &mut lo,
        );
        self.link_outs(now, link, lo, out);
        queued
    }

    /// Writes a bare `?` to the origin (ARCHITECTURE "Routing semantics": a NIC is relayed as a bare `?`).
    fn nic_to(&mut self, now: u64, origin: Origin, out: &mut Outbox) -> Result<(), DropReason> {
        let Origin::Link { link, .. } = origin else {
            return Ok(());
        };
        let Some(l) = self.links.get_mut(&link) else {
            return Err(DropReason::OriginGone);
        };
        let mut lo = self.link_scratch.pop().unwrap_or_default();
        l.write_nic(&mut lo);
        self.link_outs(now, link, lo, out);
        Ok(())
    }

    /// Tells the origin of command `id` whether it was delivered, once
    /// (ARCHITECTURE "Delivery contract"): a client gets the ACK it was
    /// waiting for, or a delivery report instead; a link to another GCU
    /// (whose frame was ACKed hop by hop) gets a report either way.
    /// `at_group`: the GCU where delivery failed.
    fn resolve(&mut self, now: u64, id: CommandId, delivery: Result<(), Undelivered>, at_group: u8, out: &mut Outbox) {
        let Some(c) = self.in_flight.get_mut(&id) else { return };
        // Only a link's command awaits its delivery outcome.
        let (Some(awaited), Origin::Link { link, .. }) = (c.delivery.take(), c.origin) else {
            return;
        };
        let (frame, command) = (c.frame.clone(), c.command);
        if c.done() {
            self.in_flight.remove(&id);
        }
        let f = frame.frame();
        match delivery {
            Ok(()) => {
                self.stats.delivered += 1;
                out.push(Action::Event(RouterEvent::Delivered { id }));
            }
            Err(failure) => {
                self.stats.undelivered.add(failure);
                out.push(Action::Event(RouterEvent::Undelivered {
                    id,
                    origin: Origin::Link { link, source: f.source },
                    dest: f.dest,
                    command,
                    failure,
                }));
            }
        }
        if awaited.client && delivery.is_ok() {
            return self.ack(now, link, out);
        }
        self.report(now, link, &f, delivery.err(), at_group, out);
    }

    /// A client's delivery time-out passed: jobs still queued are given up
    /// unsent (expired); one on the bus, or a forward, may still be
    /// delivered, which the client is told (not confirmed). A late ACK
    /// is never written: the client may be waiting for its next command's.
    fn deliver_overdue(&mut self, now: u64, id: CommandId, out: &mut Outbox) {
        let mut cancelled = false;
        let ports: Vec<u8> = self.ports.keys().copied().collect();
        for port in ports {
            let mut po = self.port_scratch.pop().unwrap_or_default();
            if let Some(p) = self.ports.get_mut(&port) {
                cancelled |= p.cancel_queued(id, DropReason::Expired, &mut po);
            }
            self.port_outs(now, port, po, out);
        }
        let still_running = self.jobs_of(id).is_some() || !cancelled;
        let failure = match still_running {
            true => Undelivered::NotConfirmed,
            false => Undelivered::Expired,
        };
        self.resolve(now, id, Err(failure), self.group, out);
    }

    /// Queues a delivery report about `command` on `link`.
    fn report(
        &mut self,
        now: u64,
        link: LinkId,
        command: &Frame<'_>,
        failure: Option<Undelivered>,
        at_group: u8,
        out: &mut Outbox,
    ) {
        let report = DeliveryReport {
            failure,
            dest: command.dest,
            command_checksum: command.checksum(),
            at_group,
        };
        let to = Address::new(command.source, LINK_PORT, CONTROL_UNIT);
        if let Ok(frame) = FrameBuf::new(to, self.group, &report.encode()) {
            if let Err(reason) = self.send_on_link(now, link, frame, None, false, out) {
                self.drop_frame(reason, Place::Link(link), to, self.group, out);
            }
        }
    }

    fn next_command_id(&mut self) -> CommandId {
        let id = CommandId(self.next_id);
        self.next_id += 1;
        id
    }

    /// Command `id` ended (its one [`RouterEvent::Finished`]); its record
    /// stays while its origin still awaits the delivery outcome.
    fn finish(&mut self, id: CommandId, outcome: CommandOutcome, out: &mut Outbox) {
        if let Some(c) = self.in_flight.get_mut(&id) {
            c.finished = true;
            c.dead_man = None;
            if c.done() {
                self.in_flight.remove(&id);
            }
        }
        self.stats.count(outcome);
        out.push(Action::Event(RouterEvent::Finished { id, outcome }));
    }

    /// A result of job `id` from `port`: back to the origin with the Table 3
    /// header (destination group = the command's source group, port and
    /// device as answered, source group = G, checksum recomputed).
    fn relay_result(
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
        let sent = match self.links.contains_key(&link) {
            true => self.send_on_link(now, link, reply, None, false, out),
            false => Err(DropReason::OriginGone),
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

    fn job_finished(&mut self, now: u64, id: CommandId, outcome: CommandOutcome, out: &mut Outbox) {
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
        let (origin, dead_man) = (c.origin, c.dead_man);
        let mut outcome = p.outcome();
        self.resolve(now, id, p.delivery(outcome), self.group, out);
        if outcome == CommandOutcome::Nic {
            if let Err(reason) = self.nic_to(now, origin, out) {
                outcome = CommandOutcome::Dropped(reason);
            }
        }
        // A safety stop that no device acknowledged is sent again: the
        // motion it ends goes on until one does.
        let again = match dead_man {
            Some((link, round)) if outcome == CommandOutcome::Unreachable && round < DEAD_MAN_ROUNDS => self
                .in_flight
                .get_mut(&id)
                .map(|c| (c.frame.clone(), c.command, link, round + 1)),
            _ => None,
        };
        self.finish(id, outcome, out);
        if let Some((frame, stop, link, round)) = again {
            let dest = frame.frame().dest;
            out.push(Action::Event(RouterEvent::DeadManStop { link, dest, stop }));
            self.dispatch(now, Origin::Internal, None, frame, Some((link, round)), out);
        }
    }

    /// The jobs of command `id` on local ports, while they run.
    fn jobs_of(&mut self, id: CommandId) -> Option<&mut Progress> {
        self.in_flight.get_mut(&id)?.jobs.as_mut()
    }

    /// Routes what a link received; the vector goes back to the scratch pool.
    fn route_received(&mut self, now: u64, link: LinkId, mut received: Vec<Received>, out: &mut Outbox) {
        for r in received.drain(..) {
            self.on_received(now, link, r, out);
        }
        if self.received_scratch.len() < SCRATCH_KEPT {
            self.received_scratch.push(received);
        }
    }

    fn on_received(&mut self, now: u64, link: LinkId, received: Received, out: &mut Outbox) {
        match received {
            Received::Frame(frame) => self.on_link_frame(now, link, frame, out),
            // A client answers no command: its `?` is a byte in the wrong
            // direction, counted as stray, not a dropped frame.
            Received::Nic if self.links.get(&link).is_some_and(|l| l.config.kind == LinkKind::Client) => {
                if let Some(l) = self.links.get_mut(&link) {
                    l.stats.line.stray_bytes += 1;
                }
            }
            Received::Nic => match self.reverse.match_nic(link) {
                AnswerMatch::One(origin) => {
                    if self.nic_to(now, origin, out).is_err() {
                        self.drop_frame(DropReason::OriginGone, Place::Link(link), Address::new(0, 0, 0), 0, out);
                    }
                }
                AnswerMatch::None => self.drop_frame(
                    DropReason::Unsolicited,
                    Place::Link(link),
                    Address::new(0, 0, 0),
                    0,
                    out,
                ),
                AnswerMatch::Ambiguous => self.drop_frame(
                    DropReason::AmbiguousAnswer,
                    Place::Link(link),
                    Address::new(0, 0, 0),
                    0,
                    out,
                ),
            },
        }
    }

    /// A frame from a link. ARCHITECTURE "Delivery contract": answers
    /// (results, delivery reports) and every frame of a link to another GCU
    /// are ACKed at once, hop by hop; a client's command is ACKed only once
    /// it is delivered (a repeat of it meanwhile is its retransmission, not
    /// a new command), or answered with a report instead.
    fn on_link_frame(&mut self, now: u64, link: LinkId, frame: FrameBuf, out: &mut Outbox) {
        let Some(l) = self.links.get_mut(&link) else { return };
        let kind = l.config.kind;
        let client = kind == LinkKind::Client;
        let f = frame.frame();
        let (dest, source) = (f.dest, f.source);
        // A client acts for this GCU and may speak as its group (Figure 7: a
        // command issued from GCU-2, answered with destination group 2); a
        // link to another GCU never may (a loop or a spoof).
        let own_group = source == self.group && !client;
        if source == WILDCARD || own_group || !l.config.allowed_sources.allows(source) {
            l.stats.line.drops.add(DropReason::SourceNotAllowed);
            if !client {
                self.ack(now, link, out);
            }
            self.drop_frame(DropReason::SourceNotAllowed, Place::Link(link), dest, source, out);
            if source != WILDCARD {
                self.stats.undelivered.add(Undelivered::SourceNotAllowed);
                self.report(now, link, &f, Some(Undelivered::SourceNotAllowed), self.group, out);
            }
            return;
        }
        // A report from another GCU is never a command (a report about a
        // report would bounce between two GCUs forever) nor a result (an
        // extended command's result may look like anything): it settles
        // what it fits, or is dropped.
        let report = (!client && dest.port == LINK_PORT && dest.device == CONTROL_UNIT)
            .then(|| DeliveryReport::parse(f.payload()).ok())
            .flatten();
        if let Some(report) = report {
            self.ack(now, link, out);
            match self.reverse.match_report(link, dest.group, &report) {
                Some(Some(id)) => self.resolve(now, id, report.failure.map_or(Ok(()), Err), report.at_group, out),
                Some(None) => {}
                None => self.drop_frame(DropReason::Unsolicited, Place::Link(link), dest, source, out),
            }
            return;
        }
        let repeats = self.links.get(&link).is_some_and(|l| !l.config.lossless);
        match self.reverse.match_result(now, link, &f, repeats) {
            AnswerMatch::One(origin) => {
                self.ack(now, link, out);
                return self.relay_forwarded(now, link, origin, frame, out);
            }
            AnswerMatch::Ambiguous => {
                self.ack(now, link, out);
                return self.drop_frame(DropReason::AmbiguousAnswer, Place::Link(link), dest, source, out);
            }
            AnswerMatch::None => {}
        }
        if client {
            let repeat = self
                .in_flight
                .values()
                .any(|c| c.delivery.is_some() && c.origin.link() == Some(link) && c.frame == frame)
                || self.report_on_its_way(link, &f);
            if repeat {
                if let Some(l) = self.links.get_mut(&link) {
                    l.stats.repeats += 1;
                }
                return;
            }
        } else {
            self.ack(now, link, out);
        }
        self.routes.learn(source, link, kind);
        self.dispatch(now, Origin::Link { link, source }, Some(kind), frame, None, out);
    }

    /// Whether the report about `command` is still unacknowledged on the
    /// client `link`: the client has no outcome yet, so an identical frame is
    /// its retransmission (ARCHITECTURE "Delivery contract": a repeat gets
    /// the original's outcome), not a new command. Its ACK followed by the
    /// report's next copy would be two outcomes to the client.
    fn report_on_its_way(&self, link: LinkId, command: &Frame<'_>) -> bool {
        let Some(l) = self.links.get(&link) else { return false };
        l.unacknowledged().any(|queued| {
            let f = queued.frame();
            f.dest == Address::new(command.source, LINK_PORT, CONTROL_UNIT)
                && DeliveryReport::parse(f.payload())
                    .is_ok_and(|r| r.dest == command.dest && r.command_checksum == command.checksum())
        })
    }

    /// Writes a bare ACK on `link`.
    fn ack(&mut self, now: u64, link: LinkId, out: &mut Outbox) {
        if let Some(l) = self.links.get_mut(&link) {
            let mut lo = self.link_scratch.pop().unwrap_or_default();
            l.ack(&mut lo);
            self.link_outs(now, link, lo, out);
        }
    }

    /// An answer from another GCU to a frame we forwarded: back to its origin, unchanged.
    fn relay_forwarded(&mut self, now: u64, from: LinkId, origin: Origin, frame: FrameBuf, out: &mut Outbox) {
        let Origin::Link { link, .. } = origin else { return };
        let f = frame.frame();
        let (dest, source) = (f.dest, f.source);
        let sent = match self.links.contains_key(&link) {
            true => self.send_on_link(now, link, frame, None, false, out),
            false => Err(DropReason::OriginGone),
        };
        match sent {
            Ok(()) => self.stats.results_relayed += 1,
            Err(reason) => self.drop_frame(reason, Place::Link(from), dest, source, out),
        }
    }

    /// A command frame accepted from `origin` (a link of `kind`, or the
    /// router itself): gives it the next command id and returns it. A stop
    /// the GCU issued itself is registered under that id before routing,
    /// since the command may end inside this call.
    fn dispatch(
        &mut self,
        now: u64,
        origin: Origin,
        kind: Option<LinkKind>,
        frame: FrameBuf,
        dead_man: Option<(LinkId, u8)>,
        out: &mut Outbox,
    ) -> CommandId {
        let id = self.next_command_id();
        let client = kind == Some(LinkKind::Client);
        self.in_flight.insert(
            id,
            InFlight {
                origin,
                command: Command::parse(frame.frame().payload()).mnemonic(),
                frame: frame.clone(),
                delivery: origin.link().map(|_| Delivery {
                    client,
                    deadline: client.then(|| now.saturating_add(self.settings.delivery_timeout)),
                }),
                jobs: None,
                dead_man,
                finished: false,
            },
        );
        self.route_command(now, id, origin, kind, frame, out);
        id
    }

    /// Routes command `id`: locally, to a link, or dropped and reported.
    fn route_command(
        &mut self,
        now: u64,
        id: CommandId,
        origin: Origin,
        kind: Option<LinkKind>,
        frame: FrameBuf,
        out: &mut Outbox,
    ) {
        let f = frame.frame();
        let dest = f.dest;
        let command = Command::parse(f.payload());
        self.stats.accepted += 1;
        out.push(Action::Event(RouterEvent::Accepted {
            id,
            origin,
            dest,
            command: command.mnemonic(),
        }));
        if let Origin::Link { link, .. } = origin {
            if self.stopping {
                self.drop_frame(DropReason::ShuttingDown, Place::Router, dest, f.source, out);
                self.finish(id, CommandOutcome::Dropped(DropReason::ShuttingDown), out);
                return self.resolve(now, id, Err(Undelivered::ShuttingDown), self.group, out);
            }
            let lease = self.links.get(&link).and_then(|l| l.config.motion_lease);
            self.deadman.on_command(now, link, lease, dest, &command);
        }
        let facts = CommandFacts::of(&command);
        let forwarded = Forwarded {
            kind: facts.kind,
            stop: facts.stop,
        };
        if dest.group == self.group || dest.group == WILDCARD {
            if dest.group == WILDCARD && kind != Some(LinkKind::Downstream) {
                self.flood(now, origin, &frame, forwarded, out);
            }
            return self.execute_local(now, id, origin, frame, facts, out);
        }
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
        let outcome = match route.and_then(|next| {
            self.forward(now, next, &frame, forwarded, (origin, settles), out)
                .map(|()| next)
        }) {
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

    /// Group 255 from upstream (or a client, or the router itself) is
    /// copied to every downstream link, never back where it came from.
    fn flood(&mut self, now: u64, origin: Origin, frame: &FrameBuf, forwarded: Forwarded, out: &mut Outbox) {
        let targets: Vec<LinkId> = self
            .links
            .iter()
            .filter(|&(&id, l)| l.config.kind == LinkKind::Downstream && Some(id) != origin.link())
            .map(|(&id, _)| id)
            .collect();
        let f = frame.frame();
        for link in targets {
            match self.forward(now, link, frame, forwarded, (origin, None), out) {
                Ok(()) => self.stats.flooded += 1,
                Err(reason) => self.drop_frame(reason, Place::Link(link), f.dest, f.source, out),
            }
        }
    }

    /// Destination group G or 255: port 0 is the GCU itself, 1..=254 one
    /// port, 255 every port.
    fn execute_local(
        &mut self,
        now: u64,
        id: CommandId,
        origin: Origin,
        frame: FrameBuf,
        facts: CommandFacts,
        out: &mut Outbox,
    ) {
        let f = frame.frame();
        let dest = f.dest;
        // One port, or every port (a broadcast to port 255): counted first,
        // then each found afresh, with no list of targets.
        let one = match dest.port {
            LINK_PORT => {
                self.resolve(now, id, Ok(()), self.group, out);
                let outcome = match answer(self.group, &self.name, &self.serial, &f) {
                    SelfAnswer::Result(reply) => match origin {
                        Origin::Link { link, .. } => match self.send_on_link(now, link, *reply, None, false, out) {
                            Ok(()) => CommandOutcome::Result,
                            Err(_) => CommandOutcome::Dropped(DropReason::OriginGone),
                        },
                        Origin::Internal => CommandOutcome::Completed,
                    },
                    SelfAnswer::Nic => match self.nic_to(now, origin, out) {
                        Ok(()) => CommandOutcome::Nic,
                        Err(reason) => CommandOutcome::Dropped(reason),
                    },
                };
                return self.finish(id, outcome, out);
            }
            WILDCARD => None,
            port => Some(port),
        };
        let targets = match one {
            Some(port) => usize::from(self.ports.contains_key(&port)),
            None => self.ports.len(),
        };
        if targets == 0 {
            self.drop_frame(DropReason::UnknownPort, Place::Router, dest, f.source, out);
            self.resolve(now, id, Err(Undelivered::NoSuchPort), self.group, out);
            return self.finish(id, CommandOutcome::Dropped(DropReason::UnknownPort), out);
        }
        if let Some(c) = self.in_flight.get_mut(&id) {
            c.jobs = Some(Progress::new(targets));
        }
        let mut after = None;
        while let Some(port) = match one {
            Some(port) => (after.is_none()).then_some(port),
            None => self.ports.range(after_key(after)).next().map(|(&id, _)| id),
        } {
            let job = Job::new(id, origin, frame.clone(), facts);
            self.with_port(now, port, out, |p, now, po| p.enqueue(now, job, po));
            after = Some(port);
        }
    }

    /// A link went down: drop its queue, forget its routes, cancel the
    /// motions it queued and stop the motions it owns (dead-man).
    fn link_down(&mut self, now: u64, link: LinkId, out: &mut Outbox) {
        let Some(mut l) = self.links.remove(&link) else {
            self.unknown_inputs += 1;
            return;
        };
        for item in l.shut_down() {
            self.dropped_on_link(now, link, &item, DropReason::LinkDown, out);
        }
        out.push(Action::LinkGone {
            link,
            stats: Box::new(l.stats),
        });
        self.routes.forget(link);
        // Nobody is left to tell whether these were delivered.
        self.in_flight.retain(|_, c| {
            if c.origin.link() == Some(link) {
                c.delivery = None;
            }
            !c.done()
        });
        out.push(Action::Event(RouterEvent::LinkState { link, up: false }));
        let ports: Vec<u8> = self.ports.keys().copied().collect();
        for port in ports {
            self.with_port(now, port, out, |p, _, po| p.cancel_motions(link, po));
        }
        let stops = self.deadman.link_down(link);
        self.stop_motions(now, stops, StopCause::DeadMan, out);
    }

    /// Shutdown (ARCHITECTURE "Safety"): refuse new commands from now on, and
    /// stop every motion still owned by a link.
    fn shut_down(&mut self, now: u64, out: &mut Outbox) {
        if self.stopping {
            return;
        }
        self.stopping = true;
        let stops = self.deadman.take_all();
        self.stop_motions(now, stops, StopCause::Shutdown, out);
    }

    /// Stops motions the GCU takes back (each logged and counted by cause).
    fn stop_motions(&mut self, now: u64, stops: Vec<OwnedStop>, cause: StopCause, out: &mut Outbox) {
        for (link, dest, stop) in stops {
            let stop_name = stop.mnemonic();
            let event = match cause {
                StopCause::DeadMan => {
                    self.stats.dead_man_stops += 1;
                    RouterEvent::DeadManStop {
                        link,
                        dest,
                        stop: stop_name,
                    }
                }
                StopCause::Shutdown => {
                    self.stats.shutdown_stops += 1;
                    RouterEvent::DeadManStop {
                        link,
                        dest,
                        stop: stop_name,
                    }
                }
                StopCause::Lease => {
                    self.stats.lease_stops += 1;
                    RouterEvent::LeaseExpired {
                        link,
                        dest,
                        stop: stop_name,
                    }
                }
            };
            out.push(Action::Event(event));
            self.issue_stop(now, dest, stop, link, out);
        }
    }

    /// The first round of a stop the GCU issues itself (dead-man, lease,
    /// shutdown) for the motion `link` owned at `dest`; an unacknowledged
    /// one is sent again (module-level `DEAD_MAN_ROUNDS`).
    fn issue_stop(&mut self, now: u64, dest: Address, stop: Command<'static>, link: LinkId, out: &mut Outbox) {
        let Ok(frame) = FrameBuf::build(dest, self.group, |buf| stop.encode(buf).map(<[u8]>::len)) else {
            return;
        };
        self.dispatch(now, Origin::Internal, None, frame, Some((link, 1)), out);
    }
}

/// The keys after `after` (all of them for `None`): a cursor over a map
/// that is walked while it may change, without collecting its keys.
fn after_key<K: Copy>(after: Option<K>) -> (Bound<K>, Bound<K>) {
    (after.map_or(Bound::Unbounded, Bound::Excluded), Bound::Unbounded)
}
