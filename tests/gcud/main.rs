//! End-to-end tests of the `gcud` daemon: the real binary, real simulated
//! gimbals (`gimbalsim`) on pseudo-terminals, TCP on 127.0.0.1 only.
//! Nothing here asserts on wall-clock speed; waits are polls with a hang guard.

#[path = "../support/mod.rs"]
mod support;

mod delivery;
mod lifecycle;
mod limits;
mod routing;
mod status;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use sagebrush_protocol::{ACK, Address, Command as Cmd, Event, FrameBuf, Framer, OwnedEvent, Position, Reply};

use support::gcud::{CLIENTS, Gcud, METRICS, WireClient, port_entry};
use support::{HANG_GUARD, Sim, eventually};

/// Connects to `addr` and requires gcud to close the connection without
/// a byte: end of stream or reset. A read that times out (after the
/// generous [`HANG_GUARD`]: only a hang, never a slow machine, reaches it)
/// means the connection was kept, and fails.
fn assert_closed_by_gcud(addr: &str, what: &str) {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(HANG_GUARD)).expect("timeout");
    let mut buf = [0u8; 1];
    match s.read(&mut buf) {
        Ok(0) => {}
        Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {}
        Ok(n) => panic!("{what}: gcud wrote {n} byte(s) instead of closing"),
        Err(e) => panic!("{what}: gcud did not close the connection ({e})"),
    }
}

/// Once port 1 is open, a wire client starts `slew` on gimbal 5.1.1 and
/// sees the gimbal move; returns where it started and the client.
fn start_slew(gcud: &Gcud, slew: &Cmd<'_>) -> ((f64, f64), WireClient) {
    gcud.wait_for_log("port open port=1");
    let start = gcud.position("5.1.1");
    let mut client = WireClient::connect(&gcud.clients());
    client.send(Address::new(5, 1, 1), 0, slew);
    assert_eq!(client.next(), OwnedEvent::Ack);
    eventually("the slew to move the gimbal", || gcud.position("5.1.1") != start);
    (start, client)
}

/// Two GCUs: group 2 has the clients and a downstream link to group 5,
/// which has port 1 with gimbal 1 only (device 2 is silent; port 9 does
/// not exist).
fn two_gcus(sim: &Sim) -> (Gcud, Gcud) {
    let free = std::net::TcpListener::bind("127.0.0.1:0").expect("probe a free port");
    let addr = free.local_addr().expect("address").to_string();
    drop(free);
    let gcu5 = Gcud::start(&format!(
        "[gcu]\ngroup = 5\n{CLIENTS}{METRICS}{}[[link]]\nname = \"gcus\"\nrole = \"upstream\"\nlisten = \"{addr}\"\n",
        port_entry(1, sim)
    ));
    gcu5.wait_for_log("port open port=1");
    let gcu2 = Gcud::start(&format!(
        "[gcu]\ngroup = 2\ndefault_route = \"gcu5\"\n{CLIENTS}{METRICS}[[link]]\nname = \"gcu5\"\nrole = \"downstream\"\nconnect = \"{addr}\"\n"
    ));
    gcu2.wait_for_log("link connected");
    (gcu5, gcu2)
}

/// A client (kept connected, returned) starts a slew of gimbal 5.1.1; gcud
/// must stop it mid-way by itself (lease, idle time-out, ...).
fn slew_that_gcud_stops(gcud: &Gcud) -> WireClient {
    let (start, client) = start_slew(gcud, &Cmd::PanRight);
    let stopped = gcud.settled_position("5.1.1");
    assert!(
        stopped.0 > start.0 && stopped.0 < 180.0,
        "stopped mid-way, not at a limit: {stopped:?}"
    );
    client
}

impl Gcud {
    fn config_path(&self) -> PathBuf {
        self.dir.path().join("gcud.toml")
    }

    /// Writes a new configuration file and sends SIGHUP; returns once the
    /// daemon logged `done` for the `nth` reload (1 = the first).
    fn reload(&self, config: Option<&str>, nth: usize, done: &str) {
        match config {
            Some(text) => std::fs::write(self.config_path(), text).expect("write config"),
            None => std::fs::remove_file(self.config_path()).expect("remove config"),
        }
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGHUP).expect("SIGHUP");
        eventually(&format!("reload {nth} to end with {done:?}"), || {
            let log = self.log();
            log.matches("SIGHUP: reloading").count() >= nth
                && log
                    .split("SIGHUP: reloading")
                    .nth(nth)
                    .is_some_and(|after| after.contains(done))
        });
    }
}

impl Gcud {
    fn rss_kib(&self) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).expect("proc status");
        let line = status.lines().find(|l| l.starts_with("VmRSS:")).expect("VmRSS");
        line.split_whitespace()
            .nth(1)
            .and_then(|v| v.parse().ok())
            .expect("RSS in kB")
    }
}
