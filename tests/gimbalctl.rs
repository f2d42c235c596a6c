//! `gimbalctl` against the real `gimbalsim` on a fresh pseudo-terminal per
//! test: every command family, exit codes, recovery from injected faults,
//! and encode/decode against golden vectors.

mod support;

use std::time::Duration;

use serde_json::Value;
use support::cli::At;
use support::{Sim, eventually, gimbalctl, gimbalctl_stdin};

#[test]
fn goto_then_position_converges_to_the_target() {
    let sim = Sim::pty(&[]);
    let ack = sim.json1(&["goto", "30", "-10.25"]);
    assert_eq!(ack["outcome"], "acknowledged");
    assert_eq!(ack["sent"], "P0BB8FBFF");
    eventually("the position to reach the target", || sim.position1() == (30.0, -10.25));
    // --wait reports arrival itself.
    let v = sim.json1(&["goto", "-15", "5", "--wait"]);
    assert_eq!(v["reached"], true, "{v}");
    assert_eq!(v["final"]["pan_deg"], -15.0);
    let text = sim.ctl1(&["position"]);
    assert_eq!(text.code, 0);
    assert!(
        text.stdout.contains("-15.00°") && text.stdout.contains("5.00°"),
        "{text:?}"
    );
}

#[test]
fn preset_store_recall_and_query() {
    let sim = Sim::pty(&["--presets", "16"]);
    sim.json1(&["goto", "12.5", "7.25", "--wait"]);
    sim.json1(&["preset", "store", "5"]);
    sim.json1(&["home"]);
    assert_eq!(sim.settled1(), (0.0, 0.0));
    let stored = sim.result1(&["preset", "stored", "5"]);
    assert_eq!(
        (stored["pan_deg"].as_f64(), stored["tilt_deg"].as_f64()),
        (Some(12.5), Some(7.25))
    );
    let query = sim.result1(&["preset", "query", "0x05"]);
    assert_eq!(query, stored);
    let untouched = sim.result1(&["preset", "query", "3"]);
    assert_eq!(untouched["pan_deg"], 0.0, "presets default to home");
    sim.json1(&["preset", "recall", "5"]);
    eventually("the preset position", || sim.position1() == (12.5, 7.25));
    // Presets 16.. are not implemented by this unit: NIC.
    let out = sim.ctl1(&["preset", "recall", "16"]);
    assert_eq!(out.code, 5, "{out:?}");
    assert!(out.stderr.contains("NIC") && out.stderr.contains("P10"), "{out:?}");
}

/// The stops the gimbal itself received, in order (its log of the wire).
fn stops_received(sim: &Sim) -> Vec<String> {
    sim.received("1.1.1")
        .into_iter()
        .map(|(_, payload)| payload)
        .filter(|p| ["PS", "TS", "PT"].contains(&p.as_str()))
        .collect()
}

#[test]
fn slew_stopped_by_its_stop_command() {
    let sim = Sim::pty(&[]);
    // The slowest speed (SP0/ST0: 7.5 deg/s): the hard stops at 180 and -90
    // degrees are 24 s and 12 s away, so a mount that settles short of
    // them was stopped, not blocked (settled1 waits for it to stand still).
    sim.json1(&["speed", "pan", "0"]);
    sim.json1(&["speed", "tilt", "0"]);
    sim.json1(&["slew", "right"]);
    eventually("pan to move", || sim.position1().0 > 1.0);
    sim.json1(&["stop", "pan"]);
    let (pan, tilt) = sim.settled1();
    assert!(
        pan > 1.0 && pan < 180.0,
        "PR moves counter-clockwise (+) and PS stops it before the hard stop: {pan}"
    );
    assert_eq!(tilt, 0.0);
    assert_eq!(stops_received(&sim), ["PS"], "the gimbal received the stop");
    // Tilt slews while pan stays stopped, until TS.
    sim.json1(&["slew", "down"]);
    eventually("tilt to move down", || sim.position1().1 < -1.0);
    sim.json1(&["stop", "tilt"]);
    let stopped = sim.settled1();
    assert_eq!(stopped.0, pan, "pan stays stopped");
    assert!(
        stopped.1 < -1.0 && stopped.1 > -90.0,
        "stopped before the hard stop: {stopped:?}"
    );
    assert_eq!(stops_received(&sim), ["PS", "TS"]);
    // Slew left, then stop everything (PT).
    sim.json1(&["slew", "left"]);
    eventually("pan to move left", || sim.position1().0 < pan - 1.0);
    sim.json1(&["stop"]);
    let all = sim.settled1();
    assert!(
        all.0 < pan && all.0 > -180.0,
        "PT stopped pan short of the hard stop: {all:?}"
    );
    assert_eq!(all.1, stopped.1, "tilt stays stopped");
    assert_eq!(stops_received(&sim), ["PS", "TS", "PT"]);
}

#[test]
fn software_limits_clamp_motion() {
    let sim = Sim::pty(&[]);
    // Simulator unit 0.1 degree: pan +10/-5, tilt +3/-2 degrees.
    sim.json1(&["limits", "set", "100", "50", "30", "20"]);
    let limits = sim.result1(&["limits"]);
    assert_eq!(limits["pan_ccw_raw"], 100);
    assert_eq!(limits["tilt_cw_raw"], 20);
    let out = sim.ctl1(&["--json", "goto", "90", "-45", "--wait"]);
    assert_eq!(out.code, 20, "stopped short: {out:?}");
    let v = out.json();
    assert_eq!(
        (v["reached"].as_bool(), v["outcome"].as_str()),
        (Some(false), Some("stopped_short")),
        "{v}"
    );
    assert_eq!(v["final"]["pan_deg"], 10.0, "{v}");
    assert_eq!(v["target"]["pan_deg"], 90.0, "{v}");
    assert_eq!(sim.position1(), (10.0, -2.0));
    sim.json1(&["slew", "left"]);
    eventually("the cw limit", || sim.position1().0 == -5.0);
    sim.json1(&["limits", "clear"]);
    assert_eq!(
        sim.result1(&["limits"])["pan_ccw_raw"],
        4095,
        "cleared limits read as FFF"
    );
    let v = sim.json1(&["goto", "90", "-45", "--wait"]);
    assert_eq!(v["reached"], true, "{v}");
}

#[test]
fn corrupted_results_are_naked_and_resent() {
    let sim = Sim::pty(&["--corrupt", "1", "--max-faults", "1"]);
    let v = sim.json1(&["position"]);
    assert_eq!(
        (v["naks_sent"].as_u64(), v["transmissions"].as_u64()),
        (Some(1), Some(1)),
        "{v}"
    );
    assert_eq!(v["result"]["pan_deg"], 0.0);
    let v = sim.json1(&["position"]);
    assert_eq!(v["naks_sent"], 0, "{v}");
    let stats = sim.stop();
    assert_eq!(stats["faults"]["corrupt"], 1, "{stats}");
    assert_eq!(stats["results_resent"], 1, "{stats}");
    assert_eq!(stats["naks_in"], 1, "{stats}");

    // A damaged ACK (HO has no result) is noise: the command is retransmitted.
    let sim = Sim::pty(&["--corrupt", "1", "--max-faults", "1"]);
    let v = sim.json1(&["--ack-timeout", "100", "home"]);
    assert_eq!(v["transmissions"], 2, "{v}");
    assert!(v["noise_bytes"].as_u64() >= Some(1), "{v}");
    assert_eq!(sim.stop()["faults"]["corrupt"], 1);
}

#[test]
fn dropped_acks_and_naks_are_recovered_by_retransmission() {
    let sim = Sim::pty(&["--drop-ack", "1", "--max-faults", "2"]);
    let v = sim.json1(&["--ack-timeout", "100", "relay", "close", "2"]);
    assert_eq!(v["transmissions"], 3, "two ACKs lost: {v}");
    assert_eq!(sim.result1(&["relay"])["on"], serde_json::json!([2]));
    assert_eq!(sim.stop()["faults"]["drop_ack"], 2);

    let sim = Sim::pty(&["--nak", "1", "--max-faults", "2"]);
    let v = sim.json1(&["position"]);
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
    let v = sim.json1(&["id"]);
    assert_eq!(v["transmissions"], 1, "{v}");
    assert_eq!(v["result"]["serial"], "SIM-0001");
    let log = sim.log();
    let stats = sim.stop();
    // The ACK was dropped (the simulator's own count) and the result, not a
    // retransmission, answered the one command the device received.
    assert_eq!(stats["faults"]["drop_ack"], 1, "{stats}\n{log}");
    assert!(!log.contains("tx ACK"), "the device sent no ACK:\n{log}");
    assert_eq!(stats["frames_in"], 1, "{stats}");
    assert_eq!(stats["acks_in"], 1, "the result was ACKed: {stats}");
}

#[test]
fn failures_have_distinct_exit_codes() {
    let sim = Sim::pty(&["--nak", "1"]);
    let out = sim.ctl1(&["--retries", "1", "--json", "position"]);
    assert_eq!(out.code, 3, "{out:?}");
    assert_eq!(out.json()["outcome"], "nak");
    drop(sim);

    let sim = Sim::pty(&["--silent", "1"]);
    let out = sim.ctl1(&["--retries", "1", "--ack-timeout", "100", "position"]);
    assert_eq!(out.code, 4, "{out:?}");
    assert!(out.stderr.contains("no ACK from 1.1.1"), "{out:?}");
    drop(sim);

    let sim = Sim::pty(&["--latency-ms", "1500"]);
    let out = sim.ctl1(&["--result-timeout", "200", "--json", "position"]);
    assert_eq!(out.code, 6, "{out:?}");
    assert_eq!(out.json()["outcome"], "no_result");
    let out = sim.ctl1(&["--json", "focus", "auto-on"]);
    assert_eq!(out.code, 5, "{out:?}");
    assert_eq!(out.json()["outcome"], "nic");
    let out = sim.ctl1(&["raw", "*dA"]);
    assert_eq!(out.code, 5, "{out:?}");

    // Another device on the bus does not answer.
    let sim = Sim::pty(&[]);
    let out = sim.ctl1(&["--to", "1.1.7", "--retries", "0", "--ack-timeout", "100", "status"]);
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
        (&["--to", "1.1.1", "position"], "no transport"),
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
    let out = gimbalctl(&["--serial", "/nonexistent/tty", "--to", "1.1.1", "position"]);
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
    let id = sim.result1(&["id"]);
    assert_eq!((id["id"].as_u64(), id["name"].as_str()), (Some(1), Some("Mast Head")));
    assert_eq!(
        (id["serial"].as_str(), id["revision"].as_str()),
        (Some("SN-77"), Some("19"))
    );
    let status = sim.result1(&["status"]);
    assert_eq!(
        (status["motors_off"].as_bool(), status["error"].as_bool()),
        (Some(false), Some(false))
    );
    assert_eq!(sim.result1(&["errors"])["azimuth"]["raw"], 0);
    assert_eq!(sim.result1(&["status-bits"])["elevation"]["positive_limit_found"], true);
    assert_eq!(sim.result1(&["data-rate"])["bps"], 38400);
    let out = sim.ctl1(&["data-rate", "115200"]);
    assert_eq!(out.code, 5, "above the unit's maximum: {out:?}");
    sim.json1(&["data-rate", "9600"]);
    sim.json1(&["gains", "set", "tilt", "1.5"]);
    let gains = sim.result1(&["gains"]);
    assert_eq!(
        (gains["pan_gain"].as_f64(), gains["tilt_gain"].as_f64()),
        (Some(1.0), Some(1.5))
    );
    sim.json1(&["relay", "close", "0"]);
    sim.json1(&["relay", "close", "3"]);
    sim.json1(&["relay", "open", "0"]);
    assert_eq!(sim.result1(&["relay"])["raw"], 8);
    // #NN: the device answers at its new address only.
    sim.json1(&["set-address", "9"]);
    assert_eq!(sim.result1(&["--to", "1.1.9", "id"])["id"], 9);
    let out = sim.ctl1(&["--retries", "0", "--ack-timeout", "100", "id"]);
    assert_eq!(out.code, 4, "{out:?}");
}

#[test]
fn rates_speeds_accelerations_vector_and_home() {
    let sim = Sim::pty(&[]);
    sim.json1(&["rate", "pan", "10.25"]);
    assert_eq!(sim.result1(&["rate", "pan"])["deg_s"], 10.25);
    sim.json1(&["speed", "tilt", "F"]);
    let rates = sim.result1(&["rate"]);
    assert_eq!(
        (rates["pan_deg_s"].as_f64(), rates["tilt_deg_s"].as_f64()),
        (Some(10.25), Some(120.0))
    );
    sim.json1(&["accel", "tilt", "80"]);
    assert_eq!(sim.result1(&["accel"])["tilt_deg_s2"], 80.0);
    assert_eq!(sim.result1(&["accel", "pan"])["deg_s2"], 120.0);
    sim.json1(&["rate", "pan", "60"]);
    sim.json1(&["vector", "on"]);
    sim.json1(&["goto", "40", "4"]);
    // Both axes arrive together: tilt is never done while pan is still far away.
    let mut samples = Vec::new();
    eventually("the vector move to end", || {
        let p = sim.position1();
        samples.push(p);
        p == (40.0, 4.0)
    });
    for (pan, tilt) in &samples {
        if *tilt == 4.0 {
            assert!(*pan > 30.0, "tilt arrived while pan was at {pan}: {samples:?}");
        }
    }
    sim.json1(&["vector", "off"]);
    let home = sim.result1(&["verify-home"]);
    assert_eq!(home["count_correct"]["pan"], false, "not on the centre switch");
    sim.json1(&["home"]);
    eventually("home", || sim.position1() == (0.0, 0.0));
    assert_eq!(sim.result1(&["verify-home"])["count_correct"]["pan"], true);
}

#[test]
fn init_halt_recall_and_motors() {
    let sim = Sim::pty(&["--init-ms", "300", "--uninitialized"]);
    assert_eq!(sim.result1(&["status"])["azimuth_not_initialized"], true);
    let init = sim.result1(&["init"]);
    assert_eq!(init["success"], true, "{init}");
    assert_eq!(init["pan_ccw"]["center_switch_detected"], true);
    assert_eq!(sim.result1(&["status"])["code"], 0);
    sim.json1(&["slew", "up"]);
    eventually("tilt to move", || sim.position1().1 > 2.0);
    sim.json1(&["halt"]);
    let held = sim.settled1();
    assert_eq!(sim.result1(&["status"])["motors_off"], true);
    sim.json1(&["home"]);
    eventually("home", || sim.position1() == (0.0, 0.0));
    sim.json1(&["recall-halt"]);
    eventually("the halt position", || sim.position1() == held);
    sim.json1(&["stop", "motors"]);
    assert_eq!(sim.result1(&["status"])["motors_off"], true);
}

#[test]
fn lens_camera_focus_and_zoom() {
    let sim = Sim::pty(&["--lens-travel-ms", "300"]);
    sim.json1(&["zoom", "speed", "9"]);
    assert_eq!(sim.result1(&["zoom", "speed"])["speed"], 9);
    sim.json1(&["zoom", "in"]);
    eventually("zoom to the far end", || sim.result1(&["lens"])["zoom"] == 4095);
    sim.json1(&["zoom", "stop"]);
    sim.json1(&["focus", "speed", "9"]);
    sim.json1(&["focus", "far"]);
    eventually("focus to move", || sim.result1(&["lens"])["focus"].as_u64() > Some(0));
    sim.json1(&["focus", "stop"]);
    sim.json1(&["lens", "goto", "2048", "100"]);
    eventually("the lens position", || {
        let l = sim.result1(&["lens"]);
        l["zoom"] == 2048 && l["focus"] == 100
    });
    sim.json1(&["zoom", "out"]);
    eventually("zoom out", || sim.result1(&["lens"])["zoom"] == 0);
    sim.json1(&["halt"]);
    sim.json1(&["recall-halt", "--lens"]);
    assert_eq!(sim.result1(&["camera", "status"])["raw"], "C1L0");
    sim.json1(&["camera", "off"]);
    assert_eq!(sim.result1(&["camera", "status"])["raw"], "C0L0");
    assert_eq!(sim.ctl1(&["zoom", "in"]).code, 5, "no lens power");
    sim.json1(&["camera", "on"]);
    for nic in [
        &["focus", "auto-on"][..],
        &["focus", "auto-off"],
        &["zoom", "digital", "A"],
    ] {
        assert_eq!(sim.ctl1(nic).code, 5, "{nic:?} is not implemented by the gimbal");
    }
    assert_eq!(sim.result1(&["focus", "speed"])["speed"], 9);
}

#[test]
fn auxiliary_port_loop_back_and_raw() {
    let sim = Sim::pty(&[]);
    sim.json1(&["aux", "1", "configure", "19200", "8", "1", "even"]);
    sim.json1(&["aux", "1", "send", "ping\\x01"]);
    assert_eq!(sim.result1(&["aux", "1", "count"])["count"], 5);
    let data = sim.result1(&["aux", "1", "read", "4"]);
    assert_eq!(data["data"], "ping");
    assert_eq!(sim.result1(&["aux", "1", "read", "10"])["data"], "\\x01");
    sim.json1(&["aux", "0", "send", "abc"]);
    sim.json1(&["aux", "0", "flush"]);
    assert_eq!(sim.result1(&["aux", "0", "count"])["count"], 0);
    let raw = sim.json1(&["raw", "P?"]);
    assert_eq!(
        (raw["result_payload"].as_str(), raw["sent"].as_str()),
        (Some("00000000"), Some("P?"))
    );
    let text = sim.ctl1(&["raw", "VS"]);
    assert!(text.stdout.contains("C1L0"), "{text:?}");
}

#[test]
fn watch_polls_position_and_lens() {
    let sim = Sim::pty(&[]);
    sim.json1(&["slew", "right"]);
    let out = sim.ctl1(&["--json", "watch", "--rate", "20", "--count", "4"]);
    assert_eq!(out.code, 0, "{out:?}");
    let samples = out.json_lines();
    assert_eq!(samples.len(), 4);
    let pans: Vec<f64> = samples
        .iter()
        .map(|s| s["position"]["pan_deg"].as_f64().unwrap())
        .collect();
    assert!(pans.windows(2).all(|w| w[1] >= w[0]) && pans[3] > pans[0], "{pans:?}");
    assert_eq!(samples[0]["lens"]["zoom"], 0);
    let text = sim.ctl1(&["watch", "--count", "2", "--rate", "20"]);
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

// ---- issues 12 and 13: jogging, failures, --wait, output, JSON, help, scan ----

use support::cli::{DemoGcud, FakeBus, spawn_ctl, wait_output};

/// What gimbal `dest` received from clients (source 0) that stops a
/// motion, by its own record; and that gcud's dead-man stopped nothing.
fn client_stops(gcud: &DemoGcud, dest: &str) -> Vec<String> {
    gcud.wait_until_clients_are_down();
    assert_eq!(
        gcud.dead_man_lines(),
        Vec::<String>::new(),
        "gcud's dead-man did the stopping:\n{}",
        gcud.log()
    );
    let received = gcud.received(dest);
    assert!(
        received.iter().all(|(source, _)| *source == 0),
        "only clients wrote to {dest}: {received:?}"
    );
    received
        .into_iter()
        .map(|(_, payload)| payload)
        .filter(|p| p.len() == 2 && p.ends_with('S') && p != "HS")
        .collect()
}

#[test]
fn jog_for_a_duration_through_gcud_keeps_moving_then_stops_and_confirms() {
    let gcud = DemoGcud::start();
    gcud.json(&["--to", "5.1.1", "rate", "pan", "20"]);
    let out = gcud.ctl(&["--json", "--to", "5.1.1", "slew", "right", "--for", "2s"]);
    assert_eq!(out.code, 0, "{out:?}\n{}", gcud.log());
    let v = out.json();
    assert_eq!(
        (v["sent"].as_str(), v["stop_sent"].as_str()),
        (Some("PR"), Some("PS")),
        "{v}"
    );
    assert_eq!(
        (v["stop_outcome"].as_str(), v["ended_by"].as_str()),
        (Some("acknowledged"), Some("duration"))
    );
    assert!(v["held_ms"].as_u64() >= Some(2000) && v["for_ms"] == 2000, "{v}");
    // The gimbal received gimbalctl's PS (not gcud's dead-man stop, which
    // would have ended the slew at once when gimbalctl disconnected) ...
    assert_eq!(client_stops(&gcud, "5.1.1"), ["PS"]);
    // ... and it stands where the PS left it, after moving for the whole
    // duration (the dead-man would have stopped it near 0).
    let stopped = gcud.position("5.1.1");
    assert!(stopped.0 > 20.0, "moved for about 2 s at 20 deg/s: {stopped:?}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(gcud.position("5.1.1"), stopped, "PS stopped it");

    // Zoom and focus are continuous motions too.
    let v = gcud.json(&["--to", "5.1.1", "zoom", "in", "--for", "300ms"]);
    assert_eq!(
        (v["sent"].as_str(), v["stop_sent"].as_str()),
        (Some("ZI"), Some("ZS")),
        "{v}"
    );
    assert!(gcud.lens("5.1.1").0 > 0, "zoomed in");
    let v = gcud.json(&["--to", "5.1.1", "focus", "far", "--for", "300ms"]);
    assert_eq!(
        (v["sent"].as_str(), v["stop_sent"].as_str()),
        (Some("FF"), Some("FS")),
        "{v}"
    );
    assert!(gcud.lens("5.1.1").1 > 0, "focused far");
    assert_eq!(client_stops(&gcud, "5.1.1"), ["PS", "ZS", "FS"]);
    // Without --for/--hold through gcud: a note says the dead-man stops it.
    let out = gcud.ctl(&["--to", "5.1.2", "slew", "left"]);
    assert!(
        out.stderr.contains("dead-man") && out.stderr.contains("--for"),
        "{out:?}"
    );
}

#[test]
fn jog_hold_lasts_until_stdin_closes_or_sigterm_then_stops() {
    let gcud = DemoGcud::start();
    gcud.json(&["--to", "5.2.1", "rate", "tilt", "5"]);
    let mut child = spawn_ctl(&[
        "--json",
        "--tcp",
        &gcud.clients,
        "--to",
        "5.2.1",
        "slew",
        "up",
        "--hold",
    ]);
    // Held: the connection stays open, so the slew goes on (at 5 deg/s the
    // hard stop is 18 s away); a dead-man stop would have ended it near 0.
    eventually("the held slew to carry tilt past 2 degrees", || {
        gcud.position("5.2.1").1 > 2.0
    });
    drop(child.stdin.take());
    let out = wait_output(child);
    assert_eq!(out.code, 0, "{out:?}");
    let v = out.json();
    assert_eq!(
        (v["ended_by"].as_str(), v["stop_sent"].as_str()),
        (Some("stdin"), Some("TS")),
        "{v}"
    );
    assert_eq!(v["stop_outcome"], "acknowledged");
    assert_eq!(
        client_stops(&gcud, "5.2.1"),
        ["TS"],
        "gimbalctl's TS reached the gimbal"
    );
    let stopped = gcud.position("5.2.1");
    assert!(stopped.1 < 90.0, "stopped short of the hard stop: {stopped:?}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(gcud.position("5.2.1"), stopped);

    let child = spawn_ctl(&[
        "--json",
        "--tcp",
        &gcud.clients,
        "--to",
        "5.2.1",
        "slew",
        "down",
        "--hold",
    ]);
    eventually("the held slew down to carry tilt 2 degrees lower", || {
        gcud.position("5.2.1").1 < stopped.1 - 2.0
    });
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("SIGTERM");
    let out = wait_output(child);
    assert_eq!(out.code, 0, "{out:?}");
    let v = out.json();
    assert_eq!(
        (
            v["ended_by"].as_str(),
            v["stop_sent"].as_str(),
            v["stop_outcome"].as_str()
        ),
        (Some("signal"), Some("TS"), Some("acknowledged")),
        "{v}"
    );
    // The TS went out before gimbalctl exited, not gcud's dead-man after.
    assert_eq!(client_stops(&gcud, "5.2.1"), ["TS", "TS"]);
    let after = gcud.position("5.2.1");
    assert!(after.1 > -90.0, "stopped short of the hard stop: {after:?}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(gcud.position("5.2.1"), after);
}

#[test]
fn jog_stop_that_is_not_acknowledged_exits_22() {
    // The device answers the slew, then goes silent: the stop is not confirmed.
    let sim = Sim::pty(&["--silent", "1"]);
    let out = sim.ctl1(&[
        "--retries",
        "0",
        "--ack-timeout",
        "100",
        "slew",
        "right",
        "--for",
        "50ms",
    ]);
    assert_eq!(out.code, 4, "the start itself was not acknowledged: {out:?}");
    drop(sim);
    let bus = FakeBus::start();
    // Device 4 of the scripted bus ACKs everything: the start and the stop are confirmed.
    let out = gimbalctl(&[
        "--json", "--tcp", &bus.addr, "--to", "1.1.4", "slew", "left", "--for", "50ms",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    assert_eq!(bus.received(), ["PL", "PS"]);
    // Device 6 acknowledges motions but not their stops: exit 22, the stop's reason given.
    let out = gimbalctl(&[
        "--json",
        "--tcp",
        &bus.addr,
        "--to",
        "1.1.6",
        "--retries",
        "0",
        "--ack-timeout",
        "100",
        "slew",
        "up",
        "--for",
        "50ms",
    ]);
    assert_eq!(out.code, 22, "{out:?}");
    let v = out.json();
    assert_eq!(
        (v["outcome"].as_str(), v["stop_outcome"].as_str()),
        (Some("stop_unconfirmed"), Some("no_ack")),
        "{v}"
    );
    assert!(out.stderr.contains("TS") && out.stderr.contains("may go on"), "{out:?}");
    // Device 9 is silent: the start fails with its reason (no ACK) and no stop is claimed.
    let out = gimbalctl(&[
        "--json",
        "--tcp",
        &bus.addr,
        "--to",
        "1.1.9",
        "--retries",
        "0",
        "--ack-timeout",
        "100",
        "zoom",
        "in",
        "--for",
        "50ms",
    ]);
    assert_eq!(
        (out.code, out.json()["outcome"].as_str()),
        (4, Some("no_ack")),
        "{out:?}"
    );
}

#[test]
fn help_documents_the_dead_man_examples_ranges_and_exit_codes() {
    for sub in [&["slew", "--help"][..], &["zoom", "--help"], &["focus", "--help"]] {
        let out = gimbalctl(sub);
        assert_eq!(out.code, 0, "{out:?}");
        assert!(
            out.stdout.contains("dead-man") && out.stdout.contains("--for") && out.stdout.contains("--hold"),
            "{sub:?}: {}",
            out.stdout
        );
    }
    let slew = gimbalctl(&["slew", "--help"]).stdout;
    assert!(!slew.contains("until `stop`)"), "no unconditional claim: {slew}");
    let every = [
        "position",
        "goto",
        "preset",
        "slew",
        "stop",
        "halt",
        "recall-halt",
        "speed",
        "rate",
        "accel",
        "vector",
        "home",
        "verify-home",
        "init",
        "limits",
        "gains",
        "relay",
        "lens",
        "camera",
        "focus",
        "zoom",
        "id",
        "status",
        "errors",
        "status-bits",
        "data-rate",
        "set-address",
        "aux",
        "raw",
        "watch",
        "scan",
        "encode",
        "decode",
    ];
    for sub in every {
        let out = gimbalctl(&["help", sub]);
        assert!(
            out.stdout.contains("Examples:"),
            "{sub} has no examples: {}",
            out.stdout
        );
        // Global options are grouped under their headings, once each.
        assert_eq!(
            out.stdout.matches("Connection (global):").count(),
            1,
            "{sub}: {}",
            out.stdout
        );
    }
    for nested in [
        &["preset", "store"][..],
        &["preset", "recall"],
        &["preset", "query"],
        &["preset", "stored"],
        &["limits", "set"],
        &["limits", "clear"],
        &["gains", "set"],
        &["relay", "open"],
        &["relay", "close"],
        &["lens", "goto"],
        &["focus", "far"],
        &["focus", "near"],
        &["focus", "stop"],
        &["focus", "speed"],
        &["zoom", "in"],
        &["zoom", "out"],
        &["zoom", "stop"],
        &["zoom", "speed"],
        &["zoom", "digital"],
        &["aux", "configure"],
        &["aux", "send"],
        &["aux", "read"],
        &["aux", "count"],
        &["aux", "flush"],
    ] {
        let mut args = vec!["help"];
        args.extend_from_slice(nested);
        let out = gimbalctl(&args);
        assert!(out.stdout.contains("Examples:"), "{nested:?} has no examples: {out:?}");
    }
    for (sub, range) in [
        (&["help", "speed"][..], "0..=15"),
        (&["help", "goto"], "-327.68..=327.67"),
        (&["help", "rate"], "0..=655.35"),
        (&["help", "accel"], "0..=655.35"),
        (&["help", "lens", "goto"], "0..=4095"),
        (&["help", "zoom", "speed"], "0..=9"),
        (&["help", "preset", "store"], "0..=255"),
        (&["help", "gains", "set"], "0.3..=3.0"),
    ] {
        let out = gimbalctl(sub);
        assert!(
            out.stdout.contains(range),
            "{sub:?} should give {range}: {}",
            out.stdout
        );
    }
    let help = gimbalctl(&["--help"]).stdout;
    for code in [
        "20  --wait: the mount stopped short",
        "21  --wait: still moving",
        "22  --for/--hold",
    ] {
        assert!(help.contains(code), "exit code table lacks {code:?}: {help}");
    }
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).expect("README");
    let section = readme.split("## gimbalctl").nth(1).expect("gimbalctl section");
    let section = section.split("\n## ").next().unwrap_or_default();
    for needle in ["dead-man", "--for", "--hold", "| 20 |", "| 22 |", "scan", "### JSON"] {
        assert!(section.contains(needle), "README gimbalctl section lacks {needle:?}");
    }
}

#[test]
fn bad_arguments_exit_2_with_a_hint_and_to_is_required() {
    let s = ["--serial", "/nonexistent"];
    for (args, needle) in [
        (
            &["--tcp", "127.0.0.1", "--to", "5.1.1", "position"][..],
            "expected HOST:PORT, e.g. 127.0.0.1:4001",
        ),
        (&["--tcp", "127.0.0.1:0", "--to", "5.1.1", "position"], "1..=65535"),
        (&[s[0], s[1], "position"], "needs --to"),
        (&[s[0], s[1], "goto", "10", "5"], "needs --to"),
        (&[s[0], s[1], "--to", "5.1", "id"], "GROUP.PORT.DEVICE"),
        (
            &[s[0], s[1], "--to", "1.1.1", "goto", "0", "-400"],
            "tilt -400 degrees is out of range -327.68..=327.67",
        ),
        (
            &[s[0], s[1], "--to", "1.1.1", "goto", "328", "0"],
            "pan 328 degrees is out of range",
        ),
        (&[s[0], s[1], "--to", "1.1.1", "speed", "pan", "16"], "0..=15"),
        (&[s[0], s[1], "--to", "1.1.1", "rate", "pan", "700"], "0..=655.35"),
        (&[s[0], s[1], "--to", "1.1.1", "accel", "tilt", "-1"], "0..=655.35"),
        (&[s[0], s[1], "--to", "1.1.1", "preset", "store", "256"], "0..=255"),
        (&[s[0], s[1], "--to", "1.1.1", "lens", "goto", "4096", "0"], "0..=4095"),
        (&[s[0], s[1], "--to", "1.1.1", "zoom", "speed", "10"], "0..=9"),
        (
            &[s[0], s[1], "--to", "1.1.1", "slew", "left", "--for", "2"],
            "2s, 500ms",
        ),
        (
            &[s[0], s[1], "--to", "1.1.1", "slew", "left", "--for", "1s", "--hold"],
            "--hold",
        ),
        (&[s[0], s[1], "--to", "1.1.255", "goto", "1", "1", "--wait"], "wildcard"),
        (&[s[0], s[1], "scan", "--devices", "0-3"], "1..=254"),
    ] {
        let out = gimbalctl(args);
        assert_eq!(out.code, 2, "{args:?}: {out:?}");
        assert!(
            out.stderr.contains(needle),
            "{args:?} should say {needle:?}: {}",
            out.stderr
        );
    }
}

#[test]
fn json_failures_of_bad_arguments_are_json_too() {
    for args in [
        &["--json", "--tcp", "127.0.0.1", "--to", "5.1.1", "position"][..],
        &[
            "--json",
            "--serial",
            "/nonexistent",
            "--to",
            "1.1.1",
            "speed",
            "pan",
            "16",
        ],
        &["--json", "--serial", "/nonexistent", "goto", "1", "2"],
    ] {
        let out = gimbalctl(args);
        assert_eq!(out.code, 2, "{args:?}: {out:?}");
        let v = out.json();
        assert_eq!(
            (v["ok"].as_bool(), v["outcome"].as_str(), v["exit_code"].as_u64()),
            (Some(false), Some("usage"), Some(2))
        );
        assert!(v["error"].as_str().is_some_and(|e| !e.is_empty()), "{v}");
    }
}

#[test]
fn undeliverable_queries_fail_at_once_with_their_own_reason_and_code() {
    let gcud = DemoGcud::start();
    for (to, code, outcome, says) in [
        ("5.1.7", 8, "device_silent", "did not acknowledge"),
        ("5.9.1", 10, "no_such_port", "no such port"),
        ("5.3.1", 11, "port_closed", "port is not open"),
        ("7.1.1", 13, "no_route", "no route"),
    ] {
        for query in ["id", "position"] {
            // A result time-out longer than the hang guard: had gimbalctl
            // waited for a result rather than ending on the report, the run
            // would be killed as hung (no clock is compared here).
            let out = gcud.ctl(&["--json", "--to", to, "--result-timeout", "120000", query]);
            assert_eq!(out.code, code, "{to} {query}: {out:?}");
            let v = out.json();
            assert_eq!(
                (v["outcome"].as_str(), v["exit_code"].as_i64()),
                (Some(outcome), Some(code.into())),
                "{v}"
            );
            assert!(out.stderr.contains(says) && out.stderr.contains(to), "{out:?}");
            assert!(!out.stderr.contains("no result"), "{out:?}");
            assert_eq!(out.stderr.lines().count(), 1, "one line, no log noise: {out:?}");
        }
    }
    // Nothing listening: an I/O error, exit 1, naming the address.
    let closed = TcpListenerGuard::free_port();
    let out = gimbalctl(&["--tcp", &closed, "--to", "5.1.1", "position"]);
    assert_eq!(out.code, 1, "{out:?}");
    assert!(out.stderr.contains(&closed), "{out:?}");
}

/// An address on 127.0.0.1 where nothing listens.
struct TcpListenerGuard;

impl TcpListenerGuard {
    fn free_port() -> String {
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        l.local_addr().expect("addr").to_string()
    }
}

#[test]
fn wait_on_every_motion_and_its_exit_codes() {
    let sim = Sim::pty(&["--presets", "256", "--lens-travel-ms", "300"]);
    let v = sim.json1(&["goto", "12.5", "-4", "--wait"]);
    assert_eq!(
        (v["reached"].as_bool(), v["final"]["pan_deg"].as_f64()),
        (Some(true), Some(12.5)),
        "{v}"
    );
    sim.json1(&["preset", "store", "255"]);
    let v = sim.json1(&["home", "--wait"]);
    assert_eq!(
        (v["reached"].as_bool(), v["final"]["tilt_deg"].as_f64()),
        (Some(true), Some(0.0)),
        "{v}"
    );
    let v = sim.json1(&["preset", "recall", "255", "--wait"]);
    assert_eq!(
        (v["sent"].as_str(), v["reached"].as_bool()),
        (Some("PFF"), Some(true)),
        "{v}"
    );
    assert_eq!(
        (v["target"]["pan_deg"].as_f64(), v["preset"].as_u64()),
        (Some(12.5), Some(255)),
        "{v}"
    );
    assert_eq!(sim.position1(), (12.5, -4.0));
    let v = sim.json1(&["lens", "goto", "1000", "200", "--wait"]);
    assert_eq!(
        (v["reached"].as_bool(), v["final"]["zoom"].as_u64()),
        (Some(true), Some(1000)),
        "{v}"
    );
    let text = sim.ctl1(&["goto", "3", "3", "--wait"]);
    assert!(
        text.stdout.contains("arrived at pan") && text.stdout.contains("P012C012C"),
        "{text:?}"
    );
    // Still moving when the wait ends: 21.
    sim.json1(&["rate", "pan", "1"]);
    let out = sim.ctl1(&["--json", "goto", "100", "3", "--wait", "--wait-timeout", "300"]);
    assert_eq!(
        (out.code, out.json()["outcome"].as_str()),
        (21, Some("wait_timeout")),
        "{out:?}"
    );
    assert!(out.stderr.contains("still moving"), "{out:?}");
    sim.json1(&["stop"]);
    // Stopped short by software limits: 20 (also for home and presets).
    sim.json1(&["rate", "pan", "60"]);
    sim.json1(&["limits", "set", "50", "50", "50", "50"]);
    let out = sim.ctl1(&["goto", "-30", "0", "--wait"]);
    assert_eq!(out.code, 20, "{out:?}");
    assert!(out.stderr.contains("stopped short at pan"), "{out:?}");
    let out = sim.ctl1(&["--json", "preset", "recall", "255", "--wait"]);
    assert_eq!(out.code, 20, "{out:?}");
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

#[test]
fn scan_finds_gcus_ports_and_devices_through_gcud() {
    let gcud = DemoGcud::start();
    let v = gcud.json(&["scan", "--gcus", "1-9", "--ports", "1-4", "--devices", "1-3"]);
    let gcus = v["gcus"].as_array().expect("gcus");
    assert_eq!(gcus.len(), 1, "{v}");
    let g = &gcus[0];
    assert_eq!(
        (g["group"].as_u64(), g["name"].as_str(), g["serial"].as_str()),
        (Some(5), Some("demo GCU"), Some("DEMO-0005"))
    );
    let ports = g["ports"].as_array().expect("ports");
    let ids = |p: &Value| -> Vec<u64> {
        p["devices"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| d["id"].as_u64().unwrap())
            .collect()
    };
    assert_eq!(
        ports.iter().map(|p| p["port"].as_u64().unwrap()).collect::<Vec<_>>(),
        [1, 2, 3],
        "{v}"
    );
    assert_eq!(
        (ids(&ports[0]), ports[0]["silent"].as_u64()),
        (vec![1, 2], Some(1)),
        "{v}"
    );
    assert_eq!(ids(&ports[1]), [1], "{v}");
    assert_eq!(ports[2]["state"], "port_closed", "{v}");
    let d = &ports[0]["devices"][0];
    assert_eq!(
        (d["address"].as_str(), d["name"].as_str()),
        (Some("5.1.1"), Some("sim gimbal 1.1")),
        "{d}"
    );
    assert_eq!(d["awake"]["hardware_ok"], true);
    assert!(d["status"]["azimuth"]["not_initialized"].is_boolean(), "{d}");
    assert_eq!(d["collision"], false);
    assert_eq!(v["problems"], serde_json::json!([]), "{v}");
    let text = gcud.ctl(&["scan", "--gcus", "5", "--ports", "1-3", "--devices", "1-2"]);
    assert_eq!(text.code, 0, "{text:?}");
    assert!(
        text.stdout.starts_with("GCU 5 (5.0.0)") && text.stdout.contains("\n  port 1\n    device 1 (5.1.1)"),
        "{text:?}"
    );
    assert!(text.stdout.contains("port 3: the port is not open"), "{text:?}");
}

#[test]
fn scan_on_a_bus_sends_only_queries_and_leaves_a_slew_alone() {
    let sim = Sim::pty(&["--device", "1,2,5"]);
    sim.json1(&["rate", "pan", "5"]);
    sim.json1(&["slew", "right"]);
    let v = sim
        .ctl(&["--json", "scan", "--devices", "1-6", "--bus", "1.1", "--timeout", "150"])
        .json();
    let devices: Vec<u64> = v["bus"]["devices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["id"].as_u64().unwrap())
        .collect();
    assert_eq!(devices, [1, 2, 5], "{v}");
    assert_eq!(v["bus"]["silent"], 3);
    // What the devices received during the scan (their own record): only
    // queries. Device 1 first got the rate and the slew.
    let mut received = sim.received("1.1.1");
    assert_eq!(
        received.drain(..2).map(|(_, p)| p).collect::<Vec<_>>(),
        ["RP01F4", "PR"],
        "{received:?}"
    );
    received.extend(sim.received("1.1.2"));
    received.extend(sim.received("1.1.5"));
    assert!(received.len() >= 3, "every device was asked: {received:?}");
    for (_, payload) in &received {
        assert!(
            payload.contains('?') || payload == "AW",
            "the scan sent {payload:?}, not a query: {received:?}"
        );
    }
    // The slew of device 1 went on through the scan (at 5 deg/s: a stopped
    // gimbal never gets there, and the wait fails on the hang guard).
    let a = sim.position1();
    eventually("the slew to go on after the scan", || sim.position1().0 > a.0 + 1.0);
    sim.json1(&["stop"]);
}

#[test]
fn scan_reports_garbage_timeouts_and_duplicate_ids_and_goes_on() {
    let bus = FakeBus::start();
    let out = gimbalctl(&[
        "--json",
        "--tcp",
        &bus.addr,
        "scan",
        "--direct",
        "--bus",
        "1.1",
        "--devices",
        "1-5",
        "--timeout",
        "200",
    ]);
    assert_eq!(out.code, 0, "{out:?}");
    let v = out.json();
    let devices: Vec<u64> = v["bus"]["devices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["id"].as_u64().unwrap())
        .collect();
    assert_eq!(devices, [1, 3], "{v}");
    assert_eq!(v["bus"]["devices"][0]["awake"]["motors_off"], true, "{v}");
    assert_eq!(
        v["bus"]["devices"][0]["status"]["azimuth"]["error_present"], true,
        "{v}"
    );
    let problems: Vec<(&str, &str)> = v["problems"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p["address"].as_str().unwrap(), p["outcome"].as_str().unwrap()))
        .collect();
    assert_eq!(problems, [("1.1.2", "bad_result"), ("1.1.4", "no_result")], "{v}");
    let collisions = v["collisions"].as_array().unwrap();
    assert_eq!(collisions.len(), 1, "{v}");
    assert_eq!(collisions[0]["address"], "1.1.3");
    let serials: Vec<&str> = collisions[0]["answers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["serial"].as_str().unwrap())
        .collect();
    assert_eq!(serials, ["FAKE-3A", "FAKE-3B"], "{v}");
    assert_eq!(v["bus"]["devices"][1]["collision"], true);
    // Only the identity and status queries went out.
    for p in bus.received() {
        assert!(["D?", "AW", "I?"].contains(&p.as_str()), "scan sent {p:?}");
    }
    let text = gimbalctl(&[
        "--tcp",
        &bus.addr,
        "scan",
        "--direct",
        "--bus",
        "1.1",
        "--devices",
        "1-5",
        "--timeout",
        "200",
    ]);
    assert!(
        text.stdout.contains("COLLISION") && text.stdout.contains("1.1.4:"),
        "{text:?}"
    );
}
