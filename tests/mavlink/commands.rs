//! Commands as the systems send them: COMMAND_INT (MAVSDK, ArduPilot),
//! component 0 (MAVProxy), GIMBAL_DEVICE_SET_ATTITUDE (ArduPilot),
//! DO_MOUNT_CONTROL (MAVProxy's `gimbal`), manual control, message intervals.

use serde_json::{Value, json};

use super::*;

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

/// ArduPilot drives a gimbal device with GIMBAL_DEVICE_SET_ATTITUDE;
/// MAVProxy's `gimbal` and many scripts use DO_MOUNT_CONTROL; what needs a
/// vehicle position (ROI, GPS point) is refused, never half done.
#[test]
fn device_attitude_and_mount_control_point_the_gimbal_and_roi_without_a_place_is_refused() {
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
