//! What anyone who may publish on the broker can throw at the door:
//! malformed and huge payloads (answered with a reason, the door goes on),
//! a flood on one command topic (memory bounded, a stop still overtakes
//! what waits).

use std::time::Duration;

use super::*;
use support::door::assert_still;

/// The door's resident memory, KiB (`VmRSS`).
fn rss_kib(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).expect("/proc status");
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .expect("VmRSS")
}

#[test]
fn malformed_and_huge_payloads_are_answered_with_a_reason() {
    let Some(broker) = Broker::start() else { return };
    let site = Site::start(&broker, "north");
    let base = site.base("mast");
    let nested = format!("{}{}", "[".repeat(5000), "]".repeat(5000));
    let payloads = [
        "not json",
        r#"{"id": "f", "fly": true}"#,
        r#"{"id": "s", "stop": true, "home": true}"#,
        r#"{"id": "n", "goto": {"pan_deg": "ten"}}"#,
        r#"{"id": "l", "slew": {"pan": 0.5, "lease_ms": 999999}}"#,
        r#"{"id": "r", "preset": {"recall": 256}}"#,
        "",
        nested.as_str(),
    ];
    let r = broker.step("results", &[&base, "3"], || site.logs());
    assert!(r["results"].as_array().expect("results").is_empty(), "{r}");
    let mut args = vec![base.as_str(), "3"];
    args.extend(payloads.iter().copied());
    let r = broker.step("results", &args, || site.logs());
    let results = r["results"].as_array().expect("results").clone();
    assert_eq!(results.len(), payloads.len(), "one result each: {r}\n{}", site.logs());
    for result in &results {
        assert_eq!(result["ok"], false, "{result}");
        assert!(!result["reason"].as_str().unwrap_or_default().is_empty(), "{result}");
    }
    let reason = |id: &str| {
        results
            .iter()
            .find(|r| r["id"] == id)
            .map(|r| r["reason"].as_str().unwrap_or_default().to_owned())
            .unwrap_or_else(|| panic!("no result for {id}: {results:?}"))
    };
    assert!(reason("f").contains("unknown field `fly`"), "{}", reason("f"));
    assert_eq!(reason("s"), "expected one command per message, found several");
    assert!(reason("l").contains("slew.lease_ms"), "{}", reason("l"));

    // A payload over the door's 4 KiB is refused unread; one over its
    // largest packet (256 KiB, MQTT 5's Maximum Packet Size) is not even
    // sent to it by the broker. The door stays connected either way.
    let cmd = format!("{base}/cmd");
    let results = std::thread::scope(|s| {
        let watch = s.spawn(|| broker.step("collect", &[&format!("{base}/result"), "4"], String::new));
        std::thread::sleep(Duration::from_millis(1500));
        broker.step("huge", &[&cmd, "100000"], || site.logs());
        broker.step("huge", &[&cmd, "2000000"], || site.logs());
        watch.join().expect("collect")
    });
    let reasons: Vec<&str> = results["messages"]
        .as_array()
        .expect("messages")
        .iter()
        .filter_map(|m| m["payload"]["reason"].as_str())
        .collect();
    assert_eq!(
        reasons,
        ["payload of 100000 bytes, at most 4096: not read"],
        "{results}"
    );
    assert!(!site.door.log().contains("lost the broker"), "{}", site.logs());
    assert!(site.door_motions(MAST).is_empty(), "{:?}", site.door_frames(MAST));
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 4.0, "tilt_deg": 0.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 4.0, 0.0);
}

#[test]
fn a_flood_of_commands_keeps_memory_bounded_and_a_stop_still_overtakes() {
    let Some(broker) = Broker::start() else { return };
    let site = Site::start(&broker, "north");
    let before = rss_kib(site.door.pid());
    // A slew that would run 5 s, then 20 000 gotos far away and a stop.
    let r = site.command(&broker, "mast", r#"{"slew": {"pan": 0.3, "lease_ms": 5000}}"#);
    assert_eq!(r["ok"], true, "{r}");
    support::door::wait_moving(&site.gcud, MAST, (0.0, 0.0));
    // One connection, so the stop comes after every goto of the flood.
    let r = broker.step(
        "flood",
        &[
            &site.base("mast"),
            "20000",
            r#"{"goto": {"pan_deg": -150.0, "tilt_deg": 60.0}}"#,
            r#"{"id": "halt", "stop": true}"#,
        ],
        || site.logs(),
    );
    assert_eq!(r["last"]["ok"], true, "{r}\n{}", site.logs());
    eprintln!("{} results of 20 001 commands came back", r["results"]);
    let after = rss_kib(site.door.pid());
    eprintln!("door RSS before the flood {before} KiB, after {after} KiB");
    assert!(after < before + 64 * 1024, "RSS {before} -> {after} KiB");
    // After the stop on the bus, nothing of the flood moves the gimbal.
    support::door::wait_for_stop(&site.gcud, MAST, DOOR_GROUP, "PS");
    let settled = site.gcud.settled_position(MAST);
    assert_still(&site.gcud, MAST, settled, "after the stop");
    let frames = site.door_frames(MAST);
    let last_stop = frames.iter().rposition(|p| p == "PS").expect("a PS");
    assert!(
        !frames[last_stop..].iter().any(|p| is_goto(p)),
        "a goto of the flood ran after the stop: {:?}",
        &frames[last_stop..]
    );
    // And the door still answers.
    let r = site.command(&broker, "mast", r#"{"goto": {"pan_deg": 1.0, "tilt_deg": 1.0}}"#);
    assert_eq!(r["ok"], true, "{r}");
    wait_at(&site.gcud, MAST, 1.0, 1.0);
}
