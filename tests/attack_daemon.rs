//! Issue 20, the daemon's side: the real `gcud` under attack on its HTTP
//! endpoint, its descriptors, its capture and its reloads, while another
//! client's `P?` must still be answered. Each test prints the latency of
//! that client's `P?` during the attack (figures, never assertions: the
//! machine is shared). `GCUD_BIN=/path/to/gcud` runs them against another
//! build (e.g. one without the fixes, to watch them fail).

mod support;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::Signal;
use sagebrush_protocol::{Address, Command as Cmd};
use support::gcud::{CLIENTS, Gcud, WireClient, port_entry};
use support::{Sim, eventually};

/// The gcud under test.
fn gcud_bin() -> String {
    std::env::var("GCUD_BIN").unwrap_or_else(|_| env!("CARGO_BIN_EXE_gcud").to_owned())
}

/// Starts gcud on `config` (`{dir}` is its private directory) with at most
/// `nofile` descriptors (soft and hard limit: gcud cannot raise it).
fn start(config: &str, nofile: u32) -> Gcud {
    let dir = tempfile::tempdir().expect("temp dir");
    let config = config.replace("{dir}", &dir.path().display().to_string());
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, config).expect("write config");
    let log = std::fs::File::create(dir.path().join("gcud.log")).expect("log file");
    let child = Command::new("bash")
        .arg("-c")
        .arg(format!("ulimit -n {nofile} && exec \"$0\" --config \"$1\""))
        .arg(gcud_bin())
        .arg(&path)
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("spawn gcud");
    let gcud = Gcud { child, dir };
    gcud.wait_for_log("gcud ready");
    gcud
}

fn signal(gcud: &Gcud, signal: Signal) {
    nix::sys::signal::kill(nix::unistd::Pid::from_raw(gcud.child.id() as i32), signal).expect("signal gcud");
}

/// `P?` to 5.1.1 and its result, `n` times on one connection: the
/// latencies, sorted.
fn query_latencies(client: &mut WireClient, n: usize) -> Vec<Duration> {
    let mut times: Vec<Duration> = (0..n)
        .map(|_| {
            let sent = Instant::now();
            client.send(Address::new(5, 1, 1), 0, &Cmd::QueryPosition);
            client.expect_result();
            sent.elapsed()
        })
        .collect();
    times.sort();
    times
}

/// Prints the median and the worst of `times` for the closing note.
fn report(what: &str, times: &[Duration]) {
    println!(
        "P? latency {what}: p50 {:.2} ms, max {:.2} ms over {}",
        times[times.len() / 2].as_secs_f64() * 1e3,
        times[times.len() - 1].as_secs_f64() * 1e3,
        times.len()
    );
}

/// A TCP connection to `to` from the loopback address `from` (127.0.0.2 is
/// loopback too, and outside an allow list of 127.0.0.1); `None` when the
/// listener's backlog is full (a gcud that stopped accepting).
fn connect_from(from: &str, to: &str) -> Option<TcpStream> {
    let to: SocketAddr = to.parse().expect("address");
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).expect("socket");
    let from: SocketAddr = format!("{from}:0").parse().expect("source address");
    socket.bind(&from.into()).expect("bind the source address");
    socket.connect_timeout(&to.into(), Duration::from_secs(2)).ok()?;
    Some(socket.into())
}

fn healthz(gcud: &Gcud) -> String {
    gcud.http_get("/healthz")
}

const METRICS_LOOPBACK: &str = "[metrics]\nlisten = \"127.0.0.1:0\"\nallow_peers = [\"127.0.0.1\"]\n";

/// Point 3: 300 idle connections from a peer outside `[metrics]
/// allow_peers` to a gcud with 64 descriptors: each is closed at accept,
/// before a byte is read, so gcud keeps its descriptors: a new client's
/// `P?` is answered and `/healthz` works from an allowed peer. Connections
/// from an allowed peer that send nothing are capped and time out.
#[test]
fn idle_http_connections_from_an_unlisted_peer_take_no_descriptors() {
    let sim = Sim::pty(&["--device", "1"]);
    let gcud = start(
        &format!("[gcu]\ngroup = 5\n{}{CLIENTS}{METRICS_LOOPBACK}", port_entry(1, &sim)),
        64,
    );
    gcud.wait_for_log("port open port=1");
    let metrics = gcud.address("metrics at /metrics");
    let mut before = WireClient::connect(&gcud.clients());
    report("before the attack", &query_latencies(&mut before, 50));

    let attack: Vec<TcpStream> = (0..300).filter_map(|_| connect_from("127.0.0.2", &metrics)).collect();
    let mut client = WireClient::connect(&gcud.clients());
    let during = query_latencies(&mut client, 50);
    report("with 300 idle HTTP connections from 127.0.0.2", &during);
    let health = healthz(&gcud);
    assert!(health.starts_with("HTTP/1.1 200"), "{health}\n{}", gcud.log());
    assert!(
        gcud.metric("gcud_http_connections_refused_total{why=\"allow_peers\"}") >= 300,
        "{}",
        gcud.metrics()
    );
    let log = gcud.log();
    assert!(
        log.matches("not in [metrics] allow_peers").count() <= 10,
        "refusals are logged throttled:\n{log}"
    );
    drop(attack);

    // An allowed peer's idle connections: capped, then timed out.
    let mut idle: Vec<TcpStream> = (0..40).filter_map(|_| connect_from("127.0.0.1", &metrics)).collect();
    let mut client = WireClient::connect(&gcud.clients());
    report(
        "with 40 idle HTTP connections from an allowed peer",
        &query_latencies(&mut client, 50),
    );
    // The first (within the cap) is closed for sending no request head: the
    // header time-out is 5 s; 30 s is generous on a loaded machine and
    // still well below a connection's 60 s lifetime, which would close it too.
    idle[0]
        .set_read_timeout(Some(Duration::from_secs(30)))
        .expect("timeout");
    let closed = match idle[0].read(&mut [0u8; 64]) {
        Ok(n) => n == 0,
        Err(e) => e.kind() == std::io::ErrorKind::ConnectionReset,
    };
    assert!(closed, "an idle HTTP connection is closed by its header time-out");
    eventually("idle HTTP connections to time out and /healthz to answer", || {
        let mut s = TcpStream::connect(&metrics).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(10))).expect("timeout");
        let _ = write!(s, "GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
        let mut text = String::new();
        let _ = s.read_to_string(&mut text);
        text.starts_with("HTTP/1.1 200")
    });
    // 64 descriptors: at most 8 HTTP connections, the others closed at once.
    let over_cap = gcud.metric("gcud_http_connections_refused_total{why=\"max_connections\"}");
    assert!(over_cap >= 32, "{over_cap} closed over the cap of 8");
    drop(idle);
}

/// Point 3 and 9: descriptors run out on the client listener (80
/// connections allowed by the configuration, 64 descriptors): "accept
/// failed" is logged throttled, and a connected client is still answered.
#[test]
fn descriptor_exhaustion_on_the_client_listener_is_logged_throttled() {
    let sim = Sim::pty(&["--device", "1"]);
    let gcud = start(
        &format!(
            "[gcu]\ngroup = 5\n[limits]\nmax_connections = 200\n{}{CLIENTS}",
            port_entry(1, &sim)
        ),
        64,
    );
    gcud.wait_for_log("port open port=1");
    let told = gcud.wait_for_log("the descriptor limit is below");
    assert!(told.contains("limit=64") && told.contains("needed=242"), "{told}");
    let mut client = WireClient::connect(&gcud.clients());
    let flood: Vec<TcpStream> = (0..120)
        .map(|_| TcpStream::connect(gcud.clients()).expect("connect"))
        .collect();
    gcud.wait_for_log("accept failed");
    // Long enough for an unthrottled loop (one line per 100 ms) to write
    // dozens of lines.
    let started = Instant::now();
    let mut during = Vec::new();
    while started.elapsed() < Duration::from_secs(4) {
        during.extend(query_latencies(&mut client, 5));
    }
    during.sort();
    report("while the client listener has no descriptors left", &during);
    let log = gcud.log();
    let failed = log.lines().filter(|l| l.contains("accept failed")).count();
    assert!(
        (1..=10).contains(&failed),
        "{failed} \"accept failed\" lines in 4 s: throttled to 10 per 10 s\n{log}"
    );
    drop(flood);
    eventually("a new client to be answered", || {
        gcud.ctl(&["--to", "5.1.1", "position"]).code == 0
    });
}

/// The blocks of a pcapng stream: (type, body) each, checking that every
/// block's two lengths agree and that the stream ends on a block boundary.
fn pcapng_blocks(data: &[u8]) -> Vec<(u32, Vec<u8>)> {
    let u32_at = |i: usize| u32::from_le_bytes(data[i..i + 4].try_into().expect("4 bytes"));
    let (mut at, mut blocks) = (0, Vec::new());
    while at < data.len() {
        assert!(at + 12 <= data.len(), "a block cut short at {at} of {}", data.len());
        let (kind, len) = (u32_at(at), u32_at(at + 4) as usize);
        assert!(len >= 12 && at + len <= data.len(), "block at {at}: length {len}");
        assert_eq!(u32_at(at + len - 4) as usize, len, "block at {at}: trailing length");
        blocks.push((kind, data[at + 8..at + len - 4].to_vec()));
        at += len;
    }
    blocks
}

/// Point 4: a FIFO as `[capture] file` that nobody reads: gcud starts
/// (binds, says ready), routes and answers `/healthz`; SIGUSR1 stops and
/// starts it; a reader that stalls does not stall routing, nor does
/// stopping the capture while it stalls; once it reads, it gets a valid
/// pcapng with the traffic.
#[test]
fn a_fifo_capture_without_a_reader_stalls_nothing() {
    use nix::fcntl::{FcntlArg, fcntl};
    let sim = Sim::pty(&["--device", "1"]);
    let fifo_dir = tempfile::tempdir().expect("temp dir");
    let fifo = fifo_dir.path().join("live.pcapng");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::from_bits_truncate(0o600)).expect("mkfifo");
    let gcud = start(
        &format!(
            "[gcu]\ngroup = 5\n{}{CLIENTS}{METRICS_LOOPBACK}[capture]\nfile = \"{}\"\n",
            port_entry(1, &sim),
            fifo.display()
        ),
        1024,
    );
    gcud.wait_for_log("port open port=1");
    gcud.wait_for_log("capture started");
    let mut client = WireClient::connect(&gcud.clients());
    report("capturing to a FIFO nobody reads", &query_latencies(&mut client, 50));
    assert!(healthz(&gcud).starts_with("HTTP/1.1 200"), "{}", gcud.log());

    signal(&gcud, Signal::SIGUSR1);
    gcud.wait_for_log("capture stopped (SIGUSR1)");
    signal(&gcud, Signal::SIGUSR1);
    eventually("the second capture to start", || {
        gcud.log().matches("capture started").count() == 2
    });
    query_latencies(&mut client, 5);

    // A reader that opens the FIFO, shrinks its buffer to one page and
    // stops reading until told.
    let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
    let reader_path = fifo.clone();
    let reader = std::thread::spawn(move || {
        let mut file = std::fs::File::open(&reader_path).expect("open the FIFO for reading");
        let _ = fcntl(&file, FcntlArg::F_SETPIPE_SZ(4096));
        go_rx.recv().expect("go");
        let mut data = Vec::new();
        file.read_to_end(&mut data).expect("read the FIFO");
        data
    });
    gcud.wait_for_log("the FIFO has a reader");
    let stalled = query_latencies(&mut client, 100);
    report("capturing to a FIFO whose reader stalls", &stalled);
    assert!(healthz(&gcud).starts_with("HTTP/1.1 200"), "{}", gcud.log());

    // Stopped while the reader stalls: the capture's writer waits for the
    // reader (up to 2 s), routing does not (the stop's log line comes
    // after the writer gave up waiting, the answer before).
    signal(&gcud, Signal::SIGUSR1);
    let stopping = query_latencies(&mut client, 1);
    report("right after SIGUSR1 stops a stalled FIFO capture", &stopping);
    assert_eq!(
        gcud.log().matches("capture stopped (SIGUSR1)").count(),
        1,
        "the P? sent after SIGUSR1 was answered only after the capture stopped: routing waited for it\n{}",
        gcud.log()
    );
    gcud.wait_for_log("records=");
    eventually("the stop to be logged", || {
        gcud.log().matches("capture stopped (SIGUSR1)").count() == 2
    });
    go_tx.send(()).expect("tell the reader to read");
    let data = reader.join().expect("reader");
    let blocks = pcapng_blocks(&data);
    assert_eq!(blocks[0].0, 0x0A0D_0D0A, "a section header first");
    assert!(blocks.iter().any(|(kind, _)| *kind == 1), "an interface block");
    let frames = blocks
        .iter()
        .filter(|(kind, body)| *kind == 6 && body.get(21) == Some(&1))
        .count();
    assert!(frames >= 2, "{frames} frame records in {} blocks", blocks.len());
    assert!(healthz(&gcud).starts_with("HTTP/1.1 200"), "{}", gcud.log());
}

/// Point 6: a reload whose new listener cannot bind (its address is in
/// use) is refused as a whole with the reason, the running configuration
/// stays (port 1, which the new file removes, still answers), `/status`
/// does not show the link, and a later SIGHUP applies it once the address
/// is free.
#[test]
fn a_reload_whose_listener_cannot_bind_is_refused_whole() {
    let sim = Sim::pty(&["--device", "1"]);
    let gcud = start(
        &format!("[gcu]\ngroup = 5\n{}{CLIENTS}{METRICS_LOOPBACK}", port_entry(1, &sim)),
        1024,
    );
    gcud.wait_for_log("port open port=1");
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let addr = taken.local_addr().expect("address");
    let new = format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{METRICS_LOOPBACK}[[link]]\nname = \"gcu2\"\nrole = \"downstream\"\nlisten = \"{addr}\"\n"
    );
    std::fs::write(gcud.dir.path().join("gcud.toml"), &new).expect("write config");
    signal(&gcud, Signal::SIGHUP);
    let refused = gcud.wait_for_log("reload refused");
    assert!(
        refused.contains("gcu2") && refused.contains(&addr.to_string()),
        "{refused}"
    );
    let mut client = WireClient::connect(&gcud.clients());
    report("after a refused reload", &query_latencies(&mut client, 20));
    let status = gcud.status();
    let links: Vec<&str> = status["links"]
        .as_array()
        .expect("links")
        .iter()
        .filter_map(|l| l["link"].as_str())
        .collect();
    assert_eq!(links, ["clients"], "{status}");

    drop(taken);
    signal(&gcud, Signal::SIGHUP);
    gcud.wait_for_log("listening link=gcu2");
    let log = gcud.log();
    assert!(!log.contains("configuration unchanged"), "{log}");
    assert!(TcpStream::connect(addr).is_ok(), "gcu2 listens");

    // A changed link keeping its address takes its listener over (binding
    // anew would find the address in use by the link being replaced).
    std::fs::write(
        gcud.dir.path().join("gcud.toml"),
        new.replace("role = \"downstream\"", "role = \"upstream\""),
    )
    .expect("write config");
    signal(&gcud, Signal::SIGHUP);
    gcud.wait_for_log("reload: link \"gcu2\": changed");
    eventually("gcu2 to listen again", || {
        gcud.log().matches("listening link=gcu2").count() == 2
    });
    assert_eq!(gcud.log().matches("reload refused").count(), 1, "{}", gcud.log());
    assert!(TcpStream::connect(addr).is_ok(), "gcu2 listens on its address");
}

/// gcud (group 5, `extra` in its configuration) with port 1 open on a TCP
/// device server: gimbalsim serving device 1.
fn behind_a_device_server(extra: &str) -> (Sim, Gcud) {
    let sim = Sim::tcp(&["--device", "1"]);
    let gcud = start(
        &format!(
            "[gcu]\ngroup = 5\n{extra}[[port]]\nid = 1\ntcp = \"{}\"\n{CLIENTS}",
            sim.endpoint
        ),
        1024,
    );
    gcud.wait_for_log("port open port=1");
    (sim, gcud)
}

/// Point 9: a port on a TCP device server is not reported as ignoring a
/// line rate change each time it opens.
#[test]
fn a_device_server_port_opens_without_a_rate_warning() {
    let (_sim, gcud) = behind_a_device_server("");
    let mut client = WireClient::connect(&gcud.clients());
    query_latencies(&mut client, 3);
    let log = gcud.log();
    assert!(!log.contains("not applied locally"), "{log}");
}

/// Issue 35: on a TCP device server gcud's ACK of a result waits up to
/// `lines::ACK_HOLD` for the port's next write (one segment, not two);
/// with no next write it still goes, alone: every result the device sent
/// is acknowledged, by the device's own count, queries spaced apart (each
/// a gimbalctl run) and back to back (one client's `P?` after `P?`).
#[test]
fn every_result_from_a_device_server_is_acknowledged_whether_or_not_a_command_follows() {
    let (sim, gcud) = behind_a_device_server("[metrics]\nlisten = \"127.0.0.1:0\"\n");
    for _ in 0..3 {
        assert_eq!(gcud.position("5.1.1"), (0.0, 0.0));
    }
    let mut client = WireClient::connect(&gcud.clients());
    query_latencies(&mut client, 20);
    let results = gcud.metric("gcud_port_frames_in_total{port=\"1\"}");
    assert!(results >= 23, "the device answered every query: {results}");
    // Idle now: the last ACK has no command to ride with.
    std::thread::sleep(Duration::from_millis(300));
    let stats = sim.stop();
    assert_eq!(
        stats["acks_in"].as_u64(),
        Some(results),
        "one ACK per result the device sent: {stats}\n{}",
        gcud.log()
    );
    // On the device's side alone: every frame it took was a `P?`, answered
    // with a result, and each result came back ACKed.
    assert_eq!(stats["acks_in"], stats["frames_in"], "the device's own count: {stats}");
}

/// Point 9: `gcud --check` refuses two ports on one serial device, and a
/// port and a link on one, through a symbolic link too, naming both keys.
#[test]
fn check_refuses_one_serial_device_configured_twice() {
    let dir = tempfile::tempdir().expect("temp dir");
    let tty = dir.path().join("ttyUSB0");
    std::fs::write(&tty, "").expect("a stand-in device");
    let alias = dir.path().join("by-id");
    std::os::unix::fs::symlink(&tty, &alias).expect("symlink");
    let cases = [
        (
            format!(
                "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"{}\"\n[[port]]\nid = 2\npath = \"{}\"\n",
                tty.display(),
                alias.display()
            ),
            ":8:8: port[1].path",
            "port[0].path",
        ),
        (
            format!(
                "[gcu]\ngroup = 5\n[[port]]\nid = 1\npath = \"{}\"\n[[link]]\nname = \"up\"\nrole = \"upstream\"\nserial = \"{}\"\n",
                tty.display(),
                tty.display()
            ),
            ":9:10: link[0].serial",
            "port[0].path",
        ),
    ];
    for (config, place, first) in cases {
        let path = dir.path().join("gcud.toml");
        std::fs::write(&path, &config).expect("write config");
        let out = Command::new(gcud_bin())
            .arg("--check")
            .arg("--config")
            .arg(&path)
            .output()
            .expect("gcud --check");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{config}\n{stderr}");
        assert!(stderr.contains(place) && stderr.contains(first), "{config}\n{stderr}");
    }
}

/// Issue 49: one listener's clients cannot lock another listener out. 32
/// connections to the clients' listener, each sending a stray byte every
/// 0.4 s (never idle long enough to be evicted), fill `max_connections`;
/// an operator on the operators' listener still connects and stops the
/// gimbal the clients' slew moves (its stop on the bus side).
#[test]
fn one_listeners_busy_connections_never_lock_another_listener_out() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    let gcud = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n[limits]\nmax_connections = 32\n[[port]]\nid = 1\nsimulate = [1]\n\
         {CLIENTS}[[link]]\nname = \"operators\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
         priority = 80\n{METRICS_LOOPBACK}"
    ));
    let operators = gcud.address("listening link=operators");
    // A slew from the clients' listener, for the operator to stop.
    let slew = gcud.ctl(&["--to", "5.1.1", "slew", "right"]);
    assert_eq!(slew.code, 0, "{slew:?}");
    let flood: Vec<TcpStream> = (0..32)
        .map(|_| TcpStream::connect(gcud.clients()).expect("connect"))
        .collect();
    eventually("the clients' 32 connections to fill the table", || {
        gcud.metric("gcud_connections_open") >= 32
    });
    let done = Arc::new(AtomicBool::new(false));
    let busy = {
        let done = Arc::clone(&done);
        let mut streams = flood;
        std::thread::spawn(move || {
            // Bounded: the test ends long before this.
            for _ in 0..600 {
                if done.load(Ordering::Relaxed) {
                    break;
                }
                for s in &mut streams {
                    let _ = s.write_all(b"x");
                }
                std::thread::sleep(Duration::from_millis(400));
            }
        })
    };
    std::thread::sleep(Duration::from_millis(1500));
    let stop = support::gimbalctl(&["--tcp", &operators, "--to", "5.1.1", "stop"]);
    done.store(true, Ordering::Relaxed);
    busy.join().expect("the busy clients");
    assert_eq!(stop.code, 0, "the operator's stop: {stop:?}\ngcud log:\n{}", gcud.log());
    let bus: Vec<String> = gcud.received("5.1.1").into_iter().map(|(_, p)| p).collect();
    let slewed = bus.iter().position(|p| p == "PR").expect("the slew on the bus");
    assert!(
        bus[slewed..].iter().any(|p| p == "PS" || p == "PT"),
        "the operator's stop on the bus after the slew: {bus:?}"
    );
    assert!(gcud.metric("gcud_connections_closed_total{why=\"evicted\"}") >= 1);
}
