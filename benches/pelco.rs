//! `cargo bench --bench pelco`: gimbal-pelco measured with real processes
//! on 127.0.0.1 (issue 50's figures): gimbalsim behind the relay that
//! watches the bus bytes <- gcud <- gimbal-pelco <- Pelco-D frames over one
//! TCP connection (a keyboard through a serial server):
//! 1. a drive (pan right or left, the speed changing every move): from the
//!    frame's write to the first byte of the direction command at the
//!    speed asked for reaching the bus, p50/p99 of `PELCO_BENCH_MOVES`
//!    moves (default 200), each followed by the stop frame, timed likewise
//!    to the pan stop's first byte; then the same on a bus paced at 9600
//!    and 115200 bit/s (`PELCO_BENCH_PACED_MOVES`, default 50), beside the
//!    line-time limit and the goal the other doors meet;
//! 2. memory under a flood: the door's resident and peak memory before and
//!    after 200,000 UDP datagrams of noise and drives from 64 sources.
//!
//! Figures are printed, never asserted: the machines are shared and noisy.

#[path = "support/door.rs"]
mod door;
#[allow(dead_code)] // TRANSACTION_BYTES is for the bus benchmarks
mod support;

use std::io::Write;
use std::net::{TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use door::{MOTION_BYTES, STOP_BYTES, addr_in, env_count, log_line, report};

/// A Pelco-D frame to camera 1.
fn pelco_d(body: [u8; 4]) -> Vec<u8> {
    let mut f = vec![0xFF, 1, body[0], body[1], body[2], body[3]];
    f.push(f[1..].iter().fold(0u8, |s, b| s.wrapping_add(*b)));
    f
}

/// gimbal-pelco in front of `stack`'s gcud; its TCP keyboard and its pid.
fn door(stack: &mut door::Stack) -> (TcpStream, u16, u32) {
    let clients = stack.clients.clone();
    let log = stack.door(
        env!("CARGO_BIN_EXE_gimbal-pelco"),
        "gimbal-pelco",
        &format!(
            "gcud = \"{clients}\"\nmotion_lease_ms = 5000\n[[input]]\ntcp_listen = \"127.0.0.1:0\"\nprotocol = \"pelco-d\"\n\
             [[input]]\nudp_listen = \"127.0.0.1:0\"\nprotocol = \"pelco-d\"\n\
             [[gimbal]]\nname = \"bench\"\naddress = \"5.1.1\"\npelco_address = 1\n"
        ),
    );
    let port = |what: &str| -> u16 {
        addr_in(&log_line(&log, what))
            .rsplit(':')
            .next()
            .and_then(|p| p.parse().ok())
            .expect("port")
    };
    let tcp = TcpStream::connect(("127.0.0.1", port("input[0] tcp_listen"))).expect("connect");
    tcp.set_nodelay(true).expect("nodelay");
    let udp = port("input[1] udp_listen");
    log_line(&log, "gimbal-pelco ready");
    (tcp, udp, pid_of(&log))
}

/// The pid of the process writing `log` (found through /proc).
fn pid_of(log: &std::path::Path) -> u32 {
    for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let fd = entry.path().join("fd/2");
        if std::fs::read_link(&fd).is_ok_and(|t| t == log) {
            return pid;
        }
    }
    panic!("no process writes {}", log.display());
}

/// `moves` drives, each followed by the stop: to the pan at the speed
/// asked for, and to the pan stop.
fn moves(stack: &door::Stack, kb: &mut TcpStream, moves: usize) -> (Vec<Duration>, Vec<Duration>) {
    let (mut to_motion, mut to_stop) = (Vec::with_capacity(moves), Vec::with_capacity(moves));
    let quiet = Duration::from_millis(300);
    for i in 0..moves {
        stack.drain();
        let (way, speed) = if i % 2 == 0 { (0x02, 0x20) } else { (0x04, 0x33) };
        let sent = Instant::now();
        kb.write_all(&pelco_d([0, way, speed, 0])).expect("write");
        let heard = stack.heard(quiet);
        let at = door::pan_at_speed(&heard).unwrap_or_else(|| panic!("no pan motion on the bus: {heard:?}"));
        to_motion.push(at.saturating_duration_since(sent));
        let sent = Instant::now();
        kb.write_all(&pelco_d([0; 4])).expect("write");
        let heard = stack.heard(quiet);
        let at = door::pan_stop(&heard).unwrap_or_else(|| panic!("no pan stop on the bus: {heard:?}"));
        to_stop.push(at.saturating_duration_since(sent));
    }
    (to_motion, to_stop)
}

/// Resident and peak memory of `pid`, kB.
fn memory_kb(pid: u32) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

fn flood(udp_port: u16, pid: u32) {
    let (rss0, hwm0) = memory_kb(pid);
    let sockets: Vec<UdpSocket> = (0..64).map(|_| UdpSocket::bind("127.0.0.1:0").expect("bind")).collect();
    let drive = pelco_d([0, 0x02, 0x10, 0]);
    let mut x: u64 = 1;
    let started = Instant::now();
    let n = 200_000;
    for i in 0..n {
        let mut d: Vec<u8> = (0..200)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x as u8
            })
            .collect();
        if i % 10 == 0 {
            d.extend_from_slice(&drive);
        }
        let _ = sockets[i % 64].send_to(&d, ("127.0.0.1", udp_port));
    }
    let took = started.elapsed();
    std::thread::sleep(Duration::from_millis(500));
    let (rss, hwm) = memory_kb(pid);
    println!(
        "2. memory under a UDP flood ({n} datagrams of 200-207 bytes from 64 sources in {:.1} s): resident {rss0} kB before, {rss} kB after; peak {hwm0} kB before, {hwm} kB after",
        took.as_secs_f64()
    );
}

fn main() {
    let mut stack = door::Stack::start(env!("CARGO_BIN_EXE_gimbalsim"), env!("CARGO_BIN_EXE_gcud"));
    let (mut kb, udp, pid) = door(&mut stack);
    let n = env_count("PELCO_BENCH_MOVES", 200);
    println!("1. to the first byte on the bus, gcud's port a TCP device server (gimbalsim):");
    let (to_motion, to_stop) = moves(&stack, &mut kb, n);
    report("drive frame -> first byte at speed", None, MOTION_BYTES, to_motion);
    report("stop frame -> first stop byte", None, STOP_BYTES, to_stop);
    for baud in [9600, 115_200] {
        let mut paced = door::Stack::paced(env!("CARGO_BIN_EXE_gcud"), baud);
        let (mut paced_kb, _, _) = door(&mut paced);
        println!("   on a bus paced at {baud} bit/s:");
        let (to_motion, to_stop) = moves(&paced, &mut paced_kb, env_count("PELCO_BENCH_PACED_MOVES", 50));
        report(
            "drive frame -> first byte at speed",
            Some(baud),
            MOTION_BYTES,
            to_motion,
        );
        report("stop frame -> first stop byte", Some(baud), STOP_BYTES, to_stop);
    }
    flood(udp, pid);
}
