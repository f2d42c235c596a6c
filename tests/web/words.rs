//! What an operator reads is words (issue 53): gcud's log, gimbalctl's
//! errors, gcud-status and gimbal-web's log say a refusal and an outcome
//! with degrees and `G.P.D` addresses, tours counted from 1 as gcud-status
//! shows them, routine governance (a take-over, a tour) at INFO, a held
//! drive that gcud refuses logged once, never a Rust `Debug` form; gcud's
//! own preset scan is no error of the gimbal's, every configured gimbal is
//! listed before it answers, and a broadcast `home` leaves no stale
//! position in the metrics. Plain HTTP to gimbal-web (no browser).

use super::principals::{post, sign_in};
use super::*;

use support::door::{DOOR_GROUP, operators_ctl, start_governed_gcud_with};
use support::{assert_no_debug_forms, debug_forms};

/// The roof gimbal 5.2.1 with limits, a keep-out zone, park at preset 1
/// (gcud asks the gimbal where its presets lie: a NIC for one never
/// stored) and a two-step tour; 5.2.7 is configured but absent from the
/// bus; metrics and `/status` on.
const RULES: &str = "[metrics]\nlisten = \"127.0.0.1:0\"\n\
    [[gimbal]]\naddress = \"5.2.1\"\npan_limits_deg = [-170.0, 170.0]\ntilt_limits_deg = [-30.0, 60.0]\n\
    park = { preset = 1, after_s = 600 }\n\
    [[gimbal.keep_out]]\npan_deg = [100.0, 130.0]\ntilt_deg = [-30.0, 10.0]\n\
    [[gimbal]]\naddress = \"5.2.7\"\npan_limits_deg = [-170.0, 170.0]\n\
    [[tour]]\nname = \"round\"\naddress = \"5.2.1\"\n\
    steps = [{ pan_deg = 0.0, tilt_deg = 0.0, dwell_s = 1 }, { pan_deg = 30.0, tilt_deg = 20.0, dwell_s = 1 }]\n";

/// The addresses `/status` lists under the ports.
fn listed(status: &Value) -> Vec<String> {
    status["ports"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|p| p["devices"].as_array().cloned().unwrap_or_default())
        .map(|d| d["address"].as_str().unwrap_or_default().to_owned())
        .collect()
}

/// `/status`'s entry of gimbal `address`.
fn device(status: &Value, address: &str) -> Value {
    status["ports"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|p| p["devices"].as_array().cloned().unwrap_or_default())
        .find(|d| d["address"] == address)
        .unwrap_or_else(|| panic!("{address} not in /status: {status}"))
}

/// The log's lines at WARN.
fn warnings(log: &str) -> Vec<&str> {
    log.lines().filter(|l| l.contains(" WARN ")).collect()
}

#[test]
fn an_operator_reads_words_degrees_and_addresses_never_debug_forms() {
    let gcud = start_governed_gcud_with(RULES);
    // Every configured gimbal from the start: 5.2.7 never answers.
    let status = gcud.status();
    for address in ["5.1.1", "5.2.1", "5.2.7"] {
        assert!(listed(&status).iter().any(|a| a == address), "{address} in {status}");
    }
    let metrics_addr = gcud.address("metrics at /metrics");
    let text = support::gimbalctl(&["gcud-status", "--http", &metrics_addr]);
    assert_eq!(text.code, 0, "{text:?}");
    let absent = text.stdout.lines().find(|l| l.trim_start().starts_with("5.2.7"));
    assert!(
        absent.is_some_and(|l| l.contains("not yet heard")),
        "gcud-status:\n{}",
        text.stdout
    );

    // gcud's own preset scan met a NIC (preset 1 was never stored): no
    // error of the gimbal's.
    eventually("gcud's preset scan to meet a NIC on port 2", || {
        gcud.metric("gcud_port_nics_in_total{port=\"2\"}") > 0
    });
    let roof = device(&gcud.status(), "5.2.1");
    assert!(roof["last_error"].is_null() && roof["nics"] == 0, "5.2.1: {roof}");

    // A broadcast home leaves no stale position in the metrics (nothing
    // else asks 5.1.1 where it is).
    let pan = "gcud_device_position_pan_degrees{port=\"1\",device=\"1\"}";
    let out = gcud.ctl(&["--to", "5.1.1", "goto", "45", "-10", "--wait"]);
    assert_eq!(out.code, 0, "{out:?}");
    assert_eq!(gcud.real_metric(pan), Some(45.0));
    // gimbalctl returns once the broadcast is sent; gcud writes it on the
    // bus in its turn, and from then on the old reading is no position.
    let out = gcud.ctl(&["--to", "5.1.255", "home"]);
    assert_eq!(out.code, 0, "{out:?}");
    eventually("no stale position after a broadcast home", || {
        gcud.real_metric(pan).is_none()
    });
    assert_eq!(gcud.settled_position("5.1.1"), (0.0, 0.0));
    assert_eq!(gcud.real_metric(pan), Some(0.0));

    // A tour, counted from 1 as gcud-status shows it; an operator takes
    // the gimbal over: INFO, named G.P.D.
    let out = operators_ctl(&gcud, &["tour", "start", "round"]);
    assert_eq!(out.code, 0, "{out:?}");
    gcud.wait_for_log("tour round: running, step 1 of 2");
    let out = operators_ctl(&gcud, &["--to", "5.2.1", "goto", "20", "30"]);
    assert_eq!(out.code, 0, "{out:?}");
    let taken = gcud.wait_for_log("5.2.1: link operators (priority 80) took control from tour round");
    assert!(taken.contains(" INFO "), "{taken}");

    // A refusal in degrees, by gimbalctl and in gcud's audit.
    let out = gcud.ctl(&["--to", "5.2.1", "goto", "115", "0"]);
    assert_eq!(out.code, 23, "{out:?}");
    assert!(
        out.stderr.contains("go to pan 115.00° tilt 0.00° for 5.2.1") && !out.stderr.contains("P2CEC0000"),
        "{out:?}"
    );
    gcud.wait_for_log("link clients: go to pan 115.00° tilt 0.00° for 5.2.1: refused, ");

    // A held drive from the page that gcud refuses every 250 ms: one line.
    let stack = Stack::with(gcud, |clients, state| {
        format!(
            "gcud = \"{clients}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\nstate_file = \"{}\"\n{USERS}\
             [[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n[[gimbal]]\nname = \"roof\"\naddress = \"5.2.1\"\n",
            state.display()
        )
    });
    let op = sign_in(&stack, "op", "op-secret");
    let mut answers = Vec::new();
    for _ in 0..8 {
        let (status, answer) = post(
            &stack,
            &op,
            "/api/move",
            json!({ "gimbal": 1, "pan": 1, "tilt": 0, "speed": 0.5 }),
        );
        assert_ne!(status, 200, "{answer}");
        answers.push(answer);
        std::thread::sleep(Duration::from_millis(250));
    }
    assert!(
        answers.iter().any(|a| a.contains("refused by gcud: pan speed")),
        "gcud's refusal in words: {answers:#?}"
    );
    let door_log = stack.log();
    let refusals: Vec<&str> = door_log.lines().filter(|l| l.contains("refused by gcud")).collect();
    assert_eq!(refusals.len(), 1, "one line for a refused held drive:\n{door_log}");

    let log = stack.gcud.log();
    assert!(!log.contains("gimbal 2.1") && !log.contains("(step 0)"), "{log}");
    let loud: Vec<&str> = warnings(&log)
        .into_iter()
        .filter(|l| l.contains("taken over") || l.contains("tour") || l.contains("took control"))
        .collect();
    assert!(loud.is_empty(), "routine governance at WARN: {loud:#?}");
    assert_no_debug_forms("gcud's log", &log);
    assert_no_debug_forms("gimbal-web's log", &door_log);
}

/// The check every end-to-end test's logs go through (`support`, on
/// dropping gcud, a door, gimbalsim, and on each gimbalctl run) finds the
/// forms the logs showed before issue 53, and no word of the new ones.
#[test]
fn the_debug_form_check_finds_structs_options_and_results() {
    let old = "WARN not delivered dest=5.2.1 report=DeliveryReport { failure: Some(NotInControl), dest: Address { group: 5, port: 2, device: 1 }, command_checksum: 229, at_group: 5 }";
    assert_eq!(debug_forms(old), [old]);
    for form in [
        "primary=Some((1, 190))",
        "holder=None",
        "Err(Closed)",
        "Ok(5)",
        "Target { .. }",
    ] {
        assert_eq!(debug_forms(form).len(), 1, "{form}");
    }
    let words = "INFO refused by gcud: pan speed 7 of 15 for 5.2.1: link operators (priority 80) controls the gimbal \
                 (logged once until something is accepted or refused otherwise) gimbal=roof; Nobody {}; {\"a\": 1}; \
                 tour round: running, step 1 of 2; NoneSuch; Someone(1)";
    assert!(debug_forms(words).is_empty(), "{:?}", debug_forms(words));
}
