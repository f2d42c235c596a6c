//! End-to-end tests of `gimbal-visca` (issue 50): the real gcud with
//! simulated gimbal buses, the real gimbal-visca in front of it, driven by
//! the PyPI `visca-over-ip` package's `Camera` (`tests/visca/client.py`,
//! VISCA over IP on UDP), the npm `visca-over-ip` package (`tcp.js`: its
//! messages over raw VISCA on TCP, and its own UDP camera), and raw
//! datagrams for what no client sends on purpose (floods, malformed
//! frames, old sequence numbers, a second client address). One module per
//! concern. What the gimbal did is read on the bus side (`gimbalctl
//! position` through gcud, the frames the simulated gimbal received and
//! from which source group), never from the door's own account.
//!
//! The PyPI client binds its inquiry socket to the camera's port on every
//! address with SO_REUSEADDR, so the door listens on 127.0.0.2 with
//! `reuse_address`, and the client's datagrams come from 127.0.0.1.

#[path = "../support/mod.rs"]
mod support;

mod attack;
mod clients;
mod metrics;
mod raw;

use serde_json::Value;
use support::door::{DOOR_GROUP, Door};
use support::gcud::Gcud;

const MAST: &str = "5.1.1";
/// The door's address: not the client's (`127.0.0.1`).
const HOST: &str = "127.0.0.2";

fn client_available() -> bool {
    support::door::python_client_available("visca_over_ip", "visca-over-ip")
}

/// gcud with its simulated buses and gimbal-visca in front of it.
struct Stack {
    /// Declared first: dropped (stopped) before gcud.
    door: Door,
    gcud: Gcud,
    /// The camera's UDP port (on [`HOST`]) and TCP port (on 127.0.0.1).
    port: u16,
    tcp: u16,
}

/// The door's configuration: one camera, `lease_ms` its motion lease,
/// `extra` more top-level keys.
fn config(gcud: &str, lease_ms: u64, extra: &str) -> String {
    format!(
        "gcud = \"{gcud}\"\nsource_group = {DOOR_GROUP}\npoll_ms = 50\nmotion_lease_ms = {lease_ms}\n{extra}\
         [[gimbal]]\nname = \"mast-1\"\naddress = \"{MAST}\"\nvisca_udp = \"{HOST}:{port}\"\nvisca_tcp = \"127.0.0.1:0\"\nreuse_address = true\n",
        port = camera_port(),
    )
}

/// A UDP port for the camera that no socket holds on any address, below
/// the kernel's ephemeral range: the PyPI client binds the camera's port
/// on every address at each step, and a port the door took on 127.0.0.2
/// alone (`:0`) could be another program's ephemeral port on 127.0.0.1
/// ("Address already in use" once in a few runs of a busy suite).
fn camera_port() -> u16 {
    use std::sync::atomic::{AtomicU32, Ordering};
    static TAKEN: AtomicU32 = AtomicU32::new(0);
    let ephemeral: u32 = std::fs::read_to_string("/proc/sys/net/ipv4/ip_local_port_range")
        .ok()
        .and_then(|r| r.split_whitespace().next()?.parse().ok())
        .unwrap_or(32768);
    let span = 8000;
    let base = ephemeral.saturating_sub(span).max(1024);
    // Test processes run side by side: each starts elsewhere in the span.
    let start = std::process::id().wrapping_mul(7919) % span;
    (0..span)
        .map(|_| base + (start + TAKEN.fetch_add(1, Ordering::Relaxed)) % span)
        .find(|&p| std::net::UdpSocket::bind(("0.0.0.0", p as u16)).is_ok())
        .expect("a free UDP port below the ephemeral range") as u16
}

impl Stack {
    fn start() -> Self {
        Self::start_with(5000, "")
    }

    fn start_with(lease_ms: u64, extra: &str) -> Self {
        let gcud = support::door::start_gcud();
        let text = config(&gcud.clients(), lease_ms, extra);
        Self::start_configured(gcud, &text)
    }

    fn start_configured(gcud: Gcud, text: &str) -> Self {
        let mut door = Door::new("gimbal-visca", env!("CARGO_BIN_EXE_gimbal-visca"));
        door.start(text);
        let port = door.port("VISCA over IP (UDP) bound");
        let tcp = door.port("raw VISCA over TCP listening");
        Self { door, gcud, port, tcp }
    }

    /// One step of the PyPI client (`tests/visca/client.py STEP ...`).
    fn step(&self, step: &str, args: &[&str]) -> Value {
        let port = self.port.to_string();
        let mut all = vec![HOST, port.as_str()];
        all.extend_from_slice(args);
        support::door::python_step("tests/visca/client.py", step, &all, || self.door.log())
    }

    /// What the mast gimbal received from the door (payloads, in order).
    fn door_frames(&self) -> Vec<String> {
        self.gcud
            .received(MAST)
            .into_iter()
            .filter(|(source, _)| *source == DOOR_GROUP)
            .map(|(_, p)| p)
            .collect()
    }

    fn position(&self) -> (f64, f64) {
        self.gcud.position(MAST)
    }
}
