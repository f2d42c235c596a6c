//! One test per rule of ARCHITECTURE "Routing semantics" and "Safety", driving
//! the public `Router` API with hand-written bytes.

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

#[test]
fn config_is_validated() {
    assert!(Router::new(RouterConfig::new(0)).is_err());
    assert!(Router::new(RouterConfig::new(255)).is_err());
    let mut c = RouterConfig::new(3);
    c.ports = vec![PortConfig::new(1), PortConfig::new(1)];
    assert!(Router::new(c).is_err());
    let mut c = RouterConfig::new(3);
    c.ports = vec![PortConfig {
        bps: 1000,
        ..PortConfig::new(1)
    }];
    assert!(Router::new(c).is_err());
    let mut c = RouterConfig::new(3);
    c.name = "a name that is longer than twenty".into();
    assert!(Router::new(c).is_err());
}

#[test]
fn port_opened_reports_its_rate_and_unknown_inputs_are_counted() {
    let mut config = RouterConfig::new(G);
    config.ports = vec![PortConfig {
        bps: 38400,
        ..port_config(1)
    }];
    let mut r = Router::new(config).unwrap();
    let a = r.handle_once(0, Input::PortOpened { port: 1 });
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 38400 }));
    assert!(
        r.handle_once(
            0,
            Input::Bytes {
                line: LineId::Port(9),
                bytes: b"x"
            }
        )
        .is_empty()
    );
    assert!(
        r.handle_once(
            0,
            Input::Bytes {
                line: LineId::Link(LinkId(9)),
                bytes: b"x"
            }
        )
        .is_empty()
    );
    assert_eq!(r.unknown_inputs(), 2);
}

#[test]
fn client_commands_are_acked_once_delivered_and_bad_checksums_naked() {
    let mut h = H::new(&[1]);
    let mut bad = frame((G, 1, 3), 2, b"PL");
    *bad.last_mut().unwrap() ^= 0xFF;
    let a = h.link(CLIENT, &bad);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![NAK]]);
    assert!(accepted(&a).is_empty());
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    assert!(link_writes(&a, CLIENT).is_empty(), "the ACK waits for the device's");
    assert_eq!(accepted(&a).len(), 1);
    // The client's retransmission meanwhile is the same command, not a new one.
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    assert!(accepted(&a).is_empty() && link_writes(&a, CLIENT).is_empty());
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    assert_eq!(port_writes(&a, 1), Vec::<Vec<u8>>::new(), "written once");
    assert_eq!(h.r.stats().links[&CLIENT].repeats, 1);
    assert_eq!(h.r.stats().router.delivered, 1);
    let s = h.r.stats();
    assert_eq!(s.links[&CLIENT].line.bad_checksums, 1);
    assert_eq!(s.links[&CLIENT].line.naks_sent, 1);
    assert_eq!(s.links[&CLIENT].line.frames_in, 2, "the repeat came in too");
}

#[test]
fn gcu_itself_answers_aw_and_id_and_nic_otherwise() {
    let mut h = H::new(&[1]);
    let a = h.link(CLIENT, &frame((G, 0, 0), 2, b"AW"));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], frame((2, 0, 0), G, b"0")]);
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    h.link(CLIENT, &[ACK]);
    let a = h.link(CLIENT, &frame((G, 0, 0), 2, b"D?"));
    let writes = link_writes(&a, CLIENT);
    let reply = FrameBuf::new(
        Address::new(2, 0, 0),
        G,
        b"0519test gcu            SN-5                ",
    )
    .unwrap();
    assert_eq!(writes[1], reply.as_bytes());
    h.link(CLIENT, &[ACK]);
    let a = h.link(CLIENT, &frame((G, 0, 0), 2, b"PL"));
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
    assert!(port_writes(&a, 1).is_empty());
}

#[test]
fn result_goes_back_with_table3_header_and_is_acked_on_the_port() {
    // Table 3: command 5.1.12 from group 2; result 2.1.12 from group 5.
    let mut h = H::new(&[1]);
    let cmd = frame((G, 1, 12), 2, b"P?");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(
        port_writes(&a, 1),
        vec![cmd.clone()],
        "written with the header unchanged"
    );
    h.port(1, &[ACK]);
    // The device swapped the groups; the GCU rewrites the source group anyway.
    let a = h.port(1, &frame((2, 1, 12), 255, b"00640000"));
    assert_eq!(port_writes(&a, 1), vec![vec![ACK]], "hop-by-hop ACK of the result");
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 12), G, b"00640000")]);
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    let s = h.r.stats();
    assert_eq!(s.devices[&(1, 12)].frames_in, 1);
    assert_eq!(s.ports[&1].line.frames_in, 1);
}

#[test]
fn bad_checksum_result_is_naked_on_the_port_and_retransmission_accepted() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    let mut bad = frame((2, 1, 3), G, b"0");
    bad[6] = b'1';
    let a = h.port(1, &bad);
    assert_eq!(port_writes(&a, 1), vec![vec![NAK]]);
    assert!(finished(&a).is_empty());
    let a = h.port(1, &frame((2, 1, 3), G, b"0"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
}

#[test]
fn nic_is_relayed_as_a_bare_question_mark() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"XYZ"));
    let a = h.port(1, &[ACK, NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK], vec![NIC]]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
    assert_eq!(h.r.stats().devices[&(1, 3)].nics, 1);
}

#[test]
fn the_device_registry_keeps_what_each_device_answered() {
    use sagebrush_gcu::DeviceError;
    let mut h = H::new(&[1]);
    assert!(
        !h.r.stats().devices.contains_key(&(1, 12)),
        "nothing known before an exchange"
    );
    h.link(CLIENT, &frame((G, 1, 12), 2, b"P?"));
    h.port(1, &[ACK]);
    h.now = 7;
    h.port(1, &frame((2, 1, 12), G, b"1194FC18"));
    let d = h.r.stats().devices[&(1, 12)];
    assert!(d.online);
    assert_eq!(d.last_error, None);
    let (at, position) = d.position.expect("P? answered");
    assert_eq!(at, 7);
    assert_eq!((position.pan.degrees(), position.tilt.degrees()), (45.0, -10.0));
    // Table 17: zoom then focus, 3 hex digits each.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"V?"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 12), G, b"123456"));
    let (_, lens) = h.r.stats().devices[&(1, 12)].lens.expect("V? answered");
    assert_eq!((lens.zoom.get(), lens.focus.get()), (0x123, 0x456));
    // A preset's stored position is not where the mount is.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"P?01"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 12), G, b"00000000"));
    assert_eq!(h.r.stats().devices[&(1, 12)].position, Some((7, position)));
    h.now = 20;
    h.link(CLIENT, &frame((G, 1, 12), 2, b"XYZ"));
    h.port(1, &[ACK, NIC]);
    let d = h.r.stats().devices[&(1, 12)];
    assert_eq!((d.online, d.last_error), (true, Some((20, DeviceError::Nic))));
    // Silent: offline, and what it answered before is kept.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"PL"));
    h.wait(100);
    let d = h.r.stats().devices[&(1, 12)];
    assert!(!d.online, "silent to every try");
    assert!(matches!(d.last_error, Some((_, DeviceError::Silent))));
    assert_eq!(d.position, Some((7, position)));
    // Answering again brings it back.
    h.link(CLIENT, &frame((G, 1, 12), 2, b"PS"));
    h.port(1, &[ACK]);
    h.wait(10);
    assert!(h.r.stats().devices[&(1, 12)].online);
    // Issue 24: an address that never answered (a scan's probe) leaves no
    // entry; one that only NAKed exists.
    h.link(CLIENT, &frame((G, 1, 40), 2, b"D?"));
    h.wait(1_000);
    assert!(!h.r.stats().devices.contains_key(&(1, 40)), "never answered");
    h.link(CLIENT, &frame((G, 1, 41), 2, b"D?"));
    for _ in 0..=port_config(1).retries {
        h.port(1, &[NAK]);
    }
    h.wait(1_000);
    assert!(h.r.stats().devices.contains_key(&(1, 41)), "a NAK is an answer");
}

#[test]
fn no_ack_retransmits_up_to_the_count_then_unreachable() {
    let mut h = H::new(&[1]);
    let cmd = frame((G, 1, 3), 2, b"PL");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    // A NAK is a retransmission too.
    let a = h.port(1, &[NAK]);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    let a = h.wait(100);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()], "retries = 2");
    assert_eq!(finished(&a), vec![CommandOutcome::Unreachable]);
    // The client hears 01, never an ACK (unacknowledged, the report goes
    // again within the wait).
    let told = link_writes(&a, CLIENT);
    assert!(
        !told.is_empty() && told.iter().all(|w| *w == report(&cmd, Some(Undelivered::DeviceSilent))),
        "{told:?}"
    );
    let s = h.r.stats();
    assert_eq!(s.devices[&(1, 3)].retransmits, 2);
    assert_eq!(s.devices[&(1, 3)].unreachable, 1);
    assert_eq!(s.ports[&1].line.naks_received, 1);
    assert_eq!(s.router.unreachable, 1);
}

/// The ACK clock starts at the write: a long frame on a slow line gets its
/// own wire time on top of the ACK time-out, and is not sent again while it
/// is still going out.
#[test]
fn a_long_frame_is_not_retransmitted_while_it_is_still_going_out() {
    let mut h = H::new(&[1]);
    // `*x1t` with 240 bytes for the auxiliary port: 251 bytes, 262 ms at 9600 bit/s.
    let mut payload = b"*x1t".to_vec();
    payload.extend(std::iter::repeat_n(b'A', 240));
    let long = frame((G, 1, 3), 2, &payload);
    assert_eq!(wire_ms(long.len(), 9600), 262);
    h.link(CLIENT, &long);
    let a = h.wait(250);
    assert!(port_writes(&a, 1).is_empty(), "still on the wire: no retransmission");
    h.port(1, &[ACK]);
    let a = h.wait(20);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed], "{a:?}");
    assert_eq!(h.r.stats().devices[&(1, 3)].retransmits, 0);
}

#[test]
fn result_time_out_classes_normal_and_long() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.port(1, &[ACK]);
    assert!(finished(&h.wait(49)).is_empty());
    assert_eq!(finished(&h.wait(1)), vec![CommandOutcome::NoResult]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"IX"));
    h.port(1, &[ACK]);
    assert!(finished(&h.wait(999)).is_empty(), "IX is long");
    assert_eq!(finished(&h.wait(1)), vec![CommandOutcome::NoResult]);
    assert_eq!(h.r.stats().devices[&(1, 3)].no_result, 2);
}

#[test]
fn command_without_result_waits_a_short_nic_window() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    let second = frame((G, 1, 4), 2, b"TU");
    let a = h.port(1, &[ACK]);
    assert!(port_writes(&a, 1).is_empty(), "bus held during the NIC window");
    let a = h.wait(5);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    h.link(CLIENT, &second);
    let a = h.port(1, &[ACK]);
    assert!(finished(&a).is_empty());
    let a = h.port(1, &[NIC]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
}

#[test]
fn device_255_written_once_without_ack_then_guard() {
    let mut h = H::new(&[1]);
    let cmd = frame((G, 1, 255), 2, b"HO");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    let next = frame((G, 1, 3), 2, b"AW");
    let a = h.link(CLIENT, &next);
    assert!(port_writes(&a, 1).is_empty(), "queued behind the guard");
    let a = h.wait(19);
    assert!(port_writes(&a, 1).is_empty(), "written once, no retransmission");
    let a = h.wait(1);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert_eq!(port_writes(&a, 1), vec![next]);
}

/// The device registry (gcud's /status and metrics) holds devices: a
/// broadcast to device 255 adds no row for the wildcard, which would read
/// as an offline gimbal, neither while it is on the bus nor after.
#[test]
fn a_broadcast_adds_no_wildcard_device_to_the_registry() {
    let mut h = H::new(&[1]);
    let broadcast = frame((G, 1, 255), 2, b"PL");
    let a = h.link(CLIENT, &broadcast);
    assert_eq!(port_writes(&a, 1), vec![broadcast]);
    let devices = |h: &H| h.r.stats().devices.keys().copied().collect::<Vec<_>>();
    assert_eq!(devices(&h), vec![], "while the broadcast is on the bus");
    let a = h.wait(20);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert_eq!(devices(&h), vec![], "after it");
    assert_eq!(h.r.stats().ports[&1].transactions, 1, "counted on its port");
    // A device that answers is in the registry; the wildcard still is not.
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 3), G, b"0"));
    h.link(CLIENT, &[ACK]);
    h.link(CLIENT, &frame((G, 1, 255), 2, b"PS"));
    assert_eq!(devices(&h), vec![(1, 3)]);
}

#[test]
fn a_late_or_duplicate_result_is_never_taken_for_the_next_exchange() {
    let mut h = H::new(&[1]);
    let mu = frame((G, 1, 3), 2, b"*mu1");
    h.link(CLIENT, &mu);
    let a = h.wait(10 + wire_ms(mu.len(), 9600));
    assert_eq!(port_writes(&a, 1), vec![mu], "ACK lost: retransmitted");
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"1"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    // The device executed it twice; the bus settles before the next exchange.
    let query = frame((G, 1, 3), 3, b"P?");
    let a = h.link(CLIENT, &query);
    assert!(port_writes(&a, 1).is_empty(), "settling");
    let a = h.port(1, &frame((2, 1, 3), G, b"1"));
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
    let a = h.wait(10);
    assert_eq!(port_writes(&a, 1), vec![query]);
    h.port(1, &[ACK]);
    // Same port and device, but for another source group: not this result.
    let a = h.port(1, &frame((2, 1, 3), G, b"1"));
    assert_eq!(dropped(&a), vec![DropReason::Unsolicited]);
    assert!(finished(&a).is_empty());
    let a = h.port(1, &frame((3, 1, 3), G, b"00000000"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert_eq!(
        link_writes(&a, CLIENT),
        Vec::<Vec<u8>>::new(),
        "behind the first result, awaiting its ACK"
    );
}

#[test]
fn stop_overtakes_queued_work() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.link(CLIENT, &frame((G, 1, 3), 2, b"HO"));
    h.link(CLIENT, &frame((G, 1, 4), 2, b"PL"));
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PS"));
    h.link(CLIENT, &frame((G, 1, 4), 2, b"HA"));
    // P? is in flight; after it, the stops in their order, then the rest.
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(port_writes(&a, 1), vec![vec![ACK], frame((G, 1, 3), 2, b"PS")]);
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 4), 2, b"HA")]);
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 3), 2, b"HO")]);
}

#[test]
fn stop_is_not_held_behind_a_long_ix_result_wait() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"IX"));
    h.port(1, &[ACK]);
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"HS"));
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 3), 2, b"HS")]);
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    // Other work waits for the set-aside IX: it could be answered with its header.
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    assert!(port_writes(&a, 1).is_empty());
    // The set-aside IX still takes its result; then the queued work goes.
    let a = h.port(1, &frame((2, 1, 3), G, b"0001000100010001"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), G, b"0001000100010001")]);
    assert_eq!(port_writes(&a, 1), vec![vec![ACK], frame((G, 1, 3), 2, b"P?")]);
}

#[test]
fn bounded_port_queue_drops_with_counter_and_warning_and_stops_have_their_own_room() {
    let mut h = H::with(&[1], |c| c.ports[0].stop_queue_bound = 2);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?")); // in flight
    for device in 4..8 {
        h.link(CLIENT, &frame((G, 1, device), 2, b"HO"));
    }
    let refused = frame((G, 1, 8), 2, b"HO");
    let a = h.link(CLIENT, &refused);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::QueueFull)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&refused, Some(Undelivered::QueueFull))],
        "no ACK: a report says why"
    );
    assert!(
        a.iter()
            .any(|x| matches!(x, Action::Event(e) if e.level() == sagebrush_gcu::Level::Warn))
    );
    // Work filled its part of the queue; stops still fit.
    let a = h.link(CLIENT, &frame((G, 1, 3), 2, b"PS"));
    assert!(finished(&a).is_empty());
    h.up(LinkId(9), LinkKind::Client);
    let a = h.link(LinkId(9), &frame((G, 1, 3), 2, b"PS"));
    assert!(
        finished(&a).is_empty() && link_writes(&a, LinkId(9)).is_empty(),
        "merged into the queued stop: it shares that stop's outcome"
    );
    let a = h.link(CLIENT, &frame((G, 1, 4), 2, b"PS"));
    assert!(finished(&a).is_empty());
    let a = h.link(CLIENT, &frame((G, 1, 5), 2, b"PS"));
    assert_eq!(
        finished(&a),
        vec![CommandOutcome::Dropped(DropReason::QueueFull)],
        "stops are bounded too"
    );
    let s = h.r.stats();
    assert_eq!(s.ports[&1].line.drops.get(DropReason::QueueFull), 2);
    assert_eq!(s.ports[&1].queue_high_water, 6);
    // The merged stop is ACKed when the queued one is delivered: P? (in
    // flight) gets its ACK and result, then the stops go first.
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(port_writes(&a, 1).last(), Some(&frame((G, 1, 3), 2, b"PS")));
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    assert_eq!(link_writes(&a, LinkId(9)), vec![vec![ACK]]);
}

#[test]
fn unknown_and_closed_ports_are_dropped_and_counted() {
    let mut h = H::new(&[1]);
    let to_port_9 = frame((G, 9, 3), 2, b"AW");
    let a = h.link(CLIENT, &to_port_9);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::UnknownPort)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&to_port_9, Some(Undelivered::NoSuchPort))]
    );
    h.link(CLIENT, &[ACK]);
    h.go(Input::PortLost { port: 1 });
    let to_port_1 = frame((G, 1, 3), 2, b"AW");
    let a = h.link(CLIENT, &to_port_1);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::PortClosed)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&to_port_1, Some(Undelivered::PortClosed))]
    );
    assert_eq!(h.r.stats().router.dropped.get(DropReason::UnknownPort), 1);
}

#[test]
fn lost_port_fails_in_flight_and_queued_then_recovers() {
    let mut h = H::new(&[1]);
    let in_flight = frame((G, 1, 3), 2, b"P?");
    let queued = frame((G, 1, 3), 2, b"HO");
    h.link(CLIENT, &in_flight);
    h.link(CLIENT, &queued);
    let a = h.go(Input::PortLost { port: 1 });
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::PortLost); 2]);
    // The client hears both, one unacknowledged report at a time: the port
    // is closed (04).
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&in_flight, Some(Undelivered::PortClosed))]
    );
    let a = h.link(CLIENT, &[ACK]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&queued, Some(Undelivered::PortClosed))]
    );
    h.link(CLIENT, &[ACK]);
    assert_eq!(h.r.stats().ports[&1].line.drops.get(DropReason::PortLost), 2);
    let a = h.go(Input::PortOpened { port: 1 });
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 9600 }));
    let cmd = frame((G, 1, 3), 2, b"AW");
    let a = h.link(CLIENT, &cmd);
    assert_eq!(port_writes(&a, 1), vec![cmd]);
}

#[test]
fn port_255_goes_to_every_port_and_each_result_names_its_port() {
    let mut h = H::new(&[1, 2]);
    let a = h.link(CLIENT, &frame((G, 255, 3), 2, b"AW"));
    assert_eq!(accepted(&a).len(), 1);
    assert_eq!(port_writes(&a, 1), vec![frame((G, 1, 3), 2, b"AW")]);
    assert_eq!(port_writes(&a, 2), vec![frame((G, 2, 3), 2, b"AW")]);
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"0"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), G, b"0")]);
    assert!(finished(&a).is_empty(), "one outcome once every port is done");
    h.port(2, &[ACK]);
    let a = h.port(2, &frame((2, 2, 3), G, b"4"));
    assert_eq!(finished(&a), vec![CommandOutcome::Result]);
    assert!(link_writes(&a, CLIENT).is_empty(), "one unacknowledged frame per link");
    let a = h.link(CLIENT, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 2, 3), G, b"4")]);
}

#[test]
fn fan_out_relays_one_nic_only_when_no_port_did_better() {
    let mut h = H::new(&[1, 2]);
    h.link(CLIENT, &frame((G, 255, 3), 2, b"XX"));
    let a = h.port(1, &[ACK, NIC]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![vec![ACK]],
        "delivered once a device has it"
    );
    let a = h.port(2, &[ACK, NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![NIC]]);
    assert_eq!(finished(&a), vec![CommandOutcome::Nic]);
}

#[test]
fn group_255_from_upstream_floods_downstream_never_back() {
    let mut h = H::new(&[1]);
    h.up(UP, LinkKind::Upstream);
    h.up(DOWN, LinkKind::Downstream);
    h.up(DOWN2, LinkKind::Downstream);
    let cmd = frame((255, 1, 3), 0, b"HO");
    let a = h.link(UP, &cmd);
    assert_eq!(link_writes(&a, UP), vec![vec![ACK]], "never back where it came from");
    assert_eq!(link_writes(&a, DOWN), vec![cmd.clone()]);
    assert_eq!(link_writes(&a, DOWN2), vec![cmd.clone()]);
    assert!(link_writes(&a, CLIENT).is_empty());
    assert_eq!(port_writes(&a, 1), vec![cmd.clone()]);
    // From a downstream GCU: executed here, not flooded.
    let from_down = frame((255, 1, 3), 7, b"HO");
    let a = h.link(DOWN, &from_down);
    assert_eq!(link_writes(&a, DOWN2), Vec::<Vec<u8>>::new());
    assert_eq!(link_writes(&a, UP), Vec::<Vec<u8>>::new());
    assert_eq!(h.r.stats().router.flooded, 2);
}

#[test]
fn other_groups_follow_static_then_learned_then_default_routes() {
    let mut h = H::with(&[1], |c| {
        c.static_routes.insert(7, DOWN2);
        c.default_upstream = Some(UP);
    });
    h.up(UP, LinkKind::Upstream);
    h.up(DOWN, LinkKind::Downstream);
    h.up(DOWN2, LinkKind::Downstream);
    // Learned: group 8 seen on DOWN (a report and the answer go back).
    h.link(DOWN, &frame((G, 0, 0), 8, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(DOWN, &[ACK]);
    let to7 = frame((7, 1, 1), 2, b"HO");
    let a = h.link(CLIENT, &to7);
    assert_eq!(link_writes(&a, DOWN2), vec![to7]);
    assert_eq!(finished(&a), vec![CommandOutcome::Forwarded(DOWN2)]);
    let to8 = frame((8, 1, 1), 2, b"HO");
    let a = h.link(CLIENT, &to8);
    assert_eq!(link_writes(&a, DOWN), vec![to8]);
    let to9 = frame((9, 1, 1), 2, b"HO");
    let a = h.link(CLIENT, &to9);
    assert_eq!(link_writes(&a, UP), vec![to9.clone()]);
    // Static route down: learned would be used; default down too: the
    // client hears that the route's link is down (07), not "no route" (06).
    let a = h.go(Input::LinkDown { link: UP });
    // The first to9 was written to UP and not yet ACKed there: it may have
    // got through, so the client hears "not confirmed" (0B), not 07.
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&to9, Some(Undelivered::NotConfirmed))]
    );
    // The client takes the report of the first to9 (its link went down):
    // the same frame after it is a new command.
    h.link(CLIENT, &[ACK]);
    let a = h.link(CLIENT, &to9);
    assert_eq!(link_writes(&a, CLIENT), vec![report(&to9, Some(Undelivered::LinkDown))]);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::LinkDown)]);
    assert_eq!(dropped(&a), vec![DropReason::LinkDown]);
    assert_eq!(h.r.stats().router.frame_drops.get(DropReason::LinkDown), 1);
    assert_eq!(h.r.stats().router.frame_drops.get(DropReason::NoRoute), 0);
}

#[test]
fn a_frame_is_never_routed_back_to_its_link() {
    let mut h = H::new(&[1]);
    h.up(UP, LinkKind::Upstream);
    let cmd = frame((9, 1, 1), 0, b"HO");
    let a = h.link(UP, &cmd);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::Loop)]);
    assert_eq!(
        link_writes(&a, UP),
        vec![vec![ACK], report(&cmd, Some(Undelivered::Loop))],
        "hop by hop on a GCU link, then the report"
    );
}

#[test]
fn disallowed_source_group_is_dropped_and_counted() {
    let mut h = H::new(&[1]);
    h.go(Input::LinkUp {
        link: LinkId(9),
        config: LinkConfig::new(LinkKind::Client, SourceFilter::Only(vec![20])),
    });
    let spoof = frame((G, 1, 3), 21, b"PL");
    let a = h.link(LinkId(9), &spoof);
    assert_eq!(
        link_writes(&a, LinkId(9)),
        vec![report(&spoof, Some(Undelivered::SourceNotAllowed))]
    );
    assert!(accepted(&a).is_empty());
    assert_eq!(dropped(&a), vec![DropReason::SourceNotAllowed]);
    // The wildcard is refused on any link, our own group on links to other
    // GCUs (a loop or a spoof). A client acts for this GCU (Figure 7: "a
    // command issued from GCU-2") and may speak as its group.
    let a = h.link(CLIENT, &frame((G, 1, 3), 255, b"PL"));
    assert!(accepted(&a).is_empty());
    h.up(UP, LinkKind::Upstream);
    let a = h.link(UP, &frame((G, 1, 3), G, b"PL"));
    assert!(accepted(&a).is_empty());
    assert_eq!(dropped(&a), vec![DropReason::SourceNotAllowed]);
    let a = h.link(CLIENT, &frame((G, 1, 3), G, b"PL"));
    assert_eq!(accepted(&a).len(), 1, "a client may speak as our own group");
    let a = h.link(LinkId(9), &frame((G, 1, 3), 20, b"PL"));
    assert_eq!(accepted(&a).len(), 1);
    assert_eq!(
        h.r.stats().links[&LinkId(9)]
            .line
            .drops
            .get(DropReason::SourceNotAllowed),
        1
    );
}

#[test]
fn frames_sent_on_links_are_retransmitted_on_nak_and_time_out_up_to_the_count() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    let result = frame((2, 1, 3), G, b"0");
    let a = h.port(1, &result);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    let a = h.link(CLIENT, &[NAK]);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    let a = h.wait(10);
    assert_eq!(link_writes(&a, CLIENT), vec![result.clone()]);
    let a = h.wait(10);
    assert!(link_writes(&a, CLIENT).is_empty(), "retries = 2: given up");
    assert_eq!(dropped(&a), vec![DropReason::LinkNoAck]);
    let s = h.r.stats().links[&CLIENT];
    assert_eq!((s.line.retransmits, s.failed, s.delivered, s.queued), (2, 1, 0, 1));
}

#[test]
fn answers_of_forwarded_commands_go_back_along_the_reverse_path_never_to_a_wrong_client() {
    let mut h = H::new(&[1]);
    let other = LinkId(6);
    h.up(other, LinkKind::Client);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    // Two clients (groups 0 and 1) ask GCU 7 the same question.
    h.link(CLIENT, &frame((7, 1, 3), 0, b"*mu1"));
    h.link(other, &frame((7, 1, 3), 1, b"*mu2"));
    h.link(DOWN, &[ACK]);
    h.link(DOWN, &[ACK]);
    let a = h.link(DOWN, &frame((1, 1, 3), 7, b"2"));
    assert_eq!(link_writes(&a, other), vec![frame((1, 1, 3), 7, b"2")]);
    assert!(link_writes(&a, CLIENT).is_empty());
    let a = h.link(DOWN, &frame((0, 1, 3), 7, b"1"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((0, 1, 3), 7, b"1")]);
    h.link(CLIENT, &[ACK]);
    h.link(other, &[ACK]);
    // Sharing one source group, their answers cannot be told apart (the
    // first command may never get its result): dropped, not guessed.
    h.link(CLIENT, &frame((7, 1, 3), 0, b"*mu3"));
    h.link(other, &frame((7, 1, 3), 0, b"*mu4"));
    h.link(DOWN, &[ACK]);
    h.link(DOWN, &[ACK]);
    let a = h.link(DOWN, &frame((0, 1, 3), 7, b"4"));
    assert_eq!(dropped(&a), vec![DropReason::AmbiguousAnswer]);
    assert!(link_writes(&a, CLIENT).is_empty() && link_writes(&a, other).is_empty());
    // The same for a `?`.
    let a = h.link(DOWN, &[NIC]);
    assert_eq!(dropped(&a), vec![DropReason::AmbiguousAnswer]);
    assert!(link_writes(&a, CLIENT).is_empty() && link_writes(&a, other).is_empty());
}

/// The reverse path waits for a whole port transaction at the next GCU
/// (assumed configured like the slowest port here, every retry included),
/// not only the configured answer time-out: an answer from behind a slow
/// bus still reaches its origin.
#[test]
fn a_forwarded_command_waits_for_a_whole_slow_port_exchange_at_the_next_gcu() {
    let mut h = H::with(&[1], |c| c.ports[0] = PortConfig::at_rate(1, 1200));
    assert!(h.r.stats().ports[&1].bps == 1200);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    // From a client: its group is never routed, only the reverse path
    // carries the answer back.
    h.link(CLIENT, &frame((7, 1, 3), 2, b"P?"));
    h.link(DOWN, &[ACK]);
    // 1200 bit/s, 4 tries of a longest frame and its ACK wait, then the
    // result wait: about 12 s, well past the configured 3 s.
    h.wait(11_000);
    let a = h.link(DOWN, &frame((2, 1, 3), 7, b"00000000"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), 7, b"00000000")], "{a:?}");
}

#[test]
fn nic_from_another_gcu_is_relayed_to_the_origin() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(CLIENT, &frame((7, 1, 3), 2, b"XX"));
    h.link(DOWN, &[ACK]);
    let a = h.link(DOWN, &[NIC]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![NIC]]);
}

#[test]
fn dead_man_stops_the_motions_of_a_link_that_goes_down() {
    let mut h = H::new(&[1]);
    h.up(DOWN, LinkKind::Downstream);
    h.link(DOWN, &frame((G, 0, 0), 7, b"AW"));
    h.link(DOWN, &[ACK]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(5);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"ZI"));
    h.link(CLIENT, &frame((G, 1, 4), 2, b"TU")); // still queued: cancelled
    h.link(CLIENT, &frame((7, 2, 2), 2, b"FF")); // on another GCU: stop routed there
    h.link(DOWN, &[ACK]); // the report of AW
    h.link(DOWN, &[ACK]); // its answer
    h.link(DOWN, &[ACK]); // FF
    let a = h.go(Input::LinkDown { link: CLIENT });
    assert_eq!(
        finished(&a).first(),
        Some(&CommandOutcome::Dropped(DropReason::OriginGone)),
        "queued TU cancelled"
    );
    let stops = dead_man_stops(&a);
    assert_eq!(stops.len(), 4, "{stops:?}");
    assert!(stops.contains(&(Address::new(G, 1, 3), "PS")));
    assert!(stops.contains(&(Address::new(G, 1, 3), "ZS")));
    assert!(stops.contains(&(Address::new(7, 2, 2), "FS")));
    assert!(stops.contains(&(Address::new(G, 1, 4), "TS")));
    assert_eq!(link_writes(&a, DOWN), vec![frame((7, 2, 2), G, b"FS")]);
    // ZI in flight; the stops go next, before anything else, and each is
    // written to the port (the events above are only the router's account).
    assert!(port_writes(&a, 1).is_empty(), "ZI still awaits its ACK");
    let mut wire = Vec::new();
    for _ in 0..4 {
        wire.extend(port_writes(&h.port(1, &[ACK]), 1));
        wire.extend(port_writes(&h.wait(5), 1));
    }
    assert!(
        wire[0] == frame((G, 1, 3), G, b"PS") || wire[0] == frame((G, 1, 3), G, b"ZS"),
        "{wire:?}"
    );
    let mut sorted = wire.clone();
    sorted.sort();
    let mut want = vec![
        frame((G, 1, 3), G, b"PS"),
        frame((G, 1, 3), G, b"ZS"),
        frame((G, 1, 4), G, b"TS"),
    ];
    want.sort();
    assert_eq!(sorted, want, "each stop written to port 1 once; nothing else: {wire:?}");
    assert_eq!(h.r.in_progress(), 0, "every stop acknowledged");
    assert_eq!(h.r.stats().router.dead_man_stops, 4);
}

#[test]
fn rate_change_acknowledged_by_every_device_switches_the_port() {
    let mut h = H::with(&[1], |c| c.ports[0].devices = Some(vec![3, 4]));
    h.link(CLIENT, &frame((G, 1, 3), 2, b"C5"));
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert!(
        !a.iter().any(|x| matches!(x, Action::SetPortRate { .. })),
        "device 4 not yet"
    );
    h.link(CLIENT, &frame((G, 1, 4), 2, b"C5"));
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 38400 }));
    assert_eq!(h.r.stats().ports[&1].bps, 38400);
}

#[test]
fn rate_change_to_device_255_switches_the_port_reserved_rates_never() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 255), 2, b"C7"));
    let a = h.wait(20);
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 115200 }));
    h.link(CLIENT, &frame((G, 1, 255), 2, b"C9"));
    let a = h.wait(20);
    assert_eq!(finished(&a), vec![CommandOutcome::Completed]);
    assert!(!a.iter().any(|x| matches!(x, Action::SetPortRate { .. })));
    // Learned devices: the one that answered switches the port alone.
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 3), G, b"0"));
    h.link(CLIENT, &[ACK]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"C2"));
    h.port(1, &[ACK]);
    let a = h.wait(5);
    assert!(a.contains(&Action::SetPortRate { port: 1, bps: 4800 }));
}

#[test]
fn statistics_count_lines_devices_and_last_seen() {
    let mut h = H::new(&[1]);
    h.now = 42;
    h.link(CLIENT, &frame((G, 1, 3), 2, b"AW"));
    h.port(1, &[ACK]);
    h.port(1, &frame((2, 1, 3), G, b"0"));
    let s = h.r.stats();
    assert_eq!(s.ports[&1].line.frames_out, 1);
    assert_eq!(s.ports[&1].line.last_seen, Some(42));
    assert_eq!(s.links[&CLIENT].line.last_seen, Some(42));
    assert_eq!(s.devices[&(1, 3)].commands, 1);
    assert_eq!(s.devices[&(1, 3)].last_seen, Some(42));
    assert_eq!(s.router.accepted, 1);
    assert_eq!(s.router.results, 1);
    assert_eq!(s.router.finished(), 1);
    assert_eq!(s.ports[&1].transactions, 1);
}

#[test]
fn link_going_down_drops_its_queue_and_answers_for_it_count_origin_gone() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.port(1, &[ACK]);
    let a = h.go(Input::LinkDown { link: CLIENT });
    let gone: Vec<_> = a
        .iter()
        .filter_map(|x| match x {
            Action::LinkGone { link, stats } => Some((*link, stats.line.frames_in)),
            _ => None,
        })
        .collect();
    assert_eq!(gone, vec![(CLIENT, 1)], "its final counters go to the daemon");
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::OriginGone)]);
    assert!(!h.r.link_is_up(CLIENT));
    assert!(
        !h.r.stats().links.contains_key(&CLIENT),
        "the router keeps nothing of a link gone"
    );
}

/// Links going down together can owe more stops than a port's stop queue
/// holds: dead-man stops are never dropped for a full queue.
#[test]
fn dead_man_stops_always_fit_the_port_queue() {
    let mut h = H::with(&[1], |c| c.ports[0].stop_queue_bound = 1);
    for device in 3..=6 {
        h.link(CLIENT, &frame((G, 1, device), 2, b"PL"));
        h.port(1, &[ACK]);
        h.wait(5);
    }
    let a = h.go(Input::LinkDown { link: CLIENT });
    assert!(
        !finished(&a).contains(&CommandOutcome::Dropped(DropReason::QueueFull)),
        "{:?}",
        finished(&a)
    );
    let mut stopped = port_writes(&a, 1);
    for _ in 0..8 {
        stopped.extend(port_writes(&h.port(1, &[ACK]), 1));
        stopped.extend(port_writes(&h.wait(200), 1));
    }
    for device in 3..=6 {
        assert!(
            stopped.contains(&frame((G, 1, device), G, b"PS")),
            "device {device}: {stopped:?}"
        );
    }
    assert_eq!(h.r.stats().router.dead_man_stops, 4);
}

/// A dead-man stop that no device acknowledges (a burst of noise, say) is
/// sent again, round after round, before the router gives up.
#[test]
fn unacknowledged_dead_man_stop_is_sent_again() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(100);
    let mut writes = port_writes(&h.go(Input::LinkDown { link: CLIENT }), 1);
    writes.extend(port_writes(&h.wait(60_000), 1));
    let stop = frame((G, 1, 3), G, b"PS");
    let retries = u64::from(port_config(1).retries);
    let sent = writes.iter().filter(|w| **w == stop).count() as u64;
    assert_eq!(
        sent,
        5 * (retries + 1),
        "five rounds of {} transmissions: {writes:?}",
        retries + 1
    );
    let unreachable = h.r.stats().router.unreachable;
    assert_eq!(unreachable, 5, "each round ends unreachable");
    assert_eq!(h.r.stats().router.dead_man_stops, 1, "one motion stopped");
}

/// A lease stop no device acknowledges goes again like a dead-man stop,
/// and every round is told as what it is: a lease that ran out, counted
/// once (one motion stopped), never a dead-man stop.
#[test]
fn unacknowledged_lease_stop_is_sent_again_and_told_as_a_lease_stop() {
    let mut h = H::new(&[1]);
    h.go(Input::LinkUp {
        link: LinkId(9),
        config: LinkConfig {
            motion_lease: Some(500),
            ..LinkConfig::new(LinkKind::Client, SourceFilter::Any)
        },
    });
    h.link(LinkId(9), &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    let a = h.wait(60_000);
    let stop = frame((G, 1, 3), G, b"PS");
    let retries = u64::from(port_config(1).retries);
    let sent = port_writes(&a, 1).iter().filter(|w| **w == stop).count() as u64;
    assert_eq!(sent, 5 * (retries + 1), "five rounds of {} transmissions", retries + 1);
    let leases = a
        .iter()
        .filter(|x| {
            matches!(
                x,
                Action::Event(RouterEvent::IssuedStop {
                    stop: "PS",
                    cause: StopCause::Lease,
                    ..
                })
            )
        })
        .count();
    assert_eq!(leases, 5, "each round told as a lease stop");
    assert_eq!(dead_man_stops(&a), vec![], "no round is a dead-man stop");
    let s = h.r.stats().router;
    assert_eq!((s.lease_stops, s.dead_man_stops), (1, 0), "one motion stopped");
}

#[test]
fn reconfigure_leaves_unchanged_ports_alone_and_stops_motions_before_closing_a_port() {
    let mut h = H::new(&[1, 2]);
    // Port 1: a query in flight. Port 2: a slew running.
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?"));
    h.link(CLIENT, &frame((G, 2, 4), 2, b"PL"));
    h.port(2, &[ACK]);
    h.wait(6);
    // New configuration: port 1 as it was, port 2 gone, port 3 new.
    let mut config = RouterConfig::new(G);
    config.name = "test gcu".into();
    config.serial = "SN-5".into();
    config.ports = vec![port_config(1), port_config(3)];
    config.links.ack_timeout = 10;
    config.links.retries = 2;
    let mut a = Outbox::new();
    h.r.reconfigure(h.now, config.clone(), &[], &mut a).expect("valid");
    assert_eq!(
        port_writes(&a, 2),
        vec![frame((G, 2, 4), G, b"PS")],
        "the slew is stopped first"
    );
    assert!(port_writes(&a, 1).is_empty(), "port 1 is not touched");
    assert!(h.r.closed_ports().is_empty(), "port 2 is busy with its stop");
    let refused = frame((G, 2, 4), 2, b"HO");
    let a = h.link(CLIENT, &refused);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&refused, Some(Undelivered::ShuttingDown))]
    );
    h.link(CLIENT, &[ACK]); // the client acknowledges the report
    // The query on port 1 goes on: delivered, then answered.
    let a = h.port(1, &[ACK]);
    assert_eq!(link_writes(&a, CLIENT), vec![vec![ACK]]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(link_writes(&a, CLIENT), vec![frame((2, 1, 3), G, b"00000000")]);
    h.port(2, &[ACK]);
    h.wait(10);
    assert_eq!(h.r.closed_ports(), vec![2]);
    let mut a = Outbox::new();
    h.r.port_closed(h.now, 2, &mut a);
    assert!(!h.r.has_port(2));
    assert!(h.r.has_port(3));
    let a = h.link(CLIENT, &frame((G, 2, 4), 2, b"HO"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::UnknownPort)]);
    // The group cannot change while running.
    config.group = 6;
    assert!(h.r.reconfigure(h.now, config, &[], &mut Outbox::new()).is_err());
}

#[test]
fn shutdown_stops_every_owned_motion_and_refuses_new_commands() {
    let mut h = H::new(&[1]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(6);
    h.link(CLIENT, &frame((G, 1, 4), 2, b"ZI"));
    h.port(1, &[ACK]);
    h.wait(6);
    assert_eq!(h.r.owned_motions(), 2);
    let a = h.go(Input::Shutdown);
    let stops = dead_man_stops(&a);
    assert_eq!(
        stops,
        vec![(Address::new(G, 1, 3), "PS"), (Address::new(G, 1, 4), "ZS")]
    );
    // The stops themselves, on the wire: the events are only the router's account.
    let mut wire = port_writes(&a, 1);
    assert_eq!(h.r.owned_motions(), 0);
    assert!(h.r.in_progress() > 0, "the daemon waits for the stops");
    let refused = frame((G, 1, 3), 2, b"PR");
    let a = h.link(CLIENT, &refused);
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::ShuttingDown)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&refused, Some(Undelivered::ShuttingDown))]
    );
    for _ in 0..2 {
        wire.extend(port_writes(&h.port(1, &[ACK]), 1));
        wire.extend(port_writes(&h.wait(10), 1));
    }
    assert_eq!(
        wire,
        vec![frame((G, 1, 3), G, b"PS"), frame((G, 1, 4), G, b"ZS")],
        "each owned motion's stop is written to its port once; nothing else"
    );
    assert_eq!(h.r.in_progress(), 0);
    assert_eq!(h.r.stats().router.shutdown_stops, 2);
}

#[test]
fn ports_serve_clients_round_robin_and_a_flood_costs_only_its_sender() {
    let other = LinkId(9);
    let mut h = H::new(&[1]);
    h.up(other, LinkKind::Client);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P?")); // in flight
    for device in 4..8 {
        h.link(CLIENT, &frame((G, 1, device), 2, b"HO")); // fills the queue (bound 4)
    }
    // The queue is full of CLIENT's work: the other client's command takes
    // the place of CLIENT's newest, which CLIENT is told was not delivered.
    let a = h.link(other, &frame((G, 1, 9), 3, b"P?"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::QueueFull)]);
    assert_eq!(
        link_writes(&a, CLIENT),
        vec![report(&frame((G, 1, 7), 2, b"HO"), Some(Undelivered::QueueFull))]
    );
    assert!(
        link_writes(&a, other).is_empty(),
        "the other client's command is queued"
    );
    // CLIENT's next command is refused: it holds the most.
    let a = h.link(CLIENT, &frame((G, 1, 8), 2, b"HO"));
    assert_eq!(finished(&a), vec![CommandOutcome::Dropped(DropReason::QueueFull)]);
    // Round robin: after CLIENT's P?, the other client's P? goes next,
    // ahead of CLIENT's older queued work.
    h.port(1, &[ACK]);
    let a = h.port(1, &frame((2, 1, 3), G, b"00000000"));
    assert_eq!(port_writes(&a, 1).last(), Some(&frame((G, 1, 9), 3, b"P?")));
}

#[test]
fn control_bytes_from_a_client_in_the_wrong_direction_are_stray_not_drops() {
    let mut h = H::new(&[1]);
    let a = h.link(CLIENT, &[NIC, ACK, NAK]);
    assert!(dropped(&a).is_empty() && link_writes(&a, CLIENT).is_empty(), "{a:?}");
    let s = h.r.stats();
    assert_eq!(s.links[&CLIENT].line.stray_bytes, 3);
    assert_eq!(s.router.frame_drops.total(), 0);
}

/// Payload bytes outside printable ASCII (an `*xpt` may carry any byte to
/// an auxiliary port) are relayed unchanged: the frame is length-delimited,
/// and what a payload means is the device's to judge (NIC).
#[test]
fn payload_bytes_outside_printable_ascii_are_relayed_unchanged() {
    let mut h = H::new(&[1]);
    let raw = frame((G, 1, 3), 2, b"*x0t\x01\xF8\x06\x15?");
    let a = h.link(CLIENT, &raw);
    assert_eq!(port_writes(&a, 1), vec![raw]);
}

/// Issue 20.5: a device that answered before goes silent to every try of a
/// goto, and its ACK comes late, after the GCU gave up. Nothing is written
/// during the late-answer guard, so that ACK cannot be taken for the next
/// command's: the next goto is written after the guard and, with no ACK of
/// its own, is reported undelivered, never ACKed.
#[test]
fn a_late_ack_is_never_taken_for_the_next_commands() {
    let mut h = H::new(&[1]);
    let guard = port_config(1).late_answer_guard;
    h.link(CLIENT, &frame((G, 1, 3), 2, b"HO"));
    h.port(1, &[ACK]);
    h.wait(100);
    let report_of = |out: &Outbox| {
        link_writes(out, CLIENT).iter().find_map(|w| {
            Frame::parse(w)
                .ok()
                .and_then(|(f, _)| DeliveryReport::parse(f.payload()).ok())
        })
    };
    let acked = |out: &Outbox| link_writes(out, CLIENT).iter().any(|w| w == &[ACK]);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"P07D001F4"));
    // Silent to every try: given up and reported 01.
    let mut first = None;
    for _ in 0..1_000 {
        let out = h.wait(1);
        assert!(!acked(&out));
        first = report_of(&out);
        if first.is_some() {
            break;
        }
    }
    assert_eq!(first.expect("a report").failure, Some(Undelivered::DeviceSilent));
    // Later than the one ACK time-out of quiet after a retransmitted
    // exchange, still within the late-answer guard.
    let past_settle = port_config(1).ack_timeout + 5;
    assert!(past_settle < guard);
    assert!(!acked(&h.wait(past_settle)));
    let second = frame((G, 1, 3), 2, b"P00640064");
    let a = h.link(CLIENT, &second);
    assert!(port_writes(&a, 1).is_empty(), "the bus is quiet during the guard");
    // The first goto's ACK arrives late, within the guard.
    let late = h.port(1, &[ACK]);
    assert!(!acked(&late), "a late ACK is not the second goto's");
    // After the guard the second goto goes out; it gets no ACK of its own.
    let out = h.wait(guard - past_settle);
    assert!(port_writes(&out, 1).contains(&second), "written after the guard");
    assert!(!acked(&out));
    let mut report = report_of(&out);
    for _ in 0..100 {
        if report.is_some() {
            break;
        }
        let out = h.wait(10);
        assert!(!acked(&out), "never ACKed");
        report = report_of(&out);
    }
    assert_eq!(report.expect("a report").failure, Some(Undelivered::DeviceSilent));
}

/// Issue 20.2, seeds 21565, 22265 and 51013 of the network simulation:
/// behind a device server that stalls, a command the GCU gave up on (`0B`)
/// still runs when the server resumes, and its ACK and result come then.
/// Neither may be taken for the command on the bus at that moment (another
/// client's): that command is `0B not confirmed` too, the late result goes
/// to nobody, and the bus serves again once it has been quiet.
#[test]
fn behind_a_stalled_device_server_a_late_answer_is_nobodys() {
    const OTHER: LinkId = LinkId(6);
    let mut h = H::with(&[1], |c| c.ports[0].buffered = true);
    h.up(OTHER, LinkKind::Client);
    let quiet_time = port_config(1).late_answer_guard.max(port_config(1).ack_timeout);
    let reports = |out: &Outbox, link: LinkId| -> Vec<Vec<u8>> {
        link_writes(out, link).into_iter().filter(|w| w.len() > 1).collect()
    };
    // Several inputs at one instant, into one outbox.
    let at_once = |h: &mut H, inputs: &[(Option<LinkId>, Vec<u8>)]| {
        let mut all = Outbox::new();
        for (link, bytes) in inputs {
            let input = match link {
                Some(link) => Input::Bytes {
                    line: LineId::Link(*link),
                    bytes,
                },
                None => Input::Bytes {
                    line: LineId::Port(1),
                    bytes,
                },
            };
            h.r.handle(h.now, input, &mut all);
        }
        all
    };
    // Client 1's query waits in the stalled server: no ACK, reported 0B.
    let query = frame((G, 1, 3), 2, b"P?");
    let out = h.link(CLIENT, &query);
    assert_eq!(port_writes(&out, 1), vec![query.clone()]);
    let mut told = Vec::new();
    for _ in 0..100 {
        told = reports(&h.wait(1), CLIENT);
        if !told.is_empty() {
            break;
        }
    }
    assert_eq!(told, vec![report(&query, Some(Undelivered::NotConfirmed))]);
    h.link(CLIENT, &[ACK]);
    // The other client's AW (same source group, same device) goes out.
    let aw = frame((G, 1, 3), 2, b"AW");
    let mut written = port_writes(&h.link(OTHER, &aw), 1);
    for _ in 0..100 {
        if !written.is_empty() {
            break;
        }
        written = port_writes(&h.wait(1), 1);
    }
    assert_eq!(written, vec![aw.clone()]);
    // The server resumes: the query's ACK and result arrive now.
    let late = at_once(&mut h, &[(None, vec![ACK]), (None, frame((2, 1, 3), G, b"00000000"))]);
    assert!(
        !link_writes(&late, OTHER).contains(&vec![ACK]),
        "the query's late ACK is not the AW's"
    );
    assert_eq!(
        reports(&late, OTHER),
        vec![report(&aw, Some(Undelivered::NotConfirmed))],
        "the AW is not confirmed, and the query's result is not its"
    );
    assert!(link_writes(&late, CLIENT).is_empty(), "client 1 was told already");
    h.link(OTHER, &[ACK]);
    // The AW's own answer comes during the quiet: nobody's either.
    h.now += 2;
    let quiet = at_once(&mut h, &[(None, vec![ACK]), (None, frame((2, 1, 3), G, b"0"))]);
    assert_eq!(dropped(&quiet), vec![DropReason::Unsolicited]);
    assert!(link_writes(&quiet, OTHER).is_empty() && link_writes(&quiet, CLIENT).is_empty());
    // Quiet since the last byte heard, the bus serves again as usual.
    let again = frame((G, 1, 3), 2, b"D?");
    let out = h.link(OTHER, &again);
    assert!(port_writes(&out, 1).is_empty(), "quiet after the late answers");
    let out = h.wait(quiet_time);
    assert_eq!(port_writes(&out, 1), vec![again]);
    let out = h.port(1, &[ACK]);
    assert_eq!(link_writes(&out, OTHER), vec![vec![ACK]], "delivered");
}

/// A client's PL acknowledged on port 1, the client gone: the dead-man PS is
/// on the bus, and another client's `P?` to the same device queued behind it.
/// Returns the stop and the query frames.
fn dead_man_stop_on_the_bus_and_a_query_behind(tweak: impl FnOnce(&mut RouterConfig)) -> (H, Vec<u8>, Vec<u8>) {
    const OTHER: LinkId = LinkId(6);
    let mut h = H::with(&[1], tweak);
    h.up(OTHER, LinkKind::Client);
    h.link(CLIENT, &frame((G, 1, 3), 2, b"PL"));
    h.port(1, &[ACK]);
    h.wait(100);
    let stop = frame((G, 1, 3), G, b"PS");
    let out = h.go(Input::LinkDown { link: CLIENT });
    assert_eq!(port_writes(&out, 1), vec![stop.clone()]);
    let query = frame((G, 1, 3), 2, b"P?");
    assert!(
        port_writes(&h.link(OTHER, &query), 1).is_empty(),
        "queued behind the stop"
    );
    (h, stop, query)
}

/// Seed 33315 of the network simulation: behind a device server nothing is
/// retransmitted, so a dead-man stop the device NAKs is given up at once;
/// its next round must still go out before other work queued meanwhile.
#[test]
fn a_nakked_dead_man_stop_goes_again_before_queued_work() {
    let (mut h, stop, query) = dead_man_stop_on_the_bus_and_a_query_behind(|c| c.ports[0].buffered = true);
    // The device NAKs the stop: given up (no retransmission into a server).
    let mut wire = port_writes(&h.port(1, &[NAK]), 1);
    for _ in 0..100 {
        if !wire.is_empty() {
            break;
        }
        wire = port_writes(&h.wait(1), 1);
    }
    assert_eq!(wire, vec![stop], "the stop's next round first");
    // Acknowledged this time; then the query goes out.
    let mut wire = port_writes(&h.port(1, &[ACK]), 1);
    wire.extend(port_writes(&h.wait(100), 1));
    assert_eq!(wire, vec![query], "then the query");
}

/// Seed 135037 of the network simulation: a client's command is reported
/// undelivered, the report is damaged on its way, and the client (no ACK)
/// retransmits the command. The report is still unacknowledged on the
/// client's line, so the client has no outcome yet: the identical frame is
/// its retransmission, never a new command (that one's ACK followed by the
/// first one's repeated report would be two outcomes to the client).
#[test]
fn a_retransmission_while_its_report_is_unacknowledged_is_not_a_new_command() {
    let mut h = H::new(&[1]);
    let home = frame((G, 1, 3), 2, b"HO");
    let said = report(&home, Some(Undelivered::DeviceSilent));
    let mut port = port_writes(&h.link(CLIENT, &home), 1);
    let mut told = Vec::new();
    for _ in 0..1_000 {
        let out = h.wait(1);
        port.extend(port_writes(&out, 1));
        told = link_writes(&out, CLIENT);
        if !told.is_empty() {
            break;
        }
    }
    assert_eq!(told, vec![said.clone()], "silent device: reported");
    assert_eq!(port.len(), 3, "three tries: {port:?}");
    // The report was damaged on the way: the client retransmits its HO.
    let out = h.link(CLIENT, &home);
    assert!(accepted(out.actions()).is_empty(), "not a new command");
    assert!(link_writes(&out, CLIENT).is_empty(), "no ACK");
    assert_eq!(h.r.stats().links[&CLIENT].repeats, 1);
    // The report comes again; acknowledged, the outcome is the client's.
    let mut again = Vec::new();
    for _ in 0..100 {
        let out = h.wait(1);
        assert!(port_writes(&out, 1).is_empty(), "not executed again");
        again = link_writes(&out, CLIENT);
        if !again.is_empty() {
            break;
        }
    }
    assert_eq!(again, vec![said]);
    h.link(CLIENT, &[ACK]);
    // After the outcome, an identical frame is a new command.
    let out = h.link(CLIENT, &home);
    assert_eq!(port_writes(&out, 1), vec![home]);
}

/// Seed 232276 of the network simulation: with a late-answer guard of 0, a
/// dead-man stop to a device that answered before went silent to every try;
/// its next round must still go out before other work queued meanwhile (the
/// one ACK time-out of quiet after any give-up holds with any guard).
#[test]
fn with_no_late_answer_guard_a_silent_dead_man_stop_still_goes_again_first() {
    let (mut h, stop, query) = dead_man_stop_on_the_bus_and_a_query_behind(|c| c.ports[0].late_answer_guard = 0);
    // Silent to every try: the first write after the give-up is the stop.
    let tries = u64::from(port_config(1).retries) + 1;
    let mut wire = Vec::new();
    for _ in 0..1_000 {
        wire.extend(port_writes(&h.wait(1), 1));
        if wire.len() as u64 > tries - 1 {
            break;
        }
    }
    assert_eq!(wire.len() as u64, tries, "{wire:?}");
    assert_eq!(wire.last(), Some(&stop), "the stop's next round first: {wire:?}");
    assert!(!wire.contains(&query), "{wire:?}");
}

/// Issue 24 (quiet logs): a device's answering is told once per change
/// (`DeviceState`), at WARN when one that answered goes silent, not once
/// per command to it; an address that never answered (a scan's probe) is
/// no device and no warning at all.
#[test]
fn a_device_going_silent_is_told_once_and_a_silent_probe_not_at_all() {
    use sagebrush_gcu::Level;
    let mut h = H::new(&[1]);
    let mut events: Vec<RouterEvent> = Vec::new();
    fn keep(events: &mut Vec<RouterEvent>, out: &Outbox) {
        for a in out.actions() {
            if let Action::Event(e) = a {
                events.push(e.clone());
            }
        }
    }
    let state = |events: &[RouterEvent]| -> Vec<(u8, bool, bool, Level)> {
        events
            .iter()
            .filter_map(|e| match e {
                RouterEvent::DeviceState {
                    device, online, first, ..
                } => Some((*device, *online, *first, e.level())),
                _ => None,
            })
            .collect()
    };
    // It answers: once, at DEBUG (a device appearing is no warning).
    keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PL")));
    keep(&mut events, &h.port(1, &[ACK]));
    keep(&mut events, &h.wait(10));
    keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PS")));
    keep(&mut events, &h.port(1, &[ACK]));
    keep(&mut events, &h.wait(10));
    assert_eq!(state(&events), vec![(12, true, true, Level::Debug)]);
    // Silent to three commands: one WARN, and the commands' own ends are DEBUG.
    events.clear();
    for _ in 0..3 {
        keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PL")));
        keep(&mut events, &h.wait(1_000));
    }
    assert_eq!(state(&events), vec![(12, false, false, Level::Warn)]);
    // (This test's client never acknowledges its reports: those drops
    // are the client's, not the device's.)
    let warnings: Vec<String> = events
        .iter()
        .filter(|e| e.level() == Level::Warn)
        .filter(|e| {
            !matches!(
                e,
                RouterEvent::Dropped {
                    reason: DropReason::LinkNoAck,
                    ..
                }
            )
        })
        .map(|e| e.to_string())
        .collect();
    assert_eq!(warnings, ["port 1 device 12 went silent: no ACK after all retries"]);
    // It answers again: INFO, once.
    events.clear();
    keep(&mut events, &h.link(CLIENT, &frame((G, 1, 12), 2, b"PS")));
    keep(&mut events, &h.port(1, &[ACK]));
    keep(&mut events, &h.wait(10));
    assert_eq!(state(&events), vec![(12, true, false, Level::Info)]);
    // A scan's probes of empty addresses: nothing above DEBUG.
    events.clear();
    for device in 20..25 {
        keep(&mut events, &h.link(CLIENT, &frame((G, 1, device), 2, b"D?")));
        keep(&mut events, &h.wait(1_000));
    }
    assert!(state(&events).is_empty(), "{events:?}");
    assert!(
        events.iter().all(|e| e.level() == Level::Debug
            || matches!(
                e,
                RouterEvent::Dropped {
                    reason: DropReason::LinkNoAck,
                    ..
                }
            )),
        "{events:?}"
    );
}

/// A configured link coming and going is the daemon's life (INFO); a
/// connection accepted on a listener is not (DEBUG), up or down.
#[test]
fn accepted_connections_come_and_go_at_debug_configured_links_at_info() {
    use sagebrush_gcu::Level;
    let mut h = H::new(&[1]);
    let levels = |o: &Outbox| -> Vec<(bool, Level)> {
        o.actions()
            .iter()
            .filter_map(|a| match a {
                Action::Event(e @ RouterEvent::LinkState { up, .. }) => Some((*up, e.level())),
                _ => None,
            })
            .collect()
    };
    let configured = h.go(Input::LinkUp {
        link: LinkId(8),
        config: LinkConfig::new(LinkKind::Upstream, SourceFilter::Any),
    });
    assert_eq!(levels(&configured), vec![(true, Level::Info)]);
    let accepted = h.go(Input::LinkUp {
        link: LinkId(70_000),
        config: LinkConfig {
            listener: Some(LinkId(8)),
            ..LinkConfig::new(LinkKind::Client, SourceFilter::Any)
        },
    });
    assert_eq!(levels(&accepted), vec![(true, Level::Debug)]);
    let gone = h.go(Input::LinkDown { link: LinkId(70_000) });
    assert_eq!(levels(&gone), vec![(false, Level::Debug)]);
    let gone = h.go(Input::LinkDown { link: LinkId(8) });
    assert_eq!(levels(&gone), vec![(false, Level::Info)]);
}
