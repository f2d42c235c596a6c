//! Test support: start the real `gimbalsim` on a fresh pseudo-terminal (or
//! a TCP port chosen by the system) and run the real `gimbalctl` against it.
//! Every test gets its own simulator, so tests run in parallel.
//!
//! Reusable by other integration tests (`mod support;`): [`Sim::pty`],
//! [`Sim::tcp`], [`Sim::ctl`] / [`Sim::ctl_json`], [`gimbalctl`],
//! [`Sim::stop`] (which returns the simulator's final statistics), and
//! [`eventually`] for polling without wall-clock assertions.

#![allow(dead_code)]

pub mod browser;
pub mod capture;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde_json::Value;

pub mod cli;
pub mod door;
pub mod fake_gcud;
pub mod gcud;
pub mod relay;

/// The programs the Debian package installs, each with its unit
/// `config/NAME.service` running `/usr/bin/NAME` on `/etc/NAME/NAME.toml`
/// (`tests/packaging.rs` checks this list against Cargo.toml's
/// systemd-units; `tests/deployment.rs` verifies each unit).
pub const PACKAGED_UNITS: [&str; 7] = [
    "gcud",
    "gimbal-onvif",
    "gimbal-mavlink",
    "gimbal-web",
    "gimbal-mqtt",
    "gimbal-visca",
    "gimbal-pelco",
];

/// The environment variable that lets a test whose third-party tool is
/// missing (a door's Python client, tshark, cargo-deb, systemd-analyze)
/// be skipped; without it such a test fails, saying how to install the
/// tool, so that a green run never hides a test that checked nothing.
pub const SKIP_MISSING_TOOLS: &str = "SAGEBRUSH_SKIP_MISSING_TOOLS";

/// A test's tool is missing (`what`, with how to install it): the test
/// fails, unless [`SKIP_MISSING_TOOLS`] is `1`, when it says SKIPPED and
/// the caller returns without checking anything.
pub fn tool_missing(what: &str) {
    if std::env::var(SKIP_MISSING_TOOLS).is_ok_and(|v| v == "1") {
        eprintln!("SKIPPED ({SKIP_MISSING_TOOLS}=1): {what}");
        return;
    }
    panic!("{what}; or set {SKIP_MISSING_TOOLS}=1 to skip the tests that need it");
}

/// Only to avoid hanging on a broken build: never an assertion on speed.
pub const HANG_GUARD: Duration = Duration::from_secs(60);

pub fn gimbalsim_bin() -> &'static str {
    env!("CARGO_BIN_EXE_gimbalsim")
}

/// gcud's log filter in the tests: INFO (the daemon's life), plus the DEBUG
/// lines the helpers read: the simulated gimbals' frames
/// ([`frames_received`]) and accepted connections coming and going
/// (`client connected`, `link closed`).
pub const GCUD_LOG: &str = "info,sagebrush_sim::bus=debug,gcud::io=debug";

/// Writes `config` to `dir/gcud.toml` and starts the real gcud on it,
/// its log ([`GCUD_LOG`]) going to `dir/gcud.log`.
pub fn spawn_gcud(dir: &Path, config: &str) -> Child {
    spawn_gcud_logging(dir, config, Some(GCUD_LOG))
}

/// [`spawn_gcud`] with `RUST_LOG` set to `filter`, or unset (the
/// configuration's `[log] level` applies) for `None`.
pub fn spawn_gcud_logging(dir: &Path, config: &str, filter: Option<&str>) -> Child {
    let path = dir.join("gcud.toml");
    std::fs::write(&path, config).expect("write config");
    let log = std::fs::File::create(dir.join("gcud.log")).expect("log file");
    let mut gcud = Command::new(env!("CARGO_BIN_EXE_gcud"));
    match filter {
        Some(filter) => gcud.env("RUST_LOG", filter),
        None => gcud.env_remove("RUST_LOG"),
    };
    gcud.arg("--config")
        .arg(&path)
        .stdout(Stdio::null())
        .stderr(Stdio::from(log))
        .spawn()
        .expect("spawn gcud")
}

/// The `addr=` field of a gcud log line ("listening link=clients ...",
/// "metrics at /metrics ...").
pub fn addr_field(line: &str) -> String {
    let addr = line.split("addr=").nth(1).expect("addr field");
    addr.split_whitespace().next().expect("address").to_owned()
}

/// `GET path` over HTTP/1.1 from `addr` (gcud's metrics endpoint): the
/// whole response, status line first.
pub fn http_get(addr: &str, path: &str) -> String {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(addr).expect("connect to the metrics endpoint");
    stream.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .expect("request");
    let mut text = String::new();
    stream.read_to_string(&mut text).expect("response");
    text
}

/// What a simulated gimbal received, by its own record: the `rx frame`
/// lines for `dest` in a gimbalsim log (or a gcud log, for its `simulate`
/// ports), in order, as (source, payload). Tests of a stop read the stop
/// here, on the gimbal's side of the wire, not in the sender's account.
pub fn frames_received(log: &str, dest: &str) -> Vec<(u8, String)> {
    let prefix = format!("rx frame dest={dest} source=");
    log.lines()
        .filter_map(|line| {
            let rest = &line[line.find(&prefix)? + prefix.len()..];
            let (source, rest) = rest.split_once(" payload=")?;
            let payload = rest.split_once(" command=").map_or(rest, |(p, _)| p);
            Some((source.parse().ok()?, payload.to_owned()))
        })
        .collect()
}

/// [`frames_received`] with when the gimbal received each: seconds of the
/// day of its log line's timestamp (`2026-11-27T02:20:01.123456Z ...`).
pub fn frames_received_at(log: &str, dest: &str) -> Vec<(f64, String)> {
    let prefix = format!("rx frame dest={dest} source=");
    log.lines()
        .filter(|line| line.contains(&prefix))
        .filter_map(|line| {
            let (_, clock) = line.split_once('T')?;
            let clock = clock.get(..clock.find('Z')?)?;
            let mut hms = clock.split(':').map(|f| f.parse::<f64>().ok());
            let at = hms.next()?? * 3600.0 + hms.next()?? * 60.0 + hms.next()??;
            let (_, payload) = frames_received(line, dest).pop()?;
            Some((at, payload))
        })
        .collect()
}

/// Waits (at most [`HANG_GUARD`]) until a line of the log file `log`
/// contains `text`; returns that line.
pub fn wait_for_log_line(log: &Path, text: &str) -> String {
    let started = Instant::now();
    loop {
        let content = std::fs::read_to_string(log).unwrap_or_default();
        if let Some(line) = content.lines().find(|l| l.contains(text)) {
            return line.to_owned();
        }
        if started.elapsed() > HANG_GUARD {
            panic!("gcud never logged {text:?}; log:\n{content}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

pub fn gimbalctl_bin() -> &'static str {
    env!("CARGO_BIN_EXE_gimbalctl")
}

/// A certificate authority with gcud's certificate and one per principal
/// in `dir` (`gimbalctl tls init`, as an operator makes them): `ca.crt`,
/// `gcud.crt`/`.key` and `NAME.crt`/`.key`. Fails the test if it cannot.
pub fn tls_init(dir: &Path, principals: &[&str]) {
    let dir_arg = dir.to_str().expect("a UTF-8 path");
    let mut args = vec!["tls", "init", "--dir", dir_arg];
    for p in principals {
        args.extend(["--principal", p]);
    }
    let made = gimbalctl(&args);
    assert_eq!(made.code, 0, "gimbalctl {}: {made:?}", args.join(" "));
}

/// What a `gimbalctl` run printed and how it exited.
#[derive(Debug)]
pub struct Output {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

impl Output {
    /// The stdout as one JSON value (the single object of `--json`).
    pub fn json(&self) -> Value {
        serde_json::from_str(self.stdout.trim())
            .unwrap_or_else(|e| panic!("stdout is not one JSON value ({e}): {self:?}"))
    }

    /// Every stdout line as JSON.
    pub fn json_lines(&self) -> Vec<Value> {
        self.stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("line {l:?} is not JSON: {e}")))
            .collect()
    }
}

/// Runs a child to completion, killing it if it outlives [`HANG_GUARD`].
fn finish(mut cmd: Command) -> Output {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn gimbalctl");
    let started = Instant::now();
    loop {
        match child.try_wait().expect("wait for gimbalctl") {
            Some(_) => break,
            None if started.elapsed() > HANG_GUARD => {
                let _ = child.kill();
                panic!("gimbalctl {cmd:?} hung");
            }
            None => std::thread::sleep(Duration::from_millis(5)),
        }
    }
    let out = child.wait_with_output().expect("gimbalctl output");
    checked_output(out)
}

/// A gimbalctl run's output, whose words hold no Rust `Debug` form
/// ([`assert_no_debug_forms`], issue 53).
fn checked_output(out: std::process::Output) -> Output {
    let out = Output {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    };
    assert_no_debug_forms("gimbalctl's output", &format!("{}\n{}", out.stdout, out.stderr));
    out
}

/// `gimbalctl ARGS` with no transport from the environment (encode, decode,
/// argument errors).
pub fn gimbalctl(args: &[&str]) -> Output {
    let mut cmd = Command::new(gimbalctl_bin());
    cmd.args(args)
        .env_remove("GIMBALCTL_SERIAL")
        .env_remove("GIMBALCTL_TCP");
    finish(cmd)
}

/// `gimbalctl ARGS` with `input` on stdin.
pub fn gimbalctl_stdin(args: &[&str], input: &str) -> Output {
    use std::io::Write;
    let mut child = Command::new(gimbalctl_bin())
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn gimbalctl");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("write stdin");
    let out = child.wait_with_output().expect("gimbalctl output");
    checked_output(out)
}

/// A running `gimbalsim`, stopped (SIGTERM) on drop.
#[derive(Debug)]
pub struct Sim {
    child: Child,
    /// The first stdout line: pty path or TCP address.
    pub endpoint: String,
    tcp: bool,
    lines: mpsc::Receiver<String>,
    dir: tempfile::TempDir,
}

impl Sim {
    fn start(tcp: bool, args: &[&str]) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let log = std::fs::File::create(dir.path().join("gimbalsim.log")).expect("log file");
        let mut cmd = Command::new(gimbalsim_bin());
        if tcp {
            cmd.args(["--tcp", "127.0.0.1:0"]);
        }
        let mut child = cmd
            .args(args)
            .env("RUST_LOG", "debug")
            .stdout(Stdio::piped())
            .stderr(Stdio::from(log))
            .spawn()
            .expect("spawn gimbalsim");
        let stdout = child.stdout.take().expect("gimbalsim stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let endpoint = match lines.recv_timeout(HANG_GUARD) {
            Ok(line) => line,
            Err(_) => {
                let _ = child.kill();
                let log = std::fs::read_to_string(dir.path().join("gimbalsim.log")).unwrap_or_default();
                panic!("gimbalsim printed no endpoint; log:\n{log}");
            }
        };
        Self {
            child,
            endpoint,
            tcp,
            lines,
            dir,
        }
    }

    /// A simulator on a fresh pseudo-terminal with extra `gimbalsim` flags.
    pub fn pty(args: &[&str]) -> Self {
        Self::start(false, args)
    }

    /// A simulator listening on 127.0.0.1 at a port the system picks.
    pub fn tcp(args: &[&str]) -> Self {
        Self::start(true, args)
    }

    /// A path in this simulator's private temporary directory.
    pub fn temp_path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// What the simulator logged so far (for failure messages).
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("gimbalsim.log")).unwrap_or_default()
    }

    /// What device `dest` received so far, by the simulator's own log:
    /// (source, payload) per frame ([`frames_received`]).
    pub fn received(&self, dest: &str) -> Vec<(u8, String)> {
        frames_received(&self.log(), dest)
    }

    /// The `gimbalctl` transport flags for this simulator (over TCP it is
    /// a device server: `--direct`, gimbalctl its bus master).
    pub fn transport(&self) -> Vec<String> {
        match self.tcp {
            true => vec!["--tcp".into(), self.endpoint.clone(), "--direct".into()],
            false => vec!["--serial".into(), self.endpoint.clone()],
        }
    }

    /// `gimbalctl` against this simulator.
    pub fn ctl(&self, args: &[&str]) -> Output {
        let mut cmd = Command::new(gimbalctl_bin());
        cmd.env_remove("GIMBALCTL_SERIAL")
            .env_remove("GIMBALCTL_TCP")
            .args(self.transport())
            .args(args);
        finish(cmd)
    }

    /// `gimbalctl --json ARGS`, which must succeed; its JSON object.
    pub fn ctl_json(&self, args: &[&str]) -> Value {
        let mut full = vec!["--json"];
        full.extend_from_slice(args);
        let out = self.ctl(&full);
        assert_eq!(
            out.code,
            0,
            "gimbalctl {args:?} failed: {out:?}\nsimulator log:\n{}",
            self.log()
        );
        out.json()
    }

    /// The JSON result of a successful query.
    pub fn result(&self, args: &[&str]) -> Value {
        let v = self.ctl_json(args);
        assert_eq!(v["outcome"], "result", "{args:?}: {v}");
        v["result"].clone()
    }

    /// Current position in degrees.
    pub fn position(&self) -> (f64, f64) {
        let r = self.result(&["--to", "1.1.1", "position"]);
        (
            r["pan_deg"].as_f64().expect("pan"),
            r["tilt_deg"].as_f64().expect("tilt"),
        )
    }

    /// Polls the position until two readings 100 ms apart agree.
    pub fn settled_position(&self) -> (f64, f64) {
        let mut last = self.position();
        eventually("the mount to stop", || {
            std::thread::sleep(Duration::from_millis(100));
            let now = self.position();
            let still = now == last;
            last = now;
            still
        });
        last
    }

    /// Stops the simulator (SIGTERM) and returns its final statistics.
    pub fn stop(mut self) -> Value {
        self.terminate();
        let started = Instant::now();
        while started.elapsed() < HANG_GUARD {
            match self.lines.recv_timeout(Duration::from_millis(100)) {
                Ok(line) => {
                    if let Some(json) = line.strip_prefix("stats ") {
                        return serde_json::from_str(json).expect("stats JSON");
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        panic!("gimbalsim printed no stats; log:\n{}", self.log());
    }

    fn terminate(&mut self) {
        let _ = terminate(&mut self.child);
    }

    /// The simulator's process id (to SIGSTOP it: a device server that
    /// stops reading).
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Whether the process is still running.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    pub fn endpoint_path(&self) -> &Path {
        Path::new(&self.endpoint)
    }
}

impl Drop for Sim {
    /// Stops gimbalsim; then its whole log must be words, no Rust `Debug`
    /// form ([`check_debug_forms_on_drop`], issue 53).
    fn drop(&mut self) {
        self.terminate();
        check_debug_forms_on_drop("gimbalsim's log", &self.log());
    }
}

/// Stops a child process gracefully: SIGTERM, then SIGKILL only after
/// [`HANG_GUARD`] (a hung process, not a slow one: a shutdown that waits
/// for in-flight work on a loaded machine is never cut short).
/// Returns how it exited, if it was still running and exited on SIGTERM.
pub fn terminate(child: &mut Child) -> Option<std::process::ExitStatus> {
    if let Ok(None) = child.try_wait() {
        let pid = nix::unistd::Pid::from_raw(child.id() as i32);
        let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM);
        let started = Instant::now();
        while started.elapsed() < HANG_GUARD {
            if let Ok(Some(status)) = child.try_wait() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = child.kill();
        let _ = child.wait();
    }
    None
}

/// The lines of `text` (a program's log or output) that hold a Rust
/// `Debug` form, which an operator must not have to decode (issue 53): a
/// struct with its fields (`Address { group: 5, ..`), an `Option` or a
/// `Result` (`Some(`, `None`, `Ok(`, `Err(`). The programs write words:
/// `5.2.1`, `refused by GCU 5 for 5.2.1: ...`, `1/190`.
pub fn debug_forms(text: &str) -> Vec<&str> {
    text.lines().filter(|line| holds_debug_form(line)).collect()
}

fn holds_debug_form(line: &str) -> bool {
    let ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    // `word` at `i`, not inside a longer name (`Some(` ends in its own
    // delimiter; `None` must end there).
    let word_at = |i: usize, word: &str| {
        line[i..].starts_with(word)
            && !line[..i].ends_with(ident)
            && (word.ends_with('(') || !line[i + word.len()..].starts_with(ident))
    };
    let mut at = 0;
    while let Some(offset) = line[at..].find(|c: char| c.is_ascii_uppercase()) {
        let i = at + offset;
        if ["Some(", "Ok(", "Err("].iter().any(|w| word_at(i, w)) || word_at(i, "None") {
            return true;
        }
        // `Type { field: ` or `Type { .. }`: a struct's Debug form.
        let name_len = line[i..].find(|c: char| !ident(c)).unwrap_or(line.len() - i);
        if !line[..i].ends_with(ident) {
            let rest = &line[i + name_len..];
            if let Some(fields) = rest.strip_prefix(" { ") {
                let field_len = fields.find(|c: char| !ident(c)).unwrap_or(fields.len());
                let field = &fields[..field_len];
                if fields.starts_with("..")
                    || (!field.is_empty()
                        && field.starts_with(|c: char| c.is_ascii_lowercase() || c == '_')
                        && fields[field_len..].starts_with(": "))
                {
                    return true;
                }
            }
        }
        at = i + name_len.max(1);
    }
    false
}

/// Fails when `text` (`what`: a program's log or output) holds a Rust
/// `Debug` form ([`debug_forms`]), naming each line.
pub fn assert_no_debug_forms(what: &str, text: &str) {
    let found = debug_forms(text);
    assert!(
        found.is_empty(),
        "{what} shows Rust Debug forms an operator must decode (issue 53; write words, Display):\n{}",
        found.join("\n")
    );
}

/// [`assert_no_debug_forms`] from a `Drop`: not while the test already
/// fails (its own message stays the one shown).
pub fn check_debug_forms_on_drop(what: &str, text: &str) {
    if !std::thread::panicking() {
        assert_no_debug_forms(what, text);
    }
}

/// Polls `condition` (which may sleep) until it holds; panics only after
/// [`HANG_GUARD`], so a slow machine never fails a test.
pub fn eventually(what: &str, mut condition: impl FnMut() -> bool) {
    let started = Instant::now();
    while !condition() {
        if started.elapsed() > HANG_GUARD {
            panic!("gave up waiting for {what}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// [`eventually`], giving up with `context()` (the programs' logs) after
/// `what` in the failure message.
pub fn eventually_with(what: &str, mut condition: impl FnMut() -> bool, context: impl FnOnce() -> String) {
    let started = Instant::now();
    while !condition() {
        if started.elapsed() > HANG_GUARD {
            panic!("gave up waiting for {what}\n{}", context());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}
