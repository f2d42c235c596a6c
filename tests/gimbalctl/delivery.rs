//! Outcomes through gcud: undeliverable queries fail at once with their
//! reason and exit code (ARCHITECTURE "Delivery contract"); `--wait` on
//! every motion and its exit codes.

use super::*;

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
