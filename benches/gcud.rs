//! `cargo bench --bench gcud`: the daemon measured with real processes on
//! 127.0.0.1, in one run:
//! 1. latency of a `P?` transaction client -> gcud -> simulator and back,
//!    beside the same client talking to the simulator directly (p50/p99 and
//!    the latency gcud adds);
//! 2. transactions per second with many ports busy at once;
//! 3. resident memory and CPU of gcud with 254 idle ports;
//! 4. with `GCUD_BENCH_SOAK=SECONDS`: a soak of N clients (`GCUD_SOAK_CLIENTS`,
//!    default 32) on M ports (`GCUD_SOAK_PORTS`, default 4) that reconnect
//!    every 50 exchanges (connection churn), printing RSS and `/metrics`
//!    size before and after, each client's share (Jain's fairness index)
//!    and every command's outcome, as the clients saw it and as gcud counted.
//!
//! Figures are printed, never asserted: the machines are shared and noisy.
//! `GCUD_BENCH_SAMPLES` sets the samples per latency series (default 2000).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Command as Cmd, Event, FrameBuf, Framer};

/// A child process killed on drop.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn spawn_sim_tcp(args: &[&str]) -> (Proc, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gimbalsim"))
        .args(["--tcp", "127.0.0.1:0", "--log", "warn"])
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn gimbalsim");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("sim address");
    (Proc(child), line.trim().to_owned())
}

fn spawn_gcud(config: &str, dir: &tempfile::TempDir) -> (Proc, String) {
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, config).expect("config");
    let log_path = dir.path().join("gcud.log");
    let child = Proc(
        Command::new(env!("CARGO_BIN_EXE_gcud"))
            .arg("--config")
            .arg(&path)
            .env("RUST_LOG", "info,sagebrush_sim=warn")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log_path).expect("log"))
            .spawn()
            .expect("spawn gcud"),
    );
    let started = Instant::now();
    loop {
        let log = std::fs::read_to_string(&log_path).unwrap_or_default();
        if log.contains("gcud ready") {
            let addr = log
                .lines()
                .find(|l| l.contains("listening link=clients"))
                .and_then(|l| l.split("addr=").nth(1))
                .map(|a| a.split_whitespace().next().unwrap_or_default().to_owned())
                .expect("client listener address");
            return (child, addr);
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "gcud did not start:\n{log}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A wire-level client doing one `P?` exchange at a time (ACK, then the result, ACKed).
struct Client {
    stream: TcpStream,
    framer: Framer,
    request: FrameBuf,
}

impl Client {
    fn connect(addr: &str, dest: Address) -> Self {
        let stream = TcpStream::connect(addr).expect("connect");
        stream.set_nodelay(true).expect("nodelay");
        let request = FrameBuf::build(dest, 0, |b| Cmd::QueryPosition.encode(b).map(<[u8]>::len)).expect("encode P?");
        Self {
            stream,
            framer: Framer::new(),
            request,
        }
    }

    fn exchange(&mut self) -> Duration {
        let started = Instant::now();
        self.stream.write_all(self.request.as_bytes()).expect("send");
        let (mut acked, mut result) = (false, false);
        let mut buf = [0u8; 512];
        while !(acked && result) {
            let n = self.stream.read(&mut buf).expect("read");
            assert!(n > 0, "connection closed");
            self.framer.feed(&buf[..n], |e| match e {
                Event::Ack => acked = true,
                Event::Frame(_) => result = true,
                other => panic!("unexpected {other:?}"),
            });
        }
        let elapsed = started.elapsed();
        self.stream.write_all(&[ACK]).expect("ack the result");
        elapsed
    }
}

fn percentile(sorted: &[Duration], p: f64) -> Duration {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn latency_series(client: &mut Client, samples: usize) -> (Duration, Duration) {
    for _ in 0..samples / 10 {
        client.exchange(); // warm-up
    }
    let mut times: Vec<Duration> = (0..samples).map(|_| client.exchange()).collect();
    times.sort();
    (percentile(&times, 0.50), percentile(&times, 0.99))
}

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

/// utime + stime of `pid` in clock ticks, and VmRSS in KiB.
fn proc_usage(pid: u32) -> (u64, u64) {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("stat");
    let fields: Vec<&str> = stat.rsplit(')').next().unwrap_or_default().split_whitespace().collect();
    let ticks = fields[11].parse::<u64>().unwrap_or(0) + fields[12].parse::<u64>().unwrap_or(0);
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    let rss = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    (ticks, rss)
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` runs us with no
    // such flag: then do nothing, quickly.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let samples: usize = std::env::var("GCUD_BENCH_SAMPLES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let dir = tempfile::tempdir().expect("temp dir");
    if let Some(secs) = std::env::var("GCUD_BENCH_SOAK").ok().and_then(|s| s.parse().ok()) {
        return soak(Duration::from_secs(secs));
    }

    // 1. Latency: direct vs through gcud, against the same simulator.
    let (_sim, sim_addr) = spawn_sim_tcp(&[]);
    let (direct50, direct99) = latency_series(&mut Client::connect(&sim_addr, Address::new(5, 1, 1)), samples);
    let (_gcud, gcud_addr) = spawn_gcud(
        &format!(
            "[gcu]\ngroup = 5\n[[port]]\nid = 1\ntcp = \"{sim_addr}\"\n\
             [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n"
        ),
        &dir,
    );
    // The simulator serves one TCP client at a time: the direct client is gone now.
    std::thread::sleep(Duration::from_millis(300));
    let (via50, via99) = latency_series(&mut Client::connect(&gcud_addr, Address::new(5, 1, 1)), samples);
    println!("latency of P? over {samples} exchanges (client -> [gcud ->] gimbalsim, TCP on 127.0.0.1):");
    println!(
        "  direct      p50 {:8.1} us   p99 {:8.1} us",
        us(direct50),
        us(direct99)
    );
    println!("  via gcud    p50 {:8.1} us   p99 {:8.1} us", us(via50), us(via99));
    println!(
        "  gcud adds   p50 {:8.1} us   p99 {:8.1} us",
        us(via50.saturating_sub(direct50)),
        us(via99.saturating_sub(direct99))
    );
    drop(_gcud);

    // 2. Throughput with many ports busy: one client per port, in parallel.
    let ports = 16;
    let per_client = samples;
    let mut config = "[gcu]\ngroup = 5\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
                      [limits]\nmax_connections = 64\n"
        .to_owned();
    let sims: Vec<(Proc, String)> = (0..ports).map(|_| spawn_sim_tcp(&[])).collect();
    for (i, (_, addr)) in sims.iter().enumerate() {
        config.push_str(&format!("[[port]]\nid = {}\ntcp = \"{addr}\"\n", i + 1));
    }
    let dir2 = tempfile::tempdir().expect("temp dir");
    let (gcud, addr) = spawn_gcud(&config, &dir2);
    std::thread::sleep(Duration::from_millis(300));
    let started = Instant::now();
    let handles: Vec<_> = (0..ports)
        .map(|i| {
            let addr = addr.clone();
            std::thread::spawn(move || {
                let mut c = Client::connect(&addr, Address::new(5, i as u8 + 1, 1));
                for _ in 0..per_client {
                    c.exchange();
                }
            })
        })
        .collect();
    for h in handles {
        h.join().expect("client thread");
    }
    let secs = started.elapsed().as_secs_f64();
    let total = ports * per_client;
    println!(
        "throughput: {ports} ports busy at once, {total} P? transactions in {secs:.2} s = {:.0} transactions/s",
        total as f64 / secs
    );
    drop(gcud);
    drop(sims);

    // 3. 254 idle ports: resident memory and CPU over an idle window.
    let mut config =
        "[gcu]\ngroup = 5\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n".to_owned();
    for id in 1..=254 {
        config.push_str(&format!("[[port]]\nid = {id}\nsimulate = [1]\n"));
    }
    let dir3 = tempfile::tempdir().expect("temp dir");
    let (gcud, _) = spawn_gcud(&config, &dir3);
    std::thread::sleep(Duration::from_secs(1));
    let (t0, _) = proc_usage(gcud.0.id());
    let window = Duration::from_secs(5);
    std::thread::sleep(window);
    let (t1, rss) = proc_usage(gcud.0.id());
    let hz = 100.0; // USER_HZ on Linux
    let cpu = (t1 - t0) as f64 / hz / window.as_secs_f64() * 100.0;
    println!(
        "254 idle ports (in-process simulated buses included): RSS {:.1} MiB, CPU {cpu:.2} % over {} s",
        rss as f64 / 1024.0,
        window.as_secs()
    );
}

/// What one soak exchange ended in, as the client saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Seen {
    /// ACK, then the result.
    Delivered,
    /// A delivery report instead of the ACK, with its failure code.
    Report(u8),
    /// Nothing in time (the client gives up on the exchange).
    Nothing,
    /// The connection was closed (refused or evicted): the client reconnects.
    Closed,
}

/// One `P?` exchange that tolerates every outcome.
fn soak_exchange(stream: &mut TcpStream, framer: &mut Framer, request: &FrameBuf) -> Seen {
    if stream.write_all(request.as_bytes()).is_err() {
        return Seen::Closed;
    }
    let (mut acked, mut result, mut report) = (false, false, None);
    let mut buf = [0u8; 512];
    let deadline = Instant::now() + Duration::from_secs(3);
    while !(acked && result) && report.is_none() {
        if Instant::now() >= deadline {
            return Seen::Nothing;
        }
        let n = match stream.read(&mut buf) {
            Ok(0) => return Seen::Closed,
            Ok(n) => n,
            Err(_) => continue, // read time-out: check the deadline
        };
        let mut frames = 0;
        framer.feed(&buf[..n], |e| match e {
            Event::Ack => acked = true,
            Event::Frame(f) => {
                frames += 1;
                match sagebrush_protocol::DeliveryReport::parse(f.payload()) {
                    Ok(r) => report = Some(r.failure.map_or(0, sagebrush_protocol::Undelivered::code)),
                    Err(_) => result = true,
                }
            }
            _ => {}
        });
        for _ in 0..frames {
            let _ = stream.write_all(&[ACK]);
        }
    }
    match report {
        Some(code) => Seen::Report(code),
        None => Seen::Delivered,
    }
}

fn metrics_text(addr: &str) -> String {
    let mut s = TcpStream::connect(addr).expect("metrics");
    s.write_all(format!("GET /metrics HTTP/1.0\r\nHost: {addr}\r\n\r\n").as_bytes())
        .expect("request");
    let mut body = String::new();
    s.read_to_string(&mut body).expect("response");
    body
}

fn soak(duration: Duration) {
    let env = |name: &str, default: usize| std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default);
    let (clients, ports) = (env("GCUD_SOAK_CLIENTS", 32), env("GCUD_SOAK_PORTS", 4));
    let sims: Vec<(Proc, String)> = (0..ports).map(|_| spawn_sim_tcp(&[])).collect();
    let free = std::net::TcpListener::bind("127.0.0.1:0").expect("probe");
    let metrics_addr = free.local_addr().expect("address").to_string();
    drop(free);
    let mut config = format!(
        "[gcu]\ngroup = 5\n[metrics]\nlisten = \"{metrics_addr}\"\n[limits]\nmax_connections = {}\nmax_connections_per_peer = {}\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n",
        clients * 2,
        clients * 2
    );
    for (i, (_, addr)) in sims.iter().enumerate() {
        config.push_str(&format!("[[port]]\nid = {}\ntcp = \"{addr}\"\n", i + 1));
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let (gcud, addr) = spawn_gcud(&config, &dir);
    std::thread::sleep(Duration::from_millis(300));
    let (_, rss_before) = proc_usage(gcud.0.id());
    let metrics_before = metrics_text(&metrics_addr).len();
    let started = Instant::now();
    let handles: Vec<_> = (0..clients)
        .map(|i| {
            let addr = addr.clone();
            std::thread::spawn(move || {
                let dest = Address::new(5, (i % ports) as u8 + 1, 1);
                let request =
                    FrameBuf::build(dest, 0, |b| Cmd::QueryPosition.encode(b).map(<[u8]>::len)).expect("encode");
                let mut seen = std::collections::BTreeMap::<Seen, u64>::new();
                let mut connections = 0u64;
                while started.elapsed() < duration {
                    let mut stream = TcpStream::connect(&addr).expect("connect");
                    stream.set_nodelay(true).expect("nodelay");
                    stream
                        .set_read_timeout(Some(Duration::from_millis(200)))
                        .expect("timeout");
                    connections += 1;
                    let mut framer = Framer::new();
                    for _ in 0..50 {
                        if started.elapsed() >= duration {
                            break;
                        }
                        let outcome = soak_exchange(&mut stream, &mut framer, &request);
                        *seen.entry(outcome).or_default() += 1;
                        if outcome == Seen::Closed {
                            std::thread::sleep(Duration::from_millis(10));
                            break;
                        }
                    }
                }
                (seen, connections)
            })
        })
        .collect();
    let results: Vec<_> = handles.into_iter().map(|h| h.join().expect("client")).collect();
    let secs = started.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_millis(500));
    let (_, rss_after) = proc_usage(gcud.0.id());
    let metrics = metrics_text(&metrics_addr);
    let delivered: Vec<f64> = results
        .iter()
        .map(|(seen, _)| seen.get(&Seen::Delivered).copied().unwrap_or(0) as f64)
        .collect();
    let sum: f64 = delivered.iter().sum();
    let jain = sum * sum / (delivered.len() as f64 * delivered.iter().map(|x| x * x).sum::<f64>());
    let mut totals = std::collections::BTreeMap::<Seen, u64>::new();
    for (seen, _) in &results {
        for (k, v) in seen {
            *totals.entry(*k).or_default() += v;
        }
    }
    let connections: u64 = results.iter().map(|(_, c)| c).sum();
    println!("soak: {clients} clients on {ports} ports for {secs:.1} s, {connections} connections");
    println!(
        "  gcud RSS {:.1} -> {:.1} MiB, /metrics {} -> {} bytes",
        rss_before as f64 / 1024.0,
        rss_after as f64 / 1024.0,
        metrics_before,
        metrics.len()
    );
    let (min, max) = delivered
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    println!(
        "  delivered per client: min {min:.0} max {max:.0}, {:.0} transactions/s, Jain's fairness index {jain:.4}",
        sum / secs
    );
    println!("  as the clients saw it: {totals:?}");
    let delivery: Vec<&str> = metrics
        .lines()
        .filter(|l| l.starts_with("gcud_commands_delivery_total") && !l.ends_with(" 0"))
        .collect();
    println!("  as gcud counted it: {delivery:?}");
    drop(gcud);
}
