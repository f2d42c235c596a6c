//! The network: GCUs with their routers, the event queue, the run phases
//! and the invariants. Buses and devices are in `devices`, clients in
//! `clients`, wires and delivery in `wires`.

use std::collections::{BTreeMap, BTreeSet};

use sagebrush_gcu::{
    Action, CommandId, Input, LineId, LinkConfig, LinkId, LinkKind, Outbox, PortConfig, Router, RouterConfig,
    RouterEvent, SourceFilter,
};
use sagebrush_protocol::{
    ACK, Address, AwakeStatus, Command, DeliveryReport, DeviceEndpoint, DeviceHandler, EndpointConfig, Extended,
    FrameBuf, Framer, Identity, InitResults, NAK, OwnedEvent, Position, Reply, ReplyTo, Response, ResultKind,
    RetryPolicy, Transmitter, TxStep, Undelivered, WILDCARD,
};

use super::Rng;

mod clients;
mod devices;
mod wires;

use clients::{Client, ClientState, ClientWire};
use devices::{Device, Gimbal, SimPort, motion_axis};

/// What a run did, summed over seeds (and compared for determinism):
/// `Summary` has a `u64` per counter below, which `add` adds, and the
/// latest end time. Declared as a list so that no counter is left out of
/// the sum.
macro_rules! summary {
    ($($(#[doc = $doc:literal])* $counter:ident,)+) => {
        #[derive(Clone, Debug, Default, PartialEq, Eq)]
        pub struct Summary {
            $($(#[doc = $doc])* pub $counter: u64,)+
            pub end_time: u64,
        }

        impl Summary {
            pub fn add(&mut self, o: &Summary) {
                $(self.$counter += o.$counter;)+
                self.end_time = self.end_time.max(o.end_time);
            }
        }
    };
}

summary! {
    accepted,
    results,
    nics,
    completed,
    no_result,
    unreachable,
    forwarded,
    dropped,
    dead_man_stops,
    rate_switches,
    retransmits,
    client_results,
    nonce_results,
    final_motions_checked,
    phantom_frames,
    /// Client commands the client saw ACKed (delivered).
    client_delivered,
    /// Client commands the client saw reported as not delivered.
    client_undelivered,
    /// Client commands the client gave up on (no ACK, no report in its budget).
    client_gave_up,
    /// Retransmissions of a client's command that the GCU recognised.
    client_repeats,
    /// ACKs a client took that were bytes of a damaged frame (its report came after).
    phantom_acks,
    /// Writes to clients that a wire damaged: the only excuse for a phantom.
    client_damaged_writes,
    /// ACKs a client took while its framer held damaged bytes: the most
    /// phantom ACKs there can be.
    tainted_acks,
    /// Fault: device servers that stopped reading for a while.
    stalls,
    /// Reports a client got again (its ACK of the first was lost).
    repeated_reports,
    /// Fault: device answers that left after the GCU gave up on them.
    late_answers,
}

// ---------------------------------------------------------------- GCUs, clients

#[derive(Debug, Default)]
struct Ledger {
    accepted: BTreeSet<CommandId>,
    finished: BTreeSet<CommandId>,
    /// Stops queued and not started, per port.
    pending_stops: BTreeMap<u8, BTreeSet<CommandId>>,
    /// Commands of links whose origin has not yet been told delivered or not.
    untold: BTreeMap<CommandId, LinkId>,
}

#[derive(Debug)]
struct Gcu {
    group: u8,
    router: Router,
    ports: Vec<SimPort>,
    ledger: Ledger,
}

#[derive(Debug)]
struct Pair {
    parent: (usize, LinkId),
    child: (usize, LinkId),
    up: bool,
    epoch: u64,
}

// ---------------------------------------------------------------- wires

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Node {
    Port { g: usize, p: usize },
    Device { g: usize, p: usize, d: usize },
    Link { g: usize, link: LinkId },
    Client { c: usize },
}

#[derive(Debug)]
enum Ev {
    Bytes {
        to: Node,
        bytes: Vec<u8>,
        epoch: u64,
        bps: u32,
    },
    Deferred {
        g: usize,
        p: usize,
        d: usize,
        to: ReplyTo,
    },
    /// The device's silence timer: no byte since `since`.
    DeviceIdle {
        g: usize,
        p: usize,
        d: usize,
        since: u64,
    },
    FlapPair(usize),
    FlapClient(usize),
    FlapPort {
        g: usize,
        p: usize,
    },
}

/// A client's ACK time-out is longer than the GCUs' delivery time-out
/// (the ACK means "the device acknowledged it", ARCHITECTURE "Delivery contract").
const CLIENT_RETRY: RetryPolicy = RetryPolicy {
    ack_timeout: 600,
    retries: 3,
};
const RANDOM_PHASE_CAP: u64 = 60_000;
/// Silence after which devices and clients abandon a partial frame.
const SILENCE: u64 = 10;
const DRAIN_CAP: u64 = 100_000;

struct World {
    rng: Rng,
    now: u64,
    seq: u64,
    events: BTreeMap<(u64, u64), Ev>,
    fifo: BTreeMap<(Node, Node), u64>,
    gcus: Vec<Gcu>,
    pairs: Vec<Pair>,
    clients: Vec<Client>,
    quiet: bool,
    drop_pm: u64,
    corrupt_pm: u64,
    jitter: u64,
    trace: bool,
    violation: Option<String>,
    summary: Summary,
}

/// Runs one seed; `Err` names the first invariant broken.
pub fn run(seed: u64, trace: bool) -> Result<Summary, String> {
    let mut w = World::generate(seed, trace);
    w.random_phase()?;
    w.final_phase()?;
    w.check_end()?;
    Ok(w.finish_summary())
}

impl World {
    fn generate(seed: u64, trace: bool) -> Self {
        let mut rng = Rng::new(seed);
        let n_gcu = rng.range(1, 3) as usize;
        let mut groups = Vec::new();
        while groups.len() < n_gcu {
            let g = rng.range(1, 60) as u8;
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
        let parents: Vec<usize> = (0..n_gcu)
            .map(|i| if i == 0 { 0 } else { rng.below(i as u64) as usize })
            .collect();
        let mut pairs = Vec::new();
        let mut next_link = vec![10u32; n_gcu];
        for (child, &parent) in parents.iter().enumerate().skip(1) {
            let pl = LinkId(next_link[parent]);
            next_link[parent] += 1;
            let cl = LinkId(next_link[child]);
            next_link[child] += 1;
            pairs.push(Pair {
                parent: (parent, pl),
                child: (child, cl),
                up: true,
                epoch: 0,
            });
        }
        let devices_configured = rng.chance(500);
        let mut gcus = Vec::new();
        for (i, &group) in groups.iter().enumerate() {
            let mut config = RouterConfig::new(group);
            config.name = format!("sim gcu {group}");
            config.serial = format!("SN{seed}").chars().take(20).collect();
            config.links.ack_timeout = 40;
            config.links.retries = 3;
            config.links.queue_bound = rng.range(4, 16) as usize;
            config.links.stop_queue_bound = 16;
            config.links.idle_timeout = 20;
            config.links.answer_timeout = 4_000;
            config.links.long_answer_timeout = 8_000;
            config.links.nic_answer_timeout = 1_500;
            config.links.max_pending = 64;
            // Below the clients' ACK time-out (600), wire delays included.
            config.links.delivery_timeout = 450;
            // Child: default upstream. Every GCU: static routes to its descendants.
            for pair in &pairs {
                if pair.child.0 == i {
                    config.default_upstream = Some(pair.child.1);
                }
            }
            for (d, &dg) in groups.iter().enumerate() {
                let mut hop = d;
                while hop != 0 && parents[hop] != i {
                    hop = parents[hop];
                }
                if d != i && hop != 0 && parents[hop] == i {
                    if let Some(pair) = pairs.iter().find(|p| p.child.0 == hop) {
                        config.static_routes.insert(dg, pair.parent.1);
                    }
                }
            }
            let n_ports = rng.range(1, 3);
            let mut ports = Vec::new();
            let mut port_ids = Vec::new();
            while port_ids.len() < n_ports as usize {
                let p = rng.range(1, 8) as u8;
                if !port_ids.contains(&p) {
                    port_ids.push(p);
                }
            }
            for &pid in &port_ids {
                let n_dev = rng.range(1, 3) as usize;
                let mut ids = Vec::new();
                while ids.len() < n_dev {
                    let d = rng.range(1, 9) as u8;
                    if !ids.contains(&d) {
                        ids.push(d);
                    }
                }
                let bound = rng.range(2, 8) as usize;
                let stop_bound = rng.range(8, 32) as usize;
                // Behind a device server that may stall (fault: stalled line).
                let buffered = rng.chance(250);
                let late_answer_guard = rng.range(0, 200);
                config.ports.push(PortConfig {
                    bps: 9600,
                    retries: 2,
                    ack_timeout: 20,
                    result_timeout: 150,
                    long_result_timeout: 2_500,
                    nic_window: 10,
                    broadcast_guard: 30,
                    queue_bound: bound,
                    stop_queue_bound: stop_bound,
                    idle_timeout: 10,
                    devices: devices_configured.then(|| ids.clone()),
                    late_answer_guard,
                    buffered,
                    ..PortConfig::new(pid)
                });
                let single = n_dev == 1 && rng.chance(500);
                let devices = ids
                    .iter()
                    .map(|&id| Device {
                        ep: DeviceEndpoint::new(if single {
                            EndpointConfig::single(id)
                        } else {
                            EndpointConfig::shared(id)
                        }),
                        gimbal: Gimbal {
                            id,
                            ..Gimbal::default()
                        },
                        bps: 9600,
                        last_rx: 0,
                    })
                    .collect();
                ports.push(SimPort {
                    id: pid,
                    bps: 9600,
                    open: true,
                    epoch: 0,
                    bound,
                    stop_bound,
                    devices,
                    buffered,
                    stalled_until: 0,
                    late_answer_guard,
                });
            }
            let router = Router::new(config).expect("generated config is valid");
            gcus.push(Gcu {
                group,
                router,
                ports,
                ledger: Ledger::default(),
            });
        }
        let n_clients = rng.range(1, 3) as usize;
        let mut clients = Vec::new();
        for c in 0..n_clients {
            let gcu = rng.below(n_gcu as u64) as usize;
            let group = rng.pick(&[0u8, 100, 101, 102]);
            let filter = if rng.chance(500) {
                SourceFilter::Any
            } else {
                SourceFilter::Only(vec![group])
            };
            clients.push(Client {
                gcu,
                link: LinkId(100 + c as u32),
                group,
                filter,
                connected: true,
                epoch: 0,
                framer: Framer::new(),
                state: ClientState::Idle,
                issued: Vec::new(),
                nonces: BTreeSet::new(),
                counter: 0,
                to_issue: rng.range(3, 10) as usize,
                next_at: rng.below(50),
                forced: None,
                nics: 0,
                last_rx: 0,
                written: BTreeSet::new(),
                current: None,
                abandoned: BTreeSet::new(),
                tainted_acked: BTreeMap::new(),
                wire: ClientWire::default(),
                last_report: None,
            });
        }
        let level = rng.below(4);
        let (drop_pm, corrupt_pm) = match level {
            0 => (0, 0),
            1 => (10, 10),
            2 => (30, 20),
            _ => (60, 50),
        };
        let jitter = rng.range(1, 5);
        let mut w = World {
            rng,
            now: 0,
            seq: 0,
            events: BTreeMap::new(),
            fifo: BTreeMap::new(),
            gcus,
            pairs,
            clients,
            quiet: false,
            drop_pm,
            corrupt_pm,
            jitter,
            trace,
            violation: None,
            summary: Summary::default(),
        };
        w.log(format_args!(
            "seed {seed}: {n_gcu} gcus {groups:?}, parents {parents:?}, {n_clients} clients, drop {drop_pm}‰ corrupt {corrupt_pm}‰"
        ));
        w.start();
        w
    }

    fn log(&self, args: std::fmt::Arguments<'_>) {
        if self.trace {
            println!("[{:>6}] {args}", self.now);
        }
    }

    fn schedule(&mut self, at: u64, ev: Ev) {
        self.seq += 1;
        self.events.insert((at, self.seq), ev);
    }

    fn start(&mut self) {
        for g in 0..self.gcus.len() {
            for p in 0..self.gcus[g].ports.len() {
                let port = self.gcus[g].ports[p].id;
                self.input(g, Input::PortOpened { port });
            }
        }
        for i in 0..self.pairs.len() {
            self.pair_up(i);
        }
        for c in 0..self.clients.len() {
            self.client_up(c);
        }
        // Disconnections during the random phase.
        if self.rng.chance(600) {
            for _ in 0..self.rng.range(1, 4) {
                let at = self.rng.range(100, 6_000);
                let choice = self.rng.below(3);
                match choice {
                    0 if !self.pairs.is_empty() => {
                        let i = self.rng.below(self.pairs.len() as u64) as usize;
                        self.schedule(at, Ev::FlapPair(i));
                    }
                    1 => {
                        let c = self.rng.below(self.clients.len() as u64) as usize;
                        self.schedule(at, Ev::FlapClient(c));
                    }
                    _ => {
                        let g = self.rng.below(self.gcus.len() as u64) as usize;
                        let p = self.rng.below(self.gcus[g].ports.len() as u64) as usize;
                        self.schedule(at, Ev::FlapPort { g, p });
                    }
                }
            }
        }
    }

    // ------------------------------------------------------------ routers

    fn input(&mut self, g: usize, input: Input<'_>) {
        let now = self.now;
        let out = self.gcus[g].router.handle_once(now, input);
        self.apply(g, out);
    }

    fn violation(&mut self, message: String) {
        if self.violation.is_none() {
            self.log(format_args!("VIOLATION: {message}"));
            self.violation = Some(format!("t={}: {message}", self.now));
        }
    }

    fn apply(&mut self, g: usize, out: Outbox) {
        for action in out.actions().iter().cloned() {
            match action {
                Action::Write {
                    line: LineId::Port(port),
                    bytes,
                } => {
                    let bytes = out.bytes(&bytes).to_vec();
                    self.log(format_args!("gcu {g} port {port} <- {bytes:02X?}"));
                    let Some(p) = self.gcus[g].ports.iter().position(|sp| sp.id == port) else {
                        self.violation(format!("gcu {g} wrote to unknown port {port}"));
                        continue;
                    };
                    let sp = &self.gcus[g].ports[p];
                    let (epoch, bps, n) = (sp.epoch, sp.bps, sp.devices.len());
                    if !sp.open {
                        self.violation(format!("gcu {g} wrote to closed port {port}"));
                        continue;
                    }
                    if let Some((at, bytes)) = self.wire(Node::Port { g, p }, Node::Device { g, p, d: 0 }, bytes) {
                        let at = self.stalled_line(g, p, at);
                        for d in 0..n {
                            let to = Node::Device { g, p, d };
                            self.schedule(
                                at,
                                Ev::Bytes {
                                    to,
                                    bytes: bytes.clone(),
                                    epoch,
                                    bps,
                                },
                            );
                        }
                    }
                }
                Action::Write {
                    line: LineId::Link(link),
                    bytes,
                } => self.write_link(g, link, out.bytes(&bytes).to_vec()),
                Action::SetPortRate { port, bps } => {
                    if let Some(sp) = self.gcus[g].ports.iter_mut().find(|sp| sp.id == port) {
                        sp.bps = bps;
                    }
                }
                Action::Event(event) => self.on_event(g, event),
                Action::LinkGone { link, stats } => {
                    // The router forgets a gone link's counters: keep its repeats.
                    self.summary.client_repeats += stats.repeats;
                    // Every frame it queued is accounted for when it leaves.
                    if stats.queued != stats.delivered + stats.failed || stats.queue_len != 0 {
                        self.violation(format!("gcu {g} {link} left with frames unaccounted {stats:?}"));
                    }
                }
            }
        }
    }

    fn on_event(&mut self, g: usize, event: RouterEvent) {
        if self.trace {
            self.log(format_args!("gcu {g}: {event}"));
        }
        let gcu = &mut self.gcus[g];
        let behind_server =
            |dest: Address| dest.group == gcu.group && gcu.ports.iter().any(|sp| sp.buffered && sp.id == dest.port);
        let ledger = &mut gcu.ledger;
        let problem = match event {
            RouterEvent::Accepted { id, origin, .. } => {
                if let Some(link) = origin.link() {
                    ledger.untold.insert(id, link);
                }
                (!ledger.accepted.insert(id)).then(|| format!("gcu {g}: {id:?} accepted twice"))
            }
            RouterEvent::Undelivered {
                dest,
                failure: Undelivered::DeviceSilent,
                ..
            } if behind_server(dest) => Some(format!(
                "gcu {g}: a command to {dest} behind a device server reported undelivered: its bytes may still run"
            )),
            RouterEvent::Delivered { id } | RouterEvent::Undelivered { id, .. } => ledger
                .untold
                .remove(&id)
                .is_none()
                .then(|| format!("gcu {g}: {id:?} told twice, or never accepted from a link")),
            RouterEvent::LinkState { link, up: false, .. } => {
                ledger.untold.retain(|_, l| *l != link);
                None
            }
            RouterEvent::Finished { id, outcome } => {
                if !ledger.accepted.contains(&id) {
                    Some(format!("gcu {g}: {id:?} finished without being accepted"))
                } else if !ledger.finished.insert(id) {
                    Some(format!("gcu {g}: {id:?} finished twice ({outcome:?})"))
                } else {
                    None
                }
            }
            RouterEvent::Queued { id, port, stop } => {
                if stop {
                    ledger.pending_stops.entry(port).or_default().insert(id);
                }
                None
            }
            RouterEvent::Started { id, port, stop } => {
                let pending = ledger.pending_stops.entry(port).or_default();
                if stop {
                    pending.remove(&id);
                    None
                } else if !pending.is_empty() {
                    Some(format!(
                        "gcu {g} port {port}: {id:?} started while stops {pending:?} wait"
                    ))
                } else {
                    None
                }
            }
            _ => None,
        };
        if let Some(problem) = problem {
            self.violation(problem);
        }
    }

    fn flap_later(&mut self, ev: Ev) {
        if !self.quiet {
            let at = self.now + self.rng.range(50, 1_000);
            self.schedule(at, ev);
        }
    }

    // ------------------------------------------------------------ events

    fn process(&mut self, ev: Ev) {
        match ev {
            Ev::Bytes { to, bytes, epoch, bps } => self.deliver(to, bytes, epoch, bps),
            Ev::Deferred { g, p, d, to } => {
                let sp = &mut self.gcus[g].ports[p];
                let (epoch, dev) = (sp.epoch, &mut sp.devices[d]);
                let mut out = Vec::new();
                let reply = Reply::Initialization(InitResults::default());
                if dev
                    .ep
                    .send_reply(to, &reply, &mut |b: &[u8]| out.extend_from_slice(b))
                    .is_err()
                {
                    return self.violation("device could not encode an IX result".into());
                }
                let bps = dev.bps;
                self.device_writes(g, p, d, out, epoch, bps);
            }
            Ev::DeviceIdle { g, p, d, since } => {
                let now = self.now;
                let sp = &mut self.gcus[g].ports[p];
                let epoch = sp.epoch;
                let dev = &mut sp.devices[d];
                if dev.last_rx != since {
                    return;
                }
                let mut out = Vec::new();
                dev.ep
                    .line_idle(now, &mut dev.gimbal, &mut |b: &[u8]| out.extend_from_slice(b));
                let bps = dev.bps;
                self.device_writes(g, p, d, out, epoch, bps);
            }
            Ev::FlapPair(i) => {
                if self.quiet {
                    return;
                }
                if self.pairs[i].up {
                    self.pair_down(i);
                } else {
                    self.pair_up(i);
                }
                self.flap_later(Ev::FlapPair(i));
            }
            Ev::FlapClient(c) => {
                if self.quiet {
                    return;
                }
                if self.clients[c].connected {
                    self.client_down(c);
                } else {
                    self.client_up(c);
                }
                self.flap_later(Ev::FlapClient(c));
            }
            Ev::FlapPort { g, p } => {
                if self.quiet {
                    return;
                }
                if self.gcus[g].ports[p].open {
                    self.port_lost(g, p);
                } else {
                    self.port_opened(g, p);
                }
                self.flap_later(Ev::FlapPort { g, p });
            }
        }
    }

    fn next_time(&self) -> Option<u64> {
        let events = self.events.keys().next().map(|k| k.0);
        let routers = self.gcus.iter().filter_map(|g| g.router.next_deadline()).min();
        let clients = (0..self.clients.len()).filter_map(|c| self.client_deadline(c)).min();
        [events, routers, clients].into_iter().flatten().min()
    }

    /// Runs until nothing is left to do or `until`; Err on a violation.
    fn run_until(&mut self, until: u64, stop: impl Fn(&World) -> bool) -> Result<(), String> {
        while let Some(t) = self.next_time() {
            if t > until || stop(self) {
                break;
            }
            self.now = self.now.max(t);
            while let Some(entry) = self.events.first_entry() {
                if entry.key().0 > self.now {
                    break;
                }
                let ev = entry.remove();
                self.process(ev);
            }
            for g in 0..self.gcus.len() {
                if self.gcus[g].router.next_deadline().is_some_and(|d| d <= self.now) {
                    self.input(g, Input::Tick);
                }
            }
            for c in 0..self.clients.len() {
                if self.client_deadline(c).is_some_and(|d| d <= self.now) {
                    self.client_poll(c);
                }
            }
            if let Some(v) = &self.violation {
                return Err(v.clone());
            }
        }
        Ok(())
    }

    fn random_phase(&mut self) -> Result<(), String> {
        self.run_until(RANDOM_PHASE_CAP, |w| {
            w.clients
                .iter()
                .all(|c| c.to_issue == 0 && matches!(c.state, ClientState::Idle))
        })
    }

    fn drain(&mut self) -> Result<(), String> {
        let cap = self.now + DRAIN_CAP;
        self.run_until(cap, |_| false)?;
        if self.next_time().is_some() {
            return Err(format!("network did not settle by t={cap}"));
        }
        Ok(())
    }

    /// Faults off, everything reconnected; each client starts a motion on a
    /// reachable device and disconnects: the dead-man must stop them all.
    fn final_phase(&mut self) -> Result<(), String> {
        self.quiet = true;
        self.log(format_args!("final phase"));
        for c in 0..self.clients.len() {
            self.clients[c].to_issue = 0;
        }
        for i in 0..self.pairs.len() {
            if !self.pairs[i].up {
                self.pair_up(i);
            }
        }
        for c in 0..self.clients.len() {
            if !self.clients[c].connected {
                self.client_up(c);
            }
        }
        for g in 0..self.gcus.len() {
            for p in 0..self.gcus[g].ports.len() {
                if !self.gcus[g].ports[p].open {
                    self.port_opened(g, p);
                }
            }
        }
        self.drain()?;
        let mut targets = Vec::new();
        for c in 0..self.clients.len() {
            let reachable: Vec<(usize, usize, usize)> = (0..self.gcus.len())
                .flat_map(|g| (0..self.gcus[g].ports.len()).map(move |p| (g, p)))
                .flat_map(|(g, p)| {
                    let sp = &self.gcus[g].ports[p];
                    (0..sp.devices.len())
                        // At the port's rate, with no switch pending (a `C0..C7`
                        // to one device of a shared bus takes it off the line).
                        .filter(move |&d| sp.devices[d].bps == sp.bps && sp.devices[d].gimbal.pending_rate.is_none())
                        .map(move |d| (g, p, d))
                })
                .collect();
            if reachable.is_empty() {
                continue;
            }
            let (g, p, d) = self.rng.pick(&reachable);
            let motion = self
                .rng
                .pick(&[&b"PL"[..], b"PR", b"TU", b"TD", b"FF", b"FN", b"ZI", b"ZO"]);
            let axis = motion_axis(&Command::parse(motion)).unwrap_or(0);
            let dest = Address::new(
                self.gcus[g].group,
                self.gcus[g].ports[p].id,
                self.gcus[g].ports[p].devices[d].gimbal.id,
            );
            self.clients[c].forced = Some((dest, motion.to_vec()));
            self.clients[c].next_at = self.now;
            targets.push((c, g, p, d, axis));
            // One at a time: a small port queue may not hold every client's.
            self.drain()?;
        }
        for &(c, g, p, d, axis) in &targets {
            if !self.gcus[g].ports[p].devices[d].gimbal.moving[axis] {
                return Err(format!(
                    "quiet network: client {c}'s motion never reached gcu {g} port {} device {}",
                    self.gcus[g].ports[p].id, self.gcus[g].ports[p].devices[d].gimbal.id
                ));
            }
        }
        for c in 0..self.clients.len() {
            self.client_down(c);
        }
        self.drain()?;
        for &(c, g, p, d, axis) in &targets {
            let sp = &self.gcus[g].ports[p];
            if sp.devices[d].bps != sp.bps {
                // Switched to another rate than its bus: no GCU can reach it.
                continue;
            }
            if self.gcus[g].ports[p].devices[d].gimbal.moving[axis] {
                return Err(format!(
                    "dead-man: client {c} gone, gcu {g} port {} device {} still moving on axis {axis}",
                    self.gcus[g].ports[p].id, self.gcus[g].ports[p].devices[d].gimbal.id
                ));
            }
            self.summary.final_motions_checked += 1;
        }
        Ok(())
    }

    fn check_end(&mut self) -> Result<(), String> {
        for (g, gcu) in self.gcus.iter().enumerate() {
            let open: Vec<_> = gcu.ledger.accepted.difference(&gcu.ledger.finished).collect();
            if !open.is_empty() {
                return Err(format!("gcu {g}: commands without outcome: {open:?}"));
            }
            if !gcu.ledger.untold.is_empty() {
                return Err(format!(
                    "gcu {g}: origins never told whether these were delivered: {:?}",
                    gcu.ledger.untold
                ));
            }
            if gcu.router.in_progress() != 0 {
                return Err(format!(
                    "gcu {g}: {} commands still in progress",
                    gcu.router.in_progress()
                ));
            }
            let stats = gcu.router.stats();
            for sp in gcu.ports.iter().filter(|sp| sp.buffered) {
                let retransmits = stats.ports.get(&sp.id).map_or(0, |p| p.line.retransmits);
                if retransmits != 0 {
                    return Err(format!(
                        "gcu {g}: {retransmits} retransmissions into the device server of port {}",
                        sp.id
                    ));
                }
            }
            if stats.router.accepted != stats.router.finished() {
                return Err(format!(
                    "gcu {g}: accepted {} != finished {}",
                    stats.router.accepted,
                    stats.router.finished()
                ));
            }
            for sp in &gcu.ports {
                let ps = &stats.ports[&sp.id];
                if ps.queue_high_water > sp.bound + sp.stop_bound {
                    return Err(format!(
                        "gcu {g} port {}: queue reached {} > {}",
                        sp.id, ps.queue_high_water, sp.bound
                    ));
                }
            }
            for (link, ls) in &stats.links {
                if ls.queued != ls.delivered + ls.failed + ls.queue_len as u64 {
                    return Err(format!("gcu {g} {link}: frames unaccounted {ls:?}"));
                }
                if ls.queue_high_water > 32 {
                    return Err(format!("gcu {g} {link}: link queue reached {}", ls.queue_high_water));
                }
            }
        }
        Ok(())
    }

    fn finish_summary(&mut self) -> Summary {
        let mut s = self.summary.clone();
        for gcu in &self.gcus {
            let st = gcu.router.stats();
            let r = st.router;
            s.accepted += r.accepted;
            s.results += r.results;
            s.nics += r.nics;
            s.completed += r.completed;
            s.no_result += r.no_result;
            s.unreachable += r.unreachable;
            s.forwarded += r.forwarded;
            s.dropped += r.dropped.total();
            s.dead_man_stops += r.dead_man_stops;
            s.client_repeats += st.links.values().map(|l| l.repeats).sum::<u64>();
            s.rate_switches += st.ports.values().map(|p| p.rate_switches).sum::<u64>();
            s.retransmits += st.ports.values().map(|p| p.line.retransmits).sum::<u64>()
                + st.links.values().map(|l| l.line.retransmits).sum::<u64>();
        }
        s.end_time = self.now;
        s
    }
}
