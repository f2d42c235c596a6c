//! What faces the LAN: malformed datagrams and TCP streams are answered or
//! dropped and the door lives on; a flood of drives from many source ports
//! keeps the door's memory and the bus bounded, and a stop still stops.

use std::io::{Read, Write};

use super::raw::{Raw, datagram, hex};
use super::*;
use support::door::{wait_for_stop, wait_moving};

/// VmRSS of process `pid`, KiB.
pub fn rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .expect("VmRSS")
}

/// The door answers a position inquiry with the position (it lives, and
/// reads the gimbal). Asked again while the answer is "not known yet"
/// (`90 60 41 FF`: gcud's first poll not answered) or lost (a socket
/// buffer full after a flood).
fn answers_position(c: &mut Raw) {
    let started = std::time::Instant::now();
    loop {
        assert!(started.elapsed() < support::HANG_GUARD, "no position answered");
        let seq = c.send(&hex("81 09 06 12 FF"));
        if let Some(payload) = c.reply_to(seq, std::time::Duration::from_secs(1)) {
            if payload != hex("90 60 41 FF") {
                assert_eq!((payload.len(), payload[1]), (11, 0x50), "{payload:?}");
                return;
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Each malformed datagram gets its answer (a bad header length or payload
/// type: "abnormality in the message"; a message no row matches, however
/// mangled: syntax error) or is dropped (too short to hold a sequence
/// number, another camera's address), and the door goes on answering.
#[test]
fn malformed_datagrams_are_answered_or_dropped_and_the_door_goes_on() {
    let stack = Stack::start();
    let mut c = Raw::new("127.0.0.3", stack.port);
    c.reset();
    // A header whose length is not the payload's.
    c.send_raw(&[
        0x01, 0x00, 0x00, 0x09, 0x00, 0x00, 0x00, 0x07, 0x81, 0x01, 0x06, 0x04, 0xFF,
    ]);
    assert_eq!(c.recv(), (0x0201, 7, vec![0x0F, 0x02]));
    // A payload type the camera does not take (a reply).
    c.send_raw(&datagram(0x0111, 8, &hex("90 41 FF")));
    assert_eq!(c.recv(), (0x0201, 8, vec![0x0F, 0x02]));
    c.sequence = 8;
    for bad in [
        "81 01 06 01 19 01 01 03 FF",
        "81 01 06",
        "00",
        "81 09 7E 7E 01 FF",
        "FF FF FF",
    ] {
        let seq = c.send(&hex(bad));
        assert_eq!(c.recv(), (0x0111, seq, hex("90 60 02 FF")), "{bad}");
    }
    // Dropped: three bytes, another camera.
    c.send_raw(&[0x01, 0x00, 0x00]);
    c.send(&hex("82 01 06 04 FF"));
    answers_position(&mut c);
    // 2,000 random datagrams from another address (whose replies nobody
    // reads), then the door still answers.
    let junk = Raw::new("127.0.0.5", stack.port);
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for i in 0..2000 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let len = (seed % 40) as usize;
        let bytes: Vec<u8> = (0..len).map(|k| (seed >> (k % 8 * 8)) as u8 ^ i as u8).collect();
        junk.send_raw(&bytes);
    }
    c.reset();
    answers_position(&mut c);
    let counters = stack.door.log();
    assert!(!counters.contains("panicked"), "{counters}");
    let sent = stack.door_frames();
    assert!(
        !sent.iter().any(|p| ["PL", "PR", "TU", "TD"].contains(&p.as_str())),
        "{sent:?}"
    );
}

/// Raw VISCA over TCP: an overlong message (no terminator within 16
/// bytes) is answered syntax error and skipped up to its terminator; the
/// messages after it are read.
#[test]
fn an_overlong_tcp_message_is_skipped_and_the_stream_goes_on() {
    let stack = Stack::start();
    let mut s = std::net::TcpStream::connect(("127.0.0.1", stack.tcp)).expect("connect");
    s.set_read_timeout(Some(support::HANG_GUARD)).expect("timeout");
    let mut bytes = vec![0x81; 40];
    bytes.push(0xFF);
    bytes.extend(hex("81 09 04 00 FF"));
    s.write_all(&bytes).expect("write");
    let mut got = Vec::new();
    while got.len() < 8 {
        let mut buf = [0u8; 64];
        let n = s.read(&mut buf).expect("read");
        assert!(n > 0, "closed after {got:?}");
        got.extend_from_slice(&buf[..n]);
    }
    assert_eq!(got, hex("90 60 02 FF 90 50 02 FF"));
}

/// A flood: 200,000 datagrams of drives, each from one of 500 source
/// ports with its own sequence numbers, and inquiries, as fast as the
/// test can send them. The door's memory stays within a few MiB, the bus
/// carries a small bounded share of it (newest drive wins, at the bus's
/// pace), and a stop afterwards still stops the gimbal. The figures are
/// printed for the closing note.
#[test]
fn a_datagram_flood_keeps_memory_and_the_bus_bounded() {
    let stack = Stack::start();
    let pid = stack.door.pid();
    let mut probe = Raw::new("127.0.0.3", stack.port);
    probe.reset();
    answers_position(&mut probe);
    let before = rss_kib(pid);
    let frames_before = stack.gcud.received(MAST).len();
    let from = stack.position();
    let senders: Vec<std::net::UdpSocket> = (0..500)
        .map(|_| {
            let s = std::net::UdpSocket::bind(("127.0.0.4", 0)).expect("bind");
            s.connect((HOST, stack.port)).expect("connect");
            s.set_nonblocking(true).expect("nonblocking");
            s
        })
        .collect();
    let drives = [
        hex("81 01 06 01 04 04 01 03 FF"),
        hex("81 01 06 01 05 05 01 01 FF"),
        hex("81 09 06 12 FF"),
    ];
    let total = 200_000u32;
    let started = std::time::Instant::now();
    for i in 0..total {
        let s = &senders[i as usize % senders.len()];
        let d = datagram(0x0100, i / senders.len() as u32 + 1, &drives[i as usize % drives.len()]);
        let _ = s.send(&d);
    }
    let took = started.elapsed();
    wait_moving(&stack.gcud, MAST, from);
    let after = rss_kib(pid);
    let bus = stack.gcud.received(MAST).len() - frames_before;
    eprintln!(
        "flood: {total} datagrams in {took:?}; door RSS {before} KiB before, {after} KiB after; {bus} frames on the bus"
    );
    assert!(
        after < before + 16 * 1024,
        "the door's memory grew from {before} to {after} KiB"
    );
    assert!(
        bus < total as usize / 100,
        "{bus} frames reached the bus for {total} datagrams"
    );
    probe.reset();
    answers_position(&mut probe);
    assert_eq!(
        probe.command(&hex("81 01 06 01 01 01 03 03 FF")),
        vec![hex("90 41 FF"), hex("90 51 FF")]
    );
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    stack.gcud.settled_position(MAST);
}
