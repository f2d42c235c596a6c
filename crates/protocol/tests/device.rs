//! The device side: `DeviceEndpoint` (1.4.2, 1.4.3, 1.5.4, Table 3).

use sagebrush_protocol::*;

/// A gimbal that knows its position and stores the reply header of `IX`
/// to answer later.
#[derive(Default)]
struct Gimbal {
    handled: Vec<(String, ReplyTo)>,
    deferred: Option<ReplyTo>,
    refuse_home: bool,
    wrong_reply: bool,
}

impl DeviceHandler for Gimbal {
    fn handle(&mut self, command: Command<'_>, reply_to: ReplyTo, _now: u64) -> Response<'_> {
        self.handled.push((command.mnemonic().to_string(), reply_to));
        match command {
            Command::QueryPosition if self.wrong_reply => Response::Reply(Reply::Relays(1)),
            Command::QueryPosition => Response::Reply(Reply::Position(Position::new(Angle(100), Angle(-100)))),
            Command::Home if self.refuse_home => Response::Nic,
            Command::Initialize => {
                self.deferred = Some(reply_to);
                Response::Deferred
            }
            _ => Response::Done,
        }
    }
}

fn frame(dest: Address, source: u8, payload: &[u8]) -> Vec<u8> {
    FrameBuf::new(dest, source, payload).unwrap().as_bytes().to_vec()
}

fn run(endpoint: &mut DeviceEndpoint, gimbal: &mut Gimbal, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    endpoint.receive(bytes, 0, gimbal, &mut |b: &[u8]| out.extend_from_slice(b));
    out
}

#[test]
fn ack_then_table3_result() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    let out = run(&mut ep, &mut g, &[0xF8, 0x05, 0x01, 0x0C, 0x02, 0x02, 0x50, 0x3F, 0xA5]);
    assert_eq!(out[0], ACK);
    // Result header per Table 3: dest group 2 (the source), port 1 and
    // device 12 unchanged, source group 5.
    let (result, rest) = Frame::parse(&out[1..]).unwrap();
    assert!(rest.is_empty());
    assert_eq!(result.dest, Address::new(2, 1, 12));
    assert_eq!(result.source, 5);
    assert_eq!(result.payload(), b"0064FF9C");
    assert_eq!(
        g.handled,
        [(
            "P?".to_string(),
            ReplyTo {
                dest: Address::new(2, 1, 12),
                source: 5,
                answered: true,
            }
        )]
    );
    let stats = ep.stats();
    assert_eq!((stats.frames_accepted, stats.results_sent, stats.nics_sent), (1, 1, 0));
}

#[test]
fn ack_only_for_commands_without_result() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"PL")), [ACK]);
    assert_eq!(g.handled.len(), 1);
}

#[test]
fn nak_on_bad_checksum_addressed_to_it_silence_otherwise() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::shared(12));
    let mut g = Gimbal::default();
    let mut bad = frame(Address::new(5, 1, 12), 2, b"P?");
    *bad.last_mut().unwrap() ^= 0x40;
    assert_eq!(run(&mut ep, &mut g, &bad), [NAK]);
    assert!(g.handled.is_empty(), "a damaged command is not executed");
    assert_eq!(ep.stats().naks_sent, 1);
    // Damaged and for another device: silence.
    let mut other = frame(Address::new(5, 1, 13), 2, b"P?");
    *other.last_mut().unwrap() ^= 0x40;
    assert_eq!(run(&mut ep, &mut g, &other), []);
    // A good frame for another device: silence, not executed.
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, 13), 2, b"P?")), []);
    assert!(g.handled.is_empty());
    assert_eq!(ep.stats().frames_accepted, 0);
    // Bare bytes on the bus are not for a device.
    assert_eq!(run(&mut ep, &mut g, &[ACK, NAK, NIC]), []);
}

#[test]
fn group_and_port_filters() {
    let config = EndpointConfig {
        device: 12,
        group: Some(5),
        port: Some(1),
        answer_broadcast: true,
    };
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(config);
    let mut g = Gimbal::default();
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(6, 1, 12), 2, b"PL")), []);
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 2, 12), 2, b"PL")), []);
    assert_eq!(
        run(&mut ep, &mut g, &frame(Address::new(255, 255, 12), 2, b"PL")),
        [ACK]
    );
    assert!(config.accepts(&Address::new(5, 1, 255)));
    assert!(!config.accepts(&Address::new(5, 1, 0)));
}

#[test]
fn nic_for_unknown_and_for_handler_nic() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    assert_eq!(
        run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"QQ")),
        [ACK, NIC]
    );
    assert!(g.handled.is_empty(), "unknown commands do not reach the handler");
    // Malformed arguments are unknown too (`#00` is not a device ID).
    assert_eq!(
        run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"#00")),
        [ACK, NIC]
    );
    g.refuse_home = true;
    assert_eq!(
        run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"HO")),
        [ACK, NIC]
    );
    // A reply of the wrong kind is not sent: NIC instead.
    g.wrong_reply = true;
    assert_eq!(
        run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"P?")),
        [ACK, NIC]
    );
    assert_eq!(ep.stats().nics_sent, 4);
    assert_eq!(ep.stats().results_sent, 0);
}

#[test]
fn broadcast_answered_or_silent() {
    let broadcast = frame(Address::new(5, 1, WILDCARD), 2, b"P?");
    // A device alone on its bus answers, and says who it is.
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    let out = run(&mut ep, &mut g, &broadcast);
    assert_eq!(out[0], ACK);
    let (result, _) = Frame::parse(&out[1..]).unwrap();
    assert_eq!(result.dest, Address::new(2, 1, 12));
    // On a shared bus it executes silently.
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::shared(12));
    let mut g = Gimbal::default();
    assert_eq!(run(&mut ep, &mut g, &broadcast), []);
    assert_eq!(g.handled.len(), 1, "executed all the same");
    assert!(!g.handled[0].1.answered, "the handler is told nobody hears its result");
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, WILDCARD), 2, b"QQ")), []);
    let mut bad = broadcast.clone();
    *bad.last_mut().unwrap() ^= 1;
    assert_eq!(run(&mut ep, &mut g, &bad), [], "no NAK either");
    assert_eq!(ep.stats().nics_sent + ep.stats().naks_sent + ep.stats().results_sent, 0);
}

#[test]
fn set_device_id_changes_the_address() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(1));
    let mut g = Gimbal::default();
    // 1.5.4: `#NN` with wild-card addressing to a device alone on the port.
    assert_eq!(
        run(&mut ep, &mut g, &frame(Address::new(255, 255, 255), 0, b"#2A")),
        [ACK]
    );
    assert_eq!(ep.config().device, 0x2A);
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, 1), 2, b"PL")), []);
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, 0x2A), 2, b"PL")), [ACK]);
}

#[test]
fn deferred_reply() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"IX")), [ACK]);
    let to = g.deferred.expect("the handler kept the header");
    let results = InitResults {
        pan_ccw: 9,
        pan_cw: 9,
        tilt_ccw: 9,
        tilt_cw: 9,
    };
    let mut out = Vec::new();
    ep.send_reply(to, &Reply::Initialization(results), &mut |b: &[u8]| {
        out.extend_from_slice(b)
    })
    .unwrap();
    let (result, _) = Frame::parse(&out).unwrap();
    assert_eq!((result.dest, result.source), (Address::new(2, 1, 12), 5));
    assert_eq!(
        Reply::parse(&Command::Initialize, result.payload()),
        Ok(Reply::Initialization(results))
    );
    assert_eq!(ep.stats().results_sent, 1);
    let mut out = Vec::new();
    assert!(
        ep.send_reply(to, &Reply::Raw(b""), &mut |b: &[u8]| out.extend_from_slice(b))
            .is_err()
    );
    assert!(out.is_empty());
}

#[test]
fn partial_frame_and_silence_hook() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    let wire = frame(Address::new(5, 1, 12), 2, b"PL");
    // A truncated frame, then silence: abandoned without an answer.
    assert_eq!(run(&mut ep, &mut g, &wire[..5]), []);
    let mut out = Vec::new();
    ep.line_idle(0, &mut g, &mut |b: &[u8]| out.extend_from_slice(b));
    assert!(out.is_empty());
    assert_eq!(ep.framer().stats().abandoned, 1);
    // The next frame in two pieces is answered once it is complete.
    assert_eq!(run(&mut ep, &mut g, &wire[..4]), []);
    assert_eq!(run(&mut ep, &mut g, &wire[4..]), [ACK]);
}

#[test]
fn dma_path_matches_receive() {
    let mut stream = frame(Address::new(5, 1, 12), 2, b"P?");
    stream.extend_from_slice(&[0x00, 0xF8]);
    stream.extend(frame(Address::new(5, 1, 12), 2, b"QQ"));
    stream.extend(frame(Address::new(5, 1, 12), 2, b"PL"));
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut g = Gimbal::default();
    let mut expected = run(&mut ep, &mut g, &stream);
    ep.line_idle(0, &mut g, &mut |b: &[u8]| expected.extend_from_slice(b));
    assert_eq!(expected[..1], [ACK]);
    for chunk in [1, 3, 16, 300] {
        let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
        let mut g = Gimbal::default();
        let mut out = Vec::new();
        let mut rest = &stream[..];
        while !rest.is_empty() {
            let spare = ep.spare_capacity_mut();
            let n = spare.len().min(chunk).min(rest.len());
            spare[..n].copy_from_slice(&rest[..n]);
            rest = &rest[n..];
            ep.commit(n, 0, &mut g, &mut |b: &[u8]| out.extend_from_slice(b));
        }
        ep.line_idle(0, &mut g, &mut |b: &[u8]| out.extend_from_slice(b));
        assert_eq!(out, expected, "chunk {chunk}");
        assert_eq!(g.handled.len(), 2);
    }
}

/// The master NAKs a damaged result (1.4.2, hop by hop): the device sends it
/// again, at most `RESULT_RESENDS` times; after an ACK or any other frame on
/// the line a NAK is someone else's and is ignored.
#[test]
fn result_is_resent_on_nak_until_the_master_moves_on() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::shared(12));
    let mut g = Gimbal::default();
    let query = frame(Address::new(5, 1, 12), 2, b"P?");
    let out = run(&mut ep, &mut g, &query);
    let result = out[1..].to_vec();
    assert_eq!(Frame::parse(&result).unwrap().0.payload(), b"0064FF9C");
    for _ in 0..RESULT_RESENDS {
        assert_eq!(run(&mut ep, &mut g, &[NAK]), result, "resent on NAK");
    }
    assert!(
        run(&mut ep, &mut g, &[NAK]).is_empty(),
        "not more than RESULT_RESENDS times"
    );
    assert_eq!(ep.stats().results_resent, u64::from(RESULT_RESENDS));

    // An ACK ends it.
    run(&mut ep, &mut g, &query);
    assert!(run(&mut ep, &mut g, &[ACK, NAK]).is_empty());
    // So does the master's next command to another device of the bus.
    run(&mut ep, &mut g, &query);
    let other = frame(Address::new(5, 1, 13), 2, b"P?");
    assert!(run(&mut ep, &mut g, &other).is_empty());
    assert!(run(&mut ep, &mut g, &[NAK]).is_empty(), "that NAK is device 13's");
    // A deferred result is kept the same way.
    run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"IX"));
    let mut sent = Vec::new();
    let reply = Reply::Initialization(InitResults::default());
    let to = g.deferred.expect("IX deferred");
    ep.send_reply(to, &reply, &mut |b: &[u8]| sent.extend_from_slice(b))
        .unwrap();
    assert_eq!(run(&mut ep, &mut g, &[NAK]), sent);
}

/// The handler learns from its `ReplyTo` whether the command is answered: a
/// broadcast on a shared bus is not, and a deferred result to it is not sent
/// (the simulator's gimbal and the firmware defer `IX` without knowing the bus).
#[test]
fn deferred_reply_to_an_unanswered_broadcast_is_not_sent() {
    let results = Reply::Initialization(InitResults::default());
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::shared(12));
    let mut g = Gimbal::default();
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, WILDCARD), 2, b"IX")), []);
    let to = g.deferred.expect("IX deferred");
    assert_eq!((to.dest, to.source, to.answered), (Address::new(2, 1, 12), 5, false));
    let mut out = Vec::new();
    ep.send_reply(to, &results, &mut |b: &[u8]| out.extend_from_slice(b))
        .unwrap();
    assert!(out.is_empty(), "nobody is listening for it");
    assert_eq!(ep.stats().results_sent, 0);
    assert!(run(&mut ep, &mut g, &[NAK]).is_empty(), "nothing kept to resend");
    // The same command to its own address is answered, later result included.
    assert_eq!(run(&mut ep, &mut g, &frame(Address::new(5, 1, 12), 2, b"IX")), [ACK]);
    let to = g.deferred.expect("IX deferred");
    assert!(to.answered);
    ep.send_reply(to, &results, &mut |b: &[u8]| out.extend_from_slice(b))
        .unwrap();
    assert_eq!(Frame::parse(&out).unwrap().0.dest, Address::new(2, 1, 12));
}

/// A device that implements only `AW` and `P?` (as the firmware declares
/// its rows).
#[derive(Default)]
struct Small {
    handled: Vec<String>,
}

impl DeviceHandler for Small {
    fn handle(&mut self, command: Command<'_>, _: ReplyTo, _now: u64) -> Response<'_> {
        self.handled.push(command.mnemonic().to_string());
        match command {
            Command::QueryPosition => Response::Reply(Reply::Position(Position::default())),
            _ => Response::Done,
        }
    }

    fn implements(row: Row) -> bool {
        matches!(row, Row::AwakeStatus | Row::QueryPosition)
    }
}

#[test]
fn rows_a_device_does_not_implement_are_nic_without_reaching_it() {
    let mut ep: DeviceEndpoint = DeviceEndpoint::new(EndpointConfig::single(12));
    let mut small = Small::default();
    let mut send = |payload: &[u8]| {
        let mut out = Vec::new();
        let bytes = frame(Address::new(5, 1, 12), 2, payload);
        ep.receive(&bytes, 0, &mut small, &mut |b: &[u8]| out.extend_from_slice(b));
        out
    };
    // Well-formed commands of other rows (a preset query next to the
    // implemented `P?`, a rev 1.9 name, one with arguments to check).
    for payload in [&b"HO"[..], b"P0064FF9C", b"RP0200", b"*me1", b"P?0A", b"#0C"] {
        assert_eq!(send(payload), [ACK, NIC], "{}", String::from_utf8_lossy(payload));
    }
    let answered = send(b"P?");
    assert_eq!(answered[0], ACK);
    assert!(
        answered.len() > 1 && answered[1] == START,
        "P? answered with a result: {answered:?}"
    );
    assert_eq!(small.handled, ["P?"], "only implemented rows reach the handler");
    // The table's own view: the same payloads parse in full for every row.
    assert_eq!(Command::parse(b"HO"), Command::Home);
    assert_eq!(
        Command::parse_implemented(b"HO", |row| row == Row::AwakeStatus),
        Command::Unknown(b"HO")
    );
}
