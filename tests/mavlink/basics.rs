//! The gimbal as a ground station first meets it: heartbeats, information,
//! angles and rates on the bus, an absent gimbal.

use serde_json::{Value, json};

use super::*;

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
    // On the bus: gimbal-mavlink's own PS after the PR, none from gcud;
    // the gimbal rests where that PS put it, by the bus's clock.
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    support::door::assert_no_stop_from_gcud(&stack.gcud, MAST);
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    let log = stack.gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "PR", DOOR_GROUP, "PS");
    let dps = support::door::speed_on_bus(&log, MAST, "PR");
    support::door::assert_rests_where_stopped(pan, dps, moving, 180.0, "the lease's stop");
    assert_eq!(tilt, 0.0);
    assert!(stack.log().contains("move time-out: stopping"), "{}", stack.log());
    assert_still(&stack, (pan, tilt), "after the lease");
    // Pitch rate down through the command.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch_rate": -30.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    support::door::wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    let (_, tilt) = stack.gcud.settled_position(MAST);
    let log = stack.gcud.log();
    let moving = support::door::seconds_moving(&log, MAST, "TD", DOOR_GROUP, "TS");
    let dps = support::door::speed_on_bus(&log, MAST, "TD");
    support::door::assert_rests_where_stopped(tilt, dps, moving, 90.0, "tilted down, then the lease's stop");
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
