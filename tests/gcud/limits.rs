//! Links and listeners under load (ARCHITECTURE "Bounded and fair under
//! load"): client links that wait for their peer, unlisted peers and caps
//! refused, idle holders evicted, a spewing bus, a client that stops reading.

use super::*;

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
    // The drop in words (issue 53: no Debug form such as `Unsolicited`).
    let lines = log
        .lines()
        .filter(|l| l.contains("a frame nobody was waiting for"))
        .count();
    assert!(
        (1..=12).contains(&lines),
        "{lines} log lines for 10000 stray frames (a burst and a summary, not none):\n{log}"
    );
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
