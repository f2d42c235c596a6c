//! Helpers for the `gimbalctl` tests: a simulator addressed with an explicit
//! `--to` ([`At`]), a `gcud` on a demo-like configuration ([`DemoGcud`]),
//! a `gimbalctl` child that keeps running ([`spawn_ctl`]), and a scripted
//! bus on 127.0.0.1 with a garbled, a silent-after-ACK and a duplicated
//! device ([`FakeBus`]). Only 127.0.0.1; every wait is bounded.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use sagebrush_protocol::{Address, AwakeStatus, Event, FrameBuf, Framer, Identity, MAX_PAYLOAD, Reply, StatusBits};
use serde_json::Value;

use super::{HANG_GUARD, Output, Sim, eventually, gimbalctl_bin};

/// `--to 1.1.1` (unless the arguments name their own) in front of `args`.
fn with_to<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut full = Vec::new();
    if !args.contains(&"--to") {
        full.extend(["--to", "1.1.1"]);
    }
    full.extend_from_slice(args);
    full
}

/// A simulator's device 1.1.1 addressed explicitly (`--to` is required).
pub trait At {
    fn ctl1(&self, args: &[&str]) -> Output;
    fn json1(&self, args: &[&str]) -> Value;
    fn result1(&self, args: &[&str]) -> Value;
    fn position1(&self) -> (f64, f64);
    fn settled1(&self) -> (f64, f64);
}

impl At for Sim {
    fn ctl1(&self, args: &[&str]) -> Output {
        self.ctl(&with_to(args))
    }

    fn json1(&self, args: &[&str]) -> Value {
        self.ctl_json(&with_to(args))
    }

    fn result1(&self, args: &[&str]) -> Value {
        self.result(&with_to(args))
    }

    fn position1(&self) -> (f64, f64) {
        let r = self.result1(&["position"]);
        (
            r["pan_deg"].as_f64().expect("pan"),
            r["tilt_deg"].as_f64().expect("tilt"),
        )
    }

    fn settled1(&self) -> (f64, f64) {
        let mut last = self.position1();
        eventually("the mount to stop", || {
            std::thread::sleep(Duration::from_millis(100));
            let now = self.position1();
            let still = now == last;
            last = now;
            still
        });
        last
    }
}

/// A `gcud` (group 5) with simulated gimbals 1 and 2 on port 1, gimbal 1 on
/// port 2, port 3 on a missing device (closed), clients on 127.0.0.1:0.
#[derive(Debug)]
pub struct DemoGcud {
    child: Child,
    dir: tempfile::TempDir,
    pub clients: String,
}

impl DemoGcud {
    pub fn start() -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let config = format!(
            "[gcu]\ngroup = 5\nname = \"demo GCU\"\nserial = \"DEMO-0005\"\n\n\
             [[port]]\nid = 1\nsimulate = [1, 2]\n\n[[port]]\nid = 2\nsimulate = [1]\n\n\
             [[port]]\nid = 3\npath = \"{}\"\n\n\
             [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n",
            dir.path().join("no-such-tty").display()
        );
        // The router's DEBUG lines too: accepted connections going up and down.
        let filter = format!("{},gcud::router_task=debug", super::GCUD_LOG);
        let child = super::spawn_gcud_logging(dir.path(), &config, Some(&filter));
        let mut gcud = Self {
            child,
            dir,
            clients: String::new(),
        };
        let started = Instant::now();
        loop {
            let log = gcud.log();
            if log.contains("gcud ready") {
                if let Some(line) = log.lines().find(|l| l.contains("listening link=clients")) {
                    gcud.clients = super::addr_field(line);
                    return gcud;
                }
            }
            assert!(started.elapsed() < HANG_GUARD, "gcud did not start; log:\n{log}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("gcud.log")).unwrap_or_default()
    }

    /// `gimbalctl --tcp CLIENTS ARGS`.
    pub fn ctl(&self, args: &[&str]) -> Output {
        let mut full = vec!["--tcp", self.clients.as_str()];
        full.extend_from_slice(args);
        super::gimbalctl(&full)
    }

    /// `gimbalctl --json --tcp CLIENTS ARGS`, which must succeed.
    pub fn json(&self, args: &[&str]) -> Value {
        let mut full = vec!["--json"];
        full.extend_from_slice(args);
        let out = self.ctl(&full);
        assert_eq!(out.code, 0, "{args:?}: {out:?}\ngcud log:\n{}", self.log());
        out.json()
    }

    /// What the simulated gimbal `dest` received, by its own log line
    /// (gcud logs its `simulate` ports): (source, payload) per frame.
    /// Clients send as source 0; gcud's own stops come from group 5.
    pub fn received(&self, dest: &str) -> Vec<(u8, String)> {
        super::frames_received(&self.log(), dest)
    }

    /// The dead-man stops gcud logged (a client link went down with a
    /// motion still running).
    pub fn dead_man_lines(&self) -> Vec<String> {
        self.log()
            .lines()
            .filter(|l| l.contains("dead-man"))
            .map(str::to_owned)
            .collect()
    }

    /// Waits until the router has taken down every client connection it
    /// saw come up: any dead-man stop those caused is logged by then (the
    /// router reports it with the link going down).
    pub fn wait_until_clients_are_down(&self) {
        eventually("every client connection to be down in gcud", || {
            let log = self.log();
            log.matches(" up (clients ").count() == log.matches(" down (clients ").count()
        });
    }

    pub fn position(&self, to: &str) -> (f64, f64) {
        let r = &self.json(&["--to", to, "position"])["result"];
        (
            r["pan_deg"].as_f64().expect("pan"),
            r["tilt_deg"].as_f64().expect("tilt"),
        )
    }

    pub fn lens(&self, to: &str) -> (u64, u64) {
        let r = &self.json(&["--to", to, "lens"])["result"];
        (r["zoom"].as_u64().expect("zoom"), r["focus"].as_u64().expect("focus"))
    }
}

impl Drop for DemoGcud {
    fn drop(&mut self) {
        let _ = super::terminate(&mut self.child);
    }
}

/// `gimbalctl ARGS` left running, stdin piped (for `--hold`).
pub fn spawn_ctl(args: &[&str]) -> Child {
    Command::new(gimbalctl_bin())
        .args(args)
        .env_remove("GIMBALCTL_SERIAL")
        .env_remove("GIMBALCTL_TCP")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn gimbalctl")
}

/// Waits (bounded) for a child and collects its output.
pub fn wait_output(mut child: Child) -> Output {
    let started = Instant::now();
    while child.try_wait().expect("try_wait").is_none() {
        if started.elapsed() > HANG_GUARD {
            let _ = child.kill();
            panic!("gimbalctl child hung");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output().expect("output");
    Output {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// A scripted bus on 127.0.0.1 (a device server, as `gimbalctl --tcp --direct`
/// sees it): device 1 answers properly, device 2 answers `D?` with
/// garbage, device 3 exists twice (two ACKs, two identity results with
/// different serial numbers), device 4 ACKs and never answers, device 6
/// ACKs motions but not stops; the rest
/// are silent. It records every payload it received.
#[derive(Debug)]
pub struct FakeBus {
    pub addr: String,
    received: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
}

/// The wire bytes of a device's `reply` to `command` (Table 3 header).
pub fn reply_frame(command: &sagebrush_protocol::Frame<'_>, reply: &Reply<'_>) -> Vec<u8> {
    let mut buf = [0u8; MAX_PAYLOAD];
    let payload = reply.encode(&mut buf).expect("encode reply").to_vec();
    raw_frame(command, &payload)
}

fn raw_frame(command: &sagebrush_protocol::Frame<'_>, payload: &[u8]) -> Vec<u8> {
    // Table 3: the groups swap, port and device stay.
    let dest = Address::new(command.source, command.dest.port, command.dest.device);
    FrameBuf::new(dest, command.dest.group, payload)
        .expect("frame")
        .as_bytes()
        .to_vec()
}

impl FakeBus {
    pub fn start() -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = listener.local_addr().expect("addr").to_string();
        let received = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let log = received.clone();
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                let Ok(stream) = stream else { return };
                let log = log.clone();
                std::thread::spawn(move || serve(stream, &log));
            }
        });
        Self { addr, received }
    }

    /// Every payload received so far.
    pub fn received(&self) -> Vec<String> {
        self.received.lock().expect("lock").clone()
    }
}

fn serve(mut stream: TcpStream, log: &std::sync::Mutex<Vec<String>>) {
    let _ = stream.set_read_timeout(Some(HANG_GUARD));
    let mut framer: Framer = Framer::new();
    let mut buf = [0u8; 512];
    loop {
        let n = match stream.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let mut out: Vec<u8> = Vec::new();
        // The twin's answer, a few milliseconds after the first device's.
        let mut late: Vec<Vec<u8>> = Vec::new();
        framer.feed(&buf[..n], |e| {
            let Event::Frame(f) = e else { return };
            let payload = f.payload();
            log.lock()
                .expect("lock")
                .push(String::from_utf8_lossy(payload).into_owned());
            let device = f.dest.device;
            let identity = |serial: &'static [u8]| {
                Reply::Identity(Identity::new(device, *b"19", b"fake gimbal", serial).expect("identity"))
            };
            match (device, payload) {
                (1, b"D?") => {
                    out.push(sagebrush_protocol::ACK);
                    out.extend(reply_frame(&f, &identity(b"FAKE-1")));
                }
                (1 | 3, b"AW") => {
                    out.push(sagebrush_protocol::ACK);
                    out.extend(reply_frame(&f, &Reply::AwakeStatus(AwakeStatus::new(4).expect("bits"))));
                }
                (1 | 3, b"I?") => {
                    out.push(sagebrush_protocol::ACK);
                    out.extend(reply_frame(&f, &Reply::StatusBits(StatusBits { pan: 0x81, tilt: 0 })));
                }
                (2, b"D?") => {
                    out.push(sagebrush_protocol::ACK);
                    out.extend(raw_frame(&f, b"%%garbage%%"));
                }
                (3, b"D?") => {
                    // Two devices with ID 3 both answer.
                    out.push(sagebrush_protocol::ACK);
                    out.extend(reply_frame(&f, &identity(b"FAKE-3A")));
                    let mut twin = vec![sagebrush_protocol::ACK];
                    twin.extend(reply_frame(&f, &identity(b"FAKE-3B")));
                    late.push(twin);
                }
                (4, _) => out.push(sagebrush_protocol::ACK),
                // Acknowledges motions, never their stops (PS, TS, ZS, FS).
                (6, p) if !p.ends_with(b"S") => out.push(sagebrush_protocol::ACK),
                _ => {}
            }
        });
        if !out.is_empty() && stream.write_all(&out).is_err() {
            return;
        }
        for twin in late {
            std::thread::sleep(Duration::from_millis(5));
            if stream.write_all(&twin).is_err() {
                return;
            }
        }
    }
}
