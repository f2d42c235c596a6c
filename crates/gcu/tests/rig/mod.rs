//! A GCU router with one port of simulated gimbals (`sagebrush-sim`:
//! physics, presets, rates) and client links, run on a discrete clock:
//! what the governance tests (`tests/governance.rs`) drive. Bytes take
//! their wire time at the port's rate each way; clients see what the
//! router writes to them, one frame or bare byte at a time.

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::sync::Arc;

use sagebrush_gcu::{
    Action, Input, LineId, LinkConfig, LinkId, LinkKind, Outbox, PortConfig, Router, RouterConfig, RouterEvent,
    SourceFilter,
};
use sagebrush_protocol::link::wire_ms;
use sagebrush_protocol::{ACK, Address, Command, DeliveryReport, Event, FrameBuf, Framer, Position, Undelivered};
use sagebrush_sim::{Bus, BusConfig, GimbalConfig};

pub const G: u8 = 5;
pub const PORT: u8 = 1;

/// What a client received: an ACK, a NIC, a delivery report, or a result frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Got {
    Ack,
    Nak,
    Nic,
    Report(Option<Undelivered>),
    Frame(Vec<u8>),
}

pub struct Rig {
    pub router: Router,
    pub bus: Bus,
    pub now: u64,
    pub bps: u32,
    /// Bytes on their way, by arrival tick: to the bus (`None`) or the router.
    wire: Vec<(u64, Option<()>, Vec<u8>)>,
    /// gcud is down ([`Rig::down_for`]).
    down: bool,
    pub received: BTreeMap<LinkId, Vec<Got>>,
    framers: BTreeMap<LinkId, Framer>,
    /// Every router event, with its tick.
    pub events: Vec<(u64, RouterEvent)>,
    /// Every command payload the bus received from the router, with its tick.
    pub bus_log: Vec<(u64, Address, Vec<u8>)>,
    bus_framer: Framer,
    /// Command payloads the bus loses, the next write carrying each (in
    /// order): a lost stop frame, say.
    pub lose: Vec<Vec<u8>>,
    /// The writes the bus lost, with their tick.
    pub lost: Vec<(u64, Vec<u8>)>,
}

/// A port at `bps` with time-outs for it.
pub fn port(bps: u32) -> PortConfig {
    PortConfig::at_rate(PORT, bps)
}

impl Rig {
    /// A router of group [`G`] with `gimbals` on port [`PORT`] at `bps`; `tweak` adjusts the configuration.
    pub fn new(bps: u32, gimbals: Vec<GimbalConfig>, tweak: impl FnOnce(&mut RouterConfig)) -> Self {
        let mut config = RouterConfig::new(G);
        config.ports = vec![port(bps)];
        tweak(&mut config);
        let bus = Bus::new(
            BusConfig {
                devices: gimbals,
                ..BusConfig::default()
            },
            0,
        )
        .expect("bus");
        let mut rig = Self {
            router: Router::new(config).expect("router config"),
            bus,
            now: 0,
            bps,
            wire: Vec::new(),
            down: false,
            received: BTreeMap::new(),
            framers: BTreeMap::new(),
            events: Vec::new(),
            bus_log: Vec::new(),
            bus_framer: Framer::new(),
            lose: Vec::new(),
            lost: Vec::new(),
        };
        rig.input(Input::PortOpened { port: PORT });
        rig
    }

    /// A client link named `name` (its configured link) of `priority`.
    pub fn client(&mut self, link: LinkId, name: &str, priority: u8) {
        let mut config = LinkConfig::new(LinkKind::Client, SourceFilter::Any);
        config.name = Some(Arc::from(name));
        config.priority = priority;
        self.input(Input::LinkUp { link, config });
    }

    pub fn drop_link(&mut self, link: LinkId) {
        self.input(Input::LinkDown { link });
    }

    pub fn input(&mut self, input: Input<'_>) {
        let mut out = Outbox::new();
        self.router.handle(self.now, input, &mut out);
        self.take(out);
    }

    fn take(&mut self, out: Outbox) {
        // Clients acknowledge every frame they receive (hop by hop).
        let mut acks = Vec::new();
        for action in out.actions() {
            match action {
                Action::Write {
                    line: LineId::Port(_),
                    bytes,
                } => {
                    let b = out.bytes(bytes).to_vec();
                    let at = self.now + wire_ms(b.len(), self.bps);
                    self.wire.push((at, None, b));
                }
                Action::Write {
                    line: LineId::Link(link),
                    bytes,
                } => {
                    let framer = self.framers.entry(*link).or_default();
                    let got = self.received.entry(*link).or_default();
                    framer.feed(out.bytes(bytes), |e| {
                        if matches!(e, Event::Frame(_)) {
                            acks.push(*link);
                        }
                        got.push(match e {
                            Event::Frame(f) if DeliveryReport::is_report(f.payload()) => {
                                Got::Report(DeliveryReport::parse(f.payload()).expect("report").failure)
                            }
                            Event::Frame(f) => Got::Frame(f.payload().to_vec()),
                            Event::Ack => Got::Ack,
                            Event::Nak => Got::Nak,
                            Event::Nic => Got::Nic,
                            Event::BadChecksum(_) => panic!("damaged frame to a client"),
                        })
                    });
                }
                Action::SetPortRate { bps, .. } => self.bps = *bps,
                Action::Event(e) => self.events.push((self.now, e.clone())),
                Action::LinkGone { .. } => {}
            }
        }
        for link in acks {
            if self.router.link_is_up(link) {
                self.input(Input::Bytes {
                    line: LineId::Link(link),
                    bytes: &[ACK],
                });
            }
        }
    }

    /// `command` from `link` (source group 0) to gimbal `device`.
    pub fn send(&mut self, link: LinkId, device: u8, command: &Command<'_>) {
        let dest = Address::new(G, PORT, device);
        let frame = FrameBuf::build(dest, 0, |b| command.encode(b).map(<[u8]>::len)).expect("encodes");
        self.send_frame(link, frame.as_bytes());
    }

    /// A raw payload from `link` to `dest`.
    pub fn send_payload(&mut self, link: LinkId, dest: Address, payload: &[u8]) {
        let frame = FrameBuf::new(dest, 0, payload).expect("frame");
        self.send_frame(link, frame.as_bytes());
    }

    fn send_frame(&mut self, link: LinkId, bytes: &[u8]) {
        self.input(Input::Bytes {
            line: LineId::Link(link),
            bytes,
        });
    }

    /// What `link` received since the last call.
    pub fn got(&mut self, link: LinkId) -> Vec<Got> {
        std::mem::take(self.received.entry(link).or_default())
    }

    /// Runs the world for `ms`, calling `each` at every step (at least every `step` ms).
    pub fn run_with(&mut self, ms: u64, step: u64, mut each: impl FnMut(&Rig)) {
        let end = self.now + ms;
        while self.now < end {
            let next = [
                self.router.next_deadline(),
                self.bus.next_deadline(),
                self.wire.iter().map(|w| w.0).min(),
                Some(self.now + step),
                Some(end),
            ]
            .into_iter()
            .flatten()
            .filter(|&t| t > self.now)
            .min()
            .unwrap_or(end)
            .min(end);
            self.now = next;
            self.deliver();
            self.bus.poll(self.now);
            while let Some(o) = self.bus.pop_due(self.now) {
                let at = o.due.max(self.now) + wire_ms(o.bytes.len(), self.bps);
                self.wire.push((at, Some(()), o.bytes));
            }
            self.deliver();
            if !self.down {
                self.input(Input::Tick);
            }
            each(self);
        }
    }

    /// Runs the world for `ms`.
    pub fn run(&mut self, ms: u64) {
        self.run_with(ms, 1000, |_| {});
    }

    fn deliver(&mut self) {
        loop {
            let Some(i) = self
                .wire
                .iter()
                .enumerate()
                .filter(|(_, w)| w.0 <= self.now)
                .min_by_key(|(_, w)| w.0)
                .map(|(i, _)| i)
            else {
                return;
            };
            let (_, to_router, bytes) = self.wire.remove(i);
            match to_router {
                Some(()) if self.down => {}
                Some(()) => self.input(Input::Bytes {
                    line: LineId::Port(PORT),
                    bytes: &bytes,
                }),
                None => {
                    if let Some(next) = self.lose.first() {
                        let mut framer: Framer = Framer::new();
                        let mut carries = false;
                        framer.feed(&bytes, |e| {
                            if let Event::Frame(f) = e {
                                carries |= f.payload() == next.as_slice();
                            }
                        });
                        if carries {
                            self.lose.remove(0);
                            self.lost.push((self.now, bytes));
                            continue;
                        }
                    }
                    let now = self.now;
                    let log = &mut self.bus_log;
                    self.bus_framer.feed(&bytes, |e| {
                        if let Event::Frame(f) = e {
                            log.push((now, f.dest, f.payload().to_vec()));
                        }
                    });
                    self.bus.receive(&bytes, self.now);
                }
            }
        }
    }

    /// gcud is down for `ms` (a restart): the bus runs on, what the
    /// gimbals send meanwhile is lost (gcud clears a serial port's buffers
    /// when it opens it), nothing goes to the bus but what was written
    /// before. `each` as in [`Rig::run_with`].
    pub fn down_for(&mut self, ms: u64, step: u64, each: impl FnMut(&Rig)) {
        self.down = true;
        self.run_with(ms, step, each);
        self.down = false;
        self.wire.retain(|(_, to_router, _)| to_router.is_none());
    }

    /// The gimbal's position on the bus side, hundredths of a degree.
    pub fn position(&self, device: u8) -> [i32; 2] {
        let p: Position = self.bus.gimbal(device).expect("gimbal").position();
        [i32::from(p.pan.centidegrees()), i32::from(p.tilt.centidegrees())]
    }

    pub fn moving(&self, device: u8) -> bool {
        self.bus.gimbal(device).is_some_and(|g| g.is_moving())
    }

    /// The commands the bus received after tick `since`, by mnemonic text.
    pub fn bus_commands_since(&self, since: u64) -> Vec<String> {
        self.bus_log
            .iter()
            .filter(|(t, _, _)| *t > since)
            .map(|(_, _, p)| String::from_utf8_lossy(p).into_owned())
            .collect()
    }
}

/// A gimbal at `device` with default physics (60 deg/s, 120 deg/s^2, 64 presets).
/// Who holds gimbal [`PORT`].1, as the router's control view says.
pub fn holder(r: &Rig) -> Option<sagebrush_gcu::Holder> {
    r.router
        .control()
        .into_iter()
        .find(|c| (c.port, c.device) == (PORT, 1))?
        .holder
}

pub fn gimbal(device: u8) -> GimbalConfig {
    GimbalConfig::at(device)
}

pub fn pos(pan_deg: f32, tilt_deg: f32) -> Position {
    Position::new(
        sagebrush_protocol::Angle::from_degrees(pan_deg).expect("pan"),
        sagebrush_protocol::Angle::from_degrees(tilt_deg).expect("tilt"),
    )
}

pub const ONE: LinkId = LinkId(1);
pub const TWO: LinkId = LinkId(2);
pub const THREE: LinkId = LinkId(3);

/// Whether `got` ended in `expected`: an ACK for `None`, the report's row otherwise.
pub fn outcome(got: &[Got]) -> Option<Result<(), Option<Undelivered>>> {
    got.iter().rev().find_map(|g| match g {
        Got::Ack => Some(Ok(())),
        Got::Report(r) => Some(Err(*r)),
        _ => None,
    })
}
