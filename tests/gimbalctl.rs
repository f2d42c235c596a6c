//! `gimbalctl` against the real `gimbalsim` on a fresh pseudo-terminal per
//! test: every command family, exit codes, recovery from injected faults,
//! and encode/decode against golden vectors.

mod support;

use std::time::Duration;

use serde_json::Value;
use support::{Sim, eventually, gimbalctl, gimbalctl_stdin};

#[test]
fn goto_then_position_converges_to_the_target() {
    let sim = Sim::pty(&[]);
    let ack = sim.ctl_json(&["goto", "30", "-10.25"]);
    assert_eq!(ack["outcome"], "acknowledged");
    assert_eq!(ack["payload"], "P0BB8FBFF");
    eventually("the position to reach the target", || sim.position() == (30.0, -10.25));
    // --wait reports arrival itself.
    let v = sim.ctl_json(&["goto", "-15", "5", "--wait"]);
    assert_eq!(v["reached"], true, "{v}");
    assert_eq!(v["final"]["pan_deg"], -15.0);
    let text = sim.ctl(&["position"]);
    assert_eq!(text.code, 0);
    assert!(
        text.stdout.contains("-15.00°") && text.stdout.contains("5.00°"),
        "{text:?}"
    );
}

#[test]
fn preset_store_recall_and_query() {
    let sim = Sim::pty(&["--presets", "16"]);
    sim.ctl_json(&["goto", "12.5", "7.25", "--wait"]);
    sim.ctl_json(&["preset", "store", "5"]);
    sim.ctl_json(&["home"]);
    assert_eq!(sim.settled_position(), (0.0, 0.0));
    let stored = sim.result(&["preset", "stored", "5"]);
    assert_eq!(
        (stored["pan_deg"].as_f64(), stored["tilt_deg"].as_f64()),
        (Some(12.5), Some(7.25))
    );
    let query = sim.result(&["preset", "query", "0x05"]);
    assert_eq!(query, stored);
    let untouched = sim.result(&["preset", "query", "3"]);
    assert_eq!(untouched["pan_deg"], 0.0, "presets default to home");
    sim.ctl_json(&["preset", "recall", "5"]);
    eventually("the preset position", || sim.position() == (12.5, 7.25));
    // Presets 16.. are not implemented by this unit: NIC.
    let out = sim.ctl(&["preset", "recall", "16"]);
    assert_eq!(out.code, 5, "{out:?}");
    assert!(out.stderr.contains("NIC") && out.stderr.contains("P10"), "{out:?}");
}

#[test]
fn slew_stopped_by_its_stop_command() {
    let sim = Sim::pty(&[]);
    sim.ctl_json(&["slew", "right"]);
    eventually("pan to move", || sim.position().0 > 1.0);
    sim.ctl_json(&["stop", "pan"]);
    let (pan, tilt) = sim.settled_position();
    assert!(pan > 1.0, "PR moves counter-clockwise (+): {pan}");
    assert_eq!(tilt, 0.0);
    // Tilt slews while pan stays stopped, until TS.
    sim.ctl_json(&["slew", "down"]);
    eventually("tilt to move down", || sim.position().1 < -1.0);
    sim.ctl_json(&["stop", "tilt"]);
    let stopped = sim.settled_position();
    assert_eq!(stopped.0, pan, "pan stays stopped");
    assert!(
        stopped.1 < -1.0 && stopped.1 > -90.0,
        "stopped before the hard stop: {stopped:?}"
    );
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(sim.position(), stopped);
    // Slew left, then stop everything (PT).
    sim.ctl_json(&["slew", "left"]);
    eventually("pan to move left", || sim.position().0 < pan);
    sim.ctl_json(&["stop"]);
    let all = sim.settled_position();
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(sim.position(), all);
}

#[test]
fn software_limits_clamp_motion() {
    let sim = Sim::pty(&[]);
    // Simulator unit 0.1 degree: pan +10/-5, tilt +3/-2 degrees.
    sim.ctl_json(&["limits", "set", "100", "50", "30", "20"]);
    let limits = sim.result(&["limits"]);
    assert_eq!(limits["pan_ccw"], 100);
    assert_eq!(limits["tilt_cw"], 20);
    let v = sim.ctl_json(&["goto", "90", "-45", "--wait"]);
    assert_eq!(v["reached"], false, "{v}");
    assert_eq!(sim.position(), (10.0, -2.0));
    sim.ctl_json(&["slew", "left"]);
    eventually("the cw limit", || sim.position().0 == -5.0);
    sim.ctl_json(&["limits", "clear"]);
    assert_eq!(sim.result(&["limits"])["pan_ccw"], 4095, "cleared limits read as FFF");
    let v = sim.ctl_json(&["goto", "90", "-45", "--wait"]);
    assert_eq!(v["reached"], true, "{v}");
}

#[test]
fn corrupted_results_are_naked_and_resent() {
    let sim = Sim::pty(&["--corrupt", "1", "--max-faults", "1"]);
    let v = sim.ctl_json(&["position"]);
    assert_eq!(
        (v["naks_sent"].as_u64(), v["transmissions"].as_u64()),
        (Some(1), Some(1)),
        "{v}"
    );
    assert_eq!(v["result"]["pan_deg"], 0.0);
    let v = sim.ctl_json(&["position"]);
    assert_eq!(v["naks_sent"], 0, "{v}");
    let stats = sim.stop();
    assert_eq!(stats["faults"]["corrupt"], 1, "{stats}");
    assert_eq!(stats["results_resent"], 1, "{stats}");
    assert_eq!(stats["naks_in"], 1, "{stats}");

    // A damaged ACK (HO has no result) is noise: the command is retransmitted.
    let sim = Sim::pty(&["--corrupt", "1", "--max-faults", "1"]);
    let v = sim.ctl_json(&["--ack-timeout", "100", "home"]);
    assert_eq!(v["transmissions"], 2, "{v}");
    assert!(v["noise_bytes"].as_u64() >= Some(1), "{v}");
    assert_eq!(sim.stop()["faults"]["corrupt"], 1);
}

#[test]
fn dropped_acks_and_naks_are_recovered_by_retransmission() {
    let sim = Sim::pty(&["--drop-ack", "1", "--max-faults", "2"]);
    let v = sim.ctl_json(&["--ack-timeout", "100", "relay", "close", "2"]);
    assert_eq!(v["transmissions"], 3, "two ACKs lost: {v}");
    assert_eq!(sim.result(&["relay"])["on"], serde_json::json!([2]));
    assert_eq!(sim.stop()["faults"]["drop_ack"], 2);

    let sim = Sim::pty(&["--nak", "1", "--max-faults", "2"]);
    let v = sim.ctl_json(&["position"]);
    assert_eq!(
        (v["transmissions"].as_u64(), v["naks_received"].as_u64()),
        (Some(3), Some(2)),
        "{v}"
    );
    let stats = sim.stop();
    assert_eq!(stats["faults"]["nak"], 2, "{stats}");
    assert_eq!(stats["naks_sent"], 2, "{stats}");
}

#[test]
fn a_lost_ack_with_a_result_still_delivers_the_result() {
    let sim = Sim::pty(&["--drop-ack", "1", "--max-faults", "1"]);
    let v = sim.ctl_json(&["id"]);
    assert_eq!(v["transmissions"], 1, "{v}");
    assert_eq!(v["result"]["serial"], "SIM-0001");
}

#[test]
fn failures_have_distinct_exit_codes() {
    let sim = Sim::pty(&["--nak", "1"]);
    let out = sim.ctl(&["--retries", "1", "--json", "position"]);
    assert_eq!(out.code, 3, "{out:?}");
    assert_eq!(out.json()["outcome"], "nak");
    drop(sim);

    let sim = Sim::pty(&["--silent", "1"]);
    let out = sim.ctl(&["--retries", "1", "--ack-timeout", "100", "position"]);
    assert_eq!(out.code, 4, "{out:?}");
    assert!(out.stderr.contains("no ACK from 1.1.1"), "{out:?}");
    drop(sim);

    let sim = Sim::pty(&["--latency-ms", "1500"]);
    let out = sim.ctl(&["--result-timeout", "200", "--json", "position"]);
    assert_eq!(out.code, 6, "{out:?}");
    assert_eq!(out.json()["outcome"], "no_result");
    let out = sim.ctl(&["--json", "focus", "auto-on"]);
    assert_eq!(out.code, 5, "{out:?}");
    assert_eq!(out.json()["outcome"], "nic");
    let out = sim.ctl(&["raw", "*dA"]);
    assert_eq!(out.code, 5, "{out:?}");

    // Another device on the bus does not answer.
    let sim = Sim::pty(&[]);
    let out = sim.ctl(&["--to", "1.1.7", "--retries", "0", "--ack-timeout", "100", "status"]);
    assert_eq!(out.code, 4, "{out:?}");
}

#[test]
fn bad_arguments_exit_2_and_name_the_problem() {
    for (args, needle) in [
        (&["--serial", "/nonexistent", "goto", "400", "0"][..], "400"),
        (&["--serial", "/nonexistent", "speed", "pan", "16"], "16"),
        (&["--serial", "/nonexistent", "--to", "1.1", "position"], "1.1"),
        (&["--serial", "/nonexistent", "gains", "set", "pan", "5"], "gain"),
        (&["--serial", "/nonexistent", "--baud", "9601", "position"], "9601"),
        (&["position"], "no transport"),
        (&["encode", "--to", "1.1.1", ""], "payload"),
        (&["decode", "F8 0"], "odd"),
    ] {
        let out = gimbalctl(args);
        assert_eq!(out.code, 2, "{args:?}: {out:?}");
        assert!(
            out.stderr.contains(needle),
            "{args:?} should name {needle:?}: {}",
            out.stderr
        );
    }
    let out = gimbalctl(&["--serial", "/nonexistent/tty", "position"]);
    assert_eq!(out.code, 1, "{out:?}");
    assert!(out.stderr.contains("/nonexistent/tty"), "{out:?}");
    let help = gimbalctl(&["--help"]);
    assert!(
        help.stdout.contains("Exit codes") && help.stdout.contains("NIC"),
        "{help:?}"
    );
}

#[test]
fn device_queries_and_settings() {
    let sim = Sim::pty(&["--name", "Mast Head", "--serial-number", "SN-77", "--max-baud", "38400"]);
    let id = sim.result(&["id"]);
    assert_eq!((id["id"].as_u64(), id["name"].as_str()), (Some(1), Some("Mast Head")));
    assert_eq!(
        (id["serial"].as_str(), id["revision"].as_str()),
        (Some("SN-77"), Some("19"))
    );
    let status = sim.result(&["status"]);
    assert_eq!(
        (status["motors_on"].as_bool(), status["error"].as_bool()),
        (Some(true), Some(false))
    );
    assert_eq!(sim.result(&["errors"])["pan"]["bits"], 0);
    assert_eq!(sim.result(&["status-bits"])["tilt"]["set"][0], "positive_limit_found");
    assert_eq!(sim.result(&["data-rate"])["bps"], 38400);
    let out = sim.ctl(&["data-rate", "115200"]);
    assert_eq!(out.code, 5, "above the unit's maximum: {out:?}");
    sim.ctl_json(&["data-rate", "9600"]);
    sim.ctl_json(&["gains", "set", "tilt", "1.5"]);
    let gains = sim.result(&["gains"]);
    assert_eq!((gains["pan"].as_f64(), gains["tilt"].as_f64()), (Some(1.0), Some(1.5)));
    sim.ctl_json(&["relay", "close", "0"]);
    sim.ctl_json(&["relay", "close", "3"]);
    sim.ctl_json(&["relay", "open", "0"]);
    assert_eq!(sim.result(&["relay"])["bits"], 8);
    // #NN: the device answers at its new address only.
    sim.ctl_json(&["set-address", "9"]);
    assert_eq!(sim.result(&["--to", "1.1.9", "id"])["id"], 9);
    let out = sim.ctl(&["--retries", "0", "--ack-timeout", "100", "id"]);
    assert_eq!(out.code, 4, "{out:?}");
}

#[test]
fn rates_speeds_accelerations_vector_and_home() {
    let sim = Sim::pty(&[]);
    sim.ctl_json(&["rate", "pan", "10.25"]);
    assert_eq!(sim.result(&["rate", "pan"])["deg_s"], 10.25);
    sim.ctl_json(&["speed", "tilt", "F"]);
    let rates = sim.result(&["rate"]);
    assert_eq!(
        (rates["pan_deg_s"].as_f64(), rates["tilt_deg_s"].as_f64()),
        (Some(10.25), Some(120.0))
    );
    sim.ctl_json(&["accel", "tilt", "80"]);
    assert_eq!(sim.result(&["accel"])["tilt_deg_s2"], 80.0);
    assert_eq!(sim.result(&["accel", "pan"])["deg_s2"], 120.0);
    sim.ctl_json(&["rate", "pan", "60"]);
    sim.ctl_json(&["vector", "on"]);
    sim.ctl_json(&["goto", "40", "4"]);
    // Both axes arrive together: tilt is never done while pan is still far away.
    let mut samples = Vec::new();
    eventually("the vector move to end", || {
        let p = sim.position();
        samples.push(p);
        p == (40.0, 4.0)
    });
    for (pan, tilt) in &samples {
        if *tilt == 4.0 {
            assert!(*pan > 30.0, "tilt arrived while pan was at {pan}: {samples:?}");
        }
    }
    sim.ctl_json(&["vector", "off"]);
    let home = sim.result(&["verify-home"]);
    assert_eq!(home["count_correct"]["pan"], false, "not on the centre switch");
    sim.ctl_json(&["home"]);
    eventually("home", || sim.position() == (0.0, 0.0));
    assert_eq!(sim.result(&["verify-home"])["count_correct"]["pan"], true);
}

#[test]
fn init_halt_recall_and_motors() {
    let sim = Sim::pty(&["--init-ms", "300", "--uninitialized"]);
    assert_eq!(sim.result(&["status"])["pan_initialized"], false);
    let init = sim.result(&["init"]);
    assert_eq!(init["success"], true, "{init}");
    assert_eq!(init["pan_ccw"]["center_switch_detected"], true);
    assert_eq!(sim.result(&["status"])["bits"], 0);
    sim.ctl_json(&["slew", "up"]);
    eventually("tilt to move", || sim.position().1 > 2.0);
    sim.ctl_json(&["halt"]);
    let held = sim.settled_position();
    assert_eq!(sim.result(&["status"])["motors_on"], false);
    sim.ctl_json(&["home"]);
    eventually("home", || sim.position() == (0.0, 0.0));
    sim.ctl_json(&["recall-halt"]);
    eventually("the halt position", || sim.position() == held);
    sim.ctl_json(&["stop", "motors"]);
    assert_eq!(sim.result(&["status"])["motors_on"], false);
}

#[test]
fn lens_camera_focus_and_zoom() {
    let sim = Sim::pty(&["--lens-travel-ms", "300"]);
    sim.ctl_json(&["zoom", "speed", "9"]);
    assert_eq!(sim.result(&["zoom", "speed"])["raw"], "9");
    sim.ctl_json(&["zoom", "in"]);
    eventually("zoom to the far end", || sim.result(&["lens"])["zoom"] == 4095);
    sim.ctl_json(&["zoom", "stop"]);
    sim.ctl_json(&["focus", "speed", "9"]);
    sim.ctl_json(&["focus", "far"]);
    eventually("focus to move", || sim.result(&["lens"])["focus"].as_u64() > Some(0));
    sim.ctl_json(&["focus", "stop"]);
    sim.ctl_json(&["lens", "goto", "2048", "100"]);
    eventually("the lens position", || {
        let l = sim.result(&["lens"]);
        l["zoom"] == 2048 && l["focus"] == 100
    });
    sim.ctl_json(&["zoom", "out"]);
    eventually("zoom out", || sim.result(&["lens"])["zoom"] == 0);
    sim.ctl_json(&["halt"]);
    sim.ctl_json(&["recall-halt", "--lens"]);
    assert_eq!(sim.result(&["camera", "status"])["raw"], "C1L0");
    sim.ctl_json(&["camera", "off"]);
    assert_eq!(sim.result(&["camera", "status"])["raw"], "C0L0");
    assert_eq!(sim.ctl(&["zoom", "in"]).code, 5, "no lens power");
    sim.ctl_json(&["camera", "on"]);
    for nic in [
        &["focus", "auto-on"][..],
        &["focus", "auto-off"],
        &["zoom", "digital", "A"],
    ] {
        assert_eq!(sim.ctl(nic).code, 5, "{nic:?} is not implemented by the gimbal");
    }
    assert_eq!(sim.result(&["focus", "speed"])["raw"], "9");
}

#[test]
fn auxiliary_port_loop_back_and_raw() {
    let sim = Sim::pty(&[]);
    sim.ctl_json(&["aux", "1", "configure", "19200", "8", "1", "even"]);
    sim.ctl_json(&["aux", "1", "send", "ping\\x01"]);
    assert_eq!(sim.result(&["aux", "1", "count"])["count"], 5);
    let data = sim.result(&["aux", "1", "read", "4"]);
    assert_eq!(data["data"], "ping");
    assert_eq!(sim.result(&["aux", "1", "read", "10"])["data"], "\\x01");
    sim.ctl_json(&["aux", "0", "send", "abc"]);
    sim.ctl_json(&["aux", "0", "flush"]);
    assert_eq!(sim.result(&["aux", "0", "count"])["count"], 0);
    let raw = sim.ctl_json(&["raw", "P?"]);
    assert_eq!(
        (raw["result_payload"].as_str(), raw["command"].as_str()),
        (Some("00000000"), Some("P?"))
    );
    let text = sim.ctl(&["raw", "VS"]);
    assert_eq!(text.stdout.trim(), "C1L0", "{text:?}");
}

#[test]
fn watch_polls_position_and_lens() {
    let sim = Sim::pty(&[]);
    sim.ctl_json(&["slew", "right"]);
    let out = sim.ctl(&["--json", "watch", "--rate", "20", "--count", "4"]);
    assert_eq!(out.code, 0, "{out:?}");
    let samples = out.json_lines();
    assert_eq!(samples.len(), 4);
    let pans: Vec<f64> = samples
        .iter()
        .map(|s| s["position"]["pan_deg"].as_f64().unwrap())
        .collect();
    assert!(pans.windows(2).all(|w| w[1] >= w[0]) && pans[3] > pans[0], "{pans:?}");
    assert_eq!(samples[0]["lens"]["zoom"], 0);
    let text = sim.ctl(&["watch", "--count", "2", "--rate", "20"]);
    assert_eq!(
        text.stdout.lines().count(),
        2,
        "one line per sample off a terminal: {text:?}"
    );
    assert!(text.stdout.contains("zoom"));
}

#[test]
fn encode_golden_vectors() {
    for (args, hex) in [
        (
            &["encode", "--to", "5.1.12", "--from", "2", "P?"][..],
            "F8 05 01 0C 02 02 50 3F A5",
        ),
        (&["encode", "HO"], "F8 01 01 01 00 02 48 4F 9C"),
        (
            &["encode", "--to", "2.1.12", "--from", "5", "1194F830"],
            "F8 02 01 0C 05 08 31 31 39 34 46 38 33 30 CC",
        ),
        (
            &["encode", "--to", "255.255.255", "#07"],
            "F8 FF FF FF 00 03 23 30 37 8A",
        ),
        (
            &["encode", "P1194F830"],
            "F8 01 01 01 00 09 50 31 31 39 34 46 38 33 30 0C",
        ),
    ] {
        let out = gimbalctl(args);
        assert_eq!((out.code, out.stdout.trim()), (0, hex), "{args:?}: {out:?}");
    }
    // A 256-byte payload is sent with length byte 0 (1.4.1.1).
    let long = "A".repeat(256);
    let out = gimbalctl(&["encode", &long]);
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
