//! gimbal-onvif under attack from the LAN (issue 31): the real gcud with a
//! simulated bus and the real gimbal-onvif in front of it, driven by raw
//! HTTP and UDP from this test (what an attacker sends is exactly what is
//! tested), everything on loopback (distinct peers are distinct 127.0.0.x
//! source addresses). What the gimbal did is read on the bus side. Every
//! loop is bounded; the time bounds asserted are the issue's acceptance
//! points (answered within 1 s, half-sent connections closed within the
//! header time-out), with margins; rates and memory are printed as figures.

mod support;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpStream, UdpSocket};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use sha1::{Digest, Sha1};
use support::door::{DOOR_GROUP, Door};
use support::gcud::Gcud;
use time::format_description::well_known::Rfc3339;

const MAST: &str = "5.1.1";
const NS_SOAP: &str = "http://www.w3.org/2003/05/soap-envelope";
const NS_PTZ: &str = "http://www.onvif.org/ver20/ptz/wsdl";
const NS_DEVICE: &str = "http://www.onvif.org/ver10/device/wsdl";
const NS_DISCOVERY: &str = "http://schemas.xmlsoap.org/ws/2005/04/discovery";
const PASSWORD_DIGEST: &str =
    "http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-username-token-profile-1.0#PasswordDigest";
const OPERATOR: (&str, &str) = ("op", "op-secret");
const VIEWER: (&str, &str) = ("viewer", "viewer-secret");

/// gimbal-onvif's configuration: `sections` (TOML tables such as `[http]`)
/// between the top-level keys and the users. Without a `[discovery]` of
/// its own, discovery is off (its default listens on 0.0.0.0 and
/// multicasts: never in a test).
fn config(gcud: &str, state: &Path, sections: &str) -> String {
    let discovery = if sections.contains("[discovery]") {
        ""
    } else {
        "[discovery]\nenabled = false\n"
    };
    format!(
        r#"gcud = "{gcud}"
source_group = {DOOR_GROUP}
state_file = "{}"
poll_ms = 100
{sections}
{discovery}
[[user]]
name = "admin"
password = "adm1n-secret"
role = "administrator"
[[user]]
name = "op"
password = "op-secret"
role = "operator"
[[user]]
name = "viewer"
password = "viewer-secret"
role = "user"
[[gimbal]]
name = "mast-1"
address = "{MAST}"
listen = "127.0.0.1:0"
"#,
        state.display()
    )
}

/// gcud with the mast gimbal and gimbal-onvif in front of it.
struct Stack {
    /// Declared first: stopped before gcud.
    onvif: Door,
    gcud: Gcud,
    device: SocketAddr,
    discovery: Option<SocketAddr>,
}

impl Stack {
    /// Starts both; gimbal-onvif with `sections` and, when `nofile` is
    /// given, that descriptor limit (the unit's LimitNOFILE).
    fn start(sections: &str, nofile: Option<u64>) -> Self {
        let gcud = support::door::start_gcud();
        let mut onvif = Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif"));
        let text = config(&gcud.clients(), &onvif.dir.path().join("presets.toml"), sections);
        with_nofile(nofile, || onvif.start(&text));
        let device = SocketAddr::from(([127, 0, 0, 1], onvif.port("gimbal=mast-1 addr=")));
        let discovery = sections
            .contains("listen = \"127.0.0.1:0\"")
            .then(|| SocketAddr::from(([127, 0, 0, 1], onvif.port("WS-Discovery listening"))));
        Self {
            onvif,
            gcud,
            device,
            discovery,
        }
    }

    fn log(&self) -> String {
        self.onvif.log()
    }

    /// gimbal-onvif's process id, found by its configuration's path.
    fn pid(&self) -> u32 {
        let config = self.onvif.dir.path().join("gimbal-onvif.toml");
        let config = config.to_string_lossy();
        for entry in std::fs::read_dir("/proc").expect("/proc") {
            let Ok(entry) = entry else { continue };
            let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
            if String::from_utf8_lossy(&cmdline).contains(config.as_ref()) {
                return pid;
            }
        }
        panic!("no gimbal-onvif process runs on {config}")
    }

    /// gimbal-onvif's resident memory, KiB (/proc/PID/status VmRSS).
    fn rss_kib(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.pid())).expect("status");
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .expect("VmRSS")
    }

    /// Motion commands the mast gimbal received from gimbal-onvif.
    fn motions(&self) -> usize {
        self.gcud
            .received(MAST)
            .iter()
            .filter(|(from, p)| *from == DOOR_GROUP && matches!(p.as_str(), "PR" | "PL" | "TU" | "TD"))
            .count()
    }
}

/// Runs `f` with the soft RLIMIT_NOFILE at `limit` (what a child spawned
/// meanwhile inherits), then puts the old one back for this process.
fn with_nofile(limit: Option<u64>, f: impl FnOnce()) {
    use nix::sys::resource::{Resource, getrlimit, setrlimit};
    let Some(limit) = limit else { return f() };
    let (soft, hard) = getrlimit(Resource::RLIMIT_NOFILE).expect("getrlimit");
    setrlimit(Resource::RLIMIT_NOFILE, limit.min(hard), hard).expect("setrlimit");
    f();
    setrlimit(Resource::RLIMIT_NOFILE, soft, hard).expect("setrlimit back");
}

/// This process may open what the floods need.
fn raise_nofile(at_least: u64) {
    use nix::sys::resource::{Resource, getrlimit, setrlimit};
    let (soft, hard) = getrlimit(Resource::RLIMIT_NOFILE).expect("getrlimit");
    assert!(hard >= at_least, "RLIMIT_NOFILE hard limit {hard} < {at_least}");
    if soft < at_least {
        setrlimit(Resource::RLIMIT_NOFILE, hard, hard).expect("setrlimit");
    }
}

fn created_now() -> String {
    let now = time::OffsetDateTime::now_utc();
    now.replace_nanosecond(0).unwrap_or(now).format(&Rfc3339).expect("time")
}

/// A WS-Security UsernameToken header (PasswordDigest) for `user`.
fn security(user: (&str, &str), nonce: &[u8], created: &str) -> String {
    let b64 = base64::engine::general_purpose::STANDARD;
    let mut h = Sha1::new();
    h.update(nonce);
    h.update(created.as_bytes());
    h.update(user.1.as_bytes());
    format!(
        r#"<Security xmlns="http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-wssecurity-secext-1.0.xsd"><UsernameToken><Username>{}</Username><Password Type="{PASSWORD_DIGEST}">{}</Password><Nonce>{}</Nonce><Created xmlns="http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-wssecurity-utility-1.0.xsd">{created}</Created></UsernameToken></Security>"#,
        user.0,
        b64.encode(h.finalize()),
        b64.encode(nonce)
    )
}

/// A SOAP envelope with `header` around `body`.
fn envelope(header: &str, body: &str) -> String {
    format!(r#"<s:Envelope xmlns:s="{NS_SOAP}"><s:Header>{header}</s:Header><s:Body>{body}</s:Body></s:Envelope>"#)
}

fn get_status() -> String {
    format!(r#"<GetStatus xmlns="{NS_PTZ}"><ProfileToken>profile1</ProfileToken></GetStatus>"#)
}

fn stop() -> String {
    format!(r#"<Stop xmlns="{NS_PTZ}"><ProfileToken>profile1</ProfileToken><PanTilt>true</PanTilt></Stop>"#)
}

fn continuous_move() -> String {
    format!(
        r#"<ContinuousMove xmlns="{NS_PTZ}"><ProfileToken>profile1</ProfileToken><Velocity><PanTilt xmlns="http://www.onvif.org/ver10/schema" x="0.5" y="0"/></Velocity><Timeout>PT5S</Timeout></ContinuousMove>"#
    )
}

/// A kept-alive HTTP/1.1 connection to a device, from `from` (a loopback
/// address of the test's choosing: a peer of its own).
struct Http {
    reader: BufReader<TcpStream>,
}

/// One answer: status and body.
struct Answer {
    status: u16,
    body: String,
}

impl Answer {
    /// Whether the answer is a SOAP fault with `subcode`.
    fn fault(&self, subcode: &str) -> bool {
        self.body.contains("<s:Fault>") && self.body.contains(&format!("<s:Value>{subcode}</s:Value>"))
    }
}

fn connect_from(from: Ipv4Addr, to: SocketAddr) -> TcpStream {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).expect("socket");
    socket.bind(&SocketAddr::from((from, 0)).into()).expect("bind");
    socket.connect(&to.into()).expect("connect");
    let stream: TcpStream = socket.into();
    stream.set_read_timeout(Some(Duration::from_secs(40))).expect("timeout");
    stream
}

impl Http {
    fn connect(from: Ipv4Addr, to: SocketAddr) -> Self {
        let stream = connect_from(from, to);
        stream.set_nodelay(true).expect("nodelay");
        Self {
            reader: BufReader::new(stream),
        }
    }

    /// POSTs `body` to `path` with `host` as the Host header.
    fn post_as(&mut self, host: &str, path: &str, body: &str) -> Answer {
        let request = format!(
            "POST {path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/soap+xml; charset=utf-8\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        );
        self.reader.get_mut().write_all(request.as_bytes()).expect("send");
        self.read_answer()
    }

    fn post(&mut self, body: &str) -> Answer {
        self.post_as("127.0.0.1", "/onvif/ptz_service", body)
    }

    fn read_answer(&mut self) -> Answer {
        let mut line = String::new();
        self.reader.read_line(&mut line).expect("status line");
        let status = line
            .split_whitespace()
            .nth(1)
            .and_then(|s| s.parse().ok())
            .unwrap_or_else(|| panic!("no HTTP status line: {line:?}"));
        let mut length = 0usize;
        loop {
            line.clear();
            self.reader.read_line(&mut line).expect("header");
            let l = line.trim_end();
            if l.is_empty() {
                break;
            }
            if let Some((k, v)) = l.split_once(':') {
                if k.eq_ignore_ascii_case("content-length") {
                    length = v.trim().parse().expect("content-length");
                }
            }
        }
        let mut body = vec![0u8; length];
        self.reader.read_exact(&mut body).expect("body");
        Answer {
            status,
            body: String::from_utf8_lossy(&body).into_owned(),
        }
    }
}

/// Whether `xml` is a well-formed XML document by a strict parser
/// (Python's expat through xml.etree), and its error when not.
fn well_formed(xml: &str) -> Result<(), String> {
    let code = "import sys, xml.etree.ElementTree as E; E.fromstring(sys.stdin.buffer.read())";
    python_on(&["-c".as_ref(), code.as_ref()], xml)
}

/// The clients' Python run with `args` and `input` on stdin: Ok, or its
/// stderr when it fails.
fn python_on(args: &[&std::ffi::OsStr], input: &str) -> Result<(), String> {
    let mut child = Command::new(support::door::python())
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(input.as_bytes())
        .expect("write");
    let out = child.wait_with_output().expect("python3");
    if out.status.success() {
        Ok(())
    } else {
        Err(String::from_utf8_lossy(&out.stderr).into_owned())
    }
}

fn assert_well_formed(what: &str, xml: &str) {
    if let Err(e) = well_formed(xml) {
        panic!("{what}: not well-formed XML: {e}\n{xml}");
    }
}

/// `xml`, a SOAP answer of the device, is valid against the ONVIF XSDs
/// (`tests/onvif/schema.py`, lxml over the schemas onvif-zeep-async ships).
fn assert_schema_valid(what: &str, xml: &str) {
    assert_well_formed(what, xml);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/onvif/schema.py");
    if let Err(e) = python_on(&[script.as_os_str()], xml) {
        panic!("{what}: invalid against the ONVIF XSDs: {e}\n{xml}");
    }
}

#[test]
fn half_sent_requests_neither_starve_get_status_and_stop_nor_outlive_the_header_timeout() {
    raise_nofile(4096);
    // The shipped unit's LimitNOFILE=1024 and the default [http] bounds
    // (512 in all, 64 per peer, header time-out 5 s).
    let stack = Stack::start("", Some(1024));
    let rss_before = stack.rss_kib();
    // 1,100 half-sent requests from 8 hosts (127.0.0.2..=9).
    let half = b"POST /onvif/ptz_service HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 400\r\n";
    let mut flood: Vec<(TcpStream, Instant)> = (0..1100)
        .map(|i| {
            let mut s = connect_from(Ipv4Addr::new(127, 0, 0, 2 + (i % 8) as u8), stack.device);
            let _ = s.write_all(half);
            (s, Instant::now())
        })
        .collect();
    // Every slot is held once the flood's connections are past the age a
    // newcomer may evict (1 s).
    std::thread::sleep(Duration::from_millis(1200));
    let rss_flood = stack.rss_kib();
    let mut client = Http::connect(Ipv4Addr::LOCALHOST, stack.device);
    let started = Instant::now();
    let status = client.post(&envelope(
        &security(OPERATOR, b"flood-status", &created_now()),
        &get_status(),
    ));
    let status_took = started.elapsed();
    assert_eq!(
        status.status,
        200,
        "GetStatus under the flood: {}\n{}",
        status.body,
        stack.log()
    );
    assert!(status.body.contains("GetStatusResponse"), "{}", status.body);
    let started = Instant::now();
    let stopped = client.post(&envelope(&security(OPERATOR, b"flood-stop", &created_now()), &stop()));
    let stop_took = started.elapsed();
    assert_eq!(stopped.status, 200, "Stop under the flood: {}", stopped.body);
    // Served, not starved: the issue's figure is 1 s (printed below); the
    // bound is ten times that, so that a busy machine does not fail it.
    assert!(
        status_took < Duration::from_secs(10) && stop_took < Duration::from_secs(10),
        "GetStatus took {status_took:?}, Stop {stop_took:?}: starved by the flood"
    );
    // Each half-sent connection is closed (refused at accept, evicted, or
    // at the header time-out) within the time-out of its last byte, plus
    // a generous margin for a loaded machine.
    let deadline = Duration::from_secs(5) + Duration::from_secs(20);
    let mut latest = Duration::ZERO;
    for (s, sent) in &mut flood {
        s.set_read_timeout(Some(
            deadline.saturating_sub(sent.elapsed()).max(Duration::from_millis(1)),
        ))
        .expect("timeout");
        let mut byte = [0u8; 1];
        match s.read(&mut byte) {
            Ok(0) | Err(_) if sent.elapsed() < deadline => latest = latest.max(sent.elapsed()),
            other => panic!(
                "a half-sent connection was still open {:?} after its last byte: {other:?}",
                sent.elapsed()
            ),
        }
    }
    let rss_after = stack.rss_kib();
    eprintln!(
        "FIGURES half-open flood: gimbal-onvif VmRSS {rss_before} KiB before, {rss_flood} KiB under 1,100 half-sent requests, {rss_after} KiB after; GetStatus answered in {status_took:?}, Stop in {stop_took:?}; the last half-sent connection closed {latest:?} after its last byte"
    );
    drop(flood);
    assert!(
        stack.log().contains("connection refused"),
        "refusals are logged: {}",
        stack.log()
    );
}

/// `count` GetStatus requests from the read-only user on one kept-alive
/// connection, each with a nonce of its own: (accepted, refused by the
/// given fault, time taken).
fn viewer_flood(device: SocketAddr, count: u32, refused_by: &str) -> (u32, u32, Duration) {
    let mut http = Http::connect(Ipv4Addr::new(127, 0, 0, 3), device);
    let body = get_status();
    let (mut accepted, mut refused) = (0, 0);
    let started = Instant::now();
    let mut created = created_now();
    for i in 0..count {
        if i % 4096 == 0 {
            created = created_now();
        }
        let answer = http.post(&envelope(&security(VIEWER, &i.to_be_bytes(), &created), &body));
        match answer.status {
            200 => accepted += 1,
            _ if answer.fault(refused_by) => refused += 1,
            other => panic!("request {i}: HTTP {other}, not {refused_by}: {}", answer.body),
        }
    }
    (accepted, refused, started.elapsed())
}

#[test]
fn a_read_only_flood_of_65536_requests_never_makes_a_captured_operator_request_replayable() {
    // Rates out of the way, the default nonce memory (65,536): the flood
    // fills it, and the door refuses rather than forgetting.
    let stack = Stack::start("[auth]\nrequests_per_s = 1000000\nburst = 1000000\n", None);
    let captured = security(OPERATOR, b"captured operator nonce", &created_now());
    let mut op = Http::connect(Ipv4Addr::LOCALHOST, stack.device);
    assert_eq!(op.post(&envelope(&captured, &stop())).status, 200);
    let (accepted, refused, took) = viewer_flood(stack.device, 65_536, "ter:TooManyRequests");
    eprintln!(
        "FIGURES GetStatus over one kept-alive loopback connection: {:.0} requests/s ({accepted} answered, {refused} refused with a full nonce memory, in {took:?})",
        f64::from(accepted + refused) / took.as_secs_f64()
    );
    assert_eq!(
        accepted, 65_535,
        "the memory holds 65,536 nonces, the operator's one of them"
    );
    assert_eq!(refused, 1);
    let motions = stack.motions();
    // The operator's kept-alive connection sat idle past the header
    // time-out meanwhile (and was closed): the replay comes on a new one.
    let mut op = Http::connect(Ipv4Addr::LOCALHOST, stack.device);
    let replay = op.post(&envelope(&captured, &continuous_move()));
    assert_ne!(
        replay.status, 200,
        "the replayed operator token was accepted: {}",
        replay.body
    );
    assert!(replay.fault("ter:NotAuthorized"), "{}", replay.body);
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(stack.motions(), motions, "the replay moved the gimbal");
}

#[test]
fn a_read_only_user_past_its_rate_is_refused_and_the_replay_still_is() {
    // The default rate: 20 a second, a burst of 40.
    let stack = Stack::start("", None);
    let captured = security(OPERATOR, b"captured operator nonce", &created_now());
    let mut op = Http::connect(Ipv4Addr::LOCALHOST, stack.device);
    assert_eq!(op.post(&envelope(&captured, &stop())).status, 200);
    let (accepted, refused, took) = viewer_flood(stack.device, 2000, "ter:TooManyRequests");
    let mut op = Http::connect(Ipv4Addr::LOCALHOST, stack.device);
    let allowed = 40.0 + 20.0 * took.as_secs_f64();
    assert!(
        f64::from(accepted) <= allowed + 1.0,
        "{accepted} answered in {took:?}: at most {allowed:.0} by [auth]"
    );
    assert!(accepted >= 40 && refused > 0, "{accepted} answered, {refused} refused");
    let replay = op.post(&envelope(&captured, &continuous_move()));
    assert!(replay.fault("ter:NotAuthorized"), "{}", replay.body);
    // The operator has a bucket of its own: not starved by the viewer.
    let fresh = op.post(&envelope(&security(OPERATOR, b"fresh", &created_now()), &get_status()));
    assert_eq!(fresh.status, 200, "{}", fresh.body);
}

/// A WS-Discovery Probe with MessageID `id`, its Probe in namespace `ns`.
fn probe(id: u32, ns: &str) -> String {
    format!(
        r#"<e:Envelope xmlns:e="{NS_SOAP}" xmlns:w="http://schemas.xmlsoap.org/ws/2004/08/addressing" xmlns:d="{ns}"><e:Header><w:MessageID>uuid:{id}</w:MessageID><w:To>urn:schemas-xmlsoap-org:ws:2005:04:discovery</w:To><w:Action>{NS_DISCOVERY}/Probe</w:Action></e:Header><e:Body><d:Probe/></e:Body></e:Envelope>"#
    )
}

/// Reads every datagram waiting on `socket` (non-blocking): their sizes.
fn drain(socket: &UdpSocket, sizes: &mut Vec<usize>) {
    let mut buf = [0u8; 65_536];
    while let Ok(n) = socket.recv(&mut buf) {
        sizes.push(n);
    }
}

#[test]
fn discovery_answers_a_flood_at_its_rate_only_and_never_a_malformed_probe() {
    let stack = Stack::start(
        "[discovery]\nlisten = \"127.0.0.1:0\"\nanswers_per_s = 20\nanswers_per_source_per_s = 5\n",
        None,
    );
    let to = stack.discovery.expect("discovery");
    // 20,000 probes in 2 s from 10 sources (127.0.0.11..=20).
    let sources: Vec<UdpSocket> = (11..=20)
        .map(|last| {
            let s = UdpSocket::bind((Ipv4Addr::new(127, 0, 0, last), 0)).expect("bind");
            s.connect(to).expect("connect");
            s.set_nonblocking(true).expect("nonblocking");
            s
        })
        .collect();
    let mut answers: Vec<Vec<usize>> = vec![Vec::new(); sources.len()];
    let flood = probe(1, NS_DISCOVERY);
    let started = Instant::now();
    for ms in 0..2000u32 {
        for (i, s) in sources.iter().enumerate() {
            let _ = s.send(flood.as_bytes());
            if ms % 50 == 0 {
                drain(s, &mut answers[i]);
            }
        }
        let next = Duration::from_millis(u64::from(ms) + 1);
        if let Some(wait) = next.checked_sub(started.elapsed()) {
            std::thread::sleep(wait);
        }
    }
    std::thread::sleep(Duration::from_millis(300));
    for (i, s) in sources.iter().enumerate() {
        drain(s, &mut answers[i]);
    }
    let took = started.elapsed().as_secs_f64();
    let total: usize = answers.iter().map(Vec::len).sum();
    let biggest = answers.iter().flatten().max().copied().unwrap_or(0);
    eprintln!(
        "FIGURES discovery under 20,000 probes in {took:.1} s from 10 sources: {total} answers ({:.1}/s; per source {:?}), largest answer {biggest} bytes to a {}-byte probe",
        total as f64 / took,
        answers.iter().map(Vec::len).collect::<Vec<_>>(),
        flood.len()
    );
    // One gimbal: one datagram per answer. The buckets hold a second's worth.
    assert!(total > 0, "no probe answered at all");
    assert!(
        total as f64 <= 20.0 + 20.0 * took + 1.0,
        "{total} answers in {took:.1} s: over answers_per_s = 20"
    );
    for (i, a) in answers.iter().enumerate() {
        assert!(
            a.len() as f64 <= 5.0 + 5.0 * took + 1.0,
            "source {i}: {} answers in {took:.1} s: over answers_per_source_per_s = 5",
            a.len()
        );
    }
    assert!(biggest < 4096, "an answer of {biggest} bytes");
    // A fresh source, buckets refilled: malformed and foreign probes get
    // nothing, then a good probe from it is answered (so the silence was
    // not the rate).
    std::thread::sleep(Duration::from_millis(1100));
    let s = UdpSocket::bind((Ipv4Addr::new(127, 0, 0, 21), 0)).expect("bind");
    s.connect(to).expect("connect");
    s.set_read_timeout(Some(Duration::from_millis(700))).expect("timeout");
    let mut buf = [0u8; 65_536];
    for bad in [
        probe(2, "http://schemas.xmlsoap.org/ws/2005/04/other"),
        probe(3, NS_DISCOVERY).replace("</e:Body>", ""),
        "<Probe/>".to_owned(),
        probe(4, NS_DISCOVERY).replace("uuid:4", &"x".repeat(300)),
    ] {
        s.send(bad.as_bytes()).expect("send");
        assert!(
            s.recv(&mut buf).is_err(),
            "a malformed or foreign probe was answered: {bad}"
        );
    }
    // The good probe's answer may be slow on a busy machine: waited for as
    // long as a hang, and it must relate to this probe (a late answer to
    // one of the bad ones above would name theirs).
    s.send(probe(5, NS_DISCOVERY).as_bytes()).expect("send");
    s.set_read_timeout(Some(support::HANG_GUARD)).expect("timeout");
    let n = s.recv(&mut buf).expect("a well-formed probe is answered");
    let answer = String::from_utf8_lossy(&buf[..n]);
    assert_well_formed("ProbeMatches", &answer);
    assert!(
        answer.contains(">uuid:5<"),
        "the answer relates to the good probe: {answer}"
    );
}

#[test]
fn hostile_preset_names_and_host_headers_never_make_ill_formed_xml() {
    if !support::door::onvif_client_available() {
        return;
    }
    let gcud = support::door::start_gcud();
    let mut onvif = Door::new("gimbal-onvif", env!("CARGO_BIN_EXE_gimbal-onvif"));
    // A name with a control character already in the state file (as an
    // older gimbal-onvif could write it): shown, never breaking the XML.
    let state = onvif.dir.path().join("presets.toml");
    std::fs::write(&state, "[gimbal.mast-1]\n\"7\" = \"old\\u0001name <&>\"\n").expect("state");
    onvif.start(&config(&gcud.clients(), &state, ""));
    let device = SocketAddr::from(([127, 0, 0, 1], onvif.port("gimbal=mast-1 addr=")));
    let mut http = Http::connect(Ipv4Addr::LOCALHOST, device);
    let mut n = 0u32;
    let mut signed = |body: &str| {
        n += 1;
        envelope(
            &security(("admin", "adm1n-secret"), &n.to_be_bytes(), &created_now()),
            body,
        )
    };
    let set = |name: &str| {
        format!(
            r#"<SetPreset xmlns="{NS_PTZ}"><ProfileToken>profile1</ProfileToken><PresetName>{name}</PresetName></SetPreset>"#
        )
    };
    let control = http.post(&signed(&set("gate&#x1B;[31m")));
    assert_schema_valid("SetPreset with a control character", &control.body);
    assert!(control.fault("ter:InvalidPresetName"), "{}", control.body);
    // A right-to-left override makes "gate\u{202E}2etag" read as another
    // name on an operator's screen: refused too (issue 49).
    let bidi = http.post(&signed(&set("gate&#x202E;2etag")));
    assert_schema_valid("SetPreset with a bidi override", &bidi.body);
    assert!(bidi.fault("ter:InvalidPresetName"), "{}", bidi.body);
    assert!(bidi.body.contains("U+202E"), "{}", bidi.body);
    let markup = http.post(&signed(&set("&lt;/tt:Name&gt;&lt;x&gt; &amp; &quot;q&quot;")));
    assert_eq!(markup.status, 200, "{}", markup.body);
    let presets = http.post(&signed(&format!(
        r#"<GetPresets xmlns="{NS_PTZ}"><ProfileToken>profile1</ProfileToken></GetPresets>"#
    )));
    assert_schema_valid("GetPresets", &presets.body);
    assert!(
        presets.body.contains("&lt;/tt:Name&gt;&lt;x&gt; &amp;"),
        "{}",
        presets.body
    );
    assert!(
        presets.body.contains("old\u{FFFD}name &lt;&amp;&gt;"),
        "{}",
        presets.body
    );
    for host in ["a\"><x/>", "127.0.0.1:1/</tt:XAddr>", "h&amp;x", "[::1", "evil:99999"] {
        for op in ["GetCapabilities", "GetServices", "GetNetworkInterfaces"] {
            let body = signed(&format!(
                r#"<{op} xmlns="{NS_DEVICE}"><IncludeCapability>false</IncludeCapability></{op}>"#
            ));
            let answer = http.post_as(host, "/onvif/device_service", &body);
            assert_eq!(answer.status, 200, "{op} with Host {host:?}: {}", answer.body);
            assert_schema_valid(&format!("{op} with Host {host:?}"), &answer.body);
            if op != "GetNetworkInterfaces" {
                assert!(
                    answer.body.contains(&format!("http://{device}/onvif/")),
                    "{op} with Host {host:?} names the device's own address: {}",
                    answer.body
                );
            }
        }
    }
}

#[test]
fn a_failed_login_is_logged_with_the_peers_address() {
    let stack = Stack::start("", None);
    let mut http = Http::connect(Ipv4Addr::new(127, 0, 0, 7), stack.device);
    let wrong = http.post(&envelope(
        &security(("op", "guess"), b"n1", &created_now()),
        &get_status(),
    ));
    assert_eq!(wrong.status, 401, "{}", wrong.body);
    let line = support::wait_for_log_line(&stack.onvif.log_path(), "failed login");
    assert!(line.contains("peer=127.0.0.7:"), "{line}");
    assert!(line.contains("user=\"op\""), "{line}");
    // A flood of them is one line per 10 s per peer.
    for i in 0..50u32 {
        http.post(&envelope(
            &security(("op", "guess"), &i.to_be_bytes(), &created_now()),
            &get_status(),
        ));
    }
    let log = stack.log();
    assert_eq!(log.lines().filter(|l| l.contains("failed login")).count(), 1, "{log}");
}

#[test]
fn check_refuses_a_state_file_whose_folder_is_missing_naming_file_and_key() {
    let dir = tempfile::tempdir().expect("temp dir");
    let state = dir.path().join("missing").join("presets.toml");
    let path = dir.path().join("o.toml");
    std::fs::write(&path, config("127.0.0.1:4001", &state, "")).expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-onvif"), &path);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("{}:3:14: state_file: {}", path.display(), state.display())),
        "{err}"
    );
    assert!(err.contains("does not exist"), "{err}");
    std::fs::create_dir(dir.path().join("missing")).expect("mkdir");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-onvif"), &path);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
}
