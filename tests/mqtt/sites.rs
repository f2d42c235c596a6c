//! A fleet on one broker: two sites (`north`, `south`), each its own gcud
//! with its own buses and its own gimbal-mqtt. A control room sees both;
//! a command to one never moves the other; a site cut off from the broker
//! keeps working on its own.

use std::collections::BTreeSet;

use super::*;
use support::door::assert_still;

#[test]
fn two_sites_on_one_broker_stay_apart_and_a_cut_site_keeps_working() {
    let Some(broker) = Broker::start() else { return };
    let uplink = Uplink::start(broker.port);
    let north = Site::start_via(&broker, &uplink.url(), "north", "", "");
    let south = Site::start(&broker, "south");

    // The control room's one subscription sees every gimbal of both.
    let seen = broker.step("collect", &["sagebrush/+/+/state", "2"], || north.logs());
    let topics: BTreeSet<&str> = seen["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .filter_map(|m| m["topic"].as_str())
        .collect();
    let expected: BTreeSet<&str> = [
        "sagebrush/north/gate/state",
        "sagebrush/north/mast/state",
        "sagebrush/south/gate/state",
        "sagebrush/south/mast/state",
    ]
    .into();
    assert_eq!(topics, expected);

    // Both sites have a gimbal named mast at 5.1.1: a command to north's
    // moves north's only.
    let r = north.command(&broker, "mast", r#"{"goto": {"pan_deg": 12.0, "tilt_deg": 3.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&north.gcud, MAST, 12.0, 3.0);
    assert_still(&south.gcud, MAST, (0.0, 0.0), "south while north moved");
    assert!(south.door_motions(MAST).is_empty(), "{:?}", south.door_frames(MAST));
    let r = south.command(&broker, "gate", r#"{"goto": {"pan_deg": -7.0, "tilt_deg": 0.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&south.gcud, GATE, -7.0, 0.0);
    assert!(north.door_motions(GATE).is_empty(), "{:?}", north.door_frames(GATE));

    // North's uplink is cut: the broker says north offline (its will) and
    // south online; north's own tools still drive north's gimbals.
    uplink.cut();
    let r = broker.step("wait_for", &["sagebrush/north/status", "offline", "30"], || {
        north.logs()
    });
    assert_eq!(r["arrived"], true, "{r}");
    assert_eq!(
        broker.step("retained", &["sagebrush/south/status"], || south.logs())["message"],
        "online"
    );
    let out = support::door::operators_ctl(&north.gcud, &["--to", MAST, "goto", "-20", "10"]);
    assert_eq!(out.code, 0, "gimbalctl at the cut site: {out:?}");
    wait_at(&north.gcud, MAST, -20.0, 10.0);
    // And south goes on through the broker.
    let r = south.command(&broker, "mast", r#"{"goto": {"pan_deg": 6.0, "tilt_deg": 0.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&south.gcud, MAST, 6.0, 0.0);
}
