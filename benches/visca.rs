//! `cargo bench --bench visca`: gimbal-visca measured with real processes
//! on 127.0.0.1 (issue 50's figures): `gimbalsim --tcp` <- a relay that
//! watches the bus bytes <- gcud (the relay is its `tcp` port) <-
//! gimbal-visca <- VISCA over IP datagrams (Sony's 8-byte header):
//! 1. Pan-tiltDrive (its pan speed changing every move): from the
//!    datagram's send to the first byte of the direction command that runs
//!    the pan at that speed (`door::pan_at_speed`), p50/p99 of
//!    `VISCA_BENCH_MOVES` moves (default 100), each followed by a
//!    Pan-tiltDrive stop timed to its pan stop's first byte; then the same
//!    on a bus paced at 9600 and at 115200 bit/s (`VISCA_BENCH_PACED_MOVES`,
//!    default 50), beside the line-time limit of the bytes needed and the
//!    goal the other doors meet (issue 35);
//! 2. A flood: `VISCA_BENCH_FLOOD` datagrams (default 200,000) of drives
//!    and inquiries from 500 source ports; the door's resident memory
//!    before and after, and how many frames reached the bus meanwhile.
//!
//! Figures are printed, never asserted: the machines are shared and noisy.

#[path = "support/door.rs"]
mod door;
#[allow(dead_code)] // TRANSACTION_BYTES is for the bus benchmarks
mod support;

use std::net::UdpSocket;
use std::time::{Duration, Instant};

use door::{MOTION_BYTES, STOP_BYTES, addr_in, env_count, log_line, report};

/// A VISCA over IP controller.
struct Controller {
    socket: UdpSocket,
    sequence: u32,
}

impl Controller {
    fn send(&mut self, payload: &[u8]) {
        self.sequence += 1;
        let mut d = vec![0x01, 0x00];
        d.extend((payload.len() as u16).to_be_bytes());
        d.extend(self.sequence.to_be_bytes());
        d.extend(payload);
        self.socket.send(&d).expect("send");
    }

    /// Waits for the Completion (or an error) of the last command.
    fn done(&self) {
        let mut buf = [0u8; 64];
        loop {
            let n = self.socket.recv(&mut buf).expect("a reply");
            let seq = u32::from_be_bytes([buf[4], buf[5], buf[6], buf[7]]);
            if n > 9 && seq == self.sequence && buf[9] & 0xF0 != 0x40 {
                assert_eq!(buf[9], 0x51, "Completion: {:?}", &buf[..n]);
                return;
            }
        }
    }

    fn drive(&mut self, pan_speed: u8, left: bool) {
        self.send(&[
            0x81,
            0x01,
            0x06,
            0x01,
            pan_speed,
            0x01,
            if left { 0x01 } else { 0x02 },
            0x03,
            0xFF,
        ]);
    }

    fn stop(&mut self) {
        self.send(&[0x81, 0x01, 0x06, 0x01, 0x01, 0x01, 0x03, 0x03, 0xFF]);
    }
}

/// gimbal-visca in front of `stack`'s gcud (lease off) and a controller
/// talking to it, once the door answers the position inquiry. Also the
/// door's log file.
fn door(stack: &mut door::Stack) -> (Controller, std::path::PathBuf) {
    let clients = stack.clients.clone();
    let log = stack.door(
        env!("CARGO_BIN_EXE_gimbal-visca"),
        "gimbal-visca",
        &format!(
            "gcud = \"{clients}\"\nmotion_lease_ms = 0\n[[gimbal]]\nname = \"bench\"\naddress = \"5.1.1\"\nvisca_udp = \"127.0.0.1:0\"\n"
        ),
    );
    let to = addr_in(&log_line(&log, "VISCA over IP (UDP) bound"));
    let socket = UdpSocket::bind("127.0.0.1:0").expect("bind");
    socket.connect(&to).expect("connect");
    socket.set_read_timeout(Some(Duration::from_secs(30))).expect("timeout");
    let mut c = Controller { socket, sequence: 0 };
    // Warm up: the position is known once gcud answered a poll.
    let mut buf = [0u8; 64];
    loop {
        c.send(&[0x81, 0x09, 0x06, 0x12, 0xFF]);
        let n = c.socket.recv(&mut buf).expect("an answer");
        if n == 19 && buf[9] == 0x50 {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    (c, log)
}

/// `moves` drives, each followed by a stop: from the drive's datagram to
/// the direction at that speed on the bus, and from the stop's to the pan stop.
fn moves(stack: &door::Stack, c: &mut Controller, moves: usize, quiet: Duration) -> (Vec<Duration>, Vec<Duration>) {
    let (mut to_motion, mut to_stop) = (Vec::with_capacity(moves), Vec::with_capacity(moves));
    for i in 0..moves {
        stack.drain();
        let sent = Instant::now();
        c.drive(if i % 2 == 0 { 0x06 } else { 0x12 }, i % 4 < 2);
        let heard = stack.heard(quiet);
        let at = door::pan_at_speed(&heard).unwrap_or_else(|| panic!("no pan motion on the bus: {heard:?}"));
        to_motion.push(at.saturating_duration_since(sent));
        c.done();
        let sent = Instant::now();
        c.stop();
        let heard = stack.heard(quiet);
        let at = door::pan_stop(&heard).unwrap_or_else(|| panic!("no pan stop on the bus: {heard:?}"));
        to_stop.push(at.saturating_duration_since(sent));
        c.done();
    }
    (to_motion, to_stop)
}

/// [`moves`] after one move not measured (the first speed on a paced bus
/// took up to 0.6 s, gcud learning the gimbal), with the door's log when
/// it fails.
fn measured(
    stack: &door::Stack,
    c: &mut Controller,
    log: &std::path::Path,
    n: usize,
) -> (Vec<Duration>, Vec<Duration>) {
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        moves(stack, c, 1, Duration::from_secs(2));
        moves(stack, c, n, Duration::from_millis(300))
    }));
    run.unwrap_or_else(|_| panic!("the door's log:\n{}", std::fs::read_to_string(log).unwrap_or_default()))
}

/// The resident memory of the process whose command line names `config`, KiB.
fn rss_kib(config: &std::path::Path) -> u64 {
    let config = config.to_string_lossy().into_owned();
    let pid = std::fs::read_dir("/proc")
        .expect("/proc")
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .find(|pid| {
            std::fs::read(format!("/proc/{pid}/cmdline")).is_ok_and(|c| String::from_utf8_lossy(&c).contains(&config))
        })
        .expect("gimbal-visca's process");
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .expect("VmRSS")
}

fn flood(stack: &door::Stack, c: &mut Controller, log: &std::path::Path) {
    let config = log.with_extension("toml");
    let to = c.socket.peer_addr().expect("peer");
    let before = rss_kib(&config);
    stack.drain();
    let senders: Vec<UdpSocket> = (0..500)
        .map(|_| {
            let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
            s.connect(to).expect("connect");
            s.set_nonblocking(true).expect("nonblocking");
            s
        })
        .collect();
    let messages: [&[u8]; 3] = [
        &[0x81, 0x01, 0x06, 0x01, 0x04, 0x04, 0x01, 0x03, 0xFF],
        &[0x81, 0x01, 0x06, 0x01, 0x08, 0x08, 0x02, 0x03, 0xFF],
        &[0x81, 0x09, 0x06, 0x12, 0xFF],
    ];
    let total = env_count("VISCA_BENCH_FLOOD", 200_000);
    let started = Instant::now();
    for i in 0..total {
        let m = messages[i % messages.len()];
        let mut d = vec![0x01, 0x00, 0x00, m.len() as u8];
        d.extend((i as u32 / 500 + 1).to_be_bytes());
        d.extend(m);
        let _ = senders[i % senders.len()].send(&d);
    }
    let took = started.elapsed();
    std::thread::sleep(Duration::from_secs(1));
    let after = rss_kib(&config);
    let bus = stack
        .heard(Duration::from_millis(300))
        .iter()
        .filter(|(m, _)| *m != "P?")
        .count();
    c.stop();
    c.done();
    println!(
        "2. flood: {total} datagrams from 500 source ports in {:.2} s; door RSS {before} KiB before, {after} KiB after; {bus} commands (polls aside) reached the bus",
        took.as_secs_f64()
    );
}

fn main() {
    let mut stack = door::Stack::start(env!("CARGO_BIN_EXE_gimbalsim"), env!("CARGO_BIN_EXE_gcud"));
    let (mut c, log) = door(&mut stack);
    println!("1. to the first byte on the bus, gcud's port a TCP device server (gimbalsim):");
    let (to_motion, to_stop) = measured(&stack, &mut c, &log, env_count("VISCA_BENCH_MOVES", 100));
    report("Pan-tiltDrive -> first byte at speed", None, MOTION_BYTES, to_motion);
    report("Pan-tiltDrive stop -> first pan stop byte", None, STOP_BYTES, to_stop);
    for baud in [9600, 115_200] {
        let mut paced = door::Stack::paced(env!("CARGO_BIN_EXE_gcud"), baud);
        let (mut pc, paced_log) = door(&mut paced);
        println!("   on a bus paced at {baud} bit/s:");
        let (to_motion, to_stop) = measured(&paced, &mut pc, &paced_log, env_count("VISCA_BENCH_PACED_MOVES", 50));
        report(
            "Pan-tiltDrive -> first byte at speed",
            Some(baud),
            MOTION_BYTES,
            to_motion,
        );
        report(
            "Pan-tiltDrive stop -> first pan stop byte",
            Some(baud),
            STOP_BYTES,
            to_stop,
        );
    }
    flood(&stack, &mut c, &log);
}
