//! `cargo bench --bench scale`: gcud from 1 to 254 busy buses (issue 52),
//! real processes on pseudo-terminals and 127.0.0.1, figures printed, never
//! asserted (the machine is shared: the load average is printed with each
//! case, and ratios are taken side by side in one run).
//!
//! Every port is a pseudo-terminal with a device behind it (module
//! `devices`: the protocol crate's instant device endpoint, its line timed
//! at the rate, all ports served by one thread), clients on gcud's listener
//! (module `clients`, one runtime thread):
//! 1. **relay**: unpaced lines, one client per port doing `P?` after `P?`,
//!    N socat relays (TCP to the pty, raw; one per port) then gcud on the
//!    same lines: transactions/s, CPU per 10k transactions, context
//!    switches per transaction, latency p50/p99, gcud's allocations per
//!    transaction (`SCALE_RELAY_SIZES`, default 8,254);
//! 2. **line rate**: lines timed at 9600 and 115200 bit/s
//!    (`SCALE_RATES`), two clients per port keeping its queue full, 1, 8,
//!    64 and 254 ports (`SCALE_SIZES`): each bus's share of its line limit
//!    (26 byte-times a `P?` transaction), the total against the buses' sum,
//!    and the figures of 1. with resident memory per port; socat with one
//!    client per port alongside at `SCALE_SOCAT_SIZES` (default 8,254);
//!    gcud again with its ports' I/O on each of `SCALE_THREADS` (`[gcu]
//!    threads`, default 1,2) and the ratio to one thread;
//! 3. **idle**: 254 pty ports, no client: CPU and resident memory per port;
//! 4. **governed**: 254 gimbals (`sagebrush-sim`, unpaced lines), each with
//!    travel limits and a keep-out zone, 64 of them slewing (pan left, then
//!    right, 3 s each, a `P?` every 200 ms): gcud's CPU and the follower's
//!    polls, as bus time per port at 9600 bit/s.
//!
//! `SCALE_SECONDS` a measured window (default 5, after a 1 s warm-up),
//! `SCALE_SECTIONS` which of relay,line,idle,governed run (default all),
//! `GCUD_BENCH_GCUD=PATH` another gcud build in gcud's place,
//! `GCUD_BENCH_BEFORE=PATH` another build measured beside it in the same
//! run (sections 1 and 2: a "before" row after gcud's, and its ratio).

use std::time::{Duration, Instant};

use clients::{Clients, Script, Target};
use devices::{Devices, Model};
use procs::{Usage, before_bin, gcud_bin, spawn_gcud};
use sagebrush_protocol::Address;

mod clients;
mod devices;
mod procs;
#[allow(dead_code)]
#[path = "../support/mod.rs"]
mod support;

/// Bytes on the wire per `P?` transaction (command 9, ACK 1, result 15, ACK 1).
const TRANSACTION_BYTES: f64 = support::TRANSACTION_BYTES;

fn env_list(name: &str, default: &[usize]) -> Vec<usize> {
    std::env::var(name)
        .ok()
        .map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .unwrap_or_else(|| default.to_vec())
}

fn window() -> Duration {
    Duration::from_secs_f64(
        std::env::var("SCALE_SECONDS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(5.0),
    )
}

/// gcud's configuration: `ports` pty ports at `baud`, the ports' I/O on
/// `threads` (`[gcu] threads`), a client listener, metrics, room for every
/// client; `extra` appended.
fn gcud_config(paths: &[String], baud: u32, metrics: &str, threads: usize, extra: &str) -> String {
    let mut config = format!(
        "[gcu]\ngroup = 5\nthreads = {threads}\n[metrics]\nlisten = \"{metrics}\"\n\
         [limits]\nmax_connections = 2048\nmax_connections_per_peer = 2048\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n"
    );
    for (i, path) in paths.iter().enumerate() {
        config.push_str(&format!("[[port]]\nid = {}\npath = \"{path}\"\nbaud = {baud}\n", i + 1));
    }
    config + extra
}

/// What one measured window saw.
struct Window {
    seconds: f64,
    usage: Usage,
    /// Commands each port's device answered in the window.
    per_port: Vec<u64>,
    transactions: u64,
    latencies: Vec<u32>,
    allocations: Option<u64>,
    failed: u64,
    /// The share of the machine's cores busy in the window (every process).
    machine_busy: f64,
}

impl Window {
    /// Runs `clients` on the lines of `devices` through the process `pids`
    /// (gcud with its metrics at `metrics`): 1 s of warm-up, then the window.
    fn measure(devices: &Devices, targets: Vec<Target>, pids: &[u32], metrics: Option<&str>) -> Self {
        let clients = Clients::start(targets);
        std::thread::sleep(Duration::from_secs(1));
        let machine0 = procs::machine_ticks();
        let (usage0, allocs0, ports0, done0) = (
            Usage::of(pids),
            metrics.map(procs::allocations),
            devices.counts(),
            clients.counts(),
        );
        let failed0 = clients.failed.load(std::sync::atomic::Ordering::Relaxed);
        clients.measure();
        let started = Instant::now();
        std::thread::sleep(window());
        let usage = Usage::of(pids).since(usage0);
        let seconds = started.elapsed().as_secs_f64();
        let machine = procs::machine_ticks();
        let machine_busy = (machine.0 - machine0.0) as f64 / (machine.1 - machine0.1).max(1) as f64;
        let per_port: Vec<u64> = devices.counts().iter().zip(&ports0).map(|(a, b)| a - b).collect();
        let transactions: u64 = clients.counts().iter().zip(&done0).map(|(a, b)| a - b).sum();
        // A scrape's own allocations (its page grows with the clients'
        // links), from one more scrape right after, subtracted.
        let allocations = metrics.zip(allocs0).map(|(m, before)| {
            let after = procs::allocations(m);
            let cost = procs::allocations(m) - after;
            after.saturating_sub(before + cost)
        });
        let failed = clients.failed.load(std::sync::atomic::Ordering::Relaxed) - failed0;
        let latencies = clients.stop();
        Self {
            seconds,
            usage,
            per_port,
            transactions,
            latencies,
            allocations,
            failed,
            machine_busy,
        }
    }

    fn rate(&self) -> f64 {
        self.transactions as f64 / self.seconds
    }

    fn cpu_per_10k(&self) -> f64 {
        self.usage.cpu_seconds() / self.transactions.max(1) as f64 * 10_000.0
    }

    /// The busiest thread's CPU per 10k transactions: the throughput the
    /// process reaches once that thread fills its core is 10k over it.
    fn busiest_per_10k(&self) -> f64 {
        self.usage.busiest_seconds() / self.transactions.max(1) as f64 * 10_000.0
    }

    fn percentile(&self, p: f64) -> f64 {
        if self.latencies.is_empty() {
            return f64::NAN;
        }
        f64::from(self.latencies[((self.latencies.len() - 1) as f64 * p).round() as usize])
    }

    /// The common figures of a row.
    fn figures(&self) -> String {
        let mut text = format!(
            "{:8.0} transactions/s  CPU {:.3} s/10k  {:.2} switches/transaction  p50 {:6.0} us  p99 {:6.0} us",
            self.rate(),
            self.cpu_per_10k(),
            self.usage.switches as f64 / self.transactions.max(1) as f64,
            self.percentile(0.5),
            self.percentile(0.99),
        );
        if let Some(a) = self.allocations {
            text += &format!(
                "  {:.2} allocations/transaction",
                a as f64 / self.transactions.max(1) as f64
            );
        }
        if self.failed > 0 {
            text += &format!("  {} failed", self.failed);
        }
        text
    }
}

fn targets(addrs: &[String], per_port: usize, gcud: bool) -> Vec<Target> {
    (0..per_port)
        .flat_map(|_| addrs.iter().enumerate())
        .map(|(i, addr)| Target {
            addr: addr.clone(),
            dest: Address::new(5, if gcud { i as u8 + 1 } else { 1 }, 1),
            script: Script::Query,
        })
        .collect()
}

/// socat relays on every line of `devices`, one client each.
fn socat_window(devices: &Devices) -> Window {
    let relays = procs::spawn_socats(&devices.paths);
    let pids: Vec<u32> = relays.iter().map(|(p, _)| p.0.id()).collect();
    let addrs: Vec<String> = relays.iter().map(|(_, a)| a.clone()).collect();
    let w = Window::measure(devices, targets(&addrs, 1, false), &pids, None);
    drop(relays);
    w
}

/// gcud (the build `bin`) on every line of `devices` at `baud`, its ports'
/// I/O on `threads`, `per_port` clients a port.
fn gcud_window(bin: &str, devices: &Devices, baud: u32, threads: usize, per_port: usize) -> Window {
    let dir = tempfile::tempdir().expect("temp dir");
    let metrics = procs::free_addr();
    let (gcud, addr) = spawn_gcud(bin, &gcud_config(&devices.paths, baud, &metrics, threads, ""), &dir);
    std::thread::sleep(Duration::from_millis(500));
    let addrs = vec![addr; devices.paths.len()];
    Window::measure(devices, targets(&addrs, per_port, true), &[gcud.0.id()], Some(&metrics))
}

/// 1. Unpaced lines, one client a port: socat and gcud side by side.
fn relay(sizes: &[usize], socat: bool) {
    println!("1. relay: unpaced pty lines with the instant device, one client per port doing P? after P?");
    for &n in sizes {
        let devices = Devices::start(n, None, |_| Model::instant());
        println!("  {n} ports ({})", procs::load());
        let s = socat.then(|| socat_window(&devices));
        if let Some(s) = &s {
            println!("    socat x{n:<3} {}", s.figures());
        }
        let g = gcud_window(&gcud_bin(), &devices, 115_200, 1, 1);
        println!("    gcud        {}", g.figures());
        if let Some(s) = &s {
            println!(
                "    gcud / socat: CPU per transaction {:.2}, throughput {:.2}",
                g.cpu_per_10k() / s.cpu_per_10k(),
                g.rate() / s.rate()
            );
        }
        if let Some(bin) = before_bin() {
            let b = gcud_window(&bin, &devices, 115_200, 1, 1);
            println!("    before      {}", b.figures());
            compare(&g, &b, s.as_ref());
        }
    }
}

/// The ratios of gcud's row to the build before it and to socat's.
fn compare(g: &Window, before: &Window, socat: Option<&Window>) {
    let mut text = format!(
        "    CPU per transaction: gcud / before {:.2}",
        g.cpu_per_10k() / before.cpu_per_10k()
    );
    if let Some(s) = socat {
        text += &format!(
            ", gcud / socat {:.2}, before / socat {:.2}",
            g.cpu_per_10k() / s.cpu_per_10k(),
            before.cpu_per_10k() / s.cpu_per_10k()
        );
    }
    println!("{text}");
}

/// Each bus's share of its line limit: min, median, max.
fn shares(w: &Window, baud: u32) -> (f64, f64, f64, f64) {
    let limit = f64::from(baud) / 10.0 / TRANSACTION_BYTES;
    let mut s: Vec<f64> = w.per_port.iter().map(|&c| c as f64 / w.seconds / limit).collect();
    s.sort_by(f64::total_cmp);
    let sum: f64 = s.iter().sum::<f64>() / s.len() as f64;
    (s[0], s[s.len() / 2], s[s.len() - 1], sum)
}

/// 2. Lines timed at each rate, every queue full.
fn line_rate(sizes: &[usize], rates: &[usize], threads: &[usize], socat_sizes: &[usize], socat: bool) {
    println!(
        "2. line rate: pty lines timed at the rate, 2 clients per port keeping its queue full \
         (socat: one client per port); share of the line limit min/median/max, all buses together"
    );
    for &baud in rates {
        let baud = baud as u32;
        for &n in sizes {
            let devices = Devices::start(n, Some(baud), |_| Model::instant());
            println!("  {baud} bit/s, {n} ports ({})", procs::load());
            let s = (socat && socat_sizes.contains(&n)).then(|| socat_window(&devices));
            if let Some(s) = &s {
                let (lo, mid, hi, all) = shares(s, baud);
                println!(
                    "    socat x{n:<3} share {lo:.3}/{mid:.3}/{hi:.3} all {all:.3}  {}",
                    s.figures()
                );
            }
            let row = |name: &str, w: &Window| {
                let (lo, mid, hi, all) = shares(w, baud);
                println!(
                    "    {name:<11} share {lo:.3}/{mid:.3}/{hi:.3} all {all:.3}  {}  RSS {:.0} KiB/port  \
                     busiest thread {:.3} s/10k  machine {:.0} % busy",
                    w.figures(),
                    w.usage.rss_kib as f64 / n as f64,
                    w.busiest_per_10k(),
                    w.machine_busy * 100.0
                );
            };
            let g = gcud_window(&gcud_bin(), &devices, baud, 1, 2);
            row("gcud", &g);
            for &threads in threads.iter().filter(|&&t| t > 1) {
                let t = gcud_window(&gcud_bin(), &devices, baud, threads, 2);
                row(&format!("threads={threads}"), &t);
                println!(
                    "    threads={threads} / 1: throughput {:.2}, CPU per transaction {:.2}, \
                     throughput once the busiest thread fills its core {:.2}",
                    t.rate() / g.rate(),
                    t.cpu_per_10k() / g.cpu_per_10k(),
                    g.busiest_per_10k() / t.busiest_per_10k()
                );
            }
            if let Some(bin) = before_bin() {
                let b = gcud_window(&bin, &devices, baud, 1, 2);
                row("before", &b);
                compare(&g, &b, s.as_ref());
            }
        }
    }
}

/// 3. 254 idle pty ports.
fn idle() {
    let devices = Devices::start(254, Some(9600), |_| Model::instant());
    let dir = tempfile::tempdir().expect("temp dir");
    let metrics = procs::free_addr();
    let (gcud, _) = spawn_gcud(&gcud_bin(), &gcud_config(&devices.paths, 9600, &metrics, 1, ""), &dir);
    std::thread::sleep(Duration::from_secs(2));
    let before = Usage::of(&[gcud.0.id()]);
    let started = Instant::now();
    std::thread::sleep(window().max(Duration::from_secs(5)));
    let usage = Usage::of(&[gcud.0.id()]).since(before);
    println!(
        "3. idle: 254 pty ports, no client ({}): CPU {:.2} % of a core over {:.0} s, RSS {:.1} MiB, {:.0} KiB per port",
        procs::load(),
        usage.cpu_seconds() / started.elapsed().as_secs_f64() * 100.0,
        started.elapsed().as_secs_f64(),
        usage.rss_kib as f64 / 1024.0,
        usage.rss_kib as f64 / 254.0
    );
}

/// 4. 254 governed gimbals, 64 slewing.
fn governed() {
    const PORTS: usize = 254;
    const SLEWING: usize = 64;
    let devices = Devices::start(PORTS, None, Model::sim);
    let mut rules = String::new();
    for port in 1..=PORTS {
        rules.push_str(&format!(
            "[[gimbal]]\naddress = \"5.{port}.1\"\npan_limits_deg = [-60.0, 60.0]\ntilt_limits_deg = [-30.0, 60.0]\n\
             [[gimbal.keep_out]]\npan_deg = [100.0, 120.0]\ntilt_deg = [-30.0, 10.0]\n"
        ));
    }
    let dir = tempfile::tempdir().expect("temp dir");
    let metrics = procs::free_addr();
    let (gcud, addr) = spawn_gcud(
        &gcud_bin(),
        &gcud_config(&devices.paths, 9600, &metrics, 1, &rules),
        &dir,
    );
    // Every followed gimbal is read at start: let that settle.
    std::thread::sleep(Duration::from_secs(3));
    let polls = |m: &str| procs::counter(m, "gcud_governance_follow_polls_total");
    let stops = |m: &str| procs::counter(m, "gcud_governance_boundary_stops_total");
    let targets = (0..SLEWING)
        .map(|i| Target {
            addr: addr.clone(),
            dest: Address::new(5, i as u8 + 1, 1),
            script: Script::Slew,
        })
        .collect();
    let (polls0, stops0) = (polls(&metrics), stops(&metrics));
    let w = Window::measure(&devices, targets, &[gcud.0.id()], None);
    let (p, s) = (polls(&metrics) - polls0, stops(&metrics) - stops0);
    // A P? transaction's wire time at 9600 bit/s, as a share of a second.
    let poll_time = TRANSACTION_BYTES * 10.0 / 9600.0;
    let per_port = p as f64 / w.seconds / SLEWING as f64;
    println!(
        "4. governed: {PORTS} gimbals with limits and a zone, {SLEWING} slewing ({}): gcud CPU {:.2} % of a core, \
         {:.1} follow polls/s per slewing port = {:.1} % of its bus at 9600 bit/s ({:.1} % at 115200), \
         {s} boundary stops, clients {}",
        procs::load(),
        w.usage.cpu_seconds() / w.seconds * 100.0,
        per_port,
        per_port * poll_time * 100.0,
        per_port * poll_time * 100.0 / 12.0,
        w.figures()
    );
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` runs us with no
    // such flag: then do nothing, quickly.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let sections = std::env::var("SCALE_SECTIONS").unwrap_or_else(|_| "relay,line,idle,governed".to_owned());
    let socat = procs::socat_present();
    if !socat {
        println!("socat is not on PATH: its relays are skipped (apt-get install socat)");
    }
    println!(
        "scale: {} cores, {}, window {:.1} s",
        std::thread::available_parallelism().map_or(0, |n| n.get()),
        procs::load(),
        window().as_secs_f64()
    );
    let sizes = env_list("SCALE_SIZES", &[1, 8, 64, 254]);
    let socat_sizes = env_list("SCALE_SOCAT_SIZES", &[8, 254]);
    for section in sections.split(',') {
        match section.trim() {
            "relay" => relay(&env_list("SCALE_RELAY_SIZES", &[8, 254]), socat),
            "line" => line_rate(
                &sizes,
                &env_list("SCALE_RATES", &[9600, 115_200]),
                &env_list("SCALE_THREADS", &[1, 2]),
                &socat_sizes,
                socat,
            ),
            "idle" => idle(),
            "governed" => governed(),
            other => println!("unknown section {other:?} (relay, line, idle, governed)"),
        }
    }
}
