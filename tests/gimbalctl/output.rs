//! What gimbalctl prints: `encode` and `decode` golden vectors, the
//! command sent and replies decoded with labels, typed JSON shapes.

use super::*;

#[test]
fn encode_golden_vectors() {
    for (args, hex) in [
        (
            &["encode", "--to", "5.1.12", "--from", "2", "P?"][..],
            "F8 05 01 0C 02 02 50 3F A5",
        ),
        (&["encode", "--to", "1.1.1", "HO"], "F8 01 01 01 00 02 48 4F 9C"),
        (
            &["encode", "--to", "2.1.12", "--from", "5", "1194F830"],
            "F8 02 01 0C 05 08 31 31 39 34 46 38 33 30 CC",
        ),
        (
            &["encode", "--to", "255.255.255", "#07"],
            "F8 FF FF FF 00 03 23 30 37 8A",
        ),
        (
            &["encode", "--to", "1.1.1", "P1194F830"],
            "F8 01 01 01 00 09 50 31 31 39 34 46 38 33 30 0C",
        ),
    ] {
        let out = gimbalctl(args);
        assert_eq!((out.code, out.stdout.trim()), (0, hex), "{args:?}: {out:?}");
    }
    // A 256-byte payload is sent with length byte 0 (1.4.1.1).
    let long = "A".repeat(256);
    let out = gimbalctl(&["encode", "--to", "1.1.1", &long]);
    let bytes: Vec<&str> = out.stdout.split_whitespace().collect();
    assert_eq!((bytes.len(), bytes[5], bytes[262]), (263, "00", "03"), "{out:?}");
    let json = gimbalctl(&["--json", "encode", "--to", "5.1.12", "--from", "2", "P?"]).json();
    assert_eq!(json["checksum"], 0xA5);
    assert_eq!(json["command"]["mnemonic"], "P?");
}

#[test]
fn decode_golden_vectors() {
    let out = gimbalctl(&[
        "--json",
        "decode",
        "41 42 F8 05 01 0C 02 02 50 3F A5 06",
        "15 3F",
        "F8020106",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    let events = out.json_lines();
    let kinds: Vec<&str> = events.iter().map(|e| e["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["noise", "frame", "ack", "nak", "nic", "noise"]);
    assert_eq!(events[0]["bytes"], 2);
    let frame = &events[1];
    assert_eq!(
        frame["dest"],
        serde_json::json!({ "group": 5, "port": 1, "device": 12 })
    );
    assert_eq!(
        (frame["source"].as_u64(), frame["payload"].as_str()),
        (Some(2), Some("P?"))
    );
    assert_eq!(frame["checksum"], 0xA5);
    assert_eq!(frame["command"]["mnemonic"], "P?");
    assert_eq!(events[5]["bytes"], 4, "a truncated frame at the end is noise");

    // A damaged frame, then a result with no command, from stdin without spaces.
    let out = gimbalctl_stdin(
        &["--json", "decode"],
        "F805010C020250 3FA6\nF8 02 01 0C 05 08 31 31 39 34 46 38 33 30 CC\n",
    );
    let events = out.json_lines();
    let kinds: Vec<&str> = events.iter().map(|e| e["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["bad_checksum", "noise", "frame"], "{events:?}");
    assert_eq!(
        (events[0]["expected"].as_u64(), events[0]["found"].as_u64()),
        (Some(0xA5), Some(0xA6))
    );
    assert_eq!(events[2]["payload"], "1194F830");
    assert_eq!(events[2]["command"], Value::Null, "a result is no command");
    let text = gimbalctl(&["decode", "F8 05 01 0C 02 02 50 3F A5"]);
    assert!(
        text.stdout
            .starts_with("frame dest 5.1.12 source 2 payload \"P?\" checksum A5"),
        "{text:?}"
    );
}

#[test]
fn output_names_the_command_sent_and_decodes_replies_with_labels() {
    let sim = Sim::pty(&["--presets", "256"]);
    let out = sim.ctl1(&["speed", "pan", "8"]);
    assert!(out.stdout.contains("SP8") && !out.stdout.contains("SPn"), "{out:?}");
    let v = sim.json1(&["speed", "tilt", "F"]);
    assert_eq!(
        (v["sent"].as_str(), v["mnemonic"].as_str(), v["speed"].as_u64()),
        (Some("STF"), Some("STn"), Some(15))
    );
    let out = sim.ctl1(&["camera", "status"]);
    assert!(
        out.stdout.contains("camera and lens power on") && out.stdout.contains("relays on: none"),
        "{out:?}"
    );
    let out = sim.ctl1(&["status-bits"]);
    assert!(out.stdout.contains("positive_limit_found"), "{out:?}");
    let out = sim.ctl1(&["zoom", "speed"]);
    assert!(
        out.stdout.contains("zoom speed") && out.stdout.contains("0 = slowest"),
        "{out:?}"
    );
    let out = sim.ctl1(&["status"]);
    assert!(out.stdout.contains("functioning properly"), "{out:?}");
    // One numbering for presets: decimal in and out, 255 works, hex with 0x.
    sim.json1(&["goto", "7", "7", "--wait"]);
    let out = sim.ctl1(&["preset", "store", "255"]);
    assert_eq!(out.code, 0, "{out:?}");
    assert!(
        out.stdout.contains("SFF") && out.stdout.contains("preset 255"),
        "{out:?}"
    );
    let v = sim.json1(&["preset", "store", "0x10"]);
    assert_eq!((v["sent"].as_str(), v["preset"].as_u64()), (Some("S10"), Some(16)));
    let stored = sim.result1(&["preset", "stored", "255"]);
    assert_eq!(stored["pan_deg"], 7.0);
    let out = sim.ctl1(&["preset", "recall", "255"]);
    assert!(out.stdout.contains("moving to preset 255"), "{out:?}");
}

/// Every string in a JSON value, to check none is a Rust `Debug` rendering.
fn strings(v: &Value, out: &mut Vec<String>) {
    match v {
        Value::String(s) => out.push(s.clone()),
        Value::Array(a) => a.iter().for_each(|x| strings(x, out)),
        Value::Object(m) => m.values().for_each(|x| strings(x, out)),
        _ => {}
    }
}

fn no_debug_strings(v: &Value) {
    let mut all = Vec::new();
    strings(v, &mut all);
    for s in all {
        assert!(
            !(s.contains(" { ") || s.contains("Some(") || s.contains("Angle(") || s.contains("::")),
            "a Debug string in JSON: {s:?} in {v}"
        );
    }
}

#[test]
fn json_shapes_are_typed() {
    let sim = Sim::pty(&["--presets", "256"]);
    // Exchange without result: typed arguments, the payload sent.
    let v = sim.json1(&["goto", "45", "-10"]);
    assert_eq!(v["command"], "goto");
    assert_eq!(
        (v["pan_deg"].as_f64(), v["tilt_deg"].as_f64()),
        (Some(45.0), Some(-10.0))
    );
    assert_eq!(
        (v["sent"].as_str(), v["outcome"].as_str()),
        (Some("P1194FC18"), Some("acknowledged"))
    );
    assert!(v["transmissions"].is_u64() && v["elapsed_ms"].is_u64() && v["result"].is_null());
    no_debug_strings(&v);
    // Results, one per table.
    let r = sim.result1(&["position"]);
    assert!(r["pan_deg"].is_f64() && r["tilt_deg"].is_f64(), "{r}");
    let r = sim.result1(&["id"]);
    assert!(r["id"].is_u64() && r["name"].is_string() && r["serial"].is_string() && r["revision"].is_string());
    let r = sim.result1(&["status"]);
    for k in [
        "hardware_ok",
        "azimuth_not_initialized",
        "elevation_not_initialized",
        "motors_off",
        "error",
    ] {
        assert!(r[k].is_boolean(), "{k}: {r}");
    }
    assert!(r["code"].is_u64());
    for q in ["status-bits", "errors"] {
        let r = sim.result1(&[q]);
        for axis in ["azimuth", "elevation"] {
            assert!(r[axis]["raw"].is_u64(), "{q}: {r}");
            let names: &[&str] = if q == "errors" {
                &["center_reference", "initialization", "motor_timeout", "temperature"]
            } else {
                &[
                    "not_initialized",
                    "positive_limit_found",
                    "negative_hard_stop",
                    "error_present",
                ]
            };
            for n in names {
                assert!(r[axis][n].is_boolean(), "{q} {axis} {n}: {r}");
            }
        }
    }
    let r = sim.result1(&["rate"]);
    assert!(r["pan_deg_s"].is_f64() && r["tilt_deg_s"].is_f64(), "{r}");
    let r = sim.result1(&["rate", "tilt"]);
    assert!(r["deg_s"].is_f64(), "{r}");
    let r = sim.result1(&["accel"]);
    assert!(r["pan_deg_s2"].is_f64() && r["tilt_deg_s2"].is_f64(), "{r}");
    let r = sim.result1(&["gains"]);
    assert!(r["pan_gain"].is_f64() && r["tilt_gain"].is_f64(), "{r}");
    let r = sim.result1(&["limits"]);
    assert!(r["pan_ccw_raw"].is_u64() && r["tilt_cw_raw"].is_u64(), "{r}");
    let r = sim.result1(&["relay"]);
    assert!(r["raw"].is_u64() && r["on"].is_array(), "{r}");
    let r = sim.result1(&["lens"]);
    assert!(r["zoom"].is_u64() && r["focus"].is_u64(), "{r}");
    let r = sim.result1(&["verify-home"]);
    assert!(
        r["count_correct"]["pan"].is_boolean() && r["center_switches"]["tilt"].is_boolean(),
        "{r}"
    );
    let r = sim.result1(&["camera", "status"]);
    assert_eq!(
        (r["camera_power"].as_bool(), r["relays"]["raw"].as_u64()),
        (Some(true), Some(0)),
        "{r}"
    );
    let r = sim.result1(&["focus", "speed"]);
    assert!(r["speed"].is_u64(), "{r}");
    let r = sim.result1(&["data-rate"]);
    assert!(r["bps"].is_u64() && r["code"].is_u64(), "{r}");
    let r = sim.result1(&["aux", "0", "count"]);
    assert!(r["count"].is_u64(), "{r}");
    let r = sim.result1(&["preset", "query", "0"]);
    assert!(r["pan_deg"].is_f64(), "{r}");
    // A broadcast (sent, not answered: the outcome says so).
    let v = sim.ctl_json(&["--to", "1.1.255", "stop"]);
    assert_eq!(
        (v["outcome"].as_str(), v["sent"].as_str()),
        (Some("broadcast"), Some("PT"))
    );
    // A failure: outcome, exit code, message; typed wait fields when --wait failed.
    let out = sim.ctl1(&["--json", "focus", "auto-on"]);
    let v = out.json();
    assert_eq!(
        (v["ok"].as_bool(), v["outcome"].as_str(), v["exit_code"].as_u64()),
        (Some(false), Some("nic"), Some(5))
    );
    assert!(v["error"].is_string() && v["command"] == "focus", "{v}");
    // Watch samples.
    let out = sim.ctl1(&["--json", "watch", "--rate", "20", "--count", "2"]);
    for s in out.json_lines() {
        assert!(
            s["sample"].is_u64() && s["position"]["pan_deg"].is_f64() && s["lens"]["zoom"].is_u64(),
            "{s}"
        );
    }
    // Encode and decode: the command as typed fields, never a Debug string.
    let v = gimbalctl(&["--json", "encode", "--to", "5.1.1", "SP8"]).json();
    assert_eq!(
        (
            v["command"]["name"].as_str(),
            v["command"]["axis"].as_str(),
            v["command"]["speed"].as_u64()
        ),
        (Some("set_speed"), Some("pan"), Some(8)),
        "{v}"
    );
    no_debug_strings(&v);
    let frame = gimbalctl(&["encode", "--to", "5.1.12", "--from", "2", "P1194F830"]);
    let v = gimbalctl(&["--json", "decode", frame.stdout.trim()]).json_lines();
    assert_eq!(v[0]["command"]["name"], "go_to", "{v:?}");
    assert!(v[0]["command"]["pan_deg"].is_f64(), "{v:?}");
    no_debug_strings(&v[0]);
}
