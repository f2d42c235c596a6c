//! What the front-door benchmarks share (`benches/onvif.rs`,
//! `benches/mavlink.rs`): gcud and the door started with their logs in
//! files, the addresses they log, and a relay between gcud's TCP port and
//! gimbalsim that tells when a motion command reaches the bus side.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Command, Stdio};
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
    /// The instant each motion command reaches the bus side.
    pub motions: mpsc::Receiver<Instant>,
    procs: Vec<Proc>,
}

impl Stack {
    /// gimbalsim, the relay and gcud, running.
    pub fn start(gimbalsim: &str, gcud: &str) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        let (sim, sim_addr) = crate::support::gimbalsim(gimbalsim, &["--tcp", "127.0.0.1:0"]);
        let port_listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let port_addr = port_listener.local_addr().expect("addr").to_string();
        let (motions_tx, motions) = mpsc::channel();
        std::thread::spawn(move || relay(port_listener, sim_addr, motions_tx));
        let config = dir.path().join("gcud.toml");
        std::fs::write(
            &config,
            format!(
                "[gcu]\ngroup = 5\n[[port]]\nid = 1\ntcp = \"{port_addr}\"\n[[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n"
            ),
        )
        .expect("config");
        let log = dir.path().join("gcud.log");
        let gcud = spawn(gcud, &["--config", config.to_str().expect("path")], &log);
        let clients = addr_in(&log_line(&log, "listening link=clients"));
        Self {
            dir,
            clients,
            motions,
            procs: vec![sim, gcud],
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
            .env("RUST_LOG", "warn,gimbal_onvif=info,gimbal_mavlink=info,gcud=info")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).expect("log"))
            .spawn()
            .expect("spawn"),
    )
}

/// Relays gcud's port connection to the simulator, sending the instant each
/// motion command (`PR`, `PL`) reaches the bus side.
pub fn relay(listener: TcpListener, sim: String, motions: mpsc::Sender<Instant>) {
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
                    if matches!(f.payload(), b"PR" | b"PL") {
                        let _ = motions.send(at);
                    }
                }
            }
            if taken == 0 {
                break;
            }
        }
    }
}
