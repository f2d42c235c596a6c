//! Issue 49 end to end: gcud's TLS listener with client certificates
//! naming its `[[principal]]`s, through the real gcud with a simulated
//! gimbal (5.1.1) and the real `gimbalctl` (which also writes the PKI:
//! `gimbalctl tls init`), and `openssl s_client` as a client gcud's code
//! never saw. Whether a refused client reached the gimbal is read on the
//! bus side, in the simulated gimbal's own record of what it received,
//! each client aiming at its own pan angle so its frame would be told
//! apart. Only 127.0.0.1; every wait is a poll bounded by [`HANG_GUARD`],
//! and nothing asserts a speed (the ignored test prints latencies for the
//! closing note: `cargo test --release --test gcud_tls -- --ignored --nocapture`).

mod support;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sagebrush_protocol::{Address, Angle, Command as Cmd, FrameBuf, Position};
use support::gcud::Gcud;
use support::{HANG_GUARD, Output, eventually};

const GIMBAL: &str = "5.1.1";

/// The log line of a failed handshake (a plain client, no client
/// certificate, or one from another CA).
const HANDSHAKE_FAILED: &str = "connection refused: TLS handshake failed";
/// The log line of a certificate whose CN names no principal.
const UNKNOWN_CN: &str = "connection refused: its client certificate's CN names no [[principal]]";

/// The files `gimbalctl tls init` wrote into `dir`.
struct Pki {
    dir: PathBuf,
}

impl Pki {
    /// `gimbalctl tls init --dir DIR --host 127.0.0.1 --principal ...`,
    /// which must write the CA, gcud's and each principal's certificate.
    fn init(dir: PathBuf, principals: &[&str]) -> Self {
        let dir_arg = dir.display().to_string();
        let mut args = vec!["tls", "init", "--dir", &dir_arg, "--host", "127.0.0.1"];
        for p in principals {
            args.extend(["--principal", p]);
        }
        let out = support::gimbalctl(&args);
        assert_eq!(out.code, 0, "tls init: {out:?}");
        let pki = Self { dir };
        let mut names = vec!["ca", "gcud"];
        names.extend_from_slice(principals);
        for name in names {
            for ext in ["crt", "key"] {
                let file = pki.file(&format!("{name}.{ext}"));
                assert!(Path::new(&file).is_file(), "tls init wrote no {file}: {out:?}");
            }
        }
        pki
    }

    fn file(&self, name: &str) -> String {
        self.dir.join(name).display().to_string()
    }

    /// gimbalctl's flags trusting this CA, with `principal`'s certificate
    /// and key from `identity` when given.
    fn flags(&self, identity: Option<(&Pki, &str)>) -> Vec<String> {
        let mut flags = vec!["--tls-ca".to_owned(), self.file("ca.crt")];
        if let Some((pki, name)) = identity {
            flags.extend([
                "--tls-cert".to_owned(),
                pki.file(&format!("{name}.crt")),
                "--tls-key".to_owned(),
                pki.file(&format!("{name}.key")),
            ]);
        }
        flags
    }
}

/// gcud (group 5) with the simulated gimbal 5.1.1, control held 60 s,
/// principals alice (80) and bob (50), the TLS listener `operators`
/// (priority 100, client certificates from `pki` required) and the plain
/// loopback listener `clients`. `pki` has certificates for alice, bob and
/// carol (no principal); `other` is another CA's, with an alice of its own.
struct Stack {
    gcud: Gcud,
    pki: Pki,
    other: Pki,
    /// The TLS listener's address.
    tls: String,
    /// The plain listener's address.
    plain: String,
}

impl Stack {
    fn start() -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let pki = Pki::init(dir.path().join("pki"), &["alice", "bob", "carol"]);
        let other = Pki::init(dir.path().join("other-pki"), &["alice"]);
        let config = format!(
            "[gcu]\ngroup = 5\n[control]\nhold_ms = 60000\n[[port]]\nid = 1\nsimulate = [1]\n\
             [[principal]]\nname = \"alice\"\npriority = 80\n\
             [[principal]]\nname = \"bob\"\npriority = 50\n\
             [[link]]\nname = \"operators\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\npriority = 100\n\
             tls = {{ cert = \"{}\", key = \"{}\", client_ca = \"{}\" }}\n\
             [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n",
            pki.file("gcud.crt"),
            pki.file("gcud.key"),
            pki.file("ca.crt"),
        );
        let child = support::spawn_gcud(dir.path(), &config);
        let gcud = Gcud { child, dir };
        gcud.wait_for_log("gcud ready");
        gcud.wait_for_log("port open port=1");
        let tls = gcud.address("listening link=operators");
        let plain = gcud.address("listening link=clients");
        Self {
            gcud,
            pki,
            other,
            tls,
            plain,
        }
    }

    /// `gimbalctl --tcp tls://OPERATORS FLAGS ARGS`.
    fn ctl_tls(&self, flags: &[String], args: &[&str]) -> Output {
        let endpoint = format!("tls://{}", self.tls);
        let mut full = vec!["--tcp", endpoint.as_str()];
        full.extend(flags.iter().map(String::as_str));
        full.extend_from_slice(args);
        support::gimbalctl(&full)
    }

    /// `gimbalctl` over TLS as `name` of this stack's CA.
    fn as_principal(&self, name: &str, args: &[&str]) -> Output {
        self.ctl_tls(&self.pki.flags(Some((&self.pki, name))), args)
    }

    /// The payloads the gimbal received, by its own record.
    fn bus(&self) -> Vec<String> {
        self.gcud.received(GIMBAL).into_iter().map(|(_, p)| p).collect()
    }

    /// How many lines of gcud's log contain `text`.
    fn count(&self, text: &str) -> usize {
        self.gcud.log().matches(text).count()
    }

    /// Waits until gcud logged one more failed handshake than `before`,
    /// the newest saying `why`; returns the count.
    fn wait_refusal(&self, before: usize, why: &str) -> usize {
        eventually("gcud to log a refused handshake", || {
            self.count(HANDSHAKE_FAILED) > before
        });
        let lines = self.lines(HANDSHAKE_FAILED);
        let newest = lines.last().expect("a refusal");
        assert!(
            newest.contains("link=operators") && newest.contains(why),
            "{newest:?} should say {why:?}"
        );
        lines.len()
    }

    /// The log lines containing `text`.
    fn lines(&self, text: &str) -> Vec<String> {
        self.gcud
            .log()
            .lines()
            .filter(|l| l.contains(text))
            .map(str::to_owned)
            .collect()
    }
}

/// The wire payload of `goto PAN 0` (as the gimbal's log shows it).
fn goto_payload(pan: f32) -> String {
    let mut buf = [0u8; 32];
    let payload = goto(pan).encode(&mut buf).expect("encode").to_vec();
    String::from_utf8(payload).expect("ASCII")
}

fn goto(pan: f32) -> Cmd<'static> {
    Cmd::GoTo(Position::new(
        Angle::from_degrees(pan).expect("pan"),
        Angle::from_degrees(0.0).expect("tilt"),
    ))
}

/// A valid goto frame to 5.1.1 from the client group 0.
fn goto_frame(pan: f32) -> FrameBuf {
    FrameBuf::build(Address::new(5, 1, 1), 0, |b| goto(pan).encode(b).map(<[u8]>::len)).expect("frame")
}

/// Writes a valid goto frame in plain TCP to `addr` and reads until gcud
/// closes the connection; returns what gcud wrote before (a TLS alert at
/// most, never a protocol byte). A read that hangs fails.
fn plain_goto_is_closed(addr: &str, pan: f32) -> Vec<u8> {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    s.write_all(goto_frame(pan).as_bytes()).expect("write the frame");
    let mut got = Vec::new();
    let mut buf = [0u8; 256];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return got,
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return got,
            Err(e) => panic!("gcud did not close a plain client on its TLS listener ({e}); it wrote {got:?}"),
        }
    }
}

/// Point 2: a plain TCP client, a TLS client without a certificate, one
/// with another CA's certificate and carol (whose CN names no principal)
/// are each refused, the log naming the refusal (and carol's CN), and
/// none of their gotos reaches the gimbal, while alice's, sent last on
/// the same listener, does.
#[test]
fn plain_certless_foreign_and_unknown_clients_are_refused_and_reach_nothing_on_the_bus() {
    let s = Stack::start();
    let failed = s.count(HANDSHAKE_FAILED);

    let written = plain_goto_is_closed(&s.tls, 11.0);
    assert!(
        written.is_empty() || written[0] == 0x15,
        "gcud answers a plain client with a TLS alert at most: {written:?}"
    );
    let failed = s.wait_refusal(failed, "error=received corrupt message of type InvalidContentType");

    let certless = s.ctl_tls(&s.pki.flags(None), &["--to", GIMBAL, "goto", "12", "0"]);
    assert_ne!(
        certless.code,
        0,
        "no client certificate: {certless:?}\n{}",
        s.gcud.log()
    );
    let failed = s.wait_refusal(failed, "error=peer sent no certificates");

    let foreign = s.ctl_tls(
        &s.pki.flags(Some((&s.other, "alice"))),
        &["--to", GIMBAL, "goto", "13", "0"],
    );
    assert_ne!(foreign.code, 0, "another CA's alice: {foreign:?}\n{}", s.gcud.log());
    // Both CAs are named alike: the other's signature does not verify.
    s.wait_refusal(failed, "error=invalid peer certificate: BadSignature");

    let carol = s.as_principal("carol", &["--to", GIMBAL, "goto", "14", "0"]);
    assert_ne!(carol.code, 0, "carol is no principal: {carol:?}\n{}", s.gcud.log());
    let line = s.gcud.wait_for_log(UNKNOWN_CN);
    assert!(
        line.contains("cn=\"carol\"") && line.contains("link=operators"),
        "{line}"
    );

    // The listener works: alice's goto, sent last, arrives.
    let alice = s.as_principal("alice", &["--to", GIMBAL, "goto", "15", "0", "--wait"]);
    assert_eq!(alice.code, 0, "{alice:?}\n{}", s.gcud.log());
    let bus = s.bus();
    assert!(bus.contains(&goto_payload(15.0)), "alice's goto on the bus: {bus:?}");
    for pan in [11.0, 12.0, 13.0, 14.0] {
        assert!(
            !bus.contains(&goto_payload(pan)),
            "a refused client's goto (pan {pan}) reached the gimbal: {bus:?}\n{}",
            s.gcud.log()
        );
    }
    let log = s.gcud.log();
    assert!(
        !log.contains("carol via"),
        "no command of carol's was governed or audited:\n{log}"
    );
    for (who, out) in [("no certificate", certless), ("another CA", foreign), ("carol", carol)] {
        println!("{who}: exit {}: {}", out.code, out.stderr.trim());
    }
}

/// `openssl s_client` with stdin and stdout piped, its output collected
/// (stdout and stderr together) as it comes.
struct SClient {
    child: std::process::Child,
    output: Arc<Mutex<Vec<u8>>>,
}

impl SClient {
    /// Connects to `addr` trusting `ca`, presenting `identity` (certificate,
    /// key) when given; the server's certificate must name 127.0.0.1.
    /// `None` when openssl is missing (and the test may be skipped).
    fn spawn(addr: &str, ca: &str, identity: Option<(&str, &str)>) -> Option<Self> {
        let mut cmd = Command::new("openssl");
        cmd.args(["s_client", "-connect", addr, "-CAfile", ca]).args([
            "-verify_return_error",
            "-verify_ip",
            "127.0.0.1",
        ]);
        if let Some((cert, key)) = identity {
            cmd.args(["-cert", cert, "-key", key]);
        }
        let mut child = match cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
        {
            Ok(child) => child,
            Err(e) => {
                support::tool_missing(&format!("openssl is needed ({e}): apt-get install openssl"));
                return None;
            }
        };
        let output = Arc::new(Mutex::new(Vec::new()));
        let readers: [Box<dyn Read + Send>; 2] = [
            Box::new(child.stdout.take().expect("stdout")),
            Box::new(child.stderr.take().expect("stderr")),
        ];
        for mut reader in readers {
            let output = output.clone();
            std::thread::spawn(move || {
                let mut buf = [0u8; 1024];
                while let Ok(n @ 1..) = reader.read(&mut buf) {
                    output.lock().expect("lock").extend_from_slice(&buf[..n]);
                }
            });
        }
        Some(Self { child, output })
    }

    fn text(&self) -> String {
        String::from_utf8_lossy(&self.output.lock().expect("lock")).into_owned()
    }

    fn send(&mut self, bytes: &[u8]) {
        let stdin = self.child.stdin.as_mut().expect("stdin");
        stdin.write_all(bytes).expect("write to s_client");
        stdin.flush().expect("flush");
    }

    /// Waits (bounded) until s_client exits by itself; its exit code.
    fn wait(&mut self) -> Option<i32> {
        let started = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("wait for s_client") {
                return status.code();
            }
            assert!(started.elapsed() < HANG_GUARD, "s_client hung:\n{}", self.text());
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Closes stdin (s_client then closes the connection and exits).
    fn close(&mut self) -> Option<i32> {
        drop(self.child.stdin.take());
        self.wait()
    }
}

impl Drop for SClient {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Point 3: `openssl s_client` as alice connects, verifies gcud's
/// certificate (against the CA and 127.0.0.1) and drives the gimbal with a
/// frame of its own; without `-cert` it is refused.
#[test]
fn openssl_s_client_verifies_as_alice_and_is_refused_without_a_certificate() {
    let s = Stack::start();
    let ca = s.pki.file("ca.crt");
    let (cert, key) = (s.pki.file("alice.crt"), s.pki.file("alice.key"));
    let Some(mut alice) = SClient::spawn(&s.tls, &ca, Some((&cert, &key))) else {
        return;
    };
    eventually("s_client to verify gcud's certificate", || {
        alice.text().contains("Verify return code: 0 (ok)")
    });
    alice.send(goto_frame(31.0).as_bytes());
    eventually("alice's goto through s_client to reach the gimbal", || {
        s.bus().contains(&goto_payload(31.0))
    });
    let code = alice.close();
    let text = alice.text();
    assert_eq!(code, Some(0), "{text}");
    assert!(
        text.contains("CONNECTED(") && text.contains("Verification: OK"),
        "{text}"
    );
    let audit = format!("alice via operators: {} for 5.1.1: accepted", goto(31.0).in_words());
    assert!(s.count(&audit) == 1, "{audit:?} in:\n{}", s.gcud.log());
    assert_eq!(s.count(HANDSHAKE_FAILED), 0, "{}", s.gcud.log());

    let Some(mut nobody) = SClient::spawn(&s.tls, &ca, None) else {
        return;
    };
    // stdin stays open: s_client ends only on gcud's refusal.
    let code = nobody.wait();
    let text = nobody.text();
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("alert certificate required"), "{text}");
    s.gcud.wait_for_log(HANDSHAKE_FAILED);
}

/// Point 4: alice drives the gimbal over TLS (the goto arrives, the audit
/// line names her and the link); bob (50) is then refused with exit 23,
/// naming alice's hold, while she holds, and his refusal is audited, his
/// goto never on the bus.
#[test]
fn alice_drives_the_gimbal_over_tls_and_bob_is_refused_while_she_holds() {
    let s = Stack::start();
    let alice = s.as_principal("alice", &["--to", GIMBAL, "goto", "21", "0", "--wait"]);
    assert_eq!(alice.code, 0, "{alice:?}\n{}", s.gcud.log());
    let payload = goto_payload(21.0);
    assert!(s.bus().contains(&payload), "{:?}", s.bus());
    let accepted = s.gcud.wait_for_log(&format!(
        "alice via operators: {} for 5.1.1: accepted",
        goto(21.0).in_words()
    ));
    assert!(
        accepted.contains("principal=alice") && accepted.contains("via=\"operators\""),
        "{accepted}"
    );

    let bob = s.as_principal("bob", &["--to", GIMBAL, "goto", "22", "0"]);
    assert_eq!(bob.code, 23, "{bob:?}\n{}", s.gcud.log());
    assert!(
        bob.stderr.contains("held by alice via operators (priority 80)"),
        "{bob:?}"
    );
    let refused = s.gcud.wait_for_log(&format!(
        "bob via operators: {} for 5.1.1: refused, ",
        goto(22.0).in_words()
    ));
    assert!(
        refused.contains("principal=bob") && refused.contains("outcome="),
        "{refused}"
    );
    assert!(
        !s.bus().contains(&goto_payload(22.0)),
        "bob's goto reached the gimbal: {:?}",
        s.bus()
    );
    println!("{accepted}\n{refused}\nbob: {}", bob.stderr.trim());
}

/// `gcud --check --config DIR/NAME.toml` on `text`: exit code and stderr.
fn check(dir: &Path, name: &str, text: &str) -> (Option<i32>, String) {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write config");
    let out = Command::new(env!("CARGO_BIN_EXE_gcud"))
        .args(["--check", "--config"])
        .arg(&path)
        .stdin(Stdio::null())
        .output()
        .expect("run gcud --check");
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Point 5: `gcud --check` warns of a plain listener off loopback, and of
/// TLS without client certificates there; TLS with `client_ca` gets
/// neither warning (only that the listener is reachable from elsewhere).
#[test]
fn check_warns_of_a_plain_or_certificate_less_listener_off_loopback() {
    let dir = tempfile::tempdir().expect("temp dir");
    let pki = Pki::init(dir.path().join("pki"), &["alice"]);
    let base = "[gcu]\ngroup = 5\n[[principal]]\nname = \"alice\"\n\
                [[link]]\nname = \"field\"\nrole = \"client\"\nlisten = \"0.0.0.0:0\"\n";
    let (cert, key, ca) = (pki.file("gcud.crt"), pki.file("gcud.key"), pki.file("ca.crt"));

    let (code, stderr) = check(dir.path(), "plain.toml", base);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("gcud: warning:")
            && stderr.contains("plain TCP off loopback: whoever reaches 0.0.0.0:0 is link \"field\" (priority 50)")
            && stderr.contains("configure `tls = { cert, key, client_ca }`"),
        "{stderr}"
    );

    let no_ca = format!("{base}tls = {{ cert = \"{cert}\", key = \"{key}\" }}\n");
    let (code, stderr) = check(dir.path(), "no-ca.toml", &no_ca);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("tls without `client_ca`") && !stderr.contains("plain TCP"),
        "{stderr}"
    );

    let full = format!("{base}tls = {{ cert = \"{cert}\", key = \"{key}\", client_ca = \"{ca}\" }}\n");
    let (code, stderr) = check(dir.path(), "tls.toml", &full);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("not on loopback") && !stderr.contains("plain TCP") && !stderr.contains("without `client_ca`"),
        "{stderr}"
    );

    let loopback = base.replace("0.0.0.0:0", "127.0.0.1:0");
    let (code, stderr) = check(dir.path(), "loopback.toml", &loopback);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        !stderr.contains("warning"),
        "a plain loopback listener is fine: {stderr}"
    );
}

// ---- figures for the closing note (printed, never asserted) ---------------------

/// Sorted durations' p50 and p99, milliseconds.
fn percentiles(times: &mut [Duration]) -> (f64, f64) {
    times.sort();
    let at = |q: f64| times[((times.len() - 1) as f64 * q).round() as usize].as_secs_f64() * 1e3;
    (at(0.50), at(0.99))
}

/// Plain (0) and TLS as alice (1) side by side: `rows` of (what, [plain, TLS] samples).
fn print_figures(rows: &mut [(&str, [Vec<Duration>; 2])]) {
    println!("{:<44} {:>22} {:>22}", "", "plain p50 / p99 ms", "TLS p50 / p99 ms");
    for (what, [plain, tls]) in rows.iter_mut() {
        let (n, (p50, p99), (t50, t99)) = (plain.len(), percentiles(plain), percentiles(tls));
        println!("{what:<44} {p50:>10.3} / {p99:>9.3} {t50:>10.3} / {t99:>9.3}   (n = {n} each)");
    }
}

/// Connect (TCP, or TCP and the TLS handshake as the client sees it) and
/// connect plus the first `P?` answered (the server's verification of the
/// client certificate included), `n` new connections to each listener,
/// interleaved; then `n` `P?` round trips to the simulated gimbal on one
/// persistent connection to each, interleaved.
async fn measure(endpoints: [sagebrush_host::tls::Endpoint; 2], n: usize) -> Vec<(&'static str, [Vec<Duration>; 2])> {
    use sagebrush_client::client::GcudClient;
    let to = Address::new(5, 1, 1);
    let mut connect: [Vec<Duration>; 2] = Default::default();
    let mut first: [Vec<Duration>; 2] = Default::default();
    for i in 0..n {
        for k in [i % 2, 1 - i % 2] {
            let started = Instant::now();
            let mut client = GcudClient::connect(&endpoints[k], 0, |_| {}).await.expect("connect");
            connect[k].push(started.elapsed());
            client.position(to).await.expect("P?");
            first[k].push(started.elapsed());
        }
    }
    let mut clients = Vec::new();
    for endpoint in &endpoints {
        clients.push(GcudClient::connect(endpoint, 0, |_| {}).await.expect("connect"));
    }
    let mut query: [Vec<Duration>; 2] = Default::default();
    for i in 0..n {
        for k in [i % 2, 1 - i % 2] {
            let started = Instant::now();
            clients[k].position(to).await.expect("P?");
            query[k].push(started.elapsed());
        }
    }
    vec![
        ("connect (TLS: handshake, client side)", connect),
        ("connect + first P? answered", first),
        ("P? round trip, persistent connection", query),
    ]
}

/// Point 6: TLS handshake and per-command latency through gcud to the
/// simulated gimbal, plain and TLS interleaved in one run; printed only.
#[test]
#[ignore = "figures: cargo test --release --test gcud_tls -- --ignored --nocapture"]
fn tls_and_plain_latency_figures() {
    let s = Stack::start();
    let n: usize = std::env::var("GCUD_TLS_SAMPLES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(500);
    let tls = sagebrush_host::tls::Endpoint::parse(
        &format!("tls://{}", s.tls),
        Some(sagebrush_host::tls::ClientFiles {
            ca: s.pki.dir.join("ca.crt"),
            identity: Some((s.pki.dir.join("alice.crt"), s.pki.dir.join("alice.key"))),
        }),
    )
    .expect("endpoint");
    let plain = sagebrush_host::tls::Endpoint::from(s.plain.as_str());
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let mut rows = runtime.block_on(measure([plain, tls], n));
    println!("gcud {} with a simulated gimbal, {} cores", GIMBAL, num_cores());
    print_figures(&mut rows);
    let asked = s.bus().iter().filter(|p| p.as_str() == "P?").count();
    println!("P? received by the simulated gimbal: {asked} (of {} sent)", 4 * n);
    assert_eq!(s.count(HANDSHAKE_FAILED), 0, "{}", s.gcud.log());
}

fn num_cores() -> usize {
    std::thread::available_parallelism().map_or(0, usize::from)
}
