//! What the front doors' end-to-end tests share (`tests/onvif.rs`,
//! `tests/mavlink/`): the gcud with two simulated buses they stand in front
//! of ([`start_gcud`]), a door binary run on a configuration with its log and
//! stopped by a signal ([`Door`]), whether the third-party Python client is
//! installed (a test fails when it is not, unless skipping is asked for), one step of that client run as a
//! script that prints JSON, the gimbal's motion and stillness read on the bus
//! side, the stops that reached the simulated bus after a motion and from
//! whom (the door's own or gcud's dead-man), `--check` run on a file and the
//! lines a shipped unit must hold.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use super::HANG_GUARD;

/// The Python that runs the doors' third-party clients: `$SAGEBRUSH_PYTHON`
/// when set, else the checkout's virtual environment `.venv/bin/python3`
/// (`./test.sh` installs the clients there, which
/// works on a Debian or Ubuntu whose own Python is externally managed), else
/// `python3` on the PATH.
pub fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("SAGEBRUSH_PYTHON") {
        return PathBuf::from(p);
    }
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python3");
    if venv.exists() { venv } else { PathBuf::from("python3") }
}

/// Whether `python -c "import ..."` works ([`python`]); when it does not,
/// the test fails saying how to install `hint` ([`super::tool_missing`]),
/// unless skipping is asked for.
pub fn python_client_available(imports: &str, hint: &str) -> bool {
    let ok = Command::new(python())
        .args(["-c", &format!("import {imports}")])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        super::tool_missing(&format!(
            "{} with {hint} is missing: `python3 -m venv .venv && .venv/bin/pip install -r tests/requirements.txt` (./test.sh does it)",
            python().display()
        ));
    }
    ok
}

/// The ONVIF clients (onvif-zeep-async, its XSDs and lxml, WS-Discovery,
/// httpx) installed, or the test fails ([`python_client_available`]).
pub fn onvif_client_available() -> bool {
    python_client_available("onvif, wsdiscovery, httpx, lxml", "onvif-zeep-async and WSDiscovery")
}

/// The MAVLink ground station's library (pymavlink with numpy for its
/// quaternions, pyserial for serial links) installed, or the test fails.
pub fn mavlink_client_available() -> bool {
    python_client_available(
        "pymavlink.mavutil, pymavlink.quaternion, serial",
        "pymavlink, numpy and pyserial",
    )
}

/// Runs `script step args...` (a `tests/<door>/*.py` client step) and
/// returns the JSON of its last stdout line; a failed step fails the test
/// with the door's `log`.
pub fn python_step(script: &str, step: &str, args: &[&str], log: impl FnOnce() -> String) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join(script);
    let out = Command::new(python())
        .arg(&script)
        .arg(step)
        .args(args)
        .output()
        .expect("run the clients' Python");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{} step {step} failed: {}\nstdout: {stdout}\nstderr: {}\ndoor log:\n{}",
        script.display(),
        out.status,
        String::from_utf8_lossy(&out.stderr),
        log()
    );
    serde_json::from_str(stdout.lines().last().unwrap_or_default())
        .unwrap_or_else(|e| panic!("step {step}: not JSON ({e}): {stdout}"))
}

/// A door binary (`gimbal-onvif`, `gimbal-mavlink`) run on a configuration
/// written to its private directory, its log (`RUST_LOG=info`) in
/// `NAME.log` there; SIGTERM on drop.
pub struct Door {
    name: &'static str,
    bin: &'static str,
    child: Option<Child>,
    pub dir: tempfile::TempDir,
}

impl Door {
    /// Not running yet: [`Door::start`] runs it.
    pub fn new(name: &'static str, bin: &'static str) -> Self {
        Self {
            name,
            bin,
            child: None,
            dir: tempfile::tempdir().expect("temp dir"),
        }
    }

    /// Writes `config` to `NAME.toml`, starts the door on it with a fresh
    /// log, and waits for its `NAME ready` line.
    pub fn start(&mut self, config: &str) {
        let path = self.dir.path().join(format!("{}.toml", self.name));
        std::fs::write(&path, config).expect("write config");
        let log = std::fs::File::create(self.log_path()).expect("log file");
        let child = Command::new(self.bin)
            .arg("--config")
            .arg(&path)
            .env("RUST_LOG", "info")
            .stdout(Stdio::null())
            .stderr(Stdio::from(log))
            .spawn()
            .unwrap_or_else(|e| panic!("spawn {}: {e}", self.name));
        self.child = Some(child);
        super::wait_for_log_line(&self.log_path(), &format!("{} ready", self.name));
    }

    /// The running door's process id.
    pub fn pid(&self) -> u32 {
        self.child
            .as_ref()
            .unwrap_or_else(|| panic!("{} is not running", self.name))
            .id()
    }

    pub fn log_path(&self) -> PathBuf {
        self.dir.path().join(format!("{}.log", self.name))
    }

    pub fn log(&self) -> String {
        std::fs::read_to_string(self.log_path()).unwrap_or_default()
    }

    /// The port of the `addr=` field of the log line holding `what`.
    pub fn port(&self, what: &str) -> u16 {
        let line = super::wait_for_log_line(&self.log_path(), what);
        super::addr_field(&line)
            .rsplit(':')
            .next()
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| panic!("no port in {line:?}"))
    }

    /// Sends `signal` and waits for the door to exit.
    pub fn signal(&mut self, signal: nix::sys::signal::Signal) -> ExitStatus {
        let mut child = self
            .child
            .take()
            .unwrap_or_else(|| panic!("{} is not running", self.name));
        let pid = nix::unistd::Pid::from_raw(child.id() as i32);
        nix::sys::signal::kill(pid, signal).expect("signal");
        let started = Instant::now();
        loop {
            if let Ok(Some(status)) = child.try_wait() {
                return status;
            }
            assert!(started.elapsed() < HANG_GUARD, "{} did not exit on {signal}", self.name);
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for Door {
    /// Stops the door; then its whole log must be words, no Rust `Debug`
    /// form ([`super::check_debug_forms_on_drop`], issue 53).
    fn drop(&mut self) {
        if let Some(child) = &mut self.child {
            super::terminate(child);
        }
        super::check_debug_forms_on_drop(&format!("{}'s log", self.name), &self.log());
    }
}

/// Samples gimbal `address`'s position on the bus side until it moved
/// away from `from`.
pub fn wait_moving(gcud: &super::gcud::Gcud, address: &str, from: (f64, f64)) {
    super::eventually("the gimbal to move", || {
        std::thread::sleep(Duration::from_millis(50));
        gcud.position(address) != from
    });
}

/// Gimbal `address`'s position `at` unchanged over about a second on the
/// bus side.
pub fn assert_still(gcud: &super::gcud::Gcud, address: &str, at: (f64, f64), what: &str) {
    for _ in 0..5 {
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(gcud.position(address), at, "{what}: the gimbal moved");
    }
}

/// gcud's group in the doors' tests: the stops gcud issues itself
/// (dead-man) come from it.
pub const GCUD_GROUP: u8 = 5;

/// The source group the doors' test configurations give them: neither
/// gimbalctl's 0 nor gcud's own, so the bus tells their frames apart.
pub const DOOR_GROUP: u8 = 7;

/// gcud (group [`GCUD_GROUP`]) with two simulated buses, the mast gimbal
/// (device 1) on port 1 and port 2 without the doors' absent device 9,
/// and a client listener that allows gimbalctl's group 0 and
/// [`DOOR_GROUP`].
pub fn start_gcud() -> super::gcud::Gcud {
    super::gcud::Gcud::start(&format!(
        "[gcu]\ngroup = {GCUD_GROUP}\n[[port]]\nid = 1\nsimulate = [1]\n[[port]]\nid = 2\nsimulate = [1]\n\
         {}allow_source_groups = [0, {DOOR_GROUP}]\n",
        super::gcud::CLIENTS
    ))
}

/// The priority of the governed gcud's `operators` listener, above the
/// doors' `clients` (50, gcud's default).
pub const OPERATORS_PRIORITY: u8 = 80;

/// How gcud names the operators' link when it holds a gimbal, as a door
/// repeats it (a fault's reason, a STATUSTEXT, the page).
pub const OPERATORS_HOLDER: &str = "link operators (priority 80)";

/// [`start_gcud`]'s buses under gcud's governance (ARCHITECTURE
/// "Front doors"): a link keeps control of a gimbal for a minute after its
/// last command that moves it (`[control] hold_ms`), the doors' listener
/// `clients` at priority 50 and a second client listener, `operators`, at
/// [`OPERATORS_PRIORITY`], where gimbalctl plays the operators' console.
/// Needs gcud's parsing of `[control]` and `[[link]] priority` (issue 32).
pub fn start_governed_gcud() -> super::gcud::Gcud {
    start_governed_gcud_with("")
}

/// [`start_governed_gcud`] with `extra` appended to its configuration
/// (`[[gimbal]]` rules, `[[tour]]`s).
pub fn start_governed_gcud_with(extra: &str) -> super::gcud::Gcud {
    let config = format!(
        "[gcu]\ngroup = {GCUD_GROUP}\n[control]\nhold_ms = 60000\n\
         [[port]]\nid = 1\nsimulate = [1]\n[[port]]\nid = 2\nsimulate = [1]\n\
         {}allow_source_groups = [0, {DOOR_GROUP}]\npriority = 50\n\
         [[link]]\nname = \"operators\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = {OPERATORS_PRIORITY}\n{extra}",
        super::gcud::CLIENTS
    );
    // A gcud that cannot read it fails the test at once, saying why.
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, &config).expect("write config");
    let checked = check(env!("CARGO_BIN_EXE_gcud"), &path);
    assert!(
        checked.status.success(),
        "gcud refuses the governed configuration (needs [control] hold_ms and [[link]] priority): {}",
        String::from_utf8_lossy(&checked.stderr)
    );
    super::gcud::Gcud::start(&config)
}

/// `gimbalctl --tcp OPERATORS ARGS`: the operators' console on the
/// governed gcud's `operators` listener.
pub fn operators_ctl(gcud: &super::gcud::Gcud, args: &[&str]) -> super::Output {
    let addr = gcud.address("listening link=operators");
    let mut full = vec!["--tcp", addr.as_str()];
    full.extend_from_slice(args);
    super::gimbalctl(&full)
}

/// A slow pan slew right (speed 2 of 15, about 6 °/s) by the operators'
/// link, held by `gimbalctl slew --hold` until dropped: closing its stdin
/// ends it with a confirmed stop.
pub struct OperatorsSlew {
    child: Option<Child>,
}

impl OperatorsSlew {
    pub fn start(gcud: &super::gcud::Gcud, address: &str) -> Self {
        let out = operators_ctl(gcud, &["--to", address, "speed", "pan", "2"]);
        assert_eq!(
            out.code,
            0,
            "the operators set the pan speed: {out:?}\ngcud log:\n{}",
            gcud.log()
        );
        let child = Command::new(super::gimbalctl_bin())
            .args([
                "--tcp",
                &gcud.address("listening link=operators"),
                "--to",
                address,
                "slew",
                "right",
                "--hold",
            ])
            .env_remove("GIMBALCTL_SERIAL")
            .env_remove("GIMBALCTL_TCP")
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn gimbalctl slew --hold");
        Self { child: Some(child) }
    }
}

impl Drop for OperatorsSlew {
    fn drop(&mut self) {
        let Some(mut child) = self.child.take() else { return };
        drop(child.stdin.take());
        let started = Instant::now();
        while started.elapsed() < HANG_GUARD {
            if let Ok(Some(_)) = child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        super::terminate(&mut child);
    }
}

/// Every frame the door's source group got onto gimbal `address`'s bus is
/// a query: gcud dropped its refused commands, and the door sent no stop
/// (which would have ended another link's motion).
pub fn assert_door_sent_only_queries(gcud: &super::gcud::Gcud, address: &str) {
    let sent: Vec<String> = gcud
        .received(address)
        .into_iter()
        .filter(|(source, _)| *source == DOOR_GROUP)
        .map(|(_, p)| p)
        .collect();
    assert!(
        sent.iter().all(|p| p.ends_with('?')),
        "the door's frames on the bus: {sent:?}"
    );
}

/// The motion commands the doors send (Table 11 and 16: pan, tilt, zoom).
fn is_motion(payload: &str) -> bool {
    matches!(payload, "PR" | "PL" | "TU" | "TD" | "ZI" | "ZO")
}

/// The stops (`PS`, `TS`, `ZS`).
fn is_stop(payload: &str) -> bool {
    matches!(payload, "PS" | "TS" | "ZS")
}

/// What gimbal `address` received after the last motion command it
/// received, by the simulated bus's own record: (source group, payload).
fn after_last_motion(gcud: &super::gcud::Gcud, address: &str) -> Vec<(u8, String)> {
    let received = gcud.received(address);
    let last = received
        .iter()
        .rposition(|(_, p)| is_motion(p))
        .unwrap_or_else(|| panic!("{address} received no motion: {received:?}"));
    received[last + 1..].to_vec()
}

/// Waits until the stop `stop` from source group `from` reached gimbal
/// `address` (read on the bus) after the last motion it received.
pub fn wait_for_stop(gcud: &super::gcud::Gcud, address: &str, from: u8, stop: &str) {
    let started = Instant::now();
    loop {
        let after = after_last_motion(gcud, address);
        if after.iter().any(|(source, p)| *source == from && p == stop) {
            return;
        }
        assert!(
            started.elapsed() < HANG_GUARD,
            "no {stop} from group {from} reached {address} after its last motion; it received {:?}\ngcud log:\n{}",
            gcud.received(address),
            gcud.log()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// No stop from gcud's own group reached gimbal `address` (read on the
/// bus): whatever stopped it, gcud's dead-man did not.
pub fn assert_no_stop_from_gcud(gcud: &super::gcud::Gcud, address: &str) {
    let received = gcud.received(address);
    assert!(
        !received.iter().any(|(source, p)| *source == GCUD_GROUP && is_stop(p)),
        "gcud (group {GCUD_GROUP}) stopped {address}: {received:?}"
    );
}

/// After the door that started a 30 °/s pan slew on `address` was killed:
/// the `PS` that reached it after the slew came from gcud's group (its
/// dead-man), gcud says it issued it, and the gimbal rests where that stop
/// put it ([`assert_rests_where_stopped`]), however late a busy machine
/// delivered it.
pub fn assert_dead_man_stopped(gcud: &super::gcud::Gcud, address: &str) {
    wait_for_stop(gcud, address, GCUD_GROUP, "PS");
    gcud.wait_for_log(&format!("dead-man PS to {address}"));
    let (pan, _) = gcud.settled_position(address);
    let log = gcud.log();
    let moving = seconds_moving(&log, address, "PR", GCUD_GROUP, "PS");
    assert_rests_where_stopped(
        pan,
        speed_on_bus(&log, address, "PR"),
        moving,
        180.0,
        "gcud's dead-man stop",
    );
}

/// How long gimbal `address` was moving by the bus's own clock (the
/// simulated gimbal's `rx frame` lines in `log`): seconds from the first
/// `motion` command (`PR`, `TU`, ...) it received to the first `stop` from
/// source group `from` after it. A busy machine makes it longer; the
/// gimbal's travel follows it, not the test's clock.
pub fn seconds_moving(log: &str, address: &str, motion: &str, from: u8, stop: &str) -> f64 {
    let frames = super::frames_received(log, address);
    let times = super::frames_received_at(log, address);
    assert_eq!(frames.len(), times.len(), "every rx frame line has its time");
    let start = frames
        .iter()
        .position(|(_, p)| p == motion)
        .unwrap_or_else(|| panic!("{address} received no {motion}: {frames:?}"));
    let end = start
        + frames[start..]
            .iter()
            .position(|(source, p)| *source == from && p == stop)
            .unwrap_or_else(|| panic!("no {stop} from group {from} reached {address} after its {motion}: {frames:?}"));
    // A day's seconds: a run across midnight wraps once.
    (times[end].0 - times[start].0).rem_euclid(86_400.0)
}

/// The speed of the slew `motion` (`PR`, `TU`, ...) that gimbal `address`
/// received, as the bus shows it: the last proportional speed `SPn` (pan)
/// or `STn` (tilt) before its first `motion`, in °/s on the simulated
/// gimbal (speed n is its max_rate, 120 °/s, × (n + 1) / 16: Table 11,
/// `sagebrush_sim`). The door chose n; the test need not guess its rounding.
pub fn speed_on_bus(log: &str, address: &str, motion: &str) -> f64 {
    let frames = super::frames_received(log, address);
    let start = frames
        .iter()
        .position(|(_, p)| p == motion)
        .unwrap_or_else(|| panic!("{address} received no {motion}: {frames:?}"));
    let prefix = if motion.starts_with('P') { "SP" } else { "ST" };
    let n = frames[..start]
        .iter()
        .rev()
        .find_map(|(_, p)| u8::from_str_radix(p.strip_prefix(prefix)?, 16).ok())
        .unwrap_or_else(|| panic!("no {prefix}n before {address}'s {motion}: {frames:?}"));
    120.0 * f64::from(n + 1) / 16.0
}

/// A slew at about `dps` from rest at 0 toward its end of travel `end`
/// degrees away, stopped after `seconds` of motion on the bus
/// ([`seconds_moving`]): it rests about `dps × seconds` away (the ramps up
/// and down cancel), or at the end when that is past it; within 5° and a
/// quarter of the distance (the speed steps, the simulation's tick). A stop
/// that did not stop it (or a motion that ran on) rests elsewhere.
pub fn assert_rests_where_stopped(rest: f64, dps: f64, seconds: f64, end: f64, what: &str) {
    let expected = (dps * seconds).min(end);
    eprintln!(
        "{what}: {seconds:.2} s of motion on the bus at about {dps} °/s: expected {expected:.1}°, rests at {rest}°"
    );
    assert!(
        (rest.abs() - expected).abs() <= 5.0 + expected / 4.0,
        "{what}: the bus saw {seconds:.2} s of motion at about {dps} °/s, so it should rest about {expected:.1}° away; it rests at {rest}°"
    );
    assert!(rest != 0.0, "{what}: it never moved");
}

/// `bin --check --config path`, its output.
pub fn check(bin: &str, path: &Path) -> std::process::Output {
    Command::new(bin)
        .args(["--check", "--config"])
        .arg(path)
        .output()
        .expect("run --check")
}

/// The shipped unit `config/NAME` holds each of `lines` (trimmed) as a line.
pub fn assert_unit_has(name: &str, lines: &[&str]) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config").join(name);
    let unit = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    for line in lines {
        assert!(unit.lines().any(|l| l.trim() == *line), "the unit lacks {line:?}");
    }
}

/// A request of raw HTTP/1.1 (`request`, head and body) over TLS to
/// `addr` (`IP:PORT`), trusting only the certificate in `ca` (a door's
/// self-signed one: its names must hold the address): the whole answer.
pub fn https_raw(addr: &str, ca: &Path, request: &str) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async {
        let connector = sagebrush_host::tls::connector(ca, None).expect("trust the certificate");
        let tcp = tokio::net::TcpStream::connect(addr).await.expect("connect");
        let mut tls = tokio::time::timeout(HANG_GUARD, sagebrush_host::tls::connect(&connector, addr, tcp))
            .await
            .expect("a TLS handshake in time")
            .unwrap_or_else(|e| panic!("TLS with {addr}, trusting {}: {e}", ca.display()));
        tls.write_all(request.as_bytes()).await.expect("request");
        let mut answer = Vec::new();
        let _ = tokio::time::timeout(HANG_GUARD, tls.read_to_end(&mut answer)).await;
        String::from_utf8_lossy(&answer).into_owned()
    })
}

/// A request of raw HTTP/1.1 in plain TCP to `addr`: the whole answer
/// (empty when the connection closed without one).
pub fn plain_raw(addr: &str, request: &str) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let _ = s.write_all(request.as_bytes());
    let mut answer = Vec::new();
    let _ = s.read_to_end(&mut answer);
    String::from_utf8_lossy(&answer).into_owned()
}

/// Two pseudo-terminals whose masters are joined, as a null-modem cable:
/// what is written to one slave is read from the other.
pub struct NullModem {
    pub ends: (PathBuf, PathBuf),
    _relay: tokio::runtime::Runtime,
}

impl NullModem {
    pub fn new() -> Self {
        let relay = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .expect("runtime");
        let ends = relay.block_on(async {
            let mut a = sagebrush_host::pty::PtyMaster::open().expect("pty");
            let mut b = sagebrush_host::pty::PtyMaster::open().expect("pty");
            let ends = (a.slave_path().to_owned(), b.slave_path().to_owned());
            tokio::spawn(async move {
                let _ = tokio::io::copy_bidirectional(&mut a, &mut b).await;
            });
            ends
        });
        Self { ends, _relay: relay }
    }
}

impl Default for NullModem {
    fn default() -> Self {
        Self::new()
    }
}

/// A door's own metrics (`[metrics] listen`, issue 53): its `/metrics` at
/// `addr`, read by the series every door exports.
pub struct DoorMetrics {
    pub addr: String,
    pub door: &'static str,
}

/// One scrape of a door's `/metrics` (the OpenMetrics text).
pub struct Scrape {
    pub text: String,
    door: &'static str,
}

impl DoorMetrics {
    /// The metrics of `door`, listening where its log says.
    pub fn of(door: &Door) -> Self {
        Self {
            addr: format!("127.0.0.1:{}", door.port("metrics at /metrics")),
            door: door.name,
        }
    }

    pub fn scrape(&self) -> Scrape {
        let text = super::http_get(&self.addr, "/metrics");
        assert!(text.starts_with("HTTP/1.1 200"), "{text}");
        Scrape { text, door: self.door }
    }
}

impl Scrape {
    /// The value of the sample `name{door="…",LABEL}`.
    pub fn sample(&self, name: &str, label: &str) -> Option<f64> {
        let series = match label {
            "" => format!("sagebrush_door_{name}{{door=\"{}\"}}", self.door),
            l => format!("sagebrush_door_{name}{{door=\"{}\",{l}}}", self.door),
        };
        self.text
            .lines()
            .find_map(|l| l.strip_prefix(&series)?.strip_prefix(' ')?.parse().ok())
    }

    /// The clients' requests of `kind`.
    pub fn requests(&self, kind: &str) -> Option<f64> {
        self.sample("requests_total", &format!("kind=\"{kind}\""))
    }

    /// gcud's refusals by `reason` (its rule).
    pub fn refusals(&self, reason: &str) -> Option<f64> {
        self.sample("refusals_total", &format!("reason=\"{reason}\""))
    }

    /// The door's commands on the bus by `outcome`.
    pub fn outcomes(&self, outcome: &str) -> Option<f64> {
        self.sample("bus_outcomes_total", &format!("outcome=\"{outcome}\""))
    }

    /// The door's clients live now.
    pub fn sessions(&self) -> Option<f64> {
        self.sample("sessions", "")
    }
}

impl std::fmt::Display for Scrape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.text)
    }
}
