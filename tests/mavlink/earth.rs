//! Yaw in the earth frame and regions of interest: from a heading (the
//! autopilot's ATTITUDE, or `mount_heading_deg`) and a place (the
//! autopilot's GLOBAL_POSITION_INT, or the configured mount location).

use serde_json::{Value, json};

use super::*;

/// Yaw in the earth frame (QGroundControl's yaw lock, PX4 ROI, MAVSDK
/// YawLock) needs the vehicle's heading; with none (no autopilot, no
/// `mount_heading_deg`): DENIED and nothing moves, never carried out
/// relative to the mount.
#[test]
fn yaw_in_the_earth_frame_without_a_heading_is_denied_and_nothing_moves() {
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
    // The yaw of 25 arrives first: a pitch alone keeps the pan where it is
    // when it comes (the door's goto of one axis; a loaded machine may
    // deliver it mid-slew).
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!((pan - 25.0).abs() <= 0.5, "bus at pan {pan}");
    // Pitch alone does not use the yaw's frame.
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 8.0, "flags": YAW_LOCK }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - 25.0).abs() <= 0.5 && (tilt - 8.0).abs() <= 0.5,
        "bus at {pan}, {tilt}"
    );
}

/// MAV_FRAME values (common.xml).
const MAV_FRAME_GLOBAL_RELATIVE_ALT: u32 = 3;
const MAV_FRAME_LOCAL_NED: u32 = 1;

/// The place `east_m` east and `north_m` north of (`lat`, `lon`), on a
/// sphere of the earth's mean radius (the door uses WGS-84's radii: within
/// a kilometre or two they differ by far less than the half degree the
/// tests allow).
fn offset(lat: f64, lon: f64, north_m: f64, east_m: f64) -> (f64, f64) {
    const R: f64 = 6_371_000.0;
    (
        lat + (north_m / R).to_degrees(),
        lon + (east_m / (R * lat.to_radians().cos())).to_degrees(),
    )
}

fn assert_at(stack: &Stack, (want_pan, want_tilt): (f64, f64), what: &str) {
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    assert!(
        (pan - want_pan).abs() <= 0.5 && (tilt - want_tilt).abs() <= 0.5,
        "{what}: bus at {pan}, {tilt}, expected {want_pan}, {want_tilt}"
    );
}

/// The autopilot of the same system (component 1) sends ATTITUDE: an
/// earth-frame yaw lands at yaw minus heading on the bus, as COMMAND_LONG
/// and as COMMAND_INT, wrapped into the travel; the reports say the frame
/// (GIMBAL_MANAGER_STATUS flags) and the heading (delta_yaw). A heading
/// gone stale, or from another system's autopilot, is no heading: DENIED.
#[test]
fn earth_frame_yaw_lands_at_yaw_minus_the_autopilots_heading() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.gcs(
        "pitchyaw",
        GCS,
        json!({ "pitch": -10.0, "yaw": 80.0, "flags": YAW_LOCK, "report": true,
                "autopilot": { "heading": 50.0 } }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_eq!(
        r["manager_flags"],
        YAW_LOCK | YAW_IN_EARTH_FRAME,
        "held in the earth frame: {r}"
    );
    let delta = r["delta_yaw"].as_f64().unwrap_or_else(|| panic!("no delta_yaw: {r}"));
    assert!((delta - 50.0).abs() < 0.01, "delta_yaw is the heading: {r}");
    assert_at(&stack, (30.0, -10.0), "yaw 80 on a heading of 50");
    // COMMAND_INT (MAVSDK), heading -120: 150 + 120 = 270, which is -90.
    let n = Value::Null;
    let r = stack.gcs(
        "command_int",
        GCS,
        json!({ "id": DO_GIMBAL_MANAGER_PITCHYAW, "params": [0.0, 150.0, n, n, YAW_IN_EARTH_FRAME, 0, 0],
                "autopilot": { "heading": -120.0 } }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_at(&stack, (-90.0, 0.0), "yaw 150 on a heading of -120");
    // The autopilot is gone: the aim lapses, the reports say so.
    support::wait_for_log_line(&stack.log_path(), "earth-frame aim lapsed");
    let st = stack.gcs("manager_status", GCS, json!({ "flags": YAW_IN_VEHICLE_FRAME }));
    assert!(st["status"].is_object(), "back in the vehicle frame: {st}");
    let stale = json!({ "heading": 50.0, "for_s": 0.3, "delay_s": 2.5 });
    let r = stack.gcs(
        "pitchyaw",
        GCS,
        json!({ "yaw": 10.0, "flags": YAW_LOCK, "autopilot": stale }),
    );
    assert_eq!(r["result"], DENIED, "a heading older than 2 s: {r}");
    let r = stack.gcs(
        "pitchyaw",
        GCS,
        json!({ "yaw": 10.0, "flags": YAW_LOCK, "autopilot": { "heading": 50.0, "system": 7 } }),
    );
    assert_eq!(r["result"], DENIED, "another system's autopilot: {r}");
    assert_still(&stack, (-90.0, 0.0), "earth-frame yaw without a heading");
}

/// A mast: `mount_heading_deg` is the heading of the pan's zero, never stale.
#[test]
fn on_a_mast_mount_heading_deg_turns_earth_yaw_into_pan() {
    if !client_available() {
        return;
    }
    let stack = Stack::start_mast("", "mount_heading_deg = 100.0");
    let r = stack.gcs(
        "pitchyaw",
        GCS,
        json!({ "pitch": 5.0, "yaw": 130.0, "flags": YAW_IN_EARTH_FRAME }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_at(&stack, (30.0, 5.0), "yaw 130 on a mast facing 100");
    // The message, yaw -150 (210 on the compass): -250, which is 110.
    stack.gcs(
        "set_pitchyaw",
        GCS,
        json!({ "yaw": -150.0, "pitch": 0.0, "flags": YAW_LOCK }),
    );
    assert_at(&stack, (110.0, 0.0), "yaw -150 on a mast facing 100");
}

/// MAV_CMD_DO_SET_ROI_LOCATION from a mast of configured place and
/// heading: the gimbal looks at the place (bearing minus heading, the
/// depression angle), as COMMAND_INT and COMMAND_LONG; ROI_NONE ends it
/// and the gimbal stays; an altitude above home (unknown on a mast) and a
/// frame that is no global one are refused.
#[test]
fn roi_location_points_the_gimbal_from_a_mast_and_roi_none_clears_it() {
    if !client_available() {
        return;
    }
    let (lat, lon, alt) = (47.0, 8.0, 500.0);
    let stack = Stack::start_mast(
        &format!("mount_latitude_deg = {lat}\nmount_longitude_deg = {lon}\nmount_altitude_m = {alt}"),
        "mount_heading_deg = 45.0",
    );
    // 1 km east, 100 m below: bearing 90, pan 45 right, 5.71 degrees down.
    let (t_lat, t_lon) = offset(lat, lon, 0.0, 1000.0);
    let e7 = |deg: f64| (deg * 1e7).round();
    let r = stack.gcs(
        "command_int",
        GCS,
        json!({ "id": DO_SET_ROI_LOCATION, "params": [0, 0, 0, 0, e7(t_lat), e7(t_lon), alt - 100.0] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let down = -(100.0f64 / 1000.0).atan().to_degrees();
    assert_at(&stack, (45.0, down), "ROI 1 km east, 100 m below");
    let st = stack.gcs("manager_status", GCS, json!({ "flags": YAW_LOCK | YAW_IN_EARTH_FRAME }));
    assert!(st["status"].is_object(), "an earth-frame aim in force: {st}");
    // COMMAND_LONG, degrees: 2 km north, level: pan 45 left.
    let (t_lat, t_lon) = offset(lat, lon, 2000.0, 0.0);
    let r = stack.gcs(
        "command_id",
        GCS,
        json!({ "id": DO_SET_ROI_LOCATION, "params": [0, 0, 0, 0, t_lat, t_lon, alt] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_at(&stack, (-45.0, 0.0), "ROI 2 km north");
    for frame in [MAV_FRAME_GLOBAL_RELATIVE_ALT, MAV_FRAME_LOCAL_NED] {
        let r = stack.gcs(
            "command_int",
            GCS,
            json!({ "id": DO_SET_ROI_LOCATION, "params": [0, 0, 0, 0, e7(t_lat), e7(t_lon), 10.0],
                    "frame": frame }),
        );
        assert_eq!(r["result"], DENIED, "frame {frame}: {r}");
    }
    let r = stack.gcs("command_int", GCS, json!({ "id": DO_SET_ROI_NONE, "params": [] }));
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let st = stack.gcs("manager_status", GCS, json!({ "flags": YAW_IN_VEHICLE_FRAME }));
    assert!(st["status"].is_object(), "no aim after ROI_NONE: {st}");
    assert_still(&stack, (-45.0, 0.0), "after ROI_NONE");
    // A refused motion of the aim's owner ends the aim too.
    let r = stack.gcs(
        "command_id",
        GCS,
        json!({ "id": DO_SET_ROI_LOCATION, "params": [0, 0, 0, 0, t_lat, t_lon, alt] }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    let r = stack.gcs("pitchyaw", GCS, json!({ "pitch": 120.0, "yaw": 0.0 }));
    assert_eq!(r["result"], DENIED, "out of travel: {r}");
    let st = stack.gcs("manager_status", GCS, json!({ "flags": YAW_IN_VEHICLE_FRAME }));
    assert!(
        st["status"].is_object(),
        "no aim after its owner's refused motion: {st}"
    );
}

/// MAV_CMD_DO_SET_ROI_LOCATION on a vehicle: the autopilot's
/// GLOBAL_POSITION_INT and ATTITUDE place and turn the mount; as the
/// vehicle turns the gimbal is re-aimed at the place; when the autopilot
/// falls silent the aim lapses and the gimbal stays.
#[test]
fn roi_location_follows_the_place_as_the_vehicle_turns() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let (lat, lon, alt) = (-33.9, 151.2, 40.0);
    let (t_lat, t_lon) = offset(lat, lon, 0.0, 1000.0);
    let down = -(100.0f64 / 1000.0).atan().to_degrees();
    let r = stack.gcs(
        "roi_turn",
        GCS,
        json!({ "autopilot": { "heading": 0.0, "position": [lat, lon, alt] },
                "roi": [t_lat, t_lon, alt - 100.0], "pitch": down,
                "yaw1": 90.0, "heading2": 60.0, "yaw2": 30.0 }),
    );
    assert_eq!(r["result"], ACCEPTED, "{r}");
    assert_eq!(r["reached1"], true, "looking east on a heading of 0: {r}");
    assert_eq!(r["reached2"], true, "re-aimed on a heading of 60: {r}");
    assert_at(&stack, (30.0, down), "after the turn");
    assert!(stack.log().contains("re-aimed"), "{}", stack.log());
    support::wait_for_log_line(&stack.log_path(), "earth-frame aim lapsed");
    let at = stack.gcud.settled_position(MAST);
    assert_still(&stack, at, "the autopilot silent");
}
