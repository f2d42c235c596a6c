//! gimbal-pelco's own metrics (issue 53, `[metrics] listen`): the frames
//! for its gimbals counted by kind, the keyboards live (a serial line
//! open, a TCP connection), and what became of the door's commands on the
//! bus (gcud's refusal by its rule), read from a scrape after the PyPI
//! `pyptzcontroller` keyboard drove it through real gcud.

use super::*;
use support::door::DoorMetrics;

#[test]
fn gimbal_pelco_counts_frames_by_kind_keyboards_live_and_gcuds_refusals() {
    if !client_available() {
        return;
    }
    let gcud = support::door::start_governed_gcud();
    let cable = NullModem::new();
    let serial = cable.ends.0.display().to_string();
    let config = door_config(&gcud.clients(), 1000, &serial, "[metrics]\nlisten = \"127.0.0.1:0\"\n");
    let stack = Stack::start_configured(gcud, cable, &config);
    let metrics = DoorMetrics::of(&stack.door);
    let held = stack.keyboard("hold", &["right", "20", "0.5"]);
    stack.keyboard("stop", &[]);
    // The operators take mast-1: the keyboard's absolute move is refused.
    let out = support::door::operators_ctl(&stack.gcud, &["--to", MAST, "goto", "20", "10"]);
    assert_eq!(out.code, 0, "{out:?}");
    stack.keyboard("move_to", &["10", "0"]);
    support::eventually("gcud's refusal counted by its rule", || {
        metrics.scrape().refusals("not_in_control") >= Some(1.0)
    });
    let scrape = metrics.scrape();
    assert_eq!(
        scrape.requests("drive"),
        held["sent"].as_f64(),
        "every drive frame held:\n{scrape}"
    );
    assert_eq!(scrape.requests("stop"), Some(1.0), "{scrape}");
    assert_eq!(scrape.requests("absolute"), Some(2.0), "pan and tilt:\n{scrape}");
    assert!(scrape.outcomes("delivered") >= Some(1.0), "the drive:\n{scrape}");
    assert!(scrape.outcomes("refused") >= Some(1.0), "{scrape}");
    assert_eq!(scrape.sessions(), Some(1.0), "the serial line open:\n{scrape}");
    // A TCP keyboard is one more while connected.
    let tcp = tcp_keyboard(stack.d_tcp);
    support::eventually("the TCP keyboard counted", || metrics.scrape().sessions() == Some(2.0));
    drop(tcp);
    support::eventually("the closed connection no longer counted", || {
        metrics.scrape().sessions() == Some(1.0)
    });
}
