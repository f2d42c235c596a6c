//! End-to-end tests of `gimbal-mavlink` (issues 25, 33): the real gcud with
//! simulated gimbal buses, the real gimbal-mavlink in front of it, driven by
//! a third-party MAVLink library from PyPI (pymavlink) through
//! `tests/mavlink/gcs.py` (`signed.py` when it signs), one module per
//! concern (`basics`, `control`, `commands`, `earth`, `robust`, `config`,
//! `signing`). What the gimbal did is read on the bus side, with
//! `gimbalctl position` through gcud and the frames the simulated gimbal
//! received (their source group tells gimbal-mavlink's own stops from gcud's
//! dead-man), never from gimbal-mavlink's own account. Everything is on
//! 127.0.0.1; waits are polls with a hang guard, never wall-clock assertions.
//!
//! Without Python and pymavlink (and numpy, which its quaternion module
//! needs) the client tests are skipped with a notice, except under
//! `CI=true`, where they fail.

#[path = "../support/mod.rs"]
mod support;

mod basics;
mod commands;
mod config;
mod control;
mod earth;
mod metrics;
mod robust;
mod signing;
mod tls;

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde_json::Value;
use support::door::{DOOR_GROUP, Door};
use support::eventually;
use support::gcud::Gcud;

const MAST: &str = "5.1.1";
/// MAV_RESULT values (common.xml).
const ACCEPTED: i64 = 0;
const DENIED: i64 = 2;
const UNSUPPORTED: i64 = 3;
const FAILED: i64 = 4;
/// The ground station's ids, and another component of the same system.
const GCS: (u8, u8) = (255, 190);
const OTHER: (u8, u8) = (255, 191);

fn client_available() -> bool {
    support::door::mavlink_client_available()
}

/// gcud with two simulated buses (the mast gimbal on bus 1; bus 2 has no
/// device 9, the absent gimbal) and gimbal-mavlink in front of it.
struct Stack {
    /// Declared first: dropped (stopped) before gcud.
    mavlink: Door,
    gcud: Gcud,
    /// The UDP endpoint's port, and the TCP endpoint's.
    port: u16,
    tcp_port: u16,
}

fn mavlink_config(gcud: &str, lease_ms: u64, extra_endpoint: &str) -> String {
    format!(
        r#"gcud = "{gcud}"
system_id = 1
lease_ms = {lease_ms}
[[endpoint]]
udp_listen = "127.0.0.1:0"
[[endpoint]]
tcp_listen = "127.0.0.1:0"
[[gimbal]]
name = "mast-1"
address = "{MAST}"
component_id = 154
pan_deg = [-180.0, 180.0]
tilt_deg = [-90.0, 90.0]
[[gimbal]]
name = "absent"
address = "5.2.9"
component_id = 171
{extra_endpoint}
"#
    )
}

impl Stack {
    fn start() -> Self {
        Self::start_with_lease(1000)
    }

    fn start_with_lease(lease_ms: u64) -> Self {
        Self::start_with(lease_ms, "")
    }

    /// With one more `[[endpoint]]` (TOML text) after the UDP and TCP ones.
    fn start_with(lease_ms: u64, extra_endpoint: &str) -> Self {
        Self::start_on(support::door::start_gcud(), lease_ms, extra_endpoint)
    }

    /// In front of the governed gcud (`support::door::start_governed_gcud`:
    /// the doors' link at priority 50, the operators' at 80).
    fn start_governed() -> Self {
        Self::start_on(support::door::start_governed_gcud(), 1000, "")
    }

    fn start_on(gcud: Gcud, lease_ms: u64, extra_endpoint: &str) -> Self {
        let config = mavlink_config(&gcud.clients(), lease_ms, extra_endpoint);
        Self::start_configured(gcud, "", &config)
    }

    /// With `top` keys (the mount's place) and `mast` keys added to the
    /// mast gimbal's table (`mount_heading_deg`).
    fn start_mast(top: &str, mast: &str) -> Self {
        let gcud = support::door::start_gcud();
        let config = mavlink_config(&gcud.clients(), 1000, "").replace(
            "tilt_deg = [-90.0, 90.0]\n",
            &format!("tilt_deg = [-90.0, 90.0]\n{mast}\n"),
        );
        Self::start_configured(gcud, top, &config)
    }

    fn start_configured(gcud: Gcud, top: &str, config: &str) -> Self {
        let mut mavlink = Door::new("gimbal-mavlink", env!("CARGO_BIN_EXE_gimbal-mavlink"));
        // Each client step is a process of its own, so a holder of control
        // is silent between steps: a lapse longer than any test.
        mavlink.start(&format!(
            "source_group = {DOOR_GROUP}\ncontrol_lapse_ms = 60000\n{top}\n{config}"
        ));
        Self {
            port: mavlink.port("MAVLink UDP endpoint bound"),
            tcp_port: mavlink.port("MAVLink TCP endpoint listening"),
            mavlink,
            gcud,
        }
    }

    fn log_path(&self) -> PathBuf {
        self.mavlink.log_path()
    }

    fn log(&self) -> String {
        self.mavlink.log()
    }

    fn signal(&mut self, signal: nix::sys::signal::Signal) -> std::process::ExitStatus {
        self.mavlink.signal(signal)
    }

    /// Runs one step of the pymavlink ground station as `who`, over UDP.
    fn gcs(&self, step: &str, who: (u8, u8), args: Value) -> Value {
        self.gcs_over(&self.port.to_string(), step, who, args)
    }

    /// The same over `connection` (a UDP port, or pymavlink's `tcp:HOST:PORT`).
    fn gcs_over(&self, connection: &str, step: &str, who: (u8, u8), args: Value) -> Value {
        let (system, component, args) = (who.0.to_string(), who.1.to_string(), args.to_string());
        support::door::python_step(
            "tests/mavlink/gcs.py",
            step,
            &[connection, &system, &component, &args],
            || self.log(),
        )
    }

    fn wait_moving(&self, from: (f64, f64)) {
        support::door::wait_moving(&self.gcud, MAST, from);
    }
}

/// The counters gimbal-mavlink logs when it stops, and a reader of one.
fn counters(log: &str) -> (String, impl Fn(&str) -> u64 + use<>) {
    let summary = log
        .lines()
        .find(|l| l.contains("counters="))
        .unwrap_or_else(|| panic!("{log}"))
        .to_owned();
    let line = summary.replace("counters=", "counters= ");
    let counter = move |name: &str| -> u64 {
        let prefix = format!("{name}=");
        line.split([' ', '"'])
            .find_map(|token| token.strip_prefix(&prefix))
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no counter {name} in {line}"))
    };
    (summary, counter)
}

/// Position `(pan, tilt)` unchanged over about a second on the bus side.
fn assert_still(stack: &Stack, at: (f64, f64), what: &str) {
    support::door::assert_still(&stack.gcud, MAST, at, what);
}

/// MAV_CMD values (common.xml).
const DO_GIMBAL_MANAGER_PITCHYAW: i64 = 1000;
const REQUEST_MESSAGE: i64 = 512;
const DO_SET_SERVO: i64 = 183;
const DO_MOUNT_CONTROL: i64 = 205;
const DO_MOUNT_CONFIGURE: i64 = 204;
const DO_SET_ROI_LOCATION: i64 = 195;
const DO_SET_ROI_NONE: i64 = 197;

/// GIMBAL_MANAGER_FLAGS (common.xml).
const ROLL_LOCK: u32 = 4;
const PITCH_LOCK: u32 = 8;
const YAW_LOCK: u32 = 16;
const YAW_IN_VEHICLE_FRAME: u32 = 32;
const YAW_IN_EARTH_FRAME: u32 = 64;
