//! One test per rule of ARCHITECTURE "Routing semantics" and "Safety", driving
//! the public `Router` API with hand-written bytes.

mod broadcast;
mod exchange;
mod late;
mod pipeline;
mod queues;
mod routing;
mod safety;
mod window;

use sagebrush_gcu::{
    Action, CommandId, CommandOutcome, DropReason, Input, LineId, LinkConfig, LinkId, LinkKind, Outbox, PortConfig,
    Router, RouterConfig, RouterEvent, SourceFilter, StopCause,
};
use sagebrush_protocol::link::wire_ms;
use sagebrush_protocol::{ACK, Address, DeliveryReport, Event, Frame, FrameBuf, Framer, NAK, NIC, Undelivered};

const G: u8 = 5;
const CLIENT: LinkId = LinkId(1);
const UP: LinkId = LinkId(2);
const DOWN: LinkId = LinkId(3);
const DOWN2: LinkId = LinkId(4);

fn frame(dest: (u8, u8, u8), source: u8, payload: &[u8]) -> Vec<u8> {
    FrameBuf::new(Address::new(dest.0, dest.1, dest.2), source, payload)
        .unwrap()
        .as_bytes()
        .to_vec()
}

/// The delivery report GCU `G` sends about `command` (ARCHITECTURE "Delivery contract").
fn report(command: &[u8], failure: Option<Undelivered>) -> Vec<u8> {
    let (f, _) = Frame::parse(command).unwrap();
    let payload = DeliveryReport {
        failure,
        dest: f.dest,
        command_checksum: f.checksum(),
        at_group: G,
    }
    .encode();
    frame((f.source, 0, 0), G, &payload)
}

/// GCU 7's report about `command` (from group 2): delivered there, or why not.
fn reported_at_7(failure: Option<Undelivered>, command: &[u8]) -> Vec<u8> {
    let (f, _) = Frame::parse(command).unwrap();
    let payload = DeliveryReport {
        failure,
        dest: f.dest,
        command_checksum: f.checksum(),
        at_group: 7,
    }
    .encode();
    frame((2, 0, 0), 7, &payload)
}

/// What the client is told by the end of the default delivery time-out.
fn told_in_time(h: &mut H) -> Vec<Vec<u8>> {
    for _ in 0..sagebrush_gcu::LinkSettings::DELIVERY_TIMEOUT_MS {
        let told = link_writes(&h.wait(1), CLIENT);
        if !told.is_empty() {
            return told;
        }
    }
    Vec::new()
}

fn port_config(id: u8) -> PortConfig {
    PortConfig {
        retries: 2,
        ack_timeout: 10,
        result_timeout: 50,
        long_result_timeout: 1000,
        nic_window: 5,
        broadcast_guard: 20,
        queue_bound: 4,
        idle_timeout: 5,
        late_answer_guard: 25,
        ..PortConfig::new(id)
    }
}

struct H {
    r: Router,
    now: u64,
}

impl H {
    fn new(ports: &[u8]) -> Self {
        Self::with(ports, |_| {})
    }

    fn with(ports: &[u8], tweak: impl FnOnce(&mut RouterConfig)) -> Self {
        let mut config = RouterConfig::new(G);
        config.name = "test gcu".into();
        config.serial = "SN-5".into();
        config.ports = ports.iter().map(|&p| port_config(p)).collect();
        config.links.ack_timeout = 10;
        config.links.retries = 2;
        tweak(&mut config);
        let mut h = Self {
            r: Router::new(config).unwrap(),
            now: 0,
        };
        for &p in ports {
            h.go(Input::PortOpened { port: p });
        }
        h.up(CLIENT, LinkKind::Client);
        h
    }

    fn up(&mut self, link: LinkId, kind: LinkKind) {
        self.go(Input::LinkUp {
            link,
            config: LinkConfig::new(kind, SourceFilter::Any),
        });
    }

    fn go(&mut self, input: Input<'_>) -> Outbox {
        self.r.handle_once(self.now, input)
    }

    fn link(&mut self, link: LinkId, bytes: &[u8]) -> Outbox {
        self.go(Input::Bytes {
            line: LineId::Link(link),
            bytes,
        })
    }

    fn port(&mut self, port: u8, bytes: &[u8]) -> Outbox {
        self.go(Input::Bytes {
            line: LineId::Port(port),
            bytes,
        })
    }

    /// Advances time by `ticks`, firing every deadline on the way.
    fn wait(&mut self, ticks: u64) -> Outbox {
        let end = self.now + ticks;
        let mut all = Outbox::new();
        while let Some(t) = self.r.next_deadline().filter(|&t| t <= end) {
            self.now = t.max(self.now);
            self.r.handle(self.now, Input::Tick, &mut all);
        }
        self.now = end;
        self.r.handle(self.now, Input::Tick, &mut all);
        all
    }
}

/// What was written where `to` says, one frame or bare byte per item (the
/// outbox merges consecutive writes to one line; the framer splits them).
fn writes(out: &Outbox, to: impl Fn(&Action) -> Option<&std::ops::Range<usize>>) -> Vec<Vec<u8>> {
    let mut framer: Framer = Framer::new();
    let mut items = Vec::new();
    for span in out.actions().iter().filter_map(to) {
        framer.feed(out.bytes(span), |e| {
            items.push(match e {
                Event::Frame(f) => FrameBuf::from_frame(&f).as_bytes().to_vec(),
                Event::Ack => vec![ACK],
                Event::Nak => vec![NAK],
                Event::Nic => vec![NIC],
                Event::BadChecksum(b) => panic!("the router wrote a damaged frame: {b:?}"),
            })
        });
    }
    items
}

fn port_writes(out: &Outbox, port: u8) -> Vec<Vec<u8>> {
    writes(out, |a| match a {
        Action::Write {
            line: LineId::Port(p),
            bytes,
        } if *p == port => Some(bytes),
        _ => None,
    })
}

fn link_writes(out: &Outbox, link: LinkId) -> Vec<Vec<u8>> {
    writes(out, |a| match a {
        Action::Write {
            line: LineId::Link(l),
            bytes,
        } if *l == link => Some(bytes),
        _ => None,
    })
}

fn finished(actions: &[Action]) -> Vec<CommandOutcome> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::Event(RouterEvent::Finished { outcome, .. }) => Some(*outcome),
            _ => None,
        })
        .collect()
}

/// The stops the router issued itself (dead-man, shutdown), in order.
fn dead_man_stops(actions: &[Action]) -> Vec<(Address, &'static str)> {
    actions
        .iter()
        .filter_map(|x| match x {
            Action::Event(RouterEvent::IssuedStop {
                dest,
                stop,
                cause: StopCause::DeadMan | StopCause::Shutdown,
                ..
            }) => Some((*dest, *stop)),
            _ => None,
        })
        .collect()
}

fn accepted(actions: &[Action]) -> Vec<CommandId> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::Event(RouterEvent::Accepted { id, .. }) => Some(*id),
            _ => None,
        })
        .collect()
}

fn dropped(actions: &[Action]) -> Vec<DropReason> {
    actions
        .iter()
        .filter_map(|a| match a {
            Action::Event(RouterEvent::Dropped { reason, .. }) => Some(*reason),
            _ => None,
        })
        .collect()
}
