//! Routing through real gcud binaries (ARCHITECTURE "Routing semantics"):
//! Table 3 results across two GCUs, dial-in listener routes, wildcards,
//! all 254 ports, ports corrupted or vanished, routes a client cannot poison.

use super::*;

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
    // Group 255 to port 2, which only GCU 5 has: delivered there, so
    // delivered, and ACKed (GCU 2 used to report `03 no such port` for
    // it, while GCU 5 ran it).
    let mut client = WireClient::connect(&gcu2.clients());
    client.send(Address::new(255, 2, 1), 0, &Cmd::MotorsStop);
    // GCU 2 has no port 2: only GCU 5's report `00` gives this ACK.
    assert_eq!(client.next(), OwnedEvent::Ack, "{}", gcu2.log());
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

/// `[gcu] threads = 3`: the ports' I/O on two threads of their own. Every
/// port routes, a damaged line recovers, a rate switch reaches the port's
/// terminal, and a port that vanishes comes back while the others go on.
#[test]
fn ports_on_threads_of_their_own_route_recover_and_switch_rate() {
    let dir = tempfile::tempdir().expect("temp dir");
    let link1: PathBuf = dir.path().join("bus1");
    let link1_arg = link1.to_str().expect("utf-8 path").to_owned();
    let first = Sim::pty(&["--link", &link1_arg]);
    let bus2 = Sim::pty(&["--seed", "7", "--corrupt", "0.3", "--nak", "0.3", "--max-faults", "12"]);
    let bus3 = Sim::pty(&["--device", "1,2"]);
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\nthreads = 3\n{CLIENTS}{METRICS}[[port]]\nid = 1\npath = \"{}\"\n{}{}",
        link1.display(),
        port_entry(2, &bus2),
        port_entry(3, &bus3)
    ));
    for port in 1..=3 {
        gcud.wait_for_log(&format!("port open port={port}"));
    }
    let mut threads: Vec<String> = std::fs::read_dir(format!("/proc/{}/task", gcud.child.id()))
        .expect("gcud's threads")
        .flatten()
        .map(|t| {
            std::fs::read_to_string(t.path().join("comm"))
                .unwrap_or_default()
                .trim()
                .to_owned()
        })
        .filter(|name| name.starts_with("gcud-ports"))
        .collect();
    threads.sort();
    assert_eq!(threads, ["gcud-ports-1", "gcud-ports-2"], "two port threads");
    for (i, to) in ["5.1.1", "5.2.1", "5.3.1", "5.3.2"].into_iter().enumerate() {
        let pan = 10.0 * (i as f64 + 1.0);
        let out = gcud.ctl(&["--to", to, "goto", &pan.to_string(), "5", "--wait"]);
        assert_eq!(out.code, 0, "{to}: {out:?}\n{}", gcud.log());
        assert_eq!(gcud.position(to), (pan, 5.0), "{to}");
    }
    for _ in 0..8 {
        let out = gcud.ctl(&["--to", "5.2.1", "position"]);
        assert_eq!(out.code, 0, "the damaged line recovers: {out:?}\n{}", gcud.log());
    }
    assert!(
        gcud.metric("gcud_port_bad_checksums_total{port=\"2\"}") > 0,
        "damage was seen"
    );

    // A rate switch of port 3's bus (device 255: every gimbal on it),
    // applied to its terminal from the router's thread.
    let out = gcud.ctl(&["--to", "5.3.255", "data-rate", "19200"]);
    assert_eq!(out.code, 0, "{out:?}\n{}", gcud.log());
    gcud.wait_for_log("line rate switched port=3 baud=19200");
    let out = gcud.ctl(&["--to", "5.3.2", "position"]);
    assert_eq!(out.code, 0, "port 3 answers at its new rate: {out:?}\n{}", gcud.log());

    first.stop();
    eventually("gcud to notice port 1 is gone", || {
        gcud.metric("gcud_port_open{port=\"1\"}") == 0
    });
    for to in ["5.2.1", "5.3.1"] {
        let out = gcud.ctl(&["--to", to, "position"]);
        assert_eq!(out.code, 0, "{to} keeps working while port 1 is away: {out:?}");
    }
    let _second = Sim::pty(&["--link", &link1_arg]);
    eventually("port 1 to answer again", || {
        gcud.ctl(&["--to", "5.1.1", "position"]).code == 0
    });
    let (status, log) = gcud.terminate();
    assert!(status.is_some_and(|s| s.success()), "{log}");
    assert!(log.contains("port closed: gcud stopping port=2"), "{log}");
}
