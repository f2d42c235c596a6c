//! gimbal-mqtt's own metrics (issue 53, `[metrics] listen`): the command
//! messages counted by kind (a bounded set: a message not read and one for
//! no gimbal by their own kinds), the broker connection as its one
//! session, and what became of the door's commands on the bus (gcud's
//! refusal by its rule), read from a scrape after paho-mqtt drove it
//! through Mosquitto and real gcud.

use super::*;
use support::door::DoorMetrics;

#[test]
fn gimbal_mqtt_counts_commands_by_kind_the_broker_session_and_gcuds_refusals() {
    let Some(broker) = Broker::start() else { return };
    let site = Site::start_with(&broker, "north", "[metrics]\nlisten = \"127.0.0.1:0\"\n", "");
    let metrics = DoorMetrics::of(&site.door);
    let r = site.command(&broker, "gate", r#"{"id": 1, "home": true}"#);
    assert_eq!(r["ok"], true, "{r}");
    // The operators take the mast: its goto is refused by gcud.
    let out = support::door::operators_ctl(&site.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    let r = site.command(
        &broker,
        "mast",
        r#"{"id": 2, "goto": {"pan_deg": -30.0, "tilt_deg": 0.0}}"#,
    );
    assert_eq!(r["ok"], false, "{r}");
    let r = site.command(&broker, "mast", r#"{"id": 3, "fly": true}"#);
    assert_eq!(r["ok"], false, "{r}");
    // A command for no gimbal of the site: answered without an id.
    broker.step(
        "publish",
        &["sagebrush/north/no-such-gimbal/cmd", r#"{"stop": true}"#],
        || site.logs(),
    );
    eventually("the command for no gimbal counted", || {
        metrics.scrape().requests("no_such_gimbal") == Some(1.0)
    });
    let scrape = metrics.scrape();
    assert_eq!(scrape.requests("home"), Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("goto"), Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("malformed"), Some(1.0), "{scrape}");
    assert!(
        !scrape.text.contains("fly") && !scrape.text.contains("no-such-gimbal"),
        "a client's text became a label:\n{scrape}"
    );
    assert!(
        scrape.refusals("not_in_control") >= Some(1.0),
        "gcud's refusal by its rule:\n{scrape}"
    );
    assert!(scrape.outcomes("delivered") >= Some(1.0), "the gate's home:\n{scrape}");
    assert!(scrape.outcomes("refused") >= Some(1.0), "{scrape}");
    assert_eq!(scrape.sessions(), Some(1.0), "connected to the broker:\n{scrape}");
}
