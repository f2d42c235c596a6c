//! gimbal-mavlink's own metrics (issue 53, `[metrics] listen`): the
//! MAVLink messages addressed to it counted by their name, the ground
//! stations live, and what became of its commands (gcud's refusal by
//! rule), read from a scrape after a real ground station (pymavlink) drove
//! it through real gcud.

use super::*;
use serde_json::json;

/// The value of the sample `series` in an OpenMetrics scrape.
fn sample(scrape: &str, series: &str) -> Option<f64> {
    scrape
        .lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

#[test]
fn gimbal_mavlink_counts_commands_by_message_stations_live_and_gcuds_refusals() {
    if !client_available() {
        return;
    }
    let gcud = support::door::start_governed_gcud();
    let config = mavlink_config(&gcud.clients(), 1000, "") + "[metrics]\nlisten = \"127.0.0.1:0\"\n";
    let stack = Stack::start_configured(gcud, "", &config);
    let metrics = format!("127.0.0.1:{}", stack.mavlink.port("metrics at /metrics"));
    let answer = stack.gcs("pitchyaw", GCS, json!({ "pitch": 10.0, "yaw": 20.0 }));
    assert_eq!(answer["result"], ACCEPTED, "{answer}");
    // The operators take mast-1: the next command is refused by gcud.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "0", "0"]);
    assert_eq!(out.code, 0, "{out:?}");
    let answer = stack.gcs("pitchyaw", GCS, json!({ "pitch": -10.0, "yaw": -20.0 }));
    assert_eq!(answer["result"], DENIED, "{answer}");
    let scrape = support::http_get(&metrics, "/metrics");
    let door = "door=\"gimbal-mavlink\"";
    let asked = sample(
        &scrape,
        &format!("sagebrush_door_requests_total{{{door},kind=\"COMMAND_LONG\"}}"),
    );
    assert!(asked >= Some(2.0), "the two pitch/yaw commands:\n{scrape}");
    let refused = sample(
        &scrape,
        &format!("sagebrush_door_refusals_total{{{door},reason=\"not_in_control\"}}"),
    );
    assert!(refused >= Some(1.0), "gcud's refusal by its rule:\n{scrape}");
    let live = sample(&scrape, &format!("sagebrush_door_sessions{{{door}}}"));
    assert!(live >= Some(1.0), "the ground station just heard:\n{scrape}");
}
