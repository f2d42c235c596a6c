//! Capture end to end: the real `gcud` with `[capture]`, commands from the
//! real `gimbalctl` and a raw TCP client on 127.0.0.1, decoded by `tshark`
//! with `tools/wireshark/sagebrush.lua` (tshark must be installed: the test
//! fails saying so otherwise). Layout and pairing rules: docs/capture.md.

mod support;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::Duration;

use nix::sys::signal::Signal;
use support::capture::{Daemon, require_tshark, tshark_fields};
use support::eventually;

fn config(capture: &str) -> String {
    format!(
        "[gcu]\ngroup = 5\n\n[[port]]\nid = 1\nsimulate = [1, 2]\n\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\n{capture}"
    )
}

const FIELDS: [&str; 13] = [
    "frame.number",
    "frame.interface_name",
    "sagebrush.kind",
    "sagebrush.direction",
    "sagebrush.type",
    "sagebrush.cmd",
    "sagebrush.address",
    "sagebrush.source",
    "sagebrush.pan_deg",
    "sagebrush.tilt_deg",
    "sagebrush.table3_swap",
    "sagebrush.checksum.bad",
    "sagebrush.response_to",
];

/// One decoded packet, by field name.
struct Row(Vec<String>);

impl Row {
    fn get(&self, field: &str) -> &str {
        let i = FIELDS.iter().position(|f| *f == field).expect("known field");
        self.0.get(i).map_or("", String::as_str)
    }
}

fn decode(file: &Path) -> (Vec<Row>, i32, String) {
    let (rows, code, stderr) = tshark_fields(file, &FIELDS);
    (rows.into_iter().map(Row).collect(), code, stderr)
}

fn table(rows: &[Row]) -> String {
    rows.iter().map(|r| r.0.join("|") + "\n").collect()
}

/// Sends a `P?` frame to 5.1.1 whose checksum byte is wrong; returns what came back.
fn send_bad_checksum(addr: &str) -> Vec<u8> {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_millis(500))).expect("timeout");
    s.write_all(&[0xF8, 5, 1, 1, 0, 2, b'P', b'?', 0x00]).expect("write");
    let mut buf = [0u8; 64];
    let n = s.read(&mut buf).unwrap_or(0);
    buf[..n].to_vec()
}

#[test]
fn gcud_capture_decodes_in_wireshark_with_units_pairing_and_bad_checksums() {
    require_tshark();
    let gcud = Daemon::start(&config("[capture]\nfile = \"{dir}/gcud.pcapng\"\n"));
    gcud.wait_for_log("capture started");
    let out = gcud.ctl(&["--to", "5.1.1", "goto", "45", "-10.5"]);
    assert_eq!(out.code, 0, "{out:?}");
    let out = gcud.ctl(&["--json", "--to", "5.1.1", "position"]);
    assert_eq!(out.code, 0, "{out:?}");
    let reported = out.json()["result"]["pan_deg"].as_f64().expect("pan");
    assert_eq!(send_bad_checksum(&gcud.clients()), [0x15], "gcud NAKs a damaged frame");
    // No device 9: retransmitted on the port, given up, reported; XX: NIC.
    assert_ne!(gcud.ctl(&["--to", "5.1.9", "position"]).code, 0);
    assert_ne!(gcud.ctl(&["--to", "5.1.1", "raw", "XX"]).code, 0);
    assert_eq!(gcud.ctl(&["--to", "5.1.2", "home"]).code, 0);
    let (log, dir) = gcud.terminate();
    let file = dir.path().join("gcud.pcapng");
    assert!(log.contains("capture stopped (gcud stopping)"), "{log}");

    let (rows, code, stderr) = decode(&file);
    assert_eq!(code, 0, "tshark: {stderr}");
    let all = table(&rows);
    // The goto, on the client link (inbound) and on port 1 (outbound), in degrees.
    let gotos: Vec<&Row> = rows.iter().filter(|r| r.get("sagebrush.cmd") == "Paaaaeeee").collect();
    assert_eq!(gotos.len(), 2, "{all}");
    for r in &gotos {
        assert_eq!(r.get("sagebrush.type"), "command", "{all}");
        assert_eq!(r.get("sagebrush.address"), "5.1.1", "{all}");
        assert_eq!(r.get("sagebrush.source"), "0", "{all}");
        assert_eq!(r.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(45.0), "{all}");
        assert_eq!(r.get("sagebrush.tilt_deg").parse::<f64>().ok(), Some(-10.5), "{all}");
    }
    assert!(
        gotos[0]
            .get("frame.interface_name")
            .starts_with("link clients 127.0.0.1:"),
        "{all}"
    );
    assert_eq!(gotos[0].get("sagebrush.direction"), "1", "{all}");
    assert!(
        gotos[1].get("frame.interface_name").starts_with("port 1 simulated"),
        "{all}"
    );
    assert_eq!(gotos[1].get("sagebrush.direction"), "2", "{all}");
    // The position result on both hops: Table 3 swap (dest group 0 = the
    // command's source, source 5 = its dest group), paired with its P?, in degrees.
    let results: Vec<&Row> = rows.iter().filter(|r| r.get("sagebrush.type") == "result").collect();
    assert_eq!(results.len(), 2, "{all}");
    for r in &results {
        assert_eq!(r.get("sagebrush.cmd"), "P?", "{all}");
        assert_eq!(r.get("sagebrush.address"), "0.1.1", "{all}");
        assert_eq!(r.get("sagebrush.source"), "5", "{all}");
        assert_eq!(r.get("sagebrush.table3_swap"), "1", "{all}");
        let to: usize = r.get("sagebrush.response_to").parse().expect("paired");
        let cmd = &rows[to - 1];
        assert_eq!(cmd.get("sagebrush.cmd"), "P?", "{all}");
        assert_eq!(cmd.get("frame.interface_name"), r.get("frame.interface_name"), "{all}");
        let pan: f64 = r.get("sagebrush.pan_deg").parse().expect("pan degrees");
        assert!(
            (pan - reported).abs() < 0.006,
            "pan {pan} vs gimbalctl {reported}: {all}"
        );
        r.get("sagebrush.tilt_deg").parse::<f64>().expect("tilt degrees");
    }
    // The damaged frame: flagged, then NAKed.
    let bad = rows
        .iter()
        .position(|r| r.get("sagebrush.kind") == "6")
        .expect("bad checksum record");
    assert_eq!(rows[bad].get("sagebrush.checksum.bad"), "1", "{all}");
    assert_eq!(rows[bad].get("sagebrush.address"), "5.1.1", "{all}");
    assert!(
        rows[bad + 1..].iter().any(|r| r.get("sagebrush.kind") == "3"),
        "NAK recorded: {all}"
    );
    assert!(
        rows.iter()
            .all(|r| r.get("sagebrush.checksum.bad") != "1" || r.get("sagebrush.kind") == "6"),
        "{all}"
    );

    // The expert info names the bad checksum and the NAK.
    let out = std::process::Command::new("tshark")
        .arg("-X")
        .arg(format!("lua_script:{}", support::capture::dissector().display()))
        .arg("-r")
        .arg(&file)
        .arg("-V")
        .output()
        .expect("tshark -V");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("Bad checksum 0x00, computed 0x98"), "{text}");
    assert!(text.contains("NAK: the command arrived damaged"), "{text}");
    assert!(text.contains("Retransmission of frame"), "{text}");
    assert!(
        text.contains("got no ACK (given up after 3 retransmission(s))"),
        "{text}"
    );
    assert!(text.contains("Not delivered: device silent"), "{text}");
    assert!(text.contains("NIC: command not implemented by the device"), "{text}");
}

#[test]
fn an_unwritable_capture_logs_one_error_and_routing_goes_on() {
    // A path below a regular file cannot be created; /dev/full takes the
    // file but fails every write (the writer thread's path).
    for (file, error) in [
        ("{dir}/gcud.toml/capture.pcapng", "cannot start the capture"),
        ("/dev/full", "capture stopped: cannot write"),
    ] {
        let gcud = Daemon::start(&config(&format!("[capture]\nfile = \"{file}\"\n")));
        gcud.wait_for_log(error);
        for _ in 0..3 {
            let out = gcud.ctl(&["--to", "5.1.1", "position"]);
            assert_eq!(out.code, 0, "{file}: routing goes on: {out:?}\n{}", gcud.log());
        }
        let (log, _dir) = gcud.terminate();
        let errors: Vec<&str> = log.lines().filter(|l| l.contains("ERROR")).collect();
        assert_eq!(errors.len(), 1, "{file}: one error line: {log}");
        assert!(errors[0].contains(error), "{log}");
    }
}

#[test]
fn sigusr1_starts_and_stops_the_capture_at_run_time() {
    require_tshark();
    let gcud = Daemon::start(&config("[capture]\nfile = \"{dir}/rt.pcapng\"\nenabled = false\n"));
    assert_eq!(gcud.ctl(&["--to", "5.1.2", "rate"]).code, 0);
    assert!(!gcud.path("rt.pcapng").exists(), "capture off at start-up");
    gcud.signal(Signal::SIGUSR1);
    gcud.wait_for_log("capture started");
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0);
    gcud.signal(Signal::SIGUSR1);
    gcud.wait_for_log("capture stopped (SIGUSR1)");
    assert_eq!(gcud.ctl(&["--to", "5.1.2", "home"]).code, 0);
    let (log, dir) = gcud.terminate();
    let (rows, code, stderr) = decode(&dir.path().join("rt.pcapng"));
    assert_eq!(code, 0, "{stderr}");
    let cmds: Vec<&str> = rows
        .iter()
        .filter(|r| r.get("sagebrush.type") == "command")
        .map(|r| r.get("sagebrush.cmd"))
        .collect();
    assert_eq!(
        cmds,
        ["P?", "P?"],
        "only what ran while capturing: {}\n{log}",
        table(&rows)
    );
}

#[test]
fn a_capture_cut_short_by_a_killed_gcud_still_reads() {
    require_tshark();
    let gcud = Daemon::start(&config("[capture]\nfile = \"{dir}/k.pcapng\"\n"));
    let file = gcud.path("k.pcapng");
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "goto", "10", "20"]).code, 0);
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0);
    // Written off the routing path: wait until the result reached the file.
    eventually("the position result in the file", || {
        let (rows, _, _) = decode(&file);
        rows.iter().filter(|r| r.get("sagebrush.type") == "result").count() == 2
    });
    let dir = gcud.kill();
    let (rows, code, stderr) = decode(&dir.path().join("k.pcapng"));
    assert_eq!(code, 0, "whole blocks only: {stderr}");
    assert!(
        rows.iter().any(|r| r.get("sagebrush.cmd") == "Paaaaeeee"),
        "{}",
        table(&rows)
    );
    // Cut in the middle of the last block (a disk that lost its tail):
    // everything before it still decodes.
    let bytes = std::fs::read(dir.path().join("k.pcapng")).expect("read");
    let cut = dir.path().join("cut.pcapng");
    std::fs::write(&cut, &bytes[..bytes.len() - 10]).expect("write");
    let (cut_rows, _, _) = decode(&cut);
    assert_eq!(cut_rows.len(), rows.len() - 1, "{}", table(&cut_rows));
    assert!(cut_rows.iter().any(|r| r.get("sagebrush.cmd") == "Paaaaeeee"));
}

#[test]
fn a_capture_out_of_budget_stops_once_and_sigusr1_starts_a_fresh_one() {
    let gcud = Daemon::start(&config("[capture]\nfile = \"{dir}/b.pcapng\"\nbudget_bytes = 4096\n"));
    eventually("the budget to run out", || {
        assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0, "{}", gcud.log());
        gcud.log().contains("capture budget of 4096 bytes reached")
    });
    assert!(std::fs::metadata(gcud.path("b.pcapng")).expect("file").len() <= 4096);
    gcud.signal(Signal::SIGUSR1);
    gcud.wait_for_log("capture stopped (SIGUSR1)");
    eventually("a second capture", || {
        gcud.log().matches("capture started").count() == 2
    });
    assert!(gcud.path("b.1.pcapng").exists(), "the spent file rotated away");
    assert_eq!(gcud.ctl(&["--to", "5.1.1", "position"]).code, 0);
    let (log, _dir) = gcud.terminate();
    assert_eq!(log.matches("capture budget of 4096 bytes reached").count(), 1, "{log}");
}

/// gimbalsim and gimbalctl capture their own line (`--capture FILE`): the
/// same exchange, recorded at both ends, decodes with the dissector, each
/// end with its own directions (the master's commands outbound, the
/// device's inbound; ACKs and results the other way).
#[test]
fn gimbalsim_and_gimbalctl_capture_their_own_line() {
    require_tshark();
    let dir = tempfile::tempdir().expect("temp dir");
    let (sim_file, ctl_file) = (dir.path().join("sim.pcapng"), dir.path().join("ctl.pcapng"));
    let sim = support::Sim::pty(&["--device", "1", "--capture", sim_file.to_str().expect("path")]);
    let out = sim.ctl(&[
        "--capture",
        ctl_file.to_str().expect("path"),
        "--to",
        "1.1.1",
        "goto",
        "12.5",
        "-3",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    let out = sim.ctl(&["--to", "1.1.1", "position"]);
    assert_eq!(out.code, 0, "{out:?}");
    sim.stop();

    // The bus master's view: one goto out, its ACK in.
    let (rows, code, stderr) = decode(&ctl_file);
    assert_eq!(code, 0, "tshark: {stderr}");
    let all = table(&rows);
    assert!(
        rows.iter()
            .all(|r| r.get("frame.interface_name").starts_with("gimbalctl serial ")),
        "{all}"
    );
    let goto = rows
        .iter()
        .find(|r| r.get("sagebrush.cmd") == "Paaaaeeee")
        .expect("the goto");
    assert_eq!(goto.get("sagebrush.direction"), "2", "written by gimbalctl: {all}");
    assert_eq!(goto.get("sagebrush.address"), "1.1.1", "{all}");
    assert_eq!(goto.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(12.5), "{all}");
    assert_eq!(goto.get("sagebrush.tilt_deg").parse::<f64>().ok(), Some(-3.0), "{all}");
    let ack = rows.iter().find(|r| r.get("sagebrush.kind") == "2").expect("the ACK");
    assert_eq!(ack.get("sagebrush.direction"), "1", "read by gimbalctl: {all}");
    assert!(
        !rows.iter().any(|r| r.get("sagebrush.cmd") == "P?"),
        "the second run was not captured: {all}"
    );

    // The device's view: both runs (one line, one file), directions reversed.
    let (rows, code, stderr) = decode(&sim_file);
    assert_eq!(code, 0, "tshark: {stderr}");
    let all = table(&rows);
    assert!(
        rows.iter()
            .all(|r| r.get("frame.interface_name").starts_with("gimbalsim pty ")),
        "{all}"
    );
    let goto = rows
        .iter()
        .find(|r| r.get("sagebrush.cmd") == "Paaaaeeee")
        .expect("the goto");
    assert_eq!(goto.get("sagebrush.direction"), "1", "read by gimbalsim: {all}");
    assert_eq!(goto.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(12.5), "{all}");
    let result = rows
        .iter()
        .find(|r| r.get("sagebrush.type") == "result")
        .expect("the P? result");
    assert_eq!(result.get("sagebrush.cmd"), "P?", "paired with its command: {all}");
    assert_eq!(result.get("sagebrush.direction"), "2", "written by gimbalsim: {all}");
    assert_eq!(result.get("sagebrush.table3_swap"), "1", "{all}");
}

/// A capture file that cannot be written is refused before anything is
/// sent (gimbalctl, exit 2) or before the bus starts (gimbalsim), naming it.
#[test]
fn an_unwritable_capture_file_is_refused_up_front() {
    let sim = support::Sim::pty(&["--device", "1"]);
    let out = sim.ctl(&[
        "--capture",
        "/nonexistent/dir/x.pcapng",
        "--to",
        "1.1.1",
        "goto",
        "1",
        "1",
    ]);
    assert_eq!(out.code, 2, "{out:?}");
    assert!(
        out.stderr
            .contains("--capture /nonexistent/dir/x.pcapng: cannot write it"),
        "{out:?}"
    );
    assert_eq!(
        sim.ctl_json(&["--to", "1.1.1", "position"])["result"]["pan_deg"],
        0.0,
        "nothing was sent"
    );
    let out = std::process::Command::new(support::gimbalsim_bin())
        .args(["--capture", "/nonexistent/dir/y.pcapng"])
        .stdin(std::process::Stdio::null())
        .output()
        .expect("run gimbalsim");
    assert!(!out.status.success(), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--capture /nonexistent/dir/y.pcapng: cannot write it"),
        "{stderr}"
    );
}
