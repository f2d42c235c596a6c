//! The capture end to end: bytes recorded through the handle or a tap,
//! read back from the file written.

use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

use super::*;

/// (interface id, EPB flags, record) of each EPB.
type Packets = Vec<(u32, u32, Vec<u8>)>;

/// The IDB names and the EPBs of a file.
fn read(path: &Path) -> (Vec<String>, Packets) {
    let data = std::fs::read(path).unwrap();
    let (mut names, mut packets, mut at) = (Vec::new(), Vec::new(), 0);
    let u32_at = |i: usize| u32::from_le_bytes(data[i..i + 4].try_into().unwrap());
    while at + 12 <= data.len() {
        let (kind, len) = (u32_at(at), u32_at(at + 4) as usize);
        assert_eq!(u32_at(at + len - 4) as usize, len, "trailing length");
        if kind == 1 {
            assert_eq!(u16::from_le_bytes([data[at + 8], data[at + 9]]), LINKTYPE);
            let nlen = u16::from_le_bytes([data[at + 18], data[at + 19]]) as usize;
            names.push(String::from_utf8(data[at + 20..at + 20 + nlen].to_vec()).unwrap());
        }
        if kind == 6 {
            let cap = u32_at(at + 20) as usize;
            let rec = data[at + 28..at + 28 + cap].to_vec();
            let flags = u32_at(at + 28 + cap.div_ceil(4) * 4 + 4);
            packets.push((u32_at(at + 8), flags, rec));
        }
        at += len;
    }
    assert_eq!(at, data.len(), "whole blocks only");
    (names, packets)
}

#[test]
fn frames_acks_noise_and_bad_checksums_become_records_across_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.pcapng");
    let c = Capture::open(&path, CaptureConfig::default()).unwrap();
    let port = c.interface("port 1 /dev/x", Role::Master);
    let now = SystemTime::now();
    // P? to 5.1.1 from 0, split over two chunks, then noise, ACK, a bad frame, NIC.
    let frame = [0xF8, 5, 1, 1, 0, 2, b'P', b'?', 0x98];
    c.record(port, Direction::Outbound, now, &frame[..4]);
    c.record(port, Direction::Outbound, now, &frame[4..]);
    c.record(port, Direction::Inbound, now, &[b'x', b'y', 0x06]);
    c.record(port, Direction::Inbound, now, &[0xF8, 5, 1, 1, 0, 1, b'A', 0x00, b'?']);
    let stats = c.stop(Duration::from_secs(5));
    assert_eq!(stats.stopped, None);
    let (names, packets) = read(&path);
    assert_eq!(names, ["port 1 /dev/x"]);
    let kinds: Vec<(u32, u8, u8, u8)> = packets.iter().map(|(_, f, r)| (*f, r[1], r[2], r[3])).collect();
    assert_eq!(
        kinds,
        [(2, 1, 2, 1), (1, 5, 1, 1), (1, 2, 1, 1), (1, 6, 1, 1), (1, 4, 1, 1)],
        "{packets:?}"
    );
    assert_eq!(&packets[0].2[4..8], &[0, 0, 0, 0], "interface number");
    assert_eq!(&packets[0].2[8..], &frame);
    assert_eq!(&packets[1].2[8..], b"xy");
    assert_eq!(&packets[3].2[8..], &[0xF8, 5, 1, 1, 0, 1, b'A', 0x00]);
}

#[test]
fn an_incomplete_frame_becomes_noise_when_the_interface_closes() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.pcapng");
    let c = Capture::open(&path, CaptureConfig::default()).unwrap();
    let i = c.interface("link a", Role::Responder);
    c.record(i, Direction::Inbound, SystemTime::now(), &[0xF8, 5, 1]);
    c.close_interface(i);
    c.stop(Duration::from_secs(5));
    let (_, packets) = read(&path);
    assert_eq!(packets.len(), 1);
    assert_eq!(packets[0].2, [1, 5, 1, 2, 0, 0, 0, 0, 0xF8, 5, 1]);
}

#[test]
fn files_rotate_by_size_and_count_and_the_budget_stops_the_capture() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.pcapng");
    let config = CaptureConfig {
        rotate_bytes: Some(1000),
        rotate_count: 3,
        budget_bytes: Some(5000),
        ..CaptureConfig::default()
    };
    let c = Capture::open(&path, config).unwrap();
    let i = c.interface("port 1", Role::Master);
    for _ in 0..200 {
        c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
    }
    let stats = c.stop(Duration::from_secs(5));
    assert!(stats.stopped.as_deref().unwrap_or("").contains("budget"), "{stats:?}");
    assert!(stats.bytes_written <= 5000, "{stats:?}");
    for n in 0..3 {
        let p = rotated_path(&path, n);
        let len = std::fs::metadata(&p).unwrap().len();
        assert!(len <= 1000, "{} is {len} bytes", p.display());
        let (names, packets) = read(&p);
        assert_eq!(names, ["port 1"], "each file declares its interface");
        assert!(!packets.is_empty());
    }
    assert!(!rotated_path(&path, 3).exists());
}

#[test]
fn a_write_error_stops_the_capture_without_blocking_the_caller() {
    let c = Capture::open("/dev/full", CaptureConfig::default()).unwrap();
    let i = c.interface("port 1", Role::Master);
    let started = Instant::now();
    for _ in 0..10_000 {
        c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
    }
    assert!(started.elapsed() < Duration::from_secs(5));
    let stats = c.stop(Duration::from_secs(5));
    assert!(
        stats.stopped.as_deref().unwrap_or("").contains("cannot write"),
        "{stats:?}"
    );
    assert!(!c.is_active());
}

#[test]
fn a_fifo_is_opened_by_the_writer_once_it_has_a_reader() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("live.pcapng");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::from_bits_truncate(0o600)).unwrap();
    // Nobody reads: open returns at once, and so does stop.
    let c = Capture::open(&fifo, CaptureConfig::default()).unwrap();
    assert!(c.waits_for_reader());
    let i = c.interface("port 1", Role::Master);
    c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
    let stats = c.stop(Duration::from_secs(5));
    assert_eq!(
        (stats.records, stats.dropped, stats.stopped),
        (0, 1, None),
        "nothing written, what waited counted, no error"
    );

    let c = Capture::open(&fifo, CaptureConfig::default()).unwrap();
    let i = c.interface("port 1", Role::Master);
    c.record(i, Direction::Inbound, SystemTime::now(), &[0x06]);
    let copy = dir.path().join("copy.pcapng");
    let (from, to) = (fifo.clone(), copy.clone());
    let reader = std::thread::spawn(move || std::fs::write(to, std::fs::read(from).unwrap()).unwrap());
    let started = Instant::now();
    while c.waits_for_reader() && started.elapsed() < Duration::from_secs(30) {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(!c.waits_for_reader(), "the writer opened the FIFO");
    c.record(i, Direction::Outbound, SystemTime::now(), &[0x15]);
    let stats = c.stop(Duration::from_secs(5));
    reader.join().unwrap();
    let (names, packets) = read(&copy);
    assert_eq!(names, ["port 1"]);
    assert_eq!(packets.len(), 2, "{stats:?}");
}

#[test]
fn taps_follow_the_switch() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.pcapng");
    let switch = CaptureSwitch::new();
    let mut tap = switch.tap("port 2", Role::Master);
    tap.outbound(&[0x06]); // off: nothing
    assert!(
        switch
            .start(Capture::open(&path, CaptureConfig::default()).unwrap())
            .is_none()
    );
    tap.outbound(&[0x15]);
    let c = switch.stop().unwrap();
    tap.outbound(&[0x06]);
    c.stop(Duration::from_secs(5));
    let (names, packets) = read(&path);
    assert_eq!(names, ["port 2"]);
    assert_eq!(packets.len(), 1);
    assert_eq!(packets[0].2, [1, 3, 2, 1, 0, 0, 0, 0, 0x15]);
}
