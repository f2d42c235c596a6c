//! The network: GCUs with their routers, the event queue and the events'
//! effects. A seed's network is generated in `generate`, the run phases and
//! the invariants at the end are in `phases`; buses and devices are in
//! `devices`, clients in `clients`, wires and delivery in `wires`.

use std::collections::{BTreeMap, BTreeSet};

use sagebrush_gcu::{
    Action, CommandId, Input, LineId, LinkConfig, LinkId, LinkKind, Outbox, PortConfig, Router, RouterConfig,
    RouterEvent, SourceFilter,
};
use sagebrush_protocol::{
    ACK, Address, AwakeStatus, Command, DeliveryReport, DeviceEndpoint, DeviceHandler, EndpointConfig, Extended,
    FrameBuf, Framer, Identity, InitResults, NAK, NIC, OwnedEvent, Position, Reply, ReplyTo, Response, ResultKind,
    RetryPolicy, Transmitter, TxStep, Undelivered, WILDCARD,
};

use super::Rng;

mod clients;
mod devices;
mod generate;
mod phases;
mod wires;

use clients::{Client, ClientState, ClientWire};
use devices::{CommandKey, Device, Gimbal, Heard, NIC_WINDOW, SimPort, motion_axis};

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
    /// Transactions started in the NIC window of the one before (full-duplex ports).
    pipelined,
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
    /// Fault: NICs that left after their ACK, just inside gcud's window or
    /// (the next counter) just after it.
    late_nics,
    nics_after_window,
    /// NICs clients took, each checked against the devices' NICs.
    nics_checked,
    /// `?` bytes a client took while its framer held damaged bytes.
    phantom_nics,
    /// `?` a client took that a command it gave up on by itself (no outcome
    /// from gcud yet) may have earned: it still executed, and a `?` names
    /// no command. (One it was told not delivered never earns one.)
    stale_nics,
    /// `?` a client took that an earlier group-255 command may have earned
    /// (each GCU it reached answers it, however late).
    fan_out_nics,
    /// `?` a GCU relayed from another GCU's link, for a command that GCU
    /// took twice over a lossy link (its first answer or report was lost).
    relayed_nics,
    /// Reports `00` that ended a TCP client's NIC wait (`~W`).
    window_reports,
    /// Nonce echoes TCP clients took as their answer, each checked to be
    /// the echo of the command awaited.
    answers_checked,
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
    /// A device's ACK and NIC, or its NIC alone, reach the port: `key` is
    /// the command they answer.
    Nic {
        g: usize,
        p: usize,
        key: CommandKey,
        bytes: Vec<u8>,
        epoch: u64,
        bps: u32,
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
    /// Every command frame some device answered NIC.
    nicd: BTreeSet<Heard>,
    /// When each command's NICs reached gcud's port.
    nics_at_port: BTreeMap<CommandKey, Vec<u64>>,
    /// When the ACK of each command a device answered NIC last reached the
    /// port, and when gcud last wrote a report `00` about it.
    acks_at_port: BTreeMap<CommandKey, u64>,
    window_reports_at: BTreeMap<CommandKey, u64>,
    /// The router's actions being applied answer bytes from another GCU.
    input_from_gcu: bool,
    /// When a port of each GCU last heard damaged bytes.
    port_damage: BTreeMap<usize, u64>,
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
        let from_gcu = match &input {
            Input::Bytes {
                line: LineId::Link(link),
                ..
            } => self
                .pairs
                .iter()
                .any(|p| p.parent == (g, *link) || p.child == (g, *link)),
            _ => false,
        };
        let out = self.gcus[g].router.handle_once(now, input);
        self.input_from_gcu = from_gcu;
        self.apply(g, out);
        self.input_from_gcu = false;
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
                // A stop that ends without starting (given up unsent, merged,
                // its port lost) no longer waits (seed 156674: an expired `PS`).
                for waiting in ledger.pending_stops.values_mut() {
                    waiting.remove(&id);
                }
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
            Ev::Nic {
                g,
                p,
                key,
                bytes,
                epoch,
                bps,
            } => {
                self.nic_reaches_port(key, &bytes);
                self.deliver(Node::Port { g, p }, bytes, epoch, bps);
            }
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
                dev.idle();
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
}
