//! End-to-end tests of `gimbal-pelco` (issue 50): the real gcud with
//! simulated gimbal buses, the real gimbal-pelco in front of it, driven by
//! a CCTV keyboard: the PyPI `pyptzcontroller` package (Pelco-D over a
//! serial port, here a pseudo-terminal joined to the door's: a null-modem
//! cable) through `tests/pelco/client.py`, and a keyboard written here for
//! what that package does not speak (Pelco-P, TCP and UDP inputs, damaged
//! frames, floods). What the gimbal did is read on the bus side, with
//! `gimbalctl position` through gcud and the frames the simulated gimbal
//! received (their source group tells the door's frames from gcud's),
//! never from the door's own account. Everything is on 127.0.0.1; waits
//! are polls with a hang guard, never wall-clock assertions. One module
//! per concern: `keyboard` (pyptzcontroller), `wire` (Pelco-P, TCP, UDP,
//! damaged frames), `attack` (floods, a second keyboard).

#[path = "../support/mod.rs"]
mod support;

mod attack;
mod keyboard;
mod metrics;
mod wire;

use std::io::{Read, Write};
use std::net::{TcpStream, UdpSocket};
use std::time::Duration;

use serde_json::Value;
use support::door::{DOOR_GROUP, Door, NullModem};
use support::gcud::Gcud;

const MAST: &str = "5.1.1";

/// gcud with the simulated mast gimbal (5.1.1) and gimbal-pelco in front
/// of it: a Pelco-D serial input on one end of a null-modem cable, a
/// Pelco-D TCP input, a Pelco-P TCP input and a Pelco-D UDP input.
struct Stack {
    /// Declared first: stopped before gcud.
    door: Door,
    gcud: Gcud,
    cable: NullModem,
    /// Pelco-D over TCP, Pelco-P over TCP, Pelco-D over UDP.
    d_tcp: u16,
    p_tcp: u16,
    d_udp: u16,
}

/// The door's configuration in front of `gcud` with `lease_ms`, its serial
/// input on `serial`; `extra`: more top-level keys. A drive may run ten
/// minutes (`max_move_ms`): only the lease or a stop ends it within a
/// test's hang guard.
fn door_config(gcud: &str, lease_ms: u64, serial: &str, extra: &str) -> String {
    format!(
        r#"gcud = "{gcud}"
source_group = {DOOR_GROUP}
motion_lease_ms = {lease_ms}
max_move_ms = 600000
poll_ms = 200
{extra}
[[input]]
serial = "{serial}"
protocol = "pelco-d"
[[input]]
tcp_listen = "127.0.0.1:0"
protocol = "pelco-d"
[[input]]
tcp_listen = "127.0.0.1:0"
protocol = "pelco-p"
[[input]]
udp_listen = "127.0.0.1:0"
protocol = "pelco-d"
[[gimbal]]
name = "mast-1"
address = "{MAST}"
pelco_address = 1
"#
    )
}

impl Stack {
    fn start() -> Self {
        Self::start_with(1000, "")
    }

    fn start_with(lease_ms: u64, extra: &str) -> Self {
        let gcud = support::door::start_gcud();
        let cable = NullModem::new();
        let config = door_config(&gcud.clients(), lease_ms, &cable.ends.0.display().to_string(), extra);
        Self::start_configured(gcud, cable, &config)
    }

    fn start_configured(gcud: Gcud, cable: NullModem, config: &str) -> Self {
        let mut door = Door::new("gimbal-pelco", env!("CARGO_BIN_EXE_gimbal-pelco"));
        door.start(config);
        support::wait_for_log_line(&door.log_path(), "serial line open");
        Self {
            d_tcp: door.port("input[1] tcp_listen"),
            p_tcp: door.port("input[2] tcp_listen"),
            d_udp: door.port("input[3] udp_listen"),
            door,
            gcud,
            cable,
        }
    }

    /// One step of the pyptzcontroller keyboard on the cable's other end.
    fn keyboard(&self, step: &str, args: &[&str]) -> Value {
        let serial = self.cable.ends.1.display().to_string();
        let mut full = vec![serial.as_str()];
        full.extend_from_slice(args);
        support::door::python_step("tests/pelco/client.py", step, &full, || self.door.log())
    }

    fn position(&self) -> (f64, f64) {
        self.gcud.position(MAST)
    }

    fn settled(&self) -> (f64, f64) {
        self.gcud.settled_position(MAST)
    }

    /// The door's frames on the mast's bus, by the gimbal's own record.
    fn door_frames(&self) -> Vec<String> {
        self.gcud
            .received(MAST)
            .into_iter()
            .filter(|(from, _)| *from == DOOR_GROUP)
            .map(|(_, p)| p)
            .collect()
    }
}

fn client_available() -> bool {
    support::door::python_client_available("ptz_control_lib, serial", "pyptzcontroller and pyserial")
}

/// A Pelco-D frame to camera `address` (the "D" Protocol manual's format).
fn pelco_d(address: u8, body: [u8; 4]) -> Vec<u8> {
    let mut f = vec![0xFF, address, body[0], body[1], body[2], body[3]];
    f.push(f[1..].iter().fold(0u8, |s, b| s.wrapping_add(*b)));
    f
}

/// A Pelco-P frame to wire address `address` (camera 1 is 0).
fn pelco_p(address: u8, body: [u8; 4]) -> Vec<u8> {
    let mut f = vec![0xA0, address, body[0], body[1], body[2], body[3], 0xAF];
    f.push(f.iter().fold(0u8, |x, b| x ^ b));
    f
}

/// A keyboard on a TCP input.
fn tcp_keyboard(port: u16) -> TcpStream {
    let s = TcpStream::connect(("127.0.0.1", port)).expect("connect to the door");
    s.set_read_timeout(Some(support::HANG_GUARD)).expect("timeout");
    s
}

/// Sends `frame` every 100 ms for `seconds`, as a keyboard repeats it
/// while the stick is held.
fn hold(send: &mut dyn FnMut(&[u8]), frame: &[u8], seconds: f64) {
    let n = (seconds * 10.0) as usize;
    for _ in 0..n.max(1) {
        send(frame);
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Reads one answer of `len` bytes from a TCP keyboard.
fn read_answer(s: &mut TcpStream, len: usize) -> Vec<u8> {
    let mut buf = vec![0u8; len];
    s.read_exact(&mut buf).expect("an answer from the door");
    buf
}

/// Sends on a TCP keyboard.
fn send_tcp(s: &mut TcpStream, bytes: &[u8]) {
    s.write_all(bytes).expect("write to the door");
}

/// A keyboard on a UDP input, its answers read with a hang guard.
fn udp_keyboard() -> UdpSocket {
    let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
    s.set_read_timeout(Some(support::HANG_GUARD)).expect("timeout");
    s
}

/// The door's resident and peak memory, kB (`/proc/PID/status`).
fn memory_kb(pid: u32) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("status");
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or(0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}
