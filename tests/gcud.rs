//! End-to-end tests of the `gcud` daemon: the real binary, real simulated
//! gimbals (`gimbalsim`) on pseudo-terminals, TCP on 127.0.0.1 only.
//! Nothing here asserts on wall-clock speed; waits are polls with a hang guard.

mod support;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Command as Cmd, Event, FrameBuf, Framer, OwnedEvent, Position, Reply};
use support::gcud::{CLIENTS, Gcud, METRICS, WireClient, port_entry};
use support::{HANG_GUARD, Sim, eventually};

/// Connects to `addr` and requires gcud to close the connection without
/// a byte: end of stream or reset. A read that times out (after the
/// generous [`HANG_GUARD`]: only a hang, never a slow machine, reaches it)
/// means the connection was kept, and fails.
fn assert_closed_by_gcud(addr: &str, what: &str) {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let mut buf = [0u8; 1];
    match s.read(&mut buf) {
        Ok(0) => {}
        Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {}
        Ok(n) => panic!("{what}: gcud wrote {n} byte(s) instead of closing"),
        Err(e) => panic!("{what}: gcud did not close the connection ({e})"),
    }
}

// ---- the tests --------------------------------------------------------------

/// Table 3: a client attached to GCU 2 commands device 12 on port 1 of GCU 5;
/// the result comes back with destination group 2 and source group 5.
#[test]
fn table3_result_crosses_two_gcus_with_groups_exchanged() {
    let sim = Sim::pty(&["--device", "12"]);
    let gcu5 = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{}[[link]]\nname = \"gcus\"\nrole = \"upstream\"\nlisten = \"127.0.0.1:0\"\n",
        port_entry(1, &sim)
    ));
    gcu5.wait_for_log("port open port=1");
    let gcu5_addr = gcu5.address("listening link=gcus");
    let gcu2 = Gcud::start(&format!(
        "[gcu]\ngroup = 2\n{CLIENTS}[[link]]\nname = \"gcu5\"\nrole = \"downstream\"\nconnect = \"{gcu5_addr}\"\n\
         [[route]]\ngroup = 5\nlink = \"gcu5\"\n"
    ));
    gcu2.wait_for_log("link connected");

    let mut client = WireClient::connect(&gcu2.clients());
    client.send(Address::new(5, 1, 12), 2, &Cmd::QueryPosition);
    let result = client.expect_result();
    let frame = result.frame();
    assert_eq!(
        frame.dest,
        Address::new(2, 1, 12),
        "destination group 2, port and device unchanged"
    );
    assert_eq!(frame.source, 5, "source group 5");
    let reply = Reply::parse(&Cmd::QueryPosition, frame.payload()).expect("a Table 15 position");
    assert!(matches!(reply, Reply::Position(Position { .. })), "{reply:?}");

    // And the CLI sees the same through both GCUs.
    let out = gcu2.ctl(&["--json", "--from", "2", "--to", "5.1.12", "id"]);
    assert_eq!(out.code, 0, "{out:?}\n{}", gcu2.log());
    assert_eq!(out.json()["result"]["id"], 12);
    // Consecutive runs (each a new connection speaking as group 2, each
    // answered identically by a gimbal at rest) each get their own answer.
    for _ in 0..3 {
        let out = gcu2.ctl(&["--json", "--from", "2", "--to", "5.1.12", "position"]);
        assert_eq!(out.code, 0, "{out:?}\n{}", gcu2.log());
    }
}

/// A field GCU that dials into the hub's `downstream` listener can be
/// routed to from the hub at once (a route names the listener), before it
/// sent anything, and again after it reconnects.
#[test]
fn a_gcu_that_dials_in_is_routed_to_through_the_listener_route() {
    let hub = Gcud::start(&format!(
        "[gcu]\ngroup = 2\n{CLIENTS}[[link]]\nname = \"field\"\nrole = \"downstream\"\nlisten = \"127.0.0.1:0\"\n\
         [[route]]\ngroup = 7\nlink = \"field\"\n"
    ));
    let listener = hub.address("listening link=field");
    let out = hub.ctl(&["--from", "2", "--to", "7.1.1", "position"]);
    assert_eq!(out.code, 14, "nobody dialled in yet: the route's link is down: {out:?}");
    let field_config = format!(
        "[gcu]\ngroup = 7\n[[port]]\nid = 1\nsimulate = [1]\n\
         [[link]]\nname = \"hub\"\nrole = \"upstream\"\nconnect = \"{listener}\"\n"
    );
    for round in 1..=2 {
        let field = Gcud::start(&field_config);
        field.wait_for_log("link connected");
        eventually("the hub to accept the field GCU", || {
            hub.log().matches("client connected link=field").count() >= round
        });
        let out = hub.ctl(&["--json", "--from", "2", "--to", "7.1.1", "id"]);
        assert_eq!(
            out.code,
            0,
            "round {round}: {out:?}\nhub:\n{}\nfield:\n{}",
            hub.log(),
            field.log()
        );
        assert_eq!(out.json()["result"]["id"], 1);
        let out = hub.ctl(&["--from", "2", "--to", "7.1.1", "goto", "5", "1", "--wait"]);
        assert_eq!(out.code, 0, "round {round}: {out:?}");
        let (_, log) = field.terminate();
        assert!(log.contains("shutting down"), "{log}");
    }
}

/// Port 255 and device 255 reach every gimbal of a GCU; group 255 reaches both GCUs.
#[test]
fn wildcards_reach_every_gimbal_and_both_gcus() {
    let bus_a = Sim::pty(&["--device", "1,2"]);
    let bus_b = Sim::pty(&["--device", "1"]);
    let bus_c = Sim::pty(&["--device", "1"]);
    let gcu5 = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{}{}[[link]]\nname = \"gcus\"\nrole = \"upstream\"\nlisten = \"127.0.0.1:0\"\n",
        port_entry(1, &bus_a),
        port_entry(2, &bus_b)
    ));
    gcu5.wait_for_log("port open port=1");
    gcu5.wait_for_log("port open port=2");
    let gcu2 = Gcud::start(&format!(
        "[gcu]\ngroup = 2\n{CLIENTS}{}[[link]]\nname = \"gcu5\"\nrole = \"downstream\"\nconnect = \"{}\"\n",
        port_entry(1, &bus_c),
        gcu5.address("listening link=gcus")
    ));
    gcu2.wait_for_log("port open port=1");
    gcu2.wait_for_log("link connected");

    // Port 255, device 255 on GCU 5: all three of its gimbals.
    let out = gcu5.ctl(&["--to", "5.255.255", "goto", "30", "5"]);
    assert_eq!(out.code, 0, "{out:?}");
    for to in ["5.1.1", "5.1.2", "5.2.1"] {
        let (pan, tilt) = gcu5.settled_position(to);
        assert_eq!((pan, tilt), (30.0, 5.0), "{to}");
    }
    // Group 255 from a client of GCU 2: its own gimbal and, flooded
    // downstream, GCU 5's gimbals on port 1.
    let out = gcu2.ctl(&["--from", "2", "--to", "255.1.255", "goto", "-20", "-4"]);
    assert_eq!(out.code, 0, "{out:?}\n{}", gcu2.log());
    assert_eq!(gcu2.settled_position("2.1.1"), (-20.0, -4.0));
    for to in ["5.1.1", "5.1.2"] {
        assert_eq!(gcu5.settled_position(to), (-20.0, -4.0), "{to}\n{}", gcu5.log());
    }
    assert_eq!(gcu5.settled_position("5.2.1"), (30.0, 5.0), "port 2 was not addressed");
}

/// Damaged answers and commands on a port: retransmission recovers every
/// exchange, and the metrics count it.
#[test]
fn port_corruption_is_recovered_and_counted() {
    let sim = Sim::pty(&["--seed", "7", "--corrupt", "0.3", "--nak", "0.3", "--max-faults", "12"]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{METRICS}{}", port_entry(1, &sim)));
    gcud.wait_for_log("port open port=1");
    for _ in 0..12 {
        let out = gcud.ctl(&["--to", "5.1.1", "position"]);
        assert_eq!(out.code, 0, "{out:?}\n{}", gcud.log());
    }
    let retransmits = gcud.metric("gcud_port_retransmits_total{port=\"1\"}");
    let bad = gcud.metric("gcud_port_bad_checksums_total{port=\"1\"}");
    assert!(retransmits > 0, "commands NAKed by the device were retransmitted");
    assert!(bad > 0, "damaged answers were seen (and NAKed)");
    assert_eq!(gcud.metric("gcud_port_naks_sent_total{port=\"1\"}"), bad);
    let stats = sim.stop();
    assert!(stats["faults"]["nak"].as_u64().unwrap_or(0) > 0, "{stats}");
}

/// A port's pseudo-terminal disappears and comes back: the port recovers by
/// itself and the other port never notices.
#[test]
fn vanished_port_recovers_and_others_never_notice() {
    let dir = tempfile::tempdir().expect("temp dir");
    let link1: PathBuf = dir.path().join("bus1");
    let link1_arg = link1.to_str().expect("utf-8 path").to_owned();
    let first = Sim::pty(&["--link", &link1_arg]);
    let bus2 = Sim::pty(&[]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{METRICS}[[port]]\nid = 1\npath = \"{}\"\n{}",
        link1.display(),
        port_entry(2, &bus2)
    ));
    gcud.wait_for_log("port open port=1");
    gcud.wait_for_log("port open port=2");
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0);

    first.stop();
    eventually("gcud to notice port 1 is gone", || {
        gcud.metric("gcud_port_open{port=\"1\"}") == 0
    });
    assert!(!Path::new(&link1).exists());
    for _ in 0..5 {
        let out = gcud.ctl(&["--to", "5.2.1", "position"]);
        assert_eq!(out.code, 0, "port 2 keeps working while port 1 is away: {out:?}");
    }
    assert_ne!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0, "port 1 is away");

    let _second = Sim::pty(&["--link", &link1_arg]);
    eventually("port 1 to come back", || gcud.metric("gcud_port_open{port=\"1\"}") == 1);
    eventually("port 1 to answer again", || {
        gcud.ctl(&["--to", "5.1.1", "position"]).code == 0
    });
    assert_eq!(
        gcud.metric("gcud_port_timeouts_total{port=\"2\"}"),
        0,
        "port 2 never noticed"
    );
    assert_eq!(gcud.metric("gcud_port_open{port=\"2\"}"), 1);
}

/// Once port 1 is open, a wire client starts `slew` on gimbal 5.1.1 and
/// sees the gimbal move; returns where it started and the client.
fn start_slew(gcud: &Gcud, slew: &Cmd<'_>) -> ((f64, f64), WireClient) {
    gcud.wait_for_log("port open port=1");
    let start = gcud.position("5.1.1");
    let mut client = WireClient::connect(&gcud.clients());
    client.send(Address::new(5, 1, 1), 0, slew);
    assert_eq!(client.next(), OwnedEvent::Ack);
    eventually("the slew to move the gimbal", || gcud.position("5.1.1") != start);
    (start, client)
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

/// Bad configuration files: each gives its specific message and exit code 2.
#[test]
fn bad_configs_name_the_problem_and_exit_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases: &[(&str, &str, &str)] = &[
        (
            "[gcu]\ngroup = 300\n",
            ":2:9: gcu.group",
            "expected an integer 1..=254, found 300",
        ),
        (
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/dev/x\"\nbaud = 9601\n",
            ":6:8: port[0].baud",
            "115200",
        ),
        (
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npaht = \"/dev/x\"\n",
            ":5:1",
            "unknown field `paht`",
        ),
        (
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"/a\"\n[[port]]\nid = 1\npath = \"/b\"\n",
            ":7:6: port[1].id",
            "configured twice",
        ),
        (
            "[gcu]\ngroup = 5\n[[route]]\ngroup = 7\nlink = \"up\"\n",
            ":5:8: route[0].link",
            "no link is named \"up\"",
        ),
        (
            "[gcu]\ngroup = 5\n[[link]]\nname = \"c\"\nrole = \"client\"\nlisten = \"localhost\"\n",
            ":6:10: link[0].listen",
            "expected an IP address and port",
        ),
        ("[gcu\ngroup = 5\n", ":1:5", "unclosed table, expected `]`"),
        ("[gcu]\n", ":1:1: gcu", "missing field `group`"),
    ];
    for (i, (text, place, message)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&path, text).expect("write");
        for check in [true, false] {
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_gcud"));
            if check {
                cmd.arg("--check");
            }
            let out = cmd.arg("--config").arg(&path).output().expect("run gcud");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "case {i} ({text:?}): {stderr}");
            let expected_place = format!("{}{place}", path.display());
            assert!(
                stderr.contains(&expected_place),
                "case {i}: {stderr:?} should contain {expected_place:?}"
            );
            assert!(
                stderr.contains(message),
                "case {i}: {stderr:?} should contain {message:?}"
            );
        }
    }
    let missing = dir.path().join("missing.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--check")
        .arg("--config")
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}

/// 254 configured ports start and route (in-process simulated buses).
#[test]
fn all_254_ports_start_and_route() {
    let mut config = format!("[gcu]\ngroup = 9\n{CLIENTS}{METRICS}");
    for id in 1..=254 {
        config.push_str(&format!("[[port]]\nid = {id}\nsimulate = [3]\n"));
    }
    let gcud = Gcud::start(&config);
    eventually("all ports to open", || {
        (1..=254).all(|id| gcud.metrics().contains(&format!("gcud_port_open{{port=\"{id}\"}} 1")))
    });
    for port in [1, 2, 127, 253, 254] {
        let out = gcud.ctl(&["--json", "--to", &format!("9.{port}.3"), "id"]);
        assert_eq!(out.code, 0, "port {port}: {out:?}");
        assert_eq!(out.json()["result"]["id"], 3);
    }
    assert_eq!(gcud.metric("gcud_port_transactions_total{port=\"127\"}"), 1);
    assert_eq!(gcud.metric("gcud_port_transactions_total{port=\"128\"}"), 0);
}

/// SIGTERM with a transaction in flight: gcud lets it finish (its client
/// gets the result it asked for), says so, and exits 0. The test plays the
/// gimbal on a TCP port and holds the result back until gcud has logged
/// that it is shutting down: the command was provably in flight at SIGTERM.
#[test]
fn sigterm_shuts_down_gracefully() {
    let bus = std::net::TcpListener::bind("127.0.0.1:0").expect("bind the device server");
    let addr = bus.local_addr().expect("address");
    let mut gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\nshutdown_grace_ms = 60000\n{CLIENTS}[[port]]\nid = 1\ntcp = \"{addr}\"\n\
         ack_timeout_ms = 10000\nresult_timeout_ms = 30000\n[link_timing]\ndelivery_timeout_ms = 30000\n"
    ));
    let (mut line, _) = bus.accept().expect("gcud connects to its port");
    line.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let clients = gcud.clients();
    let client = std::thread::spawn(move || {
        support::gimbalctl(&[
            "--json",
            "--tcp",
            &clients,
            "--to",
            "5.1.1",
            "--result-timeout",
            "30000",
            "position",
        ])
    });
    // The P? reaches the gimbal; it is ACKed, its result not yet sent.
    let mut framer: Framer = Framer::new();
    let mut command = None;
    while command.is_none() {
        let mut buf = [0u8; 64];
        let n = line.read(&mut buf).expect("gcud writes the P?");
        assert!(n > 0, "gcud closed its port");
        framer.feed(&buf[..n], |e| {
            if let Event::Frame(f) = e {
                command = Some(FrameBuf::from_frame(&f));
            }
        });
    }
    let command = command.expect("a frame");
    assert_eq!(command.frame().payload(), b"P?");
    line.write_all(&[ACK]).expect("ACK the P?");
    let pid = nix::unistd::Pid::from_raw(gcud.child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("SIGTERM");
    gcud.wait_for_log("shutting down");
    assert!(
        matches!(gcud.child.try_wait(), Ok(None)),
        "gcud exited with the P? in flight:\n{}",
        gcud.log()
    );
    let result = Reply::Position(Position::new(
        sagebrush_protocol::Angle::from_centidegrees(1250),
        sagebrush_protocol::Angle::from_centidegrees(-300),
    ));
    line.write_all(&support::cli::reply_frame(&command.frame(), &result))
        .expect("the result");
    let out = client.join().expect("client thread");
    let started = Instant::now();
    let status = loop {
        if let Some(status) = gcud.child.try_wait().expect("wait for gcud") {
            break status;
        }
        assert!(started.elapsed() < HANG_GUARD, "gcud never exited:\n{}", gcud.log());
        std::thread::sleep(Duration::from_millis(20));
    };
    let log = gcud.log();
    assert_eq!(out.code, 0, "the command in flight finished: {out:?}\n{log}");
    let v = out.json();
    assert_eq!(
        (v["outcome"].as_str(), v["result"]["pan_deg"].as_f64()),
        (Some("result"), Some(12.5)),
        "the client got the result sent after SIGTERM: {v}"
    );
    assert!(status.success(), "exit status {status:?}\n{log}");
    let shutting = log.find("shutting down").expect("logged");
    let finished = log
        .find("in-flight transactions finished")
        .unwrap_or_else(|| panic!("{log}"));
    assert!(shutting < finished, "{log}");
}

/// A TCP client link configured before its peer exists keeps retrying and
/// connects once the peer is up; routing through it then works.
#[test]
fn client_link_connects_once_its_peer_appears() {
    let free = std::net::TcpListener::bind("127.0.0.1:0").expect("probe a free port");
    let addr = free.local_addr().expect("address").to_string();
    drop(free);
    let gcu2 = Gcud::start(&format!(
        "[gcu]\ngroup = 2\n{CLIENTS}[[link]]\nname = \"gcu5\"\nrole = \"downstream\"\nconnect = \"{addr}\"\n\
         [[route]]\ngroup = 5\nlink = \"gcu5\"\n"
    ));
    gcu2.wait_for_log("cannot connect; retrying with backoff");
    let sim = Sim::pty(&["--device", "3"]);
    let gcu5 = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{}[[link]]\nname = \"gcus\"\nrole = \"upstream\"\nlisten = \"{addr}\"\n",
        port_entry(1, &sim)
    ));
    gcu5.wait_for_log("port open port=1");
    gcu2.wait_for_log("link connected");
    let out = gcu2.ctl(&["--json", "--from", "2", "--to", "5.1.3", "id"]);
    assert_eq!(out.code, 0, "{out:?}\n{}", gcu2.log());
    assert_eq!(out.json()["result"]["id"], 3);
}

/// Security defaults on a listener: a peer outside `allow_peers` and a
/// connection beyond `limits.max_connections` are closed at once.
#[test]
fn listener_refuses_unlisted_peers_and_connections_over_the_limit() {
    let only_v6 = Gcud::start(
        "[gcu]\ngroup = 5\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\nallow_peers = [\"::1\"]\n",
    );
    assert_closed_by_gcud(&only_v6.clients(), "127.0.0.1 is not allowed");
    only_v6.wait_for_log("peer not in allow_peers");

    let sim = Sim::pty(&[]);
    let one = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[limits]\nmax_connections = 1\n{CLIENTS}{}",
        port_entry(1, &sim)
    ));
    one.wait_for_log("port open port=1");
    // An allowed peer within the limit is kept: it is answered.
    let mut kept = WireClient::connect(&one.clients());
    kept.send(Address::new(5, 1, 1), 0, &Cmd::QueryPosition);
    kept.expect_result();
    drop(kept);
    eventually("that connection's slot to be free", || {
        one.log().matches("link closed").count() == 1
    });
    let mut first = WireClient::connect(&one.clients());
    eventually("the first client to be connected", || {
        one.log().matches("client connected").count() == 2
    });
    assert_closed_by_gcud(&one.clients(), "a second connection is over the limit");
    one.wait_for_log("limits.max_connections reached");
    first.send(Address::new(5, 1, 1), 0, &Cmd::QueryPosition);
    first.expect_result();
    drop(first);
    eventually("the slot to be free again", || {
        one.ctl(&["--to", "5.1.1", "position"]).code == 0
    });
}

// ---- honest outcomes, shutdown, poisoning, lease (ARCHITECTURE "Delivery contract") ----

/// Two GCUs: group 2 has the clients and a downstream link to group 5,
/// which has port 1 with gimbal 1 only (device 2 is silent; port 9 does
/// not exist).
fn two_gcus(sim: &Sim) -> (Gcud, Gcud) {
    let free = std::net::TcpListener::bind("127.0.0.1:0").expect("probe a free port");
    let addr = free.local_addr().expect("address").to_string();
    drop(free);
    let gcu5 = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{METRICS}{}[[link]]\nname = \"gcus\"\nrole = \"upstream\"\nlisten = \"{addr}\"\n",
        port_entry(1, sim)
    ));
    gcu5.wait_for_log("port open port=1");
    let gcu2 = Gcud::start(&format!(
        "[gcu]\ngroup = 2\ndefault_route = \"gcu5\"\n{CLIENTS}{METRICS}[[link]]\nname = \"gcu5\"\nrole = \"downstream\"\nconnect = \"{addr}\"\n"
    ));
    gcu2.wait_for_log("link connected");
    (gcu5, gcu2)
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
        for command in ["stop", "halt"] {
            let out = gcud.ctl(&["--from", from, "--to", to, command]);
            assert_eq!(out.code, *code, "{command} to {to} from {from}: {out:?}");
            assert!(
                out.stderr.contains(to) && out.stderr.contains(message),
                "the message names {to} and says {message:?}: {}",
                out.stderr
            );
        }
    }
    let out = gcu2.ctl(&["--json", "--from", "2", "--to", "5.1.2", "stop"]);
    assert_eq!(out.json()["outcome"], "device_silent", "{out:?}");
    // A live gimbal, directly and through two GCUs.
    for (gcud, from) in [(&gcu5, "0"), (&gcu2, "2")] {
        assert_eq!(gcud.ctl(&["--from", from, "--to", "5.1.1", "stop"]).code, 0);
        assert_eq!(gcud.ctl(&["--from", from, "--to", "5.1.1", "position"]).code, 0);
    }
    assert!(gcu5.log().contains("not delivered"), "{}", gcu5.log());
    assert!(gcu5.metric("gcud_commands_delivery_total{delivery=\"device_silent\"}") >= 4);
    assert!(gcu5.metric("gcud_commands_delivery_total{delivery=\"no_such_port\"}") >= 4);
    assert_eq!(gcu2.metric("gcud_commands_delivery_total{delivery=\"delivered\"}"), 2);
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

/// A client claiming another GCU's source group can neither speak as it
/// (default allow list: the MCU and this GCU) nor, where a listener allows
/// it, divert or drop the traffic routed to that GCU for anyone.
#[test]
fn a_client_speaking_as_another_gcu_never_poisons_its_route() {
    let sim = Sim::pty(&["--device", "1"]);
    let free = std::net::TcpListener::bind("127.0.0.1:0").expect("probe a free port");
    let addr = free.local_addr().expect("address").to_string();
    drop(free);
    let gcu5 = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{}[[link]]\nname = \"gcus\"\nrole = \"upstream\"\nlisten = \"{addr}\"\n",
        port_entry(1, &sim)
    ));
    gcu5.wait_for_log("port open port=1");
    let gcu2 = Gcud::start(&format!(
        "[gcu]\ngroup = 2\ndefault_route = \"gcu5\"\n{CLIENTS}\
         [[link]]\nname = \"open\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\nallow_source_groups = [0, 5]\n\
         [[link]]\nname = \"gcu5\"\nrole = \"downstream\"\nconnect = \"{addr}\"\n"
    ));
    gcu2.wait_for_log("link connected");
    let out = gcu2.ctl(&["--from", "5", "--to", "5.1.1", "position"]);
    assert_eq!(out.code, 16, "source group 5 is not a client's by default: {out:?}");
    assert!(out.stderr.contains("source group"), "{}", out.stderr);
    // The listener that allows group 5: one frame speaking as GCU 5.
    let mut spoofer = WireClient::connect(&gcu2.address("listening link=open"));
    spoofer.send(Address::new(2, 0, 0), 5, &Cmd::AwakeStatus);
    assert_eq!(spoofer.next(), OwnedEvent::Ack);
    for _ in 0..3 {
        let out = gcu2.ctl(&["--from", "0", "--to", "5.1.1", "position"]);
        assert_eq!(out.code, 0, "delivery to GCU 5 is intact: {out:?}\n{}", gcu2.log());
    }
    drop(spoofer);
    let out = gcu2.ctl(&["--from", "0", "--to", "5.1.1", "position"]);
    assert_eq!(out.code, 0, "and after the spoofer left: {out:?}");
}

/// A client (kept connected, returned) starts a slew of gimbal 5.1.1; gcud
/// must stop it mid-way by itself (lease, idle time-out, ...).
fn slew_that_gcud_stops(gcud: &Gcud) -> WireClient {
    let (start, client) = start_slew(gcud, &Cmd::PanRight);
    let stopped = gcud.settled_position("5.1.1");
    assert!(
        stopped.0 > start.0 && stopped.0 < 180.0,
        "stopped mid-way, not at a limit: {stopped:?}"
    );
    client
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

impl Gcud {
    fn config_path(&self) -> PathBuf {
        self.dir.path().join("gcud.toml")
    }

    /// Writes a new configuration file and sends SIGHUP; returns once the
    /// daemon logged `done` for the `nth` reload (1 = the first).
    fn reload(&self, config: Option<&str>, nth: usize, done: &str) {
        match config {
            Some(text) => std::fs::write(self.config_path(), text).expect("write config"),
            None => std::fs::remove_file(self.config_path()).expect("remove config"),
        }
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGHUP).expect("SIGHUP");
        eventually(&format!("reload {nth} to end with {done:?}"), || {
            let log = self.log();
            log.matches("SIGHUP: reloading").count() >= nth
                && log
                    .split("SIGHUP: reloading")
                    .nth(nth)
                    .is_some_and(|after| after.contains(done))
        });
    }
}

/// SIGHUP: an unchanged file disturbs nothing, an added and a changed port
/// are applied (a slew on the changed one is stopped first), a broken or
/// missing file is refused with its file:line and the daemon keeps running;
/// meanwhile a P? loop on port 1 never misses.
#[test]
fn sighup_reloads_the_difference_and_refuses_broken_files() {
    let sim1 = Sim::pty(&["--device", "1"]);
    let sim2 = Sim::pty(&["--device", "1", "--rate", "10"]);
    let sim3 = Sim::pty(&["--device", "1"]);
    let base = format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim1));
    let gcud = Gcud::start(&base);
    gcud.wait_for_log("port open port=1");

    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let clients = gcud.clients();
    let poller = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let (mut ok, mut failed) = (0u32, Vec::new());
            let started = Instant::now();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) && started.elapsed() < HANG_GUARD * 4 {
                let out = support::gimbalctl(&["--tcp", &clients, "--to", "5.1.1", "position"]);
                match out.code {
                    0 => ok += 1,
                    _ => failed.push(out),
                }
            }
            (ok, failed)
        })
    };

    gcud.reload(Some(&base), 1, "configuration unchanged");
    let with2 = format!("{base}{}", port_entry(2, &sim2));
    gcud.reload(Some(&with2), 2, "reload: port 2: added");
    gcud.wait_for_log("port open port=2");
    let start = gcud.position("5.2.1");

    let broken = format!("{with2}[[port]]\nid = \"three\"\n");
    gcud.reload(Some(&broken), 3, "reload refused");
    let refused = gcud
        .log()
        .lines()
        .find(|l| l.contains("reload refused"))
        .unwrap_or_default()
        .to_owned();
    assert!(
        refused.contains("gcud.toml:") && refused.contains("port[2].id"),
        "{refused}"
    );
    gcud.reload(None, 4, "reload refused");

    // Port 2 moves to another bus while its gimbal slews: stopped first.
    let mut client = WireClient::connect(&gcud.clients());
    client.send(Address::new(5, 2, 1), 0, &Cmd::PanRight);
    assert_eq!(client.next(), OwnedEvent::Ack);
    eventually("the slew to move the gimbal", || gcud.position("5.2.1").0 > start.0);
    let moved = format!("{base}{}", port_entry(2, &sim3));
    gcud.reload(Some(&moved), 5, "reload: port 2: changed");
    gcud.wait_for_log("port closed (configuration reloaded)");
    assert!(gcud.log().contains("dead-man PS to 5.2.1"), "{}", gcud.log());
    let first = sim2.position();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(sim2.position(), first, "the old bus's gimbal was stopped");
    eventually("port 2 on its new bus", || {
        gcud.ctl(&["--to", "5.2.1", "position"]).code == 0
    });

    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let (ok, failed) = poller.join().expect("poller");
    assert!(ok >= 3, "the P? loop ran ({ok})");
    assert!(failed.is_empty(), "the P? loop on port 1 missed: {failed:?}");
    drop(client);
}

/// `--check --against`: what a reload would change, without applying it.
#[test]
fn check_against_prints_what_a_reload_would_change() {
    let dir = tempfile::tempdir().expect("temp dir");
    let old = dir.path().join("old.toml");
    let new = dir.path().join("new.toml");
    // A client link: a GCU without links routes nothing and is refused.
    let head = format!("[gcu]\ngroup = 5\n{CLIENTS}[[port]]\nid = 1\nsimulate = [1]\n");
    std::fs::write(&old, format!("{head}[[port]]\nid = 2\nsimulate = [1]\n")).expect("write");
    std::fs::write(&new, format!("{head}[[port]]\nid = 3\nsimulate = [1]\n")).expect("write");
    let run = |a: &Path, b: &Path| {
        Command::new(env!("CARGO_BIN_EXE_gcud"))
            .args(["--check", "--config"])
            .arg(a)
            .arg("--against")
            .arg(b)
            .output()
            .expect("run gcud --check")
    };
    let out = run(&new, &old);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(
        text.contains("port 3: added") && text.contains("port 2: removed"),
        "{text}"
    );
    assert!(!text.contains("port 1"), "port 1 did not change: {text}");
    std::fs::write(&new, head.replace("group = 5", "group = 6")).expect("write");
    let out = run(&new, &old);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stdout).contains("gcu.group: changed; needs a restart"));
}

// ---- bounded and fair under hostile load (issue: per-connection state, hygiene, fairness, logs) ----

impl Gcud {
    fn rss_kib(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).expect("proc status");
        let line = status.lines().find(|l| l.starts_with("VmRSS:")).expect("VmRSS");
        line.split_whitespace()
            .nth(1)
            .and_then(|v| v.parse().ok())
            .expect("RSS in kB")
    }
}

/// Thousands of connections come and go: memory and the metrics stay flat
/// (a connection's counters fold into its configured link).
#[test]
fn connection_churn_leaves_memory_and_metrics_flat() {
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{METRICS}"));
    let addr = gcud.clients();
    let aw = FrameBuf::new(Address::new(5, 0, 0), 0, b"AW").expect("frame");
    let churn = |n: usize| {
        for _ in 0..n {
            let mut s = TcpStream::connect(&addr).expect("connect");
            s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
            s.write_all(aw.as_bytes()).expect("send");
            let mut ack = [0u8; 1];
            assert_eq!(s.read(&mut ack).expect("the ACK"), 1);
        }
        eventually("every churned connection to be closed", || {
            gcud.metric("gcud_connections_open") == 0
        });
    };
    churn(500); // warm up allocator pools and the metrics' label set
    let (rss_before, metrics_before) = (gcud.rss_kib(), gcud.metrics().len());
    churn(5000);
    let (rss_after, metrics_after) = (gcud.rss_kib(), gcud.metrics().len());
    eprintln!(
        "5000 connections: RSS {rss_before} -> {rss_after} KiB, /metrics {metrics_before} -> {metrics_after} bytes"
    );
    assert_eq!(gcud.metric("gcud_connections_accepted_total"), 5500);
    assert!(
        gcud.metric("gcud_link_frames_in_total{link=\"clients\",role=\"client\"}") >= 5000,
        "the connections' counters live on in their link's"
    );
    assert!(
        metrics_after <= metrics_before + 200,
        "metrics grew from {metrics_before} to {metrics_after} bytes"
    );
    assert!(
        rss_after <= rss_before + 2048,
        "RSS grew from {rss_before} to {rss_after} KiB over 5000 connections"
    );
}

/// Connections that hold their slot and say nothing do not lock a newcomer
/// out: at the limit, the one idle the longest is evicted.
#[test]
fn idle_holders_make_room_for_a_newcomer() {
    let sim = Sim::pty(&[]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[limits]\nmax_connections = 2\n{CLIENTS}{METRICS}{}",
        port_entry(1, &sim)
    ));
    gcud.wait_for_log("port open port=1");
    let holders: Vec<TcpStream> = (0..2)
        .map(|_| TcpStream::connect(gcud.clients()).expect("connect"))
        .collect();
    eventually("both holders to be admitted", || {
        gcud.metric("gcud_connections_open") == 2
    });
    std::thread::sleep(Duration::from_millis(1200));
    let out = gcud.ctl(&["--to", "5.1.1", "position"]);
    assert_eq!(out.code, 0, "the newcomer is served: {out:?}\n{}", gcud.log());
    assert_eq!(gcud.metric("gcud_connections_closed_total{why=\"evicted\"}"), 1);
    assert!(gcud.log().contains("connection evicted"), "{}", gcud.log());
    drop(holders);
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

/// A bus that spews frames nobody asked for: every one is counted, but
/// the log holds a burst and a summary, not a line per frame.
#[test]
fn a_spewing_bus_is_counted_exactly_and_logged_briefly() {
    let bus = std::net::TcpListener::bind("127.0.0.1:0").expect("bind the fake device server");
    let addr = bus.local_addr().expect("address");
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{METRICS}[[port]]\nid = 1\ntcp = \"{addr}\"\n"
    ));
    let (mut line, _) = bus.accept().expect("gcud connects");
    let stray = FrameBuf::new(Address::new(7, 1, 1), 5, b"00000000").expect("frame");
    let burst: Vec<u8> = (0..200).flat_map(|_| stray.as_bytes().to_vec()).collect();
    for _ in 0..50 {
        line.write_all(&burst).expect("spew");
    }
    eventually("every stray frame to be counted", || {
        gcud.metric("gcud_port_drops_total{port=\"1\",reason=\"unsolicited\"}") == 10_000
    });
    let log = gcud.log();
    let lines = log.lines().filter(|l| l.contains("Unsolicited")).count();
    assert!(
        (1..=12).contains(&lines),
        "{lines} log lines for 10000 stray frames (a burst and a summary, not none):\n{log}"
    );
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

/// One peer cannot hold more than `limits.max_connections_per_peer`, and
/// `/metrics` answers only its own `allow_peers`.
#[test]
fn per_peer_cap_and_metrics_allow_peers_hold() {
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[limits]\nmax_connections_per_peer = 2\n{CLIENTS}{METRICS}"
    ));
    let held: Vec<TcpStream> = (0..2)
        .map(|_| TcpStream::connect(gcud.clients()).expect("connect"))
        .collect();
    eventually("both admitted", || gcud.metric("gcud_connections_open") == 2);
    assert_closed_by_gcud(&gcud.clients(), "the third connection of one peer");
    assert_eq!(
        gcud.metric("gcud_connections_refused_total{why=\"max_connections_per_peer\"}"),
        1
    );
    drop(held);

    // A peer outside `[metrics] allow_peers` is closed at accept, unanswered.
    let closed = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}[metrics]\nlisten = \"127.0.0.1:0\"\nallow_peers = [\"::1\"]\n"
    ));
    let metrics = closed.address("metrics at /metrics");
    for path in ["/metrics", "/status", "/healthz"] {
        let mut s = TcpStream::connect(&metrics).expect("connect");
        s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
        let _ = write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n");
        let mut text = String::new();
        let answered = s.read_to_string(&mut text).is_ok_and(|n| n > 0);
        assert!(!answered, "127.0.0.1 may not GET {path}: {text}");
    }
}

/// gcud keeps what it learns of each device (the router core's registry)
/// and shows it: `/status` (JSON) and per-device gauges with Unix times;
/// `/healthz` answers while the router task does.
#[test]
fn status_metrics_and_health_show_the_devices_gcud_has_seen() {
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\nname = \"field gcu\"\n[[port]]\nid = 1\nsimulate = [1, 2]\n{CLIENTS}{METRICS}"
    ));
    let health = gcud.http_get("/healthz");
    assert!(
        health.starts_with("HTTP/1.1 200") && health.ends_with("ok\n"),
        "{health}"
    );
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .expect("clock")
        .as_secs_f64();
    let out = gcud.ctl(&["--to", "5.1.1", "goto", "12.5", "-3", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}");
    let (pan, tilt) = gcud.position("5.1.1");
    assert_eq!((pan, tilt), (12.5, -3.0));
    let out = gcud.ctl(&["--to", "5.1.9", "id"]);
    assert_eq!(out.code, 8, "nobody at 5.1.9: {out:?}");

    let status = gcud.status();
    assert_eq!(status["gcud"]["group"], 5);
    assert_eq!(status["gcud"]["name"], "field gcu");
    assert_eq!(status["gcud"]["shutting_down"], false);
    let port = &status["ports"][0];
    assert_eq!(
        (port["port"].as_u64(), port["open"].as_bool()),
        (Some(1), Some(true)),
        "{port}"
    );
    let devices = port["devices"].as_array().expect("devices");
    let device = |n: u64| {
        devices
            .iter()
            .find(|d| d["device"].as_u64() == Some(n))
            .unwrap_or_else(|| panic!("device {n} in {port}"))
    };
    let one = device(1);
    assert_eq!(one["address"], "5.1.1");
    assert_eq!(one["online"], true);
    assert_eq!(one["position"]["pan_deg"].as_f64(), Some(12.5), "{one}");
    assert_eq!(one["position"]["tilt_deg"].as_f64(), Some(-3.0), "{one}");
    let seen = one["last_seen_unix"].as_f64().expect("last seen");
    assert!(
        seen >= before - 1.0 && seen < before + 600.0,
        "a Unix time: {seen} vs {before}"
    );
    // Issue 24: an address that never answered (nobody at 5.1.9) leaves
    // nothing behind; a device that answered once and then went silent
    // stays, offline (crates/gcu/tests/rules.rs, the device registry).
    assert!(
        devices.iter().all(|d| d["device"] != 9 && d["device"] != 2),
        "only devices that answered: {port}"
    );
    assert_eq!(status["links"][0]["link"], "clients");

    let one = "{port=\"1\",device=\"1\"}";
    assert_eq!(gcud.real_metric(&format!("gcud_device_online{one}")), Some(1.0));
    assert_eq!(
        gcud.real_metric(&format!("gcud_device_position_pan_degrees{one}")),
        Some(12.5)
    );
    assert_eq!(
        gcud.real_metric(&format!("gcud_device_position_tilt_degrees{one}")),
        Some(-3.0)
    );
    assert!(
        !gcud.metrics().contains("device=\"9\""),
        "no series for an address that never answered"
    );
    let seen = gcud.real_metric(&format!("gcud_device_last_seen_timestamp_seconds{one}"));
    assert!(seen.is_some_and(|t| t >= before - 1.0), "{seen:?}");
    assert!(
        gcud.metrics().contains("gcud_build_info{version=\""),
        "{}",
        gcud.metrics()
    );

    // The operator's view of the same: gimbalctl gcud-status.
    let http = gcud.address("metrics at /metrics");
    let out = support::gimbalctl(&["gcud-status", "--http", &http]);
    assert_eq!(out.code, 0, "{out:?}");
    let line = |address: &str| {
        out.stdout
            .lines()
            .find(|l| l.trim_start().starts_with(address))
            .unwrap_or_else(|| panic!("{address} in {}", out.stdout))
    };
    assert!(
        line("5.1.1").contains("yes") && line("5.1.1").contains("pan 12.50° tilt -3.00°"),
        "{out:?}"
    );
    assert!(
        !out.stdout.lines().any(|l| l.trim_start().starts_with("5.1.9")),
        "{out:?}"
    );
    assert!(
        out.stdout.starts_with("gcud ") && out.stdout.contains("\"field gcu\" (group 5)"),
        "{out:?}"
    );
    let out = support::gimbalctl(&["--json", "gcud-status", "--http", &http]);
    assert_eq!(out.code, 0, "{out:?}");
    let json = out.json();
    assert_eq!(json["ok"], true);
    assert_eq!(json["status"]["ports"][0]["devices"][0]["address"], "5.1.1", "{json}");
    drop(gcud);
    let out = support::gimbalctl(&["--json", "gcud-status", "--http", &http]);
    assert_eq!(out.code, 1, "gcud is gone: {out:?}");
    assert_eq!(out.json()["outcome"], "io", "{out:?}");
    assert!(
        out.stderr.contains(&format!("http://{http}/status")),
        "names what it asked: {out:?}"
    );
}

/// Under systemd (`JOURNAL_STREAM` set) each line starts with its syslog
/// priority, so journald records the level: `<6>` for info.
#[test]
fn journal_lines_carry_their_priority() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, format!("[gcu]\ngroup = 5\n{CLIENTS}")).expect("write config");
    let log = std::fs::File::create(dir.path().join("gcud.log")).expect("log file");
    let child = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .arg("--config")
        .arg(&path)
        .env("RUST_LOG", "info")
        .env("JOURNAL_STREAM", "8:1234")
        .stdout(Stdio::null())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("spawn gcud");
    let gcud = Gcud { child, dir };
    let ready = gcud.wait_for_log("gcud ready");
    assert!(ready.starts_with("<6>"), "{ready:?}");
    let (status, log) = gcud.terminate();
    assert!(status.is_some_and(|s| s.success()), "exit status {status:?}\n{log}");
    for line in log.lines() {
        let prefixed = ["<3>", "<4>", "<6>", "<7>"].iter().any(|p| line.starts_with(p));
        assert!(prefixed, "a line without its priority: {line:?}\n{log}");
    }
}

/// A clean SIGTERM is not a loss: the ports and links that end with it log
/// at info or below, never WARN; a port lost while running stays a WARN.
#[test]
fn clean_sigterm_logs_no_warning() {
    // A real loss while running: the device end of the port goes away.
    let lost = Sim::pty(&[]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &lost)));
    gcud.wait_for_log("port open port=1");
    drop(lost);
    let line = gcud.wait_for_log("port lost");
    assert!(line.contains("WARN"), "{line}");
    drop(gcud);

    let sim = Sim::pty(&[]);
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{CLIENTS}{}", port_entry(1, &sim)));
    gcud.wait_for_log("port open port=1");
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0);
    // A client connection still open when the signal comes.
    let held = TcpStream::connect(gcud.clients()).expect("connect");
    eventually("the held connection to be up", || {
        gcud.log().lines().filter(|l| l.contains("client connected")).count() == 2
    });
    let (status, log) = gcud.terminate();
    drop(held);
    assert!(status.is_some_and(|s| s.success()), "exit status {status:?}\n{log}");
    let after = log
        .split_once("shutting down")
        .map(|(_, after)| after)
        .unwrap_or_else(|| panic!("no \"shutting down\" line:\n{log}"));
    // The port's end is logged (so a WARN for it would be seen), at info.
    let ended = after
        .lines()
        .find(|l| l.contains("port=1") && !l.contains("port open"))
        .unwrap_or_else(|| panic!("the port's end is not logged after \"shutting down\":\n{log}"));
    assert!(ended.contains("INFO"), "{ended}");
    let warnings: Vec<&str> = after
        .lines()
        .filter(|l| l.contains("WARN") || l.contains("ERROR"))
        .collect();
    assert!(
        warnings.is_empty(),
        "a clean shutdown warned: {warnings:#?}\nlog:\n{log}"
    );
}

/// A client that stops reading cannot grow gcud: what its line has not
/// taken is capped (64 KiB), more is dropped and logged, and another
/// client is still answered.
#[test]
fn a_client_that_stops_reading_cannot_grow_the_daemon() {
    let gcud = Gcud::start(&format!("[gcu]\ngroup = 5\n{METRICS}{CLIENTS}"));
    let addr = gcud.clients();
    let heap_before = gcud.metric("gcud_heap_bytes");
    let mut hog = TcpStream::connect(&addr).expect("connect");
    hog.set_write_timeout(Some(Duration::from_secs(10))).expect("timeout");
    // D? to the GCU itself: ACK and a Table 6 answer for every 10 bytes sent.
    let ask = FrameBuf::build(Address::new(5, 0, 0), 0, |b| Cmd::Identify.encode(b).map(<[u8]>::len)).expect("encode");
    let burst: Vec<u8> = (0..1000).flat_map(|_| ask.as_bytes().to_vec()).collect();
    for _ in 0..400 {
        if hog.write_all(&burst).is_err() {
            break;
        }
    }
    // Every command read and answered (into the line or dropped): the
    // heap holds what the line keeps, not the ~18 MB of answers.
    eventually("every command to be read", || {
        gcud.metric("gcud_link_frames_in_total{link=\"clients\",role=\"client\"}") == 400_000
    });
    let heap = gcud.metric("gcud_heap_bytes");
    assert!(
        heap < heap_before + (4 << 20),
        "gcud's heap grew from {heap_before} to {heap} bytes for a client that does not read"
    );
    gcud.wait_for_log("the peer is not reading");
    let mut other = WireClient::connect(&addr);
    other.send(Address::new(5, 0, 0), 0, &Cmd::Identify);
    assert_eq!(other.next(), OwnedEvent::Ack);
    assert!(
        matches!(other.next(), OwnedEvent::Frame(_)),
        "the other client is answered"
    );
}
