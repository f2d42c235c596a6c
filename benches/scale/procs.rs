//! The processes a scale case measures, gcud and socat relays: started,
//! found listening, and what they spend (from `/proc`) and allocate
//! (gcud's `gcud_heap_allocations_total`).

use std::io::{Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::support::Proc;

/// The gcud build measured: `GCUD_BENCH_GCUD`, or this workspace's.
pub fn gcud_bin() -> String {
    std::env::var("GCUD_BENCH_GCUD").unwrap_or_else(|_| env!("CARGO_BIN_EXE_gcud").to_owned())
}

/// Another gcud build measured beside it in the same run
/// (`GCUD_BENCH_BEFORE`), if any.
pub fn before_bin() -> Option<String> {
    std::env::var("GCUD_BENCH_BEFORE").ok().filter(|b| !b.is_empty())
}

/// gcud (the build `bin`) with `config`, once it is ready; its client
/// listener's address.
pub fn spawn_gcud(bin: &str, config: &str, dir: &tempfile::TempDir) -> (Proc, String) {
    let path = dir.path().join("gcud.toml");
    std::fs::write(&path, config).expect("config");
    let log_path = dir.path().join("gcud.log");
    let child = Proc(
        Command::new(bin)
            .arg("--config")
            .arg(&path)
            .env("RUST_LOG", "info")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log_path).expect("log"))
            .spawn()
            .expect("spawn gcud"),
    );
    let started = Instant::now();
    loop {
        let log = std::fs::read_to_string(&log_path).unwrap_or_default();
        if let Some(addr) = log
            .lines()
            .find(|l| l.contains("listening link=clients"))
            .and_then(|l| l.split("addr=").nth(1))
            .and_then(|a| a.split_whitespace().next())
        {
            return (child, addr.to_owned());
        }
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "gcud did not start:\n{log}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A free port on 127.0.0.1 (bound, then released).
pub fn free_addr() -> String {
    let probe = std::net::TcpListener::bind("127.0.0.1:0").expect("probe");
    probe.local_addr().expect("address").to_string()
}

/// Whether socat is on PATH (`cargo bench --bench gcud` installs it).
pub fn socat_present() -> bool {
    Command::new("socat")
        .arg("-V")
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Ports listening on 127.0.0.1 (from /proc/net/tcp, without connecting:
/// a socat relay serves its first connection only).
fn listening() -> std::collections::HashSet<u16> {
    std::fs::read_to_string("/proc/net/tcp")
        .unwrap_or_default()
        .lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let (ip, port) = f.get(1)?.split_once(':')?;
            (ip == "0100007F" && f.get(3) == Some(&"0A")).then(|| u16::from_str_radix(port, 16).ok())?
        })
        .collect()
}

/// One socat per pty, TCP on 127.0.0.1 to the pty's slave, raw: the relays
/// and their addresses, once all listen.
pub fn spawn_socats(ptys: &[String]) -> Vec<(Proc, String)> {
    let relays: Vec<(Proc, String, u16)> = ptys
        .iter()
        .map(|pty| {
            let addr = free_addr();
            let port: u16 = addr.rsplit(':').next().and_then(|p| p.parse().ok()).expect("port");
            let child = Command::new("socat")
                .arg(format!("TCP-LISTEN:{port},bind=127.0.0.1,reuseaddr,nodelay"))
                .arg(format!("{pty},raw,echo=0"))
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("spawn socat");
            (Proc(child), addr, port)
        })
        .collect();
    let started = Instant::now();
    while !relays.iter().all(|(_, _, p)| listening().contains(p)) {
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "the socat relays did not listen"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    relays.into_iter().map(|(p, a, _)| (p, a)).collect()
}

/// What processes spent: CPU (nanoseconds on a core, summed over their
/// live threads from `/proc/PID/task/TID/schedstat`: `utime + stime` in
/// clock ticks rounds each process to 10 ms, as much as 8 socat relays
/// spend in a paced window), context switches (voluntary and not, over
/// their live threads), and resident memory (KiB); each thread's CPU, for
/// the busiest one (which bounds a process's throughput once it fills its
/// core).
#[derive(Debug, Clone, Default)]
pub struct Usage {
    pub cpu_ns: u64,
    pub switches: u64,
    pub rss_kib: u64,
    /// CPU by thread id.
    pub threads: Vec<(u64, u64)>,
}

impl Usage {
    pub fn of(pids: &[u32]) -> Self {
        let mut total = Self::default();
        for &pid in pids {
            let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
            total.rss_kib += status
                .lines()
                .find_map(|l| l.strip_prefix("VmRSS:"))
                .and_then(|v| v.split_whitespace().next()?.parse::<u64>().ok())
                .unwrap_or(0);
            for task in std::fs::read_dir(format!("/proc/{pid}/task"))
                .into_iter()
                .flatten()
                .flatten()
            {
                let schedstat = std::fs::read_to_string(task.path().join("schedstat")).unwrap_or_default();
                let ns = schedstat
                    .split_whitespace()
                    .next()
                    .and_then(|ns| ns.parse::<u64>().ok())
                    .unwrap_or(0);
                total.cpu_ns += ns;
                let tid = task.file_name().to_string_lossy().parse().unwrap_or(0);
                total.threads.push((tid, ns));
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

    /// CPU and switches since `before`; the resident memory now.
    pub fn since(self, before: Self) -> Self {
        let threads = self
            .threads
            .iter()
            .map(|&(tid, ns)| {
                let was = before.threads.iter().find(|t| t.0 == tid).map_or(0, |t| t.1);
                (tid, ns.saturating_sub(was))
            })
            .collect();
        Self {
            cpu_ns: self.cpu_ns.saturating_sub(before.cpu_ns),
            switches: self.switches.saturating_sub(before.switches),
            rss_kib: self.rss_kib,
            threads,
        }
    }

    /// CPU seconds.
    pub fn cpu_seconds(&self) -> f64 {
        self.cpu_ns as f64 / 1e9
    }

    /// CPU seconds of the busiest thread.
    pub fn busiest_seconds(&self) -> f64 {
        self.threads.iter().map(|t| t.1).max().unwrap_or(0) as f64 / 1e9
    }
}

/// The machine's busy and total CPU time so far (`/proc/stat`, clock
/// ticks): whether its cores were all taken in a window.
pub fn machine_ticks() -> (u64, u64) {
    let stat = std::fs::read_to_string("/proc/stat").unwrap_or_default();
    let fields: Vec<u64> = stat
        .lines()
        .next()
        .unwrap_or_default()
        .split_whitespace()
        .skip(1)
        .filter_map(|f| f.parse().ok())
        .collect();
    let total: u64 = fields.iter().take(8).sum();
    // idle and iowait
    let idle = fields.get(3).copied().unwrap_or(0) + fields.get(4).copied().unwrap_or(0);
    (total - idle, total)
}

fn metrics_text(addr: &str) -> String {
    let mut s = TcpStream::connect(addr).expect("metrics");
    s.write_all(format!("GET /metrics HTTP/1.0\r\nHost: {addr}\r\n\r\n").as_bytes())
        .expect("request");
    let mut body = String::new();
    s.read_to_string(&mut body).expect("response");
    body
}

/// A counter (no labels) from gcud's `/metrics` at `addr`.
pub fn counter(addr: &str, name: &str) -> u64 {
    metrics_text(addr)
        .lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(' '))
        .and_then(|v| v.trim().parse::<f64>().ok())
        .map_or(0, |v| v as u64)
}

/// gcud's heap allocations so far.
pub fn allocations(addr: &str) -> u64 {
    counter(addr, "gcud_heap_allocations_total")
}

/// The machine's load average (1 minute) and its cores' busy share since
/// the last call, for the figures' context.
pub fn load() -> String {
    let avg = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    format!(
        "load average {}",
        avg.split_whitespace().take(3).collect::<Vec<_>>().join(" ")
    )
}
