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
