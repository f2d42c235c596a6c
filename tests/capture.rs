//! Capture end to end: the real `gcud` with `[capture]`, commands from the
//! real `gimbalctl` and a raw TCP client on 127.0.0.1, decoded by `tshark`
//! with `tools/wireshark/sagebrush.lua` (tshark must be installed: the test
//! fails saying so otherwise). Layout and pairing rules: docs/capture.md.

mod support;

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;

use nix::sys::signal::Signal;
use support::capture::{Daemon, Program, require_tshark, tshark_fields, wait_until_read};
use support::eventually;

fn config(capture: &str) -> String {
    format!(
        "[gcu]\ngroup = 5\n\n[[port]]\nid = 1\nsimulate = [1, 2]\n\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\n{capture}"
    )
}

const FIELDS: [&str; 15] = [
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
    "sagebrush.ack_of",
    "frame.len",
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
    // The NAK ends the read as soon as it comes; the time-out is only a hang guard.
    s.set_read_timeout(Some(support::HANG_GUARD)).expect("timeout");
    s.write_all(&[0xF8, 5, 1, 1, 0, 2, b'P', b'?', 0x00]).expect("write");
    let mut buf = [0u8; 64];
    let n = s.read(&mut buf).unwrap_or(0);
    buf[..n].to_vec()
}

/// The result rows of devices: not gcud's own `~W=` (to 0.0.0), the
/// answer to the `~W` gimbalctl asks before a goto (ARCHITECTURE "End of
/// the NIC window").
fn device_results(rows: &[Row]) -> Vec<&Row> {
    rows.iter()
        .filter(|r| r.get("sagebrush.type") == "result" && r.get("sagebrush.address") != "0.0.0")
        .collect()
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
    let results = device_results(&rows);
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
        device_results(&rows).len() == 2
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

/// The rows of a capture file (tshark must read it) and their table for messages.
fn decoded(file: &Path) -> (Vec<Row>, String) {
    let (rows, code, stderr) = decode(file);
    assert_eq!(code, 0, "tshark {}: {stderr}", file.display());
    let all = table(&rows);
    (rows, all)
}

/// The row of frame number `n` (tshark numbers from 1).
fn frame<'a>(rows: &'a [Row], n: &str, all: &str) -> &'a Row {
    let n: usize = n.parse().unwrap_or_else(|_| panic!("a frame number, not {n:?}: {all}"));
    &rows[n - 1]
}

/// gimbalsim and gimbalctl capture their own line (`--capture FILE`), on a
/// pseudo-terminal and over TCP: the same exchanges, recorded at both ends,
/// decode with the dissector, each end with its own directions (the
/// master's commands and its ACKs of results outbound, the device's ACKs
/// and results inbound; the other way round at the device), every ACK
/// paired with what it answers.
#[test]
fn gimbalsim_and_gimbalctl_capture_their_own_line() {
    require_tshark();
    for tcp in [false, true] {
        let dir = tempfile::tempdir().expect("temp dir");
        let file = |name: &str| dir.path().join(name).to_str().expect("path").to_owned();
        let sim_args = ["--device", "1", "--capture", &file("sim.pcapng")];
        let sim = if tcp {
            support::Sim::tcp(&sim_args)
        } else {
            support::Sim::pty(&sim_args)
        };
        let goto = ["--capture", &file("goto.pcapng"), "--to", "1.1.1", "goto", "12.5", "-3"];
        let out = sim.ctl(&goto);
        assert_eq!(out.code, 0, "{out:?}");
        assert_eq!(sim.settled_position(), (12.5, -3.0));
        let reported = sim.result(&["--capture", &file("position.pcapng"), "--to", "1.1.1", "position"]);
        assert_eq!(
            (reported["pan_deg"].as_f64(), reported["tilt_deg"].as_f64()),
            (Some(12.5), Some(-3.0))
        );
        let endpoint = sim.endpoint.clone();
        sim.stop();
        let ctl_interface = match tcp {
            true => format!("gimbalctl tcp {endpoint}"),
            false => format!("gimbalctl serial {endpoint}"),
        };

        // gimbalctl's goto: the command out, the device's ACK in.
        let (rows, all) = decoded(&dir.path().join("goto.pcapng"));
        assert_eq!(rows.len(), 2, "{all}");
        assert!(
            rows.iter().all(|r| r.get("frame.interface_name") == ctl_interface),
            "{all}"
        );
        let (goto, ack) = (&rows[0], &rows[1]);
        assert_eq!(goto.get("sagebrush.type"), "command", "{all}");
        assert_eq!(goto.get("sagebrush.cmd"), "Paaaaeeee", "{all}");
        assert_eq!(goto.get("sagebrush.direction"), "2", "written by gimbalctl: {all}");
        assert_eq!(goto.get("sagebrush.address"), "1.1.1", "{all}");
        assert_eq!(goto.get("sagebrush.source"), "0", "{all}");
        assert_eq!(goto.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(12.5), "{all}");
        assert_eq!(goto.get("sagebrush.tilt_deg").parse::<f64>().ok(), Some(-3.0), "{all}");
        assert_eq!(ack.get("sagebrush.kind"), "2", "{all}");
        assert_eq!(ack.get("sagebrush.direction"), "1", "read by gimbalctl: {all}");
        assert_eq!(ack.get("sagebrush.ack_of"), goto.get("frame.number"), "{all}");

        // gimbalctl's position: P? out, ACK in, the result in (in degrees), its ACK out.
        let (rows, all) = decoded(&dir.path().join("position.pcapng"));
        let seen: Vec<(&str, &str, &str)> = rows
            .iter()
            .map(|r| {
                (
                    r.get("sagebrush.kind"),
                    r.get("sagebrush.direction"),
                    r.get("sagebrush.cmd"),
                )
            })
            .collect();
        assert_eq!(
            seen,
            [("1", "2", "P?"), ("2", "1", ""), ("1", "1", "P?"), ("2", "2", "")],
            "{all}"
        );
        assert!(
            rows.iter().all(|r| r.get("frame.interface_name") == ctl_interface),
            "{all}"
        );
        let (query, result) = (&rows[0], &rows[2]);
        assert_eq!(query.get("sagebrush.address"), "1.1.1", "{all}");
        assert_eq!(rows[1].get("sagebrush.ack_of"), query.get("frame.number"), "{all}");
        assert_eq!(result.get("sagebrush.type"), "result", "{all}");
        assert_eq!(result.get("sagebrush.response_to"), query.get("frame.number"), "{all}");
        assert_eq!(result.get("sagebrush.address"), "0.1.1", "Table 3 swap: {all}");
        assert_eq!(result.get("sagebrush.source"), "1", "{all}");
        assert_eq!(result.get("sagebrush.table3_swap"), "1", "{all}");
        assert_eq!(result.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(12.5), "{all}");
        assert_eq!(
            result.get("sagebrush.tilt_deg").parse::<f64>().ok(),
            Some(-3.0),
            "{all}"
        );
        assert_eq!(rows[3].get("sagebrush.ack_of"), result.get("frame.number"), "{all}");

        // gimbalsim's view: every run (one file, an interface per TCP
        // connection), directions reversed.
        let (rows, all) = decoded(&dir.path().join("sim.pcapng"));
        let sim_interface = match tcp {
            true => "gimbalsim tcp 127.0.0.1:".to_owned(),
            false => format!("gimbalsim pty {endpoint}"),
        };
        assert!(
            rows.iter()
                .all(|r| r.get("frame.interface_name").starts_with(&sim_interface)),
            "{all}"
        );
        let gotos: Vec<&Row> = rows.iter().filter(|r| r.get("sagebrush.cmd") == "Paaaaeeee").collect();
        assert_eq!(gotos.len(), 1, "{all}");
        let goto = gotos[0];
        assert_eq!(goto.get("sagebrush.direction"), "1", "read by gimbalsim: {all}");
        assert_eq!(goto.get("sagebrush.address"), "1.1.1", "{all}");
        assert_eq!(goto.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(12.5), "{all}");
        assert_eq!(goto.get("sagebrush.tilt_deg").parse::<f64>().ok(), Some(-3.0), "{all}");
        let ack = rows
            .iter()
            .find(|r| r.get("sagebrush.kind") == "2" && r.get("sagebrush.ack_of") == goto.get("frame.number"))
            .unwrap_or_else(|| panic!("gimbalsim's ACK of the goto: {all}"));
        assert_eq!(ack.get("sagebrush.direction"), "2", "written by gimbalsim: {all}");
        // The last result is the captured position's.
        let result = rows
            .iter()
            .rfind(|r| r.get("sagebrush.type") == "result")
            .unwrap_or_else(|| panic!("a result: {all}"));
        assert_eq!(result.get("sagebrush.direction"), "2", "written by gimbalsim: {all}");
        assert_eq!(result.get("sagebrush.address"), "0.1.1", "{all}");
        assert_eq!(result.get("sagebrush.pan_deg").parse::<f64>().ok(), Some(12.5), "{all}");
        assert_eq!(
            result.get("sagebrush.tilt_deg").parse::<f64>().ok(),
            Some(-3.0),
            "{all}"
        );
        let query = frame(&rows, result.get("sagebrush.response_to"), &all);
        assert_eq!(query.get("sagebrush.cmd"), "P?", "{all}");
        assert_eq!(query.get("sagebrush.direction"), "1", "read by gimbalsim: {all}");
        assert!(
            rows.iter()
                .any(|r| r.get("sagebrush.ack_of") == result.get("frame.number") && r.get("sagebrush.direction") == "1"),
            "gimbalctl's ACK of the result, read by gimbalsim: {all}"
        );
    }
}

/// What a program read before SIGINT or SIGTERM is in its capture file:
/// gimbalctl (through a stand-in for gcud that acknowledges a `P?` and
/// sends half its result) and gimbalsim (sent half a command) complete the
/// file on the way out, the cut frame written as noise; gimbalctl exits
/// 128 + the signal, gimbalsim prints its stats line as before.
#[test]
fn sigint_and_sigterm_complete_the_capture_files() {
    require_tshark();
    for signal in [Signal::SIGINT, Signal::SIGTERM] {
        let dir = tempfile::tempdir().expect("temp dir");
        let file = |name: &str| dir.path().join(name).to_str().expect("path").to_owned();

        let gcud = TcpListener::bind("127.0.0.1:0").expect("listen");
        let gcud_addr = gcud.local_addr().expect("address").to_string();
        let ctl = Program::spawn(
            support::gimbalctl_bin(),
            &[
                "--tcp",
                &gcud_addr,
                "--capture",
                &file("ctl.pcapng"),
                "--to",
                "1.1.1",
                "position",
            ],
        );
        gcud.set_nonblocking(true).expect("nonblocking");
        let mut accepted = None;
        eventually("gimbalctl to connect", || {
            accepted = gcud.accept().ok();
            accepted.is_some()
        });
        let (mut conn, ctl_addr) = accepted.expect("connection");
        conn.set_nonblocking(false).expect("blocking");
        conn.set_read_timeout(Some(support::HANG_GUARD)).expect("timeout");
        let mut query = [0u8; 9];
        conn.read_exact(&mut query).expect("gimbalctl's P?");
        assert_eq!(&query[..8], [0xF8, 1, 1, 1, 0, 2, b'P', b'?']);
        conn.write_all(&[0x06, 0xF8, 0, 1, 1]).expect("ACK and half a result");
        wait_until_read(ctl_addr.port(), gcud.local_addr().expect("address").port());
        ctl.signal(signal);
        let (status, _, stderr) = ctl.wait();

        let (rows, all) = decoded(&dir.path().join("ctl.pcapng"));
        let seen: Vec<(&str, &str)> = rows
            .iter()
            .map(|r| (r.get("sagebrush.kind"), r.get("sagebrush.direction")))
            .collect();
        assert_eq!(
            seen,
            [("1", "2"), ("2", "1"), ("5", "1")],
            "{signal}: P?, ACK, half a result: {all}"
        );
        assert_eq!(rows[2].get("frame.len"), "12", "a record header and 4 bytes: {all}");
        assert_eq!(
            status.code(),
            Some(128 + signal as i32),
            "{signal}: {status:?} {stderr}"
        );
        assert!(stderr.contains(&format!("interrupted by {signal}")), "{stderr}");

        let sim = Program::spawn(
            support::gimbalsim_bin(),
            &[
                "--device",
                "1",
                "--tcp",
                "127.0.0.1:0",
                "--capture",
                &file("sim.pcapng"),
            ],
        );
        let sim_addr = sim.line();
        let mut master = TcpStream::connect(&sim_addr).expect("connect to gimbalsim");
        master.write_all(&[0xF8, 1, 1, 1]).expect("half a command");
        let sim_port: u16 = sim_addr.rsplit(':').next().and_then(|p| p.parse().ok()).expect("port");
        let master_port = master.local_addr().expect("address").port();
        wait_until_read(sim_port, master_port);
        sim.signal(signal);
        let (status, stdout, stderr) = sim.wait();
        assert!(status.success(), "{signal}: {status:?} {stderr}");
        assert!(stdout.contains("stats {"), "{signal}: the stats line: {stdout}");
        let (rows, all) = decoded(&dir.path().join("sim.pcapng"));
        assert_eq!(rows.len(), 1, "{signal}: {all}");
        assert_eq!(rows[0].get("sagebrush.kind"), "5", "{signal}: half a command: {all}");
        assert_eq!(rows[0].get("sagebrush.direction"), "1", "{all}");
        assert_eq!(
            rows[0].get("frame.interface_name"),
            format!("gimbalsim tcp 127.0.0.1:{master_port}"),
            "{all}"
        );
    }
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
    // The gimbal's own record, after a query that went out later on the
    // same line (frames are logged in the order they arrive): the goto
    // never reached it.
    sim.ctl_json(&["--to", "1.1.1", "position"]);
    assert_eq!(
        sim.received("1.1.1"),
        [(0, "P?".to_owned())],
        "nothing was sent before the query"
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

/// SIGUSR1 reads the configuration file through the same path as SIGHUP:
/// a broken file is one ERROR line naming its file:line:column and key, the
/// same error a reload reports, and the capture starts with the running
/// `[capture]` settings (docs/capture.md).
#[test]
fn sigusr1_and_sighup_report_a_broken_file_alike() {
    let text = config("[capture]\nfile = \"{dir}/s.pcapng\"\nenabled = false\n");
    let gcud = Daemon::start(&text);
    let broken = format!(
        "{}[[port]]\nid = \"three\"\n",
        text.replace("{dir}", &gcud.dir.path().display().to_string())
    );
    std::fs::write(gcud.path("gcud.toml"), broken).expect("write config");
    gcud.signal(Signal::SIGUSR1);
    let refused = gcud.wait_for_log("SIGUSR1: the configuration file is refused, running configuration kept: ");
    gcud.wait_for_log("capture started");
    assert!(
        gcud.path("s.pcapng").exists(),
        "the running [capture] settings were used"
    );
    gcud.signal(Signal::SIGHUP);
    let reload = gcud.wait_for_log("reload refused, running configuration kept: ");
    let error = |line: &str, prefix: &str| line.split(prefix).nth(1).map(str::to_owned).unwrap_or_default();
    let sigusr1 = error(&refused, "running configuration kept: ");
    assert!(
        sigusr1.contains("gcud.toml:17:6: port[1].id: expected an integer"),
        "{refused}"
    );
    assert!(refused.contains("ERROR"), "{refused}");
    assert_eq!(
        sigusr1,
        error(&reload, "running configuration kept: "),
        "{}",
        gcud.log()
    );
    assert!(reload.contains("ERROR"), "{reload}");
}
