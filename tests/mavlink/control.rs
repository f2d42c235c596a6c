//! Who may command (MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE, gcud's own
//! control above it).

use serde_json::json;

use super::*;

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

/// A MAVLink rate on a governed gimbal (issue 48: the door's session sends a
/// speed, then the direction, and the governed gimbal did not move):
/// MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW with a yaw rate of 60 °/s toward the
/// gimbal's keep-out zone (pan 60..90) is accepted, the gimbal moves, and
/// gcud's own stop keeps it short of the zone (where it rests, read on the
/// bus). The door's lease (20 s) would carry it far past.
#[test]
fn a_rate_on_a_governed_gimbal_moves_it_and_stops_short_of_its_zone() {
    if !client_available() {
        return;
    }
    let rules = "[[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
                 [[gimbal.keep_out]]\npan_deg = [60.0, 90.0]\ntilt_deg = [-30.0, 10.0]\n";
    let stack = Stack::start_on(support::door::start_governed_gcud_with(rules), 20_000, "");
    let r = stack.gcs("pitchyaw", GCS, json!({ "yaw_rate": 60.0 }));
    assert_eq!(r["result"], ACCEPTED, "{r}\n{}", stack.log());
    support::door::wait_for_stop(&stack.gcud, MAST, support::door::GCUD_GROUP, "PS");
    let (pan, tilt) = stack.gcud.settled_position(MAST);
    eprintln!("MAVLink yaw rate toward the zone: rests at pan {pan} (zone from 60)");
    let received = stack.gcud.received(MAST);
    assert!(
        received.iter().any(|(source, p)| *source == DOOR_GROUP && p == "PR"),
        "the door's slew reached the gimbal: {received:?}"
    );
    assert!(pan > 30.0, "it moved: {pan}");
    assert!(tilt.abs() < 0.05, "{tilt}");
    assert!(pan <= 60.5, "into the zone: {pan}\n{}", stack.gcud.log());
}
