//! gimbalctl as the bus master of a simulated bus (`--serial`, `--tcp` to
//! gimbalsim): each command family of Tables 4, 11 and 16, limits,
//! recovery from corrupted and lost frames, exit codes, `watch`.

use super::*;

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
    // The command in words (issue 53), not its payload `P10`.
    assert!(
        out.stderr.contains("NIC") && out.stderr.contains("go to preset 16"),
        "{out:?}"
    );
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
