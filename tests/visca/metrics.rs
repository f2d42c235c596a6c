//! gimbal-visca's own metrics (issue 53, `[metrics] listen`): the VISCA
//! messages counted by kind, the controllers live, and what became of the
//! door's commands on the bus (gcud's refusal by its rule), read from a
//! scrape after the PyPI `visca-over-ip` client drove it through real gcud.

use super::*;
use support::door::DoorMetrics;

#[test]
fn gimbal_visca_counts_messages_by_kind_controllers_live_and_gcuds_refusals() {
    if !client_available() {
        return;
    }
    let gcud = support::door::start_governed_gcud();
    let text = config(&gcud.clients(), 5000, "[metrics]\nlisten = \"127.0.0.1:0\"\n");
    let stack = Stack::start_configured(gcud, &text);
    let metrics = DoorMetrics::of(&stack.door);
    assert_eq!(stack.step("absolute", &["100", "0"]), serde_json::json!({"ok": true}));
    stack.step("position", &[]);
    // The operators take mast-1: the next goto is refused by gcud.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    // The client returns at the ACK; the refusal (90 61 41 FF) follows.
    stack.step("absolute", &["-100", "0"]);
    support::eventually("gcud's refusal counted by its rule", || {
        metrics.scrape().refusals("not_in_control") >= Some(1.0)
    });
    stack.step("stop", &[]);
    let scrape = metrics.scrape();
    assert_eq!(scrape.requests("absolute"), Some(2.0), "two gotos:\n{scrape}");
    assert!(scrape.requests("inquiry") >= Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("stop"), Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("drive"), None, "no drive asked:\n{scrape}");
    assert!(scrape.outcomes("delivered") >= Some(1.0), "the first goto:\n{scrape}");
    assert!(scrape.outcomes("refused") >= Some(1.0), "{scrape}");
    assert!(scrape.sessions() >= Some(1.0), "the controller just heard:\n{scrape}");
}
