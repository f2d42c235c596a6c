//! The PyPI `visca-over-ip` client (`client.py`): drives with speeds,
//! stop, home, absolute and relative positions, presets, the position
//! inquiry, an inquiry the door does not implement, the motion lease and a
//! joystick stream then a stop; and the npm `visca-over-ip` package
//! (`tcp.js`) on raw VISCA over TCP and UDP.

use std::time::Duration;

use super::*;
use support::door::{assert_no_stop_from_gcud, wait_for_stop, wait_moving};
use support::eventually;

/// The gimbal speed (`SPn`, 0..=15, Table 11) the door last set on the bus.
fn last_pan_speed(stack: &Stack) -> u8 {
    let sent = stack.door_frames();
    let p = sent
        .iter()
        .rev()
        .find(|p| p.starts_with("SP"))
        .unwrap_or_else(|| panic!("no pan speed on the bus: {sent:?}"));
    u8::from_str_radix(&p[2..], 16).expect("hex speed")
}

/// A Pan-tiltDrive moves the gimbal the way VISCA says (`01` left: the
/// PyPI package's negative pan speed, whatever its docstring says; `02`
/// down: its positive tilt), at a gimbal speed that grows with the VISCA
/// speed, and a stop stops it: all read on the bus.
#[test]
fn a_drive_moves_the_right_way_at_a_speed_growing_with_the_request_and_a_stop_stops_it() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let mut speeds = Vec::new();
    for (pan, stop) in [(-3, "PL"), (-12, "PL"), (-24, "PL"), (6, "PR")] {
        let from = stack.position();
        let r = stack.step("pantilt", &[&pan.to_string(), "0"]);
        assert_eq!(r["ok"], true, "{r}");
        wait_moving(&stack.gcud, MAST, from);
        let sent = stack.door_frames();
        assert!(sent.iter().any(|p| p == stop), "VISCA pan speed {pan}: {sent:?}");
        speeds.push(last_pan_speed(&stack));
        let now = stack.position();
        if pan < 0 {
            assert!(now.0 < from.0, "pan {pan} moved left: {from:?} -> {now:?}");
        } else {
            assert!(now.0 > from.0, "pan {pan} moved right: {from:?} -> {now:?}");
        }
        let r = stack.step("stop", &[]);
        assert_eq!(r["ok"], true, "{r}");
        wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
        stack.gcud.settled_position(MAST);
    }
    eprintln!("gimbal pan speeds for VISCA 3, 12, 24, 6: {speeds:?}");
    assert!(speeds[0] < speeds[1] && speeds[1] < speeds[2], "{speeds:?}");
    assert_eq!(speeds[2], 15, "VISCA's fastest is the gimbal's fastest");
    // Tilt: the package's positive tilt speed is VISCA down (`02`).
    let from = stack.position();
    assert_eq!(stack.step("pantilt", &["0", "10"])["ok"], true);
    wait_moving(&stack.gcud, MAST, from);
    assert!(
        stack.door_frames().iter().any(|p| p == "TD"),
        "{:?}",
        stack.door_frames()
    );
    assert!(stack.position().1 < from.1);
    assert_eq!(stack.step("stop", &[])["ok"], true);
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "TS");
    assert_no_stop_from_gcud(&stack.gcud, MAST);
}

/// AbsolutePosition and RelativePosition arrive (0.075° a step), the
/// position inquiry reads them back in steps, a preset stored is recalled
/// after Home.
#[test]
fn positions_and_presets_arrive_and_the_position_inquiry_reads_them() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    assert_eq!(stack.step("absolute", &["400", "-200"])["ok"], true);
    eventually("the gimbal at 30°, -15°", || {
        stack.gcud.settled_position(MAST) == (30.0, -15.0)
    });
    let read = stack.step("position", &[]);
    assert_eq!(
        (read["pan"].as_i64(), read["tilt"].as_i64()),
        (Some(400), Some(-200)),
        "{read}"
    );
    assert_eq!(stack.step("save", &["7"])["ok"], true);
    eventually("preset 7 stored", || stack.door_frames().iter().any(|p| p == "S07"));
    assert_eq!(stack.step("relative", &["100", "0"])["ok"], true);
    eventually("the gimbal at 37.5°", || {
        stack.gcud.settled_position(MAST) == (37.5, -15.0)
    });
    assert_eq!(stack.step("home", &[])["ok"], true);
    eventually("the gimbal home", || stack.gcud.settled_position(MAST) == (0.0, 0.0));
    assert_eq!(stack.step("recall", &["7"])["ok"], true);
    eventually("the gimbal at preset 7", || {
        stack.gcud.settled_position(MAST) == (30.0, -15.0)
    });
    let sent = stack.door_frames();
    assert!(
        sent.iter().any(|p| p == "HO") && sent.iter().any(|p| p == "P07"),
        "{sent:?}"
    );
}

/// An inquiry the door does not implement (iris, `09 04 4B`) and the zoom
/// of a gimbal without a lens are answered syntax error at once (the
/// client would time out and retry otherwise; it raises on the error).
#[test]
fn an_inquiry_not_implemented_is_answered_syntax_error_at_once() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    for (step, args) in [("inquiry", &["04 4B"][..]), ("zoom_position", &[][..])] {
        let r = stack.step(step, args);
        assert_eq!(r["error"], 2, "{step}: {r}");
        eprintln!("{step}: syntax error after {} s", r["seconds"]);
    }
}

/// A drive nobody repeats or stops runs for the motion lease, then the
/// door stops it (its own `PS`, not gcud's dead-man): VISCA drives have no
/// time-out of their own.
#[test]
fn a_drive_never_repeated_is_stopped_by_the_lease() {
    if !client_available() {
        return;
    }
    let stack = Stack::start_with(1000, "");
    let from = stack.position();
    assert_eq!(stack.step("pantilt", &["-4", "0"])["ok"], true);
    wait_moving(&stack.gcud, MAST, from);
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let (pan, _) = stack.gcud.settled_position(MAST);
    assert!(pan < from.0, "{pan}");
    assert_no_stop_from_gcud(&stack.gcud, MAST);
}

/// A joystick: drives at 20 Hz for two seconds, then a stop. The stop
/// overtakes whatever drives wait: the `PS` is the last pan frame on the
/// bus and the gimbal stands still after it. How long the stop took to
/// reach the bus is printed (the closing note's figure), not asserted.
#[test]
fn a_stop_after_a_20_hz_stream_is_the_last_frame_on_the_bus() {
    if !client_available() {
        return;
    }
    let stack = Stack::start();
    let r = stack.step("stream", &["-10", "0", "2"]);
    assert_eq!(r["ok"], true, "{r}");
    wait_for_stop(&stack.gcud, MAST, DOOR_GROUP, "PS");
    let at = stack.gcud.settled_position(MAST);
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(stack.position(), at, "the gimbal moved after the stop");
    let timed = support::frames_received_at(&stack.gcud.log(), MAST);
    let last_pan = timed
        .iter()
        .rev()
        .find(|(_, p)| ["PL", "PR", "PS", "PT"].contains(&p.as_str()))
        .expect("pan frames");
    assert_eq!(last_pan.1, "PS", "{timed:?}");
    let stop_at = r["stop_at"].as_f64().expect("stop_at");
    let ps = timed
        .iter()
        .find(|(t, p)| *t >= stop_at - 0.01 && p == "PS")
        .expect("a PS after the stop left");
    eprintln!(
        "{} drives at 20 Hz, then the stop reached the bus {:.0} ms after it left the client",
        r["sent"],
        (ps.0 - stop_at) * 1000.0
    );
}

/// `node tests/visca/tcp.js ARGS`: its JSON line. Without node, or without
/// the package (`npm ci` in tests/visca, as .ci/run does), the test fails
/// saying so, unless skipping is asked for.
fn node_step(args: &[&str], log: impl FnOnce() -> String) -> Option<Value> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/visca");
    if !dir.join("node_modules/visca-over-ip").is_dir() {
        support::tool_missing("the npm visca-over-ip package: `npm ci` in tests/visca (.ci/run does)");
        return None;
    }
    let out = std::process::Command::new("node")
        .arg(dir.join("tcp.js"))
        .args(args)
        .output();
    let Ok(out) = out else {
        support::tool_missing("node (apt-get install nodejs npm; .ci/run does)");
        return None;
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "tcp.js {args:?}: {}\n{stdout}{}\ndoor log:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr),
        log()
    );
    Some(serde_json::from_str(stdout.lines().last().unwrap_or_default()).expect("JSON"))
}

/// The npm `visca-over-ip` package's messages over raw VISCA on TCP: a
/// left drive moves the gimbal left, a stop stops it, an absolute
/// position (200, 100 steps) arrives; each answered ACK then Completion
/// as the package reads them. Its own camera (raw VISCA on UDP) sends
/// Home, which arrives.
#[test]
fn the_npm_visca_over_ip_package_drives_over_tcp_and_raw_udp() {
    let stack = Stack::start();
    let Some(r) = node_step(&["tcp", &stack.tcp.to_string()], || stack.door.log()) else {
        return;
    };
    for step in ["left", "stop", "absolute"] {
        let types: Vec<i64> = r[step]
            .as_array()
            .expect(step)
            .iter()
            .map(|x| x["type"].as_i64().unwrap())
            .collect();
        assert_eq!(types, vec![0x40, 0x50], "{step}: {r}");
    }
    let sent = stack.door_frames();
    let (pl, ps) = (
        sent.iter().position(|p| p == "PL").expect("PL on the bus"),
        sent.iter().position(|p| p == "PS").expect("PS on the bus"),
    );
    assert!(pl < ps, "{sent:?}");
    eventually("the gimbal at 15°, 7.5°", || {
        stack.gcud.settled_position(MAST) == (15.0, 7.5)
    });
    let r = node_step(&["udp", HOST, &stack.port.to_string()], || stack.door.log()).expect("node ran before");
    assert_eq!(r["home"], serde_json::json!(["ack", "complete"]), "{r}");
    eventually("the gimbal home", || stack.gcud.settled_position(MAST) == (0.0, 0.0));
}
