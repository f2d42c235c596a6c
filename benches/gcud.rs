//! `cargo bench --bench gcud`: the daemon measured with real processes on
//! 127.0.0.1, side by side in one run (issue 14's figures):
//! 1. latency of sequential `P?` transactions client -> [relay ->]
//!    `gimbalsim --tcp` on three paths: direct, through a `socat` relay
//!    (installed with apt-get when missing and possible, skipped with a
//!    message otherwise) and through gcud: p50/p99 (median of
//!    `GCUD_BENCH_RUNS` runs, default 3, of `GCUD_BENCH_SAMPLES` samples,
//!    default 10,000, the runs interleaved), the latency each relay adds and
//!    gcud's as a ratio of socat's, each relay's CPU seconds per 10k
//!    transactions and context switches per transaction (all its threads),
//!    and gcud's heap allocations per transaction (`gcud_heap_allocations_total`);
//! 2. throughput with 8 clients on 8 ports, each client its own port, on
//!    the same three paths;
//! 3. bus efficiency with gcud the bus master on a pseudo-terminal port at
//!    9600 and 115200 bit/s, four clients keeping its queue full: achieved /
//!    theoretical `P?` rate (26 byte-times a transaction) and the time per
//!    transaction beyond those 26 byte-times, with an instant reference
//!    device (the protocol crate's `DeviceEndpoint` answering at once, its
//!    line timed at the rate; it also measures gcud's turnaround, from an
//!    answer's last byte to the next command, in byte-times) and with
//!    `gimbalsim --pace`; `GCUD_BENCH_BUS_SECONDS` a case (default 3);
//! 4. resident memory and CPU of gcud with 254 idle ports;
//! 5. with `GCUD_BENCH_SOAK=SECONDS`: a soak of N clients (`GCUD_SOAK_CLIENTS`,
//!    default 32) on M ports (`GCUD_SOAK_PORTS`, default 4) that reconnect
//!    every 50 exchanges (connection churn), printing RSS and `/metrics`
//!    size before and after, each client's share (Jain's fairness index)
//!    and every command's outcome, as the clients saw it and as gcud counted.
//!
//! `GCUD_BENCH_GCUD=PATH` runs another gcud build in gcud's place (a
//! change measured against the build before it).
//!
//! Figures are printed, never asserted: the machines are shared and noisy.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Command as Cmd, Event, FrameBuf, Framer};
use support::{Proc, TRANSACTION_BYTES, percentile};

mod support;

fn spawn_sim_tcp(args: &[&str]) -> (Proc, String) {
    let mut all = vec!["--tcp", "127.0.0.1:0"];
    all.extend_from_slice(args);
    support::gimbalsim(env!("CARGO_BIN_EXE_gimbalsim"), &all)
}

fn spawn_gcud(config: &str, dir: &tempfile::TempDir) -> (Proc, String) {
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, config).expect("config");
    let log_path = dir.path().join("gcud.log");
    let child = Proc(
        Command::new(std::env::var("GCUD_BENCH_GCUD").unwrap_or_else(|_| env!("CARGO_BIN_EXE_gcud").to_owned()))
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

fn us(d: Duration) -> f64 {
    d.as_secs_f64() * 1e6
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

/// What a relay process spent: CPU (utime + stime of all its threads, in
/// clock ticks) and context switches (voluntary and not, summed over its
/// live threads).
#[derive(Debug, Clone, Copy, Default)]
struct Usage {
    ticks: u64,
    switches: u64,
}

impl Usage {
    fn of(pids: &[u32]) -> Self {
        let mut total = Self::default();
        for &pid in pids {
            let (ticks, _) = proc_usage(pid);
            total.ticks += ticks;
            let tasks = std::fs::read_dir(format!("/proc/{pid}/task"))
                .into_iter()
                .flatten()
                .flatten();
            for task in tasks {
                let status = std::fs::read_to_string(task.path().join("status")).unwrap_or_default();
                total.switches += status
                    .lines()
                    .filter(|l| l.starts_with("voluntary_ctxt_switches") || l.starts_with("nonvoluntary_ctxt_switches"))
                    .filter_map(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
                    .sum::<u64>();
            }
        }
        total
    }

    fn since(self, before: Self) -> Self {
        Self {
            ticks: self.ticks - before.ticks,
            switches: self.switches - before.switches,
        }
    }

    /// CPU seconds per 10k transactions (USER_HZ is 100 on Linux).
    fn cpu_per_10k(self, transactions: usize) -> f64 {
        self.ticks as f64 / 100.0 / transactions as f64 * 10_000.0
    }

    fn switches_per(self, transactions: usize) -> f64 {
        self.switches as f64 / transactions as f64
    }
}

/// gcud's heap allocations so far, from its `/metrics`.
fn heap_allocations(metrics: &str) -> u64 {
    metrics_text(metrics)
        .lines()
        .find_map(|l| l.strip_prefix("gcud_heap_allocations_total "))
        .and_then(|v| v.trim().parse().ok())
        .expect("gcud_heap_allocations_total in /metrics")
}

/// A free port on 127.0.0.1 (bound, then released).
fn free_addr() -> String {
    let probe = std::net::TcpListener::bind("127.0.0.1:0").expect("probe");
    probe.local_addr().expect("address").to_string()
}

/// Whether a TCP socket listens on 127.0.0.1:`port` (from /proc/net/tcp,
/// without connecting: a socat relay serves its first connection only).
fn listening(port: u16) -> bool {
    let local = format!("0100007F:{port:04X}");
    std::fs::read_to_string("/proc/net/tcp")
        .unwrap_or_default()
        .lines()
        .any(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            f.len() > 3 && f[1] == local && f[3] == "0A"
        })
}

/// socat on PATH, installed with apt-get when missing and that is possible
/// (root, or sudo without a password).
fn socat_ready() -> bool {
    let present = || {
        Command::new("socat")
            .arg("-V")
            .stdout(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if present() {
        return true;
    }
    println!("socat not found: installing it with apt-get");
    let root = std::fs::read_to_string("/proc/self/status")
        .unwrap_or_default()
        .lines()
        .any(|l| l.starts_with("Uid:") && l.split_whitespace().nth(1) == Some("0"));
    let apt = |args: &[&str]| {
        let mut c = if root {
            Command::new("apt-get")
        } else {
            Command::new("sudo")
        };
        if !root {
            c.args(["-n", "apt-get"]);
        }
        c.args(args)
            .env("DEBIAN_FRONTEND", "noninteractive")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    let _ = apt(&["update", "-qq"]) && apt(&["install", "-y", "-qq", "socat"]);
    present()
}

/// A socat relay of one connection to `target`, TCP_NODELAY both ways.
fn spawn_socat(target: &str) -> (Proc, String) {
    let addr = free_addr();
    let port: u16 = addr.rsplit(':').next().and_then(|p| p.parse().ok()).expect("port");
    let child = Proc(
        Command::new("socat")
            .arg(format!("TCP-LISTEN:{port},bind=127.0.0.1,reuseaddr,nodelay"))
            .arg(format!("TCP:{target},nodelay"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn socat"),
    );
    let started = Instant::now();
    while !listening(port) {
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "socat did not listen on {addr}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    (child, addr)
}

/// One latency series on a fresh connection: p50, p99, and the relay's
/// usage (and gcud's allocations) over the measured exchanges.
struct Series {
    p50: Duration,
    p99: Duration,
    usage: Usage,
    allocations: Option<u64>,
}

fn latency_series(addr: &str, samples: usize, relay: &[u32], metrics: Option<&str>) -> Series {
    let mut client = Client::connect(addr, Address::new(5, 1, 1));
    for _ in 0..samples / 10 {
        client.exchange(); // warm-up
    }
    // The scrapes' own allocations: measured on an idle gcud, subtracted.
    let scrape_cost = metrics.map(|m| {
        let a = heap_allocations(m);
        heap_allocations(m) - a
    });
    let before = (Usage::of(relay), metrics.map(heap_allocations));
    let mut times: Vec<Duration> = (0..samples).map(|_| client.exchange()).collect();
    let usage = Usage::of(relay).since(before.0);
    let allocations = metrics
        .zip(before.1)
        .zip(scrape_cost)
        .map(|((m, b), cost)| heap_allocations(m).saturating_sub(b + cost));
    times.sort();
    Series {
        p50: percentile(&times, 0.50),
        p99: percentile(&times, 0.99),
        usage,
        allocations,
    }
}

/// The median of each figure over runs, for one path.
#[derive(Default)]
struct PathFigures {
    runs: Vec<Series>,
}

impl PathFigures {
    fn p50(&self) -> f64 {
        median(self.runs.iter().map(|s| us(s.p50)).collect())
    }
    fn p99(&self) -> f64 {
        median(self.runs.iter().map(|s| us(s.p99)).collect())
    }
    fn cpu(&self, samples: usize) -> f64 {
        median(self.runs.iter().map(|s| s.usage.cpu_per_10k(samples)).collect())
    }
    fn switches(&self, samples: usize) -> f64 {
        median(self.runs.iter().map(|s| s.usage.switches_per(samples)).collect())
    }
    fn allocations(&self, samples: usize) -> Option<f64> {
        let per: Vec<f64> = self
            .runs
            .iter()
            .filter_map(|s| s.allocations)
            .map(|a| a as f64 / samples as f64)
            .collect();
        (!per.is_empty()).then(|| median(per))
    }
}

fn gcud_config(ports: &[String], metrics: &str) -> String {
    let mut config = format!(
        "[gcu]\ngroup = 5\n[metrics]\nlisten = \"{metrics}\"\n[limits]\nmax_connections = 64\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n"
    );
    for (i, addr) in ports.iter().enumerate() {
        config.push_str(&format!("[[port]]\nid = {}\ntcp = \"{addr}\"\n", i + 1));
    }
    config
}

/// 1. Sequential `P?` latency, direct / socat / gcud, runs interleaved.
fn latency(samples: usize, runs: usize, socat: bool) {
    let (_direct_sim, direct_sim) = spawn_sim_tcp(&[]);
    let (_socat_sim, socat_sim) = spawn_sim_tcp(&[]);
    let (_gcud_sim, gcud_sim) = spawn_sim_tcp(&[]);
    let dir = tempfile::tempdir().expect("temp dir");
    let metrics = free_addr();
    let (gcud, gcud_addr) = spawn_gcud(&gcud_config(&[gcud_sim], &metrics), &dir);
    let gcud_pid = [gcud.0.id()];
    let (mut direct, mut relayed, mut routed) =
        (PathFigures::default(), PathFigures::default(), PathFigures::default());
    for _ in 0..runs {
        direct.runs.push(latency_series(&direct_sim, samples, &[], None));
        if socat {
            let (relay, addr) = spawn_socat(&socat_sim);
            relayed.runs.push(latency_series(&addr, samples, &[relay.0.id()], None));
        }
        routed
            .runs
            .push(latency_series(&gcud_addr, samples, &gcud_pid, Some(&metrics)));
    }
    println!(
        "1. latency of sequential P? (client -> [relay ->] gimbalsim --tcp on 127.0.0.1), \
         median of {runs} runs of {samples}:"
    );
    let line = |name: &str, f: &PathFigures, relay: bool| {
        let mut text = format!("  {name:<7} p50 {:6.1} us  p99 {:6.1} us", f.p50(), f.p99());
        if relay {
            text += &format!(
                "  adds p50 {:5.1} us p99 {:5.1} us  CPU {:.2} s/10k  {:.2} context switches/transaction",
                f.p50() - direct.p50(),
                f.p99() - direct.p99(),
                f.cpu(samples),
                f.switches(samples)
            );
        }
        if let Some(a) = f.allocations(samples) {
            text += &format!("  {a:.2} allocations/transaction");
        }
        println!("{text}");
    };
    line("direct", &direct, false);
    if socat {
        line("socat", &relayed, true);
    }
    line("gcud", &routed, true);
    if socat {
        let ratio = |via: f64, relay: f64, base: f64| (via - base) / (relay - base);
        println!(
            "  gcud's added latency / socat's: p50 {:.2}x  p99 {:.2}x;  CPU per transaction gcud / socat {:.2}",
            ratio(routed.p50(), relayed.p50(), direct.p50()),
            ratio(routed.p99(), relayed.p99(), direct.p99()),
            routed.cpu(samples) / relayed.cpu(samples)
        );
    }
}

/// `clients` threads, client `i` on `addrs[i]` to port `i + 1`, each doing
/// `per_client` exchanges; transactions per second.
fn hammer(addrs: &[String], per_client: usize) -> f64 {
    let started = Instant::now();
    let handles: Vec<_> = addrs
        .iter()
        .enumerate()
        .map(|(i, addr)| {
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
    (addrs.len() * per_client) as f64 / started.elapsed().as_secs_f64()
}

/// 2. Throughput, 8 clients on 8 ports, direct / socat / gcud.
fn throughput(per_client: usize, socat: bool) {
    const PORTS: usize = 8;
    let total = PORTS * per_client;
    let sims: Vec<(Proc, String)> = (0..PORTS).map(|_| spawn_sim_tcp(&[])).collect();
    let sim_addrs: Vec<String> = sims.iter().map(|(_, a)| a.clone()).collect();
    println!("2. throughput, {PORTS} clients on {PORTS} ports (each client its own port), {total} P? each path:");
    let direct = hammer(&sim_addrs, per_client);
    println!("  direct  {direct:8.0} transactions/s");
    if socat {
        let relays: Vec<(Proc, String)> = sim_addrs.iter().map(|a| spawn_socat(a)).collect();
        let pids: Vec<u32> = relays.iter().map(|(p, _)| p.0.id()).collect();
        let before = Usage::of(&pids);
        let rate = hammer(&relays.iter().map(|(_, a)| a.clone()).collect::<Vec<_>>(), per_client);
        let usage = Usage::of(&pids).since(before);
        println!(
            "  socat   {rate:8.0} transactions/s  CPU {:.2} s/10k  {:.2} context switches/transaction",
            usage.cpu_per_10k(total),
            usage.switches_per(total)
        );
        drop(relays);
        // The simulators serve one client at a time: let them see socat go.
        std::thread::sleep(Duration::from_millis(300));
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let metrics = free_addr();
    let (gcud, addr) = spawn_gcud(&gcud_config(&sim_addrs, &metrics), &dir);
    std::thread::sleep(Duration::from_millis(300));
    // The scrapes' own allocations (a /metrics page of 8 ports), measured
    // on the idle gcud and subtracted, as in 1.; the 8 connections the
    // clients open stay counted.
    let scrape_cost = {
        let a = heap_allocations(&metrics);
        heap_allocations(&metrics) - a
    };
    let before = (Usage::of(&[gcud.0.id()]), heap_allocations(&metrics));
    let rate = hammer(&vec![addr; PORTS], per_client);
    let usage = Usage::of(&[gcud.0.id()]).since(before.0);
    let allocations = (heap_allocations(&metrics) - before.1).saturating_sub(scrape_cost);
    println!(
        "  gcud    {rate:8.0} transactions/s  CPU {:.2} s/10k  {:.2} context switches/transaction  \
         {:.2} allocations/transaction",
        usage.cpu_per_10k(total),
        usage.switches_per(total),
        allocations as f64 / total as f64
    );
}

/// The device's side of a bus case: its turnaround figures, once `stop` is set and the line closed.
type DeviceEnd = Box<dyn FnOnce(&AtomicBool) -> Vec<f64> + Send>;

/// One bus efficiency case: gcud on a pty port at `baud`, four clients
/// keeping its queue full for `seconds`.
fn bus_case(baud: u32, seconds: f64, device: &str) {
    let dir = tempfile::tempdir().expect("temp dir");
    let (pty_path, device_end): (String, DeviceEnd);
    let _sim;
    match device {
        "instant" => {
            let (file, path) = support::pty();
            pty_path = path;
            device_end = Box::new(move |stop| support::paced_device(file, baud, stop, |_, _| {}));
            _sim = None;
        }
        _ => {
            let rate = baud.to_string();
            let (sim, path) = support::gimbalsim(
                env!("CARGO_BIN_EXE_gimbalsim"),
                &["--pace", "--baud", &rate, "--device", "1"],
            );
            pty_path = path;
            device_end = Box::new(|_| Vec::new());
            _sim = Some(sim);
        }
    }
    let stop = Arc::new(AtomicBool::new(false));
    let device_thread = {
        let stop = stop.clone();
        std::thread::spawn(move || device_end(&stop))
    };
    let config = format!(
        "[gcu]\ngroup = 5\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
         [[port]]\nid = 1\npath = \"{pty_path}\"\nbaud = {baud}\n"
    );
    let (gcud, addr) = spawn_gcud(&config, &dir);
    // Completion times of every transaction, all clients.
    let done = Arc::new(std::sync::Mutex::new(Vec::<Instant>::new()));
    let clients: Vec<_> = (0..4)
        .map(|_| {
            let (addr, stop, done) = (addr.clone(), stop.clone(), done.clone());
            std::thread::spawn(move || {
                let mut c = Client::connect(&addr, Address::new(5, 1, 1));
                while !stop.load(Ordering::Relaxed) {
                    c.exchange();
                    done.lock().expect("lock").push(Instant::now());
                }
            })
        })
        .collect();
    let started = Instant::now() + Duration::from_millis(500); // after a warm-up
    std::thread::sleep(Duration::from_secs_f64(seconds + 0.5));
    stop.store(true, Ordering::Relaxed);
    for c in clients {
        c.join().expect("client");
    }
    drop(gcud);
    // The rate between the first and the last completion in the window.
    let mut times: Vec<Instant> = done
        .lock()
        .expect("lock")
        .iter()
        .copied()
        .filter(|t| *t >= started)
        .collect();
    times.sort();
    let (first, last) = (times[0], times[times.len() - 1]);
    let rate = (times.len() - 1) as f64 / last.duration_since(first).as_secs_f64();
    let mut turnarounds = device_thread.join().expect("device");
    let byte_time = 10.0 / f64::from(baud);
    let theoretical = f64::from(baud) / 10.0 / TRANSACTION_BYTES;
    let beyond = 1.0 / rate / byte_time - TRANSACTION_BYTES;
    let mut text = format!(
        "  {baud:>6} bit/s {device:<9} {rate:6.1} P?/s of {theoretical:6.1} = {:.3}  {beyond:+.2} byte-times/transaction beyond 26",
        rate / theoretical
    );
    if !turnarounds.is_empty() {
        turnarounds.sort_by(f64::total_cmp);
        let at = |p: f64| turnarounds[((turnarounds.len() - 1) as f64 * p).round() as usize];
        text += &format!("  gcud turnaround p50 {:.2} p99 {:.2} byte-times", at(0.5), at(0.99));
    }
    println!("{text}");
}

/// 3. Bus efficiency with gcud as the master on a pty port.
fn bus_efficiency(seconds: f64) {
    println!(
        "3. bus efficiency, gcud the master on a pty port, 4 clients keeping its queue full, {seconds} s a case \
         (theoretical: 26 byte-times a P? transaction):"
    );
    for baud in [9600, 115200] {
        for device in ["instant", "gimbalsim"] {
            bus_case(baud, seconds, device);
        }
    }
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
    let env = |name: &str, default: usize| std::env::var(name).ok().and_then(|s| s.parse().ok()).unwrap_or(default);
    if let Some(secs) = std::env::var("GCUD_BENCH_SOAK").ok().and_then(|s| s.parse().ok()) {
        return soak(Duration::from_secs(secs));
    }
    let samples = env("GCUD_BENCH_SAMPLES", 10_000);
    let socat = socat_ready();
    if !socat {
        println!("socat is missing and cannot be installed here: the socat path is skipped");
    }
    latency(samples, env("GCUD_BENCH_RUNS", 3), socat);
    throughput(samples / 4, socat);
    bus_efficiency(env("GCUD_BENCH_BUS_SECONDS", 3) as f64);

    // 4. 254 idle ports: resident memory and CPU over an idle window.
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
        "4. 254 idle ports (in-process simulated buses included): RSS {:.1} MiB, CPU {cpu:.2} % over {} s",
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
