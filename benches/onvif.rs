//! `cargo bench --bench onvif`: gimbal-onvif measured with real processes
//! on 127.0.0.1 (issue 21's figures): `gimbalsim --tcp` <- a relay that
//! watches the bus bytes <- gcud (the relay is its `tcp` port) <-
//! gimbal-onvif <- SOAP requests signed with a UsernameToken digest, sent
//! over one keep-alive HTTP connection each (ureq):
//! 1. ContinuousMove: from the request's first byte to the first byte of
//!    its motion command (`PR`/`PL`) reaching the bus, p50/p99 of
//!    `ONVIF_BENCH_MOVES` moves (default 200), each followed by a Stop,
//!    timed likewise to its stop command's first byte; then the same on a
//!    bus paced at 9600 and at 115200 bit/s (gcud's port a pty, the instant
//!    device of `support::paced_device` on its other side;
//!    `ONVIF_BENCH_PACED_MOVES` moves, default 50), beside the line-time
//!    limit of the bytes the motion or stop needs (issue 35);
//! 2. GetStatus: latency p50/p99 of `ONVIF_BENCH_STATUS` sequential
//!    requests (default 2,000), then requests per second with 4 clients for
//!    3 s.
//!
//! Figures are printed, never asserted: the machines are shared and noisy.

#[path = "support/door.rs"]
mod door;
#[allow(dead_code)] // TRANSACTION_BYTES is for the bus benchmarks
mod support;

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use base64::Engine;
use base64::engine::general_purpose::STANDARD as B64;
use door::{MOTION_BYTES, STOP_BYTES, addr_in, env_count, log_line, report};
use sha1::{Digest, Sha1};
use support::percentile;

const USER: &str = "bench";
const PASSWORD: &str = "bench-secret";

static NONCE: AtomicU64 = AtomicU64::new(1);

/// A SOAP 1.2 request for `body`, signed with a fresh UsernameToken digest.
fn envelope(body: &str) -> String {
    let nonce = NONCE.fetch_add(1, Ordering::Relaxed).to_be_bytes();
    let created = time::OffsetDateTime::now_utc()
        .format(&time::format_description::well_known::Rfc3339)
        .expect("time");
    let mut h = Sha1::new();
    h.update(nonce);
    h.update(created.as_bytes());
    h.update(PASSWORD.as_bytes());
    format!(
        r#"<?xml version="1.0"?><s:Envelope xmlns:s="http://www.w3.org/2003/05/soap-envelope" xmlns:tptz="http://www.onvif.org/ver20/ptz/wsdl" xmlns:tt="http://www.onvif.org/ver10/schema"><s:Header><Security xmlns="http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-wssecurity-secext-1.0.xsd"><UsernameToken><Username>{USER}</Username><Password Type="http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-username-token-profile-1.0#PasswordDigest">{}</Password><Nonce>{}</Nonce><Created xmlns="http://docs.oasis-open.org/wss/2004/01/oasis-200401-wss-wssecurity-utility-1.0.xsd">{created}</Created></UsernameToken></Security></s:Header><s:Body>{body}</s:Body></s:Envelope>"#,
        B64.encode(h.finalize()),
        B64.encode(nonce)
    )
}

struct Client {
    agent: ureq::Agent,
    url: String,
    port: u16,
}

impl Client {
    fn new(port: u16) -> Self {
        Self {
            agent: ureq::Agent::config_builder()
                .timeout_global(Some(Duration::from_secs(30)))
                .build()
                .into(),
            url: format!("http://127.0.0.1:{port}/onvif/ptz_service"),
            port,
        }
    }

    fn call(&self, body: &str) -> String {
        let mut r = self
            .agent
            .post(&self.url)
            .header("Content-Type", "application/soap+xml")
            .send(envelope(body))
            .unwrap_or_else(|e| panic!("{body}: {e}"));
        r.body_mut().read_to_string().expect("body")
    }
}

const STATUS: &str = "<tptz:GetStatus><tptz:ProfileToken>profile1</tptz:ProfileToken></tptz:GetStatus>";
const STOP: &str = "<tptz:Stop><tptz:ProfileToken>profile1</tptz:ProfileToken></tptz:Stop>";

/// gimbal-onvif in front of `stack`'s gcud; its client, warmed up.
fn door(stack: &mut door::Stack) -> Client {
    let clients = stack.clients.clone();
    let onvif_log = stack.door(
        env!("CARGO_BIN_EXE_gimbal-onvif"),
        "gimbal-onvif",
        &format!(
            "gcud = \"{clients}\"\nmax_move_ms = 60000\n[discovery]\nenabled = false\n\
             [auth]\nrequests_per_s = 1000000\nburst = 1000000\n[[user]]\nname = \"{USER}\"\n\
             password = \"{PASSWORD}\"\nrole = \"operator\"\n[[gimbal]]\nname = \"bench\"\naddress = \"5.1.1\"\n\
             listen = \"127.0.0.1:0\"\n"
        ),
    );
    let port: u16 = addr_in(&log_line(&onvif_log, "gimbal=bench addr="))
        .rsplit(':')
        .next()
        .and_then(|p| p.parse().ok())
        .expect("port");
    let client = Client::new(port);
    // Warm up: the connection to gcud, the first poll.
    for _ in 0..20 {
        client.call(STATUS);
    }
    client
}

/// `moves` ContinuousMoves, each followed by a Stop, the pan speed
/// changing every move: from the request to the first byte of the
/// direction command that runs the pan at the speed asked for
/// ([`door::pan_at_speed`]), and from the Stop to its pan stop's.
fn moves(stack: &door::Stack, client: &Client, moves: usize) -> (Vec<Duration>, Vec<Duration>) {
    let (mut to_motion, mut to_stop) = (Vec::with_capacity(moves), Vec::with_capacity(moves));
    let quiet = Duration::from_millis(300);
    for i in 0..moves {
        stack.drain();
        let x = if i % 2 == 0 { "0.5" } else { "-0.8" };
        let body = format!(
            "<tptz:ContinuousMove><tptz:ProfileToken>profile1</tptz:ProfileToken><tptz:Velocity>\
             <tt:PanTilt x=\"{x}\" y=\"0\"/></tptz:Velocity><tptz:Timeout>PT5S</tptz:Timeout></tptz:ContinuousMove>"
        );
        let sent = Instant::now();
        client.call(&body);
        let heard = stack.heard(quiet);
        let at = door::pan_at_speed(&heard).unwrap_or_else(|| panic!("no pan motion on the bus: {heard:?}"));
        to_motion.push(at.saturating_duration_since(sent));
        let sent = Instant::now();
        client.call(STOP);
        let heard = stack.heard(quiet);
        let at = door::pan_stop(&heard).unwrap_or_else(|| panic!("no pan stop on the bus: {heard:?}"));
        to_stop.push(at.saturating_duration_since(sent));
    }
    (to_motion, to_stop)
}

fn main() {
    let mut stack = door::Stack::start(env!("CARGO_BIN_EXE_gimbalsim"), env!("CARGO_BIN_EXE_gcud"));
    let client = door(&mut stack);
    let n = env_count("ONVIF_BENCH_MOVES", 200);
    println!("1. to the first byte on the bus, gcud's port a TCP device server (gimbalsim):");
    let (to_motion, to_stop) = moves(&stack, &client, n);
    report("ContinuousMove -> first byte at speed", None, MOTION_BYTES, to_motion);
    report("Stop -> first stop byte", None, STOP_BYTES, to_stop);
    for baud in [9600, 115_200] {
        let mut paced = door::Stack::paced(env!("CARGO_BIN_EXE_gcud"), baud);
        let paced_client = door(&mut paced);
        println!("   on a bus paced at {baud} bit/s:");
        let (to_motion, to_stop) = moves(&paced, &paced_client, env_count("ONVIF_BENCH_PACED_MOVES", 50));
        report(
            "ContinuousMove -> first byte at speed",
            Some(baud),
            MOTION_BYTES,
            to_motion,
        );
        report("Stop -> first stop byte", Some(baud), STOP_BYTES, to_stop);
    }

    let n = env_count("ONVIF_BENCH_STATUS", 2000);
    let mut latencies = Vec::with_capacity(n);
    for _ in 0..n {
        let started = Instant::now();
        let text = client.call(STATUS);
        latencies.push(started.elapsed());
        assert!(text.contains("PTZStatus"), "{text}");
    }
    latencies.sort();
    println!(
        "GetStatus latency ({n} sequential): p50 {:.3} ms, p99 {:.3} ms",
        percentile(&latencies, 0.5).as_secs_f64() * 1e3,
        percentile(&latencies, 0.99).as_secs_f64() * 1e3
    );

    let window = Duration::from_secs(3);
    let started = Instant::now();
    let counts: Vec<usize> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..4)
            .map(|_| {
                s.spawn(|| {
                    let c = Client::new(client.port);
                    let mut done = 0;
                    while started.elapsed() < window {
                        c.call(STATUS);
                        done += 1;
                    }
                    done
                })
            })
            .collect();
        workers.into_iter().map(|w| w.join().expect("worker")).collect()
    });
    let total: usize = counts.iter().sum();
    println!(
        "GetStatus throughput (4 clients, keep-alive, {} s): {:.0} requests/s",
        window.as_secs(),
        total as f64 / started.elapsed().as_secs_f64()
    );
}
