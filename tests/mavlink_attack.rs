//! `gimbal-mavlink` under attack (issue 31): the real gcud with simulated
//! buses and the real gimbal-mavlink in front of it, the ground station
//! made of pymavlink (`tests/mavlink/gcs.py`, as in `tests/mavlink/`),
//! the attacks made of raw sockets. Everything is on 127.0.0.1; every loop
//! is bounded; figures (memory, bytes per second) are printed, not
//! asserted, except the 16 MB bound the issue sets.
//!
//! Without Python and pymavlink the tests that need the ground station are
//! skipped with a notice, except under `CI=true`, where they fail.

mod support;

use std::io::{Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::{COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage};
use serde_json::{Value, json};
use support::door::{DOOR_GROUP, Door};
use support::gcud::Gcud;

const MAST: &str = "5.1.1";
/// MAV_RESULT values (common.xml).
const ACCEPTED: i64 = 0;
const DENIED: i64 = 2;
const UNSUPPORTED: i64 = 3;
/// Two ground stations (two components of one system).
const GCS: (u8, u8) = (255, 190);
const OTHER: (u8, u8) = (255, 191);
/// gimbal-mavlink's control lapse (`control_lapse_ms`' default, the README says it).
const LAPSE: Duration = Duration::from_secs(5);
const MB: u64 = 1 << 20;

fn client_available() -> bool {
    support::door::mavlink_client_available()
}

/// gcud with its simulated buses, gimbal-mavlink in front of it with a UDP
/// and a TCP endpoint and the mast gimbal (component 154).
struct Stack {
    /// Declared first: dropped (stopped) before gcud.
    mavlink: Door,
    _gcud: Gcud,
    udp_port: u16,
    tcp_port: u16,
}

impl Stack {
    fn start() -> Self {
        let gcud = support::door::start_gcud();
        let mut mavlink = Door::new("gimbal-mavlink", env!("CARGO_BIN_EXE_gimbal-mavlink"));
        mavlink.start(&format!(
            r#"source_group = {DOOR_GROUP}
gcud = "{}"
system_id = 1
[[endpoint]]
udp_listen = "127.0.0.1:0"
[[endpoint]]
tcp_listen = "127.0.0.1:0"
[[gimbal]]
name = "mast-1"
address = "{MAST}"
component_id = 154
"#,
            gcud.clients()
        ));
        Self {
            udp_port: mavlink.port("MAVLink UDP endpoint bound"),
            tcp_port: mavlink.port("MAVLink TCP endpoint listening"),
            mavlink,
            _gcud: gcud,
        }
    }

    fn log(&self) -> String {
        self.mavlink.log()
    }

    /// One step of the pymavlink ground station as `who` over `connection`
    /// (a UDP port, or `tcp:127.0.0.1:PORT`).
    fn gcs_over(&self, connection: &str, step: &str, who: (u8, u8), args: Value) -> Value {
        let (system, component, args) = (who.0.to_string(), who.1.to_string(), args.to_string());
        support::door::python_step(
            "tests/mavlink/gcs.py",
            step,
            &[connection, &system, &component, &args],
            || self.log(),
        )
    }

    fn gcs(&self, step: &str, who: (u8, u8), args: Value) -> Value {
        self.gcs_over(&self.udp_port.to_string(), step, who, args)
    }

    /// gimbal-mavlink's process id: the process whose command line names
    /// this stack's configuration file.
    fn pid(&self) -> u32 {
        let config = self.mavlink.dir.path().join("gimbal-mavlink.toml");
        let config = config.to_string_lossy().into_owned();
        std::fs::read_dir("/proc")
            .expect("/proc")
            .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
            .find(|pid| {
                std::fs::read(format!("/proc/{pid}/cmdline"))
                    .is_ok_and(|c| String::from_utf8_lossy(&c).contains(&config))
            })
            .unwrap_or_else(|| panic!("no gimbal-mavlink process runs on {config}"))
    }

    /// Stops gimbal-mavlink and returns the counters it logs as it stops.
    fn stop_counters(&mut self) -> String {
        self.mavlink.signal(nix::sys::signal::Signal::SIGTERM);
        let log = self.log();
        log.lines()
            .find(|l| l.contains("counters="))
            .unwrap_or_else(|| panic!("no counters in\n{log}"))
            .to_owned()
    }
}

/// The counter `name` in a `counters=` line.
fn counter(line: &str, name: &str) -> u64 {
    let prefix = format!("{name}=");
    line.split([' ', '"'])
        .find_map(|t| t.strip_prefix(&prefix))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no counter {name} in {line}"))
}

/// VmRSS of process `pid`, bytes.
fn rss(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    let kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .expect("VmRSS");
    kb * 1024
}

/// A MAVLink 2 frame of `message` from `who`.
fn frame(who: (u8, u8), message: &MavMessage) -> Vec<u8> {
    let header = MavHeader {
        system_id: who.0,
        component_id: who.1,
        sequence: 0,
    };
    let mut bytes = Vec::new();
    mavlink::write_v2_msg(&mut bytes, header, message).expect("encode");
    bytes
}

fn heartbeat(who: (u8, u8)) -> Vec<u8> {
    frame(who, &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()))
}

/// A COMMAND_LONG to the mast gimbal with `command` and params 1..4.
fn command_long(who: (u8, u8), command: MavCmd, params: [f32; 4]) -> Vec<u8> {
    frame(
        who,
        &MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 154,
            command,
            param1: params[0],
            param2: params[1],
            param3: params[2],
            param4: params[3],
            ..COMMAND_LONG_DATA::DEFAULT
        }),
    )
}

/// The same with a command id no dialect has (the CRC written again).
fn unknown_command(who: (u8, u8), id: u16) -> Vec<u8> {
    let mut f = command_long(who, MavCmd::MAV_CMD_DO_SET_SERVO, [1.0, 0.0, 0.0, 0.0]);
    f[10 + 28..10 + 30].copy_from_slice(&id.to_le_bytes());
    let end = 10 + usize::from(f[1]);
    let crc = mavlink::calculate_crc(&f[1..end], 152);
    f[end..end + 2].copy_from_slice(&crc.to_le_bytes());
    f
}

/// Pseudo-random bytes (xorshift64*), the same for a seed.
fn random_bytes(seed: &mut u64, buf: &mut [u8]) {
    for chunk in buf.chunks_mut(8) {
        *seed ^= *seed >> 12;
        *seed ^= *seed << 25;
        *seed ^= *seed >> 27;
        let v = seed.wrapping_mul(0x2545_F491_4F6C_DD1D).to_le_bytes();
        chunk.copy_from_slice(&v[..chunk.len()]);
    }
}

/// The intact frames in `bytes` from the mast gimbal, by message id.
fn message_ids(bytes: &[u8]) -> Vec<u32> {
    let mut reader = mavlink::MavlinkReader::new(bytes);
    let mut out = Vec::new();
    for _ in 0..=bytes.len() / 8 {
        match reader.read_any_message::<MavMessage>() {
            Ok((h, m)) if h.component_id == 154 => out.push(mavlink::Message::message_id(&m)),
            Ok(_) | Err(mavlink::error::MessageReadError::Parse(_)) => continue,
            Err(_) => break,
        }
    }
    out
}

// ---- the tests --------------------------------------------------------------

#[test]
fn random_bytes_on_one_tcp_connection_keep_the_door_under_16_mb_and_are_freed_on_close() {
    let mut stack = Stack::start();
    let pid = stack.pid();
    let before = rss(pid);
    let peak = Arc::new(AtomicU64::new(before));
    let done = Arc::new(AtomicBool::new(false));
    let sampler = {
        let (peak, done) = (Arc::clone(&peak), Arc::clone(&done));
        std::thread::spawn(move || {
            while !done.load(Ordering::Relaxed) {
                peak.fetch_max(rss(pid), Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(10));
            }
        })
    };
    const TOTAL: u64 = 200 * MB;
    let mut conn = TcpStream::connect(("127.0.0.1", stack.tcp_port)).expect("connect");
    conn.set_read_timeout(Some(support::HANG_GUARD)).unwrap();
    let started = Instant::now();
    let (mut seed, mut chunk) = (0x9E37_79B9_7F4A_7C15u64, vec![0u8; MB as usize]);
    for _ in 0..TOTAL / MB {
        random_bytes(&mut seed, &mut chunk);
        conn.write_all(&chunk).expect("the door reads on");
    }
    let during = peak.load(Ordering::Relaxed);
    // The door closes its side once it has read everything to the end.
    conn.shutdown(std::net::Shutdown::Write).unwrap();
    let mut rest = Vec::new();
    let _ = conn.read_to_end(&mut rest);
    let elapsed = started.elapsed();
    drop(conn);
    done.store(true, Ordering::Relaxed);
    sampler.join().unwrap();
    let peak = peak.load(Ordering::Relaxed).max(during);
    // Freed: back near where it started (bounded wait).
    let mut after = rss(pid);
    for _ in 0..100 {
        if after < before + 4 * MB {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
        after = rss(pid);
    }
    let counters = stack.stop_counters();
    let damaged = counter(&counters, "damaged_bytes");
    eprintln!(
        "FIGURES: RSS before {:.1} MB, peak during {:.1} MB, after close {:.1} MB; \
         {} MB decoded in {:.2} s = {:.0} MB/s; damaged_bytes={damaged}",
        before as f64 / MB as f64,
        peak as f64 / MB as f64,
        after as f64 / MB as f64,
        TOTAL / MB,
        elapsed.as_secs_f64(),
        TOTAL as f64 / MB as f64 / elapsed.as_secs_f64()
    );
    assert!(
        peak < before + 16 * MB,
        "RSS grew by {} MB (from {before} to {peak} bytes)",
        (peak - before) / MB
    );
    assert!(after < before + 4 * MB, "RSS after close {after}, before {before}");
    // Every byte was read (all but the few chance frames are counted).
    assert!(damaged > TOTAL - MB, "damaged_bytes {damaged} of {TOTAL}");
}

#[test]
fn idle_tcp_connections_make_room_for_a_ground_station() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let idle: Vec<TcpStream> = (0..10)
        .map(|_| TcpStream::connect(("127.0.0.1", stack.tcp_port)).expect("connect"))
        .collect();
    // Idle for more than a second: the longest idle may be closed for a newcomer.
    std::thread::sleep(Duration::from_millis(1500));
    let tcp = format!("tcp:127.0.0.1:{}", stack.tcp_port);
    let hb = stack.gcs_over(&tcp, "heartbeat", GCS, json!({}));
    assert_eq!(hb["heartbeat"]["type"], 26, "{hb}");
    let r = stack.gcs_over(&tcp, "unsupported", GCS, json!({}));
    assert_eq!(r["result"], UNSUPPORTED, "an answer over TCP: {r}");
    assert!(stack.log().contains("closed for a newcomer"), "{}", stack.log());
    drop(idle);
}

#[test]
fn a_flood_of_fresh_udp_source_ports_does_not_push_out_a_ground_station() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let ready = stack.mavlink.dir.path().join("gcs-ready");
    let duration_s = 6.0;
    let stop = Arc::new(AtomicBool::new(false));
    let flood = {
        let (stop, ready, port) = (Arc::clone(&stop), ready.clone(), stack.udp_port);
        std::thread::spawn(move || {
            let started = Instant::now();
            while !ready.exists() && started.elapsed() < support::HANG_GUARD {
                std::thread::sleep(Duration::from_millis(10));
            }
            std::thread::sleep(Duration::from_millis(300));
            let mut sent = 0u64;
            // Bounded: until the ground station's watch ends, at most the guard.
            while !stop.load(Ordering::Relaxed) && started.elapsed() < support::HANG_GUARD {
                let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
                let who = ((sent % 200) as u8 + 10, 1);
                let _ = s.send_to(&heartbeat(who), ("127.0.0.1", port));
                sent += 1;
            }
            sent
        })
    };
    let seen = stack.gcs(
        "watch",
        GCS,
        json!({ "duration_s": duration_s, "beat_s": 1.0, "ready_file": ready }),
    );
    stop.store(true, Ordering::Relaxed);
    let sent = flood.join().unwrap();
    let statuses = seen["statuses"].as_f64().expect("a count");
    eprintln!("FIGURES: {sent} datagrams from fresh source ports; {statuses} attitude statuses in {duration_s} s");
    assert!(sent > 1000, "the flood ran: {sent}");
    // 5 Hz configured: pushed out, it would see about one per heartbeat.
    assert!(
        statuses >= duration_s * 5.0 / 2.0,
        "the ground station kept its place: {statuses} statuses in {duration_s} s\n{}",
        stack.log()
    );
}

#[test]
fn a_request_is_answered_once_to_the_asker_only() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    // A bystander ground station, heard by the door, reading everything.
    let bystander = UdpSocket::bind("127.0.0.1:0").unwrap();
    bystander
        .send_to(&heartbeat(OTHER), ("127.0.0.1", stack.udp_port))
        .unwrap();
    bystander.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    let asked = std::thread::scope(|s| {
        let asker = s.spawn(|| stack.gcs("request_once", GCS, json!({ "listen_s": 2.0 })));
        let mut got = Vec::new();
        let mut buf = [0u8; 2048];
        let (started, mut beat) = (Instant::now(), Instant::now());
        while !asker.is_finished() && started.elapsed() < support::HANG_GUARD {
            if let Ok((n, _)) = bystander.recv_from(&mut buf) {
                got.extend(message_ids(&buf[..n]));
            }
            if beat.elapsed() >= Duration::from_millis(500) {
                let _ = bystander.send_to(&heartbeat(OTHER), ("127.0.0.1", stack.udp_port));
                beat = Instant::now();
            }
        }
        (asker.join().unwrap(), got)
    });
    let (asked, bystander_got) = asked;
    assert_eq!(asked["result"], ACCEPTED, "{asked}");
    assert_eq!(asked["acks"], 1, "one ACK to the asker: {asked}");
    assert_eq!(
        asked["infos"], 1,
        "one GIMBAL_MANAGER_INFORMATION to the asker: {asked}"
    );
    assert!(bystander_got.contains(&0), "the bystander still gets the heartbeats");
    assert!(
        !bystander_got.contains(&77) && !bystander_got.contains(&280),
        "the answer went to the bystander too: {bystander_got:?}"
    );
}

#[test]
fn control_given_to_two_components_never_heard_is_denied() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.gcs("configure", GCS, json!({ "params": [200, 7, 201, 8] }));
    assert_eq!(r["result"], DENIED, "{r}");
    // Nobody was locked out: each ground station may still take control.
    let r = stack.gcs("configure", OTHER, json!({}));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("configure", OTHER, json!({ "params": [-3, -3, -1, -1] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("configure", GCS, json!({}));
    assert_eq!(r["result"], ACCEPTED, "{r}");
}

#[test]
fn an_owner_silent_past_the_lapse_loses_control_to_another_ground_station() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    // GCS takes control, then stays silent (its step ended). Held: another
    // is denied. A busy machine may start the second step past the lapse,
    // which proves nothing: then again, once whoever holds control lapsed.
    let mut tries = 0;
    let taken = loop {
        let r = stack.gcs("configure", GCS, json!({}));
        assert_eq!(r["result"], ACCEPTED, "{r}");
        let taken = Instant::now();
        let r = stack.gcs("configure", OTHER, json!({}));
        if taken.elapsed() < LAPSE {
            assert_eq!(r["result"], DENIED, "{r}");
            break taken;
        }
        tries += 1;
        assert!(tries < 3, "three times the second step began past the lapse");
        std::thread::sleep(LAPSE + Duration::from_millis(500));
    };
    std::thread::sleep((LAPSE + Duration::from_millis(500)).saturating_sub(taken.elapsed()));
    let r = stack.gcs("configure", OTHER, json!({}));
    assert_eq!(
        r["result"],
        ACCEPTED,
        "the silent owner's control lapsed: {r}\n{}",
        stack.log()
    );
    let st = stack.gcs("manager_status", OTHER, json!({ "primary_sysid": 255 }));
    assert_eq!(st["status"]["primary_control_compid"], 191, "{st}");
    assert!(stack.log().contains("control lapsed"), "{}", stack.log());
}

#[test]
fn a_command_id_the_dialect_does_not_know_gets_unsupported() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    for id in [64_000, 31_999] {
        let r = stack.gcs("command_id", GCS, json!({ "id": id }));
        assert_eq!(r["result"], UNSUPPORTED, "command {id}: {r}");
    }
}

#[test]
fn a_flood_of_refused_messages_writes_a_bounded_number_of_log_lines() {
    let mut stack = Stack::start();
    let lines_before = stack.log().lines().count();
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    let to = ("127.0.0.1", stack.udp_port);
    const EACH: u64 = 5000;
    let configure = command_long(
        GCS,
        MavCmd::MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE,
        [200.0, 7.0, 201.0, 8.0],
    );
    let unknown = unknown_command(GCS, 64_000);
    for i in 0..EACH {
        s.send_to(&configure, to).unwrap();
        s.send_to(&unknown, to).unwrap();
        s.send_to(b"\xfd\x09 not MAVLink at all", to).unwrap();
        if i % 50 == 0 {
            // Paced, so that few are lost in the loopback's buffers.
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    // A peer connecting and leaving again and again.
    for _ in 0..300 {
        drop(TcpStream::connect(("127.0.0.1", stack.tcp_port)).expect("connect"));
    }
    let counters = stack.stop_counters();
    let log = stack.log();
    let lines = log.lines().count() - lines_before;
    eprintln!(
        "FIGURES: {} refused messages and damaged datagrams and 300 TCP connections, {lines} log lines; {counters}",
        3 * EACH
    );
    // The door saw a thousand or more of each (UDP on a busy loopback may
    // lose some): a hundred times the lines one kind may write in a window.
    for kind in ["refused", "unsupported", "damaged"] {
        assert!(counter(&counters, kind) >= 1000, "{kind}: {counters}");
    }
    // Ten per kind and place per window, a summary, the stop's own lines.
    assert!(lines < 100, "{lines} lines logged:\n{log}");
}
