//! What the front-door benchmarks share (`benches/onvif.rs`,
//! `benches/mavlink.rs`): gcud and the door started with their logs in
//! files, the addresses they log, and the bus: a relay between gcud's TCP
//! port and gimbalsim, or an instant device on a pty timed at a bit rate,
//! either telling when a motion or a stop command reaches the bus.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use sagebrush_protocol::{Event, Framer};

use crate::support::Proc;

/// gimbalsim behind the [`relay`], gcud with the relay as its `tcp` port 1
/// and a client listener, and then the door: the bench's whole stack.
pub struct Stack {
    pub dir: tempfile::TempDir,
    /// gcud's client listener, for the door's `gcud` key.
    pub clients: String,
    /// Each command reaching the bus side: its mnemonic and the instant
    /// its first byte did.
    pub bus: mpsc::Receiver<(&'static str, Instant)>,
    procs: Vec<Proc>,
    /// Set when the stack goes: the paced device's thread ends.
    done: Arc<AtomicBool>,
}

/// Pan directions and the pan speed, as the benches' moves (pan only) use them.
const PAN: [&str; 2] = ["PR", "PL"];
const PAN_SPEED: &str = "SPn";
const PAN_STOP: &str = "PS";

impl Stack {
    /// The commands a request put on the bus: those heard until no
    /// command but the session's position polls (`P?`) comes for `quiet`
    /// (longer than a NIC window), at most 5 s.
    pub fn heard(&self, quiet: Duration) -> Vec<(&'static str, Instant)> {
        let mut heard = Vec::new();
        let started = Instant::now();
        let mut last = started;
        while last.elapsed() < quiet && started.elapsed() < Duration::from_secs(5) {
            if let Ok(event) = self.bus.recv_timeout(quiet.saturating_sub(last.elapsed())) {
                if event.0 != "P?" {
                    last = Instant::now();
                }
                heard.push(event);
            }
        }
        heard
    }

    /// Forgets what the bus heard so far.
    pub fn drain(&self) {
        while self.bus.try_recv().is_ok() {}
    }
}

/// When a pan move began at the speed asked for: the first direction
/// command after the move's last speed command (a direction sent before it
/// runs at the speed set before), or the first direction when the speed
/// was already set.
pub fn pan_at_speed(heard: &[(&str, Instant)]) -> Option<Instant> {
    let from = heard.iter().rposition(|(m, _)| *m == PAN_SPEED).unwrap_or(0);
    heard[from..].iter().find(|(m, _)| PAN.contains(m)).map(|&(_, at)| at)
}

/// When the pan stop reached the bus.
pub fn pan_stop(heard: &[(&str, Instant)]) -> Option<Instant> {
    heard.iter().find(|(m, _)| *m == PAN_STOP).map(|&(_, at)| at)
}

impl Drop for Stack {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Relaxed);
    }
}

/// gcud's configuration with port 1 as `port` (a TOML key and value).
fn gcud_config(port: &str) -> String {
    format!(
        "[gcu]\ngroup = 5\n[[port]]\nid = 1\n{port}\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n"
    )
}

impl Stack {
    /// gimbalsim, the relay and gcud, running.
    pub fn start(gimbalsim: &str, gcud: &str) -> Self {
        let (sim, sim_addr) = crate::support::gimbalsim(gimbalsim, &["--tcp", "127.0.0.1:0"]);
        let port_listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let port_addr = port_listener.local_addr().expect("addr").to_string();
        let (bus_tx, bus) = mpsc::channel();
        std::thread::spawn(move || relay(port_listener, sim_addr, bus_tx));
        // One gimbal behind the device server, point to point: full duplex.
        let mut stack = Self::gcud(gcud, &format!("tcp = \"{port_addr}\"\nduplex = \"full\""), bus);
        stack.procs.push(sim);
        stack
    }

    /// gcud with port 1 on a pty at `baud`, its other side the instant
    /// device of `support::paced_device`, the line timed at that rate.
    pub fn paced(gcud: &str, baud: u32) -> Self {
        let (pty, path) = crate::support::pty();
        let (bus_tx, bus) = mpsc::channel();
        let done = Arc::new(AtomicBool::new(false));
        let device_done = Arc::clone(&done);
        std::thread::spawn(move || {
            crate::support::paced_device(pty, baud, &device_done, |mnemonic, at| {
                let _ = bus_tx.send((mnemonic, at));
            })
        });
        // RS-232 point to point: full duplex.
        let mut stack = Self::gcud(
            gcud,
            &format!("path = \"{path}\"\nbaud = {baud}\nduplex = \"full\""),
            bus,
        );
        stack.done = done;
        stack
    }

    fn gcud(gcud: &str, port: &str, bus: mpsc::Receiver<(&'static str, Instant)>) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let config = dir.path().join("gcud.toml");
        std::fs::write(&config, gcud_config(port)).expect("config");
        let log = dir.path().join("gcud.log");
        let gcud = spawn(gcud, &["--config", config.to_str().expect("path")], &log);
        let clients = addr_in(&log_line(&log, "listening link=clients"));
        Self {
            dir,
            clients,
            bus,
            procs: vec![gcud],
            done: Arc::default(),
        }
    }

    /// Starts the door `bin` (`name`) on configuration `config`; returns
    /// its log file's path.
    pub fn door(&mut self, bin: &str, name: &str, config: &str) -> std::path::PathBuf {
        let path = self.dir.path().join(format!("{name}.toml"));
        std::fs::write(&path, config).expect("config");
        let log = self.dir.path().join(format!("{name}.log"));
        self.procs
            .push(spawn(bin, &["--config", path.to_str().expect("path")], &log));
        log
    }
}

/// Prints p50 and p99 of `latencies` for `what`; on a paced bus at `baud`,
/// beside the line-time limit of the `bytes` the operation needs on the
/// line and issue 35's goal for p50 (twice the limit plus 2 ms; 5 ms at
/// 115200 bit/s and above). Figures, never asserted.
pub fn report(what: &str, baud: Option<u32>, bytes: u32, mut latencies: Vec<Duration>) {
    latencies.sort();
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let (p50, p99) = (
        ms(crate::support::percentile(&latencies, 0.5)),
        ms(crate::support::percentile(&latencies, 0.99)),
    );
    let Some(baud) = baud else {
        return println!(
            "  {what} ({} samples): p50 {p50:.2} ms, p99 {p99:.2} ms",
            latencies.len()
        );
    };
    let limit = f64::from(bytes) * 10.0 / f64::from(baud) * 1e3;
    let goal = if baud >= 115_200 { 5.0 } else { 2.0 * limit + 2.0 };
    println!(
        "  {what} ({} samples): p50 {p50:.2} ms, p99 {p99:.2} ms; line-time limit ({bytes} bytes at {baud} bit/s) {limit:.2} ms, goal p50 <= {goal:.2} ms: {}",
        latencies.len(),
        if p50 <= goal { "met" } else { "not met" }
    );
}

/// The bytes a motion needs on the line before it starts: the speed frame
/// (10 bytes), its ACK and the first byte of the direction frame.
pub const MOTION_BYTES: u32 = 12;
/// The bytes a stop needs: the first byte of the stop frame.
pub const STOP_BYTES: u32 = 1;

pub fn env_count(name: &str, default: usize) -> usize {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
}

/// Waits for a line containing `text` in the log file; returns it.
pub fn log_line(path: &std::path::Path, text: &str) -> String {
    let started = Instant::now();
    loop {
        let log = std::fs::read_to_string(path).unwrap_or_default();
        if let Some(line) = log.lines().find(|l| l.contains(text)) {
            return line.to_owned();
        }
        assert!(
            started.elapsed() < Duration::from_secs(30),
            "no {text:?} in {}:\n{log}",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

pub fn addr_in(line: &str) -> String {
    line.split("addr=")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .expect("addr=")
        .to_owned()
}

pub fn spawn(bin: &str, args: &[&str], log: &std::path::Path) -> Proc {
    Proc(
        Command::new(bin)
            .args(args)
            .env(
                "RUST_LOG",
                "warn,gimbal_onvif=info,gimbal_mavlink=info,gimbal_visca=info,gimbal_pelco=info,gcud=info",
            )
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).expect("log"))
            .spawn()
            .expect("spawn"),
    )
}

/// Relays gcud's port connection to the simulator, sending each command's
/// mnemonic and the instant it reaches the bus side.
pub fn relay(listener: TcpListener, sim: String, bus: mpsc::Sender<(&'static str, Instant)>) {
    let (from_gcud, _) = listener.accept().expect("gcud connects to its port");
    from_gcud.set_nodelay(true).expect("nodelay");
    let to_sim = TcpStream::connect(&sim).expect("connect to gimbalsim");
    to_sim.set_nodelay(true).expect("nodelay");
    let (mut back_from, mut back_to) = (
        to_sim.try_clone().expect("clone"),
        from_gcud.try_clone().expect("clone"),
    );
    std::thread::spawn(move || std::io::copy(&mut back_from, &mut back_to));
    let (mut from, mut to) = (from_gcud, to_sim);
    let mut framer: Framer = Framer::default();
    let mut buf = [0u8; 4096];
    loop {
        let n = match from.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        let at = Instant::now();
        if to.write_all(&buf[..n]).is_err() {
            return;
        }
        let mut rest = &buf[..n];
        while !rest.is_empty() {
            let taken = framer.push(rest);
            rest = &rest[taken..];
            while let Some(event) = framer.next_event() {
                if let Event::Frame(f) = event {
                    let _ = bus.send((sagebrush_protocol::Command::parse(f.payload()).mnemonic(), at));
                }
            }
            if taken == 0 {
                break;
            }
        }
    }
}
