//! What a client of gcud can believe (ARCHITECTURE "Delivery contract",
//! "Safety"): undelivered commands named and not ACKed, one outcome per
//! pipelined command, and every slew stopped when its client goes away,
//! falls silent, lets its lease run out or gcud stops.

use super::*;

/// A port-255 command is ACKed once every port's device acknowledged it
/// or its job ended, and one did (ARCHITECTURE "Delivery contract"): with
/// port 2's bus silent, the ACK waits for port 2 to give up, not just for
/// port 1's device. An ACK at the first device's ACK let the fan-out's `?`
/// come after the client's next command's ACK (simulation seed 165293).
#[test]
fn a_port_255_command_is_acked_once_every_port_decided() {
    let live = Sim::pty(&["--device", "1"]);
    let silent = Sim::pty(&["--device", "1", "--silent", "1"]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{}{}ack_timeout_ms = 150\nretries = 1\n",
        port_entry(1, &live),
        port_entry(2, &silent)
    ));
    gcud.wait_for_log("port open port=1");
    gcud.wait_for_log("port open port=2");
    let mut client = WireClient::connect(&gcud.clients());
    let sent = Instant::now();
    client.send(Address::new(5, 255, 1), 0, &Cmd::MotorsStop);
    assert_eq!(client.next(), OwnedEvent::Ack, "delivered on port 1\n{}", gcud.log());
    // Port 2's job: two writes, each given 150 ms for its ACK. A lower
    // bound: a slow machine only makes it later.
    let waited = sent.elapsed();
    assert!(
        waited >= Duration::from_millis(300),
        "ACKed after {waited:?}, before port 2 gave up"
    );
}

/// Dead-man: a client that started a slew disconnects; gcud stops the gimbal.
#[test]
fn slew_of_a_disconnected_client_is_stopped() {
    let sim = Sim::pty(&["--rate", "10"]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{METRICS}{}", port_entry(1, &sim)));
    let (start, client) = start_slew(&gcud, &Cmd::PanRight);
    drop(client);

    let stopped = gcud.settled_position("5.1.1");
    assert!(
        stopped.0 > start.0 && stopped.0 < 180.0,
        "stopped mid-way, not at a limit: {stopped:?}"
    );
    assert_eq!(gcud.metric("gcud_dead_man_stops_total"), 1);
}

/// Through one GCU and through two, a command that was not delivered exits
/// with its own code and a message naming the address; a live gimbal still
/// exits 0 and no command runs twice.
#[test]
fn undelivered_commands_exit_non_zero_naming_the_address() {
    let sim = Sim::pty(&["--device", "1"]);
    let (gcu5, gcu2) = two_gcus(&sim);
    let cases: &[(&Gcud, &str, &str, i32, &str)] = &[
        (&gcu5, "0", "5.1.2", 8, "did not acknowledge"),
        (&gcu5, "0", "5.9.1", 10, "no such port"),
        (&gcu2, "2", "5.1.2", 8, "did not acknowledge"),
        (&gcu2, "2", "5.9.1", 10, "no such port"),
        (&gcu2, "2", "7.1.1", 17, "leads back"),
    ];
    for (gcud, from, to, code, message) in cases {
        // A stop needs no control; a halt (HA: motors off, the halt position
        // overwritten) does, and the two GCUs' links would contend for it.
        let out = gcud.ctl(&["--from", from, "--to", to, "stop"]);
        assert_eq!(out.code, *code, "stop to {to} from {from}: {out:?}");
        assert!(
            out.stderr.contains(to) && out.stderr.contains(message),
            "the message names {to} and says {message:?}: {}",
            out.stderr
        );
    }
    let out = gcu2.ctl(&["--json", "--from", "2", "--to", "5.1.2", "stop"]);
    assert_eq!(out.json()["outcome"], "device_silent", "{out:?}");
    // A live gimbal, directly and through two GCUs.
    let delivered = "gcud_commands_delivery_total{delivery=\"delivered\"}";
    let before = gcu2.metric(delivered);
    for (gcud, from) in [(&gcu5, "0"), (&gcu2, "2")] {
        assert_eq!(gcud.ctl(&["--from", from, "--to", "5.1.1", "stop"]).code, 0);
        assert_eq!(gcud.ctl(&["--from", from, "--to", "5.1.1", "position"]).code, 0);
    }
    assert!(gcu5.log().contains("not delivered"), "{}", gcu5.log());
    assert!(gcu5.metric("gcud_commands_delivery_total{delivery=\"device_silent\"}") >= 2);
    assert!(gcu5.metric("gcud_commands_delivery_total{delivery=\"no_such_port\"}") >= 2);
    // The stop, the position, and the `~W` gimbalctl asks of GCU 5 before
    // the stop (answered NIC there: a link between GCUs gets no
    // end-of-window reports, ARCHITECTURE "End of the NIC window").
    assert_eq!(gcu2.metric(delivered) - before, 3);
    drop(gcu2);
    drop(gcu5);
    let stats = sim.stop();
    assert_eq!(
        stats["frames_in"], 4,
        "each command to gimbal 1 reached it once: {stats}"
    );
}

/// A client that knows only the spec sees no ACK for an undelivered command:
/// a delivery report comes instead, naming the command's address and checksum.
#[test]
fn a_spec_client_gets_no_ack_for_an_undelivered_command() {
    let sim = Sim::pty(&["--device", "1"]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim)));
    gcud.wait_for_log("port open port=1");
    let mut client = WireClient::connect(&gcud.clients());
    client.send(Address::new(5, 1, 2), 0, &Cmd::MotorsStop);
    let OwnedEvent::Frame(report) = client.next() else {
        panic!("expected a delivery report, not an ACK");
    };
    let report_frame = report.frame();
    assert_eq!(report_frame.dest, Address::new(0, 0, 0));
    assert_eq!(report_frame.source, 5);
    let parsed = sagebrush_protocol::DeliveryReport::parse(report_frame.payload()).expect("a report");
    assert_eq!(parsed.failure, Some(sagebrush_protocol::Undelivered::DeviceSilent));
    assert_eq!(parsed.dest, Address::new(5, 1, 2));
    let sent =
        FrameBuf::build(Address::new(5, 1, 2), 0, |b| Cmd::MotorsStop.encode(b).map(<[u8]>::len)).expect("encode");
    assert_eq!(
        parsed.command_checksum,
        sent.frame().checksum(),
        "the report names the command's checksum"
    );
    // The live gimbal: the ACK comes (after the device's), then the result.
    client.send(Address::new(5, 1, 1), 0, &Cmd::QueryPosition);
    let result = client.expect_result();
    assert_eq!(result.frame().dest, Address::new(0, 1, 1));
}

/// SIGTERM while a client's slew runs: gcud stops the gimbal before it
/// exits (refusing new commands meanwhile is the router rule
/// `shutdown_stops_every_owned_motion_and_refuses_new_commands`).
#[test]
fn sigterm_stops_a_running_slew_before_exit() {
    let sim = Sim::pty(&["--rate", "10"]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim)));
    let (_, client) = start_slew(&gcud, &Cmd::PanLeft);
    let (status, log) = gcud.terminate();
    assert!(status.is_some_and(|s| s.success()), "exit status {status:?}\n{log}");
    assert!(log.contains("shutting down: PS to 5.1.1"), "{log}");
    assert!(log.contains("in-flight transactions finished"), "{log}");
    // gcud is gone and the client still connected: the gimbal stands still.
    let first = sim.position();
    std::thread::sleep(Duration::from_millis(300));
    let second = sim.position();
    assert_eq!(first, second, "the gimbal was stopped before gcud exited");
    assert!(first.0 > -180.0, "stopped mid-way, not at a limit: {first:?}");
    drop(client);
}

/// A link with a motion lease: a slew its client started and does not
/// refresh is stopped although the connection stays open.
#[test]
fn an_unrefreshed_slew_is_stopped_when_its_lease_runs_out() {
    let sim = Sim::pty(&["--rate", "10"]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}motion_lease_ms = 400\n{METRICS}{}",
        port_entry(1, &sim)
    ));
    let client = slew_that_gcud_stops(&gcud);
    assert_eq!(gcud.metric("gcud_lease_stops_total"), 1);
    assert!(gcud.log().contains("motion lease over"), "{}", gcud.log());
    drop(client);
}

/// Eight clients pipeline five commands each at one port: every command
/// ends in exactly one outcome its client sees (an ACK or a report), the
/// reports name that client's own commands, and the ACKed ones are exactly
/// those the gimbal received.
#[test]
fn pipelining_clients_see_one_outcome_per_command() {
    let sim = Sim::pty(&[]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[limits]\nqueue_depth = 4\nmax_connections = 8\n{CLIENTS}{METRICS}{}",
        port_entry(1, &sim)
    ));
    gcud.wait_for_log("port open port=1");
    let mut clients: Vec<WireClient> = (0..8).map(|_| WireClient::connect(&gcud.clients())).collect();
    // Each command distinct, and within a client distinct in checksum too
    // (a report names its command by destination and checksum).
    let mut sent: Vec<Vec<FrameBuf>> = Vec::new();
    let mut pan = 0i16;
    for client in clients.iter_mut() {
        let mut mine: Vec<FrameBuf> = Vec::new();
        while mine.len() < 5 {
            pan += 100;
            let angle = |centi| sagebrush_protocol::Angle::from_centidegrees(centi);
            let command = Cmd::GoTo(Position::new(angle(pan), angle(0)));
            let frame =
                FrameBuf::build(Address::new(5, 1, 1), 0, |b| command.encode(b).map(<[u8]>::len)).expect("encode");
            if mine.iter().any(|f| f.frame().checksum() == frame.frame().checksum()) {
                continue;
            }
            client.send(Address::new(5, 1, 1), 0, &command);
            mine.push(frame);
        }
        sent.push(mine);
    }
    // Every command finished in gcud's count; then nothing more can come
    // for them. A D? to the GCU itself (an ACK, then its answer) marks the
    // end of each client's stream: everything before that answer is read.
    let delivery_total = |metrics: &str| -> u64 {
        metrics
            .lines()
            .filter(|l| l.starts_with("gcud_commands_delivery_total{"))
            .filter_map(|l| l.rsplit(' ').next()?.parse::<u64>().ok())
            .sum()
    };
    eventually("every command to have its outcome", || {
        delivery_total(&gcud.metrics()) == 40
    });
    let (mut acks, mut reports) = (0u64, 0u64);
    let mut acked_payloads = std::collections::BTreeSet::new();
    for (c, client) in clients.iter_mut().enumerate() {
        client.send(Address::new(5, 0, 0), 0, &Cmd::Identify);
        let mut events = Vec::new();
        loop {
            match client.next() {
                OwnedEvent::Frame(f) if sagebrush_protocol::DeliveryReport::parse(f.frame().payload()).is_ok() => {
                    events.push(sagebrush_protocol::DeliveryReport::parse(f.frame().payload()).ok());
                }
                OwnedEvent::Frame(answer) => {
                    assert!(
                        Reply::parse(&Cmd::Identify, answer.frame().payload()).is_ok(),
                        "client {c}: the GCU's D? answer: {answer:?}"
                    );
                    break;
                }
                OwnedEvent::Ack => events.push(None),
                other => panic!("client {c}: unexpected {other:?}"),
            }
        }
        // Five outcomes and the D?'s ACK: a command with two outcomes (an
        // ACK and a report) makes seven.
        assert_eq!(events.len(), 6, "client {c}: {events:?}");
        let mut unanswered: Vec<&FrameBuf> = sent[c].iter().collect();
        for report in events.iter().flatten() {
            assert!(report.failure.is_some(), "client {c}: a report of success: {report:?}");
            let at = unanswered
                .iter()
                .position(|f| f.frame().dest == report.dest && f.frame().checksum() == report.command_checksum)
                .unwrap_or_else(|| panic!("client {c}: a report of none of its commands, or a second: {report:?}"));
            unanswered.remove(at);
            reports += 1;
        }
        let client_acks = events.iter().filter(|e| e.is_none()).count() - 1;
        assert_eq!(
            client_acks,
            unanswered.len(),
            "client {c}: one ACK per command not reported"
        );
        acks += client_acks as u64;
        acked_payloads.extend(
            unanswered
                .iter()
                .map(|f| String::from_utf8_lossy(f.frame().payload()).into_owned()),
        );
    }
    assert_eq!(acks + reports, 40);
    // What the gimbal itself received: exactly the ACKed commands.
    let received: std::collections::BTreeSet<String> =
        sim.received("5.1.1").into_iter().map(|(_, payload)| payload).collect();
    assert_eq!(
        received, acked_payloads,
        "the gimbal received what was ACKed, nothing reported"
    );
    // gcud's count agrees (the eight D? to the GCU itself were delivered too).
    assert_eq!(
        gcud.metric("gcud_commands_delivery_total{delivery=\"delivered\"}"),
        acks + 8,
        "{}",
        gcud.metrics()
    );
    assert_eq!(delivery_total(&gcud.metrics()), 40 + 8);
    assert!(gcud.metric("gcud_commands_delivery_total{delivery=\"queue_full\"}") > 0);
}

/// A connection that says nothing for `limits.idle_timeout_ms` is closed,
/// and the slew it left running is stopped by the dead-man.
#[test]
fn a_silent_connection_is_closed_and_its_slew_stopped() {
    let sim = Sim::pty(&["--rate", "10"]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[limits]\nidle_timeout_ms = 1000\n{CLIENTS}{METRICS}{}",
        port_entry(1, &sim)
    ));
    let _client = slew_that_gcud_stops(&gcud);
    assert_eq!(gcud.metric("gcud_connections_closed_total{why=\"idle\"}"), 1);
    assert_eq!(gcud.metric("gcud_dead_man_stops_total"), 1);
    assert!(gcud.log().contains("idle (limits.idle_timeout_ms)"), "{}", gcud.log());
}

/// End of the NIC window (ARCHITECTURE "Delivery contract"): the doors'
/// connection asks gcud for end-of-window reports, and a command without a
/// result then ends when gcud's port window passed (35 ms by default), not
/// after the connection's own (here 30 s, so that a busy machine never
/// comes near the bound, half of it), a NIC still ending as NIC.
#[test]
fn a_door_waits_gcuds_nic_window_not_its_own_too() {
    use sagebrush_client::{CommandError, GimbalConnection};
    use sagebrush_protocol::{Axis, Speed};
    let sim = Sim::pty(&["--device", "1"]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim)));
    gcud.wait_for_log("port open port=1");
    let own_window = Duration::from_secs(30);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async {
        let mut c = GimbalConnection::new(gcud.clients(), 0, Address::new(5, 1, 1), own_window);
        // The connection opens (and asks `~W`) with its first command.
        c.position().await.expect("P?");
        for _ in 0..3 {
            let began = Instant::now();
            c.send(&Cmd::SetSpeed(Axis::Pan, Speed::new(7).unwrap()))
                .await
                .expect("SP7");
            let took = began.elapsed();
            assert!(took < own_window / 2, "gcud's window, not its own as well: {took:?}");
        }
        // A command the gimbal does not apply: still a NIC (gimbalsim answers
        // `FA`, auto focus, NIC without a lens).
        let nic = c.send(&Cmd::AutoFocusOn).await;
        assert!(matches!(nic, Err(CommandError::Nic(_))), "{nic:?}");
    });
}

/// The next command in the window (ARCHITECTURE "Routing semantics"): on a
/// `duplex = "full"` port the doors' connection sends a speed's direction at
/// the speed's ACK and gcud writes it to the device at once, in the speed's
/// NIC window (counted by `gcud_port_pipelined_total`); each outcome stays
/// its own command's, a NIC included. On a half-duplex port (the default)
/// nothing goes in a window. Read on the gimbal's side of the wire too:
/// with a window of 500 ms, the direction reaches it within a fraction of
/// that after the speed, or a whole window later.
#[test]
fn a_speed_and_its_direction_go_with_no_window_between_on_a_full_duplex_port() {
    use sagebrush_client::{CommandError, GimbalConnection};
    use sagebrush_protocol::{Axis, Speed};
    for duplex in ["full", "half"] {
        let sim = Sim::pty(&["--device", "1"]);
        let gcud = Gcud::start(&format!(
            "[gcu]\ngroup = 5\n{CLIENTS}{METRICS}{}duplex = \"{duplex}\"\nnic_window_ms = 500\n",
            port_entry(1, &sim)
        ));
        gcud.wait_for_log("port open port=1");
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        runtime.block_on(async {
            let mut c = GimbalConnection::new(gcud.clients(), 0, Address::new(5, 1, 1), Duration::from_secs(3));
            c.position().await.expect("P?");
            for speed in [3, 9, 5] {
                let sp = Cmd::SetSpeed(Axis::Pan, Speed::new(speed).unwrap());
                let (a, b) = c.send_chained(&sp, &Cmd::PanRight, &|| true).await;
                assert!(a.is_ok() && matches!(b, Some(Ok(_))), "{duplex}: {a:?} {b:?}");
                c.send(&Cmd::PanStop).await.expect("PS");
            }
            // A NIC is still its own command's: `FA` (no lens) then a pan.
            let (a, b) = c.send_chained(&Cmd::AutoFocusOn, &Cmd::PanLeft, &|| true).await;
            assert!(matches!(a, Err(CommandError::Nic(_))), "{duplex}: {a:?}");
            assert!(matches!(b, None | Some(Ok(_))), "{duplex}: {b:?}");
            c.send(&Cmd::PanStop).await.expect("PS");
        });
        let pipelined = gcud.metric("gcud_port_pipelined_total{port=\"1\"}");
        match duplex {
            "full" => assert!(pipelined >= 3, "each direction went in its speed's window: {pipelined}"),
            _ => assert_eq!(pipelined, 0, "never in a window on a half-duplex bus"),
        }
        // The gimbal's own record: how long after each speed its direction came.
        let heard = support::frames_received_at(&sim.log(), "5.1.1");
        let gaps: Vec<f64> = heard
            .windows(2)
            .filter(|w| w[0].1.starts_with("SP") && w[1].1 == "PR")
            .map(|w| w[1].0 - w[0].0)
            .collect();
        assert_eq!(gaps.len(), 3, "{duplex}: {heard:?}");
        match duplex {
            "full" => assert!(gaps.iter().all(|&g| g < 0.25), "{duplex}: not in the window: {gaps:?}"),
            _ => assert!(
                gaps.iter().all(|&g| g >= 0.45),
                "{duplex}: a whole window first: {gaps:?}"
            ),
        }
    }
}
