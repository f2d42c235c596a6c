//! The Wireshark dissector (`tools/wireshark/sagebrush.lua` with its
//! generated `sagebrush_tables.lua`) pairs results from the answer column
//! of the protocol crate's command table: a rev 1.9 set/read command (`*me`,
//! `*mp`, `*mu`, `*sa`, `*sgr`, `*sgp`, `*sl`) gets its result when it reads,
//! and a set that got none does not take the next command's result. The
//! capture is written with the host crate's capture writer (the file gcud
//! writes) and decoded by `tshark` (it must be installed).

mod support;

use std::time::{Duration, SystemTime};

use sagebrush_host::capture::{Capture, CaptureConfig, Direction, Role};
use sagebrush_protocol::dissector::ARGUMENT_SAMPLES;
use sagebrush_protocol::{ACK, Address, Axis, Command, Extended, Frame, ResultKind};
use support::capture::tshark_fields;

/// A bus master's conversation with device 5.1.1: each command, and the
/// result the device answers it with (`None`: ACK only).
fn conversation() -> Vec<(String, Option<String>)> {
    let mut steps = Vec::new();
    for ext in Extended::ALL {
        if ext.result_kind() != ResultKind::Optional {
            continue;
        }
        // A set (arguments) gets only the ACK, the read right after it its result.
        steps.push((format!("{}1", ext.name()), None));
        steps.push((ext.name().to_owned(), Some(format!("R{}", ext.name()))));
    }
    // A set last, then a query: the position goes to the P?, not the set.
    steps.push(("*sl9".to_owned(), None));
    steps.push(("P?".to_owned(), Some("00640000".to_owned())));
    steps
}

fn frame(dest: Address, source: u8, payload: &str) -> Vec<u8> {
    let mut buf = [0u8; 300];
    let frame = Frame::new(dest, source, payload.as_bytes()).expect("frame");
    frame.encode(&mut buf).expect("encode").to_vec()
}

#[test]
fn set_read_commands_pair_their_results_and_sets_take_none() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("setread.pcapng");
    let capture = Capture::open(&path, CaptureConfig::default()).expect("open capture");
    let port = capture.interface("port 1 test", Role::Master);
    let device = Address::new(5, 1, 1);
    let reply_to = Address::new(0, 1, 1);
    let mut at = SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
    let mut tick = || {
        at += Duration::from_millis(20);
        at
    };
    let steps = conversation();
    for (command, result) in &steps {
        capture.record(port, Direction::Outbound, tick(), &frame(device, 0, command));
        capture.record(port, Direction::Inbound, tick(), &[ACK]);
        if let Some(result) = result {
            capture.record(port, Direction::Inbound, tick(), &frame(reply_to, 5, result));
            capture.record(port, Direction::Outbound, tick(), &[ACK]);
        }
    }
    capture.stop(Duration::from_secs(10));

    let (rows, code, stderr) = tshark_fields(
        &path,
        &[
            "frame.number",
            "sagebrush.type",
            "sagebrush.cmd",
            "sagebrush.payload",
            "sagebrush.response_to",
        ],
    );
    assert_eq!(code, 0, "tshark: {stderr}");
    let table: String = rows.iter().map(|r| r.join(" | ") + "\n").collect();
    let results: Vec<&Vec<String>> = rows.iter().filter(|r| r[1] == "result").collect();
    let expected: Vec<&(String, Option<String>)> = steps.iter().filter(|(_, r)| r.is_some()).collect();
    assert_eq!(results.len(), expected.len(), "{table}");
    for (row, (command, result)) in results.iter().zip(expected) {
        assert_eq!(Some(&row[3]), result.as_ref(), "{table}");
        let to: usize = row[4]
            .parse()
            .unwrap_or_else(|_| panic!("result {row:?} unpaired:\n{table}"));
        let paired = &rows[to - 1];
        assert_eq!(&paired[3], command, "result {row:?} paired with frame {to}:\n{table}");
        // The command row names it by the table's mnemonic.
        assert_eq!(paired[2], Command::parse(command.as_bytes()).mnemonic(), "{table}");
    }
}

/// The dissector tells commands apart by hand (first character and
/// length): every row's sample, as the protocol crate encodes it, must get
/// the mnemonic the protocol crate's parser gives it, and its arguments
/// (the per-axis rows' axis and value among them) must be decoded.
#[test]
fn every_row_is_recognised_as_the_protocol_crate_parses_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("rows.pcapng");
    let capture = Capture::open(&path, CaptureConfig::default()).expect("open capture");
    let port = capture.interface("port 1 test", Role::Master);
    let mut at = SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
    let mut payloads: Vec<Vec<u8>> = Command::FIXED.iter().map(|(wire, _)| wire.to_vec()).collect();
    payloads.extend(ARGUMENT_SAMPLES.iter().map(|s| s.to_vec()));
    payloads.extend(Extended::ALL.iter().map(|e| e.name().as_bytes().to_vec()));
    for payload in &payloads {
        at += Duration::from_millis(20);
        let text = String::from_utf8(payload.clone()).expect("ASCII sample");
        capture.record(port, Direction::Outbound, at, &frame(Address::new(5, 1, 1), 0, &text));
    }
    capture.stop(Duration::from_secs(10));

    let (rows, code, stderr) = tshark_fields(
        &path,
        &[
            "sagebrush.cmd",
            "sagebrush.axis",
            "sagebrush.rate",
            "sagebrush.accel",
            "sagebrush.cmd.description",
        ],
    );
    assert_eq!(code, 0, "tshark: {stderr}");
    assert_eq!(rows.len(), payloads.len(), "one row per frame: {rows:?}");
    let unknown = Command::Unknown(&[]).description().replace(['`', '[', ']'], "");
    for (row, payload) in rows.iter().zip(&payloads) {
        let command = Command::parse(payload);
        assert_eq!(row[0], command.mnemonic(), "{row:?}");
        // Its row of the generated table, not the unknown one's (a
        // mnemonic missing from the table falls back to that).
        assert!(!row[4].starts_with(&unknown), "{row:?} described as unknown");
        // The per-axis rows' arguments: the axis, then the value in
        // degrees per second (squared), hundredths on the wire (Table 12).
        let (axis, rate, accel) = match command {
            Command::QueryRate(a) | Command::QueryAcceleration(a) => (Some(a), None, None),
            Command::SetRate(a, v) => (Some(a), Some(v.0), None),
            Command::SetAcceleration(a, v) => (Some(a), None, Some(v.0)),
            Command::SetSpeed(a, _) | Command::SetRateGain(a, _) => (Some(a), None, None),
            _ => (None, None, None),
        };
        let name = |a: Axis| if a == Axis::Pan { "pan" } else { "tilt" };
        let degrees = |v: Option<u16>| v.map_or(String::new(), |v| (f64::from(v) / 100.0).to_string());
        assert_eq!(row[1], axis.map_or("", name), "axis of {row:?}");
        assert_eq!(row[2], degrees(rate), "rate of {row:?}");
        assert_eq!(row[3], degrees(accel), "acceleration of {row:?}");
    }
}
