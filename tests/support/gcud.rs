//! A running `gcud` for end-to-end tests ([`Gcud`]: a private directory,
//! its log, its listeners, metrics and `/status`; SIGTERM on drop) and a
//! client speaking the wire protocol itself ([`WireClient`]).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::Child;
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Command as Cmd, Event, FrameBuf, Framer, OwnedEvent};

use super::{HANG_GUARD, Output, Sim, eventually};

// ---- a running daemon ---------------------------------------------------------

/// A `gcud` process on a configuration written to a private directory;
/// SIGTERM on drop.
pub struct Gcud {
    pub child: Child,
    pub dir: tempfile::TempDir,
}

impl Gcud {
    pub fn start(config: &str) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let child = super::spawn_gcud(dir.path(), config);
        let gcud = Self { child, dir };
        gcud.wait_for_log("gcud ready");
        gcud
    }

    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("gcud.log")).unwrap_or_default()
    }

    pub fn wait_for_log(&self, text: &str) -> String {
        super::wait_for_log_line(&self.dir.path().join("gcud.log"), text)
    }

    /// What the simulated gimbal `dest` (on a `simulate` port) received,
    /// by the bus's own record ([`super::frames_received`], logged under
    /// [`super::GCUD_LOG`]): (source group, payload) per frame, in order.
    pub fn received(&self, dest: &str) -> Vec<(u8, String)> {
        super::frames_received(&self.log(), dest)
    }

    /// The address a listener link (or the metrics endpoint) was bound to.
    pub fn address(&self, what: &str) -> String {
        super::addr_field(&self.wait_for_log(what))
    }

    pub fn clients(&self) -> String {
        self.address("listening link=clients")
    }

    /// `gimbalctl --tcp` to this daemon's client listener.
    pub fn ctl(&self, args: &[&str]) -> Output {
        let mut full = vec!["--tcp".to_owned(), self.clients()];
        full.extend(args.iter().map(|s| s.to_string()));
        let refs: Vec<&str> = full.iter().map(String::as_str).collect();
        super::gimbalctl(&refs)
    }

    pub fn position(&self, to: &str) -> (f64, f64) {
        let out = self.ctl(&["--json", "--to", to, "position"]);
        assert_eq!(out.code, 0, "position of {to}: {out:?}\ngcud log:\n{}", self.log());
        let r = &out.json()["result"];
        (
            r["pan_deg"].as_f64().expect("pan"),
            r["tilt_deg"].as_f64().expect("tilt"),
        )
    }

    pub fn settled_position(&self, to: &str) -> (f64, f64) {
        let mut last = self.position(to);
        eventually(&format!("{to} to stop moving"), || {
            std::thread::sleep(Duration::from_millis(150));
            let now = self.position(to);
            let still = now == last;
            last = now;
            still
        });
        last
    }

    /// SIGTERM, then the exit status (None: it had to be killed) and the whole log.
    pub fn terminate(mut self) -> (Option<std::process::ExitStatus>, String) {
        let status = super::terminate(&mut self.child);
        (status, self.log())
    }

    /// `GET path` from the metrics endpoint (`[metrics] listen` must be
    /// configured): the whole response, status line first.
    pub fn http_get(&self, path: &str) -> String {
        super::http_get(&self.address("metrics at /metrics"), path)
    }

    /// The metrics text.
    pub fn metrics(&self) -> String {
        let text = self.http_get("/metrics");
        assert!(text.starts_with("HTTP/1.1 200"), "{text}");
        text
    }

    /// A gauge with a fraction or a sign, `None` when absent.
    pub fn real_metric(&self, series: &str) -> Option<f64> {
        let text = self.metrics();
        text.lines()
            .find_map(|l| l.strip_prefix(series).and_then(|v| v.strip_prefix(' ')))
            .map(|v| v.trim().parse().expect("metric value"))
    }

    /// `/status` as JSON.
    pub fn status(&self) -> serde_json::Value {
        let text = self.http_get("/status");
        assert!(text.starts_with("HTTP/1.1 200"), "{text}");
        let body = text.split("\r\n\r\n").nth(1).expect("body");
        serde_json::from_str(body).unwrap_or_else(|e| panic!("/status is not JSON ({e}): {body}"))
    }

    /// A counter or gauge from the metrics, 0 when absent.
    pub fn metric(&self, series: &str) -> u64 {
        let text = self.metrics();
        text.lines()
            .find_map(|l| l.strip_prefix(series).and_then(|v| v.strip_prefix(' ')))
            .map_or(0, |v| v.trim().parse().expect("metric value"))
    }
}

impl Drop for Gcud {
    /// Stops gcud; then its whole log must be words, no Rust `Debug`
    /// form ([`super::check_debug_forms_on_drop`], issue 53).
    fn drop(&mut self) {
        let _ = super::terminate(&mut self.child);
        super::check_debug_forms_on_drop("gcud's log", &self.log());
    }
}

pub fn port_entry(id: u8, sim: &Sim) -> String {
    format!("[[port]]\nid = {id}\npath = \"{}\"\n", sim.endpoint)
}

pub const CLIENTS: &str = "[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n";
pub const METRICS: &str = "[metrics]\nlisten = \"127.0.0.1:0\"\n";

// ---- a byte-level client --------------------------------------------------

/// A client speaking the wire protocol itself, to check headers byte by byte.
pub struct WireClient {
    stream: TcpStream,
    framer: Framer,
    pending: Vec<OwnedEvent>,
}

impl WireClient {
    pub fn connect(addr: &str) -> Self {
        let stream = TcpStream::connect(addr).expect("connect to gcud");
        // As gimbalctl: a command after our ACK of the last answer is not
        // held back by Nagle's algorithm waiting for gcud's delayed ACK.
        stream.set_nodelay(true).expect("nodelay");
        stream
            .set_read_timeout(Some(Duration::from_millis(100)))
            .expect("timeout");
        Self {
            stream,
            framer: Framer::new(),
            pending: Vec::new(),
        }
    }

    pub fn send(&mut self, dest: Address, source: u8, command: &Cmd<'_>) {
        let frame = FrameBuf::build(dest, source, |b| command.encode(b).map(<[u8]>::len)).expect("encode");
        self.stream.write_all(frame.as_bytes()).expect("send");
    }

    /// The next thing received; frames are ACKed (hop by hop).
    pub fn next(&mut self) -> OwnedEvent {
        let started = Instant::now();
        while self.pending.is_empty() {
            assert!(started.elapsed() < HANG_GUARD, "nothing received from gcud");
            let mut buf = [0u8; 512];
            match self.stream.read(&mut buf) {
                Ok(0) => panic!("gcud closed the connection"),
                Ok(n) => {
                    let pending = &mut self.pending;
                    self.framer.feed(&buf[..n], |e| match e {
                        Event::BadChecksum(b) => panic!("bad checksum from gcud: {b:?}"),
                        e => pending.push(e.to_owned()),
                    });
                }
                // A stop signal interrupts a read with a time-out (signal(7)).
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => panic!("read from gcud: {e}"),
            }
        }
        let next = self.pending.remove(0);
        if let OwnedEvent::Frame(_) = next {
            self.stream.write_all(&[ACK]).expect("ack");
        }
        next
    }

    pub fn expect_result(&mut self) -> FrameBuf {
        assert_eq!(self.next(), OwnedEvent::Ack, "gcud acknowledges the command hop by hop");
        match self.next() {
            OwnedEvent::Frame(f) => f,
            other => panic!("expected a result frame, got {other:?}"),
        }
    }
}
