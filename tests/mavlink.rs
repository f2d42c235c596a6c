//! End-to-end tests of `gimbal-mavlink` (issue 25): the real gcud with
//! simulated gimbal buses, the real gimbal-mavlink in front of it, driven by
//! a third-party MAVLink library from PyPI (pymavlink) through
//! `tests/mavlink/gcs.py`. What the gimbal did is read on the bus side, with
//! `gimbalctl position` through gcud and the frames the simulated gimbal
//! received (their source group tells gimbal-mavlink's own stops from gcud's
//! dead-man), never from gimbal-mavlink's own account. Everything is on
//! 127.0.0.1; waits are polls with a hang guard, never wall-clock assertions.
//!
//! Without Python and pymavlink (and numpy, which its quaternion module
//! needs) the client tests are skipped with a notice, except under
//! `CI=true`, where they fail.

mod support;

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde_json::{Value, json};
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
    support::door::python_client_available(
        "pymavlink.mavutil, pymavlink.quaternion, serial",
        "pymavlink, numpy and pyserial (pip install pymavlink==2.4.50 numpy==2.4.6 pyserial==3.5)",
    )
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
        let mut mavlink = Door::new("gimbal-mavlink", env!("CARGO_BIN_EXE_gimbal-mavlink"));
        let config = mavlink_config(&gcud.clients(), lease_ms, extra_endpoint);
        // Each client step is a process of its own, so a holder of control
        // is silent between steps: a lapse longer than any test.
        mavlink.start(&format!(
            "source_group = {DOOR_GROUP}\ncontrol_lapse_ms = 60000\n{config}"
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

// ---- the tests --------------------------------------------------------------

#[test]
fn each_gimbal_sends_a_heartbeat_of_type_gimbal() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    for component in [154, 171] {
        let hb = stack.gcs("heartbeat", GCS, json!({ "component": component }));
        let hb = &hb["heartbeat"];
        assert_eq!(hb["type"], 26, "MAV_TYPE_GIMBAL: {hb}");
        assert_eq!(hb["autopilot"], 8, "MAV_AUTOPILOT_INVALID: {hb}");
        assert_eq!(hb["system"], 1, "{hb}");
        assert_eq!(hb["v2"], true, "MAVLink 2: {hb}");
    }
}

#[test]
fn a_ground_station_over_tcp_sees_the_heartbeat_and_points_the_gimbal() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let tcp = format!("tcp:127.0.0.1:{}", stack.tcp_port);
    let hb = stack.gcs_over(&tcp, "heartbeat", GCS, json!({}));
    assert_eq!(hb["heartbeat"]["type"], 26, "{hb}");
    let r = stack.gcs_over(&tcp, "pitchyaw", GCS, json!({ "pitch": -15.0, "yaw": 25.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 25.0).abs() <= 0.5 && (tilt + 15.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    let seen = stack.gcs_over(&tcp, "attitude", GCS, json!({ "pitch": -15.0, "yaw": 25.0 }));
    assert_eq!(seen["reached"], true, "{seen}");
}

#[test]
fn information_on_request_carries_the_gimbals_serial_and_travel() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let id = stack.gcud.ctl(&["--json", "--to", MAST, "id"]);
    assert_eq!(id.code, 0, "{id:?}");
    let serial = id.json()["result"]["serial"]
        .as_str()
        .expect("serial")
        .trim()
        .to_owned();
    assert!(!serial.is_empty());
    let info = stack.gcs("info", GCS, json!({}));
    assert_eq!(info["manager_ack"], ACCEPTED, "{info}");
    assert_eq!(info["device_ack"], ACCEPTED, "{info}");
    let device = &info["device"];
    assert_eq!(device["custom_name"], serial.as_str(), "{info}");
    assert_eq!(device["vendor_name"], "Sagebrush", "{info}");
    let manager = &info["manager"];
    assert_eq!(manager["gimbal_device_id"], 154, "{info}");
    let deg = |v: &Value| v.as_f64().expect("a number").to_degrees();
    assert!((deg(&manager["pitch_min"]) + 90.0).abs() < 0.01, "{info}");
    assert!((deg(&manager["yaw_max"]) - 180.0).abs() < 0.01, "{info}");
    assert!((deg(&device["pitch_max"]) - 90.0).abs() < 0.01, "{info}");
}

#[test]
fn angles_are_reached_within_half_a_degree_and_reported_with_the_right_signs() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    // The command: yaw 30° right, pitch 20° up.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 20.0, "yaw": 30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 30.0).abs() <= 0.5 && (tilt - 20.0).abs() <= 0.5,
        "yaw right is pan right (positive), pitch up is tilt up: bus at {pan}, {tilt}"
    );
    let seen = stack.gcs("attitude", GCS, json!({ "pitch": 20.0, "yaw": 30.0 }));
    assert_eq!(seen["reached"], true, "{seen}");
    assert!(seen["attitude"]["roll"].as_f64().unwrap().abs() < 0.01, "{seen}");
    // The message, in radians: yaw 45° left, pitch 10° down.
    stack.gcs("set_pitchyaw", GCS, json!({ "pitch": -10.0, "yaw": -45.0 }));
    let seen = stack.gcs("attitude", GCS, json!({ "pitch": -10.0, "yaw": -45.0 }));
    assert_eq!(seen["reached"], true, "{seen}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan + 45.0).abs() <= 0.5 && (tilt + 10.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    // An attitude quaternion (pymavlink's): yaw 60° right, pitch 5° up.
    stack.gcs("set_attitude", GCS, json!({ "pitch": 5.0, "yaw": 60.0 }));
    let seen = stack.gcs("attitude", GCS, json!({ "pitch": 5.0, "yaw": 60.0 }));
    assert_eq!(seen["reached"], true, "{seen}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 60.0).abs() <= 0.5 && (tilt - 5.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
}

#[test]
fn a_rate_moves_the_gimbal_and_stops_when_not_refreshed() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    // 30 °/s right, refreshed every 0.2 s for 1 s; then nothing. Without
    // the 1 s lease it would run on to the end of travel (180°) in 6 s.
    stack.gcs(
        "set_pitchyaw",
        GCS,
        json!({ "yaw_rate": 30.0, "count": 5, "every_s": 0.2 }),
    );
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(pan > 10.0 && pan < 150.0, "moved right, then stopped: {pan}");
    assert_eq!(tilt, 0.0);
    // On the bus: gimbal-mavlink's own PS after the PR, none from gcud.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    assert!(stack.log().contains("move time-out: stopping"), "{}", stack.log());
    assert_still(&stack, (pan, tilt), "after the lease");
    // Pitch rate down through the command.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch_rate": -30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (_, tilt) = stack.gcud.settled_position(MAST);
    assert!(tilt < -5.0 && tilt > -80.0, "tilted down, then stopped: {tilt}");
}

#[test]
fn control_taken_by_one_component_denies_another_and_nothing_moves() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.gcs("configure", GCS, json!({ "params": [-2, -2, -1, -1] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let st = stack.gcs("manager_status", GCS, json!({ "primary_sysid": 255 }));
    assert_eq!(st["status"]["primary_control_compid"], 190, "{st}");
    // Right after the holder was heard: each step is a process of its own,
    // and an owner silent for 5 s loses control.
    let r = stack.gcs("configure", OTHER, json!({ "params": [-2, -2, -1, -1] }));
    assert_eq!(r["result"], DENIED, "-2 takes no control from its holder: {r}");
    let r = stack.gcs("pitchyaw", OTHER, json!({ "pitch": 30.0, "yaw": 40.0 }));
    assert_eq!(r["result"], DENIED, "{r}");
    stack.gcs(
        "set_pitchyaw",
        OTHER,
        json!({ "yaw_rate": 60.0, "count": 3, "every_s": 0.1 }),
    );
    let r = stack.gcs("configure", OTHER, json!({ "params": [-3, -3, -1, -1] }));
    assert_eq!(
        r["result"], ACCEPTED,
        "-3 from a non-holder: nothing to release (PX4): {r}"
    );
    assert_still(&stack, (0.0, 0.0), "commands from a component not in control");
    // The holder moves it; after it releases, the other may.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 0.0, "yaw": 10.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("configure", GCS, json!({ "params": [-3, -3, -1, -1] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("pitchyaw", OTHER, json!({ "pitch": 0.0, "yaw": 20.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!((pan - 20.0).abs() <= 0.5, "{pan}");
}

/// gcud decides who controls a gimbal (issue 32, ARCHITECTURE
/// "Front doors"): while the operators' link (priority 80, gimbalctl) holds
/// the mast gimbal, a ground station's commands through gimbal-mavlink (the
/// doors' link, priority 50) are answered MAV_RESULT_DENIED with a
/// STATUSTEXT naming the holder, GIMBAL_MANAGER_STATUS names the manager
/// itself as primary owner (no MAVLink component commands it), and the door
/// sends no stop that would end the holder's slew.
/// Needs gcud's `[control] hold_ms` and `[[link]] priority`.
#[test]
fn commands_while_a_higher_priority_link_holds_the_gimbal_are_denied_naming_it() {
    if !client_available() {
        return;
    }
    let stack = Stack::start_governed();
    let from = stack.gcud.position(MAST);
    let slew = support::door::OperatorsSlew::start(&stack.gcud, MAST);
    stack.wait_moving(from);
    let r = stack.gcs("pitchyaw_text", GCS, json!({ "pitch": 10.0, "yaw": -20.0 }));
    assert_eq!(r["result"], DENIED, "{r}");
    let text = r["text"].as_str().unwrap_or_else(|| panic!("no STATUSTEXT: {r}"));
    assert!(text.contains(support::door::OPERATORS_HOLDER), "{r}");
    let st = stack.gcs("manager_status", GCS, json!({ "primary_sysid": 1 }));
    assert_eq!(st["status"]["primary_control_compid"], 154, "the manager itself: {st}");
    // A stream of rates (no answer owed), a zero pitch rate beside the yaw
    // rate: refused whole, and the holder's slew goes on.
    stack.gcs(
        "set_pitchyaw",
        GCS,
        json!({ "yaw_rate": -30.0, "pitch_rate": 0.0, "count": 5, "every_s": 0.1 }),
    );
    stack.wait_moving(stack.gcud.position(MAST));
    drop(slew);
    let at = stack.gcud.settled_position(MAST);
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 0.0, "yaw": 15.0 }));
    assert_eq!(r["result"], DENIED, "{r}");
    assert_still(&stack, at, "denied commands");
    support::door::assert_door_sent_only_queries(&stack.gcud, MAST);
    eprintln!("STATUSTEXT: {text}");
}

/// QGroundControl's "take control" and PX4's navigator name their own ids
/// in CONFIGURE and rely on that taking control from whoever holds it
/// (PX4 `input_mavlink.cpp`: an explicit id is set unconditionally).
#[test]
fn an_explicit_id_takes_control_from_its_holder_as_qgroundcontrol_does() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.gcs("configure", GCS, json!({ "params": [-2, -2, -1, -1] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("pitchyaw", OTHER, json!({ "pitch": 0.0, "yaw": 15.0 }));
    assert_eq!(r["result"], DENIED, "{r}");
    let r = stack.gcs("configure", OTHER, json!({ "params": [255, 191, -1, -1] }));
    assert_eq!(r["result"], ACCEPTED, "take-over by explicit id: {r}");
    let st = stack.gcs("manager_status", OTHER, json!({ "primary_sysid": 255 }));
    assert_eq!(st["status"]["primary_control_compid"], 191, "{st}");
    let r = stack.gcs("pitchyaw", OTHER, json!({ "pitch": 0.0, "yaw": 15.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!((pan - 15.0).abs() <= 0.5, "{pan}");
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 0.0, "yaw": -15.0 }));
    assert_eq!(r["result"], DENIED, "the former holder: {r}");
}

/// MAV_CMD values (common.xml).
const DO_GIMBAL_MANAGER_PITCHYAW: i64 = 1000;
const REQUEST_MESSAGE: i64 = 512;
const DO_SET_SERVO: i64 = 183;

/// MAVSDK sends DO_GIMBAL_MANAGER_PITCHYAW as COMMAND_INT, ArduPilot its
/// ROI commands: every command is answered as it is for COMMAND_LONG.
#[test]
fn commands_as_command_int_are_answered_and_move_the_gimbal() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let n = Value::Null;
    let r = stack.gcs(
        "command_int",
        GCS,
        json!({ "id": DO_GIMBAL_MANAGER_PITCHYAW, "params": [-10.0, 30.0, n, n, 0, 0, 0] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 30.0).abs() <= 0.5 && (tilt + 10.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    let r = stack.gcs("command_int", GCS, json!({ "id": REQUEST_MESSAGE, "params": [280] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("command_int", GCS, json!({ "id": DO_SET_SERVO, "params": [1, 1500] }));
    assert_eq!(r["result"], UNSUPPORTED, "{r}");
    let r = stack.gcs("command_int", GCS, json!({ "id": 31999, "params": [] }));
    assert_eq!(r["result"], UNSUPPORTED, "an id the dialect does not know: {r}");
    let r = stack.gcs(
        "command_int",
        GCS,
        json!({ "id": DO_GIMBAL_MANAGER_PITCHYAW, "params": [120.0, 0.0, n, n, 0, 0, 0] }),
    );
    assert_eq!(r["result"], DENIED, "out of travel: {r}");
}

/// MAVProxy sends to component 0 before it has seen the gimbal: each
/// gimbal manager answers for itself (PX4: "for us or for anyone").
#[test]
fn a_command_to_component_0_is_answered_by_every_gimbal_manager() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let n = Value::Null;
    for int in [false, true] {
        let yaw = if int { -20.0 } else { 20.0 };
        let r = stack.gcs(
            "broadcast",
            GCS,
            json!({ "id": DO_GIMBAL_MANAGER_PITCHYAW, "params": [5.0, yaw, n, n, 0, 0, 0], "int": int }),
        );
        assert_eq!(r["results"]["154"], json!([ACCEPTED]), "COMMAND_INT {int}: {r}");
        assert_eq!(r["results"]["171"], json!([FAILED]), "the absent gimbal: {r}");
        let (pan, tilt) = stack.gcud.settled_position(MAST);
        assert!(
            (pan - yaw).abs() <= 0.5 && (tilt - 5.0).abs() <= 0.5,
            "bus at {pan}, {tilt}"
        );
    }
    // Device id 171 in param 7 picks that gimbal alone (the absent one).
    let r = stack.gcs(
        "broadcast",
        GCS,
        json!({ "id": DO_GIMBAL_MANAGER_PITCHYAW, "params": [0.0, 0.0, n, n, 0, 0, 171] }),
    );
    assert_eq!(r["results"], json!({ "171": [FAILED] }), "{r}");
    // REQUEST_MESSAGE's param 7 is the response target, not a device id.
    let r = stack.gcs(
        "broadcast",
        GCS,
        json!({ "id": REQUEST_MESSAGE, "params": [280, 0, 0, 0, 0, 0, 1] }),
    );
    assert_eq!(r["results"], json!({ "154": [ACCEPTED], "171": [ACCEPTED] }), "{r}");
    let r = stack.gcs("broadcast", GCS, json!({ "id": DO_SET_SERVO, "params": [1, 1500] }));
    assert_eq!(
        r["results"],
        json!({ "154": [UNSUPPORTED], "171": [UNSUPPORTED] }),
        "{r}"
    );
}

/// GIMBAL_MANAGER_FLAGS (common.xml).
const YAW_LOCK: u32 = 16;
const YAW_IN_VEHICLE_FRAME: u32 = 32;
const YAW_IN_EARTH_FRAME: u32 = 64;
const ROLL_LOCK: u32 = 4;
const PITCH_LOCK: u32 = 8;

/// Yaw in the earth frame (QGroundControl's yaw lock, PX4 ROI, MAVSDK
/// YawLock) needs the vehicle's heading, which the door does not have:
/// DENIED and nothing moves, never carried out relative to the mount.
#[test]
fn yaw_in_the_earth_frame_is_denied_and_nothing_moves() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    for flags in [YAW_LOCK, YAW_IN_EARTH_FRAME, YAW_LOCK | YAW_IN_EARTH_FRAME] {
        let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 0.0, "yaw": 30.0, "flags": flags }));
        assert_eq!(r["result"], DENIED, "flags {flags}: {r}");
        let r = stack.gcs("pitchyaw", GCS, json!({ "yaw_rate": 30.0, "flags": flags }));
        assert_eq!(r["result"], DENIED, "a rate, flags {flags}: {r}");
    }
    stack.gcs(
        "set_pitchyaw",
        GCS,
        json!({ "yaw": 40.0, "flags": YAW_IN_EARTH_FRAME, "count": 3, "every_s": 0.1 }),
    );
    assert_still(&stack, (0.0, 0.0), "yaw in the earth frame");
    // QGroundControl's default flags (roll and pitch lock, no yaw lock),
    // and YAW_LOCK overridden by YAW_IN_VEHICLE_FRAME: the vehicle frame.
    let r = stack.gcs(
        "pitchyaw",
        GCS,
        json!({ "pitch": -5.0, "yaw": 12.0, "flags": ROLL_LOCK | PITCH_LOCK }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs(
        "pitchyaw",
        GCS,
        json!({ "pitch": -5.0, "yaw": 25.0, "flags": YAW_LOCK | YAW_IN_VEHICLE_FRAME }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    // Pitch alone does not use the yaw's frame.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 8.0, "flags": YAW_LOCK }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 25.0).abs() <= 0.5 && (tilt - 8.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
}

#[test]
fn an_absent_gimbal_gets_failed_not_accepted() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 10.0, "yaw": 10.0, "component": 171 }));
    assert_eq!(r["result"], FAILED, "{r}");
    let r = stack.gcs("pitchyaw", GCS, json!({ "yaw_rate": 10.0, "component": 171 }));
    assert_eq!(r["result"], FAILED, "{r}");
    let info = stack.gcs("info", GCS, json!({ "component": 171 }));
    assert_eq!(info["device_ack"], FAILED, "D? unanswered: {info}");
    let r = stack.gcs("unsupported", GCS, json!({}));
    assert_eq!(r["result"], UNSUPPORTED, "{r}");
}

/// README: the attitude status carries COMMS_ERROR while the gimbal does
/// not answer; one that never answered reports an unknown attitude with it,
/// read by pymavlink (its own COMMS_ERROR constant).
#[test]
fn an_absent_gimbal_reports_comms_error_in_its_attitude_status() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let absent = stack.gcs("attitude", GCS, json!({ "component": 171 }));
    assert_eq!(absent["reached"], true, "an attitude status from 171: {absent}");
    assert_eq!(absent["attitude"]["comms_error"], true, "{absent}");
    assert!(absent["attitude"]["pitch"].is_null(), "no attitude is known: {absent}");
    let present = stack.gcs("attitude", GCS, json!({ "component": 154 }));
    assert_eq!(present["attitude"]["comms_error"], false, "{present}");
    assert!(present["attitude"]["pitch"].is_f64(), "{present}");
}

#[test]
fn sigkill_of_gimbal_mavlink_mid_slew_and_the_gimbal_stops() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start();
    // 30 °/s right; the lease would stop it after 1 s, but gimbal-mavlink
    // is killed at once, so only gcud's dead-man can stop it.
    let r = stack.gcs("pitchyaw", GCS, json!({ "yaw_rate": 30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    stack.wait_moving((0.0, 0.0));
    let status = stack.signal(nix::sys::signal::Signal::SIGKILL);
    assert!(!status.success());
    support::door::assert_dead_man_stopped(&stack.gcud, MAST);
}

#[test]
fn sigterm_stops_the_slew_gimbal_mavlink_started() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start_with_lease(60_000);
    // A 60 s lease: only gimbal-mavlink's own stop at SIGTERM ends it early.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch_rate": 20.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    stack.wait_moving((0.0, 0.0));
    let status = stack.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}");
    let (_, tilt) = stack.gcud.settled_position(MAST);
    assert!(tilt > 0.0 && tilt < 80.0, "stopped short of the end: {tilt}");
    // gimbal-mavlink stopped it itself, on the bus: its TS after the TU,
    // and nothing from gcud's group (its dead-man) once its connection closed.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    assert!(
        stack.log().contains("stopping what this service started"),
        "{}",
        stack.log()
    );
    assert!(!stack.gcud.log().contains("dead-man"), "{}", stack.gcud.log());
}

#[test]
fn bad_input_is_counted_and_refused_never_a_panic_and_nothing_moves() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start();
    let r = stack.gcs("garbage", GCS, json!({}));
    assert_eq!(r["nan"], DENIED, "{r}");
    assert_eq!(r["out_of_travel"], DENIED, "{r}");
    assert_eq!(r["bad_configure"], DENIED, "{r}");
    assert_eq!(r["alive"], true, "{r}");
    // Random datagrams straight at the endpoint, fuzz style (a fixed seed).
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for i in 0..500 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = (x % 300) as usize;
        let mut bytes: Vec<u8> = (0..len).map(|k| (x >> (k % 56)) as u8 ^ k as u8).collect();
        if i % 2 == 0 && !bytes.is_empty() {
            bytes[0] = 0xFD; // a MAVLink 2 marker, the rest noise
        }
        socket.send_to(&bytes, ("127.0.0.1", stack.port)).expect("send");
        if i % 10 == 0 {
            // Paced, so that few are lost to the socket's receive buffer.
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    assert_still(&stack, (0.0, 0.0), "after bad input");
    let alive = stack.gcs("heartbeat", GCS, json!({}));
    assert_eq!(alive["heartbeat"]["type"], 26, "{alive}");
    let status = stack.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}\n{}", stack.log());
    let log = stack.log();
    assert!(!log.contains("panicked"), "{log}");
    let (summary, counter) = counters(&log);
    // 21 damaged heartbeats, noise, a frame of no dialect, and the random
    // datagrams (none has a valid CRC; UDP may lose a few of them).
    assert!(counter("damaged") >= 23 + 400, "{summary}");
    assert!(counter("refused") >= 3, "{summary}");
    assert!(counter("ignored") >= 1, "PARAM_REQUEST_LIST: {summary}");
}

#[test]
fn bytes_without_an_intact_frame_on_tcp_are_counted_to_the_byte() {
    if !client_available() {
        return;
    }
    let mut stack = Stack::start();
    let tcp = format!("tcp:127.0.0.1:{}", stack.tcp_port);
    let r = stack.gcs_over(&tcp, "garbage", GCS, json!({}));
    assert_eq!(r["nan"], DENIED, "{r}");
    assert_eq!(r["out_of_travel"], DENIED, "{r}");
    assert_eq!(r["alive"], true, "{r}");
    assert_still(&stack, (0.0, 0.0), "after bad input over TCP");
    let status = stack.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(status.success(), "{status:?}\n{}", stack.log());
    let (summary, counter) = counters(&stack.log());
    // TCP loses nothing: every byte written that is no intact frame is
    // counted, and none of the intact frames around them.
    let written = r["garbage_bytes"].as_u64().expect("garbage_bytes");
    assert!(written > 400, "{r}");
    assert_eq!(counter("damaged_bytes"), written, "{summary}");
    assert!(counter("damaged") >= 1, "{summary}");
    assert!(counter("ignored") >= 1, "PARAM_REQUEST_LIST: {summary}");
}

/// Two pseudo-terminals whose masters are joined, as a null-modem cable:
/// what is written to one slave is read from the other.
struct NullModem {
    ends: (PathBuf, PathBuf),
    _relay: tokio::runtime::Runtime,
}

impl NullModem {
    fn new() -> Self {
        let relay = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .expect("runtime");
        let ends = relay.block_on(async {
            let mut a = sagebrush_host::pty::PtyMaster::open().expect("pty");
            let mut b = sagebrush_host::pty::PtyMaster::open().expect("pty");
            let ends = (a.slave_path().to_owned(), b.slave_path().to_owned());
            tokio::spawn(async move {
                let _ = tokio::io::copy_bidirectional(&mut a, &mut b).await;
            });
            ends
        });
        Self { ends, _relay: relay }
    }
}

#[test]
fn a_ground_station_on_a_serial_line_points_the_gimbal() {
    if !client_available() {
        return;
    }
    let cable = NullModem::new();
    let stack = Stack::start_with(
        1000,
        &format!("[[endpoint]]\nserial = \"{}\"\nbaud = 115200", cable.ends.0.display()),
    );
    support::wait_for_log_line(&stack.log_path(), "MAVLink serial line open");
    let serial = cable.ends.1.display().to_string();
    let hb = stack.gcs_over(&serial, "heartbeat", GCS, json!({}));
    assert_eq!(hb["heartbeat"]["type"], 26, "{hb}");
    let r = stack.gcs_over(&serial, "pitchyaw", GCS, json!({ "pitch": 12.0, "yaw": -30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan + 30.0).abs() <= 0.5 && (tilt - 12.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
}

#[test]
fn a_serial_line_plugged_in_while_tcp_peers_fill_their_limit_still_opens() {
    if !client_available() {
        return;
    }
    let cable = NullModem::new();
    // The radio's device node appears only after the TCP peers connected.
    let plug = tempfile::tempdir().expect("temp dir");
    let radio = plug.path().join("radio");
    let stack = Stack::start_with(
        1000,
        &format!("[[endpoint]]\nserial = \"{}\"\nbaud = 115200", radio.display()),
    );
    // As many TCP peers as gimbal-mavlink serves (stream::MAX_CONNECTIONS).
    let peers: Vec<std::net::TcpStream> = (0..8)
        .map(|_| std::net::TcpStream::connect(("127.0.0.1", stack.tcp_port)).expect("connect"))
        .collect();
    eventually("the 8 TCP peers to be accepted", || {
        std::thread::sleep(Duration::from_millis(50));
        stack.log().matches("MAVLink TCP connection accepted").count() == 8
    });
    std::os::unix::fs::symlink(&cable.ends.0, &radio).expect("plug the radio in");
    support::wait_for_log_line(&stack.log_path(), "MAVLink serial line open");
    let serial = cable.ends.1.display().to_string();
    let hb = stack.gcs_over(&serial, "heartbeat", GCS, json!({}));
    assert_eq!(hb["heartbeat"]["type"], 26, "{hb}\n{}", stack.log());
    let r = stack.gcs_over(&serial, "pitchyaw", GCS, json!({ "pitch": 0.0, "yaw": 15.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!((pan - 15.0).abs() <= 0.5, "bus at {pan}");
    assert!(!stack.log().contains("refused"), "{}", stack.log());
    drop(peers);
}

#[test]
fn check_names_the_file_line_column_and_key_and_exits_2() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("m.toml");
    std::fs::write(
        &path,
        mavlink_config("127.0.0.1:4001", 1000, "").replace("component_id = 171", "component_id = 154"),
    )
    .expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("m.toml:17:16: gimbal[1].component_id: expected a component id of its own"),
        "{err}"
    );
}

#[test]
fn check_warns_of_a_serial_device_absent_now_and_still_passes() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("m.toml");
    let serial = "[[endpoint]]\nserial = \"/dev/no-such-mavlink-radio\"";
    std::fs::write(&path, mavlink_config("127.0.0.1:4001", 1000, serial)).expect("write");
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    // Plugged in later, it is opened then: valid, with a warning at its place.
    assert_eq!(out.status.code(), Some(0), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("gimbal-mavlink: warning: "), "{err}");
    assert!(
        err.contains("m.toml:19:10: endpoint[2].serial: /dev/no-such-mavlink-radio does not exist now"),
        "{err}"
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("valid (2 gimbal(s), 3 endpoint(s))"),
        "{out:?}"
    );
}

#[test]
fn the_shipped_configuration_documents_every_key_and_passes_check() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/gimbal-mavlink.toml");
    let text = std::fs::read_to_string(&path).expect("config/gimbal-mavlink.toml");
    for key in [
        "gcud",
        "system_id",
        "source_group",
        "nic_window_ms",
        "attitude_rate_hz",
        "lease_ms",
        "udp_listen",
        "udp",
        "tcp_listen",
        "tcp",
        "name",
        "address",
        "component_id",
        "pan_deg",
        "tilt_deg",
        "max_rate_dps",
    ] {
        assert!(
            text.lines()
                .any(|l| l.trim_start_matches(['#', ' ']).starts_with(&format!("{key} ="))),
            "config/gimbal-mavlink.toml does not document {key}"
        );
    }
    let out = support::door::check(env!("CARGO_BIN_EXE_gimbal-mavlink"), &path);
    assert_eq!(out.status.code(), Some(0), "{out:?}");
}

#[test]
fn the_shipped_unit_is_hardened_and_checks_its_configuration_first() {
    support::door::assert_unit_has(
        "gimbal-mavlink.service",
        &[
            "Type=notify",
            "ExecStartPre=/usr/bin/gimbal-mavlink --check --config /etc/gimbal-mavlink/gimbal-mavlink.toml",
            "ExecStart=/usr/bin/gimbal-mavlink --config /etc/gimbal-mavlink/gimbal-mavlink.toml",
            "DynamicUser=yes",
            "NoNewPrivileges=yes",
            "CapabilityBoundingSet=",
            "ProtectSystem=strict",
            // Serial endpoints: tty devices only, as gcud.service.
            "SupplementaryGroups=dialout",
            "DevicePolicy=closed",
            "DeviceAllow=char-ttyUSB rw",
            "DeviceAllow=char-ttyS rw",
            "DeviceAllow=char-ttyACM rw",
            "DeviceAllow=char-ttyAMA rw",
            "DeviceAllow=char-ttyTHS rw",
            "DeviceAllow=char-ttymxc rw",
            "DeviceAllow=char-ttyO rw",
            "RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX",
            "SystemCallFilter=@system-service",
            "MemoryDenyWriteExecute=yes",
            "KillSignal=SIGTERM",
        ],
    );
}

/// MAV_CMD values of the legacy and ROI commands (common.xml).
const DO_MOUNT_CONTROL: i64 = 205;
const DO_MOUNT_CONFIGURE: i64 = 204;
const DO_SET_ROI_LOCATION: i64 = 195;
const DO_SET_ROI_NONE: i64 = 197;

/// ArduPilot drives a gimbal device with GIMBAL_DEVICE_SET_ATTITUDE;
/// MAVProxy's `gimbal` and many scripts use DO_MOUNT_CONTROL; what needs a
/// vehicle position (ROI, GPS point) is refused, never half done.
#[test]
fn device_attitude_and_mount_control_point_the_gimbal_and_roi_is_refused() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    stack.gcs("device_set_attitude", GCS, json!({ "pitch": -20.0, "yaw": 35.0 }));
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 35.0).abs() <= 0.5 && (tilt + 20.0).abs() <= 0.5,
        "GIMBAL_DEVICE_SET_ATTITUDE: bus at {pan}, {tilt}"
    );
    stack.gcs(
        "device_set_attitude",
        GCS,
        json!({ "pitch": 0.0, "yaw": 70.0, "flags": YAW_LOCK, "count": 3 }),
    );
    assert_still(
        &stack,
        (35.0, -20.0),
        "GIMBAL_DEVICE_SET_ATTITUDE with yaw in the earth frame",
    );
    // MAVLink targeting (mode 2): param1 pitch, param3 yaw; 330 is -30.
    let r = stack.gcs(
        "command_id",
        GCS,
        json!({ "id": DO_MOUNT_CONTROL, "params": [10.0, 0.0, 330.0, 0, 0, 0, 2] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan + 30.0).abs() <= 0.5 && (tilt - 10.0).abs() <= 0.5,
        "DO_MOUNT_CONTROL: bus at {pan}, {tilt}"
    );
    for (mode, why) in [(0, "retract"), (3, "RC"), (4, "GPS point"), (9, "no mode")] {
        let r = stack.gcs(
            "command_id",
            GCS,
            json!({ "id": DO_MOUNT_CONTROL, "params": [0.0, 0.0, 0.0, 0, 0, 0, mode] }),
        );
        assert_eq!(r["result"], DENIED, "{why}: {r}");
    }
    let r = stack.gcs(
        "command_id",
        GCS,
        json!({ "id": DO_MOUNT_CONFIGURE, "params": [2, 0, 0, 0, 0, 0, 0] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs(
        "command_id",
        GCS,
        json!({ "id": DO_MOUNT_CONFIGURE, "params": [2, 0, 0, 0, 0, 0, 2] }),
    );
    assert_eq!(r["result"], DENIED, "yaw input in the absolute frame: {r}");
    // ArduPilot sends its ROI commands as COMMAND_INT (lat, lon * 1e7).
    let r = stack.gcs(
        "command_int",
        GCS,
        json!({ "id": DO_SET_ROI_LOCATION, "params": [0, 0, 0, 0, 515_000_000, -1_000_000, 100.0] }),
    );
    assert_eq!(r["result"], DENIED, "no vehicle position: {r}");
    let r = stack.gcs("command_int", GCS, json!({ "id": DO_SET_ROI_NONE, "params": [] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_still(&stack, (-30.0, 10.0), "refused mount modes and ROI");
    // Neutral (mode 1): the mount's zero.
    let r = stack.gcs(
        "command_id",
        GCS,
        json!({ "id": DO_MOUNT_CONTROL, "params": [0.0, 0.0, 0.0, 0, 0, 0, 1] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(pan.abs() <= 0.5 && tilt.abs() <= 0.5, "neutral: bus at {pan}, {tilt}");
}

/// GIMBAL_MANAGER_SET_MANUAL_CONTROL's unitless -1..1: an angle is that
/// fraction of the travel (mast-1: pan ±180°, tilt ±90°), a rate that
/// fraction of max_rate_dps; anything outside -1..1 moves nothing.
#[test]
fn manual_control_points_the_gimbal_by_fractions_of_its_travel() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    stack.gcs("manual", GCS, json!({ "pitch": 1.5, "yaw": 0.2 }));
    assert_still(&stack, (0.0, 0.0), "manual control outside -1..1");
    stack.gcs("manual", GCS, json!({ "pitch": 0.5, "yaw": -0.25 }));
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan + 45.0).abs() <= 0.5 && (tilt - 45.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
    stack.gcs(
        "manual",
        GCS,
        json!({ "yaw_rate": 0.5, "pitch_rate": 0.0, "count": 5, "every_s": 0.1 }),
    );
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!(pan > -44.0, "a rate to the right moved the pan from -45: {pan}");
}

/// MAV_CMD_SET_MESSAGE_INTERVAL for the two status streams: the mean
/// interval, by the door's own time_boot_ms stamps, within 10 % of the
/// one asked for; -1 stops the stream; what it cannot keep is DENIED.
#[test]
fn set_message_interval_is_honoured_within_ten_percent() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    for (id, us, count) in [(285, 100_000, 21), (285, 400_000, 8), (281, 50_000, 41)] {
        let r = stack.gcs("interval", GCS, json!({ "id": id, "us": us, "count": count }));
        assert_eq!(r["result"], ACCEPTED, "{r}");
        let asked = us as f64 / 1000.0;
        let mean = r["mean_ms"].as_f64().unwrap_or_else(|| panic!("{r}"));
        assert!(
            (mean - asked).abs() <= asked * 0.1,
            "message {id} at {asked} ms: mean {mean} ms ({r})"
        );
    }
    let r = stack.gcs("interval", GCS, json!({ "id": 285, "us": -1, "listen_s": 2.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_eq!(r["seen"], 0, "the stream is off: {r}");
    for (id, us) in [(285, 5_000), (0, 100_000), (285, 60_000_000)] {
        let r = stack.gcs("interval", GCS, json!({ "id": id, "us": us }));
        assert_eq!(r["result"], DENIED, "message {id} at {us} us: {r}");
    }
}
